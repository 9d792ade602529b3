//! The curl step of the init stage, `--curl auto`: whether the hair is curly, and which curl
//! ([`crate::curl`]). Its result is handed forward to the growth (ringlet axes, helices) and to DR
//! (which keeps curls' shape).
//!
//! Ringlets hang: the handedness whose ringlet axes (at the nominal pitch) point down more is the
//! hair's, and the hair is curly only when those axes point down clearly more (by
//! [`crate::curl::CurlOptions::min_down_gain`]) than the points' own directions, which on straight hair are the
//! strands' and hang the most. Then the period is read off the hair surface's bumps along those
//! axes ([`crate::curl::bump_period`]), and the radius is the one that gives the nominal pitch at that
//! period ([`crate::curl::CurlOptions::nominal_pitch_deg`]). The pitch is assumed, not measured: the points see
//! the ringlets' visible side only, where the tangents are the same at every turn.
//!
//! When the surface shows no period (or [`crate::curl::CurlOptions::bump_period`] is off), strands are grown
//! along the axes and the curl (of the radii and periods of the options) whose helices about them
//! fit the Gabor orientation maps best ([`crate::dr::optimize::orientation_misfit`], on a subset of
//! children and views) is chosen. That misfit prefers wide radii (it rewards how densely the helices
//! are drawn, not their radius), which is why the period from the surface comes first.

use serde::Serialize;

use hairrecon_core::mesh::TriMesh;
use hairrecon_core::StrandSet;

use crate::config::ReconstructConfig;
use crate::curl::{bump_period, hang, mean_down, ringlet_axes, sweep_helices, BumpReport, Curl};
use crate::dr::optimize::orientation_misfit;
use crate::dr::DrTargets;
use crate::error::ReconError;
use crate::oriented_points::OrientedPoints;
use crate::progress::Progress;

/// One curl the misfit tried.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tried {
    pub radius_mm: f32,
    pub period_mm: f32,
    pub misfit: f64,
}

/// What `auto` measured and how it chose.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CurlChoiceReport {
    /// Mean downward component of the right- and left-handed axes, and of the points' directions.
    pub down_right: f32,
    pub down_left: f32,
    pub down_tangents: f32,
    pub hand: f32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bumps: Option<BumpReport>,
    /// `bumps` or `misfit` when curls were chosen.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chosen_by: Option<&'static str>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tried: Vec<Tried>,
}

/// Chooses the curl (`None`: not curly). `targets` makes the orientation targets the misfit
/// needs (only called when the surface shows no period); `grow_children` grows children along
/// some directed points.
pub fn choose(
    directed: &OrientedPoints,
    raw: &TriMesh,
    cfg: &ReconstructConfig,
    targets: &dyn Fn() -> Result<DrTargets, ReconError>,
    grow_children: &dyn Fn(&OrientedPoints) -> Result<StrandSet, ReconError>,
    progress: &dyn Progress,
) -> Result<(Option<Curl>, CurlChoiceReport), ReconError> {
    let co = &cfg.curl_options;
    let tan_nominal = co.nominal_pitch_deg.to_radians().tan();
    let nominal =
        |hand: f32| Curl { radius: co.periods[1] * tan_nominal / std::f32::consts::TAU, period: co.periods[1], hand };
    progress.update("init", 0.55, "curls: handedness");
    let right = ringlet_axes(directed, raw, &nominal(1.0), co).ok_or(ReconError::CurlGrid)?;
    let left = ringlet_axes(directed, raw, &nominal(-1.0), co).ok_or(ReconError::CurlGrid)?;
    let (down_right, down_left, down_tangents) = (mean_down(&right), mean_down(&left), mean_down(directed));
    let (hand, axes, down) = if down_right >= down_left { (1.0, right, down_right) } else { (-1.0, left, down_left) };
    let mut report = CurlChoiceReport { down_right, down_left, down_tangents, hand, ..Default::default() };
    if down < down_tangents + co.min_down_gain {
        return Ok((None, report));
    }
    let mut axes = axes;
    if co.hang {
        hang(&mut axes);
    }
    if co.bump_period {
        progress.check()?;
        progress.update("init", 0.58, "curls: period from the surface");
        let bumps = bump_period(&directed.positions, &axes.directions, &co.bumps);
        let period = bumps.period;
        report.bumps = Some(bumps);
        if let Some(period) = period {
            let c = Curl { radius: period * tan_nominal / std::f32::consts::TAU, period, hand };
            if c.validate().is_ok() {
                report.chosen_by = Some("bumps");
                return Ok((Some(c), report));
            }
        }
    }
    progress.update("init", 0.5, "curls: targets");
    let targets = targets()?;
    progress.update("init", 0.6, "curls: growing along the ringlets");
    let centre = grow_children(&axes)?;
    let nv = targets.views.len();
    let k = co.score_views.clamp(1, nv.max(1));
    let views: Vec<usize> = (0..k).map(|i| i * nv / k).collect();
    let centre = centre.select(&(0..centre.num_strands()).step_by(co.score_every.max(1)).collect::<Vec<_>>());
    let mut best: (f64, Option<Curl>) = (f64::INFINITY, None);
    let n = co.radii.len() * co.periods.len();
    for (i, &radius) in co.radii.iter().enumerate() {
        for (j, &period) in co.periods.iter().enumerate() {
            progress.check()?;
            progress.update("init", 0.6 + 0.1 * (i * co.periods.len() + j) as f32 / n as f32, "curls: scoring");
            let c = Curl { radius, period, hand };
            let misfit =
                orientation_misfit(&sweep_helices(&centre, &c, co, cfg.seed)?, &targets, &views, &cfg.dr_options)?;
            report.tried.push(Tried { radius_mm: radius * 1e3, period_mm: period * 1e3, misfit });
            if misfit < best.0 {
                best = (misfit, Some(c));
            }
        }
    }
    report.chosen_by = Some("misfit");
    Ok((best.1, report))
}
