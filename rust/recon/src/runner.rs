//! The runner of `hairrecon reconstruct`: the stages of [`crate::stages`] in order, each output
//! saved as it is made, evaluation ([`crate::eval`]) beside the run when the capture has ground
//! truth, and a report ([`crate::report`]).
//!
//! `--from STAGE` reloads what an earlier run saved in the same folder for the stages before
//! STAGE; `--stop-after STAGE` stops there. Every run writes `config.json` (the whole
//! configuration) first and `report.json` last. Outputs of the stages a run makes again are
//! removed at its start, so that nothing of an earlier run can pass for this one's.
//!
//! Cancellation: stages check `progress` between views, chunks, solver iterations and DR steps;
//! a cancelled run returns [`ReconError::Cancelled`] and writes no result (`strands.hair`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::write_strands;

use crate::config::{ConfigFile, Plan, ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::eval::Evaluator;
use crate::progress::Progress;
use crate::report::Report;
use crate::stages::direction::DirectionOut;
use crate::stages::init::InitOut;
use crate::stages::orient2d::Orient2dOut;
use crate::stages::orient3d::Orient3dOut;
use crate::stages::partings::PartingsOut;
use crate::stages::{self, mkdir, remove, Context};

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructOutput {
    /// The final child strands (`strands.hair`), when the run reached the init stage.
    pub strands: Option<PathBuf>,
    /// The final guide strands (`guides.hair`).
    pub guides: Option<PathBuf>,
    /// The strands before DR (`init_strands.hair`, `init_guides.hair`).
    pub init_strands: Option<PathBuf>,
    pub init_guides: Option<PathBuf>,
    /// The loss curve (`loss.csv`; the plot is `loss.png` beside it), when DR ran.
    pub loss_csv: Option<PathBuf>,
    /// What `report.json` holds.
    pub report: Report,
}

/// Runs the plan's stages on the capture into `out_dir` (see the module doc).
pub fn reconstruct(
    capture: &Capture,
    out_dir: &Path,
    cfg: &ReconstructConfig,
    plan: Plan,
    progress: &dyn Progress,
) -> Result<ReconstructOutput, ReconError> {
    cfg.validate()?;
    if !capture.is_canonical() {
        return Err(ReconError::NotCanonical {
            dir: capture.dir.clone(),
            frame: capture.frame.name().into(),
            units: capture.units.name().into(),
        });
    }
    let stop = plan.stop_after.unwrap_or(Stage::Dr);
    let last = if cfg.dr { stop } else { stop.min(Stage::Init) };
    let from = plan.from;
    if from > last {
        return Err(ReconError::EmptyPlan { from, stop: last });
    }
    let ctx = Context::new(capture, out_dir, progress);
    crate::preflight::check(&ctx)?;
    mkdir(out_dir)?;
    for (_, files) in stages::OUTPUTS.iter().filter(|(s, _)| *s >= from) {
        files.iter().try_for_each(|f| remove(&out_dir.join(f)))?;
    }
    ConfigFile::new(cfg.clone()).save(&out_dir.join("config.json"))?;
    let mut report = Report::resumed(&capture.dir, out_dir, from);
    // The report is written whatever happens: a cancelled or failed run lists the stages it finished.
    let run = run_stages(&ctx, cfg, &mut report, from, last);
    let saved = report.save(&out_dir.join("report.json"));
    run?;
    saved?;
    let file = |name: &str, made: bool| made.then(|| out_dir.join(name));
    Ok(ReconstructOutput {
        strands: file("strands.hair", last >= Stage::Init),
        guides: file("guides.hair", last >= Stage::Init),
        init_strands: file("init_strands.hair", last >= Stage::Init),
        init_guides: file("init_guides.hair", last >= Stage::Init),
        loss_csv: file("loss.csv", last == Stage::Dr),
        report,
    })
}

/// The stages from `from` to `last`, recorded in `report`.
fn run_stages(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    report: &mut Report,
    from: Stage,
    last: Stage,
) -> Result<(), ReconError> {
    let eval = Evaluator::new(ctx.capture);
    let runs = |s: Stage| from <= s && s <= last;
    let t = Instant::now();
    let maps = if runs(Stage::Orient2d) {
        let o = stages::orient2d::run(ctx, cfg)?;
        o.save(ctx, cfg.write_pictures)?;
        report.record(Stage::Orient2d, t.elapsed().as_secs_f64(), &());
        report.scores.orient2d = eval.orient2d(&o.maps)?;
        o.maps
    } else {
        Orient2dOut::load(ctx, from)?.maps
    };
    if last == Stage::Orient2d {
        return Ok(());
    }

    let t = Instant::now();
    let points = if runs(Stage::Orient3d) {
        let o = stages::orient3d::run(ctx, cfg, &maps)?;
        o.save(ctx)?;
        report.record(Stage::Orient3d, t.elapsed().as_secs_f64(), &());
        report.scores.orient3d = eval.points(ctx.raw()?, &o.points)?;
        Some(o.points)
    } else if runs(Stage::Direction) {
        Some(Orient3dOut::load(ctx, from)?.points)
    } else {
        None
    };
    if last == Stage::Orient3d {
        return Ok(());
    }

    let t = Instant::now();
    let scalp = if runs(Stage::Partings) {
        let o = stages::partings::run(ctx, cfg)?;
        o.save(ctx)?;
        report.record(Stage::Partings, t.elapsed().as_secs_f64(), &o.stats);
        o.scalp
    } else {
        PartingsOut::load(ctx, from, &cfg.parting)?.scalp
    };
    if last == Stage::Partings {
        return Ok(());
    }

    let t = Instant::now();
    let directed = match points {
        Some(points) => {
            let o = stages::direction::run(ctx, cfg, &points, &scalp)?;
            o.save(ctx)?;
            report.record(Stage::Direction, t.elapsed().as_secs_f64(), &o.stats);
            report.scores.direction = eval.directions(ctx.raw()?, &o.directed)?;
            o.directed
        }
        None if runs(Stage::Init) => DirectionOut::load(ctx, from)?.directed,
        None => Default::default(),
    };
    if last == Stage::Direction {
        return Ok(());
    }

    let t = Instant::now();
    let init = if runs(Stage::Init) {
        let o = stages::init::run(ctx, cfg, &directed, &scalp, &maps)?;
        o.save(ctx)?;
        report.record(Stage::Init, t.elapsed().as_secs_f64(), &o.stats);
        report.warnings.extend(o.stats.hull_warning.clone());
        if let (Some(axes), Some(c)) = (&o.seen_axes, o.info.curl) {
            report.scores.axes = eval.axes(ctx.raw()?, axes, &c)?;
        }
        ctx.progress.update("metrics", 0.0, "scoring strands");
        report.scores.init_guides = eval.strands(ctx.raw()?, &o.guides)?;
        report.scores.init_strands = eval.strands(ctx.raw()?, &o.children)?;
        o
    } else {
        InitOut::load(ctx, from)?
    };
    drop(directed);
    if last == Stage::Init {
        write_strands(ctx.path("guides.hair"), &init.guides)?;
        write_strands(ctx.path("strands.hair"), &init.children)?;
        return Ok(());
    }

    let t = Instant::now();
    let o = stages::dr::run(ctx, cfg, &init, &maps, &scalp)?;
    o.save(ctx)?;
    report.record(Stage::Dr, t.elapsed().as_secs_f64(), &o.stats);
    ctx.progress.update("metrics", 0.5, "scoring strands");
    report.scores.dr_guides = eval.strands(ctx.raw()?, &o.guides)?;
    report.scores.dr_strands = eval.strands(ctx.raw()?, &o.children)?;
    ctx.progress.update("dr", 1.0, "");
    Ok(())
}
