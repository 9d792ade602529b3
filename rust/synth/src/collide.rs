//! Keeping strands outside the head: a signed-distance collider with a minimum offset.
//!
//! In: the head mesh. Out: signed distances and push-outs. The head's vertices are first welded by
//! exact position (a PLY from Blender splits vertices at UV seams), so that the angle-weighted
//! pseudo-normals of [`hairrecon_core::Bvh`] (Bærentzen & Aanæs 2005) see a connected surface and the
//! inside test is right across seams. The head is cut open at the bottom (below the shoulders):
//! points lower than [`FLOOR_MARGIN`] above the cut are not tested, since there the sign is
//! meaningless and real hair hangs freely past the cut.

use glam::Vec3;
use hairrecon_core::{Bvh, TriMesh};

/// Points lower than this above the bottom of the head mesh are left alone, metres.
pub const FLOOR_MARGIN: f32 = 0.02;

/// A head for collision queries.
#[derive(Debug, Clone)]
pub struct HeadCollider {
    bvh: Bvh,
    floor: f32,
}

impl HeadCollider {
    /// Welds `head` and builds its BVH.
    pub fn new(head: &TriMesh) -> Self {
        let (vertices, remap) = head.weld_positions();
        let triangles: Vec<[u32; 3]> = head
            .triangles
            .iter()
            .map(|t| t.map(|v| remap[v as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        let floor = head.bbox().0.z + FLOOR_MARGIN;
        // Welding keeps finite vertices and valid indices; fall back to the mesh as given otherwise.
        let mesh = TriMesh::new(vertices, triangles, None, None).unwrap_or_else(|_| head.clone());
        Self { bvh: Bvh::new(mesh), floor }
    }

    /// The welded head.
    pub fn mesh(&self) -> &TriMesh {
        self.bvh.mesh()
    }

    /// Whether `p` is high enough above the cut to be tested.
    #[inline]
    pub fn active(&self, p: Vec3) -> bool {
        p.z > self.floor
    }

    /// Signed distance (negative inside) if `p` is tested and within `max_dist` of the head.
    pub fn signed_distance(&self, p: Vec3, max_dist: f32) -> Option<f32> {
        if !self.active(p) {
            return None;
        }
        self.bvh.signed_distance(p, max_dist)
    }

    /// `p` moved, if needed, to lie at least `offset` outside the head: onto the closest surface
    /// point plus `offset` along the outward direction. Points more than `reach` inside the head are
    /// not found (the query stops at `max(offset, reach)` from `p`): give the largest depth that a
    /// step can reach. A few passes settle points in creases.
    pub fn push_out(&self, p: Vec3, offset: f32, reach: f32) -> Vec3 {
        self.push_out_bound(p, offset, reach).0
    }

    /// [`Self::push_out`] that also returns a lower bound on the distance from the returned point
    /// to the head (at least `offset` up to float error, `max(offset, reach)` when nothing is that
    /// near; below the floor, the distance up to the floor). Since distance is 1-Lipschitz, a caller that moves the point
    /// by less than `bound − offset` need not ask again.
    pub fn push_out_bound(&self, mut p: Vec3, offset: f32, reach: f32) -> (Vec3, f32) {
        let radius = offset.max(reach);
        for _ in 0..4 {
            if !self.active(p) {
                // Not tested down here: what matters is how far the point is from being tested.
                return (p, self.floor - p.z);
            }
            let Some(cp) = self.bvh.closest_point(p, radius) else { return (p, radius) };
            let n = self.bvh.pseudo_normal(&cp).normalize_or_zero();
            let delta = p - cp.point;
            let outside = delta.dot(n) >= 0.0;
            if outside && cp.distance >= offset * 0.999 {
                return (p, cp.distance);
            }
            let dir = if cp.distance > 1e-7 {
                let d = delta / cp.distance;
                if outside {
                    d
                } else {
                    -d
                }
            } else {
                n
            };
            p = cp.point + dir * offset;
        }
        (p, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> TriMesh {
        let v = vec![Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];
        // Duplicate vertex 4 to check welding: triangles use 4 or 6 for the top.
        let mut v2 = v.clone();
        v2.push(Vec3::Z);
        let t = vec![[0, 2, 4], [2, 1, 6], [1, 3, 4], [3, 0, 6], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        TriMesh::new(v2, t, None, None).unwrap()
    }

    #[test]
    fn welds_and_pushes_out() {
        let c = HeadCollider::new(&octahedron());
        assert_eq!(c.mesh().vertices.len(), 6);
        // Above the floor (bottom at -1, margin 0.02).
        let p = c.push_out(Vec3::new(0.1, 0.1, 0.1), 0.01, 1.0);
        let sd = c.signed_distance(p, 1.0).unwrap();
        assert!((sd - 0.01).abs() < 1e-4, "{sd}");
        // Near the welded top vertex, inside: pushed out too.
        let p = c.push_out(Vec3::new(0.0, 0.0, 0.99), 0.01, 1.0);
        assert!(c.signed_distance(p, 1.0).unwrap() > 0.0099);
        // Already far enough: unchanged.
        let q = Vec3::new(1.0, 1.0, 1.0);
        assert_eq!(c.push_out(q, 0.01, 1.0), q);
        // Deeper than the reach: not found.
        assert_eq!(c.push_out(Vec3::new(0.1, 0.1, 0.1), 0.01, 0.1), Vec3::new(0.1, 0.1, 0.1));
    }
}
