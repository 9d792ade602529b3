//! Stage `masks`: hair masks ([`crate::masks`]) for the views that have none, from the raw mesh,
//! the photos and the head (the capture's, or the fitted one of stage `head`). Masks a user gave
//! are kept. A capture whose views all have masks skips the stage and saves nothing.
//!
//! Saves `masks/<view>.png` (16-bit) for the views it made masks for, `hair_region.ply` (the raw
//! mesh in its file's frame, each vertex's hair probability as its quality) and `masks.json`
//! (what `hairrecon masks` prints), which a resumed run reloads.

use std::path::Path;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::write_mesh_with_quality;
use hairrecon_core::image_io::write_png16_gray;

use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::masks::capture_masks::{report, HAIR_REGION, MASKS_DIR, MASKS_JSON};
use crate::masks::{make_masks, MaskError, MaskSet};
use crate::stages::{mkdir, need, write_json, Context};

/// The masks made, with the names of the views they are for.
#[derive(Debug)]
pub struct MasksOut {
    pub set: MaskSet,
    /// The views that had no mask (the ones whose masks are saved).
    pub views: Vec<String>,
    /// What `masks.json` holds.
    pub report: serde_json::Value,
}

/// Whether the capture needs the stage.
pub fn needed(capture: &Capture, cfg: &ReconstructConfig) -> bool {
    cfg.make_masks && capture.views.iter().any(|v| v.mask.is_none())
}

fn mask_file(view: &str) -> String {
    format!("{MASKS_DIR}/{view}.png")
}

/// Makes the masks of `ctx.capture` (in the canonical frame, with a head and a scalp).
pub fn run(ctx: &Context<'_>, cfg: &ReconstructConfig) -> Result<MasksOut, ReconError> {
    let t = std::time::Instant::now();
    let set = make_masks(ctx.capture, &cfg.masks, ctx.progress).map_err(|e| match e {
        MaskError::Cancelled(c) => ReconError::Cancelled(c),
        e => ReconError::Masks(e.to_string()),
    })?;
    let names: Vec<String> = ctx.capture.views.iter().map(|v| v.name.clone()).collect();
    let report = report(&set, &names, None, &cfg.masks, t.elapsed().as_secs_f64());
    let views = ctx.capture.views.iter().filter(|v| v.mask.is_none()).map(|v| v.name.clone()).collect();
    Ok(MasksOut { set, views, report })
}

impl MasksOut {
    /// Writes the masks of the views without one, the hair region and `masks.json`.
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        mkdir(&ctx.path(MASKS_DIR))?;
        for (view, alpha) in ctx.capture.views.iter().zip(&self.set.alphas) {
            if self.views.contains(&view.name) {
                write_png16_gray(ctx.output(&mask_file(&view.name)), alpha)?;
            }
        }
        // The raw mesh as its file has it: the region's vertices are the file's, in order.
        let raw = hairrecon_core::formats::read_mesh(&ctx.capture.raw_mesh)?;
        write_mesh_with_quality(ctx.output(HAIR_REGION), &raw, &self.set.region)?;
        write_json(&ctx.output(MASKS_JSON), &self.report)
    }

    /// Checks that an earlier run saved the masks of every view without one.
    pub fn check_saved(ctx: &Context<'_>, from: Stage) -> Result<(), ReconError> {
        need(ctx, from, Stage::Masks, MASKS_JSON)?;
        for v in ctx.capture.views.iter().filter(|v| v.mask.is_none()) {
            need(ctx, from, Stage::Masks, &mask_file(&v.name))?;
        }
        Ok(())
    }
}

/// The capture with the saved masks in `out_dir` for the views that had none.
pub fn apply(capture: &Capture, out_dir: &Path) -> Capture {
    let mut c = capture.clone();
    for v in c.views.iter_mut().filter(|v| v.mask.is_none()) {
        v.mask = Some(out_dir.join(mask_file(&v.name)));
    }
    c
}
