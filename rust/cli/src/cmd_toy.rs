//! `hairrecon toy-aa` and `hairrecon toy-letters`: the anti-aliasing demos of Dr.Hair's supplement
//! (3.1 and 3.2), on top of `hairrecon_raster::toy` and `hairrecon_raster::letters`.

use std::io::Write;
use std::path::{Path, PathBuf};

use hairrecon_raster::plot::{write_loss_plot, write_mosaic, LossPanel, Tile};
use hairrecon_raster::toy::{render_coverage, run_toy, ToyConfig, ToyResult, ToyTarget};
use hairrecon_raster::AaMethod;

use crate::progress;
use crate::CmdResult;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AaArg {
    Ours,
    Nvdiffrast,
    Splat,
}

impl From<AaArg> for AaMethod {
    fn from(a: AaArg) -> Self {
        match a {
            AaArg::Ours => AaMethod::Ours,
            AaArg::Nvdiffrast => AaMethod::Nvdiffrast,
            AaArg::Splat => AaMethod::Splat,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TargetArg {
    /// The full-length strand rendered by the method under test (loss 0 at the target).
    Rendered,
    /// Exact area coverage of the full-length strand (8×8 supersampling), the same for all methods.
    Coverage,
}

#[derive(Debug, clap::Args)]
pub struct ToyAaArgs {
    /// Anti-aliasing method.
    #[arg(long, value_enum, default_value = "ours")]
    aa: AaArg,
    /// Width of the triangle's root edge in pixels.
    #[arg(long, default_value_t = 0.6)]
    width_px: f32,
    /// SGD iterations.
    #[arg(long, default_value_t = 25_000)]
    iters: usize,
    /// How the target image is made.
    #[arg(long, value_enum, default_value = "rendered")]
    target: TargetArg,
    /// The loss is `loss_scale · Σ_p (ĉ(p) − target(p))²` (the paper does not give its normalisation).
    #[arg(long, default_value_t = 0.4)]
    loss_scale: f32,
    /// Write the curve (iter, loss, tip error in px, length ratio) as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    json: bool,
    /// Instead of one run: run the three methods at widths 1.0, 0.8 and 0.6 (in parallel), write the
    /// loss plot (Figure 9 of the supplement) to this PNG and the target/start/final pictures to
    /// `<stem>_final.png` beside it, and print one line per run.
    #[arg(long)]
    plot: Option<PathBuf>,
}

fn config(a: &ToyAaArgs, method: AaMethod, width: f32) -> ToyConfig {
    let mut cfg = ToyConfig::paper(method, width, a.iters);
    cfg.loss_scale = a.loss_scale;
    cfg.target = match a.target {
        TargetArg::Rendered => ToyTarget::Rendered,
        TargetArg::Coverage => ToyTarget::Coverage,
    };
    cfg
}

fn write_csv(path: &Path, r: &ToyResult) -> CmdResult {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(f, "iter,loss,tip_error_px,length_ratio")?;
    for s in &r.curve {
        writeln!(f, "{},{},{},{}", s.iter, s.loss, s.tip_error_px, s.length_ratio)?;
    }
    f.flush()?;
    Ok(())
}

pub fn run_aa(a: ToyAaArgs) -> CmdResult {
    if !(a.width_px.is_finite() && a.width_px > 0.0) {
        return Err(format!("--width-px must be a positive number, got {}", a.width_px).into());
    }
    if let Some(plot) = &a.plot {
        return run_plot(&a, plot);
    }
    let method: AaMethod = a.aa.into();
    let cfg = config(&a, method, a.width_px);
    let pb = progress::bar(a.iters as u64, "toy-aa");
    let r = run_toy(&cfg, |i| {
        if i % 256 == 0 {
            pb.set_position(i as u64);
        }
    })?;
    pb.finish_and_clear();
    if let Some(csv) = &a.csv {
        write_csv(csv, &r)?;
    }
    if a.json {
        let v = serde_json::json!({
            "aa": method.name(),
            "width_px": (a.width_px as f64 * 1e6).round() / 1e6,
            "iters": a.iters,
            "initial_loss": r.initial_loss,
            "final_loss": r.final_loss,
            "final_tip_error_px": r.final_tip_error_px,
            "final_length_ratio": r.final_length_ratio,
        });
        println!("{v}");
    } else {
        println!(
            "aa {} width {} px, {} iterations: loss {:.6} -> {:.6}, tip error {:.3} px, length ratio {:.4}",
            method.name(),
            a.width_px,
            a.iters,
            r.initial_loss,
            r.final_loss,
            r.final_tip_error_px,
            r.final_length_ratio
        );
    }
    Ok(())
}

fn run_plot(a: &ToyAaArgs, plot: &Path) -> CmdResult {
    let widths = [1.0f32, 0.8, 0.6];
    let jobs: Vec<(f32, AaMethod)> = widths.iter().flat_map(|&w| AaMethod::ALL.map(|m| (w, m))).collect();
    let pb = progress::bar((jobs.len() * a.iters) as u64, "toy-aa");
    let results: Vec<Result<ToyResult, hairrecon_raster::RasterError>> = std::thread::scope(|s| {
        let handles: Vec<_> = jobs
            .iter()
            .map(|&(w, m)| {
                let pb = &pb;
                s.spawn(move || {
                    run_toy(&config(a, m, w), |i| {
                        if i % 1024 == 0 {
                            pb.inc(1024);
                        }
                    })
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap_or_else(|_| panic!("a toy run panicked"))).collect()
    });
    pb.finish_and_clear();
    let mut results_ok = Vec::with_capacity(results.len());
    for r in results {
        results_ok.push(r?);
    }
    let colours = [[200u8, 30, 30], [30, 90, 200], [30, 150, 60]];
    let mut panels = Vec::new();
    for &w in &widths {
        let mut curves = Vec::new();
        for (ci, m) in AaMethod::ALL.iter().enumerate() {
            let k = jobs.iter().position(|j| j.0 == w && j.1 == *m).unwrap_or(0);
            curves.push((m.name().to_string(), colours[ci], results_ok[k].curve.iter().map(|s| s.loss).collect()));
        }
        panels.push(LossPanel { title: format!("WIDTH {w:.1} PX"), curves });
    }
    write_loss_plot(plot, &panels, "LOSS / INITIAL LOSS")?;
    // Pictures: per width, the target and the final state of each method.
    let mut images = Vec::new();
    let mut captions = Vec::new();
    for &w in &widths {
        let cfg = config(a, AaMethod::Ours, w);
        let start = cfg.root + (cfg.target_tip - cfg.root) * cfg.start_fraction;
        let mut target = render_coverage(AaMethod::Ours, cfg.size, cfg.root, cfg.target_tip, w)?;
        let init = render_coverage(AaMethod::Ours, cfg.size, cfg.root, start, w)?;
        // Target in grey, start in the same picture, darker.
        for (t, i) in target.data.iter_mut().zip(&init.data) {
            *t = (0.5 * *t).max(*i);
        }
        images.push(target);
        captions.push(format!("{w:.1} TARGET/START"));
        for m in AaMethod::ALL {
            let k = jobs.iter().position(|j| j.0 == w && j.1 == m).unwrap_or(0);
            images.push(render_coverage(AaMethod::Ours, cfg.size, cfg.root, results_ok[k].final_tip, w)?);
            captions.push(format!("{} FINAL", m.name()));
        }
    }
    let tiles: Vec<Tile<'_>> = images.iter().zip(captions).map(|(image, caption)| Tile { image, caption }).collect();
    let stem = plot.file_stem().and_then(|s| s.to_str()).unwrap_or("toy_aa");
    let finals = plot.with_file_name(format!("{stem}_final.png"));
    write_mosaic(&finals, &tiles, 4, 2)?;
    for ((w, m), r) in jobs.iter().zip(&results_ok) {
        println!(
            "aa {:<10} width {:.1} px: loss {:.6} -> {:.6}, tip error {:8.3} px, length ratio {:.4}",
            m.name(),
            w,
            r.initial_loss,
            r.final_loss,
            r.final_tip_error_px,
            r.final_length_ratio
        );
    }
    eprintln!("wrote {} and {}", plot.display(), finals.display());
    Ok(())
}

#[derive(Debug, clap::Args)]
pub struct ToyLettersArgs {
    /// The word; its letters must be among C, V, P and R.
    #[arg(long, default_value = "CVPR")]
    word: String,
    /// Strands per bundle.
    #[arg(long, default_value_t = 500)]
    strands: usize,
    /// Segments per strand.
    #[arg(long, default_value_t = 50)]
    segments: usize,
    /// Adam iterations.
    #[arg(long, default_value_t = 300)]
    iters: usize,
    /// Adam learning rate (metres per step on each segment vector).
    #[arg(long, default_value_t = 2e-5)]
    lr: f32,
    /// Average each strand's gradient with its 10 nearest strands' (experimental, overshoots; see
    /// `hairrecon_raster::letters`).
    #[arg(long)]
    neighbours: bool,
    /// Picture of target, start and end (front view).
    #[arg(long, default_value = "docs/images/letters.png")]
    out: PathBuf,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run_letters(a: ToyLettersArgs) -> CmdResult {
    use hairrecon_raster::letters::{run_letters as run, LettersConfig};
    if a.strands == 0 || a.segments < 2 {
        return Err("--strands must be at least 1 and --segments at least 2".into());
    }
    let cfg = LettersConfig {
        word: a.word.clone(),
        strands: a.strands,
        segments: a.segments,
        iters: a.iters,
        learning_rate: a.lr,
        neighbour_mixing: a.neighbours,
        ..LettersConfig::default()
    };
    let pb = progress::bar(a.iters as u64, "toy-letters");
    let t0 = std::time::Instant::now();
    let r = run(&cfg, |i| pb.set_position(i as u64 + 1))?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let tiles = [
        Tile { image: &r.target, caption: "TARGET".into() },
        Tile { image: &r.start, caption: format!("START (10 PCT), IOU {:.2}", r.start_iou) },
        Tile { image: &r.end, caption: format!("END AFTER {} ADAM STEPS, IOU {:.2}", a.iters, r.end_iou) },
    ];
    write_mosaic(&a.out, &tiles, 1, 2)?;
    if a.json {
        let v = serde_json::json!({
            "word": a.word,
            "strands_per_bundle": a.strands,
            "segments": a.segments,
            "iters": a.iters,
            "initial_loss": r.loss_curve.first(),
            "final_loss": r.loss_curve.last(),
            "start_length_ratio": r.start_length_ratio,
            "end_length_ratio": r.end_length_ratio,
            "start_tip_error_mm": r.start_tip_error_mm,
            "end_tip_error_mm": r.end_tip_error_mm,
            "start_iou": r.start_iou,
            "end_iou": r.end_iou,
            "seconds": secs,
        });
        println!("{v}");
    } else {
        println!(
            "{}: length ratio {:.3} -> {:.3}, mean tip error {:.2} -> {:.2} mm, front-view IoU {:.3} -> {:.3} ({:.1} s); wrote {}",
            a.word,
            r.start_length_ratio,
            r.end_length_ratio,
            r.start_tip_error_mm,
            r.end_tip_error_mm,
            r.start_iou,
            r.end_iou,
            secs,
            a.out.display()
        );
    }
    Ok(())
}
