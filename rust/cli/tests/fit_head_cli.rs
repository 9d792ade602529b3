//! `hairrecon fit-head` through the real binary, on a capture as an import leaves it: the bundled
//! head moved into another frame (scale 40, turned, offset) as the raw mesh, four cameras around
//! it, no head and no scalp. `--write` adds the fitted head and scalp, in the capture's frame,
//! and head_fit.json; a capture that has a scalp keeps it and gets the fitted one's distance to it.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::Scratch;

use glam::{DMat3, DVec3};
use hairrecon_core::capture::{CaptureSpec, ViewSpec};
use hairrecon_core::formats::{read_mesh, write_mesh};
use hairrecon_core::TriMesh;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hairrecon")
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new(&format!("fit-head-cli-{name}"))
}

/// The capture's frame: canonical → capture.
fn frame() -> (f64, DMat3, DVec3) {
    (40.0, DMat3::from_rotation_x(1.1) * DMat3::from_rotation_z(2.3), DVec3::new(3.0, -7.0, 11.0))
}

fn to_capture(mesh: &TriMesh) -> TriMesh {
    let (s, r, t) = frame();
    let mut m = mesh.clone();
    for v in &mut m.vertices {
        *v = (s * (r * v.as_dvec3()) + t).as_vec3();
    }
    m.normals = None;
    m
}

/// Writes the capture: raw mesh, four cameras 0.6 m (canonical) from the head looking at it.
fn capture(dir: &Path, with_scalp: bool) {
    write_mesh(dir.join("raw.ply"), &to_capture(&read_mesh(fixtures().join("head.ply")).unwrap())).unwrap();
    let (s, r, t) = frame();
    let views = (0..4)
        .map(|i| {
            let a = std::f64::consts::FRAC_PI_2 * i as f64 + 0.3;
            // Canonical camera: at 0.6 m on a ring, looking at the head; OpenCV axes (y down).
            let c = DVec3::new(0.6 * a.cos(), 0.6 * a.sin(), 0.05);
            let z = -c.normalize();
            let x = z.cross(DVec3::Z).normalize();
            let y = z.cross(x);
            let r_cam = DMat3::from_cols(x, y, z).transpose() * r.transpose();
            let centre = s * (r * c) + t;
            let tc = -(r_cam * centre);
            let rows = |m: DMat3| {
                let m = m.transpose();
                [m.x_axis, m.y_axis, m.z_axis].map(|v| v.as_vec3().to_array())
            };
            ViewSpec {
                name: format!("v{i}"),
                image: format!("v{i}.png").into(),
                mask: None,
                width: 400,
                height: 600,
                k: [[700.0, 0.0, 199.5], [0.0, 700.0, 299.5], [0.0, 0.0, 1.0]],
                r: rows(r_cam),
                t: tc.as_vec3().to_array(),
                gt_orientation: None,
                gt_depth: None,
                original: None,
            }
        })
        .collect();
    let mut spec = CaptureSpec {
        version: 1,
        units: "unknown".into(),
        frame: Some("imported".into()),
        convention: "opencv".into(),
        views,
        raw_mesh: "raw.ply".into(),
        head_mesh: None,
        scalp_mesh: None,
        gt_strands: None,
        to_canonical: None,
    };
    if with_scalp {
        write_mesh(dir.join("scalp.ply"), &to_capture(&read_mesh(fixtures().join("scalp.ply")).unwrap())).unwrap();
        spec.scalp_mesh = Some("scalp.ply".into());
    }
    spec.write(dir).unwrap();
}

fn fit_head(dir: &Path, write: bool) -> serde_json::Value {
    let mut cmd = Command::new(bin());
    cmd.arg("fit-head").arg(dir);
    if write {
        cmd.arg("--write");
    }
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn write_adds_the_fitted_head_and_scalp_in_the_captures_frame() {
    let dir = tmp("write");
    capture(&dir, false);
    let out = fit_head(&dir, true);
    let scale = out["to_canonical"]["scale"].as_f64().unwrap();
    assert!((scale * frame().0 - 1.0).abs() < 0.01, "scale {scale}");
    let spec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("capture.json")).unwrap()).unwrap();
    assert_eq!(spec["scalp_mesh"], "fitted_scalp.ply");
    assert_eq!(spec["head_mesh"], "fitted_head.ply");
    assert!(dir.join("head_fit.json").is_file());
    // The fitted scalp lies on the true one, in the capture's frame (40 units per metre).
    let truth = to_capture(&read_mesh(fixtures().join("scalp.ply")).unwrap());
    let fitted = read_mesh(dir.join("fitted_scalp.ply")).unwrap();
    let e = hairrecon_recon::head_fit::compare::surface_error(&fitted, &truth, 5000).unwrap();
    println!("fitted scalp: mean {:.3} mm, p95 {:.3} mm", e.mean / 40.0 * 1e3, e.p95 / 40.0 * 1e3);
    assert!(e.mean / 40.0 < 0.5e-3 && e.p95 / 40.0 < 1e-3, "{e:?}");
}

