//! `hairrecon masks` through the real binary, on a scene whose truth is exact: the bundled head
//! with a hair shell (its scalp pushed 8 mm outward) as the raw mesh, six views ray-cast from it
//! with textured brown hair, pink skin and a green-and-grey checkered backdrop, and the shell's
//! pixels as the ground-truth masks. Masks made without them must match them, never touch the
//! backdrop, and `--write` must put them into a capture that had none. `hairrecon reconstruct` on
//! the same scene moved into another frame, without head, scalp or masks, must fit the head (the
//! frame within 1° and 1%) and make the masks itself, in its output folder.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::Scratch;

use glam::{Vec2, Vec3};
use hairrecon_core::capture::{CaptureSpec, ViewSpec};
use hairrecon_core::formats::ply::read_ply;
use hairrecon_core::formats::{read_mesh, write_mesh};
use hairrecon_core::image_io::{write_png8_gray, write_png8_rgb, GrayImage32, RgbImage32};
use hairrecon_core::{Bvh, Camera, TriMesh};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hairrecon")
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new(&format!("masks-cli-{name}"))
}

/// A value in [0, 1) from integer coordinates (a hash, the texture's noise).
fn noise(x: u32, y: u32, k: u32) -> f32 {
    let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77) ^ k.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    (h & 0xFFFF) as f32 / 65536.0
}

/// The head and its hair shell in one mesh; returns it and the first triangle of the shell.
fn raw_mesh() -> (TriMesh, usize) {
    let head = read_mesh(fixtures().join("head.ply")).unwrap();
    let scalp = read_mesh(fixtures().join("scalp.ply")).unwrap();
    let normals = scalp.compute_vertex_normals();
    let offset = head.vertices.len() as u32;
    let mut vertices = head.vertices.clone();
    vertices.extend(scalp.vertices.iter().zip(&normals).map(|(v, n)| *v + 0.008 * *n));
    let mut triangles = head.triangles.clone();
    let shell_start = triangles.len();
    triangles.extend(scalp.triangles.iter().map(|t| t.map(|i| i + offset)));
    (TriMesh::new(vertices, triangles, None, None).unwrap(), shell_start)
}

/// Writes the capture: raw mesh, head, scalp, six views with images and (if `masks`) masks.
fn capture(dir: &Path, masks: bool) {
    let (raw, shell_start) = raw_mesh();
    write_mesh(dir.join("raw.ply"), &raw).unwrap();
    std::fs::copy(fixtures().join("head.ply"), dir.join("head.ply")).unwrap();
    std::fs::copy(fixtures().join("scalp.ply"), dir.join("scalp.ply")).unwrap();
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::create_dir_all(dir.join("gt")).unwrap();
    let bvh = Bvh::new(raw);
    let head_centre = Vec3::new(0.0, 0.0, 0.05);
    let (w, h) = (120u32, 180u32);
    let views = (0..6)
        .map(|i| {
            let a = std::f32::consts::TAU * i as f32 / 6.0 + 0.4;
            let eye = head_centre + Vec3::new(0.7 * a.cos(), 0.7 * a.sin(), 0.15 + 0.1 * (i % 2) as f32);
            let cam = Camera::look_at(eye, head_centre, Vec3::Z, 0.45, w, h).unwrap();
            let (mut rgb, mut gt) = (Vec::new(), Vec::new());
            for y in 0..h {
                for x in 0..w {
                    let d = cam.ray_direction(Vec2::new(x as f32, y as f32));
                    let hit = bvh.ray_cast(cam.center(), d, 0.0, f32::INFINITY);
                    let n = noise(x, y, i);
                    let (c, hair) = match hit {
                        Some(r) if r.triangle as usize >= shell_start => {
                            // Brown hair with dark gaps and lighter strands.
                            let s = 0.6 + 0.8 * n;
                            ([0.32 * s, 0.2 * s, 0.11 * s], 1.0)
                        }
                        Some(_) => ([0.85 + 0.1 * n, 0.66 + 0.08 * n, 0.58 + 0.08 * n], 0.0),
                        None => {
                            let check = ((x / 8) + (y / 8)) % 2 == 0;
                            let base = if check { [0.2, 0.45, 0.2] } else { [0.55, 0.55, 0.5] };
                            (base.map(|v| v + 0.1 * (n - 0.5)), 0.0)
                        }
                    };
                    rgb.extend(c);
                    gt.push(hair);
                }
            }
            let name = format!("view_{i}");
            write_png8_rgb(dir.join(format!("images/{name}.png")), &RgbImage32::new(w, h, rgb).unwrap()).unwrap();
            write_png8_gray(dir.join(format!("gt/{name}.png")), &GrayImage32::new(w, h, gt).unwrap()).unwrap();
            ViewSpec {
                name: name.clone(),
                image: format!("images/{name}.png").into(),
                mask: masks.then(|| format!("gt/{name}.png").into()),
                width: w,
                height: h,
                k: cam.k_rows(),
                r: cam.r_rows(),
                t: cam.t().to_array(),
                gt_orientation: None,
                gt_depth: None,
                original: None,
            }
        })
        .collect();
    CaptureSpec {
        version: 1,
        units: "metres".into(),
        frame: None,
        convention: "opencv".into(),
        views,
        raw_mesh: "raw.ply".into(),
        head_mesh: Some("head.ply".into()),
        scalp_mesh: Some("scalp.ply".into()),
        gt_strands: None,
        to_canonical: None,
    }
    .write(dir)
    .unwrap();
}

