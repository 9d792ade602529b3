//! The runner of `hairrecon reconstruct`: the stages of [`crate::stages`] in order, each output
//! saved as it is made, evaluation ([`crate::eval`]) beside the run when the capture has ground
//! truth, and a report ([`crate::report`]). It has three parts: `place` runs stages `head` and
//! `masks` (the capture in its files' frame, placed in the canonical frame and masked), `chain` the
//! stages after them, and `record` what every stage shares (a failed stage's files removed, a finished
//! stage recorded in the report).
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
use crate::progress::Progress;
use crate::report::{Report, RunStatus};
use crate::stages::Context;

mod chain;
mod place;
mod record;

use record::guarded;

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

/// Every stage from `from` to `last`, recorded in `report`: stages `head` and `masks`
/// ([`place::place`]), then the rest on the capture they place ([`chain::run_stages`]).
fn run_all(
    capture: &Capture,
    out_dir: &Path,
    cfg: &ReconstructConfig,
    report: &mut Report,
    from: Stage,
    last: Stage,
    progress: &dyn Progress,
) -> Result<(), ReconError> {
    let Some(masked) = place::place(capture, out_dir, cfg, report, from, last, progress)? else {
        return Ok(());
    };
    report.warnings.extend(place::missing_masks_warning(&masked));
    report.save(&out_dir.join("report.json"))?;
    let ctx = Context::new(&masked, out_dir, progress);
    guarded(&ctx, || chain::run_stages(&ctx, cfg, report, from.max(Stage::Orient2d), last))
}
