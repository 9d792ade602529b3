//! Spatial queries shared by every stage: one kd-tree index over oriented points.
//!
//! [`PointIndex`] holds points with unit tangents and a kd-tree over the points (kiddo's
//! `ImmutableKdTree`, a static tree built once): k nearest, all within a radius, and the best
//! undirected match within a distance and an angle. Strands become points by the one arc-length
//! sampler, [`StrandSet::resample_by_arclength`], with [`StrandSet::tangents`].

use std::num::NonZero;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::{StrandError, StrandSet};

/// Strand points every `step` metres of arc, root and tip included
/// ([`StrandSet::resample_by_arclength`]), and their root→tip unit tangents ([`StrandSet::tangents`]):
/// the one sampler of strands into oriented points.
pub fn oriented_samples(strands: &StrandSet, step: f32) -> Result<(Vec<Vec3>, Vec<Vec3>), StrandError> {
    let r = strands.resample_by_arclength(step)?;
    let tangents = r.tangents();
    Ok((r.into_parts().0, tangents))
}

/// Points with unit tangents and a kd-tree over the points.
#[derive(Debug)]
pub struct PointIndex {
    pub points: Vec<Vec3>,
    pub tangents: Vec<Vec3>,
    pub(crate) tree: ImmutableKdTree<f32, 3>,
}

impl PointIndex {
    /// Builds the tree over `points`; `tangents` is one per point (or empty when only positions are
    /// queried).
    pub fn new(points: Vec<Vec3>, tangents: Vec<Vec3>) -> Self {
        let arr: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::new_from_slice(&arr);
        Self { points, tangents, tree }
    }

    /// Strand points every `step` metres of arc, root and tip included
    /// ([`StrandSet::resample_by_arclength`]), with root→tip unit tangents.
    pub fn from_strands(strands: &StrandSet, step: f32) -> Result<Self, StrandError> {
        let (points, tangents) = oriented_samples(strands, step)?;
        Ok(Self::new(points, tangents))
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Indices of the `k` nearest points (nearest first) with their distances, at most `len()`.
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

    /// The nearest point's index and squared distance (`None` when empty).
    pub fn nearest_one(&self, p: Vec3) -> Option<(usize, f32)> {
        if self.points.is_empty() {
            return None;
        }
        let n = self.tree.nearest_one::<SquaredEuclidean>(&p.to_array());
        Some((n.item as usize, n.distance))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_strand_is_indexed_every_step_from_root_to_tip_with_its_tangent() {
        // 0.75 in two segments of 0.25 and 0.5 (binary fractions: exact): samples every 0.125.
        let s =
            StrandSet::new(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.25), Vec3::new(0.0, 0.0, -0.75)], vec![3]).unwrap();
        let index = PointIndex::from_strands(&s, 0.125).unwrap();
        assert_eq!(index.len(), 7);
        for (k, q) in index.points.iter().enumerate() {
            assert_eq!(q.z, -0.125 * k as f32, "{k}: {q}");
        }
        assert!(index.tangents.iter().all(|t| *t == Vec3::NEG_Z));
        assert!(PointIndex::from_strands(&s, 0.0).is_err());
    }

    #[test]
    fn queries_agree_with_brute_force() {
        let mut seed = 7u64;
        let mut next = || {
            seed = crate::scalp::splitmix64(seed);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let pts: Vec<Vec3> = (0..500).map(|_| Vec3::new(next(), next(), next())).collect();
        let tans: Vec<Vec3> = (0..500).map(|_| Vec3::new(next() - 0.5, next() - 0.5, 1.0).normalize()).collect();
        let index = PointIndex::new(pts.clone(), tans.clone());
        for _ in 0..50 {
            let q = Vec3::new(next(), next(), next());
            let mut brute: Vec<(usize, f32)> = pts.iter().enumerate().map(|(i, p)| (i, p.distance(q))).collect();
            brute.sort_by(|a, b| a.1.total_cmp(&b.1));
            let got = index.nearest(q, 3);
            assert_eq!(got.iter().map(|g| g.0).collect::<Vec<_>>(), brute[..3].iter().map(|b| b.0).collect::<Vec<_>>());
            assert_eq!(index.nearest_one(q).unwrap().0, brute[0].0);
            let mut within = index.within(q, 0.2);
            within.sort();
            let want: Vec<usize> = brute
                .iter()
                .filter(|b| b.1 <= 0.2)
                .map(|b| b.0)
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .collect();
            assert_eq!(within, want);
            let t = Vec3::Z;
            let best = index.match_undirected(q, t, 0.2, 0.5);
            let want = want
                .iter()
                .copied()
                .filter(|&i| tans[i].dot(t).abs() >= 0.5f32.cos())
                .max_by(|&a, &b| tans[a].dot(t).abs().total_cmp(&tans[b].dot(t).abs()));
            assert_eq!(best, want);
        }
    }
}
