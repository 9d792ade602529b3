//! Tests of the capture folder: its schema, its checks and its errors.

use super::*;

fn write_png(path: &Path, w: u32, h: u32) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::RgbImage::new(w, h).save(path).unwrap();
}

fn spec() -> CaptureSpec {
    CaptureSpec {
        version: 1,
        units: "metres".into(),
        frame: None,
        convention: "opencv".into(),
        views: vec![ViewSpec {
            name: "v0".into(),
            image: "images/v0.png".into(),
            mask: Some("masks/v0.png".into()),
            width: 4,
            height: 6,
            k: [[10.0, 0.0, 1.5], [0.0, 10.0, 2.5], [0.0, 0.0, 1.0]],
            r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            t: [0.0, 0.0, 1.0],
            gt_orientation: None,
            gt_depth: None,
            original: None,
        }],
        raw_mesh: "raw_mesh.ply".into(),
        head_mesh: None,
        scalp_mesh: None,
        gt_strands: None,
        to_canonical: None,
    }
}

fn setup(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hairrecon-capture-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    write_png(&dir.join("images/v0.png"), 4, 6);
    write_png(&dir.join("masks/v0.png"), 4, 6);
    std::fs::write(dir.join("raw_mesh.ply"), b"ply\n").unwrap();
    dir
}

fn load(dir: &Path, s: &CaptureSpec) -> Result<Capture, CaptureError> {
    std::fs::write(dir.join("capture.json"), serde_json::to_string_pretty(s).unwrap()).unwrap();
    Capture::load(dir)
}

