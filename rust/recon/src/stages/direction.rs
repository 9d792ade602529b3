//! Stage `direction`: the points' root-to-tip directions ([`crate::direction`]): the global
//! optimization from the scalp, or the gravity heuristic (`global_opt = false`). Saves
//! `points_directed.ply`.

use crate::config::{ReconstructConfig, Stage};
use crate::direction::{global_directions, gravity_directions, DirectionStats};
use crate::error::ReconError;
use crate::oriented_points::OrientedPoints;
use crate::roots::Scalp;
use crate::stages::{need, Context};

const FILE: &str = "points_directed.ply";

/// The directed points.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionOut {
    pub directed: OrientedPoints,
    pub stats: Option<DirectionStats>,
}

/// Directs the points of [`crate::stages::orient3d`].
pub fn run(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    points: &OrientedPoints,
    scalp: &Scalp,
) -> Result<DirectionOut, ReconError> {
    ctx.progress.update("direction", 0.0, "");
    Ok(if cfg.global_opt {
        let (directed, stats) = global_directions(points, scalp, &cfg.direction);
        DirectionOut { directed, stats: Some(stats) }
    } else {
        DirectionOut { directed: gravity_directions(points), stats: None }
    })
}

impl DirectionOut {
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        Ok(self.directed.save_ply(&ctx.output(FILE))?)
    }

    pub fn load(ctx: &Context<'_>, from: Stage) -> Result<Self, ReconError> {
        Ok(Self { directed: OrientedPoints::load_ply(&need(ctx, from, Stage::Direction, FILE)?)?, stats: None })
    }
}
