//! `hairrecon reconstruct`: the whole pipeline from a capture folder to optimized strands
//! ([`hairrecon_recon::pipeline::reconstruct`]: initial strands, then DR unless `--no-dr`), with a
//! progress bar per stage (DR's shows the current loss), the time of each stage at the end and,
//! when the capture has ground truth, the metric table before and after DR (every stage's metrics
//! are in `metrics.json`). `--print-options` shows the options a run would use and exits.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use hairrecon_core::capture::Capture;
use hairrecon_recon::dr::DrOptions;
use hairrecon_recon::pipeline::{reconstruct, ReconstructOptions, Stage};
use hairrecon_recon::progress::Progress;
use indicatif::ProgressBar;

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct ReconstructArgs {
    /// Capture folder (or its capture.json).
    capture: PathBuf,
    /// Output folder: every stage's result goes there.
    #[arg(long)]
    out: PathBuf,
    /// Stop after this stage: orient2d, orient3d, direction, init (before DR) or dr.
    #[arg(long)]
    stop_after: Option<String>,
    /// Guide strands.
    #[arg(long, default_value_t = 2000)]
    guides: usize,
    /// Child strands.
    #[arg(long, default_value_t = 50000)]
    children: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Ablation: the gravity heuristic instead of the global direction optimization.
    #[arg(long)]
    no_global_opt: bool,
    /// Ablation: straight strands along the scalp normal instead of the Laplace flow.
    #[arg(long)]
    no_strand_init: bool,
    /// Curls: `auto` (the capture decides whether the hair is curly, the handedness, and the period
    /// from the hair surface's bumps, with the radius of a 60° pitch), `off` (strands follow the points' directions, as for straight and wavy
    /// hair), or RADIUS_MM,PERIOD_MM,HAND with HAND 1 right-handed, -1 left-handed (e.g. 6.5,22,1).
    #[arg(long, default_value = "auto")]
    curl: String,
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
    /// DR steps on the guides (children following them).
    #[arg(long, default_value_t = DrOptions::default().iterations_guides)]
    dr_iters_guides: usize,
    /// DR steps on the children.
    #[arg(long, default_value_t = DrOptions::default().iterations_children)]
    dr_iters_children: usize,
    /// DR learning rate: the largest step of a point's coordinate in u per iteration, metres (halved
    /// when the strands carry curls, unless --dr-plain-curls).
    #[arg(long, default_value_t = DrOptions::default().lr)]
    dr_lr: f32,
    /// With curls, optimize them like any strands: by default DR keeps their shape (curvature held to
    /// the init's own, half the learning rate), which scored 18.7 · 72.7 · 92.3 against 17.3 · 71.5 ·
    /// 92.2 at 1 · 2 · 3 mm on the paper curly capture (whole runs, session 30).
    #[arg(long)]
    dr_plain_curls: bool,
    /// DR views rendered per step (random, seeded); more is steadier and slower.
    #[arg(long, default_value_t = DrOptions::default().views_per_step)]
    dr_views: usize,
    /// λ of the reparameterization u = (I + λL)x: larger moves strands more smoothly.
    #[arg(long, default_value_t = DrOptions::default().lambda)]
    dr_lambda: f32,
    /// Rendered strand width in DR, millimetres.
    #[arg(long, default_value_t = (DrOptions::default().width_m * 1e6).round() / 1e3)]
    dr_width_mm: f32,
    /// Print the options this run would use and exit.
    #[arg(long)]
    print_options: bool,
}

/// One indicatif bar per stage, replaced when the stage changes. When stderr is not a terminal
/// (a log file, a pipe), the bars are hidden and a plain line goes to stderr when the stage changes
/// and then at most every [`LOG_EVERY`].
struct Bars {
    current: Mutex<Option<(String, ProgressBar)>>,
    log: Option<Mutex<(String, Instant)>>,
    start: Instant,
}

const LOG_EVERY: Duration = Duration::from_secs(10);

impl std::fmt::Debug for Bars {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Bars")
    }
}

const STEPS: u64 = 1000;

impl Progress for Bars {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
        if let Some(log) = &self.log {
            let Ok(mut last) = log.lock() else { return };
            if last.0 != stage || last.1.elapsed() >= LOG_EVERY {
                let t = self.start.elapsed().as_secs_f64();
                eprintln!("[{t:7.1} s] {stage} {:3.0}% {message}", 100.0 * fraction.clamp(0.0, 1.0));
                *last = (stage.to_string(), Instant::now());
            }
            return;
        }
        let Ok(mut cur) = self.current.lock() else { return };
        if cur.as_ref().is_none_or(|(s, _)| s != stage) {
            if let Some((_, pb)) = cur.take() {
                pb.set_position(STEPS);
                pb.finish();
            }
            *cur = Some((stage.to_string(), crate::progress::bar(STEPS, stage)));
        }
        if let Some((_, pb)) = cur.as_ref() {
            pb.set_position((fraction.clamp(0.0, 1.0) * STEPS as f32) as u64);
            pb.set_message(message.to_string());
        }
    }
}

impl Bars {
    fn finish(&self) {
        if let Ok(mut cur) = self.current.lock() {
            if let Some((_, pb)) = cur.take() {
                pb.set_position(STEPS);
                pb.finish();
            }
        }
    }
}

