//! Strand sets: many polylines stored flat, root first.
//!
//! A [`StrandSet`] holds one array of points and one array of per-strand point counts, the layout of
//! Cem Yuksel's `.hair` files and of Blender's hair Curves. Every strand has at least two points and
//! every coordinate is finite: [`StrandSet::new`] checks this once so that later stages need not.

use glam::Vec3;
use thiserror::Error;

/// Why a strand set could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StrandError {
    #[error("the point counts add up to {sum} but {points} points were given; give one count per strand")]
    CountMismatch { sum: u64, points: usize },
    #[error("strand {strand} has {count} point(s); every strand needs at least 2 points (root and tip)")]
    TooShort { strand: usize, count: u32 },
    #[error("point {index} (strand {strand}) is not finite: {value:?}; remove NaN or infinite coordinates")]
    NotFinite { index: usize, strand: usize, value: [f32; 3] },
    #[error("resampling step must be a positive finite length in metres, got {0}")]
    BadStep(f32),
    #[error(
        "resampling {length:.4e} units of strand every {step} would make {points:.3e} points (at most {max} are \
         allowed); the strands are probably not in metres (millimetres read as metres?), or the step is too small"
    )]
    TooManyPoints { length: f64, step: f32, points: f64, max: u64 },
}

/// The most points [`StrandSet::resample_by_arclength`] makes (about 1.2 GB of points): far above any
/// head of hair at 1 mm (a 150k-strand head of 30 cm is 45M), far below a unit mix-up's.
pub const MAX_RESAMPLED_POINTS: u64 = 100_000_000;

/// Length statistics of a strand set, in the units of its points (metres in hairrecon).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LengthStats {
    pub min: f32,
    pub max: f32,
    pub mean: f32,
    pub median: f32,
    pub total: f64,
}

/// A validated set of strands: polylines stored flat, each root first.
#[derive(Debug, Clone, PartialEq)]
pub struct StrandSet {
    points: Vec<Vec3>,
    counts: Vec<u32>,
    /// `offsets[i]..offsets[i + 1]` are the points of strand `i`; `offsets.len() == counts.len() + 1`.
    offsets: Vec<usize>,
}

impl StrandSet {
    /// Builds a strand set, checking that counts add up, that each strand has two or more points and
    /// that every coordinate is finite.
    pub fn new(points: Vec<Vec3>, counts: Vec<u32>) -> Result<Self, StrandError> {
        let sum: u64 = counts.iter().map(|&c| c as u64).sum();
        if sum != points.len() as u64 {
            return Err(StrandError::CountMismatch { sum, points: points.len() });
        }
        let mut offsets = Vec::with_capacity(counts.len() + 1);
        offsets.push(0usize);
        for (i, &c) in counts.iter().enumerate() {
            if c < 2 {
                return Err(StrandError::TooShort { strand: i, count: c });
            }
            let start = *offsets.last().unwrap_or(&0);
            let end = start + c as usize;
            if let Some(k) = points[start..end].iter().position(|p| !p.is_finite()) {
                let p = points[start + k];
                return Err(StrandError::NotFinite { index: start + k, strand: i, value: p.to_array() });
            }
            offsets.push(end);
        }
        Ok(Self { points, counts, offsets })
    }

    /// Builds a strand set from a flat `[x, y, z, x, y, z, ...]` array.
    pub fn from_flat(flat: &[f32], counts: Vec<u32>) -> Result<Self, StrandError> {
        let points = flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect::<Vec<_>>();
        if !flat.len().is_multiple_of(3) {
            let sum: u64 = counts.iter().map(|&c| c as u64).sum();
            return Err(StrandError::CountMismatch { sum, points: flat.len() / 3 });
        }
        Self::new(points, counts)
    }

    /// An empty set (no strands).
    pub fn empty() -> Self {
        Self { points: Vec::new(), counts: Vec::new(), offsets: vec![0] }
    }

    pub fn num_strands(&self) -> usize {
        self.counts.len()
    }

    pub fn num_points(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    pub fn points(&self) -> &[Vec3] {
        &self.points
    }

    pub fn counts(&self) -> &[u32] {
        &self.counts
    }

    /// Start offsets of each strand, plus the total at the end.
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// The points of strand `i`, root first.
    pub fn strand(&self, i: usize) -> &[Vec3] {
        &self.points[self.offsets[i]..self.offsets[i + 1]]
    }

    /// Iterates over the strands, each as a slice of points, root first.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[Vec3]> + '_ {
        self.offsets.windows(2).map(move |w| &self.points[w[0]..w[1]])
    }

    /// The points as a flat `[x, y, z, ...]` array.
    pub fn flat_points(&self) -> Vec<f32> {
        self.points.iter().flat_map(|p| p.to_array()).collect()
    }

