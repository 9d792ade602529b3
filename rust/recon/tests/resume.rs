//! A run resumed from a saved stage (`--from`) or replayed from its `config.json` gives the same
//! bytes as one whole run, on the synthetic capture of `common/mod.rs`; resuming without the
//! earlier stages' files names the stage to run; an imported capture that no head fit can place
//! fails at stage `head`; views without masks get them from stage `masks`. A run owns its folder: what an earlier run left there is cleared, a cancelled run
//! leaves the stages it finished and nothing else, and a folder that is not a run's is refused.

use crate::common;

use hairrecon_core::capture::Capture;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use hairrecon_recon::progress::{NoProgress, Progress};
use hairrecon_recon::report::{Report, RunStatus};
use hairrecon_recon::{reconstruct, Plan, ReconError, ReconstructConfig, Stage};

fn capture(name: &str) -> Capture {
    let dir = std::env::temp_dir().join(format!("hairrecon-resume-{name}-{}", std::process::id()));
    common::write_capture(&dir, 600, 128, 7);
    Capture::load(&dir).unwrap()
}

/// Every file under `dir`, relative to it, sorted.
fn files_in(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if p.is_dir() {
            out.extend(files_in(&p).into_iter().map(|f| format!("{name}/{f}")));
        } else {
            out.push(name);
        }
    }
    out.sort();
    out
}

/// The files the folder's report lists, sorted.
fn listed(dir: &Path) -> Vec<String> {
    let mut files: Vec<String> = Report::load(dir).unwrap().files().map(String::from).collect();
    files.sort();
    files
}

