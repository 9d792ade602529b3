//! The runner of `hairrecon reconstruct`: the stages of [`crate::stages`] in order, each output
//! saved as it is made, evaluation ([`crate::eval`]) beside the run when the capture has ground
//! truth, and a report ([`crate::report`]).
//!
//! `--from STAGE` reloads what an earlier run saved in the same folder for the stages before
//! STAGE; `--stop-after STAGE` stops there. A run owns its folder ([`crate::run_folder`]): at its
//! start it clears what an earlier run left there for the stages it makes again (and refuses a
//! folder that is not a run's unless `Plan::overwrite`). It writes `report.json` (status
//! `running`) and `config.json` (the whole configuration) first, the report again after each
//! stage with the files the stage wrote, and last with the outcome.
//!
//! Cancellation: stages check `progress` between views, chunks, solver iterations and DR steps;
//! a cancelled run returns [`ReconError::Cancelled`] and writes no result (`strands.hair`). Every
//! file is written through a temporary file and a rename, so a cancelled or failed run leaves the
//! stages it finished, complete, and nothing of the stage it was in (what that stage had written
//! is removed); its report says `cancelled` or `failed` and lists what is there.

use std::path::{Path, PathBuf};

use hairrecon_core::capture::Capture;

use crate::config::{ConfigFile, Plan, ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::eval::Evaluator;
use crate::progress::Progress;
use crate::report::{Report, RunStatus, StageClock};
use crate::stages::direction::DirectionOut;
use crate::stages::head::{HeadOut, Need};
use crate::stages::init::InitOut;
use crate::stages::masks::MasksOut;
use crate::stages::orient2d::Orient2dOut;
use crate::stages::orient3d::Orient3dOut;
use crate::stages::partings::PartingsOut;
use crate::stages::{self, remove, Context};

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
    let stop = plan.stop_after.unwrap_or(Stage::Dr);
    let last = if cfg.dr { stop } else { stop.min(Stage::Init) };
    let from = plan.from;
    if from > last {
        return Err(ReconError::EmptyPlan { from, stop: last });
    }
    // The capture as given is checked before anything is written, in the canonical frame; an
    // imported capture that no head fit has placed yet is checked once stage `head` has.
    if let Some(given) = capture.in_canonical_frame().map_err(ReconError::Capture)? {
        crate::preflight::check(&given)?;
        // Cancelled while the meshes were checked: the earlier run's files are still whole.
        progress.check()?;
    }
    let _lock = crate::run_folder::lock(out_dir)?;
    crate::run_folder::claim(out_dir, &plan, &capture.dir)?;
    let mut report = Report::resumed(&capture.dir, out_dir, from);
    report.save(&out_dir.join("report.json"))?;
    ConfigFile::new(cfg.clone()).save(&out_dir.join("config.json"))?;
    // The report is written whatever happens: a cancelled or failed run lists the stages it finished.
    let run = run_all(capture, out_dir, cfg, &mut report, from, last, progress);
    (report.status, report.message) = match &run {
        Ok(()) => (RunStatus::Complete, None),
        Err(e) => {
            let status = if matches!(e, ReconError::Cancelled(_)) { RunStatus::Cancelled } else { RunStatus::Failed };
            (status, Some(e.to_string()))
        }
    };
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

/// A warning when views have no hair mask: every pixel of such a view counts as hair (DR's
/// silhouette, the 3D points, the visual hull, the partings), which a photo's background is not.
pub fn missing_masks_warning(capture: &Capture) -> Option<String> {
    let without: Vec<&str> = capture.views.iter().filter(|v| v.mask.is_none()).map(|v| v.name.as_str()).collect();
    if without.is_empty() {
        return None;
    }
    let which = if without.len() == capture.views.len() {
        "no view has a hair mask".to_string()
    } else {
        format!("{} of {} views have no hair mask (first: {})", without.len(), capture.views.len(), without[0])
    };
    Some(format!(
        "{which}: every pixel of those views counts as hair; make masks from the raw mesh and the photos with \
         `hairrecon masks {} --write` (after `hairrecon fit-head {} --write` if the capture has no head)",
        capture.dir.display(),
        capture.dir.display()
    ))
}

/// Runs `f`, a stage on `ctx`; when it fails, what it wrote goes (as far as it can: the error to
/// report is the stage's).
fn guarded<T>(ctx: &Context<'_>, f: impl FnOnce() -> Result<T, ReconError>) -> Result<T, ReconError> {
    let r = f();
    if r.is_err() {
        for f in ctx.take_written() {
            let _ = remove(&ctx.path(&f));
        }
    }
    r
}

/// Every stage from `from` to `last`, recorded in `report`: stage `head` on the capture as loaded
/// (its files' frame), then, in the canonical frame, stage `masks` and the rest ([`run_stages`]).
fn run_all(
    capture: &Capture,
    out_dir: &Path,
    cfg: &ReconstructConfig,
    report: &mut Report,
    from: Stage,
    last: Stage,
    progress: &dyn Progress,
) -> Result<(), ReconError> {
    let runs = |s: Stage| from <= s && s <= last;
    let need = stages::head::needed(capture, cfg.make_masks);
    let head = if need == Need::No {
        None
    } else {
        let ctx = Context::new(capture, out_dir, progress);
        let made = if runs(Stage::Head) {
            let t = StageClock::start();
            let made = guarded(&ctx, || {
                let (o, meshes) = stages::head::run(&ctx, cfg)?;
                o.save(&ctx, &meshes)?;
                Ok(o)
            });
            if let Ok(o) = &made {
                finished(&ctx, report, Stage::Head, t, &o.fit)?;
            }
            made
        } else {
            HeadOut::load(&ctx, from)
        };
        match made {
            Ok(o) => Some(o),
            // Wanted only for the masks: the run goes on without them (a warning says so below).
            Err(ReconError::HeadFit(msg)) if need == Need::ForMasks => {
                report.warnings.push(format!("no hair masks were made: the head fit failed: {msg}"));
                None
            }
            Err(ReconError::MissingStageOutput { .. }) if need == Need::ForMasks => None,
            Err(e) => return Err(e),
        }
    };
    let placed = match &head {
        Some(h) => h.apply(capture, out_dir),
        None => capture.clone(),
    };
    let Some(placed) = placed.in_canonical_frame().map_err(ReconError::Capture)? else {
        return Err(ReconError::NotCanonical {
            dir: capture.dir.clone(),
            frame: capture.frame.name().into(),
            units: capture.units.name().into(),
        });
    };
    if head.is_some() {
        // What the fit made, checked as a user's meshes are.
        crate::preflight::check(&placed)?;
    }
    if last == Stage::Head {
        return Ok(());
    }

    // Masks need a head: without one (a fit that failed) the views stay without masks.
    let masked = if stages::masks::needed(&placed, cfg) && placed.head_mesh.is_some() {
        let ctx = Context::new(&placed, out_dir, progress);
        if runs(Stage::Masks) {
            let t = StageClock::start();
            let o = guarded(&ctx, || {
                let o = stages::masks::run(&ctx, cfg)?;
                o.save(&ctx)?;
                Ok(o)
            })?;
            finished(&ctx, report, Stage::Masks, t, &o.report)?;
        } else {
            MasksOut::check_saved(&ctx, from)?;
        }
        stages::masks::apply(&placed, out_dir)
    } else {
        placed
    };
    if last == Stage::Masks {
        return Ok(());
    }
    report.warnings.extend(missing_masks_warning(&masked));
    report.save(&out_dir.join("report.json"))?;
    let ctx = Context::new(&masked, out_dir, progress);
    guarded(&ctx, || run_stages(&ctx, cfg, report, from.max(Stage::Orient2d), last))
}

/// The stages from `from` (orient2d or later) to `last`, recorded in `report`.
fn run_stages(
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

/// Records a finished stage (its time, statistics and the files it wrote) and saves the report,
/// so that a run killed outright still says what it finished.
fn finished(
    ctx: &Context<'_>,
    report: &mut Report,
    stage: Stage,
    start: StageClock,
    stats: &impl serde::Serialize,
) -> Result<(), ReconError> {
    let (seconds, cpu_seconds) = start.elapsed();
    report.record(stage, seconds, cpu_seconds, stats, ctx.take_written());
    report.save(&ctx.path("report.json"))
}