    /// Consumes the set and returns its points and counts.
    pub fn into_parts(self) -> (Vec<Vec3>, Vec<u32>) {
        (self.points, self.counts)
    }

    /// The same strands with every point mapped by `f` (for example a scale or a change of axes).
    /// Fails if `f` produces a non-finite point.
    pub fn map_points(&self, f: impl Fn(Vec3) -> Vec3) -> Result<Self, StrandError> {
        Self::new(self.points.iter().map(|&p| f(p)).collect(), self.counts.clone())
    }

    /// The same strands, each ordered tip first instead of root first.
    pub fn reversed(&self) -> Self {
        let mut points = Vec::with_capacity(self.points.len());
        for s in self.iter() {
            points.extend(s.iter().rev());
        }
        Self { points, counts: self.counts.clone(), offsets: self.offsets.clone() }
    }

    /// Arc length of strand `i`.
    pub fn strand_length(&self, i: usize) -> f32 {
        polyline_length(self.strand(i))
    }

    /// Length statistics over all strands. `None` for an empty set.
    pub fn length_stats(&self) -> Option<LengthStats> {
        if self.is_empty() {
            return None;
        }
        let mut lengths: Vec<f32> = (0..self.num_strands()).map(|i| self.strand_length(i)).collect();
        lengths.sort_by(f32::total_cmp);
        let total: f64 = lengths.iter().map(|&l| l as f64).sum();
        let n = lengths.len();
        let median = if n % 2 == 1 { lengths[n / 2] } else { 0.5 * (lengths[n / 2 - 1] + lengths[n / 2]) };
        Some(LengthStats { min: lengths[0], max: lengths[n - 1], mean: (total / n as f64) as f32, median, total })
    }

    /// Axis-aligned bounding box `(min, max)`. `None` for an empty set.
    pub fn bbox(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.points.first()?;
        Some(self.points.iter().fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))))
    }

    /// Unit tangent at every point, pointing from root to tip: central differences inside a strand,
    /// one-sided at the ends. A zero-length neighbourhood gives the zero vector.
    pub fn tangents(&self) -> Vec<Vec3> {
        let mut out = Vec::with_capacity(self.points.len());
        for s in self.iter() {
            let n = s.len();
            for j in 0..n {
                let a = s[j.saturating_sub(1)];
                let b = s[(j + 1).min(n - 1)];
                out.push((b - a).normalize_or_zero());
            }
        }
        out
    }

    /// Resamples every strand uniformly by arc length with spacing `step` (the last sample is the tip,
    /// so the final spacing may be shorter). Strands keep their order; roots and tips are kept exactly.
    /// A strand shorter than `step` keeps just its root and tip.
    pub fn resample_by_arclength(&self, step: f32) -> Result<Self, StrandError> {
        if !(step.is_finite() && step > 0.0) {
            return Err(StrandError::BadStep(step));
        }
        let length: f64 = self.iter().map(|s| polyline_length(s) as f64).sum();
        let estimate = length / step as f64 + 2.0 * self.num_strands() as f64;
        if estimate > MAX_RESAMPLED_POINTS as f64 {
            return Err(StrandError::TooManyPoints { length, step, points: estimate, max: MAX_RESAMPLED_POINTS });
        }
        let mut points = Vec::new();
        let mut counts = Vec::with_capacity(self.num_strands());
        for s in self.iter() {
            let before = points.len();
            resample_polyline(s, step, &mut points);
            counts.push((points.len() - before) as u32);
        }
        Self::new(points, counts)
    }

    /// Resamples every strand to exactly `n >= 2` points evenly spaced by arc length.
    pub fn resample_to_count(&self, n: usize) -> Result<Self, StrandError> {
        let n = n.max(2);
        let mut points = Vec::with_capacity(self.num_strands() * n);
        for s in self.iter() {
            let len = polyline_length(s);
            if len <= 0.0 {
                points.extend(std::iter::repeat_n(s[0], n));
                continue;
            }
            let step = len / (n - 1) as f32;
            let before = points.len();
            resample_polyline(s, step, &mut points);
            // Floating error may give n-1 or n+1 samples; fix the count by trimming or padding the tip.
            points.truncate(before + n);
            while points.len() < before + n {
                points.insert(points.len() - 1, *s.last().unwrap_or(&s[0]));
            }
            let last = points.len() - 1;
            points[last] = *s.last().unwrap_or(&s[0]);
        }
        Self::new(points, vec![n as u32; self.num_strands()])
    }

    /// Concatenates two strand sets.
    pub fn concat(&self, other: &StrandSet) -> Self {
        let mut points = self.points.clone();
        points.extend_from_slice(&other.points);
        let mut counts = self.counts.clone();
        counts.extend_from_slice(&other.counts);
        let mut offsets = self.offsets.clone();
        let base = *offsets.last().unwrap_or(&0);
        offsets.extend(other.offsets[1..].iter().map(|o| o + base));
        Self { points, counts, offsets }
    }

    /// A new set holding only the strands whose indices are given, in that order.
    pub fn select(&self, indices: &[usize]) -> Self {
        let mut points = Vec::new();
        let mut counts = Vec::with_capacity(indices.len());
        for &i in indices {
            points.extend_from_slice(self.strand(i));
            counts.push(self.counts[i]);
        }
        let mut offsets = Vec::with_capacity(counts.len() + 1);
        offsets.push(0);
        for &c in &counts {
            offsets.push(offsets.last().unwrap_or(&0) + c as usize);
        }
        Self { points, counts, offsets }
    }
}

