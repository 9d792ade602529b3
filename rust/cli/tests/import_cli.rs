//! `hairrecon import` through the real binary: a small COLMAP model with JPEG photos becomes a
//! capture in the model's own frame, on which `reconstruct` fits the head first (and, the mesh being
//! one triangle, fails there with one clear line); bad inputs are one line naming the file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hairrecon_import::{colmap, pose, Distortion, Intrinsics, Scene, SceneView, Units};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hairrecon")
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Three 300x200 JPEG photos, their COLMAP text model (k1 only, written as OPENCV; in a frame 40 units across)
/// and a one-triangle PLY.
fn inputs(dir: &Path) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::create_dir_all(dir.join("sparse")).unwrap();
    let mut views = Vec::new();
    for i in 0..3 {
        let name = format!("P{i}.jpg");
        image::RgbImage::from_fn(300, 200, |x, y| image::Rgb([x as u8, y as u8, 90]))
            .save(dir.join("images").join(&name))
            .unwrap();
        let a = i as f64;
        let c = [20.0 * a.cos(), 20.0 * a.sin(), 3.0];
        let z = [-a.cos(), -a.sin(), 0.0];
        let r = [[-z[1], z[0], 0.0], [0.0, 0.0, -1.0], z];
        views.push(SceneView {
            name: name.clone(),
            image: name.into(),
            width: 300,
            height: 200,
            intrinsics: Intrinsics { fx: 280.0, fy: 280.0, cx: 149.5, cy: 99.5, skew: 0.0 },
            distortion: Distortion { k: [0.01, 0.0, 0.0, 0.0], ..Default::default() },
            r,
            t: pose::translation(&r, &c),
        });
    }
    let scene = Scene { views, points: Vec::new(), units: Units::Unknown, warnings: Vec::new() };
    colmap::write_text(&dir.join("sparse"), &scene).unwrap();
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    std::fs::write(dir.join("mesh.ply"), ply).unwrap();
}

fn import(dir: &Path, extra: &[&str]) -> Output {
    let mut cmd = Command::new(bin());
    cmd.args(["import", "colmap"]).arg(dir.join("sparse")).arg("--images").arg(dir.join("images"));
    cmd.arg("--mesh").arg(dir.join("mesh.ply")).arg("--out").arg(dir.join("capture")).args(extra);
    cmd.output().unwrap()
}

/// The one error line of a failed run.
fn error_line(out: &Output) -> String {
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected: {err}");
    assert!(lines[0].starts_with("hairrecon: error: "), "{err}");
    lines[0].to_string()
}

#[test]
fn a_colmap_model_imports_and_reconstruct_refuses_its_frame() {
    let dir = tmp("ok");
    inputs(&dir);
    let out = import(&dir, &["--height", "100"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json = dir.join("capture/capture.json");
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), json.display().to_string());
    let spec: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!((spec["units"].as_str(), spec["frame"].as_str()), (Some("unknown"), Some("imported")));
    let v = &spec["views"][1];
    assert_eq!((v["name"].as_str(), v["width"].as_u64(), v["height"].as_u64()), (Some("P1"), Some(150), Some(100)));
    // fx scales by 1/2; cx = 0.5 (149.5 + 0.5) - 0.5
    assert_eq!((v["K"][0][0].as_f64(), v["K"][0][2].as_f64()), (Some(140.0), Some(74.5)));
    assert!(dir.join("capture/images/P1.png").is_file() && dir.join("capture/raw_mesh.ply").is_file());
    // The capture is in COLMAP's frame: reconstruct fits the head first, which a one-triangle mesh
    // cannot give; the error (the last line, after the stage's progress) names the mesh and what to do.
    let rec = Command::new(bin())
        .arg("reconstruct")
        .arg(dir.join("capture"))
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(!rec.status.success());
    let err = String::from_utf8_lossy(&rec.stderr).into_owned();
    let line = err.lines().rfind(|l| !l.trim().is_empty()).unwrap_or_default();
    assert!(line.starts_with("hairrecon: error: the head fit: "), "{err}");
    assert!(line.contains("raw_mesh.ply") && line.contains("to_canonical") && line.contains("fit-head"), "{line}");
    assert!(!dir.join("out/fitted_scalp.ply").exists() && !dir.join("out/strands.hair").exists());
    // Importing again over the capture is refused.
    let line = error_line(&import(&dir, &[]));
    assert!(line.contains("not empty"), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_inputs_are_one_line_naming_the_file() {
    let dir = tmp("bad");
    inputs(&dir);
    std::fs::remove_file(dir.join("images/P2.jpg")).unwrap();
    let line = error_line(&import(&dir, &[]));
    assert!(line.contains("P2.jpg") && line.contains("does not exist"), "{line}");
    let cameras = dir.join("sparse/cameras.txt");
    let text = std::fs::read_to_string(&cameras).unwrap();
    std::fs::write(&cameras, text.replace(" OPENCV ", " OPENCV_FISHEYE ")).unwrap();
    let line = error_line(&import(&dir, &[]));
    assert!(line.contains("cameras.txt") && line.contains("OPENCV_FISHEYE"), "{line}");
    std::fs::remove_file(&cameras).unwrap();
    let line = error_line(&import(&dir, &[]));
    assert!(line.contains("cameras"), "{line}");
    assert!(!dir.join("capture").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