/// Cancels the run when `stage` starts (the user's cancel in Blender, or SIGINT in the CLI).
struct CancelAt(&'static str, AtomicBool);

impl Progress for CancelAt {
    fn update(&self, stage: &str, _fraction: f32, _message: &str) {
        if stage == self.0 {
            self.1.store(true, Ordering::SeqCst);
        }
    }
    fn cancelled(&self) -> bool {
        self.1.load(Ordering::SeqCst)
    }
}

#[test]
fn a_resumed_or_replayed_run_gives_the_same_bytes_as_a_whole_run() {
    let cap = capture("resume");
    let mvs = hairrecon_recon::points3d::LineMvsParams { stride: 2, ..Default::default() };
    let mut cfg = ReconstructConfig { guides: 100, children: 600, mvs, seed: 3, ..Default::default() };
    (cfg.dr_options.iterations_guides, cfg.dr_options.iterations_children) = (6, 3);
    let run = |dir: &str, from: Stage, stop_after: Option<Stage>, cfg: &ReconstructConfig| {
        reconstruct(&cap, &cap.dir.join(dir), cfg, Plan { from, stop_after, overwrite: false }, &NoProgress)
    };
    let read = |dir: &str, f: &str| std::fs::read(cap.dir.join(dir).join(f)).unwrap();
    run("whole", Stage::Orient2d, None, &cfg).unwrap();
    // Stopped after the directions, then resumed at init.
    run("resumed", Stage::Orient2d, Some(Stage::Direction), &cfg).unwrap();
    assert!(!cap.dir.join("resumed/strands.hair").exists());
    let out = run("resumed", Stage::Init, None, &cfg).unwrap();
    let stages: Vec<Stage> = out.report.stages.iter().map(|s| s.stage).collect();
    // (The capture has its scalp, head and masks: stages head and masks have nothing to do.)
    let made: Vec<Stage> = Stage::ALL.into_iter().filter(|&s| s >= Stage::Orient2d).collect();
    assert_eq!(stages, made, "the resumed report keeps the earlier stages' records");
    // DR again on the whole run's init; and the whole run replayed from its config.json.
    run("whole", Stage::Dr, None, &cfg).unwrap();
    let file = hairrecon_recon::config::ConfigFile::load(&cap.dir.join("whole/config.json")).unwrap();
    assert_eq!(file.config, cfg);
    run("replayed", Stage::Orient2d, None, &file.config).unwrap();
    for f in ["strands.hair", "guides.hair", "init_strands.hair", "points_directed.ply"] {
        let whole = read("whole", f);
        assert!(whole.len() > 1000, "{f}");
        assert!(read("resumed", f) == whole, "{f}: --from init differs from the whole run");
        assert!(read("replayed", f) == whole, "{f}: --config differs from the whole run");
    }
    // A different seed must change the strands (the comparison above can fail).
    let other = ReconstructConfig { seed: 4, ..cfg.clone() };
    run("other", Stage::Init, None, &other).unwrap_err();
    run("other", Stage::Orient2d, None, &other).unwrap();
    assert!(read("other", "strands.hair") != read("whole", "strands.hair"));
    assert_eq!(files_in(&cap.dir.join("whole")), listed(&cap.dir.join("whole")));

    // `--stop-after orient2d` into the folder of a whole run leaves none of that run's files (nor the
    // map of a view the capture no longer has, nor the temporary file of a run killed outright).
    let whole = cap.dir.join("whole");
    std::fs::write(whole.join("orient2d/gone.exr"), b"x").unwrap();
    // (A process id above any Linux pid_max: no process has it.)
    std::fs::write(whole.join(".strands.hair.tmp-999999999-2"), b"x").unwrap();
    run("whole", Stage::Orient2d, Some(Stage::Orient2d), &cfg).unwrap();
    let files = files_in(&whole);
    assert_eq!(files, listed(&whole), "the folder holds exactly the files its report lists");
    assert!(files.contains(&"orient2d/maps.bin".to_string()) && !files.iter().any(|f| f.ends_with(".hair")));
    let report = Report::load(&whole).unwrap();
    assert_eq!((report.status, report.stages.len()), (RunStatus::Complete, 1));

    // A run cancelled when orient3d starts, in the folder of a whole run: the orient2d it finished,
    // nothing of the earlier run, no temporary file; the report says so.
    let replayed = cap.dir.join("replayed");
    let cancel = CancelAt("orient3d", AtomicBool::new(false));
    let e = reconstruct(&cap, &replayed, &cfg, Plan::default(), &cancel).unwrap_err();
    assert!(matches!(e, ReconError::Cancelled(_)), "{e}");
    let files = files_in(&replayed);
    assert_eq!(files, listed(&replayed));
    assert!(!files.iter().any(|f| f.ends_with(".hair") || f.ends_with(".ply")), "{files:?}");
    let report = Report::load(&replayed).unwrap();
    assert_eq!(report.status, RunStatus::Cancelled);
    assert_eq!(report.stages.iter().map(|s| s.stage).collect::<Vec<_>>(), [Stage::Orient2d]);
    assert!(report.scores.init_strands.is_none() && report.scores.dr_strands.is_none());
    // ... and it resumes from there.
    run("replayed", Stage::Orient3d, Some(Stage::Orient3d), &cfg).unwrap();
    assert!(read("replayed", "points3d.ply") == read("resumed", "points3d.ply"));
    let _ = std::fs::remove_dir_all(&cap.dir);
}

#[test]
fn a_folder_that_is_not_a_runs_is_refused_unless_overwrite_is_given() {
    let cap = capture("foreign");
    let out_dir = cap.dir.join("documents");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("notes.txt"), b"mine").unwrap();
    let plan = |overwrite| Plan { stop_after: Some(Stage::Orient2d), overwrite, ..Default::default() };
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), plan(false), &NoProgress).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ReconError::ForeignOutDir { .. }), "{msg}");
    assert!(msg.contains("notes.txt") && msg.contains("--overwrite"), "{msg}");
    assert_eq!(files_in(&out_dir), ["notes.txt"], "a refused run wrote or removed something");
    reconstruct(&cap, &out_dir, &ReconstructConfig::default(), plan(true), &NoProgress).unwrap();
    assert_eq!(std::fs::read(out_dir.join("notes.txt")).unwrap(), b"mine");
    // Now a run's folder: the next run clears only the files its report lists, and only inside it.
    let mut report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("report.json")).unwrap()).unwrap();
    report["stages"][0]["files"].as_array_mut().unwrap().push("../capture.json".into());
    std::fs::write(out_dir.join("report.json"), report.to_string()).unwrap();
    reconstruct(&cap, &out_dir, &ReconstructConfig::default(), plan(false), &NoProgress).unwrap();
    assert!(cap.dir.join("capture.json").exists() && out_dir.join("notes.txt").exists());
    // Resuming the run of another capture would mix the two.
    let mut report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("report.json")).unwrap()).unwrap();
    report["capture"] = out_dir.display().to_string().into();
    std::fs::write(out_dir.join("report.json"), report.to_string()).unwrap();
    let resume = Plan { from: Stage::Orient3d, stop_after: Some(Stage::Orient3d), overwrite: false };
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), resume, &NoProgress).unwrap_err();
    assert!(matches!(e, ReconError::OtherCapture { .. }) && e.to_string().contains("mix"), "{e}");
    let _ = std::fs::remove_dir_all(&cap.dir);
}

