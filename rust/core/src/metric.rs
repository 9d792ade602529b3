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
//! Matching searches a grid over each set (see [`OrientedPoints::match_counts`]), tightest
//! threshold first: its blocks hold their points sorted by tangent into the cells of a cube map of
//! the sphere, and a cell whose every direction lies farther than the angle threshold from the
//! query's tangent (and, undirected, from its reverse) is skipped. Along strands, the neighbours of
//! the previous match are tried first; points are processed in parallel with rayon.

use glam::Vec3;

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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct Score {
    pub dist_mm: f32,
    pub angle_deg: f32,
    pub precision: f64,
    pub recall: f64,
    pub f1: f64,
}

/// Scores in both modes, one entry per threshold in the order given.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct MetricReport {
    pub directed: Vec<Score>,
    pub undirected: Vec<Score>,
}

/// Cells per cube-face side of the direction cells: 6 × 4 × 4 = 96 cells of at most 16.5° radius.
const BIN_SIDE: usize = 4;
const N_BINS: usize = 6 * BIN_SIDE * BIN_SIDE;

/// The cube-map cell of a non-zero direction: face (±x, ±y, ±z), then the cell on that face.
fn dir_bin(t: Vec3) -> usize {
    let a = t.abs();
    let (face, u, v, m) = if a.x >= a.y && a.x >= a.z {
        (usize::from(t.x < 0.0), t.y, t.z, a.x)
    } else if a.y >= a.z {
        (2 + usize::from(t.y < 0.0), t.x, t.z, a.y)
    } else {
        (4 + usize::from(t.z < 0.0), t.x, t.y, a.z)
    };
    // Equal-angle cells: the face coordinate is the angle atan(w / m) ∈ [-45°, 45°].
    let quarter = std::f32::consts::FRAC_PI_4;
    let cell = |w: f32| ((((w / m).atan() / quarter + 1.0) * 0.5 * BIN_SIDE as f32) as usize).min(BIN_SIDE - 1);
    (face * BIN_SIDE + cell(u)) * BIN_SIDE + cell(v)
}

/// The direction of face angles (u, v) ∈ [-1, 1]² (in units of 45°) on cube face `face` (the
/// inverse of [`dir_bin`]).
fn face_dir(face: usize, u: f32, v: f32) -> Vec3 {
    let s = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
    let quarter = std::f32::consts::FRAC_PI_4;
    let (u, v) = ((u * quarter).tan(), (v * quarter).tan());
    match face / 2 {
        0 => Vec3::new(s, u, v),
        1 => Vec3::new(u, s, v),
        _ => Vec3::new(u, v, s),
    }
    .normalize()
}

/// Centre direction and angular radius of every direction cell.
///
/// Each cell is a convex spherical quadrilateral; its radius is the largest angle from its centre
/// to a corner (a spherical cap under 90° is convex, so the corners bound the cell). A tangent
/// within angle θ of the query's lies in a cell whose centre is within θ + radius of it.
fn dir_cells() -> ([Vec3; N_BINS], [f32; N_BINS]) {
    let mut centres = [Vec3::ZERO; N_BINS];
    let mut radii = [0.0f32; N_BINS];
    let step = 2.0 / BIN_SIDE as f32;
    for face in 0..6 {
        for i in 0..BIN_SIDE {
            for j in 0..BIN_SIDE {
                let b = (face * BIN_SIDE + i) * BIN_SIDE + j;
                let (u0, v0) = (-1.0 + step * i as f32, -1.0 + step * j as f32);
                let c = face_dir(face, u0 + 0.5 * step, v0 + 0.5 * step);
                let corners = [(u0, v0), (u0 + step, v0), (u0, v0 + step), (u0 + step, v0 + step)];
                let r = corners.iter().map(|&(u, v)| face_dir(face, u, v).dot(c).clamp(-1.0, 1.0).acos());
                centres[b] = c;
                // A margin for rounding at cell borders.
                radii[b] = r.fold(0.0, f32::max) + 1e-3;
            }
        }
    }
    (centres, radii)
}

/// A run of points of one block that share a direction cell.
#[derive(Debug, Clone, Copy)]
struct Run {
    bin: u32,
    start: u32,
    end: u32,
}

