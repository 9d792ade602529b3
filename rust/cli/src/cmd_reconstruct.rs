//! `hairrecon reconstruct`: the pipeline from a capture folder to initial strands
//! ([`hairrecon_recon::pipeline::reconstruct`]), with a progress bar per stage, the time of each
//! stage at the end and, when the capture has ground truth, the metrics of each stage.

use std::path::PathBuf;
use std::sync::Mutex;

use hairrecon_core::capture::Capture;
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
    /// Stop after this stage: orient2d, orient3d, direction or init.
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
}

/// One indicatif bar per stage, replaced when the stage changes.
struct Bars {
    current: Mutex<Option<(String, ProgressBar)>>,
}

impl std::fmt::Debug for Bars {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Bars")
    }
}

const STEPS: u64 = 1000;

impl Progress for Bars {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
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

pub fn run(a: ReconstructArgs) -> CmdResult {
    if let Some(t) = a.threads {
        if t == 0 {
            return Err("--threads must be at least 1".into());
        }
        // Read by rayon when its global pool starts, which has not happened yet.
        std::env::set_var("RAYON_NUM_THREADS", t.to_string());
    }
    let stop_after = a.stop_after.as_deref().map(str::parse::<Stage>).transpose()?;
    let capture = Capture::load(&a.capture)?;
    let opts = ReconstructOptions {
        guides: a.guides,
        children: a.children,
        stop_after,
        global_opt: !a.no_global_opt,
        strand_init: !a.no_strand_init,
        seed: a.seed,
        ..ReconstructOptions::default()
    };
    let bars = Bars { current: Mutex::new(None) };
    let out = reconstruct(&capture, &a.out, &opts, &bars);
    bars.finish();
    let out = out?;
    println!("stage times:");
    let mut total = 0.0;
    for (s, t) in &out.stage_times {
        println!("  {s:>10}  {t:8.2} s");
        total += t;
    }
    println!("  {:>10}  {total:8.2} s", "total");
    if out.metrics.as_object().is_some_and(|m| !m.is_empty()) {
        println!("metrics (also in {}):", a.out.join("metrics.json").display());
        println!("{}", serde_json::to_string_pretty(&out.metrics)?);
    }
    if let Some(s) = &out.strands {
        println!("strands: {}", s.display());
    }
    if let Some(g) = &out.guides {
        println!("guides: {}", g.display());
    }
    Ok(())
}
