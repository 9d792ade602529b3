//! The curl step of the init stage, `--curl auto`: whether the hair is curly, and which curl
//! ([`crate::curl`]). Its result is handed forward to the growth (ringlet axes, helices) and to DR
//! (which keeps curls' shape).
//!
//! Ringlets hang: the handedness whose ringlet axes (at the nominal pitch) point down more is the
//! hair's, and the hair is curly only when those axes point down clearly more (by
//! [`crate::curl::CurlOptions::min_down_gain`]) than the points' own directions, which on straight hair are the
//! strands' and hang the most. Looser curls (a smaller pitch: a wider period for their radius) turn
//! the tangents less, so axes turned by the nominal pitch overshoot them and hang no better than the
//! tangents; when the nominal pitch finds no curls, the lower pitches of
//! [`crate::curl::CurlOptions::lower_pitches_deg`] are tried in turn, each asking a gain in proportion to
//! what perfect ringlets of that pitch would gain (`1 − cos θ` of a strand hanging along its axis);
//! the first that finds curls gives the axes. Then the period is read off the hair surface's bumps
//! along those axes ([`crate::curl::bump_period`]), and the radius is the one that gives the nominal
//! pitch at that period ([`crate::curl::CurlOptions::nominal_pitch_deg`]), whichever pitch found
//! the curls: the lower pitches only decide that the hair is curly (on a curly capture found at 50°
//! the radius of a 50° pitch scored 9 points lower; docs/reconstruction.md, "Looser curls"). The
//! pitch is assumed, not measured: the points see the ringlets' visible side only, where the
//! tangents are the same at every turn.
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
use crate::curl::{
    bump_period, hang, mean_down, ringlet_axes_from_normals, surface_normals, sweep_helices, BumpReport, Curl,
    CurlOptions,
};
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

/// The ringlet axes at one pitch: how much they hang.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PitchTest {
    pub pitch_deg: f32,
    /// Mean downward component of the right- and left-handed axes.
    pub down_right: f32,
    pub down_left: f32,
    /// How much more than the points' directions the better of them must hang for curls.
    pub min_gain: f32,
}

/// What `auto` measured and how it chose.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CurlChoiceReport {
    /// Mean downward component of the points' directions.
    pub down_tangents: f32,
    /// The pitches tried, the nominal first, until one found curls.
    pub pitches: Vec<PitchTest>,
    /// The handedness and pitch of the curls found (the last pitch tried when none).
    pub hand: f32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch_deg: Option<f32>,
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
    let (found, mut report) = find_curls(directed, raw, co, progress)?;
    let Some(Found { hand, mut axes }) = found else {
        return Ok((None, report));
    };
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
            let tan = co.nominal_pitch_deg.to_radians().tan();
            let c = Curl { radius: period * tan / std::f32::consts::TAU, period, hand };
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

/// Curls found by [`find_curls`]: their handedness and the ringlet axes (not hung).
struct Found {
    hand: f32,
    axes: OrientedPoints,
}

