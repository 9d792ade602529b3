//! Guides smoothed along their length where the directed points agree (straight hair), and every
//! guide cut at `max_length` of arc.

use glam::Vec3;
use hairrecon_core::spatial::PointIndex;
use hairrecon_core::StrandSet;
use rayon::prelude::*;

use super::{coherence_radius, push_out, GrowParams};
use crate::laplace::FlowField;

/// How coherent the directed points along a guide are: the mean angle (radians) of their tangents
/// to their local mean direction, over the guide's points with at least 5 points within `radius`.
fn guide_coherence(guide: &[Vec3], points: &PointIndex, radius: f32) -> Option<f32> {
    let (mut sum, mut n) = (0.0f32, 0u32);
    for (k, p) in guide.iter().enumerate().step_by(2) {
        let near = points.within(*p, radius);
        if near.len() < 5 {
            continue;
        }
        let along = guide[(k + 1).min(guide.len() - 1)] - guide[k.saturating_sub(1)];
        let sign = |t: Vec3| if t.dot(along) < 0.0 { -t } else { t };
        let mean = near.iter().map(|&i| sign(points.tangents[i])).sum::<Vec3>().normalize_or_zero();
        if mean == Vec3::ZERO {
            continue;
        }
        let a: f32 = near.iter().map(|&i| points.tangents[i].dot(mean).abs().min(1.0).acos()).sum();
        sum += a / near.len() as f32;
        n += 1;
    }
    (n > 0).then(|| sum / n as f32)
}

/// `s` with its segment vectors smoothed by a Gaussian of `sigma` segments (weights renormalized at
/// the ends; none shorter than half its own length), rebuilt from its root.
fn smooth_strand(s: &[Vec3], sigma: f32) -> Vec<Vec3> {
    if sigma < 0.1 || s.len() < 3 {
        return s.to_vec();
    }
    let seg: Vec<Vec3> = s.windows(2).map(|w| w[1] - w[0]).collect();
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r).map(|j| (-0.5 * (j as f32 / sigma).powi(2)).exp()).collect();
    let mut out = Vec::with_capacity(s.len());
    out.push(s[0]);
    let mut p = s[0];
    for i in 0..seg.len() as isize {
        let (mut acc, mut ws) = (Vec3::ZERO, 0.0f32);
        for (j, &kw) in (-r..=r).zip(&kernel) {
            if (0..seg.len() as isize).contains(&(i + j)) {
                acc += seg[(i + j) as usize] * kw;
                ws += kw;
            }
        }
        // The mean segment (shorter than the segments where they wiggle: a straightened wiggle
        // does not reach farther), but at least half the segment's own length: where the strand
        // turns back, mean segments near zero would make a cusp the DR's evening cannot even out.
        let (own, mean) = (seg[i as usize], acc / ws);
        let l = mean.length();
        p += if l > 1e-9 { mean * (l.clamp(0.5 * own.length(), own.length()) / l) } else { own };
        out.push(p);
    }
    out
}

/// How many guides [`smooth_guides`] smoothed, and how.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SmoothStats {
    /// Guides smoothed with the whole σ, with part of it, not at all.
    pub full: u64,
    pub partly: u64,
    pub none: u64,
    /// Median coherence angle of the guides' points, degrees (see [`GrowParams::smooth_angles_deg`]).
    pub median_angle_deg: f32,
}

