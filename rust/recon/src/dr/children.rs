//! Children as a linear function of the guides, for the guide stage of the hierarchy (Dr.Hair,
//! CVPR 2024, "Hierarchical Strand Optimization": guides are optimized first and children follow
//! by interpolation; the children's rendering sends gradients back to the guides).
//!
//! In: guides and children as [`crate::grow::interpolate_children`] made them (each child blends
//! the segment vectors of its `k` nearest guides by root, weights `1/d²`, normalized over the guides
//! that still have a segment at that index), or any other child set. Out: a [`ChildMap`] with
//! `child = root + Σ_{j≤i} Σ_g ŵ_gj (G_g[j] − G_g[j−1]) + r_i`, where the residual `r` is fixed at
//! construction so that the map reproduces the given children exactly (it keeps what grow.rs added
//! beyond the blend, such as pushing points out of the head). [`ChildMap::forward`] evaluates it,
//! [`ChildMap::backward`] is its transpose. Both are deterministic: the backward sums fixed chunks
//! of children in order.

use glam::Vec3;
use hairrecon_core::StrandSet;
use rayon::prelude::*;

use crate::grow::{BlendParams, GuideBlend};

/// Chunks of children summed separately in [`ChildMap::backward`] (a constant, so that the sum order
/// does not depend on the thread count).
const BACKWARD_CHUNKS: usize = 16;

/// The linear map guides → children.
#[derive(Debug, Clone)]
pub struct ChildMap {
    k: usize,
    /// `k` (guide, weight) pairs per child (unused slots have weight 0).
    nb: Vec<(u32, f32)>,
    child_offsets: Vec<usize>,
    guide_offsets: Vec<usize>,
    roots: Vec<Vec3>,
    residual: Vec<Vec3>,
    scratch: Vec<Vec<Vec3>>,
}

impl ChildMap {
    /// Builds the map so that `forward(guides)` gives `children` back. Children blend the guides as
    /// growing chose them ([`GuideBlend`] with `params`).
    pub fn new(guides: &StrandSet, children: &StrandSet, params: &BlendParams) -> Self {
        let blend = GuideBlend::new(guides, params);
        let k = params.k.max(1).min(blend.len().max(1));
        let nb: Vec<(u32, f32)> = children
            .iter()
            .collect::<Vec<_>>()
            .par_iter()
            .flat_map_iter(|c| {
                let w = blend.weights(c[0], k);
                (0..k).map(move |j| w.get(j).map_or((0, 0.0), |&(g, wt)| (g as u32, wt)))
            })
            .collect();
        let mut map = Self {
            k,
            nb,
            child_offsets: children.offsets().to_vec(),
            guide_offsets: guides.offsets().to_vec(),
            roots: children.iter().map(|c| c[0]).collect(),
            residual: vec![Vec3::ZERO; children.num_points()],
            scratch: Vec::new(),
        };
        let mut blend = vec![Vec3::ZERO; children.num_points()];
        map.forward(guides.points(), &mut blend);
        map.residual = children.points().iter().zip(&blend).map(|(c, b)| *c - *b).collect();
        map
    }

    pub fn num_children(&self) -> usize {
        self.roots.len()
    }

    /// Child point offsets (strand layout of the output).
    pub fn child_offsets(&self) -> &[usize] {
        &self.child_offsets
    }