fn masks(args: &[&str]) -> serde_json::Value {
    let o = Command::new(bin()).arg("masks").args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn masks_match_the_hair_shell_and_never_touch_the_backdrop() {
    let dir = tmp("score");
    capture(&dir, true);
    let d = dir.to_str().unwrap();
    let matted = masks(&[d, "--score"]);
    let hard = masks(&[d, "--score", "--no-matting"]);
    let (s, h) = (&matted["score"], &hard["score"]);
    println!("matted {s:#}\nhard {h:#}");
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    assert!(f(s, "mean_iou") >= 0.95 && f(s, "min_iou") >= 0.9, "{s}");
    assert!(f(s, "max_off_hair") <= 0.01, "{s}");
    assert!(f(h, "mean_iou") >= 0.9, "{h}");
    // The phases' times add up to no more than the whole.
    let phases = |r: &serde_json::Value| -> Vec<f64> {
        ["rays", "region", "silhouettes", "matting"].iter().map(|k| r["phase_seconds"][k].as_f64().unwrap()).collect()
    };
    for r in [&matted, &hard] {
        let (p, total) = (phases(r), r["seconds"].as_f64().unwrap());
        assert!(p.iter().all(|&t| t >= 0.0) && p.iter().sum::<f64>() <= total + 0.2, "{p:?} of {total}");
    }
    // The hair colours the region learned are the shell's brown (L* about 25 to 45, b* > a* > 0).
    let hair = matted["region"]["hair_colours"].as_array().unwrap();
    let heaviest = hair.iter().max_by(|a, b| a[3].as_f64().partial_cmp(&b[3].as_f64()).unwrap()).unwrap();
    let (l, a, b) = (heaviest[0].as_f64().unwrap(), heaviest[1].as_f64().unwrap(), heaviest[2].as_f64().unwrap());
    assert!((20.0..50.0).contains(&l) && b > a && a > 0.0, "{heaviest}");
}

#[test]
fn write_adds_masks_and_the_hair_region_to_a_capture_without_masks() {
    let dir = tmp("write");
    capture(&dir, false);
    masks(&[dir.to_str().unwrap(), "--write"]);
    let spec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("capture.json")).unwrap()).unwrap();
    for (i, v) in spec["views"].as_array().unwrap().iter().enumerate() {
        assert_eq!(v["mask"], format!("masks/view_{i}.png"));
        assert!(dir.join(format!("masks/view_{i}.png")).is_file());
    }
    assert!(dir.join("masks.json").is_file());
    // hair_region.ply: the raw mesh with the hair probability as vertex quality; the shell's
    // vertices (after the head's) are hair, the face's are not.
    let bytes = std::fs::read(dir.join("hair_region.ply")).unwrap();
    let ply = read_ply(&bytes, |_, _| true).unwrap();
    let q = ply.element("vertex").unwrap().scalar("quality").unwrap().to_vec();
    let head_vertices = read_mesh(fixtures().join("head.ply")).unwrap().vertices.len();
    let shell = &q[head_vertices..];
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!("shell {:.3}, head {:.3}", mean(shell), mean(&q[..head_vertices]));
    assert!(mean(shell) > 0.9, "{}", mean(shell));
    // Face vertices: in front (y < -0.05) and below the hairline (z < 0.05).
    let raw = read_mesh(dir.join("raw.ply")).unwrap();
    let face: Vec<f64> =
        (0..head_vertices).filter(|&i| raw.vertices[i].y < -0.05 && raw.vertices[i].z < 0.05).map(|i| q[i]).collect();
    assert!(face.len() > 50 && mean(&face) < 0.1, "{} face vertices, mean {}", face.len(), mean(&face));
    // A second --write keeps the masks the first one named (they are now the capture's own).
    let before = std::fs::read(dir.join("masks/view_0.png")).unwrap();
    masks(&[dir.to_str().unwrap(), "--write"]);
    assert_eq!(before, std::fs::read(dir.join("masks/view_0.png")).unwrap());
}