/// Smooths the guides along which the directed points are coherent (straight hair), see
/// [`GrowParams::smooth_sigma`]; points that the smoothing takes into the head are pushed out. A
/// guide without points near it takes the median coherence of the others. Measured at commit
/// 7e468b1 (the init stage alone with 10,000 children scored against every 5th ground-truth strand,
/// paper preset, undirected F1 at 2 mm/20°, 1 mm/10° in brackets): smoothing every guide by
/// σ = 4 mm: straight 71.9 → 74.5 (39.5 → 45.7), wavy 38.0 → 33.0, curly 32.0 → 18.2 (their zig-zags
/// offer tangents that the curls' cone of tangents matches; smooth strands along the curls' axis
/// match none). The guides' median coherence angle: straight 11.1°, wavy 18.0°, curly 17.9°. With
/// the default thresholds 12°/14.5° (1246 / 337 / 417 straight guides smoothed fully / partly /
/// not; curly 20 / 169 / 1811): straight 71.9 → 73.9 (39.5 → 44.0), curly 32.0 → 31.6; thresholds
/// 13°/16°: straight 74.5, wavy 38.0 → 38.5, curly 31.1. At commit 47e5d5a, σ (default thresholds)
/// 4 → 8 / 12 / 20 mm: straight 73.9 → 74.8 / 75.2 / **75.6**, curly 31.6 → 31.3 at 12 and 20 mm,
/// wavy 38.3 → 38.2 at 12 mm; σ 20 mm with thresholds 14°/17° gave straight 76.2 but curly 29.4,
/// σ 30 mm with 15°/18° straight 75.3. At full size (50,000 children) σ 20 mm lifts straight from
/// 81.8 to 83.7 (1 mm/10° 59.7 → 63.3, directed 79.4 → 81.3): the straight guides' wiggles are
/// tracing noise over centimetres. The default since commit 8a37645, when the DR test's one uneven
/// strand (`tests/pipeline_dr.rs`, a max/min segment ratio of 2.02) turned out to be a child
/// blending two guides on either side of a parting, now prevented by
/// [`super::BlendParams::parting_reach`].
pub fn smooth_guides(
    guides: &StrandSet,
    points: Option<&PointIndex>,
    flow: Option<&FlowField>,
    params: &GrowParams,
) -> (StrandSet, SmoothStats) {
    let mut stats = SmoothStats::default();
    let (Some(points), true) = (points, params.smooth_sigma > 0.0 && params.step > 0.0) else {
        stats.none = guides.num_strands() as u64;
        return (cut_at_arc(guides, params.max_length), stats);
    };
    let radius = coherence_radius(params);
    let angles: Vec<Option<f32>> =
        (0..guides.num_strands()).into_par_iter().map(|g| guide_coherence(guides.strand(g), points, radius)).collect();
    let mut known: Vec<f32> = angles.iter().flatten().copied().collect();
    known.sort_by(f32::total_cmp);
    let median = known.get(known.len() / 2).copied().unwrap_or(f32::INFINITY);
    stats.median_angle_deg = median.to_degrees();
    let [lo, hi] = params.smooth_angles_deg.map(f32::to_radians);
    let share = |a: f32| ((hi - a) / (hi - lo).max(1e-6)).clamp(0.0, 1.0);
    let shares: Vec<f32> = angles.iter().map(|a| share(a.unwrap_or(median))).collect();
    let sigma = params.smooth_sigma / params.step;
    let smoothed: Vec<Vec<Vec3>> = (0..guides.num_strands())
        .into_par_iter()
        .map(|g| {
            let mut s = smooth_strand(guides.strand(g), sigma * shares[g]);
            if let Some(flow) = flow {
                for p in s[1..].iter_mut() {
                    *p = push_out(flow, *p, params.head_clearance);
                }
            }
            s
        })
        .collect();
    for &f in &shares {
        match f {
            f if f >= 1.0 => stats.full += 1,
            f if f <= 0.0 => stats.none += 1,
            _ => stats.partly += 1,
        }
    }
    let counts = smoothed.iter().map(|s| s.len() as u32).collect();
    let set = StrandSet::new(smoothed.concat(), counts).unwrap_or_else(|_| guides.clone());
    (cut_at_arc(&set, params.max_length), stats)
}

/// Every strand cut at `max_length` metres of arc (the last point interpolated on its segment).
pub fn cut_at_arc(strands: &StrandSet, max_length: f32) -> StrandSet {
    let mut points = Vec::with_capacity(strands.points().len());
    let mut counts = Vec::with_capacity(strands.num_strands());
    for s in strands.iter() {
        let start = points.len();
        points.push(s[0]);
        let mut arc = 0.0f32;
        for w in s.windows(2) {
            let l = w[0].distance(w[1]);
            if arc + l >= max_length {
                if max_length - arc > 1e-6 {
                    points.push(w[0] + (w[1] - w[0]) * ((max_length - arc) / l.max(1e-12)));
                }
                break;
            }
            arc += l;
            points.push(w[1]);
        }
        if points.len() - start < 2 {
            points.truncate(start);
            points.extend_from_slice(&s[..s.len().min(2)]);
        }
        counts.push((points.len() - start) as u32);
    }
    StrandSet::new(points, counts).unwrap_or_else(|_| strands.clone())
}
