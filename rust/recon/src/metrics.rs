//! Per-stage metrics against ground truth, and the small kd-tree index they share.
//!
//! In: a stage's output (oriented points, directed points, strands) and the capture's ground-truth
//! strands. Out: plain numbers (serialisable) that `hairrecon reconstruct` prints and writes to
//! `metrics.json`. Definitions follow the evaluation protocol of `docs/method.md` (points matched
//! at a distance and an angle, undirected = |cos|):
//! - oriented points: *precision* = share of points with a ground-truth point within 2 mm whose
//!   tangent is within 20° (undirected); *coverage* = share of the ground-truth points of the
//!   visible hair surface (within `surface_band` of the raw mesh) that have such a point.
//! - directed points: *agreement* = among points matched (undirected, 2 mm/20°), the share whose
//!   direction also points the same way as the ground-truth tangent (dot > 0).
//! - ringlet axes (curly hair, [`crate::curl`]): each point is matched to the nearest ground-truth
//!   strand sample within 2 mm, whose axis is the tangent of that strand's centreline over one turn
//!   of arc; *within_20* = share of matched points whose axis is within 20° of it (undirected),
//!   *directed_within_20* the same with the sign.
//!
//! The strand metric itself (precision/recall/F1) is `hairrecon_core::metric`.

use std::num::NonZero;

use glam::Vec3;
use hairrecon_core::StrandSet;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// Points with unit tangents and a kd-tree over the points.
#[derive(Debug)]
pub struct PointIndex {
    pub points: Vec<Vec3>,
    pub tangents: Vec<Vec3>,
    tree: ImmutableKdTree<f32, 3>,
}

impl PointIndex {
    pub fn new(points: Vec<Vec3>, tangents: Vec<Vec3>) -> Self {
        let arr: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::new_from_slice(&arr);
        Self { points, tangents, tree }
    }

    /// Strand points resampled every `step` metres with root→tip unit tangents.
    pub fn from_strands(strands: &StrandSet, step: f32) -> Self {
        let (points, tangents) = sample_strands(strands, step);
        Self::new(points, tangents)
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Indices of the `k` nearest points (nearest first), at most `len()`.
    pub fn nearest(&self, p: Vec3, k: usize) -> Vec<(usize, f32)> {
        if self.points.is_empty() || k == 0 {
            return Vec::new();
        }
        let k = NonZero::new(k.min(self.points.len())).unwrap_or(NonZero::<usize>::MIN);
        self.tree
            .nearest_n::<SquaredEuclidean>(&p.to_array(), k)
            .into_iter()
            .map(|n| (n.item as usize, n.distance.sqrt()))
            .collect()
    }

    /// Indices of the points within `r` (any order).
    pub fn within(&self, p: Vec3, r: f32) -> Vec<usize> {
        if self.points.is_empty() {
            return Vec::new();
        }
        self.tree
            .within_unsorted::<SquaredEuclidean>(&p.to_array(), r * r)
            .into_iter()
            .map(|n| n.item as usize)
            .collect()
    }

    /// The best match of an undirected query within `dist` and `angle` (radians): the index of the
    /// point with the largest |cos| among those in range, if any passes.
    pub fn match_undirected(&self, p: Vec3, t: Vec3, dist: f32, angle: f32) -> Option<usize> {
        let cmin = angle.cos();
        let mut best: Option<(usize, f32)> = None;
        for i in self.within(p, dist) {
            let c = self.tangents[i].dot(t).abs();
            if c >= cmin && best.is_none_or(|(_, b)| c > b) {
                best = Some((i, c));
            }
        }
        best.map(|b| b.0)
    }
}

/// Samples strands every `step` (arc length) with unit tangents (root → tip).
pub fn sample_strands(strands: &StrandSet, step: f32) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut pts = Vec::new();
    let mut tans = Vec::new();
    for s in strands.iter() {
        let mut carry = 0.0f32;
        for w in s.windows(2) {
            let d = w[1] - w[0];
            let len = d.length();
            if len <= 1e-9 {
                continue;
            }
            let t = d / len;
            let mut a = carry;
            while a < len {
                pts.push(w[0] + t * a);
                tans.push(t);
                a += step;
            }
            carry = a - len;
        }
    }
    (pts, tans)
}

/// Precision and coverage of oriented points.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PointsScore {
    pub points: u64,
    /// Percent of points matched by the ground truth (undirected).
    pub precision: f64,
    /// Percent of visible ground-truth surface points matched by some point (undirected).
    pub coverage: f64,
    /// Number of ground-truth points counted as the visible surface.
    pub surface_points: u64,
}

/// Scores oriented points against ground truth at `dist`/`angle` (radians). `surface` is the
/// subset of ground-truth point indices that counts as the visible hair surface.
pub fn score_points(
    positions: &[Vec3],
    directions: &[Vec3],
    gt: &PointIndex,
    surface: &[usize],
    dist: f32,
    angle: f32,
) -> PointsScore {
    if positions.is_empty() {
        return PointsScore { surface_points: surface.len() as u64, ..Default::default() };
    }
    let matched = positions
        .par_iter()
        .zip(directions)
        .filter(|(p, d)| gt.match_undirected(**p, **d, dist, angle).is_some())
        .count();
    let pred = PointIndex::new(positions.to_vec(), directions.to_vec());
    let covered = surface
        .par_iter()
        .filter(|&&i| pred.match_undirected(gt.points[i], gt.tangents[i], dist, angle).is_some())
        .count();
    PointsScore {
        points: positions.len() as u64,
        precision: 100.0 * matched as f64 / positions.len() as f64,
        coverage: if surface.is_empty() { 0.0 } else { 100.0 * covered as f64 / surface.len() as f64 },
        surface_points: surface.len() as u64,
    }
}

