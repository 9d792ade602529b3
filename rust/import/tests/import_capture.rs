//! The whole import, calibration + photos + mesh to a capture folder: a textured plane photographed
//! through distorted cameras (OPENCV k1 = -0.1, k2 = 0.02, p1 = p2 = 1e-3), calibrated as a
//! COLMAP model, imported at half height. The capture's pinhole cameras must project like the
//! original cameras without distortion, scaled (1e-3 px), and its undistorted working photos must
//! match the plane seen by those pinhole cameras (under 1 grey level on average). Bad inputs and a
//! cancel leave no folder behind. And the same capture through every format (COLMAP text and
//! binary, Metashape XML, transforms.json) in random similarity frames (scale 0.013 to 87): the
//! written capture.json's cameras project the raw mesh's vertices within 1e-3 px of the original
//! cameras, scaled.

use std::path::{Path, PathBuf};

use hairrecon_core::capture::{Capture, Frame, Units};
use hairrecon_core::image_io::read_rgb_f32;
use hairrecon_import::colmap::{write_binary, write_text};
use hairrecon_import::metashape::write_xml;
use hairrecon_import::nerf::write_transforms;
use hairrecon_import::photo::Prefer;
use hairrecon_import::pose::Similarity;
use hairrecon_import::{
    import_capture, pose, Distortion, Error, Intrinsics, Scene, SceneView, Source, WriteError, WriteOptions,
};

const W: u32 = 640;
const H: u32 = 480;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-e2e-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The plane z = 0's grey value at (x, y): smooth, so bilinear sampling is accurate.
fn pattern(x: f64, y: f64) -> f64 {
    0.5 + 0.3 * (2.5 * x).sin() * (1.7 * y + 0.3).cos() + 0.1 * (0.9 * x - 1.3 * y).sin()
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / n)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Four cameras above the plane looking at its centre.
fn scene() -> Scene {
    let distortion = Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] };
    let views = (0..4)
        .map(|i| {
            let a = i as f64 * std::f64::consts::FRAC_PI_2 + 0.3;
            let c = [2.0 * a.cos(), 2.0 * a.sin(), 2.5];
            let z = normalize(c.map(|v| -v));
            let x = normalize(cross(z, [0.0, 0.0, 1.0]));
            let r = [x, cross(z, x), z];
            SceneView {
                name: format!("IMG_{i:04}.png"),
                image: PathBuf::from(format!("IMG_{i:04}.png")),
                width: W,
                height: H,
                intrinsics: Intrinsics { fx: 520.0, fy: 515.0, cx: 322.3, cy: 236.8, skew: 0.0 },
                distortion,
                r,
                t: pose::translation(&r, &c),
            }
        })
        .collect();
    Scene { views, points: Vec::new(), units: Units::Unknown, warnings: Vec::new() }
}

/// The plane's value seen through pixel (u, v) of a camera (pixel centres at integers): the
/// pixel's ray, undistorted when `distortion` (with its valid radius) is given, meets z = 0.
fn seen(v: &SceneView, k: &Intrinsics, distortion: Option<(&Distortion, f64)>, u: f64, w: f64) -> f64 {
    let (yd, xd) = ((w - k.cy) / k.fy, (u - k.cx) / k.fx);
    let (x, y) = match distortion {
        Some((d, radius)) => d.undistort_within(xd, yd, radius).expect("inside the model's valid radius"),
        None => (xd, yd),
    };
    let r = &v.r;
    let d = [0, 1, 2].map(|j| r[0][j] * x + r[1][j] * y + r[2][j]);
    let c = pose::centre(&v.r, &v.t);
    let s = -c[2] / d[2];
    pattern(c[0] + s * d[0], c[1] + s * d[1])
}

/// Writes the photos, a quad mesh (OBJ, one four-sided face) and the COLMAP model.
fn write_inputs(dir: &Path, scene: &Scene) -> (PathBuf, PathBuf, PathBuf) {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for v in &scene.views {
        let radius = v.distortion.valid_radius();
        let img = image::RgbImage::from_fn(W, H, |x, y| {
            let g = seen(v, &v.intrinsics, Some((&v.distortion, radius)), x as f64, y as f64);
            image::Rgb([(g * 255.0).round().clamp(0.0, 255.0) as u8; 3])
        });
        img.save(images.join(&v.image)).unwrap();
    }
    let mesh = dir.join("mesh.obj");
    std::fs::write(&mesh, "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n").unwrap();
    let sparse = dir.join("sparse");
    std::fs::create_dir_all(&sparse).unwrap();
    write_text(&sparse, scene).unwrap();
    (sparse, images, mesh)
}

