//! The strand metric: precision, recall and F1 of predicted strands against ground truth.
//!
//! Follows the evaluation protocol of `docs/method.md` (consistent with Nam et al. 2019, Rosu et al.
//! 2022 and the Dr.Hair paper's Table 1): both strand sets are resampled uniformly by arc length
//! (default 1 mm) into points with unit tangents (root → tip). A point of set A is *matched* when
//! some point of set B lies within distance `d` AND their tangents differ by less than angle `θ`.
//! Precision is the matched share of predicted points, recall the matched share of ground-truth
//! points, F1 their harmonic mean, all in percent. Two modes: *directed* (a reversed strand does not
//! match) and *undirected* (180°-tolerant, compares |cos|). Default thresholds: 1 mm/10°, 2 mm/20°,
//! 3 mm/30°.
//!
//! Matching uses a kd-tree (kiddo's `ImmutableKdTree`) over each set: one nearest-neighbour query
//! settles most points, and a radius query is made only when the nearest point fails the angle test
//! (see [`OrientedPoints::match_mask`]); along strands, the neighbours of the previous match are
//! tried first (see [`OrientedPoints::match_counts`]); points are processed in parallel with rayon.

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use serde::Serialize;

use crate::strands::{StrandError, StrandSet};

/// One distance/angle threshold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Threshold {
    /// Distance in metres.
    pub dist: f32,
    /// Angle in degrees.
    pub angle_deg: f32,
}

/// The paper's thresholds: 1 mm/10°, 2 mm/20°, 3 mm/30°.
pub const PAPER_THRESHOLDS: [Threshold; 3] = [
    Threshold { dist: 0.001, angle_deg: 10.0 },
    Threshold { dist: 0.002, angle_deg: 20.0 },
    Threshold { dist: 0.003, angle_deg: 30.0 },
];

/// Most thresholds one evaluation handles (flags are kept in a bit mask).
pub const MAX_THRESHOLDS: usize = 16;

/// Options of [`evaluate`].
#[derive(Debug, Clone, PartialEq)]
pub struct MetricOptions {
    /// Arc-length resampling step in metres (default 1 mm).
    pub step: f32,
    pub thresholds: Vec<Threshold>,
}

impl Default for MetricOptions {
    fn default() -> Self {
        Self { step: 0.001, thresholds: PAPER_THRESHOLDS.to_vec() }
    }
}

/// Scores at one threshold, in percent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Score {
    pub dist_mm: f32,
    pub angle_deg: f32,
    pub precision: f64,
    pub recall: f64,
    pub f1: f64,
}

/// Scores in both modes, one entry per threshold in the order given.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricReport {
    pub directed: Vec<Score>,
    pub undirected: Vec<Score>,
}

/// Points with unit tangents and a kd-tree over the points: one side of the comparison.
#[derive(Debug)]
pub struct OrientedPoints {
    pub points: Vec<Vec3>,
    pub tangents: Vec<Vec3>,
    tree: ImmutableKdTree<f32, 3>,
}

impl OrientedPoints {
    /// Builds the kd-tree over oriented points (tangents should be unit vectors; zero never matches).
    pub fn new(points: Vec<Vec3>, tangents: Vec<Vec3>) -> Self {
        assert_eq!(points.len(), tangents.len(), "one tangent per point");
        let arr: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::new_from_slice(&arr);
        Self { points, tangents, tree }
    }

