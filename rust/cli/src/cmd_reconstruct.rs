//! `hairrecon reconstruct`: the whole pipeline from a capture folder to optimized strands
//! ([`hairrecon_recon::reconstruct`]: initial strands, then DR unless `--no-dr`), with a progress
//! bar per stage (DR's shows the current loss), the time of each stage at the end and, when the
//! capture has ground truth, the metric table before and after DR (every stage's scores are in
//! `report.json`). `--from`/`--stop-after` run part of it; `--config` replays a run's
//! `config.json`; `--print-config` shows the configuration a run would use and exits.
//!
//! SIGINT/SIGTERM ([`crate::interrupt`]) cancel the run at its next safe point: the stages that
//! finished stay (complete, listed in `report.json`, for `--from`), no result is written, and the
//! process exits with code 130.

use std::path::PathBuf;

use hairrecon_core::capture::Capture;
use hairrecon_core::metric::MetricReport;
use hairrecon_recon::config::{ConfigFile, ReconstructConfig, Stage};
use hairrecon_recon::curl::CurlError;
use hairrecon_recon::{reconstruct, Plan, ReconError};

use crate::progress::Bars;
use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct ReconstructArgs {
    /// Capture folder (or its capture.json).
    capture: PathBuf,
    /// Output folder: every stage's result goes there, with config.json and report.json. A run
    /// clears what an earlier run left there for the stages it makes again.
    #[arg(long)]
    out: PathBuf,
    /// Write into an output folder that holds files other than a hairrecon run's (by default such
    /// a folder is refused; only the files this run writes are replaced).
    #[arg(long)]
    overwrite: bool,
    /// Start from this stage, reloading what an earlier run saved in --out for the stages before
    /// it: head, masks, orient2d, orient3d, partings, direction, init or dr.
    #[arg(long, value_name = "STAGE")]
    from: Option<String>,
    /// Stop after this stage: head, masks, orient2d, orient3d, partings, direction, init (before DR)
    /// or dr.
    #[arg(long, value_name = "STAGE")]
    stop_after: Option<String>,
    /// Accept a capture.json whose paths are absolute or leave the capture folder with `..`
    /// (by default every path must stay inside the folder).
    #[arg(long)]
    allow_outside_paths: bool,
    /// Start from this configuration (a run's config.json, or `--print-config`'s output); the
    /// options below override it.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Guide strands [default: 2000].
    #[arg(long)]
    guides: Option<usize>,
    /// Child strands [default: 50000].
    #[arg(long)]
    children: Option<usize>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of every random choice [default: 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Ablation: the gravity heuristic instead of the global direction optimization.
    #[arg(long)]
    no_global_opt: bool,
    /// Ablation: straight strands along the scalp normal instead of the Laplace flow.
    #[arg(long)]
    no_strand_init: bool,
    /// Curls: `auto` (the capture decides whether the hair is curly, the handedness, and the period
    /// from the hair surface's bumps, with the radius of a 60° pitch, or 50° for looser curls), `off` (strands follow the
    /// points' directions, as for straight and wavy hair), RADIUS_MM,PERIOD_MM,HAND with HAND 1
    /// right-handed, -1 left-handed (e.g. 6.5,22,1), or fine:RADIUS_MM,PERIOD_MM,HAND for coils finer
    /// than the photos resolve (strands grow along the ropes the photos show, helices about them;
    /// `auto` cannot tell such hair) [default: auto].
    #[arg(long)]
    curl: Option<String>,
    /// Keep the initial strands: no strand optimization by differentiable rendering (DR).
    #[arg(long)]
    no_dr: bool,
    /// Keep the initial strands' ends that some view sees where there is no hair (by default they
    /// are cut at the visual hull of the masks before DR, the head hiding what lies behind it).
    #[arg(long)]
    no_hull_trim: bool,
    /// Do not look for partings (by default, where the views see the scalp's skin, the hair beside it
    /// leaves it sideways; see partings.ply).
    #[arg(long)]
    no_parting: bool,
    /// DR ablation: no guide stage (every child optimized on its own from the start).
    #[arg(long)]
    no_guide_opt: bool,
    /// DR ablation: Adam on the points, without the reparameterization u = (I + λL)x.
    #[arg(long)]
    no_reparam: bool,
    /// DR ablation: the Laplacian along strands only, without N between neighbouring strands.
    #[arg(long)]
    no_neighbor_reparam: bool,
    /// DR steps on the guides (children following them) [default: 60].
    #[arg(long)]
    dr_iters_guides: Option<usize>,
    /// DR steps on the children [default: 20].
    #[arg(long)]
    dr_iters_children: Option<usize>,
    /// DR moves every Nth point of each strand (and its tip), the points between following them;
    /// 1 moves every point [default: the configuration's dr_options.stride].
    #[arg(long)]
    dr_stride: Option<usize>,
    /// DR's guide stage renders and compares the views N times smaller in both directions (the
    /// child stage at full size); 1 is full size [default: the configuration's
    /// dr_options.guide_downsample].
    #[arg(long)]
    dr_guide_downsample: Option<usize>,
    /// DR's guide stage moves the strands on every Nth point (the child stage on every
    /// --dr-stride-th) [default: the configuration's dr_options.guide_stride; 0 there: --dr-stride].
    #[arg(long)]
    dr_guide_stride: Option<usize>,
    /// DR learning rate: the largest step of a point's coordinate in u per iteration, metres (halved
    /// when the strands carry curls, unless --dr-plain-curls) [default: 0.002].
    #[arg(long)]
    dr_lr: Option<f32>,
    /// With curls, optimize them like any strands: by default DR keeps their shape (curvature held to
    /// the init's own, half the learning rate).
    #[arg(long)]
    dr_plain_curls: bool,
    /// DR views rendered per step (random, seeded); more is steadier and slower [default: 4].
    #[arg(long)]
    dr_views: Option<usize>,
    /// λ of the reparameterization u = (I + λL)x: larger moves strands more smoothly [default: 10].
    #[arg(long)]
    dr_lambda: Option<f32>,
    /// Rendered strand width in DR, millimetres [default: 0.2].
    #[arg(long)]
    dr_width_mm: Option<f32>,
    /// Print the configuration this run would use (JSON, for --config) and exit.
    #[arg(long, alias = "print-options")]
    print_config: bool,
}

/// The configuration of the arguments: `--config` (else the defaults) with the options given.
fn config(a: &ReconstructArgs) -> Result<ReconstructConfig, Box<dyn std::error::Error + Send + Sync>> {
    let mut c = match &a.config {
        Some(p) => ConfigFile::load(p)?.config,
        None => ReconstructConfig::default(),
    };
    let positive = |v: f32, flag: &str| -> Result<f32, String> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(format!("{flag} must be a positive number, got {v}"))
        }
    };
    let d = &mut c.dr_options;
    if let Some(v) = a.dr_lr {
        d.lr = positive(v, "--dr-lr")?;
    }
    if let Some(v) = a.dr_lambda {
        if !(v.is_finite() && v >= 0.0) {
            return Err(format!("--dr-lambda must be at least 0, got {v}").into());
        }
        d.lambda = v;
    }
    if let Some(v) = a.dr_width_mm {
        d.width_m = positive(v, "--dr-width-mm")? * 1e-3;
    }
    match a.dr_views {
        Some(0) => return Err("--dr-views must be at least 1".into()),
        Some(v) => d.views_per_step = v,
        None => {}
    }
    d.iterations_guides = a.dr_iters_guides.unwrap_or(d.iterations_guides);
    d.iterations_children = a.dr_iters_children.unwrap_or(d.iterations_children);
    match a.dr_stride {
        Some(0) => return Err("--dr-stride must be at least 1".into()),
        Some(k) => d.stride = k,
        None => {}
    }
    match a.dr_guide_downsample {
        Some(0) => return Err("--dr-guide-downsample must be at least 1".into()),
        Some(f) => d.guide_downsample = f,
        None => {}
    }
    match a.dr_guide_stride {
        Some(0) => return Err("--dr-guide-stride must be at least 1".into()),
        Some(k) => d.guide_stride = k,
        None => {}
    }
    d.guide_opt &= !a.no_guide_opt;
    d.reparam &= !a.no_reparam;
    d.neighbor_reparam &= !a.no_neighbor_reparam;
    if let Some(s) = a.seed {
        (c.seed, c.dr_options.seed) = (s, s);
    }
    if matches!(a.guides, Some(0)) || matches!(a.children, Some(0)) {
        return Err("--guides and --children must be at least 1".into());
    }
    c.guides = a.guides.unwrap_or(c.guides);
    c.children = a.children.unwrap_or(c.children);
    c.global_opt &= !a.no_global_opt;
    c.strand_init &= !a.no_strand_init;
    c.dr &= !a.no_dr;
    c.dr_keep_curls &= !a.dr_plain_curls;
    c.hull_trim &= !a.no_hull_trim;
    c.parting.enabled &= !a.no_parting;
    if let Some(curl) = &a.curl {
        c.curl = curl.parse().map_err(|e: CurlError| format!("--curl: {e}"))?;
    }
    c.validate()?;
    Ok(c)
}

