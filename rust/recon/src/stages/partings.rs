//! Stage `partings`: the scalp, with the skin that the views see on it ([`crate::parting`]): where
//! there is skin, S(p_s) turns away from it. Saves `partings.ply` (the skin points, with the
//! scalp's normal) when any skin is found, and removes an earlier run's file otherwise; and
//! `partings.json`, the search's statistics, which tells a resumed run that the stage ran.

use hairrecon_core::scalp::Partings;

use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::oriented_points::OrientedPoints;
use crate::parting::{find_partings, PartingParams, PartingStats};
use crate::roots::Scalp;
use crate::stages::{need, remove, write_json, Context};

const FILE: &str = "partings.ply";
const STATS: &str = "partings.json";

/// The scalp with its partings set.
#[derive(Debug)]
pub struct PartingsOut {
    pub scalp: Scalp,
    /// What the search found (`None` when partings are off or the output was reloaded).
    pub stats: Option<PartingStats>,
}

fn load_scalp(ctx: &Context<'_>) -> Result<Scalp, ReconError> {
    let path = ctx.scalp_path()?;
    Scalp::new(ctx.capture.read_mesh(path)?).map_err(|source| ReconError::Scalp { path: path.into(), source })
}

/// Reads the scalp and finds its partings (unless `cfg.parting.enabled` is false).
pub fn run(ctx: &Context<'_>, cfg: &ReconstructConfig) -> Result<PartingsOut, ReconError> {
    ctx.progress.update("partings", 0.0, "");
    let mut scalp = load_scalp(ctx)?;
    ctx.progress.check()?;
    let (found, stats) = if cfg.parting.enabled {
        let (p, stats) = find_partings(ctx.capture, &scalp, ctx.inner()?, &cfg.parting, "partings", ctx.progress)?;
        (p, Some(stats))
    } else {
        (None, None)
    };
    scalp.set_partings(found);
    Ok(PartingsOut { scalp, stats })
}

impl PartingsOut {
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        match self.scalp.partings() {
            Some(p) => OrientedPoints {
                positions: p.skin().to_vec(),
                directions: p.skin().iter().map(|&q| self.scalp.closest_root(q).normal).collect(),
                confidence: vec![1.0; p.skin().len()],
            }
            .save_ply(&ctx.output(FILE))?,
            None => remove(&ctx.path(FILE))?,
        }
        write_json(&ctx.output(STATS), &self.stats)
    }

    /// The scalp with the partings an earlier run saved (none when it saved no file).
    pub fn load(ctx: &Context<'_>, from: Stage, params: &PartingParams) -> Result<Self, ReconError> {
        need(ctx, from, Stage::Partings, STATS)?;
        let mut scalp = load_scalp(ctx)?;
        let path = ctx.path(FILE);
        if params.enabled && path.exists() {
            let skin = OrientedPoints::load_ply(&path)?.positions;
            scalp.set_partings(Some(Partings::new(skin, params.reach, params.strength)));
        }
        Ok(Self { scalp, stats: None })
    }
}