    /// Resamples strands by arc length with `step` and builds the tree.
    pub fn from_strands(strands: &StrandSet, step: f32) -> Result<Self, StrandError> {
        let r = strands.resample_by_arclength(step)?;
        let t = r.tangents();
        let (points, _) = r.into_parts();
        Ok(Self::new(points, t))
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// For a query point and tangent, a bit mask: bit `i` is set when some point of this set
    /// matches under threshold `i` in directed mode, bit `MAX_THRESHOLDS + i` in undirected mode.
    /// `thresholds` must be sorted by distance and hold at most [`MAX_THRESHOLDS`] entries; `cos`
    /// holds the cosines of their angles.
    ///
    /// Exact, and cheap in the common case: one nearest-neighbour query settles every threshold
    /// closer than the nearest point (unmatched) and, when the nearest point passes the angle test,
    /// every other one (matched). Only a threshold the nearest point fails on angle needs a radius
    /// query.
    pub fn match_mask(&self, p: Vec3, t: Vec3, thresholds: &[Threshold], cos: &[f32]) -> u32 {
        self.match_mask_nearest(p, t, thresholds, cos).0
    }

    /// [`Self::match_mask`] and the index of the nearest point (`u32::MAX` when none was searched).
    fn match_mask_nearest(&self, p: Vec3, t: Vec3, thresholds: &[Threshold], cos: &[f32]) -> (u32, u32) {
        let n = thresholds.len();
        if self.points.is_empty() || t == Vec3::ZERO || n == 0 {
            return (0, u32::MAX);
        }
        let q = p.to_array();
        // Bounded by the widest threshold: a query far from every point (a strand the other set
        // lacks) then prunes the tree at once instead of searching it for a far nearest point.
        let dmax = thresholds.iter().fold(0.0f32, |m, t| m.max(t.dist));
        let one = std::num::NonZeroUsize::MIN;
        let Some(nearest) = self.tree.nearest_n_within::<SquaredEuclidean>(&q, dmax * dmax, one, true).pop() else {
            return (0, u32::MAX);
        };
        let d0 = nearest.distance;
        let c0 = self.tangents[nearest.item as usize].dot(t);
        let mut mask = 0u32;
        for i in 0..n {
            let di2 = thresholds[i].dist * thresholds[i].dist;
            if d0 > di2 {
                continue; // nothing within d_i at all
            }
            let (mut dir, mut und) = (c0 > cos[i], c0.abs() > cos[i]);
            if !(dir && und) {
                // The nearest point fails the angle test: look at every point within d_i.
                for nb in self.tree.within_unsorted::<SquaredEuclidean>(&q, di2) {
                    let c = self.tangents[nb.item as usize].dot(t);
                    dir |= c > cos[i];
                    und |= c.abs() > cos[i];
                    if dir && und {
                        break;
                    }
                }
            }
            mask |= (dir as u32) << i | (und as u32) << (MAX_THRESHOLDS + i);
        }
        (mask, nearest.item as u32)
    }

    /// Counts, per threshold, the points of `query` matched by this set: `(directed, undirected)`.
    ///
    /// Queries run in parallel over chunks in the query's own order (along its strands). Each query
    /// first tries the points next to the previous query's nearest point: when thresholds grow in
    /// both distance and angle, one of them matching the tightest threshold proves a match at every
    /// threshold, in both modes, without a tree search. Along well-reconstructed strands that settles
    /// most points; the result is exactly that of [`Self::match_mask`] for every point.
    pub fn match_counts(&self, query: &OrientedPoints, thresholds: &[Threshold]) -> (Vec<u64>, Vec<u64>) {
        let cos: Vec<f32> = thresholds.iter().map(|t| t.angle_deg.to_radians().cos()).collect();
        let n = thresholds.len();
        let all = ((1u32 << n) - 1) | (((1u32 << n) - 1) << MAX_THRESHOLDS);
        let monotone = thresholds.windows(2).all(|w| w[0].dist <= w[1].dist && w[0].angle_deg <= w[1].angle_deg);
        let (d1, c1) = (thresholds.first().map_or(0.0, |t| t.dist), cos.first().copied().unwrap_or(1.0));
        let last = self.points.len() as i64 - 1;
        let idx: Vec<u32> = (0..query.points.len() as u32).collect();
        idx.par_chunks(4096)
            .fold(
                || (vec![0u64; n], vec![0u64; n]),
                |(mut dir, mut und), chunk| {
                    let mut hint = u32::MAX;
                    for &k in chunk {
                        let (p, t) = (query.points[k as usize], query.tangents[k as usize]);
                        let mut m = 0;
                        if monotone && hint != u32::MAX && t != Vec3::ZERO {
                            for c in [hint as i64 + 1, hint as i64, hint as i64 + 2] {
                                let c = c.clamp(0, last) as usize;
                                if self.points[c].distance_squared(p) <= d1 * d1 && self.tangents[c].dot(t) > c1 {
                                    m = all;
                                    hint = c as u32;
                                    break;
                                }
                            }
                        }
                        if m == 0 {
                            let (mm, nearest) = self.match_mask_nearest(p, t, thresholds, &cos);
                            m = mm;
                            hint = nearest;
                        }
                        for i in 0..n {
                            dir[i] += ((m >> i) & 1) as u64;
                            und[i] += ((m >> (MAX_THRESHOLDS + i)) & 1) as u64;
                        }
                    }
                    (dir, und)
                },
            )
            .reduce(
                || (vec![0u64; n], vec![0u64; n]),
                |(mut a, mut b), (c, d)| {
                    for i in 0..n {
                        a[i] += c[i];
                        b[i] += d[i];
                    }
                    (a, b)
                },
            )
    }
}

/// Why an evaluation could not run.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum MetricError {
    #[error(transparent)]
    Strands(#[from] StrandError),
    #[error("between 1 and {MAX_THRESHOLDS} thresholds are needed, got {0}")]
    ThresholdCount(usize),
    #[error("threshold {0} has a non-positive or non-finite distance or angle")]
    BadThreshold(usize),
}

/// Scores predicted strands against ground truth. Empty sets score 0.
pub fn evaluate(pred: &StrandSet, gt: &StrandSet, opts: &MetricOptions) -> Result<MetricReport, MetricError> {
    let a = OrientedPoints::from_strands(pred, opts.step)?;
    let b = OrientedPoints::from_strands(gt, opts.step)?;
    evaluate_points(&a, &b, &opts.thresholds)
}

/// Scores two sets of oriented points (already sampled).
pub fn evaluate_points(
    pred: &OrientedPoints,
    gt: &OrientedPoints,
    thresholds: &[Threshold],
) -> Result<MetricReport, MetricError> {
    if thresholds.is_empty() || thresholds.len() > MAX_THRESHOLDS {
        return Err(MetricError::ThresholdCount(thresholds.len()));
    }
    if let Some(i) = thresholds
        .iter()
        .position(|t| !(t.dist.is_finite() && t.dist > 0.0 && t.angle_deg.is_finite() && t.angle_deg > 0.0))
    {
        return Err(MetricError::BadThreshold(i));
    }
    // Sort thresholds by distance for the growing-radius queries; report in the caller's order.
    let mut order: Vec<usize> = (0..thresholds.len()).collect();
    order.sort_by(|&i, &j| thresholds[i].dist.total_cmp(&thresholds[j].dist));
    let sorted: Vec<Threshold> = order.iter().map(|&i| thresholds[i]).collect();
    let (p_dir, p_und) = gt.match_counts(pred, &sorted);
    let (r_dir, r_und) = pred.match_counts(gt, &sorted);
    let mut directed = vec![None; thresholds.len()];
    let mut undirected = vec![None; thresholds.len()];
    for (k, &i) in order.iter().enumerate() {
        directed[i] = Some(score(thresholds[i], p_dir[k], pred.len(), r_dir[k], gt.len()));
        undirected[i] = Some(score(thresholds[i], p_und[k], pred.len(), r_und[k], gt.len()));
    }
    Ok(MetricReport {
        directed: directed.into_iter().flatten().collect(),
        undirected: undirected.into_iter().flatten().collect(),
    })
}

fn score(th: Threshold, p_hit: u64, p_n: usize, r_hit: u64, r_n: usize) -> Score {
    let precision = if p_n == 0 { 0.0 } else { 100.0 * p_hit as f64 / p_n as f64 };
    let recall = if r_n == 0 { 0.0 } else { 100.0 * r_hit as f64 / r_n as f64 };
    let f1 = if precision + recall > 0.0 { 2.0 * precision * recall / (precision + recall) } else { 0.0 };
    Score { dist_mm: th.dist * 1000.0, angle_deg: th.angle_deg, precision, recall, f1 }
}

impl MetricReport {
    /// A table like the paper's Table 1: one row per mode, P/R/F1 per threshold.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let head: Vec<String> =
            self.directed.iter().map(|t| format!("{:>5.0}mm/{:.0}°", t.dist_mm, t.angle_deg)).collect();
        s.push_str(&format!("{:<11}", "threshold"));
        for h in &head {
            s.push_str(&format!("{:>24}", h));
        }
        s.push('\n');
        s.push_str(&format!("{:<11}", "measure"));
        for _ in &head {
            s.push_str(&format!("{:>8}{:>8}{:>8}", "P", "R", "F1"));
        }
        s.push('\n');
        for (name, rows) in [("directed", &self.directed), ("undirected", &self.undirected)] {
            s.push_str(&format!("{:<11}", name));
            for r in rows {
                s.push_str(&format!("{:>8.1}{:>8.1}{:>8.1}", r.precision, r.recall, r.f1));
            }
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` straight parallel strands along Z, `spacing` apart along X, 10 cm long, 11 points.
    fn parallel(n: usize, spacing: f32, offset: Vec3) -> StrandSet {
        let mut pts = Vec::new();
        for i in 0..n {
            for j in 0..11 {
                pts.push(Vec3::new(i as f32 * spacing, 0.0, 0.01 * j as f32) + offset);
            }
        }
        StrandSet::new(pts, vec![11; n]).unwrap()
    }

    fn f1s(r: &[Score]) -> Vec<f64> {
        r.iter().map(|s| (s.f1 * 1e6).round() / 1e6).collect()
    }

    #[test]
    fn identical_sets_score_100() {
        let a = parallel(20, 0.01, Vec3::ZERO);
        let r = evaluate(&a, &a, &MetricOptions::default()).unwrap();
        assert_eq!(f1s(&r.directed), vec![100.0; 3]);
        assert_eq!(f1s(&r.undirected), vec![100.0; 3]);
    }

    #[test]
    fn perpendicular_shift_of_1_5_mm() {
        let gt = parallel(20, 0.01, Vec3::ZERO);
        let pred = parallel(20, 0.01, Vec3::new(0.0015, 0.0, 0.0));
        let r = evaluate(&pred, &gt, &MetricOptions::default()).unwrap();
        assert_eq!(f1s(&r.directed), vec![0.0, 100.0, 100.0]);
        assert_eq!(f1s(&r.undirected), vec![0.0, 100.0, 100.0]);
    }

    #[test]
    fn reversed_strands_match_only_undirected() {
        let gt = parallel(20, 0.01, Vec3::ZERO);
        let r = evaluate(&gt.reversed(), &gt, &MetricOptions::default()).unwrap();
        assert_eq!(f1s(&r.directed), vec![0.0; 3]);
        assert_eq!(f1s(&r.undirected), vec![100.0; 3]);
    }

    #[test]
    fn angle_threshold_and_partial_recall() {
        // Half the strands: precision 100, recall 50.
        let gt = parallel(10, 0.01, Vec3::ZERO);
        let half = gt.select(&[0, 2, 4, 6, 8]);
        let r = evaluate(&half, &gt, &MetricOptions::default()).unwrap();
        for s in &r.directed {
            assert!((s.precision - 100.0).abs() < 1e-9);
            assert!((s.recall - 50.0).abs() < 1e-9);
            assert!((s.f1 - 200.0 / 3.0).abs() < 1e-9);
        }
        // Isolated strands (1 m apart) tilted by 15 degrees about the root: a point at height z lies
        // z sin 15 from the other line, so it matches at d when z <= d / sin 15 (and never at 10 deg).
        let gt = parallel(3, 1.0, Vec3::ZERO);
        let (c, s) = (15f32.to_radians().cos(), 15f32.to_radians().sin());
        let tilted = gt.map_points(|p| Vec3::new(p.x + s * p.z, p.y, c * p.z)).unwrap();
        let r = evaluate(&tilted, &gt, &MetricOptions::default()).unwrap();
        assert_eq!(r.directed[0].f1, 0.0);
        // 101 samples per strand at 1 mm; z = 0..7 mm match at 2 mm (7.7 mm), z = 0..11 at 3 mm (11.6 mm).
        for (k, n) in [(1, 8.0), (2, 12.0)] {
            let want = 100.0 * n / 101.0;
            assert!((r.directed[k].precision - want).abs() < 1.0, "{:?} vs {want}", r.directed[k]);
            assert!((r.directed[k].recall - want).abs() < 1.0, "{:?} vs {want}", r.directed[k]);
        }
        assert_eq!(r.directed, r.undirected);
    }

    #[test]
    fn shortcut_counts_equal_the_full_search() {
        // Random wiggly strands, and a prediction that matches some and misses others.
        let mut seed = 99u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32 - 0.5
        };
        let mut make = |jitter: f32| {
            let mut pts = Vec::new();
            for i in 0..200 {
                let root = Vec3::new((i % 20) as f32 * 0.002, (i / 20) as f32 * 0.002, 0.0);
                let off = Vec3::new(rnd(), rnd(), rnd()) * jitter;
                for j in 0..30 {
                    let z = -0.002 * j as f32;
                    pts.push(root + off + Vec3::new(0.002 * (z * 300.0).sin(), 0.001 * rnd() * jitter * 100.0, z));
                }
            }
            StrandSet::new(pts, vec![30; 200]).unwrap()
        };
        let gt = make(0.0);
        let pred = make(0.004);
        let a = OrientedPoints::from_strands(&pred, 0.001).unwrap();
        let b = OrientedPoints::from_strands(&gt, 0.001).unwrap();
        let cos: Vec<f32> = PAPER_THRESHOLDS.iter().map(|t| t.angle_deg.to_radians().cos()).collect();
        let mut want = (vec![0u64; 3], vec![0u64; 3]);
        for (&p, &t) in a.points.iter().zip(&a.tangents) {
            let m = b.match_mask(p, t, &PAPER_THRESHOLDS, &cos);
            for i in 0..3 {
                want.0[i] += ((m >> i) & 1) as u64;
                want.1[i] += ((m >> (MAX_THRESHOLDS + i)) & 1) as u64;
            }
        }
        let got = b.match_counts(&a, &PAPER_THRESHOLDS);
        assert_eq!(got, want);
        assert!(want.0[0] > 0 && want.0[0] < a.len() as u64, "the case must mix matches and misses: {want:?}");
    }

    #[test]
    fn empty_prediction_scores_zero() {
        let gt = parallel(3, 0.01, Vec3::ZERO);
        let r = evaluate(&StrandSet::empty(), &gt, &MetricOptions::default()).unwrap();
        assert!(r.directed.iter().all(|s| s.f1 == 0.0 && s.recall == 0.0));
    }
}