#[test]
fn loads_a_valid_capture_and_names_each_problem() {
    let dir = setup("valid");
    let c = load(&dir, &spec()).unwrap();
    assert_eq!(c.views.len(), 1);
    assert_eq!(c.views[0].camera.width(), 4);

    let mut s = spec();
    s.views[0].width = 5;
    let e = load(&dir, &s).unwrap_err().to_string();
    assert!(e.contains("\"v0\"") && e.contains("v0.png") && e.contains("4x6"), "{e}");

    let mut s = spec();
    s.views[0].mask = Some("masks/missing.png".into());
    let e = load(&dir, &s).unwrap_err().to_string();
    assert!(e.contains("mask") && e.contains("missing.png"), "{e}");

    let mut s = spec();
    s.views[0].r[0][0] = 0.5;
    let e = load(&dir, &s).unwrap_err().to_string();
    assert!(e.contains("\"v0\"") && e.contains("rotation"), "{e}");

    let mut s = spec();
    s.views[0].k[1][1] = 0.0;
    assert!(matches!(load(&dir, &s), Err(CaptureError::Camera { .. })));

    let mut s = spec();
    s.units = "cubits".into();
    assert!(matches!(load(&dir, &s), Err(CaptureError::Units { .. })));
    s.units = "millimetres".into();
    s.frame = Some("imported".into());
    let c = load(&dir, &s).unwrap();
    assert_eq!(
        (c.units.clone(), c.frame),
        (Units::Named { name: "millimetres".into(), metres: 0.001 }, Frame::Imported)
    );
    assert!(!c.is_canonical());
    s.frame = Some("y-up".into());
    assert!(matches!(load(&dir, &s), Err(CaptureError::Frame { .. })));

    // Paths stay inside the folder unless allowed: `a/../b` is inside, `../x` and `/x` are not.
    let mut s = spec();
    s.views[0].image = "images/../images/v0.png".into();
    load(&dir, &s).unwrap();
    let name = format!("outside-{}.png", std::process::id());
    let outside = dir.join("..").join(&name);
    write_png(&outside, 4, 6);
    for bad in [PathBuf::from("images/../..").join(&name), outside.canonicalize().unwrap()] {
        s.views[0].image = bad.clone();
        let e = load(&dir, &s).unwrap_err();
        assert!(matches!(e, CaptureError::OutsidePath { .. }), "{bad:?}: {e}");
        assert!(e.to_string().contains("\"v0\": image") && e.to_string().contains("outside"), "{e}");
        assert!(Capture::load_allowing_outside_paths(&dir).is_ok(), "{bad:?}");
    }
    let mut s = spec();
    s.raw_mesh = "../raw_mesh.ply".into();
    assert!(matches!(load(&dir, &s), Err(CaptureError::OutsidePath { .. })));
    let _ = std::fs::remove_file(outside);

    // Files where a file belongs, and a capture where a capture belongs: a folder or a pipe as an
    // image, a folder without capture.json, a strand file given as the capture.
    let mut s = spec();
    std::fs::create_dir_all(dir.join("images/folder.png")).unwrap();
    s.views[0].image = "images/folder.png".into();
    let e = load(&dir, &s).unwrap_err().to_string();
    assert!(e.contains("folder.png is a folder, not a file"), "{e}");
    let fifo = dir.join("images/pipe.png");
    if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
        s.views[0].image = "images/pipe.png".into();
        let e = load(&dir, &s).unwrap_err().to_string();
        assert!(e.contains("pipe.png is not a regular file"), "{e}");
    }
    let e = Capture::load(dir.join("images")).unwrap_err().to_string();
    assert!(e.contains("is not a capture") && e.contains("holds no capture.json"), "{e}");
    std::fs::write(dir.join("strands.hair"), b"HAIR\x02\x00\x00\x00\xff\xfe").unwrap();
    let e = Capture::load(dir.join("strands.hair")).unwrap_err().to_string();
    assert!(e.contains("strands.hair is not a capture") && e.contains("binary file"), "{e}");

    // NaN cannot be written as JSON; a null where a number belongs is a parse error.
    std::fs::write(dir.join("capture.json"), "{\"version\": 1, \"views\": [}").unwrap();
    assert!(matches!(Capture::load(&dir), Err(CaptureError::Json { .. })));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_written_spec_loads_to_the_same_values() {
    let dir = setup("write");
    let mut s = spec();
    // Values that f32 cannot hold exactly: they must come back bit for bit.
    s.views[0].k = [[512.3456, 0.0, 1.5], [0.0, 512.3456, 2.5], [0.0, 0.0, 1.0]];
    let (c, sn) = (0.6f32.cos(), 0.6f32.sin());
    s.views[0].r = [[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]];
    s.views[0].t = [0.1, -0.2, 1.0 / 3.0];
    s.views[0].gt_depth = Some("gt/depth/v0.exr".into());
    std::fs::create_dir_all(dir.join("gt/depth")).unwrap();
    std::fs::write(dir.join("gt/depth/v0.exr"), b"x").unwrap();
    s.head_mesh = Some("raw_mesh.ply".into());
    let written = s.write(&dir).unwrap();
    assert_eq!(written, dir.join("capture.json"));
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.ends_with("}\n") && text.contains("\"K\": ["), "{text}");
    assert!(!text.contains("scalp_mesh") && !text.contains("\"mask\": null"), "absent fields are left out: {text}");
    // The file parses back to the same spec, strictly and leniently.
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(CaptureSpec::from_json(value, &written).unwrap(), s);
    let c = Capture::load(&dir).unwrap();
    let v = &c.views[0];
    assert_eq!(v.name, "v0");
    assert_eq!(v.image, dir.join("images/v0.png"));
    assert_eq!(v.mask.as_deref(), Some(dir.join("masks/v0.png").as_path()));
    assert_eq!(v.gt_depth.as_deref(), Some(dir.join("gt/depth/v0.exr").as_path()));
    assert_eq!(v.gt_orientation, None);
    assert_eq!(v.camera, Camera::new(s.views[0].k, s.views[0].r, s.views[0].t, 4, 6).unwrap());
    assert_eq!((v.camera.width(), v.camera.height()), (4, 6));
    assert_eq!(c.head_mesh.as_deref(), Some(dir.join("raw_mesh.ply").as_path()));
    assert_eq!(c.scalp_mesh, None);
    // A .json path is the file itself; a missing folder is created.
    let other = dir.join("sub/other.json");
    assert_eq!(s.write(&other).unwrap(), other);
    assert!(other.is_file());
    assert_eq!(s.write(dir.join("new")).unwrap(), dir.join("new/capture.json"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_spec_is_rejected_and_nothing_is_written() {
    let dir = std::env::temp_dir().join(format!("hairrecon-capture-test-badwrite-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let json = dir.join("capture.json");
    let write = |s: &CaptureSpec| {
        let e = s.write(&dir).unwrap_err();
        assert!(!json.exists(), "a rejected spec left {}", json.display());
        e
    };

    let mut s = spec();
    s.views[0].image = PathBuf::new();
    let e = write(&s);
    assert!(matches!(e, CaptureError::EmptyPath { .. }), "{e}");
    assert!(e.to_string().contains("view \"v0\": its image is empty"), "{e}");

    let mut s = spec();
    s.views[0].k[0][2] = f32::NAN;
    let e = write(&s);
    assert!(matches!(e, CaptureError::Camera { source: CameraError::NotFinite("K"), .. }), "{e}");
    assert!(e.to_string().contains("\"v0\"") && e.to_string().contains("non-finite value in K"), "{e}");

    let mut s = spec();
    s.views.push(s.views[0].clone());
    assert!(matches!(write(&s), CaptureError::DuplicateView { .. }));
    // A view name becomes an output file name: nothing may reach outside the output folder.
    for bad in ["", ".", "..", "../../other/images/y", "/tmp/x", "a\\b", "v\n0"] {
        let mut s = spec();
        s.views[0].name = bad.into();
        let e = write(&s);
        assert!(matches!(e, CaptureError::BadViewName { .. }), "{bad:?}: {e}");
    }
    for good in ["IMG_0001.JPG", "view 3", "cam-2.left", "Camera (1)", "caméra_é"] {
        let mut s = spec();
        s.views[0].name = good.into();
        assert!(s.validate(&json).is_ok(), "{good:?}");
    }
    let mut s = spec();
    s.views.clear();
    assert!(matches!(write(&s), CaptureError::NoViews { .. }));
    let mut s = spec();
    s.version = 2;
    assert!(matches!(write(&s), CaptureError::Version { found: 2, .. }));
    let mut s = spec();
    s.convention = "opengl".into();
    assert!(matches!(write(&s), CaptureError::Convention { .. }));
    let mut s = spec();
    s.raw_mesh = PathBuf::new();
    assert!(write(&s).to_string().contains("raw_mesh is empty"));

    // Parsed JSON: the error names the view and the field.
    let good = serde_json::to_value(spec()).unwrap();
    let mut v = good.clone();
    v["views"][0].as_object_mut().unwrap().remove("image");
    let e = CaptureSpec::from_json(v, &json).unwrap_err().to_string();
    assert!(e.contains("views[0] \"v0\"") && e.contains("missing field `image`"), "{e}");
    let mut v = good.clone();
    v["views"][0]["K"] = serde_json::json!([[1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let e = CaptureSpec::from_json(v, &json).unwrap_err().to_string();
    assert!(e.contains("views[0] \"v0\""), "{e}");
    let mut v = good.clone();
    v["gt_strand"] = serde_json::json!("gt/strands.hair");
    let e = CaptureSpec::from_json(v, &json).unwrap_err().to_string();
    assert!(e.contains("unknown field \"gt_strand\""), "{e}");
    let mut v = good.clone();
    v["views"][0]["masks"] = serde_json::json!("m.png");
    let e = CaptureSpec::from_json(v, &json).unwrap_err().to_string();
    assert!(e.contains("views[0] \"v0\": unknown field \"masks\""), "{e}");
    let e = CaptureSpec::from_json(serde_json::json!([1]), &json).unwrap_err().to_string();
    assert!(e.contains("must be a JSON object, not a list"), "{e}");
    // A null optional field is the field left out.
    let mut v = good.clone();
    v["head_mesh"] = serde_json::Value::Null;
    assert_eq!(CaptureSpec::from_json(v, &json).unwrap(), spec());
    assert!(!dir.exists());
}
