//! `hairrecon reconstruct` through the real binary on a small synthetic capture (the one of
//! `rust/recon/tests/common`): the DR flags parse and reach the pipeline's options, bad values
//! give one clear error, `--no-dr` writes the same strands as `--stop-after init`, and a DR run
//! keeps those as `init_strands.hair` beside its own `strands.hair`, `loss.csv` and `loss.png`.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hairrecon")
}

fn run(args: &[&str], dirs: &[&Path]) -> Output {
    let mut c = Command::new(bin());
    c.arg("reconstruct");
    for d in dirs {
        c.arg(d);
    }
    c.args(args).output().unwrap()
}

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-reconstruct-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn dr_flags_reach_the_options() {
    let cap = Path::new("unused-capture");
    let out = Path::new("unused-out");
    let flags = [
        "--out",
        "unused-out",
        "--print-config",
        "--no-guide-opt",
        "--no-reparam",
        "--no-neighbor-reparam",
        "--dr-iters-guides",
        "7",
        "--dr-iters-children",
        "3",
        "--dr-lr",
        "0.004",
        "--dr-views",
        "6",
        "--dr-lambda",
        "5",
        "--dr-width-mm",
        "0.5",
        "--dr-stride",
        "3",
        "--dr-guide-downsample",
        "4",
        "--dr-guide-stride",
        "5",
        "--seed",
        "9",
    ];
    let cfg = |args: &[&str]| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_str(&ok(&run(args, &[cap]))).unwrap();
        v["config"].clone()
    };
    let c = cfg(&flags);
    let d = &c["dr_options"];
    assert_eq!(c["dr"], true);
    assert_eq!((d["iterations_guides"].as_u64(), d["iterations_children"].as_u64()), (Some(7), Some(3)));
    assert_eq!(
        (d["lr"].as_f64(), d["lambda"].as_f64(), d["views_per_step"].as_u64()),
        (Some(0.004), Some(5.0), Some(6))
    );
    assert_eq!((&d["reparam"], &d["neighbor_reparam"], &d["guide_opt"]), (&false.into(), &false.into(), &false.into()));
    assert_eq!((d["width_m"].as_f64(), d["seed"].as_u64(), c["seed"].as_u64()), (Some(0.0005), Some(9), Some(9)));
    assert_eq!(
        (d["stride"].as_u64(), d["guide_downsample"].as_u64(), d["guide_stride"].as_u64()),
        (Some(3), Some(4), Some(5))
    );
    assert!(!out.exists(), "--print-config must not run anything");
    // The defaults: DR on, every part of it on.
    let c = cfg(&["--out", "unused-out", "--print-config"]);
    let d = &c["dr_options"];
    assert!(c["dr"] == true && d["reparam"] == true && d["neighbor_reparam"] == true && d["guide_opt"] == true, "{c}");
    assert_eq!(d["stride"].as_u64(), Some(3), "DR moves every third point by default");
    assert_eq!(d["cg_tolerance"].as_f64().map(|t| t as f32), Some(1e-2), "the solves stop at 1e-2");
    assert_eq!(
        (d["guide_stride"].as_u64(), d["guide_downsample"].as_u64()),
        (Some(4), Some(2)),
        "the guide stage on every fourth point, at half the image size"
    );
    assert_eq!(c["curl"], "Auto");
    assert_eq!(cfg(&["--out", "unused-out", "--print-config", "--curl", "off"])["curl"], "Off");
    let fixed = &cfg(&["--out", "unused-out", "--print-config", "--curl", "6.5,22,-1"])["curl"]["Fixed"];
    assert_eq!(
        (fixed["radius"].as_f64(), fixed["period"].as_f64(), fixed["hand"].as_f64()),
        (Some(0.0065), Some(0.022), Some(-1.0))
    );
    assert_eq!(cfg(&["--out", "unused-out", "--print-config", "--no-dr", "--stop-after", "dr"])["dr"], false);
    // --config starts from a file; the flags given override it.
    let dir = tmp("config");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("c.json");
    std::fs::write(&file, r#"{"guides": 77, "children": 88, "dr": false}"#).unwrap();
    let c = cfg(&["--out", "unused-out", "--print-config", "--config", file.to_str().unwrap(), "--children", "99"]);
    assert_eq!((c["guides"].as_u64(), c["children"].as_u64(), &c["dr"]), (Some(77), Some(99), &false.into()));
    std::fs::write(&file, r#"{"guides": 77, "colour": 1}"#).unwrap();
    let o = run(&["--out", "unused-out", "--print-config", "--config", file.to_str().unwrap()], &[cap]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(1) && err.contains("colour") && err.contains("c.json"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
    // Bad values: one line on stderr, exit code 1.
    for (flag, value, words) in [
        ("--dr-lr", "0", "--dr-lr must be a positive number"),
        ("--dr-views", "0", "--dr-views must be at least 1"),
        ("--dr-stride", "0", "--dr-stride must be at least 1"),
        ("--dr-guide-downsample", "0", "--dr-guide-downsample must be at least 1"),
        ("--dr-guide-stride", "0", "--dr-guide-stride must be at least 1"),
        ("--dr-width-mm", "0", "--dr-width-mm must be a positive number"),
        ("--stop-after", "paint", "use one of head, masks, orient2d, orient3d, partings, direction, init, dr"),
        ("--from", "paint", "use one of head, masks, orient2d, orient3d, partings, direction, init, dr"),
        ("--curl", "tight", "give off, auto, RADIUS_MM,PERIOD_MM,HAND (e.g. 6.5,22,1) or fine:RADIUS_MM"),
        ("--curl", "6.5,22", "give three numbers"),
        ("--curl", "6.5,22,2", "give 1 (right) or -1 (left)"),
    ] {
        let o = run(&["--out", "unused-out", "--print-config", flag, value], &[cap]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{flag} {value}: {err}");
        assert!(err.contains(words) && err.trim().lines().count() == 1, "{flag} {value}: {err}");
    }
}

#[test]
fn no_dr_equals_stop_after_init_and_dr_keeps_it_as_init() {
    let dir = tmp("runs");
    let cap = common::write_capture(&dir.join("capture"), 600, 128, 3);
    let small = ["--guides", "60", "--children", "400"];
    let (a, b, c) = (dir.join("no_dr"), dir.join("init"), dir.join("dr"));
    let text_a = ok(&run(&[&small[..], &["--out", a.to_str().unwrap(), "--no-dr"]].concat(), &[&cap]));
    ok(&run(&[&small[..], &["--out", b.to_str().unwrap(), "--stop-after", "init"]].concat(), &[&cap]));
    let text_c = ok(&run(
        &[&small[..], &["--out", c.to_str().unwrap(), "--dr-iters-guides", "4", "--dr-iters-children", "2"]].concat(),
        &[&cap],
    ));
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    for f in ["strands.hair", "guides.hair"] {
        assert!(read(a.join(f)) == read(b.join(f)), "{f}: --no-dr and --stop-after init differ");
    }
    assert!(read(c.join("init_strands.hair")) == read(a.join("strands.hair")), "DR's init_strands.hair differs");
    assert!(read(c.join("init_guides.hair")) == read(a.join("guides.hair")), "DR's init_guides.hair differs");
    assert!(read(c.join("strands.hair")) != read(a.join("strands.hair")), "DR did not move the strands");
    // The init stage saves its strands whatever follows (so that `--from dr` can resume); without
    // DR they are the result too.
    assert!(read(a.join("init_strands.hair")) == read(a.join("strands.hair")), "--no-dr: init differs from result");
    for f in ["loss.csv", "loss.png"] {
        assert!(!a.join(f).exists(), "--no-dr wrote {f}");
    }
    let csv = String::from_utf8(read(c.join("loss.csv"))).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4 + 2, "{csv}");
    // Printed: stage times with DR's, and the metric table before and after DR.
    assert!(!text_a.contains("after DR") && text_a.contains("strands before DR (init)"), "{text_a}");
    for want in ["stage times:", "dr ", "strands before DR (init)", "strands after DR", "undirected", "2mm/20°"] {
        assert!(text_c.contains(want), "{want:?} not in\n{text_c}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--curl`: on this straight synthetic capture `auto` finds no curls (the ringlet axes hang less
/// than the points' own directions) and writes the same strands as `off`; a fixed curl grows along
/// the ringlet axes (saved as `points_axes.ply`), sweeps helices of that radius and records it.
#[test]
fn curl_auto_keeps_straight_hair_and_a_fixed_curl_makes_helices() {
    let dir = tmp("curl");
    let cap = common::write_capture(&dir.join("capture"), 600, 128, 3);
    let small = ["--guides", "60", "--children", "400", "--stop-after", "init"];
    let (a, b, c) = (dir.join("auto"), dir.join("off"), dir.join("fixed"));
    ok(&run(&[&small[..], &["--out", a.to_str().unwrap()]].concat(), &[&cap]));
    ok(&run(&[&small[..], &["--out", b.to_str().unwrap(), "--curl", "off"]].concat(), &[&cap]));
    ok(&run(&[&small[..], &["--out", c.to_str().unwrap(), "--curl", "6.5,22,1"]].concat(), &[&cap]));
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let json = |p: PathBuf| -> serde_json::Value { serde_json::from_slice(&read(p)).unwrap() };
    let init_stats = |d: &Path| json(d.join("report.json"))["stages"][4]["stats"].clone();
    let auto = &init_stats(&a)["curl_auto"];
    let nominal = &auto["pitches"][0];
    assert!(nominal["pitch_deg"].as_f64() == Some(60.0), "{auto}");
    assert!(auto["down_tangents"].as_f64().unwrap() > nominal["down_right"].as_f64().unwrap(), "{auto}");
    assert!(auto["pitch_deg"].is_null(), "{auto}");
    assert!(json(a.join("init.json"))["curl"].is_null() && !a.join("points_axes.ply").exists());
    assert!(read(a.join("strands.hair")) == read(b.join("strands.hair")), "auto changed straight hair");
    let curl = &json(c.join("init.json"))["curl"];
    assert!((curl["radius"].as_f64().unwrap() - 0.0065).abs() < 1e-7, "{curl}");
    assert!(c.join("points_axes.ply").exists());
    assert!(read(c.join("strands.hair")) != read(b.join("strands.hair")));
    let _ = std::fs::remove_dir_all(&dir);
}
