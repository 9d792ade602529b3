//! The reconstruction proper, in the canonical frame: orient2d, orient3d, partings, direction,
//! init and DR, each saved as it is made (or reloaded from an earlier run before `from`) and scored
//! when the capture has ground truth.

use super::record::finished;
use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::eval::Evaluator;
use crate::report::{Report, StageClock};
use crate::stages::direction::DirectionOut;
use crate::stages::init::InitOut;
use crate::stages::orient2d::Orient2dOut;
use crate::stages::orient3d::Orient3dOut;
use crate::stages::partings::PartingsOut;
use crate::stages::{self, Context};

/// The stages from `from` (orient2d or later) to `last`, recorded in `report`.
pub(super) fn run_stages(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    report: &mut Report,
    from: Stage,
    last: Stage,
) -> Result<(), ReconError> {
    let raw = || ctx.raw();
    let eval = Evaluator::new(ctx.capture, &raw);
    let runs = |s: Stage| from <= s && s <= last;
    let t = StageClock::start();
    let maps = if runs(Stage::Orient2d) {
        let o = stages::orient2d::run(ctx, cfg)?;
        o.save(ctx, cfg.write_pictures)?;
        finished(ctx, report, Stage::Orient2d, t, &())?;
        report.scores.orient2d = eval.orient2d(&o.maps)?;
        o.maps
    } else {
        Orient2dOut::load(ctx, from)?.maps
    };
    if last == Stage::Orient2d {
        return Ok(());
    }

    let t = StageClock::start();
    let points = if runs(Stage::Orient3d) {
        let o = stages::orient3d::run(ctx, cfg, &maps)?;
        o.save(ctx)?;
        finished(ctx, report, Stage::Orient3d, t, &())?;
        report.scores.orient3d = eval.points(&o.points)?;
        Some(o.points)
    } else if runs(Stage::Direction) {
        Some(Orient3dOut::load(ctx, from)?.points)
    } else {
        None
    };
    if last == Stage::Orient3d {
        return Ok(());
    }

    let t = StageClock::start();
    let scalp = if runs(Stage::Partings) {
        let o = stages::partings::run(ctx, cfg)?;
        o.save(ctx)?;
        finished(ctx, report, Stage::Partings, t, &o.stats)?;
        o.scalp
    } else {
        PartingsOut::load(ctx, from, &cfg.parting)?.scalp
    };
    if last == Stage::Partings {
        return Ok(());
    }

    let t = StageClock::start();
    let directed = match points {
        Some(points) => {
            let o = stages::direction::run(ctx, cfg, &points, &scalp)?;
            o.save(ctx)?;
            finished(ctx, report, Stage::Direction, t, &o.stats)?;
            report.scores.direction = eval.directions(&o.directed)?;
            o.directed
        }
        None if runs(Stage::Init) => DirectionOut::load(ctx, from)?.directed,
        None => Default::default(),
    };
    if last == Stage::Direction {
        return Ok(());
    }

    let t = StageClock::start();
    let init = if runs(Stage::Init) {
        let o = stages::init::run(ctx, cfg, &directed, &scalp, &maps)?;
        o.save(ctx)?;
        finished(ctx, report, Stage::Init, t, &o.stats)?;
        report.warnings.extend(o.stats.hull_warning.clone());
        if let (Some(axes), Some(c)) = (&o.seen_axes, o.info.curl) {
            report.scores.axes = eval.axes(axes, &c)?;
        }
        ctx.progress.update("metrics", 0.0, "scoring strands");
        report.scores.init_guides = eval.strands(&o.guides)?;
        report.scores.init_strands = eval.strands(&o.children)?;
        o
    } else {
        InitOut::load(ctx, from)?
    };
    drop(directed);
    if last == Stage::Init {
        ctx.write_result("guides.hair", &init.guides)?;
        ctx.write_result("strands.hair", &init.children)?;
        if let Some(r) = report.stages.iter_mut().find(|r| r.stage == Stage::Init) {
            r.files.extend(ctx.take_written());
        }
        return Ok(());
    }

    let t = StageClock::start();
    let o = stages::dr::run(ctx, cfg, init, maps, &scalp)?;
    o.save(ctx)?;
    finished(ctx, report, Stage::Dr, t, &o.stats)?;
    ctx.progress.update("metrics", 0.5, "scoring strands");
    report.scores.dr_guides = eval.strands(&o.guides)?;
    report.scores.dr_strands = eval.strands(&o.children)?;
    ctx.progress.update("dr", 1.0, "");
    Ok(())
}
