//! Every way a calibration file can be wrong gives its own error, and every message names the file.

use std::path::{Path, PathBuf};

use hairrecon_import::colmap::write_binary;
use hairrecon_import::{read_colmap, read_metashape, read_nerf, ImportError};
use hairrecon_import::{Distortion, Intrinsics, Scene, SceneView, Units};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-err-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

/// A two-view scene (for binary files to damage).
fn small_scene() -> Scene {
    let view = |i: usize| SceneView {
        name: format!("v{i}.png"),
        image: PathBuf::from(format!("v{i}.png")),
        width: 64,
        height: 48,
        intrinsics: Intrinsics { fx: 50.0, fy: 50.0, cx: 31.5, cy: 23.5, skew: 0.0 },
        distortion: Distortion::default(),
        r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        t: [i as f64, 0.0, 3.0],
    };
    Scene { views: vec![view(0), view(1)], points: vec![[0.0; 3]; 3], units: Units::Unknown, warnings: vec![] }
}

/// A text model with these cameras and images lines.
fn text_model(name: &str, cameras: &str, images: &str) -> PathBuf {
    let dir = tmpdir(name);
    write(&dir.join("cameras.txt"), cameras);
    write(&dir.join("images.txt"), images);
    dir
}

fn message_names(e: &ImportError, file: &str) {
    let m = e.to_string();
    assert!(m.contains(file), "the message does not name {file}: {m}");
}