/// Whether the hair is curly: the nominal pitch, then the lower ones, until the better-hanging
/// handedness's axes hang more than the points' directions by the pitch's share of
/// [`crate::curl::CurlOptions::min_down_gain`] (see the module doc).
fn find_curls(
    directed: &OrientedPoints,
    raw: &TriMesh,
    co: &CurlOptions,
    progress: &dyn Progress,
) -> Result<(Option<Found>, CurlChoiceReport), ReconError> {
    let down_tangents = mean_down(directed);
    let mut report = CurlChoiceReport { down_tangents, ..Default::default() };
    let nominal_gain = 1.0 - co.nominal_pitch_deg.to_radians().cos();
    let lower = co.lower_pitches_deg.iter().copied().filter(|&p| p > 0.0);
    let normals = surface_normals(directed, raw, co).ok_or(ReconError::CurlGrid)?;
    for pitch_deg in std::iter::once(co.nominal_pitch_deg).chain(lower) {
        progress.check()?;
        progress.update("init", 0.55, &format!("curls: handedness at a {pitch_deg}° pitch"));
        let tan = pitch_deg.to_radians().tan();
        let curl =
            |hand: f32| Curl { radius: co.periods[1] * tan / std::f32::consts::TAU, period: co.periods[1], hand };
        let right = ringlet_axes_from_normals(directed, &normals, &curl(1.0), co).ok_or(ReconError::CurlGrid)?;
        let left = ringlet_axes_from_normals(directed, &normals, &curl(-1.0), co).ok_or(ReconError::CurlGrid)?;
        let (down_right, down_left) = (mean_down(&right), mean_down(&left));
        let min_gain = co.min_down_gain * (1.0 - pitch_deg.to_radians().cos()) / nominal_gain;
        report.pitches.push(PitchTest { pitch_deg, down_right, down_left, min_gain });
        let (hand, axes, down) =
            if down_right >= down_left { (1.0, right, down_right) } else { (-1.0, left, down_left) };
        report.hand = hand;
        if down >= down_tangents + min_gain {
            report.pitch_deg = Some(pitch_deg);
            return Ok((Some(Found { hand, axes }), report));
        }
    }
    Ok((None, report))
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::curl::test_util::{helix, plane_facing_x};
    use crate::progress::NoProgress;

    /// The visible (x > r/2) samples of five ringlets of `curl` hanging along -z side by side, with
    /// their tangents, and the hair surface before them (a plane facing +x).
    fn ringlets(curl: &Curl) -> (OrientedPoints, TriMesh) {
        let (mut positions, mut directions) = (Vec::new(), Vec::new());
        for (j, y0) in [-0.06f32, -0.03, 0.0, 0.03, 0.06].iter().enumerate() {
            let h = helix(curl, 0.15, j as f32);
            for k in 1..h.len() - 1 {
                if h[k].x > 0.5 * curl.radius {
                    positions.push(h[k] + Vec3::new(0.0, *y0, 0.0));
                    directions.push((h[k + 1] - h[k - 1]).normalize());
                }
            }
        }
        let n = positions.len();
        let raw = plane_facing_x(curl.radius, [-0.12, 0.12], [-0.4, -0.04]);
        (OrientedPoints { positions, directions, confidence: vec![1.0; n] }, raw)
    }

    #[test]
    fn loose_curls_are_found_at_a_lower_pitch_and_straight_hair_at_none() {
        let co = CurlOptions::default();
        // Right-handed ringlets of a 35° pitch (radius 6.7 mm, period 60 mm): axes turned by the
        // nominal 60° overshoot them by 25° and hang about as much as the tangents; at 50° they
        // are 15° off and hang clearly more.
        let loose = Curl { radius: 0.0067, period: 0.06, hand: 1.0 };
        assert!((loose.pitch_angle().to_degrees() - 35.0).abs() < 0.5);
        let (points, raw) = ringlets(&loose);
        let (found, report) = find_curls(&points, &raw, &co, &NoProgress).unwrap();
        let found = found.expect("curls found");
        assert_eq!((found.hand, report.pitch_deg), (1.0, Some(50.0)), "{report:?}");
        assert_eq!(report.pitches.len(), 2, "{report:?}");
        let [nominal, lower] = [report.pitches[0], report.pitches[1]];
        assert!(nominal.down_right < report.down_tangents + nominal.min_gain, "{report:?}");
        assert!(lower.down_right > lower.down_left, "{report:?}");
        // The gain asked at 50° is the nominal's times (1 - cos 50°) / (1 - cos 60°).
        assert!((lower.min_gain - co.min_down_gain * 0.7144).abs() < 1e-4, "{report:?}");
        // The paper's tight ringlets (6.5 mm, 22 mm: 62°) are found at the nominal pitch.
        let (points, raw) = ringlets(&crate::curl::test_util::CURL);
        let (found, report) = find_curls(&points, &raw, &co, &NoProgress).unwrap();
        assert!(found.is_some() && report.pitch_deg == Some(60.0), "{report:?}");
        // Hair hanging straight down is curly at no pitch.
        let straight = OrientedPoints {
            positions: points.positions.clone(),
            directions: vec![-Vec3::Z; points.len()],
            confidence: points.confidence.clone(),
        };
        let (found, report) = find_curls(&straight, &raw, &co, &NoProgress).unwrap();
        assert!(found.is_none() && report.pitch_deg.is_none(), "{report:?}");
        assert_eq!(report.pitches.len(), 2, "{report:?}");
    }
}