/// Arc length of a polyline.
pub fn polyline_length(s: &[Vec3]) -> f32 {
    s.windows(2).map(|w| w[0].distance(w[1])).sum()
}

/// Appends samples of `s` spaced `step` apart along its arc length, starting at the root and ending
/// exactly at the tip.
fn resample_polyline(s: &[Vec3], step: f32, out: &mut Vec<Vec3>) {
    out.push(s[0]);
    let mut next = step; // arc length of the next sample
    let mut walked = 0.0f32; // arc length at the start of the current segment
    for w in s.windows(2) {
        let seg = w[0].distance(w[1]);
        if seg <= 0.0 {
            continue;
        }
        while next < walked + seg {
            let t = (next - walked) / seg;
            out.push(w[0].lerp(w[1], t));
            next += step;
        }
        walked += seg;
    }
    let tip = *s.last().unwrap_or(&s[0]);
    // Avoid a degenerate last segment: replace a sample that sits (almost) on the tip.
    let n = out.len();
    if n >= 2 && out[n - 1].distance(tip) < 1e-3 * step {
        out[n - 1] = tip;
    } else {
        out.push(tip);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(n: usize, len: f32) -> Vec<Vec3> {
        (0..n).map(|i| Vec3::new(0.0, 0.0, len * i as f32 / (n - 1) as f32)).collect()
    }

    #[test]
    fn rejects_bad_input() {
        assert!(matches!(StrandSet::new(line(3, 1.0), vec![2]), Err(StrandError::CountMismatch { .. })));
        assert!(matches!(StrandSet::new(line(3, 1.0), vec![1, 2]), Err(StrandError::TooShort { strand: 0, .. })));
        let mut p = line(3, 1.0);
        p[2].y = f32::NAN;
        assert!(matches!(StrandSet::new(p, vec![3]), Err(StrandError::NotFinite { index: 2, .. })));
    }

    #[test]
    fn resampling_spacing_and_ends() {
        // A bent polyline of length 0.01 + 0.005 = 0.015 m resampled at 1 mm gives 16 points.
        let pts = vec![Vec3::ZERO, Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.01, 0.005, 0.0)];
        let s = StrandSet::new(pts, vec![3]).unwrap();
        let r = s.resample_by_arclength(0.001).unwrap();
        assert_eq!(r.counts(), &[16]);
        // 1000 strands of 300 m (a head in millimetres read as metres) at 1 mm: refused, not 3e8 points.
        let long = StrandSet::new(
            (0..1000).flat_map(|i| [Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32, 300.0, 0.0)]).collect(),
            vec![2; 1000],
        )
        .unwrap();
        let e = long.resample_by_arclength(0.001).unwrap_err();
        assert!(matches!(e, StrandError::TooManyPoints { .. }) && e.to_string().contains("millimetres"), "{e}");
        let n = long.resample_by_arclength(0.01).unwrap().num_points();
        assert!((30_000_000..30_010_000).contains(&n), "{n}");
        let st = r.strand(0);
        assert_eq!(st[0], Vec3::ZERO);
        assert_eq!(st[15], Vec3::new(0.01, 0.005, 0.0));
        for w in st.windows(2) {
            assert!((w[0].distance(w[1]) - 0.001).abs() < 1e-5, "{:?}", w);
        }
        let fixed = s.resample_to_count(7).unwrap();
        assert_eq!(fixed.counts(), &[7]);
        assert!((polyline_length(fixed.strand(0)) - 0.015).abs() < 1e-3);
    }

    #[test]
    fn tangents_point_root_to_tip_and_stats() {
        let s = StrandSet::new([line(4, 0.3), line(2, 0.1)].concat(), vec![4, 2]).unwrap();
        for t in s.tangents() {
            assert!((t - Vec3::Z).length() < 1e-6);
        }
        for t in s.reversed().tangents() {
            assert!((t + Vec3::Z).length() < 1e-6);
        }
        let st = s.length_stats().unwrap();
        assert!((st.max - 0.3).abs() < 1e-6 && (st.min - 0.1).abs() < 1e-6 && (st.mean - 0.2).abs() < 1e-6);
    }
}