    /// Writes the children's points for guide points `g` into `out`.
    pub fn forward(&self, g: &[Vec3], out: &mut [Vec3]) {
        let nc = self.roots.len();
        let chunk = nc.div_ceil(BACKWARD_CHUNKS * 4).max(1);
        // Split `out` by children without unsafe: chunks of whole children.
        let mut parts: Vec<(usize, &mut [Vec3])> = Vec::with_capacity(nc.div_ceil(chunk));
        let mut rest = out;
        let mut c0 = 0;
        while c0 < nc {
            let c1 = (c0 + chunk).min(nc);
            let len = self.child_offsets[c1] - self.child_offsets[c0];
            let (a, b) = rest.split_at_mut(len);
            parts.push((c0, a));
            rest = b;
            c0 = c1;
        }
        parts.into_par_iter().for_each(|(c0, part)| {
            let base = self.child_offsets[c0];
            let mut c = c0;
            while c < nc && self.child_offsets[c] - base < part.len() {
                let (o, e) = (self.child_offsets[c], self.child_offsets[c + 1]);
                let nb = &self.nb[c * self.k..(c + 1) * self.k];
                let mut p = self.roots[c];
                part[o - base] = p + self.residual[o];
                for i in 1..e - o {
                    let (mut acc, mut wa) = (Vec3::ZERO, 0.0f32);
                    for &(gi, w) in nb {
                        let (go, ge) = (self.guide_offsets[gi as usize], self.guide_offsets[gi as usize + 1]);
                        if w > 0.0 && i < ge - go {
                            acc += (g[go + i] - g[go + i - 1]) * w;
                            wa += w;
                        }
                    }
                    if wa > 0.0 {
                        p += acc / wa;
                    }
                    part[o + i - base] = p + self.residual[o + i];
                }
                c += 1;
            }
        });
    }

