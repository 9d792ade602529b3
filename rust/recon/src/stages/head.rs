//! Stage `head`: the head fit ([`crate::head_fit`]) of a capture that lacks what the later stages
//! need: the similarity to the canonical frame (an imported capture not yet placed), the scalp,
//! or the head that the masks tell skin from hair by. What the capture gives is kept; the fit
//! fills in the rest.
//!
//! Saves `fitted_head.ply` and `fitted_scalp.ply` (in the frame and units of the capture's
//! files, as the user's own would be) and `head_fit.json` (the fit, and what it filled in), which
//! a resumed run reloads. A capture that lacks nothing skips the stage and saves nothing.

use std::path::Path;

use hairrecon_core::capture::{Capture, FrameSpec};
use hairrecon_core::formats::write_mesh;
use serde::{Deserialize, Serialize};

use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::head_fit::capture_fit::{
    capture_landmarks, fit_files, fit_json, Template, FITTED_HEAD, FITTED_SCALP, HEAD_FIT_JSON,
};
use crate::head_fit::FitOptions;
use crate::stages::{need, write_json, Context};

/// What the fit gave the capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeadOut {
    /// The similarity to the canonical frame (an imported capture that had none).
    pub to_canonical: Option<FrameSpec>,
    /// Whether the fitted head stands in for a missing `head_mesh`.
    pub head: bool,
    /// Whether the fitted scalp stands in for a missing `scalp_mesh`.
    pub scalp: bool,
    /// The fit (see [`fit_json`]).
    pub fit: serde_json::Value,
}

/// Why a capture needs the stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Need {
    /// It has what the later stages need.
    No,
    /// Only for the masks of views without one (they need the head): when the fit fails, the run
    /// goes on without those masks, with a warning.
    ForMasks,
    /// It has no frame (an imported capture not yet placed) or no scalp: no run without the fit.
    Required,
}

/// Whether the capture (as loaded, in its files' frame) needs the stage, with `make_masks` when
/// masks will be made for views without them.
pub fn needed(capture: &Capture, make_masks: bool) -> Need {
    let unplaced = !capture.is_canonical() && capture.to_canonical.is_none();
    let masks_need_head = make_masks && capture.head_mesh.is_none() && capture.views.iter().any(|v| v.mask.is_none());
    if unplaced || capture.scalp_mesh.is_none() {
        Need::Required
    } else if masks_need_head {
        Need::ForMasks
    } else {
        Need::No
    }
}

/// Fits the bundled head to the raw mesh of `ctx.capture` (as loaded, in its files' frame).
pub fn run(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
) -> Result<(HeadOut, [Option<hairrecon_core::TriMesh>; 2]), ReconError> {
    let cap = ctx.capture;
    ctx.progress.update("head", 0.0, "fitting the head template to the raw mesh");
    let defaults = FitOptions::default();
    let opts = FitOptions {
        max_exposed_fraction: cfg.head_fit.max_exposed_fraction,
        deform: defaults.deform.clone().filter(|_| cfg.head_fit.shape),
        ..defaults
    };
    let cameras: Vec<_> = cap.views.iter().map(|v| v.camera).collect();
    let cams = cfg.head_fit.use_cameras.then_some(cameras.as_slice());
    // The user's landmarks, when the capture has them (landmarks.json beside capture.json).
    let landmarks = capture_landmarks(&cap.dir).map_err(|e| ReconError::HeadFit(e.to_string()))?;
    let (fit, head, scalp) =
        fit_files(&cap.raw_mesh, cams, &Template::bundled(), landmarks.as_ref(), &opts).map_err(|e| {
            ReconError::HeadFit(format!(
                "{e}. Give the capture a scalp and head (scalp_mesh, head_mesh and, for an imported capture, \
             to_canonical in capture.json; `hairrecon fit-head {} --write` writes them where a fit succeeds)",
                cap.dir.display()
            ))
        })?;
    ctx.progress.check()?;
    let unplaced = !cap.is_canonical() && cap.to_canonical.is_none();
    let out = HeadOut {
        to_canonical: unplaced.then(|| FrameSpec::of(&fit.to_canonical)),
        head: cap.head_mesh.is_none(),
        scalp: cap.scalp_mesh.is_none(),
        fit: fit_json(&fit),
    };
    let meshes = [out.head.then_some(head), out.scalp.then_some(scalp)];
    Ok((out, meshes))
}

impl HeadOut {
    /// Writes the fitted meshes the capture lacked and `head_fit.json`.
    pub fn save(&self, ctx: &Context<'_>, meshes: &[Option<hairrecon_core::TriMesh>; 2]) -> Result<(), ReconError> {
        for (name, mesh) in [FITTED_HEAD, FITTED_SCALP].into_iter().zip(meshes) {
            if let Some(m) = mesh {
                write_mesh(ctx.output(name), m)?;
            }
        }
        write_json(&ctx.output(HEAD_FIT_JSON), self)
    }

    /// What an earlier run's stage saved in `out_dir`.
    pub fn load(ctx: &Context<'_>, from: Stage) -> Result<Self, ReconError> {
        let path = need(ctx, from, Stage::Head, HEAD_FIT_JSON)?;
        let bad = |msg: String| ReconError::StageFile { stage: Stage::Head, path: path.clone(), msg };
        let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
        let out: Self = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if out.to_canonical.is_some_and(|s| s.similarity().is_none()) {
            return Err(bad("its to_canonical is not a similarity".into()));
        }
        for (name, used) in [(FITTED_HEAD, out.head), (FITTED_SCALP, out.scalp)] {
            if used {
                need(ctx, from, Stage::Head, name)?;
            }
        }
        Ok(out)
    }

    /// The capture with what the fit filled in: the frame, and the fitted head and scalp (files in
    /// `out_dir`) where it had none.
    pub fn apply(&self, capture: &Capture, out_dir: &Path) -> Capture {
        let mut c = capture.clone();
        if let Some(s) = self.to_canonical.and_then(|s| s.similarity()) {
            c.to_canonical = Some(s);
        }
        if self.head {
            c.head_mesh = Some(out_dir.join(FITTED_HEAD));
        }
        if self.scalp {
            c.scalp_mesh = Some(out_dir.join(FITTED_SCALP));
        }
        c
    }
}