/// Direction agreement of directed points.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionScore {
    /// Points matched undirected (2 mm/20°) and so judged.
    pub judged: u64,
    /// Percent of judged points whose direction agrees with the ground truth.
    pub agreement: f64,
}

/// How well points' directions follow the ground truth's ringlet axes.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxisScore {
    /// Points within the match distance of a ground-truth strand, and so judged.
    pub judged: u64,
    /// Percent of judged points within 20° of the axis, undirected.
    pub within_20: f64,
    /// The same, directed.
    pub directed_within_20: f64,
    /// Median undirected angle to the axis, degrees.
    pub median_deg: f64,
}

/// The ground truth's ringlet axes: every strand's samples (every `step`) with the tangent of its
/// centreline over `turn_arc` of arc ([`crate::curl::centreline`]), as an index.
pub fn gt_axes(gt: &StrandSet, turn_arc: f32, step: f32) -> PointIndex {
    let per: Vec<(Vec<Vec3>, Vec<Vec3>)> = gt
        .iter()
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|s| {
            let one = StrandSet::new(s.to_vec(), vec![s.len() as u32]).ok()?.resample_by_arclength(step).ok()?;
            let r = one.points();
            let c = crate::curl::centreline(s, turn_arc, step)?;
            // The centreline is resampled along its own (shorter) arc: pair by arc fraction.
            let n = r.len().min(c.len());
            let tangent = |k: usize| (c[(k + 1).min(c.len() - 1)] - c[k.saturating_sub(1)]).normalize_or_zero();
            let pts = r[..n].to_vec();
            let tans = (0..n).map(|k| tangent(k * (c.len() - 1) / (r.len() - 1).max(1))).collect();
            Some((pts, tans))
        })
        .collect();
    let (mut points, mut tangents) = (Vec::new(), Vec::new());
    for (p, t) in per {
        points.extend(p);
        tangents.extend(t);
    }
    PointIndex::new(points, tangents)
}

/// Scores `directions` at `positions` against the ground-truth axes of [`gt_axes`].
pub fn score_axes(positions: &[Vec3], directions: &[Vec3], axes: &PointIndex, dist: f32) -> AxisScore {
    let mut cosines: Vec<f32> = positions
        .par_iter()
        .zip(directions)
        .filter_map(|(p, d)| {
            let (i, r) = *axes.nearest(*p, 1).first()?;
            (r <= dist).then(|| axes.tangents[i].dot(*d))
        })
        .collect();
    let n = cosines.len();
    if n == 0 {
        return AxisScore::default();
    }
    let c20 = 20f32.to_radians().cos();
    let within = cosines.iter().filter(|c| c.abs() >= c20).count();
    let directed = cosines.iter().filter(|c| **c >= c20).count();
    cosines.iter_mut().for_each(|c| *c = c.abs());
    cosines.sort_by(|a, b| b.total_cmp(a));
    AxisScore {
        judged: n as u64,
        within_20: 100.0 * within as f64 / n as f64,
        directed_within_20: 100.0 * directed as f64 / n as f64,
        median_deg: cosines[n / 2].clamp(-1.0, 1.0).acos().to_degrees() as f64,
    }
}

/// Share of points (among those matched undirected) whose direction agrees with the ground truth.
pub fn score_directions(
    positions: &[Vec3],
    directions: &[Vec3],
    gt: &PointIndex,
    dist: f32,
    angle: f32,
) -> DirectionScore {
    let (judged, agree) = positions
        .par_iter()
        .zip(directions)
        .filter_map(|(p, d)| {
            gt.match_undirected(*p, *d, dist, angle).map(|i| (1u64, (gt.tangents[i].dot(*d) > 0.0) as u64))
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    DirectionScore { judged, agreement: if judged == 0 { 0.0 } else { 100.0 * agree as f64 / judged as f64 } }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_strand_match_it() {
        let s = StrandSet::new(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.1)], vec![2]).unwrap();
        let gt = PointIndex::from_strands(&s, 0.001);
        assert_eq!(gt.len(), 100);
        let pos = vec![Vec3::new(0.001, 0.0, -0.05), Vec3::new(0.01, 0.0, -0.05), Vec3::new(0.0, 0.0, -0.02)];
        let dir = vec![Vec3::Z, Vec3::Z, Vec3::X];
        let all: Vec<usize> = (0..gt.len()).collect();
        let sc = score_points(&pos, &dir, &gt, &all, 0.002, 20f32.to_radians());
        assert!((sc.precision - 100.0 / 3.0).abs() < 1e-6, "{sc:?}");
        assert!(sc.coverage > 2.0 && sc.coverage < 6.0, "{sc:?}");
        let d = score_directions(&pos, &dir, &gt, 0.002, 20f32.to_radians());
        assert_eq!(d.judged, 1);
        assert_eq!(d.agreement, 0.0);
    }
}
