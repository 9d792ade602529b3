//! Ray queries on a [`Bvh`]: the first hit ([`Bvh::ray_cast`]) and an occlusion test
//! ([`Bvh::occluded`]), with the Möller–Trumbore test (Möller & Trumbore, "Fast, Minimum Storage
//! Ray/Triangle Intersection", 1997) and slab tests against the nodes' boxes.

use glam::Vec3;

use super::{Bvh, RayHit};

impl Bvh {
    /// The first hit of the ray `origin + t * dir` with `t_min < t < t_max`, if any.
    ///
    /// Nodes are visited nearer child first (by where the ray enters their boxes), so that the
    /// first hits found cut the farther boxes away.
    pub fn ray_cast(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        if !(origin.is_finite() && dir.is_finite()) || dir == Vec3::ZERO {
            return None; // a NaN ray would pass every box test: it hits nothing
        }
        if self.order.is_empty() {
            return None;
        }
        let inv = Vec3::ONE / dir;
        let mut best: Option<RayHit> = None;
        let mut t_best = t_max;
        let root = self.nodes[0];
        let t_root = slab_entry(origin, inv, root.lo, root.hi, t_min, t_best)?;
        // (node, where the ray enters its box)
        let mut stack = [(0u32, 0.0f32); 64];
        stack[0] = (0, t_root);
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let (ni, t_enter) = stack[sp];
            if t_enter > t_best {
                continue;
            }
            let node = self.nodes[ni as usize];
            if node.count > 0 {
                for &ti in &self.order[node.start as usize..(node.start + node.count) as usize] {
                    let [a, b, c] = self.mesh.corners(ti as usize);
                    if let Some((t, u, v)) = ray_triangle(origin, dir, a, b, c) {
                        if t > t_min && t < t_best {
                            t_best = t;
                            best = Some(RayHit { t, triangle: ti, u, v });
                        }
                    }
                }
            } else if sp + 2 <= stack.len() {
                let enter = |i: u32| {
                    let n = self.nodes[i as usize];
                    slab_entry(origin, inv, n.lo, n.hi, t_min, t_best).map(|t| (i, t))
                };
                // Push the farther child first, so that the nearer is visited next.
                match (enter(node.start), enter(node.start + 1)) {
                    (Some(l), Some(r)) => {
                        let (near, far) = if r.1 < l.1 { (r, l) } else { (l, r) };
                        stack[sp] = far;
                        stack[sp + 1] = near;
                        sp += 2;
                    }
                    (Some(one), None) | (None, Some(one)) => {
                        stack[sp] = one;
                        sp += 1;
                    }
                    (None, None) => {}
                }
            }
        }
        best
    }

    /// Whether the ray `origin + t * dir` hits the mesh anywhere with `t_min < t < t_max` (an
    /// occlusion test: the same answer as `ray_cast(..).is_some()`, returned at the first hit
    /// found).
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
        if !(origin.is_finite() && dir.is_finite()) || dir == Vec3::ZERO || self.order.is_empty() {
            return false;
        }
        let inv = Vec3::ONE / dir;
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            if slab_entry(origin, inv, node.lo, node.hi, t_min, t_max).is_none() {
                continue;
            }
            if node.count > 0 {
                for &ti in &self.order[node.start as usize..(node.start + node.count) as usize] {
                    let [a, b, c] = self.mesh.corners(ti as usize);
                    if ray_triangle(origin, dir, a, b, c).is_some_and(|(t, _, _)| t > t_min && t < t_max) {
                        return true;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
            }
        }
        false
    }
}

/// Where the ray enters the box within `[t_min, t_max]`; `None` when it misses it there.
#[inline]
fn slab_entry(o: Vec3, inv: Vec3, lo: Vec3, hi: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let tn = t0.min(t1).max_element().max(t_min);
    let tf = t0.max(t1).min_element().min(t_max);
    // NaN (0 * inf) comparisons fall through to "hit" (entering at `t_min`), which is conservative.
    if tn.is_nan() || tf.is_nan() {
        Some(t_min)
    } else {
        (tn <= tf).then_some(tn)
    }
}

/// Möller–Trumbore ray/triangle intersection, both faces. Returns (t, u, v).
#[inline]
pub fn ray_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<(f32, f32, f32)> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((e2.dot(qv) * inv, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriMesh;

    /// A soup of 400 random triangles overlapping in a 2-unit box, and random rays through it: the
    /// nearer-child-first traversal finds the brute-force first hit, and the occlusion test agrees
    /// with it, for any `t` range.
    #[test]
    fn ray_queries_agree_with_brute_force_on_a_triangle_soup() {
        let mut rnd = crate::mesh::tests::uniform(987_654_321, 1.0);
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..400u32 {
            let c = Vec3::new(rnd(), rnd(), rnd());
            for _ in 0..3 {
                vertices.push(c + 0.2 * Vec3::new(rnd(), rnd(), rnd()));
            }
            triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let mesh = TriMesh::new(vertices, triangles, None, None).unwrap();
        let bvh = Bvh::new(mesh.clone());
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..2000 {
            let o = 3.0 * Vec3::new(rnd(), rnd(), rnd());
            // Towards a point of the soup's box (t = 1 there).
            let d = Vec3::new(rnd(), rnd(), rnd()) - o;
            let (t_min, t_max) = (0.5 * rnd().abs(), if rnd() > 0.0 { f32::INFINITY } else { 0.6 + rnd().abs() });
            let brute = (0..mesh.triangles.len())
                .filter_map(|i| {
                    let [a, b, c] = mesh.corners(i);
                    ray_triangle(o, d, a, b, c).map(|h| h.0).filter(|&t| t > t_min && t < t_max)
                })
                .fold(None, |m: Option<f32>, t| Some(m.map_or(t, |m| m.min(t))));
            let hit = bvh.ray_cast(o, d, t_min, t_max);
            assert_eq!(hit.map(|h| h.t), brute, "ray {o:?} + t {d:?}, t in ({t_min}, {t_max})");
            assert_eq!(bvh.occluded(o, d, t_min, t_max), brute.is_some());
            if brute.is_some() {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 200 && misses > 200, "{hits} hits, {misses} misses: the rays should test both");
    }
}
