//! The whole pipeline with its DR stage on the synthetic capture of `common/mod.rs` (sphere head,
//! 16 views): the acceptance for simulation-ready output (no strand point inside the head,
//! every root within 0.5 mm of the scalp, even segment lengths), DR's gain in strand F1 over the
//! initial strands, the files of the DR stage, and a run cancelled during DR writing no strands.
//! The floors are measured values less a margin (see the comments). The capture's masks are the
//! strands' alpha (a matte, as a renderer gives it) and DR renders strands 1 mm wide, about as wide
//! as the capture's painted strands; with the dilated binary masks of `pipeline_synthetic.rs` and
//! 0.2 mm strands, DR lowered F1 from 75.1 to 70.6 (the silhouette loss spreads the strands to fill
//! the dilated mask).

use crate::common;

use std::sync::atomic::{AtomicBool, Ordering};

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::Bvh;
use hairrecon_recon::dr::DrOptions;
use hairrecon_recon::progress::{NoProgress, Progress};
use hairrecon_recon::{reconstruct, Plan, ReconError, ReconstructConfig};

fn capture(name: &str, n_strands: usize, size: u32) -> Capture {
    let dir = std::env::temp_dir().join(format!("hairrecon-dr-{name}-{}", std::process::id()));
    common::write_capture_with(&dir, n_strands, size, 7, true);
    Capture::load(&dir).unwrap()
}

fn f1_2mm(m: &serde_json::Value, key: &str, mode: &str) -> f64 {
    m[key][mode][1]["f1"].as_f64().unwrap_or_else(|| panic!("no {key}/{mode} in {m:#}"))
}

fn options() -> ReconstructConfig {
    // Every second pixel in the line MVS keeps the test fast (as in pipeline_synthetic.rs).
    let mvs = hairrecon_recon::points3d::LineMvsParams { stride: 2, ..Default::default() };
    ReconstructConfig {
        guides: 400,
        children: 4000,
        mvs,
        // Strands 1 mm wide: the capture's painted strands are about a pixel (1.3 mm) wide.
        dr_options: DrOptions { iterations_guides: 60, iterations_children: 30, width_m: 0.001, ..Default::default() },
        ..Default::default()
    }
}