#[test]
fn a_capture_with_a_scalp_keeps_it_and_is_scored_against_it() {
    let dir = tmp("scored");
    capture(&dir, true);
    let before = std::fs::read(dir.join("capture.json")).unwrap();
    let out = fit_head(&dir, true);
    let e = &out["scalp_error_against_the_captures_scalp"];
    println!("{e}");
    assert!(e["mean_mm"].as_f64().unwrap() < 0.5 && e["p95_mm"].as_f64().unwrap() < 1.0, "{e}");
    let after: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("capture.json")).unwrap()).unwrap();
    assert_eq!(after["scalp_mesh"], "scalp.ply", "the user's scalp stays");
    assert_eq!(after["head_mesh"], "fitted_head.ply");
    assert_ne!(before, std::fs::read(dir.join("capture.json")).unwrap());
    assert!(!dir.join("fitted_scalp.ply").exists());
}

/// The capture's landmarks (landmarks.json beside capture.json, in its frame) start the fit of
/// `reconstruct`'s head stage, whose head_fit.json says how far they lie from the template's; a
/// file with the subject's sides swapped stops `fit-head --landmarks` with one error naming it.
#[test]
fn landmarks_beside_the_capture_start_reconstructs_head_fit() {
    use hairrecon_recon::head_fit::landmarks::bundled;
    let dir = tmp("landmarks");
    capture(&dir, false);
    let (s, r, t) = frame();
    let place = |p: DVec3| (s * (r * p) + t).to_array();
    let placed: serde_json::Map<String, serde_json::Value> =
        bundled().into_iter().map(|(n, p)| (n, serde_json::json!(place(p)))).collect();
    std::fs::write(dir.join("landmarks.json"), serde_json::Value::Object(placed.clone()).to_string()).unwrap();
    // reconstruct reads the photos as the capture loads (the fit itself reads none)
    for i in 0..4 {
        let grey = hairrecon_core::image_io::RgbImage32::new(400, 600, vec![0.5f32; 3 * 400 * 600]).unwrap();
        hairrecon_core::image_io::write_png8_rgb(dir.join(format!("v{i}.png")), &grey).unwrap();
    }
    let out = dir.join("out");
    let o = Command::new(bin())
        .args(["reconstruct", dir.to_str().unwrap(), "--out", out.to_str().unwrap(), "--stop-after", "head"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("head_fit.json")).unwrap()).unwrap();
    let lm = report["fit"]["landmarks_rms_mm"].as_f64().unwrap_or_else(|| panic!("{report}"));
    assert!(lm < 1.0, "{lm}");
    let each = report["fit"]["landmarks_mm"].as_object().unwrap_or_else(|| panic!("{report}"));
    assert_eq!(each.len(), 6, "{report}");
    assert!(each.values().all(|d| d.as_f64().is_some_and(|d| d < 1.5)), "{report}");
    assert!((report["fit"]["to_canonical"]["scale"].as_f64().unwrap() * s - 1.0).abs() < 0.01, "{report}");

    let mut swapped = placed.clone();
    swapped.insert("ear_left".into(), placed["ear_right"].clone());
    swapped.insert("ear_right".into(), placed["ear_left"].clone());
    swapped.insert("eye_outer_left".into(), placed["eye_outer_right"].clone());
    swapped.insert("eye_outer_right".into(), placed["eye_outer_left"].clone());
    let bad = dir.join("swapped.json");
    std::fs::write(&bad, serde_json::Value::Object(swapped).to_string()).unwrap();
    let o = Command::new(bin()).arg("fit-head").arg(&*dir).arg("--landmarks").arg(&bad).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && o.stdout.is_empty(), "{err}");
    assert!(err.contains("swapped.json") && err.contains("subject's own"), "{err}");
}