#[test]
fn reconstruct_fits_the_head_and_makes_masks_for_an_imported_capture_without_them() {
    use glam::{DMat3, DVec3};
    use hairrecon_core::similarity::{transform_camera, transform_mesh, Similarity};
    let dir = tmp("imported");
    capture(&dir, false);
    // The capture's frame: canonical metres → 23 units a metre, turned, moved.
    let to_canonical = Similarity {
        scale: 1.0 / 23.0,
        rotation: DMat3::from_rotation_x(1.1) * DMat3::from_rotation_z(-2.4),
        translation: DVec3::new(0.2, -0.4, 0.1),
    };
    let to_capture = to_canonical.inverse();
    let raw = read_mesh(dir.join("raw.ply")).unwrap();
    write_mesh(dir.join("raw.ply"), &transform_mesh(&raw, &to_capture)).unwrap();
    let json = dir.join("capture.json");
    let mut spec: CaptureSpec = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for v in &mut spec.views {
        let cam = Camera::new(v.k, v.r, v.t, v.width, v.height).unwrap();
        let moved = transform_camera(&cam, &to_capture).unwrap();
        (v.r, v.t) = (moved.r_rows(), moved.t().to_array());
    }
    (spec.units, spec.frame, spec.head_mesh, spec.scalp_mesh) = ("unknown".into(), Some("imported".into()), None, None);
    spec.write(&dir).unwrap();
    let before = std::fs::read(&json).unwrap();

    let out = dir.join("out");
    let o = Command::new(bin())
        .args(["reconstruct", dir.to_str().unwrap(), "--out", out.to_str().unwrap(), "--stop-after", "masks"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&json).unwrap(), before, "the capture's own files are not changed");
    let fit: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("head_fit.json")).unwrap()).unwrap();
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let spec_fit = &fit["to_canonical"];
    let rows: Vec<[f64; 3]> = (0..3).map(|i| [0, 1, 2].map(|j| f(&spec_fit["rotation"][i][j]))).collect();
    let found = Similarity {
        scale: f(&spec_fit["scale"]),
        rotation: DMat3::from_cols_array_2d(&[rows[0], rows[1], rows[2]]).transpose(),
        translation: DVec3::new(0.0, 0.0, 0.0),
    };
    let degrees = found.rotation_angle_to(&to_canonical);
    let scale = found.scale / to_canonical.scale;
    println!("fit: {degrees:.2} deg, scale x{scale:.4}");
    assert!(degrees < 1.0 && (scale - 1.0).abs() < 0.01, "{fit:#}");
    assert!(fit["head"].as_bool().unwrap() && fit["scalp"].as_bool().unwrap(), "{fit:#}");
    // The fitted scalp, in the capture's frame, lies on the true one.
    let scalp = transform_mesh(&read_mesh(out.join("fitted_scalp.ply")).unwrap(), &to_canonical);
    let truth = Bvh::new(read_mesh(fixtures().join("scalp.ply")).unwrap());
    let d: Vec<f32> =
        scalp.vertices.iter().map(|&v| (truth.closest_point(v, f32::INFINITY).unwrap().point - v).length()).collect();
    let mean_mm = 1e3 * d.iter().sum::<f32>() / d.len() as f32;
    println!("fitted scalp: mean {mean_mm:.2} mm from the true one");
    assert!(mean_mm < 2.0, "{mean_mm}");
    // Masks of every view, against the shell's pixels.
    for i in 0..6 {
        let made = hairrecon_core::image_io::read_gray_f32(out.join(format!("masks/view_{i}.png"))).unwrap();
        let gt = hairrecon_core::image_io::read_gray_f32(dir.join(format!("gt/view_{i}.png"))).unwrap();
        let (mut inter, mut union) = (0, 0);
        for (&a, &g) in made.data.iter().zip(&gt.data) {
            inter += usize::from(a >= 0.5 && g >= 0.5);
            union += usize::from(a >= 0.5 || g >= 0.5);
        }
        let iou = inter as f64 / union as f64;
        assert!(iou > 0.9, "view_{i}: IoU {iou}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let stages: Vec<&str> = report["stages"].as_array().unwrap().iter().map(|s| s["stage"].as_str().unwrap()).collect();
    assert_eq!(stages, ["head", "masks"]);
    assert!(report["warnings"].as_array().is_none_or(|w| w.is_empty()), "{report:#}");
}