#[test]
fn colmap_missing_files() {
    let dir = tmpdir("missing");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::MissingFile { .. }), "{e}");
    message_names(&e, &dir.display().to_string());
    assert!(e.to_string().contains("cameras.bin") && e.to_string().contains("none of them"), "{e}");

    write_binary(&dir, &small_scene()).unwrap();
    std::fs::remove_file(dir.join("cameras.bin")).unwrap();
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::MissingFile { .. }), "{e}");
    assert!(e.to_string().contains("only images.bin, points3D.bin"), "{e}");

    let e = read_colmap(&dir.join("nope")).unwrap_err();
    assert!(matches!(e, ImportError::MissingFile { .. }) && e.to_string().contains("does not exist"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn colmap_truncated_and_corrupt_binary() {
    let dir = tmpdir("truncated");
    write_binary(&dir, &small_scene()).unwrap();
    let full = std::fs::read(dir.join("cameras.bin")).unwrap();
    std::fs::write(dir.join("cameras.bin"), &full[..full.len() - 5]).unwrap();
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::Truncated { .. }), "{e}");
    message_names(&e, "cameras.bin");
    assert!(e.to_string().contains("byte"), "{e}");
    std::fs::write(dir.join("cameras.bin"), &full[..3]).unwrap();
    assert!(matches!(read_colmap(&dir).unwrap_err(), ImportError::Truncated { .. }));
    std::fs::write(dir.join("cameras.bin"), &full).unwrap();

    // A count far larger than the file.
    let mut images = std::fs::read(dir.join("images.bin")).unwrap();
    images[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(dir.join("images.bin"), &images).unwrap();
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::Binary { .. }), "{e}");
    message_names(&e, "images.bin");

    // Bytes after the last point.
    write_binary(&dir, &small_scene()).unwrap();
    let mut points = std::fs::read(dir.join("points3D.bin")).unwrap();
    points.extend([0u8; 7]);
    std::fs::write(dir.join("points3D.bin"), &points).unwrap();
    let e = read_colmap(&dir).unwrap_err();
    message_names(&e, "points3D.bin");

    // A fisheye camera (model id 5) in cameras.bin.
    write_binary(&dir, &small_scene()).unwrap();
    let mut b = Vec::new();
    b.extend(1u64.to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.extend(5i32.to_le_bytes());
    b.extend(64u64.to_le_bytes());
    b.extend(48u64.to_le_bytes());
    for _ in 0..8 {
        b.extend(1.0f64.to_le_bytes());
    }
    std::fs::write(dir.join("cameras.bin"), &b).unwrap();
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::UnsupportedModel { .. }), "{e}");
    message_names(&e, "cameras.bin");
    assert!(e.to_string().contains("OPENCV_FISHEYE"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn colmap_unsupported_model() {
    let dir =
        text_model("fisheye", "7 OPENCV_FISHEYE 640 480 500 500 320 240 0.1 0 0 0\n", "1 1 0 0 0 0 0 5 7 a.jpg\n\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::UnsupportedModel { .. }), "{e}");
    let m = e.to_string();
    for part in ["cameras.txt", "camera 7", "OPENCV_FISHEYE", "SIMPLE_PINHOLE, PINHOLE", "FULL_OPENCV"] {
        assert!(m.contains(part), "{part:?} not in {m}");
    }
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = text_model("unknown-model", "7 WEIRD 640 480 1\n", "");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::UnsupportedModel { .. }) && e.to_string().contains("WEIRD"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn colmap_duplicate_names() {
    let cams = "1 PINHOLE 640 480 500 500 320 240\n";
    let dir = text_model("dup", cams, "1 1 0 0 0 0 0 5 1 left/img.png\n\n2 1 0 0 0 1 0 5 1 right/img.png\n\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::DuplicateImage { ref name, .. } if name == "img.png"), "{e}");
    message_names(&e, "images.txt");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn colmap_bad_poses_and_lines() {
    let cams = "1 PINHOLE 640 480 500 500 320 240\n";
    let dir = text_model("nan", cams, "1 nan 0 0 0 0 0 5 1 a.png\n\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::BadPose { .. }), "{e}");
    message_names(&e, "images.txt");
    assert!(e.to_string().contains("NaN pose") && e.to_string().contains("a.png"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = text_model("zero-q", cams, "1 0 0 0 0 0 0 5 1 a.png\n\n");
    assert!(read_colmap(&dir).unwrap_err().to_string().contains("zero norm"));
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = text_model("bad-number", cams, "# c\n1 1 0 0 zero 0 0 5 1 a.png\n\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::Parse { line: 2, .. }), "{e}");
    assert!(e.to_string().contains("images.txt, line 2") && e.to_string().contains("QZ"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = text_model("params", "1 PINHOLE 640 480 500 500 320\n", "");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::Parse { line: 1, .. }) && e.to_string().contains("cameras.txt"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = text_model("unknown-camera", cams, "1 1 0 0 0 0 0 5 2 a.png\n\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::UnknownCamera { .. }), "{e}");
    message_names(&e, "images.txt");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn colmap_no_views() {
    let dir = text_model("empty", "1 PINHOLE 640 480 500 500 320 240\n", "# Image list\n# Number of images: 0\n");
    let e = read_colmap(&dir).unwrap_err();
    assert!(matches!(e, ImportError::NoViews { .. }), "{e}");
    message_names(&e, "images.txt");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn metashape_errors() {
    let dir = tmpdir("metashape");
    let path = dir.join("cameras.xml");
    write(&path, "<document><chunk><sensors>\n<sensor></chunk></document>");
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, ImportError::Parse { .. }), "{e}");
    message_names(&e, "cameras.xml");

    let sensor = r#"<sensors><sensor id="0" type="frame"><resolution width="10" height="10"/>
        <calibration type="frame" class="adjusted"><f>10</f></calibration></sensor></sensors>"#;
    write(
        &path,
        &format!(
            r#"<document><chunk>{sensor}<cameras><camera id="0" sensor_id="0" label="a.jpg"/></cameras></chunk></document>"#
        ),
    );
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, ImportError::NoViews { .. }), "{e}");
    message_names(&e, "cameras.xml");

    let scaled = "2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1";
    write(
        &path,
        &format!(
            r#"<document><chunk>{sensor}<cameras><camera id="0" sensor_id="0" label="a.jpg"><transform>{scaled}</transform></camera></cameras></chunk></document>"#
        ),
    );
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, ImportError::BadPose { .. }) && e.to_string().contains("not orthonormal"), "{e}");
    message_names(&e, "cameras.xml");

    let ok = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    write(
        &path,
        &format!(
            r#"<document><chunk>{sensor}<cameras><camera id="0" sensor_id="0" label="d/a.jpg"><transform>{ok}</transform></camera>
            <camera id="1" sensor_id="0" label="e/a.jpg"><transform>{ok}</transform></camera></cameras></chunk></document>"#
        ),
    );
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, ImportError::DuplicateImage { .. }), "{e}");

    write(
        &path,
        &format!(
            r#"<document><chunk>{sensor}<cameras><camera id="0" sensor_id="3" label="a.jpg"><transform>{ok}</transform></camera></cameras></chunk></document>"#
        ),
    );
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, ImportError::Parse { line: 2, .. }) && e.to_string().contains("sensor 3"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nerf_errors() {
    let dir = tmpdir("nerf");
    let path = dir.join("transforms.json");
    let identity = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
    write(&path, &format!(r#"{{"fl_x": 100, "frames": [{{"file_path": "a.png", "transform_matrix": {identity}}}]}}"#));
    let e = read_nerf(&path).unwrap_err();
    assert!(matches!(e, ImportError::Invalid { .. }), "{e}");
    message_names(&e, "transforms.json");
    assert!(e.to_string().contains("\"w\"") && e.to_string().contains("a.png"), "{e}");

    let head = r#""w": 64, "h": 48, "fl_x": 100"#;
    write(
        &path,
        &format!(
            r#"{{{head}, "camera_model": "OPENCV_FISHEYE", "frames": [{{"file_path": "a.png", "transform_matrix": {identity}}}]}}"#
        ),
    );
    let e = read_nerf(&path).unwrap_err();
    assert!(matches!(e, ImportError::UnsupportedModel { .. }) && e.to_string().contains("OPENCV_FISHEYE"), "{e}");
    message_names(&e, "transforms.json");

    write(
        &path,
        &format!(
            r#"{{{head}, "frames": [{{"file_path": "a.png", "transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}}]}}"#
        ),
    );
    let e = read_nerf(&path).unwrap_err();
    assert!(matches!(e, ImportError::BadPose { .. }), "{e}");
    message_names(&e, "transforms.json");

    write(&path, &format!(r#"{{{head}, "frames": []}}"#));
    let e = read_nerf(&path).unwrap_err();
    assert!(matches!(e, ImportError::NoViews { .. }), "{e}");
    message_names(&e, "transforms.json");

    write(&path, "{\n\"frames\": [,]}");
    let e = read_nerf(&path).unwrap_err();
    assert!(matches!(e, ImportError::Parse { line: 2, .. }), "{e}");
    message_names(&e, "transforms.json");
    std::fs::remove_dir_all(&dir).unwrap();
}