/// One set's points for radius searches with an angle test: sorted by the block of a regular grid
/// that holds them, and within a block by direction cell, so that a search scans the blocks near
/// the query and, in each, only the runs whose cell can pass the angle test.
#[derive(Debug)]
struct SearchGrid {
    centres: [Vec3; N_BINS],
    radii: [f32; N_BINS],
    origin: Vec3,
    block: f32,
    dims: [usize; 3],
    /// Per block, the index of its first run (one more entry than blocks).
    first_run: Vec<u32>,
    runs: Vec<Run>,
    /// The sorted points with their tangents, side by side (a search reads both).
    oriented: Vec<[Vec3; 2]>,
    /// Each sorted point's index in the set.
    idx: Vec<u32>,
}

impl SearchGrid {
    /// Blocks of side `block_min`, larger when the grid would pass 2^24 blocks.
    fn new(points: &[Vec3], tangents: &[Vec3], block_min: f32) -> Self {
        let (centres, radii) = dir_cells();
        let keep = |t: Vec3| t != Vec3::ZERO && t.is_finite();
        let (lo, hi) = points
            .iter()
            .zip(tangents)
            .filter(|(_, &t)| keep(t))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (&p, _)| (lo.min(p), hi.max(p)));
        let empty = || Self {
            centres,
            radii,
            origin: Vec3::ZERO,
            block: 1.0,
            dims: [0; 3],
            first_run: vec![0],
            runs: Vec::new(),
            oriented: Vec::new(),
            idx: Vec::new(),
        };
        if !(lo.is_finite() && hi.is_finite() && block_min > 0.0) {
            return empty();
        }
        let size = (hi - lo).max(Vec3::splat(1e-6));
        let block = block_min.max((size.x * size.y * size.z / (1u32 << 24) as f32).cbrt());
        let dims = (size / block).floor().to_array().map(|d| d as usize + 1);
        let block_of = |p: Vec3| {
            let c = ((p - lo) / block).floor().to_array();
            let [i, j, l] = [0, 1, 2].map(|a| (c[a].max(0.0) as usize).min(dims[a] - 1));
            (i * dims[1] + j) * dims[2] + l
        };
        let mut keys: Vec<(u64, u32)> = (0..points.len())
            .into_par_iter()
            .filter(|&k| keep(tangents[k]))
            .map(|k| ((block_of(points[k]) * N_BINS + dir_bin(tangents[k])) as u64, k as u32))
            .collect();
        keys.par_sort_unstable();
        let n_blocks = dims[0] * dims[1] * dims[2];
        // One run per distinct (block, cell) key, in key order; then, per block, the index of its
        // first run as a prefix sum of the runs per block.
        let mut runs: Vec<Run> = Vec::new();
        let mut first_run = vec![0u32; n_blocks + 1];
        for (pos, &(key, _)) in keys.iter().enumerate() {
            if pos == 0 || key != keys[pos - 1].0 {
                if let Some(r) = runs.last_mut() {
                    r.end = pos as u32;
                }
                runs.push(Run { bin: (key as usize % N_BINS) as u32, start: pos as u32, end: keys.len() as u32 });
                first_run[key as usize / N_BINS + 1] += 1;
            }
        }
        for b in 0..n_blocks {
            first_run[b + 1] += first_run[b];
        }
        let oriented = keys.iter().map(|&(_, k)| [points[k as usize], tangents[k as usize]]).collect();
        let idx = keys.iter().map(|&(_, k)| k).collect();
        Self { centres, radii, origin: lo, block, dims, first_run, runs, oriented, idx }
    }

    /// Per threshold and direction cell, cos(θ + cell radius): below it the cell holds no match.
    fn cell_limits(&self, thresholds: &[Threshold]) -> Vec<[f32; N_BINS]> {
        let pi = std::f32::consts::PI;
        thresholds
            .iter()
            .map(|th| std::array::from_fn(|b| (th.angle_deg.to_radians() + self.radii[b]).min(pi).cos()))
            .collect()
    }

    /// Whether some point within distance² `d2` of `p` has a tangent with cosine above `cos` to `t`
    /// (looked for when `want.0`) or above `cos` in absolute value (when `want.1`); returns the
    /// `(directed, undirected)` findings and the set's index of a directed match (`u32::MAX` when
    /// none was found). `cos_lim[b]` is cos(θ + radius of cell b): a cell whose centre's cosine to `t`
    /// (directed) or to `±t` (undirected) lies below it holds no match, and its run is skipped (the
    /// cosine is computed for the runs met, not for every cell).
    #[allow(clippy::too_many_arguments)]
    fn search(
        &self,
        p: Vec3,
        t: Vec3,
        d2: f32,
        cos: f32,
        cos_lim: &[f32; N_BINS],
        want: (bool, bool),
    ) -> (bool, bool, u32) {
        if self.runs.is_empty() {
            return (false, false, u32::MAX);
        }
        let (mut dir, mut und) = (!want.0, !want.1);
        let mut found = u32::MAX;
        let d = d2.sqrt();
        let lo = ((p - Vec3::splat(d) - self.origin) / self.block).floor();
        let hi = ((p + Vec3::splat(d) - self.origin) / self.block).floor();
        let top = Vec3::new(self.dims[0] as f32, self.dims[1] as f32, self.dims[2] as f32) - 1.0;
        if hi.cmplt(Vec3::ZERO).any() || lo.cmpgt(top).any() || !(lo.is_finite() && hi.is_finite()) {
            return (false, false, u32::MAX);
        }
        let (lo, hi) = (lo.max(Vec3::ZERO), hi.min(top));
        for i in lo.x as usize..=hi.x as usize {
            for j in lo.y as usize..=hi.y as usize {
                let row = (i * self.dims[1] + j) * self.dims[2];
                let (r0, r1) = (self.first_run[row + lo.z as usize], self.first_run[row + hi.z as usize + 1]);
                for run in &self.runs[r0 as usize..r1 as usize] {
                    // Whether the run's cell may hold a directed match, or an undirected one.
                    let (c, lim) = (self.centres[run.bin as usize].dot(t), cos_lim[run.bin as usize]);
                    let may_hold = (!dir && c >= lim) || (!und && c.abs() >= lim);
                    if !may_hold {
                        continue;
                    }
                    let (a, z) = (run.start as usize, run.end as usize);
                    for (k, [q, s]) in self.oriented[a..z].iter().enumerate() {
                        if q.distance_squared(p) <= d2 {
                            let c = s.dot(t);
                            if !dir && c > cos {
                                dir = true;
                                found = self.idx[a + k];
                            }
                            und |= c.abs() > cos;
                        }
                    }
                    if dir && und {
                        return (want.0, want.1, found);
                    }
                }
            }
        }
        (dir && want.0, und && want.1, found)
    }
}