#[test]
fn resuming_without_the_earlier_stages_names_the_stage_to_run() {
    let cap = capture("missing");
    let out_dir = cap.dir.join("out");
    let e = reconstruct(
        &cap,
        &out_dir,
        &ReconstructConfig::default(),
        Plan { from: Stage::Init, ..Default::default() },
        &NoProgress,
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ReconError::MissingStageOutput { needs: Stage::Orient2d, .. }), "{msg}");
    assert!(msg.contains("maps.bin") && msg.contains("--from orient2d"), "{msg}");
    let plan = Plan { from: Stage::Dr, stop_after: Some(Stage::Init), overwrite: false };
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), plan, &NoProgress).unwrap_err();
    assert!(matches!(e, ReconError::EmptyPlan { .. }), "{e}");
    let _ = std::fs::remove_dir_all(&cap.dir);
}

#[test]
fn an_imported_capture_that_no_head_fit_can_place_fails_at_stage_head() {
    // The capture's raw mesh is a sphere with hair on it: no face for the head template to fit.
    let mut cap = capture("imported");
    cap.frame = hairrecon_core::capture::Frame::Imported;
    cap.units = hairrecon_core::capture::Units::Unknown;
    let out_dir = cap.dir.join("out");
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), Plan::default(), &NoProgress).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ReconError::HeadFit(_)), "{msg}");
    assert!(msg.contains("raw_mesh.ply") && msg.contains("fit-head") && msg.contains("to_canonical"), "{msg}");
    let report = Report::load(&out_dir).unwrap();
    assert_eq!((report.status, report.stages.len()), (RunStatus::Failed, 0));
    assert_eq!(files_in(&out_dir), ["config.json", "report.json"], "a failed fit leaves no fitted file");
    // Centimetres in the canonical frame need the fit too (the reconstruction works in metres).
    cap.frame = hairrecon_core::capture::Frame::Canonical;
    cap.units = hairrecon_core::capture::Units::parse("cm").unwrap();
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), Plan::default(), &NoProgress).unwrap_err();
    assert!(matches!(e, ReconError::HeadFit(_)), "{e}");
    // Resuming after stage head needs what it saved.
    let plan = Plan { from: Stage::Orient2d, ..Plan::default() };
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), plan, &NoProgress).unwrap_err();
    assert!(matches!(e, ReconError::MissingStageOutput { needs: Stage::Head, .. }), "{e}");
    let _ = std::fs::remove_dir_all(&cap.dir);
}

