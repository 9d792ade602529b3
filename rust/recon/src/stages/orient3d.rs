//! Stage `orient3d`: oriented 3D points near the hair surface by line MVS on the raw mesh
//! ([`crate::points3d`]). Saves `points3d.ply`.

use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::orient2d::{GrayImage, OrientationMap};
use crate::oriented_points::OrientedPoints;
use crate::points3d::{estimate, MvsView};
use crate::stages::{need, Context};

const FILE: &str = "points3d.ply";

/// The oriented (undirected) points.
#[derive(Debug, Clone, PartialEq)]
pub struct Orient3dOut {
    pub points: OrientedPoints,
}

/// The points from the maps of every view.
pub fn run(ctx: &Context<'_>, cfg: &ReconstructConfig, maps: &[OrientationMap]) -> Result<Orient3dOut, ReconError> {
    ctx.progress.update("orient3d", 0.0, "loading the raw mesh");
    let raw = ctx.raw()?;
    ctx.progress.check()?;
    let images: Vec<GrayImage> =
        ctx.capture.views.iter().map(|v| GrayImage::load(&v.image)).collect::<Result<_, _>>()?;
    let views = MvsView::for_capture(ctx.capture, maps, &images);
    let points = estimate(&views, raw, &cfg.mvs, ctx.progress)?;
    if points.is_empty() {
        return Err(ReconError::EmptyStage {
            stage: Stage::Orient3d,
            what: "no 3D hair points",
            cause: "no hair pixel matched across views; check that the masks show the hair (not all black), that at \
                    least two views see it, and that the cameras look at the raw mesh",
        });
    }
    Ok(Orient3dOut { points })
}

impl Orient3dOut {
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        Ok(self.points.save_ply(&ctx.output(FILE))?)
    }

    pub fn load(ctx: &Context<'_>, from: Stage) -> Result<Self, ReconError> {
        Ok(Self { points: OrientedPoints::load_ply(&need(ctx, from, Stage::Orient3d, FILE)?)? })
    }
}