/// Points with unit tangents: one side of the comparison.
#[derive(Debug)]
pub struct OrientedPoints {
    pub points: Vec<Vec3>,
    pub tangents: Vec<Vec3>,
}

impl OrientedPoints {
    /// Oriented points (tangents should be unit vectors; zero never matches).
    pub fn new(points: Vec<Vec3>, tangents: Vec<Vec3>) -> Self {
        assert_eq!(points.len(), tangents.len(), "one tangent per point");
        Self { points, tangents }
    }

    /// Strand points every `step` metres of arc with their tangents ([`crate::spatial::oriented_samples`]).
    pub fn from_strands(strands: &StrandSet, step: f32) -> Result<Self, StrandError> {
        let (points, tangents) = crate::spatial::oriented_samples(strands, step)?;
        Ok(Self::new(points, tangents))
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// For a query point and tangent, a bit mask: bit `i` is set when some point of this set
    /// matches under threshold `i` in directed mode, bit `MAX_THRESHOLDS + i` in undirected mode.
    /// `found[i]` is set to a point that matches threshold `i` in directed mode (`u32::MAX` when
    /// the search there found none or did not look). `thresholds` must be sorted by distance and
    /// hold at most [`MAX_THRESHOLDS`] entries; `cos` holds the cosines of their angles. With
    /// `monotone` (thresholds growing in both distance and angle), a match at one threshold is
    /// carried to the wider ones without a search.
    ///
    /// Each threshold not yet settled is one search of `grid` within its distance, which scans only
    /// the direction cells that can pass its angle.
    fn match_mask(
        p: Vec3,
        t: Vec3,
        thresholds: &[Threshold],
        cos: &[f32],
        grid: &SearchGrid,
        cos_lim: &[[f32; N_BINS]],
        monotone: bool,
        found: &mut [u32; MAX_THRESHOLDS],
    ) -> u32 {
        found.fill(u32::MAX);
        if t == Vec3::ZERO {
            return 0;
        }
        let mut mask = 0u32;
        let (mut prev_dir, mut prev_und) = (false, false);
        for (i, th) in thresholds.iter().enumerate() {
            let mut dir = monotone && prev_dir;
            let mut und = monotone && prev_und;
            if !(dir && und) {
                let (d, u, f) = grid.search(p, t, th.dist * th.dist, cos[i], &cos_lim[i], (!dir, !und));
                dir |= d;
                und |= u;
                found[i] = f;
            }
            (prev_dir, prev_und) = (dir, und);
            mask |= (dir as u32) << i | (und as u32) << (MAX_THRESHOLDS + i);
        }
        mask
    }

    /// Counts, per threshold, the points of `query` matched by this set: `(directed, undirected)`.
    ///
    /// Queries run in parallel over chunks in the query's own order (along its strands). When the
    /// thresholds grow in both distance and angle, each query first tries, per threshold from the
    /// tightest, the points next to the one that matched the previous query there: a match at one
    /// threshold proves a match at it and every wider one, in both modes, so only the tighter
    /// thresholds are searched in the grid. Along strands that follow the other set's at some
    /// distance that settles most points; the result is exactly that of a search of every point.
    pub fn match_counts(&self, query: &OrientedPoints, thresholds: &[Threshold]) -> (Vec<u64>, Vec<u64>) {
        let cos: Vec<f32> = thresholds.iter().map(|t| t.angle_deg.to_radians().cos()).collect();
        let n = thresholds.len();
        let monotone = thresholds.windows(2).all(|w| w[0].dist <= w[1].dist && w[0].angle_deg <= w[1].angle_deg);
        let last = self.points.len() as i64 - 1;
        // Blocks the size of the tightest threshold: a search at distance d scans about
        // (2d / block + 1)³ blocks, but only the runs of the direction cells that can pass.
        let grid = SearchGrid::new(&self.points, &self.tangents, thresholds.first().map_or(0.0, |t| t.dist));
        let lim = grid.cell_limits(thresholds);
        // Whether point `c` of this set matches `(p, t)` under threshold `i` in directed mode.
        let matches = |c: usize, p: Vec3, t: Vec3, i: usize| {
            self.points[c].distance_squared(p) <= thresholds[i].dist * thresholds[i].dist
                && self.tangents[c].dot(t) > cos[i]
        };
        let idx: Vec<u32> = (0..query.points.len() as u32).collect();
        idx.par_chunks(4096)
            .fold(
                || (vec![0u64; n], vec![0u64; n]),
                |(mut dir, mut und), chunk| {
                    let mut hints = [u32::MAX; MAX_THRESHOLDS];
                    let mut found = [u32::MAX; MAX_THRESHOLDS];
                    for &k in chunk {
                        let (p, t) = (query.points[k as usize], query.tangents[k as usize]);
                        // The tightest threshold a hint settles (n: none), and the point that did.
                        let (mut from, mut by) = (n, u32::MAX);
                        if monotone && t != Vec3::ZERO {
                            'hints: for i in 0..n {
                                let h = hints[i];
                                if h == u32::MAX {
                                    continue;
                                }
                                for c in [h as i64 + 1, h as i64, h as i64 + 2] {
                                    let c = c.clamp(0, last) as usize;
                                    if matches(c, p, t, i) {
                                        (from, by) = (i, c as u32);
                                        break 'hints;
                                    }
                                }
                            }
                        }
                        let wide = ((1u32 << n) - 1) & !((1u32 << from) - 1);
                        let mut m = wide | wide << MAX_THRESHOLDS;
                        if from > 0 {
                            m |= Self::match_mask(p, t, &thresholds[..from], &cos, &grid, &lim, monotone, &mut found);
                        }
                        if monotone {
                            // Each threshold's hint: a point that matched it, or the tighter one's.
                            let mut cur = u32::MAX;
                            for i in 0..n {
                                if i < from && found[i] != u32::MAX {
                                    cur = found[i];
                                } else if i == from {
                                    cur = by;
                                }
                                hints[i] = if (m >> i) & 1 == 1 { cur } else { u32::MAX };
                            }
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
        let want = brute_force_counts(&a, &b, &PAPER_THRESHOLDS);
        let got = b.match_counts(&a, &PAPER_THRESHOLDS);
        assert_eq!(got, want);
        assert!(want.0[0] > 0 && want.0[0] < a.len() as u64, "the case must mix matches and misses: {want:?}");
    }

    /// Per threshold, the points of `query` that some point of `set` matches, by comparing every pair.
    fn brute_force_counts(query: &OrientedPoints, set: &OrientedPoints, ths: &[Threshold]) -> (Vec<u64>, Vec<u64>) {
        let mut want = (vec![0u64; ths.len()], vec![0u64; ths.len()]);
        for (&p, &t) in query.points.iter().zip(&query.tangents) {
            for (i, th) in ths.iter().enumerate() {
                let c = th.angle_deg.to_radians().cos();
                let near =
                    || set.points.iter().zip(&set.tangents).filter(|(q, _)| q.distance_squared(p) <= th.dist * th.dist);
                want.0[i] += near().any(|(_, s)| s.dot(t) > c) as u64;
                want.1[i] += near().any(|(_, s)| s.dot(t).abs() > c) as u64;
            }
        }
        want
    }

    /// A small seeded generator of uniform numbers in [-0.5, 0.5).
    fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32 - 0.5
        }
    }

    fn random_unit(rnd: &mut impl FnMut() -> f32) -> Vec3 {
        loop {
            let v = Vec3::new(rnd(), rnd(), rnd());
            if v.length_squared() > 0.01 && v.length_squared() < 0.25 {
                return v.normalize();
            }
        }
    }

    #[test]
    fn every_direction_lies_in_its_cell() {
        let (centres, radii) = dir_cells();
        let mut rnd = uniform(7);
        let mut axes = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::ONE.normalize()];
        axes.extend((0..20000).map(|_| random_unit(&mut rnd)));
        for t in axes {
            let b = dir_bin(t);
            let angle = centres[b].dot(t).clamp(-1.0, 1.0).acos();
            assert!(angle <= radii[b], "{t} in cell {b}: {angle} > {}", radii[b]);
        }
        // The cells are small enough to prune: none wider than 16.5 degrees.
        assert!(radii.iter().all(|&r| r < 16.5f32.to_radians()), "{radii:?}");
    }

    #[test]
    fn counts_equal_brute_force_for_any_directions() {
        // Points packed in a 1 cm cube with tangents in every direction: the direction cells must
        // prune exactly the points a brute-force comparison rejects, in both modes.
        let mut rnd = uniform(3);
        let mut cloud = |n: usize| {
            let p: Vec<Vec3> = (0..n).map(|_| Vec3::new(rnd(), rnd(), rnd()) * 0.01).collect();
            let t: Vec<Vec3> = (0..n).map(|_| random_unit(&mut rnd)).collect();
            (p, t)
        };
        let (pa, ta) = cloud(3000);
        let (pb, tb) = cloud(2000);
        let ths = [
            Threshold { dist: 0.0005, angle_deg: 10.0 },
            Threshold { dist: 0.001, angle_deg: 20.0 },
            Threshold { dist: 0.0015, angle_deg: 30.0 },
            Threshold { dist: 0.0015, angle_deg: 5.0 },
        ];
        let a = OrientedPoints::new(pa, ta);
        let b = OrientedPoints::new(pb, tb);
        let want = brute_force_counts(&a, &b, &ths);
        let got = b.match_counts(&a, &ths);
        assert_eq!(got, want);
        // A case that tests something: partial matches, and more undirected than directed.
        assert!(want.0[1] > 100 && want.0[1] < 2900 && want.1[1] > want.0[1], "{want:?}");
        // Half the set moved 1 km away: the grid's blocks grow (the grid stays under 2^24 blocks).
        let far: Vec<Vec3> =
            b.points.iter().enumerate().map(|(k, &p)| if k % 2 == 0 { p + Vec3::X * 1000.0 } else { p }).collect();
        let b = OrientedPoints::new(far, b.tangents.clone());
        let grid = SearchGrid::new(&b.points, &b.tangents, ths[0].dist);
        assert!(grid.block > 0.001, "block {}", grid.block);
        assert_eq!(b.match_counts(&a, &ths), brute_force_counts(&a, &b, &ths));
    }

    #[test]
    fn empty_prediction_scores_zero() {
        let gt = parallel(3, 0.01, Vec3::ZERO);
        let r = evaluate(&StrandSet::empty(), &gt, &MetricOptions::default()).unwrap();
        assert!(r.directed.iter().all(|s| s.f1 == 0.0 && s.recall == 0.0));
    }
}
