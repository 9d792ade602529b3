//! What every stage of a run shares: a failed stage leaves nothing of its own behind, and a finished
//! one is recorded in the report at once.

use crate::config::Stage;
use crate::error::ReconError;
use crate::report::{Report, StageClock};
use crate::stages::{remove, Context};

/// Runs `f`, a stage on `ctx`; when it fails, what it wrote goes (as far as it can: the error to
/// report is the stage's).
pub(super) fn guarded<T>(ctx: &Context<'_>, f: impl FnOnce() -> Result<T, ReconError>) -> Result<T, ReconError> {
    let r = f();
    if r.is_err() {
        for f in ctx.take_written() {
            let _ = remove(&ctx.path(&f));
        }
    }
    r
}

/// Records a finished stage (its time, statistics and the files it wrote) and saves the report,
/// so that a run killed outright still says what it finished.
pub(super) fn finished(
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