#[test]
fn meshes_in_other_units_or_frames_are_refused_before_anything_is_written() {
    use hairrecon_core::formats::{read_mesh, write_mesh};
    let cap = capture("units");
    let out_dir = cap.dir.join("out");
    let run = |cap: &Capture| reconstruct(cap, &out_dir, &ReconstructConfig::default(), Plan::default(), &NoProgress);
    let refused = |cap: &Capture, what: &str, words: &[&str]| {
        let e = run(cap).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, ReconError::Implausible { .. }), "{msg}");
        assert!(msg.contains(what) && words.iter().all(|w| msg.contains(w)), "{msg}");
        assert!(!out_dir.exists(), "a refused run created {}", out_dir.display());
    };
    let raw = read_mesh(&cap.raw_mesh).unwrap();
    let scalp = read_mesh(cap.scalp_mesh.as_ref().unwrap()).unwrap();
    let mm = glam::Affine3A::from_scale(glam::Vec3::splat(1000.0));
    // The raw mesh in millimetres.
    let mut c = cap.clone();
    c.raw_mesh = cap.dir.join("raw_mm.ply");
    write_mesh(&c.raw_mesh, &raw.transformed(mm)).unwrap();
    refused(&c, "raw_mm.ply", &["in metres"]);
    // One triangle.
    let one = hairrecon_core::mesh::TriMesh::new(raw.vertices.clone(), vec![raw.triangles[0]], None, None).unwrap();
    write_mesh(&c.raw_mesh, &one).unwrap();
    refused(&c, "raw_mm.ply", &["1 triangles"]);
    // The scalp in millimetres, and the scalp somewhere else.
    let mut c = cap.clone();
    c.scalp_mesh = Some(cap.dir.join("scalp_mm.ply"));
    write_mesh(c.scalp_mesh.as_ref().unwrap(), &scalp.transformed(mm)).unwrap();
    refused(&c, "scalp_mm.ply", &["in metres"]);
    let away = glam::Affine3A::from_translation(glam::Vec3::new(0.0, 0.0, 2.0));
    write_mesh(c.scalp_mesh.as_ref().unwrap(), &scalp.transformed(away)).unwrap();
    refused(&c, "scalp_mm.ply", &["outside the raw mesh"]);
    // Cameras that see nothing of the mesh: the mesh moved 10 m away.
    let mut c = cap.clone();
    c.raw_mesh = cap.dir.join("raw_far.ply");
    c.scalp_mesh = None;
    write_mesh(&c.raw_mesh, &raw.transformed(glam::Affine3A::from_translation(glam::Vec3::new(10.0, 0.0, 0.0))))
        .unwrap();
    refused(&c, "the cameras", &["same frame"]);
    let _ = std::fs::remove_dir_all(&cap.dir);
}

#[test]
fn masks_without_hair_stop_at_the_stage_that_finds_no_points() {
    let cap = capture("black");
    for v in &cap.views {
        let m = v.mask.as_ref().expect("the synthetic capture has masks");
        let (w, h) = (v.camera.width(), v.camera.height());
        hairrecon_core::image_io::write_png8_gray(m, &hairrecon_core::image_io::GrayImage32::filled(w, h, 0.0))
            .unwrap();
    }
    let out_dir = cap.dir.join("out");
    let e = reconstruct(&cap, &out_dir, &ReconstructConfig::default(), Plan::default(), &NoProgress).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ReconError::EmptyStage { stage: Stage::Orient3d, .. }), "{msg}");
    assert!(msg.contains("orient3d") && msg.contains("masks"), "{msg}");
    assert!(!out_dir.join("strands.hair").exists());
    let _ = std::fs::remove_dir_all(&cap.dir);
}

