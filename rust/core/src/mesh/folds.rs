//! Inside tests that survive folded faces.
//!
//! A photogrammetry mesh with vertex noise comparable to its edge length has faces that fold over
//! their neighbours (adjacent face normals more than 90° apart). There the pseudo-normal at the
//! closest feature can point the wrong way, and a point centimetres outside reads as inside. At
//! such doubtful triangles the side is judged instead by the net normal of the surface around the
//! closest point: the sum of the area vectors (area × unit normal) of every triangle within a few
//! edge lengths. A fold's faces point opposite ways and cancel in that sum, which leaves the
//! surface's own orientation. (The generalized winding number of Jacobson et al. 2013 cancels
//! folds too, but it is global: on an open mesh with many holes, as fused scans are, it calls
//! large regions outside the surface "inside".)
//!
//! Only a Bvh made by [`Bvh::with_fold_vote`] votes, and only at doubtful triangles (a corner with
//! a folded edge): smooth meshes keep the exact pseudo-normal test, and modelled meshes (a head's
//! sharp creases fold too) keep it everywhere.

use glam::Vec3;

use super::Bvh;

/// The neighbourhood of the vote, in mean edge lengths of the mesh.
pub(super) const VOTE_RADIUS_EDGES: f32 = 4.0;

/// Per triangle: whether one of its corners has a folded edge (two faces whose normals are more
/// than 90° apart), where the pseudo-normal sign cannot be trusted. Empty when no edge folds.
///
/// `edge_pn` holds each welded edge's sum of unit face normals and face count: for two faces
/// |n₀ + n₁|² = 2 + 2 cos θ, below 2 when θ > 90°. A degenerate face (zero normal) next to a
/// sound one sums to 1 and counts as a fold too: its pseudo-normals are no better.
pub(super) fn doubtful_triangles(
    triangles: &[[u32; 3]],
    weld: &[u32],
    edge_pn: &rustc_hash::FxHashMap<(u32, u32), (Vec3, u32)>,
) -> Vec<bool> {
    let mut folded_vertex = vec![false; weld.len()];
    let mut any = false;
    for (&(a, b), &(sum, faces)) in edge_pn {
        if faces == 2 && sum.length_squared() < 2.0 {
            folded_vertex[a as usize] = true;
            folded_vertex[b as usize] = true;
            any = true;
        }
    }
    if !any {
        return Vec::new();
    }
    triangles.iter().map(|t| t.iter().any(|&v| folded_vertex[weld[v as usize] as usize])).collect()
}

/// The mean edge length of a mesh (each triangle's three edges).
pub(super) fn mean_edge(bvh: &Bvh) -> f32 {
    let n = bvh.mesh.triangles.len().max(1);
    let sum: f64 = (0..bvh.mesh.triangles.len())
        .map(|i| {
            let [a, b, c] = bvh.mesh.corners(i);
            (a.distance(b) + b.distance(c) + c.distance(a)) as f64
        })
        .sum();
    (sum / (3 * n) as f64) as f32
}

/// The sum of the area vectors of the triangles whose centroid lies within `radius` of `centre`.
pub(super) fn net_normal(bvh: &Bvh, centre: Vec3, radius: f32) -> Vec3 {
    let r2 = radius * radius;
    let mut sum = Vec3::ZERO;
    let mut stack = [0u32; 64];
    let mut sp = 1;
    while sp > 0 {
        sp -= 1;
        let node = bvh.nodes[stack[sp] as usize];
        if (centre - centre.clamp(node.lo, node.hi)).length_squared() > r2 {
            continue;
        }
        if node.count > 0 {
            for &t in &bvh.order[node.start as usize..(node.start + node.count) as usize] {
                let [a, b, c] = bvh.mesh.corners(t as usize);
                if ((a + b + c) / 3.0).distance_squared(centre) <= r2 {
                    sum += 0.5 * (b - a).cross(c - a);
                }
            }
        } else if sp + 2 <= stack.len() {
            stack[sp] = node.start;
            stack[sp + 1] = node.start + 1;
            sp += 2;
        }
    }
    sum
}