#[test]
fn dr_output_is_simulation_ready_and_better_than_init() {
    let cap = capture("full", 1500, 256);
    let out_dir = cap.dir.join("out");
    let out = reconstruct(&cap, &out_dir, &options(), Plan::default(), &NoProgress).unwrap();
    let m = &serde_json::to_value(&out.report.scores).unwrap();
    println!("{:?}", out.report.stage_times());
    println!("dr stats {}", out.report.stages.last().unwrap().stats);
    assert_eq!(out.report.stage_times().last().unwrap().0, "dr");
    for f in ["strands.hair", "guides.hair", "init_strands.hair", "init_guides.hair", "loss.csv", "loss.png"] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
    assert_eq!(out.strands.as_deref(), Some(out_dir.join("strands.hair").as_path()));
    assert_eq!(out.init_strands.as_deref(), Some(out_dir.join("init_strands.hair").as_path()));
    let csv = std::fs::read_to_string(out_dir.join("loss.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], hairrecon_recon::dr::report::CSV_HEADER);
    assert_eq!(rows.len(), 1 + 60 + 30);
    assert!(rows[1].starts_with("guides,0,") && rows[61].starts_with("children,0,"));

    // DR's gain in strand F1 (2 mm/20°) over the initial strands.
    let (i_d, d_d) = (f1_2mm(m, "init_strands", "directed"), f1_2mm(m, "dr_strands", "directed"));
    let (i_u, d_u) = (f1_2mm(m, "init_strands", "undirected"), f1_2mm(m, "dr_strands", "undirected"));
    println!("strand F1 at 2 mm/20°: directed {i_d:.1} -> {d_d:.1}, undirected {i_u:.1} -> {d_u:.1}");

    // Simulation-ready output.
    let strands = read_strands(out_dir.join("strands.hair")).unwrap();
    let head = Bvh::new(read_mesh(cap.head_mesh.as_ref().unwrap()).unwrap());
    let scalp = Bvh::new(read_mesh(cap.scalp_mesh.as_ref().unwrap()).unwrap());
    let (mut worst_root, mut deepest, mut worst_ratio) = (0.0f32, f32::INFINITY, 1.0f32);
    let mut ratios = Vec::new();
    for s in strands.iter() {
        let d = scalp.closest_point(s[0], 0.01).map_or(f32::INFINITY, |c| c.distance);
        worst_root = worst_root.max(d);
        for p in &s[1..] {
            let sd = head.signed_distance(*p, 0.5).unwrap_or(f32::INFINITY);
            deepest = deepest.min(sd);
        }
        let l: Vec<f32> = s.windows(2).map(|w| (w[1] - w[0]).length()).collect();
        let (lo, hi) = l.iter().fold((f32::INFINITY, 0.0f32), |(a, b), x| (a.min(*x), b.max(*x)));
        let r = hi / lo.max(1e-12);
        worst_ratio = worst_ratio.max(r);
        ratios.push(r);
    }
    ratios.sort_by(f32::total_cmp);
    println!(
        "roots: worst {:.4} mm from the scalp; nearest point to the head {:.3} mm (negative: inside); \
         max/min segment length per strand: median {:.3}, 99% {:.3}, worst {:.3}",
        worst_root * 1e3,
        deepest * 1e3,
        ratios[ratios.len() / 2],
        ratios[ratios.len() * 99 / 100],
        worst_ratio
    );
    // Measured (60 + 30 steps) at commit 90a7267, with the DR defaults of commit 6a05744: roots
    // 0.0000 mm from the scalp; nearest point 0.85 mm outside the head (the clearance is 1 mm; the
    // final evening of the segments may move a point along its strand closer); max/min segment
    // length per strand 1.001 for 99% of the strands, 1.40 at worst; F1 at 2 mm/20° 78.3 -> 86.3.
    // Two rules of the growth keep the segments even, as evening cannot: a step turns by at most
    // 40° (before that rule a kink left a worst ratio of 1.756; commit ba29de5), and a child whose
    // two guides part follows the nearest (without it one child blended two guides leaving the
    // crown in opposite directions; its segments started 0.02 mm long and it ended crumpled at a
    // worst ratio of 2.02; commit 0659987).
    assert!(worst_root < 0.0005, "a root is {:.3} mm from the scalp", worst_root * 1e3);
    assert!(deepest > 0.0, "a strand point is {:.3} mm inside the head", -deepest * 1e3);
    let p99 = ratios[ratios.len() * 99 / 100];
    assert!(worst_ratio < 1.5 && p99 < 1.1, "uneven segments: max/min length ratio {worst_ratio:.3} (99%: {p99:.3})");
    // On this scene DR adds a few points to the init (78.3 -> 86.3 at commit 90a7267, above); how
    // much DR recovers from a worse start is asserted by tests/dr.rs (70.4 -> 89.8). Here: DR must
    // not make the pipeline's answer worse.
    assert!(
        d_d >= i_d && d_u >= i_u,
        "DR must not lower F1: directed {i_d:.1} -> {d_d:.1}, undirected {i_u:.1} -> {d_u:.1}"
    );
    let _ = std::fs::remove_dir_all(&cap.dir);
}

/// Cancels once DR has taken `steps` steps (the message of the "dr" stage says "guides k/n ...").
struct CancelInDr {
    steps: usize,
    flag: AtomicBool,
}

impl Progress for CancelInDr {
    fn update(&self, stage: &str, _fraction: f32, message: &str) {
        let step =
            message.strip_prefix("guides ").and_then(|m| m.split('/').next()).and_then(|k| k.parse::<usize>().ok());
        if stage == "dr" && step.is_some_and(|k| k >= self.steps) {
            self.flag.store(true, Ordering::SeqCst);
        }
    }
    fn cancelled(&self) -> bool {
        self.flag.load(Ordering::SeqCst)
    }
}

#[test]
fn a_run_cancelled_during_dr_writes_no_strands_and_resumes_from_its_init() {
    // A small capture and a short DR: this test is about files, not quality.
    let cap = capture("cancel", 600, 128);
    let out_dir = cap.dir.join("out");
    // A previous run's strands in the folder must not survive as if they were this run's.
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("strands.hair"), b"stale").unwrap();
    std::fs::write(out_dir.join("loss.csv"), b"stale").unwrap();
    let mut opts = options();
    opts.guides = 100;
    opts.children = 500;
    (opts.dr_options.iterations_guides, opts.dr_options.iterations_children) = (8, 4);
    let progress = CancelInDr { steps: 3, flag: AtomicBool::new(false) };
    let r = reconstruct(&cap, &out_dir, &opts, Plan::default(), &progress);
    assert!(matches!(r, Err(ReconError::Cancelled(_))), "{r:?}");
    for f in ["strands.hair", "guides.hair", "loss.csv", "loss.png"] {
        assert!(!out_dir.join(f).exists(), "{f} exists after a cancelled run");
    }
    // The init stage had finished: its strands are saved whole, and DR resumes from them.
    assert!(out_dir.join("init_strands.hair").is_file() && out_dir.join("init.json").is_file());
    let resumed = Plan { from: hairrecon_recon::Stage::Dr, ..Default::default() };
    let out = reconstruct(&cap, &out_dir, &opts, resumed, &NoProgress).unwrap();
    assert!(out.strands.as_ref().is_some_and(|p| p.is_file()));
    assert_eq!(out.report.stages.len(), 6, "the resumed report keeps the stages before DR");
    let leftovers: Vec<String> = std::fs::read_dir(&out_dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "half-written files: {leftovers:?}");
    let _ = std::fs::remove_dir_all(&cap.dir);
}