/// The capture of `capture(name)` moved into another frame (a photogrammetry tool's: scale 40,
/// turned, offset; units unknown), with `to_canonical` as head fitting writes it.
fn imported(name: &str) -> (Capture, hairrecon_core::similarity::Similarity) {
    use glam::{DMat3, DVec3};
    use hairrecon_core::capture::{CaptureSpec, FrameSpec};
    use hairrecon_core::formats::{read_mesh, read_strands, write_mesh, write_strands};
    use hairrecon_core::similarity::{transform_camera, transform_mesh, transform_strands, Similarity};
    let canonical = capture(name);
    let dir =
        canonical.dir.with_file_name(format!("{}-imported", canonical.dir.file_name().unwrap().to_string_lossy()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("gt")).unwrap();
    let to_file = Similarity {
        scale: 40.0,
        rotation: DMat3::from_euler(glam::EulerRot::ZXY, 2.1, -0.6, 0.4),
        translation: DVec3::new(7.0, -3.0, 25.0),
    };
    let json = canonical.dir.join("capture.json");
    let mut spec: CaptureSpec = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for m in ["raw_mesh.ply", "head.ply", "scalp.ply"] {
        write_mesh(dir.join(m), &transform_mesh(&read_mesh(canonical.dir.join(m)).unwrap(), &to_file)).unwrap();
    }
    let gt = read_strands(canonical.dir.join("gt/strands.hair")).unwrap();
    write_strands(dir.join("gt/strands.hair"), &transform_strands(&gt, &to_file).unwrap()).unwrap();
    for (v, view) in spec.views.iter_mut().zip(&canonical.views) {
        let cam = transform_camera(&view.camera, &to_file).unwrap();
        (v.r, v.t) = (cam.r_rows(), cam.t().to_array());
        v.gt_orientation = None;
        for f in [&v.image, v.mask.as_ref().unwrap()] {
            std::fs::create_dir_all(dir.join(f).parent().unwrap()).unwrap();
            std::fs::copy(canonical.dir.join(f), dir.join(f)).unwrap();
        }
    }
    spec.units = "unknown".into();
    spec.frame = Some("imported".into());
    spec.to_canonical = Some(FrameSpec::of(&to_file.inverse()));
    spec.write(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&canonical.dir);
    (Capture::load(&dir).unwrap(), to_file)
}

#[test]
fn an_imported_capture_with_its_frame_runs_in_the_canonical_one_and_writes_in_its_own() {
    let (cap, to_file) = imported("frame");
    let canonical_cap = capture("frame-canonical");
    let mvs = hairrecon_recon::points3d::LineMvsParams { stride: 2, ..Default::default() };
    let cfg = ReconstructConfig { guides: 100, children: 600, mvs, seed: 3, dr: false, ..Default::default() };
    let plan = Plan::default();
    let ours = reconstruct(&cap, &cap.dir.join("out"), &cfg, plan, &NoProgress).unwrap();
    let theirs = reconstruct(&canonical_cap, &canonical_cap.dir.join("out"), &cfg, plan, &NoProgress).unwrap();
    // Scored in the canonical frame (millimetres), as the same capture in metres is.
    let f1 = |r: &Report| r.scores.init_strands.as_ref().unwrap().undirected[1].f1;
    let (a, b) = (f1(&ours.report), f1(&theirs.report));
    println!("F1 at 2 mm: imported {a:.2}, canonical {b:.2}");
    assert!((a - b).abs() < 1.0, "imported {a:.2} against canonical {b:.2}");
    // strands.hair and init_strands.hair are in the capture's own frame: back in the canonical one
    // they lie on the canonical run's strands.
    for (a, b) in [(ours.strands, theirs.strands), (ours.init_strands, theirs.init_strands)] {
        let (a, b) = (a.unwrap(), b.unwrap());
        let strands = hairrecon_core::read_strands(&a).unwrap();
        let back = hairrecon_core::similarity::transform_strands(&strands, &to_file.inverse()).unwrap();
        let reference = hairrecon_core::read_strands(&b).unwrap();
        let opts = hairrecon_core::metric::MetricOptions::default();
        let m = hairrecon_core::metric::evaluate(&back, &reference, &opts).unwrap();
        println!("imported run's {} against the canonical run's: {m:?}", a.display());
        assert!(m.undirected[0].f1 > 90.0, "{}: {m:?}", a.display());
    }
    for c in [&cap, &canonical_cap] {
        let _ = std::fs::remove_dir_all(&c.dir);
    }
}

#[test]
fn views_without_masks_get_masks_from_stage_masks_or_a_warning() {
    let mut cap = capture("unmasked");
    let plan = Plan { stop_after: Some(Stage::Orient2d), ..Plan::default() };
    let no_masks = ReconstructConfig { make_masks: false, ..ReconstructConfig::default() };
    let masked = reconstruct(&cap, &cap.dir.join("masked"), &no_masks, plan, &NoProgress).unwrap();
    assert!(masked.report.warnings.is_empty(), "{:?}", masked.report.warnings);
    let n = cap.views.len();
    let given: Vec<_> = cap.views.iter().map(|v| v.mask.clone().unwrap()).collect();
    for v in cap.views.iter_mut().skip(1).step_by(2) {
        v.mask = None;
    }
    // Without stage masks: a warning names the views.
    let out_dir = cap.dir.join("unmasked");
    let run = reconstruct(&cap, &out_dir, &no_masks, plan, &NoProgress).unwrap();
    let w = run.report.warnings.join("\n");
    assert!(w.contains(&format!("{} of {n} views have no hair mask (first: {})", n / 2, cap.views[1].name)), "{w}");
    assert!(w.contains("hairrecon masks") && w.contains("--write"), "{w}");
    // The report on disk says the same.
    assert_eq!(Report::load(&out_dir).unwrap().warnings, run.report.warnings);

    // With it: masks for those views only, close to the ones the capture had.
    let cfg = ReconstructConfig::default();
    let plan = Plan { stop_after: Some(Stage::Masks), ..Plan::default() };
    let run = reconstruct(&cap, &out_dir, &cfg, plan, &NoProgress).unwrap();
    assert!(run.report.warnings.is_empty(), "{:?}", run.report.warnings);
    assert_eq!(run.report.stages.iter().map(|s| s.stage).collect::<Vec<_>>(), [Stage::Masks]);
    let mut expected: Vec<String> =
        cap.views.iter().skip(1).step_by(2).map(|v| format!("masks/{}.png", v.name)).collect();
    expected.extend(["config.json", "hair_region.ply", "masks.json", "report.json"].map(String::from));
    expected.sort();
    assert_eq!(files_in(&out_dir), expected);
    for (v, truth) in cap.views.iter().zip(&given).skip(1).step_by(2) {
        let made = hairrecon_core::image_io::read_gray_f32(out_dir.join(format!("masks/{}.png", v.name))).unwrap();
        let truth = hairrecon_core::image_io::read_gray_f32(truth).unwrap();
        let s = hairrecon_recon::masks::quality::score(&made, &truth);
        assert!(s.iou > 0.8, "view {}: {s:?}", v.name);
    }
    // A resumed run reads them; without them it names the stage to run.
    let plan = Plan { from: Stage::Orient2d, stop_after: Some(Stage::Orient2d), ..Plan::default() };
    let run = reconstruct(&cap, &out_dir, &cfg, plan, &NoProgress).unwrap();
    assert!(run.report.warnings.is_empty(), "{:?}", run.report.warnings);
    std::fs::remove_file(out_dir.join(format!("masks/{}.png", cap.views[1].name))).unwrap();
    let e = reconstruct(&cap, &out_dir, &cfg, plan, &NoProgress).unwrap_err();
    assert!(matches!(e, ReconError::MissingStageOutput { needs: Stage::Masks, .. }), "{e}");

    // Without a head, the masks need the head fit; where it fails (the capture's raw mesh is a
    // sphere with hair, no face) the run goes on without masks and says why.
    cap.head_mesh = None;
    let plan = Plan { stop_after: Some(Stage::Orient2d), ..Plan::default() };
    let run = reconstruct(&cap, &cap.dir.join("headless"), &cfg, plan, &NoProgress).unwrap();
    let w = run.report.warnings.join("\n");
    assert!(w.contains("no hair masks were made: the head fit") && w.contains("have no hair mask"), "{w}");
    assert_eq!(run.report.stages.iter().map(|s| s.stage).collect::<Vec<_>>(), [Stage::Orient2d]);
    let _ = std::fs::remove_dir_all(&cap.dir);
}