    /// Adds `(∂child/∂guides)ᵀ d_child` into `d_guide`.
    pub fn backward(&mut self, d_child: &[Vec3], d_guide: &mut [Vec3]) {
        let nc = self.roots.len();
        let ng = d_guide.len();
        let chunk = nc.div_ceil(BACKWARD_CHUNKS).max(1);
        let nchunks = nc.div_ceil(chunk);
        self.scratch.resize_with(nchunks, Vec::new);
        let (nb_all, k, co, go) = (&self.nb, self.k, &self.child_offsets, &self.guide_offsets);
        self.scratch.par_iter_mut().enumerate().for_each(|(ci, acc_g)| {
            acc_g.clear();
            acc_g.resize(ng, Vec3::ZERO);
            for c in ci * chunk..((ci + 1) * chunk).min(nc) {
                let (o, e) = (co[c], co[c + 1]);
                let nb = &nb_all[c * k..(c + 1) * k];
                // ∂L/∂(segment i) = Σ_{j ≥ i} ∂L/∂p_j.
                let mut s = Vec3::ZERO;
                for i in (1..e - o).rev() {
                    s += d_child[o + i];
                    let mut wa = 0.0f32;
                    for &(gi, w) in nb {
                        if w > 0.0 && i < go[gi as usize + 1] - go[gi as usize] {
                            wa += w;
                        }
                    }
                    if wa <= 0.0 {
                        continue;
                    }
                    for &(gi, w) in nb {
                        let g0 = go[gi as usize];
                        if w > 0.0 && i < go[gi as usize + 1] - g0 {
                            let d = s * (w / wa);
                            acc_g[g0 + i] += d;
                            acc_g[g0 + i - 1] -= d;
                        }
                    }
                }
            }
        });
        for acc_g in &self.scratch {
            for (d, a) in d_guide.iter_mut().zip(acc_g) {
                *d += *a;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_children_and_backward_is_the_transpose() {
        let mk = |x: f32, len: usize| -> Vec<Vec3> {
            (0..len)
                .map(|j| Vec3::new(x + 0.001 * (j as f32).sin(), 0.002 * j as f32, -0.01 * j as f32 * (1.0 + x)))
                .collect()
        };
        let mut gp = Vec::new();
        let mut gc = Vec::new();
        for (i, len) in [6usize, 8, 5, 7].iter().enumerate() {
            gp.extend(mk(i as f32 * 0.01, *len));
            gc.push(*len as u32);
        }
        let guides = StrandSet::new(gp, gc).unwrap();
        let mut cp = Vec::new();
        let mut cc = Vec::new();
        for i in 0..9 {
            let len = 4 + i % 5;
            cp.extend(mk(0.004 * i as f32, len).iter().map(|p| *p + Vec3::splat(0.0003)));
            cc.push(len as u32);
        }
        let children = StrandSet::new(cp, cc).unwrap();
        let mut map =
            ChildMap::new(&guides, &children, &BlendParams { k: 3, min_guide_fraction: 0.0, parting_reach: 0.0 });
        let mut out = vec![Vec3::ZERO; children.num_points()];
        map.forward(guides.points(), &mut out);
        for (a, b) in out.iter().zip(children.points()) {
            assert!((*a - *b).length() < 1e-6);
        }
        // ⟨J δg, d⟩ = ⟨δg, Jᵀ d⟩ (J is linear up to the constant part).
        let dg: Vec<Vec3> =
            (0..guides.num_points()).map(|i| Vec3::new((i as f32).sin(), 0.3, (i as f32).cos())).collect();
        let dc: Vec<Vec3> = (0..children.num_points()).map(|i| Vec3::new(0.5, (i as f32 * 1.3).sin(), -0.2)).collect();
        let moved: Vec<Vec3> = guides.points().iter().zip(&dg).map(|(p, d)| *p + *d).collect();
        let mut out2 = vec![Vec3::ZERO; children.num_points()];
        map.forward(&moved, &mut out2);
        let lhs: f32 = out2.iter().zip(&out).zip(&dc).map(|((a, b), d)| (*a - *b).dot(*d)).sum();
        let mut jt = vec![Vec3::ZERO; guides.num_points()];
        map.backward(&dc, &mut jt);
        let rhs: f32 = jt.iter().zip(&dg).map(|(a, b)| a.dot(*b)).sum();
        assert!((lhs - rhs).abs() < 1e-3 * lhs.abs().max(1.0), "{lhs} vs {rhs}");
    }

    #[test]
    fn short_guides_move_no_child() {
        // Guide 1 is 1 cm long, the others 5 cm: at 0.3 of the median (1.5 cm) no child blends it,
        // though its root is the nearest to every child.
        let line = |x: f32, n: usize| (0..n).map(move |j| Vec3::new(x, 0.0, -0.01 * j as f32));
        let mut gp: Vec<Vec3> = line(0.0, 6).collect();
        gp.extend(line(0.01, 2));
        gp.extend(line(0.02, 6));
        let guides = StrandSet::new(gp, vec![6, 2, 6]).unwrap();
        let cp: Vec<Vec3> = line(0.0101, 5).chain(line(0.0099, 4)).collect();
        let children = StrandSet::new(cp, vec![5, 4]).unwrap();
        let moved = |map: &mut ChildMap, g: usize| {
            let mut pts = guides.points().to_vec();
            let o = guides.offsets()[g];
            for p in &mut pts[o + 1..guides.offsets()[g + 1]] {
                *p += Vec3::X * 0.01;
            }
            let (mut a, mut b) = (vec![Vec3::ZERO; children.num_points()], vec![Vec3::ZERO; children.num_points()]);
            map.forward(guides.points(), &mut a);
            map.forward(&pts, &mut b);
            a.iter().zip(&b).map(|(p, q)| (*p - *q).length()).fold(0.0f32, f32::max)
        };
        let mut with_short =
            ChildMap::new(&guides, &children, &BlendParams { k: 2, min_guide_fraction: 0.0, parting_reach: 0.0 });
        assert!(moved(&mut with_short, 1) > 1e-3, "the short guide is a neighbour without the minimum");
        let mut without =
            ChildMap::new(&guides, &children, &BlendParams { k: 2, min_guide_fraction: 0.3, parting_reach: 0.0 });
        assert_eq!(moved(&mut without, 1), 0.0);
        assert!(moved(&mut without, 0) > 1e-3 && moved(&mut without, 2) > 1e-3);
    }
}
