//! The capture the stages read: stage `head` on the capture as loaded (in its files' frame, when it
//! needs a head, a scalp or a frame), then, in the canonical frame, stage `masks` (when views have no
//! hair mask and the run makes them).

use std::path::Path;

use hairrecon_core::capture::Capture;

use super::record::{finished, guarded};
use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::progress::Progress;
use crate::report::{Report, StageClock};
use crate::stages::head::{HeadOut, Need};
use crate::stages::masks::MasksOut;
use crate::stages::{self, Context};

/// Stages `head` and `masks` from `from` to `last`, recorded in `report`: the capture, placed in
/// the canonical frame and masked, that the later stages read, or `None` when the run ends at
/// one of these two stages.
pub(super) fn place(
    capture: &Capture,
    out_dir: &Path,
    cfg: &ReconstructConfig,
    report: &mut Report,
    from: Stage,
    last: Stage,
    progress: &dyn Progress,
) -> Result<Option<Capture>, ReconError> {
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
            Ok(o) => {
                if let Some(w) = o.fit.get("warning").and_then(|w| w.as_str()) {
                    report.warnings.push(w.to_string());
                }
                Some(o)
            }
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
        return Ok(None);
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
        return Ok(None);
    }
    Ok(Some(masked))
}

/// A warning when views have no hair mask: every pixel of such a view counts as hair (DR's
/// silhouette, the 3D points, the visual hull, the partings), which a photo's background is not.
pub(super) fn missing_masks_warning(capture: &Capture) -> Option<String> {
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