/// The pipeline options of the arguments.
fn options(a: &ReconstructArgs) -> Result<ReconstructOptions, Box<dyn std::error::Error + Send + Sync>> {
    let stop_after = a.stop_after.as_deref().map(str::parse::<Stage>).transpose()?;
    if !(a.dr_lr.is_finite() && a.dr_lr > 0.0) {
        return Err(format!("--dr-lr must be a positive number, got {}", a.dr_lr).into());
    }
    if !(a.dr_lambda.is_finite() && a.dr_lambda >= 0.0) {
        return Err(format!("--dr-lambda must be at least 0, got {}", a.dr_lambda).into());
    }
    if !(a.dr_width_mm.is_finite() && a.dr_width_mm > 0.0) {
        return Err(format!("--dr-width-mm must be a positive number, got {}", a.dr_width_mm).into());
    }
    if a.dr_views == 0 {
        return Err("--dr-views must be at least 1".into());
    }
    if a.guides == 0 || a.children == 0 {
        return Err("--guides and --children must be at least 1".into());
    }
    Ok(ReconstructOptions {
        guides: a.guides,
        children: a.children,
        stop_after,
        global_opt: !a.no_global_opt,
        strand_init: !a.no_strand_init,
        seed: a.seed,
        dr: !a.no_dr,
        dr_keep_curls: !a.dr_plain_curls,
        hull_trim: !a.no_hull_trim,
        parting: hairrecon_recon::parting::PartingParams { enabled: !a.no_parting, ..Default::default() },
        curl: a.curl.parse().map_err(|e: String| format!("--curl: {e}"))?,
        dr_options: DrOptions {
            iterations_guides: a.dr_iters_guides,
            iterations_children: a.dr_iters_children,
            lr: a.dr_lr,
            lambda: a.dr_lambda,
            width_m: a.dr_width_mm * 1e-3,
            views_per_step: a.dr_views,
            guide_opt: !a.no_guide_opt,
            reparam: !a.no_reparam,
            neighbor_reparam: !a.no_neighbor_reparam,
            seed: a.seed,
            ..DrOptions::default()
        },
        ..ReconstructOptions::default()
    })
}

/// The metric table of one strand set in `metrics.json` (P/R/F1 per threshold, directed and
/// undirected), or None if it is not there.
fn metric_table(m: &serde_json::Value) -> Option<String> {
    let rows = |mode: &str| m[mode].as_array().cloned();
    let (dir, und) = (rows("directed")?, rows("undirected")?);
    let mut s = format!("{:<11}", "threshold");
    for r in &dir {
        let h = format!("{}mm/{}°", r["dist_mm"].as_f64()?, r["angle_deg"].as_f64()?);
        s.push_str(&format!("{h:>24}"));
    }
    s.push_str(&format!("\n{:<11}", "measure"));
    for _ in &dir {
        s.push_str(&format!("{:>8}{:>8}{:>8}", "P", "R", "F1"));
    }
    for (name, rows) in [("directed", &dir), ("undirected", &und)] {
        s.push_str(&format!("\n{name:<11}"));
        for r in rows {
            s.push_str(&format!(
                "{:>8.1}{:>8.1}{:>8.1}",
                r["precision"].as_f64()?,
                r["recall"].as_f64()?,
                r["f1"].as_f64()?
            ));
        }
    }
    Some(s)
}

pub fn run(a: ReconstructArgs) -> CmdResult {
    if let Some(t) = a.threads {
        if t == 0 {
            return Err("--threads must be at least 1".into());
        }
        // Read by rayon when its global pool starts, which has not happened yet.
        std::env::set_var("RAYON_NUM_THREADS", t.to_string());
    }
    let opts = options(&a)?;
    if a.print_options {
        println!("{opts:#?}");
        return Ok(());
    }
    let capture = Capture::load(&a.capture)?;
    let log = (!std::io::stderr().is_terminal()).then(|| Mutex::new((String::new(), Instant::now())));
    let bars = Bars { current: Mutex::new(None), log, start: Instant::now() };
    let out = reconstruct(&capture, &a.out, &opts, &bars);
    bars.finish();
    let out = out?;
    let m = &out.metrics;
    println!("stage times: (and the peak memory of the process at the end of each stage)");
    let mut total = 0.0;
    for (s, t) in &out.stage_times {
        match m.get("peak_rss_mb").and_then(|p| p.get(s)).and_then(|v| v.as_f64()) {
            Some(mb) => println!("  {s:>10}  {t:8.2} s  {:6.2} GB", mb / 1024.0),
            None => println!("  {s:>10}  {t:8.2} s"),
        }
        total += t;
    }
    println!("  {:>10}  {total:8.2} s", "total");
    if let Some(st) = m.get("dr_stats") {
        println!(
            "DR: {} steps, {:.2} s per step, mean CG iterations {:.1}",
            st["steps"],
            st["seconds_per_step"].as_f64().unwrap_or(0.0),
            st["mean_cg_iterations"].as_f64().unwrap_or(0.0)
        );
    }
    for (key, title) in [("init_strands", "strands before DR (init)"), ("dr_strands", "strands after DR")] {
        if let Some(t) = m.get(key).and_then(metric_table) {
            println!("{title}, against the ground truth:\n{t}");
        }
    }
    if m.as_object().is_some_and(|m| !m.is_empty()) {
        println!("every stage's metrics: {}", a.out.join("metrics.json").display());
    }
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