/// The metric table of one strand set (P/R/F1 per threshold, directed and undirected).
fn metric_table(m: &MetricReport) -> String {
    let mut s = format!("{:<11}", "threshold");
    for r in &m.directed {
        s.push_str(&format!("{:>24}", format!("{}mm/{}°", r.dist_mm, r.angle_deg)));
    }
    s.push_str(&format!("\n{:<11}", "measure"));
    for _ in &m.directed {
        s.push_str(&format!("{:>8}{:>8}{:>8}", "P", "R", "F1"));
    }
    for (name, rows) in [("directed", &m.directed), ("undirected", &m.undirected)] {
        s.push_str(&format!("\n{name:<11}"));
        for r in rows {
            s.push_str(&format!("{:>8.1}{:>8.1}{:>8.1}", r.precision, r.recall, r.f1));
        }
    }
    s
}

pub fn run(a: ReconstructArgs) -> CmdResult {
    if let Some(t) = a.threads {
        if t == 0 {
            return Err("--threads must be at least 1".into());
        }
        // Read by rayon when its global pool starts, which has not happened yet.
        std::env::set_var("RAYON_NUM_THREADS", t.to_string());
    }
    let cfg = config(&a)?;
    let plan = Plan {
        from: a.from.as_deref().map(str::parse::<Stage>).transpose()?.unwrap_or(Stage::FIRST),
        stop_after: a.stop_after.as_deref().map(str::parse::<Stage>).transpose()?,
        overwrite: a.overwrite,
    };
    if a.print_config {
        println!("{}", serde_json::to_string_pretty(&ConfigFile::new(cfg))?);
        return Ok(());
    }
    let capture = if a.allow_outside_paths {
        Capture::load_allowing_outside_paths(&a.capture)?
    } else {
        Capture::load(&a.capture)?
    };
    let bars = Bars::new();
    let out = reconstruct(&capture, &a.out, &cfg, plan, &bars);
    bars.finish();
    if matches!(out, Err(ReconError::Cancelled(_))) && bars.interrupt.requested() {
        bars.interrupt.exit(&format!(
            "no result was written; {} keeps the stages that finished (report.json lists them; --from resumes)",
            a.out.display()
        ));
    }
    let out = out?;
    let r = &out.report;
    println!("stage times: (and the peak memory of the process at the end of each stage)");
    let mut total = 0.0;
    for s in &r.stages {
        match s.peak_rss_mb {
            Some(mb) => println!("  {:>10}  {:8.2} s  {:6.2} GB", s.stage, s.seconds, mb / 1024.0),
            None => println!("  {:>10}  {:8.2} s", s.stage, s.seconds),
        }
        total += s.seconds;
    }
    println!("  {:>10}  {total:8.2} s", "total");
    if let Some(st) = r.stages.iter().find(|s| s.stage == Stage::Dr).map(|s| &s.stats) {
        println!(
            "DR: {} steps, {:.2} s per step, mean CG iterations {:.1}",
            st["steps"],
            st["seconds_per_step"].as_f64().unwrap_or(0.0),
            st["mean_cg_iterations"].as_f64().unwrap_or(0.0)
        );
    }
    for (m, title) in [(&r.scores.init_strands, "strands before DR (init)"), (&r.scores.dr_strands, "strands after DR")]
    {
        if let Some(m) = m {
            println!("{title}, against the ground truth:\n{}", metric_table(m));
        }
    }
    for w in &r.warnings {
        println!("warning: {w}");
    }
    println!("report (times, memory, scores): {}", a.out.join("report.json").display());
    for (what, p) in [
        ("strands", &out.strands),
        ("guides", &out.guides),
        ("strands before DR", &out.init_strands),
        ("loss curve", &out.loss_csv),
    ] {
        if let Some(p) = p {
            println!("{what}: {}", p.display());
        }
    }
    Ok(())
}