fn options(images: &Path, mesh: &Path) -> WriteOptions {
    WriteOptions { images: images.into(), mesh: mesh.into(), height: 240, prefer: Prefer::Stored }
}

#[test]
fn an_imported_colmap_capture_projects_and_looks_like_the_pinhole_cameras() {
    let dir = tmpdir("ok");
    let scene = scene();
    let (sparse, images, mesh) = write_inputs(&dir, &scene);
    let out = dir.join("capture");
    let imported = import_capture(&Source::Colmap(sparse), &options(&images, &mesh), &out, &|_, _| true).unwrap();
    assert_eq!(imported.capture_json, out.join("capture.json"));
    let cap = Capture::load(&out).unwrap();
    assert_eq!((cap.units.clone(), cap.frame), (Units::Unknown, Frame::Imported));
    assert_eq!(cap.views.len(), 4);
    let mut worst_px = 0.0f64;
    let mut worst_grey = 0.0f64;
    for (v, cv) in scene.views.iter().zip(&cap.views) {
        assert_eq!(cv.name, v.name.trim_end_matches(".png"));
        assert_eq!((cv.camera.width(), cv.camera.height()), (320, 240));
        // Geometry: the capture camera = the original pinhole camera scaled by 1/2.
        for p in [[-1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [0.3, -0.4, 0.0], [0.0, 0.0, 0.2]] {
            let undistorted = SceneView { distortion: Distortion::default(), ..v.clone() };
            let [u, w] = undistorted.project(p).unwrap();
            let expected = [0.5 * (u + 0.5) - 0.5, 0.5 * (w + 0.5) - 0.5];
            let got = cv.camera.project(glam::Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)).unwrap().pixel;
            worst_px = worst_px.max((got.x as f64 - expected[0]).abs()).max((got.y as f64 - expected[1]).abs());
        }
        // Pixels: the working copy against the plane seen by the capture's pinhole camera.
        let img = read_rgb_f32(&cv.image).unwrap();
        let k = cv.camera.k();
        let k = Intrinsics {
            fx: k.x_axis.x as f64,
            fy: k.y_axis.y as f64,
            cx: k.z_axis.x as f64,
            cy: k.z_axis.y as f64,
            skew: 0.0,
        };
        let (mut sum, mut n) = (0.0, 0);
        for y in 8..img.height - 8 {
            for x in 8..img.width - 8 {
                let expected = seen(v, &k, None, x as f64, y as f64);
                sum += (img.get(x, y)[0] as f64 - expected).abs() * 255.0;
                n += 1;
            }
        }
        worst_grey = worst_grey.max(sum / n as f64);
    }
    println!("worst reprojection {worst_px:.2e} px, worst mean difference {worst_grey:.3} grey levels");
    assert!(worst_px < 1e-3, "{worst_px}");
    assert!(worst_grey < 1.0, "{worst_grey}");
    // Without undistortion the comparison fails: the check can see distortion.
    let raw = read_rgb_f32(images.join("IMG_0000.png")).unwrap();
    let v = &scene.views[0];
    let pinhole_full = (0..H).step_by(2).flat_map(|y| (0..W).step_by(2).map(move |x| (x, y)));
    let off: f64 = pinhole_full
        .map(|(x, y)| (raw.get(x, y)[0] as f64 - seen(v, &v.intrinsics, None, x as f64, y as f64)).abs() * 255.0)
        .sum::<f64>()
        / (W * H / 4) as f64;
    assert!(off > 3.0, "the distortion changes the photo by only {off} grey levels");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes `scene` as `format` under `dir`; returns the source to import.
fn export(format: &str, dir: &Path, scene: &Scene) -> Source {
    std::fs::create_dir_all(dir).unwrap();
    match format {
        "colmap-text" => {
            write_text(dir, scene).unwrap();
            Source::Colmap(dir.into())
        }
        "colmap-binary" => {
            write_binary(dir, scene).unwrap();
            Source::Colmap(dir.into())
        }
        "metashape" => {
            write_xml(&dir.join("cameras.xml"), scene).unwrap();
            Source::Metashape(dir.join("cameras.xml"))
        }
        _ => {
            write_transforms(&dir.join("transforms.json"), scene).unwrap();
            Source::Nerf(dir.join("transforms.json"))
        }
    }
}

#[test]
fn every_format_in_any_frame_imports_to_the_same_cameras() {
    let dir = tmpdir("frames");
    let scene = scene();
    let (_, images, _) = write_inputs(&dir, &scene);
    let corners = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let frames = [
        Similarity::IDENTITY,
        Similarity {
            rotation: pose::rotation_from_quaternion([0.3, -0.5, 0.7, 0.2]).unwrap(),
            translation: [40.0, -7.0, 300.0],
            scale: 87.0,
        },
        Similarity {
            rotation: pose::rotation_from_quaternion([-0.9, 0.1, 0.2, 0.4]).unwrap(),
            translation: [0.02, 0.5, -0.1],
            scale: 0.013,
        },
    ];
    let mut worst = 0.0f64;
    for (f, frame) in frames.iter().enumerate() {
        let moved = Scene { points: corners.to_vec(), ..scene.clone() }.transformed(frame);
        let mesh = dir.join(format!("mesh_{f}.obj"));
        let obj: String = moved.points.iter().map(|p| format!("v {} {} {}\n", p[0], p[1], p[2])).collect();
        std::fs::write(&mesh, obj + "f 1 2 3 4\n").unwrap();
        for format in ["colmap-text", "colmap-binary", "metashape", "nerf"] {
            let source = export(format, &dir.join(format!("{format}_{f}")), &moved);
            let out = dir.join(format!("capture_{format}_{f}"));
            import_capture(&source, &options(&images, &mesh), &out, &|_, _| true).unwrap();
            let cap = Capture::load(&out).unwrap();
            let raw = hairrecon_core::formats::read_mesh(&cap.raw_mesh).unwrap();
            for (v, cv) in scene.views.iter().zip(&cap.views) {
                let pinhole = SceneView { distortion: Distortion::default(), ..v.clone() };
                for (p, q) in corners.iter().zip(&raw.vertices) {
                    let [u, w] = pinhole.project(*p).unwrap();
                    let got = cv.camera.project(*q).unwrap().pixel;
                    let err = (got.x as f64 - (0.5 * (u + 0.5) - 0.5))
                        .abs()
                        .max((got.y as f64 - (0.5 * (w + 0.5) - 0.5)).abs());
                    assert!(err < 1e-3, "{format} in frame {f}: view {} is off by {err} px", cv.name);
                    worst = worst.max(err);
                }
            }
        }
    }
    println!("worst reprojection of the raw mesh over 4 formats x 3 frames: {worst:.2e} px");
    let _ = std::fs::remove_dir_all(&dir);
}

/// True when `dir` holds nothing but the given names (no capture, no staging folder left).
fn only(dir: &Path, names: &[&str]) -> bool {
    std::fs::read_dir(dir).unwrap().all(|e| names.contains(&e.unwrap().file_name().to_str().unwrap()))
}

#[test]
fn bad_inputs_and_a_cancel_leave_no_capture_behind() {
    let dir = tmpdir("bad");
    let scene = scene();
    let (sparse, images, mesh) = write_inputs(&dir, &scene);
    let inputs = ["images", "mesh.obj", "sparse", "flat.ply", "taken", "IMG_0002.png"];
    let source = Source::Colmap(sparse);
    let out = dir.join("capture");
    // A photo missing: the error names the view and the file.
    std::fs::rename(images.join("IMG_0002.png"), dir.join("IMG_0002.png")).unwrap();
    let e = import_capture(&source, &options(&images, &mesh), &out, &|_, _| true).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, Error::Write(WriteError::Photo { .. })), "{msg}");
    assert!(msg.contains("IMG_0002") && msg.contains("does not exist"), "{msg}");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(only(&dir, &inputs) && !out.exists(), "a failed import left files: {left:?}");
    std::fs::rename(dir.join("IMG_0002.png"), images.join("IMG_0002.png")).unwrap();
    // A mesh without faces.
    let flat = dir.join("flat.ply");
    std::fs::write(&flat, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    let e = import_capture(&source, &options(&images, &flat), &out, &|_, _| true).unwrap_err();
    assert!(matches!(e, Error::Write(WriteError::Mesh(_))) && e.to_string().contains("flat.ply"), "{e}");
    assert!(only(&dir, &inputs));
    // An output folder that holds files is refused.
    let taken = dir.join("taken");
    std::fs::create_dir_all(&taken).unwrap();
    std::fs::write(taken.join("keep.txt"), "mine").unwrap();
    let e = import_capture(&source, &options(&images, &mesh), &taken, &|_, _| true).unwrap_err();
    assert!(matches!(e, Error::Write(WriteError::OutExists { .. })), "{e}");
    assert_eq!(std::fs::read_to_string(taken.join("keep.txt")).unwrap(), "mine");
    // A cancel after the first photo.
    let e = import_capture(&source, &options(&images, &mesh), &out, &|done, _| done < 1).unwrap_err();
    assert!(matches!(e, Error::Write(WriteError::Cancelled)), "{e}");
    assert!(only(&dir, &inputs) && !out.exists(), "a cancelled import left files");
    let _ = std::fs::remove_dir_all(&dir);
}
