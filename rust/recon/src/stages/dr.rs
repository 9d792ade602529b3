//! Stage `dr`: the initial strands optimized by differentiable rendering of line segments
//! ([`crate::dr`]): targets from the capture's masks and the orientation maps, the head (else
//! the scalp) hiding what is behind it; the orientation quiet around partings; guides first, then
//! children. Saves `guides.hair`, `strands.hair` (the run's result), `loss.csv` and `loss.png`.

use hairrecon_core::StrandSet;
use serde::Serialize;

use crate::config::{ReconstructConfig, Stage};
use crate::dr::optimize::optimize;
use crate::dr::report::{write_loss_csv, write_loss_png};
use crate::dr::{DrOptions, DrStage, DrTargets, LossRecord};
use crate::error::ReconError;
use crate::orient2d::OrientationMap;
use crate::roots::Scalp;
use crate::stages::init::InitOut;
use crate::stages::sanity::check_strands;
use crate::stages::Context;

/// The losses of one DR stage (guides or children).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageLoss {
    pub steps: usize,
    pub first_loss: Option<f64>,
    pub last_loss: Option<f64>,
    pub seconds_per_step: f64,
}

/// What DR measured.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DrStats {
    pub steps: usize,
    pub targets_seconds: f64,
    pub optimize_seconds: f64,
    pub seconds_per_step: f64,
    pub mean_cg_iterations: f32,
    /// Whether DR kept the init's curls ([`DrOptions::keeping_curls`]).
    pub keeps_curls: bool,
    /// Orientation pixels quieted around partings.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parting_pixels_quieted: Option<usize>,
    pub guides: StageLoss,
    pub children: StageLoss,
}

/// The optimized strands.
#[derive(Debug, Clone)]
pub struct DrOut {
    pub guides: StrandSet,
    pub children: StrandSet,
    pub loss_curve: Vec<LossRecord>,
    pub stats: DrStats,
}

/// Optimizes the strands of [`crate::stages::init`]. Takes the init's strands and the orientation
/// maps, so that neither outlives the targets and the steps (50,000 children of ~250 points:
/// 150 MB; the paper preset's maps: 115 MB).
pub fn run(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    init: InitOut,
    maps: Vec<OrientationMap>,
    scalp: &Scalp,
) -> Result<DrOut, ReconError> {
    let t = std::time::Instant::now();
    ctx.progress.update("dr", 0.0, "targets");
    let inner = ctx.inner()?;
    let mut targets = DrTargets::from_capture(ctx.capture, &maps, Some(inner), ctx.progress)?;
    drop(maps);
    let parting_pixels_quieted = match scalp.partings() {
        Some(p) if cfg.parting.quiet_orientation => Some(targets.quiet_partings(p)),
        _ => None,
    };
    let targets_seconds = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    // The guide stage's child map blends as many guides as growing did.
    let keeps_curls = init.info.curl.is_some() && cfg.dr_keep_curls;
    let base = if keeps_curls { cfg.dr_options.keeping_curls() } else { cfg.dr_options.clone() };
    let options = DrOptions { child_blend: cfg.grow.blend, ..base };
    let r = optimize(init.guides, init.children, &targets, scalp.bvh(), Some(inner), &options, ctx.progress)?;
    let optimize_seconds = t.elapsed().as_secs_f64();
    ctx.progress.check()?;
    let losses = |stage| {
        let recs: Vec<_> = r.loss_curve.iter().filter(|x| x.stage == stage).collect();
        let secs: f64 = recs.iter().map(|x| x.seconds as f64).sum();
        StageLoss {
            steps: recs.len(),
            first_loss: recs.first().map(|x| x.terms.total()),
            last_loss: recs.last().map(|x| x.terms.total()),
            seconds_per_step: if recs.is_empty() { 0.0 } else { secs / recs.len() as f64 },
        }
    };
    let steps = r.loss_curve.len();
    let stats = DrStats {
        steps,
        targets_seconds,
        optimize_seconds,
        seconds_per_step: if steps > 0 { optimize_seconds / steps as f64 } else { 0.0 },
        mean_cg_iterations: r.mean_cg_iterations,
        keeps_curls,
        parting_pixels_quieted,
        guides: losses(DrStage::Guides),
        children: losses(DrStage::Children),
    };
    let raw_box = ctx.raw_bbox()?;
    check_strands(Stage::Dr, "guides", &r.guides, raw_box)?;
    check_strands(Stage::Dr, "strands", &r.children, raw_box)?;
    Ok(DrOut { guides: r.guides, children: r.children, loss_curve: r.loss_curve, stats })
}

impl DrOut {
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        write_loss_csv(&ctx.output("loss.csv"), &self.loss_curve)?;
        write_loss_png(&ctx.output("loss.png"), &self.loss_curve)?;
        ctx.write_result("guides.hair", &self.guides)?;
        ctx.write_result("strands.hair", &self.children)?;
        Ok(())
    }
}
