//! Triangle meshes and a bounding-volume hierarchy for ray casts, closest points and inside tests.
//!
//! [`TriMesh`] is validated at construction (finite vertices, indices in range, optional per-vertex
//! normals and UVs of the right length). [`Bvh`] is a binary BVH over triangles built by median split
//! on the longest axis of the centroid bounds; queries are exact:
//! - ray casts with the Möller–Trumbore test (Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle
//!   Intersection", 1997);
//! - closest points with the Voronoi-region method of Ericson, "Real-Time Collision Detection",
//!   §5.1.5;
//! - inside tests by the sign of the angle-weighted pseudo-normal at the closest feature
//!   (Bærentzen & Aanæs, "Signed distance computation using the angle weighted pseudonormal", 2005),
//!   which is robust for closed meshes. For meshes with holes (a head cut at the neck) it is still
//!   the right answer near the surface, which is where hair lives. Where faces fold over their
//!   neighbours (a noisy photogrammetry mesh) the pseudo-normal can point the wrong way, and the
//!   test at those triangles is a vote of the surface around the closest point instead (`mesh/folds.rs`).
//!
//! A hand-written BVH keeps this crate small: we need three queries, all in f32 glam, and the
//! collision crates we looked at (parry3d 0.31) bring their own math types.

use std::sync::OnceLock;

use glam::{Vec2, Vec3};
use rustc_hash::FxHashMap;
use thiserror::Error;

mod folds;
mod ray;

pub use ray::ray_triangle;

/// Why a mesh could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    #[error("mesh has no triangles; give a mesh with at least one face")]
    NoFaces,
    #[error("vertex {0} is not finite; remove NaN or infinite coordinates")]
    NotFinite(usize),
    #[error("triangle {tri} uses vertex {index} but the mesh has only {count} vertices")]
    IndexOutOfRange { tri: usize, index: u32, count: usize },
    #[error("the mesh has {got} {what} but {expected} vertices; give one per vertex")]
    AttributeLength { what: &'static str, got: usize, expected: usize },
}

/// A triangle mesh with optional per-vertex normals and UVs.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
}

impl TriMesh {
    /// Builds and validates a mesh.
    pub fn new(
        vertices: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
    ) -> Result<Self, MeshError> {
        if triangles.is_empty() {
            return Err(MeshError::NoFaces);
        }
        if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(MeshError::NotFinite(i));
        }
        for (tri, t) in triangles.iter().enumerate() {
            for &index in t {
                if index as usize >= vertices.len() {
                    return Err(MeshError::IndexOutOfRange { tri, index, count: vertices.len() });
                }
            }
        }
        if let Some(n) = &normals {
            if n.len() != vertices.len() {
                return Err(MeshError::AttributeLength { what: "normals", got: n.len(), expected: vertices.len() });
            }
        }
        if let Some(uv) = &uvs {
            if uv.len() != vertices.len() {
                return Err(MeshError::AttributeLength { what: "UVs", got: uv.len(), expected: vertices.len() });
            }
        }
        Ok(Self { vertices, triangles, normals, uvs })
    }

    /// The three corners of triangle `i`.
    #[inline]
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        let t = self.triangles[i];
        [self.vertices[t[0] as usize], self.vertices[t[1] as usize], self.vertices[t[2] as usize]]
    }

    /// Unit face normal of triangle `i` (counter-clockwise winding); zero for a degenerate triangle.
    pub fn face_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.corners(i);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Area of triangle `i`.
    pub fn face_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.corners(i);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Area-weighted vertex normals computed from the faces.
    pub fn compute_vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; self.vertices.len()];
        for (i, t) in self.triangles.iter().enumerate() {
            let [a, b, c] = self.corners(i);
            let fnrm = (b - a).cross(c - a);
            for &v in t {
                n[v as usize] += fnrm;
            }
        }
        n.into_iter().map(|v| v.normalize_or_zero()).collect()
    }

    /// The distinct vertex positions (bit for bit) in first-seen order, and each vertex's index into
    /// them: a mesh split at UV seams or written per face becomes one surface.
    pub fn weld_positions(&self) -> (Vec<Vec3>, Vec<u32>) {
        let mut index: FxHashMap<[u32; 3], u32> =
            FxHashMap::with_capacity_and_hasher(self.vertices.len(), Default::default());
        let mut positions = Vec::new();
        let remap = self
            .vertices
            .iter()
            .map(|p| {
                *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                    positions.push(*p);
                    positions.len() as u32 - 1
                })
            })
            .collect();
        (positions, remap)
    }

    /// Axis-aligned bounding box of the vertices.
    pub fn bbox(&self) -> (Vec3, Vec3) {
        let first = self.vertices.first().copied().unwrap_or(Vec3::ZERO);
        self.vertices.iter().fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)))
    }

    /// The same mesh with every vertex (and normal, by the linear part) mapped.
    pub fn transformed(&self, m: glam::Affine3A) -> Self {
        let nm = glam::Mat3::from(m.matrix3).inverse().transpose();
        Self {
            vertices: self.vertices.iter().map(|&v| m.transform_point3(v)).collect(),
            triangles: self.triangles.clone(),
            normals: self.normals.as_ref().map(|n| n.iter().map(|&v| (nm * v).normalize_or_zero()).collect()),
            uvs: self.uvs.clone(),
        }
    }
}

/// Result of a ray cast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit or not) ray direction: `origin + t * dir`.
    pub t: f32,
    pub triangle: u32,
    /// Barycentric coordinates of the hit (weights of corners 1 and 2; corner 0 gets 1 - u - v).
    pub u: f32,
    pub v: f32,
}

/// Result of a closest-point query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    pub point: Vec3,
    pub distance: f32,
    pub triangle: u32,
    /// Barycentric weights of the three corners.
    pub bary: Vec3,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// For a leaf: first triangle index into `order`; for an inner node: index of the left child
    /// (the right child is `left + 1`).
    start: u32,
    /// Number of triangles for a leaf, 0 for an inner node.
    count: u32,
}

/// A bounding-volume hierarchy over a mesh's triangles. It owns a copy of the mesh.
#[derive(Debug, Clone)]
pub struct Bvh {
    mesh: TriMesh,
    nodes: Vec<Node>,
    order: Vec<u32>,
    /// The welded edges and pseudo-normals, made on the first query that needs them (inside
    /// tests, the rim, folds): closest points and rays alone never do, and on a photogrammetry
    /// mesh of millions of triangles they take twice as long to make as the tree.
    topology: OnceLock<Topology>,
    /// Per triangle, whether a corner has a folded edge, where inside tests vote over the
    /// neighbourhood (empty when no edge folds; see `mesh/folds.rs`).
    doubtful: Vec<bool>,
    /// The radius of that vote (zero when nothing is doubtful).
    vote_radius: f32,
}

/// What inside tests and the rim need of a mesh's connectivity.
#[derive(Debug, Clone)]
struct Topology {
    /// Angle-weighted pseudo-normals for vertices and for edges (keyed by sorted vertex pair), with
    /// the number of faces at each edge.
    vertex_pn: Vec<Vec3>,
    edge_pn: FxHashMap<(u32, u32), (Vec3, u32)>,
    /// Vertices on an edge with a single face (the rim of an open mesh).
    boundary_vertex: Vec<bool>,
    /// Each vertex's first vertex at the same position (the key of the two tables above).
    weld: Vec<u32>,
}

impl Topology {
    fn of(mesh: &TriMesh) -> Self {
        let n = mesh.triangles.len();
        // Vertices at the same position are one for the pseudo-normals and the rim (meshes from
        // Blender split vertices at UV seams, which would otherwise look like open edges).
        let mut first: FxHashMap<[u32; 3], u32> =
            FxHashMap::with_capacity_and_hasher(mesh.vertices.len(), Default::default());
        let weld: Vec<u32> = (0..mesh.vertices.len() as u32)
            .map(|i| *first.entry(mesh.vertices[i as usize].to_array().map(f32::to_bits)).or_insert(i))
            .collect();
        // Angle-weighted pseudo-normals.
        let mut vertex_pn = vec![Vec3::ZERO; mesh.vertices.len()];
        let mut edge_pn = FxHashMap::with_capacity_and_hasher(n * 3 / 2, Default::default());
        for i in 0..n {
            let t = mesh.triangles[i].map(|v| weld[v as usize]);
            let fnrm = mesh.face_normal(i);
            let c = mesh.corners(i);
            for k in 0..3 {
                let a = c[k];
                let b = c[(k + 1) % 3];
                let d = c[(k + 2) % 3];
                let angle = (b - a).normalize_or_zero().dot((d - a).normalize_or_zero()).clamp(-1.0, 1.0).acos();
                vertex_pn[t[k] as usize] += angle * fnrm;
                let (x, y) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                let e = edge_pn.entry((x, y)).or_insert((Vec3::ZERO, 0));
                e.0 += fnrm;
                e.1 += 1;
            }
        }
        let mut boundary_vertex = vec![false; mesh.vertices.len()];
        for (&(a, b), &(_, faces)) in &edge_pn {
            if faces == 1 {
                boundary_vertex[a as usize] = true;
                boundary_vertex[b as usize] = true;
            }
        }
        Self { vertex_pn, edge_pn, boundary_vertex, weld }
    }
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    /// Builds the hierarchy. O(n log n).
    pub fn new(mesh: TriMesh) -> Self {
        let n = mesh.triangles.len();
        let centroids: Vec<Vec3> = (0..n)
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                (a + b + c) / 3.0
            })
            .collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF_SIZE + 2);
        nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
        // Iterative build: (node index, range start, range end).
        let mut stack = vec![(0usize, 0usize, n)];
        while let Some((ni, s, e)) = stack.pop() {
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            let (mut clo, mut chi) = (lo, hi);
            for &t in &order[s..e] {
                for p in mesh.corners(t as usize) {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                clo = clo.min(centroids[t as usize]);
                chi = chi.max(centroids[t as usize]);
            }
            nodes[ni].lo = lo;
            nodes[ni].hi = hi;
            if e - s <= LEAF_SIZE {
                nodes[ni].start = s as u32;
                nodes[ni].count = (e - s) as u32;
                continue;
            }
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (s + e) / 2;
            order[s..e].select_nth_unstable_by(mid - s, |&a, &b| {
                centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
            });
            let left = nodes.len();
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            nodes[ni].start = left as u32;
            nodes[ni].count = 0;
            stack.push((left, s, mid));
            stack.push((left + 1, mid, e));
        }
        Self { mesh, nodes, order, topology: OnceLock::new(), doubtful: Vec::new(), vote_radius: 0.0 }
    }

    /// [`Bvh::new`] for a measured surface (a photogrammetry or fused mesh): where its faces fold
    /// over each other, inside tests vote over the surface around the closest point instead of
    /// trusting the pseudo-normal there (`mesh/folds.rs`). Not for modelled meshes: a head's sharp creases
    /// (the ears, the nostrils) fold by more than 90° too, and the pseudo-normal is exact there.
    pub fn with_fold_vote(mesh: TriMesh) -> Self {
        let mut bvh = Self::new(mesh);
        let topo = bvh.topology();
        let doubtful = folds::doubtful_triangles(&bvh.mesh.triangles, &topo.weld, &topo.edge_pn);
        bvh.doubtful = doubtful;
        if !bvh.doubtful.is_empty() {
            bvh.vote_radius = folds::VOTE_RADIUS_EDGES * folds::mean_edge(&bvh);
        }
        bvh
    }

    /// The fraction of triangles at a folded edge, whose inside tests vote over the neighbourhood.
    pub fn doubtful_fraction(&self) -> f32 {
        if self.doubtful.is_empty() {
            0.0
        } else {
            self.doubtful.iter().filter(|d| **d).count() as f32 / self.doubtful.len() as f32
        }
    }

    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    fn topology(&self) -> &Topology {
        self.topology.get_or_init(|| Topology::of(&self.mesh))
    }

    /// The mesh's rim: its edges with one face (after welding), as pairs of end points, in a fixed order.
    pub fn rim_edges(&self) -> Vec<(Vec3, Vec3)> {
        let mut e: Vec<(u32, u32)> =
            self.topology().edge_pn.iter().filter(|(_, &(_, faces))| faces == 1).map(|(&k, _)| k).collect();
        e.sort_unstable();
        e.into_iter().map(|(a, b)| (self.mesh.vertices[a as usize], self.mesh.vertices[b as usize])).collect()
    }

    /// The closest point of the mesh to `p` within `max_dist` (use `f32::INFINITY` for no limit).
    pub fn closest_point(&self, p: Vec3, max_dist: f32) -> Option<ClosestPoint> {
        self.closest_point_near(p, max_dist, None)
    }

    /// [`Bvh::closest_point`] given a triangle that is likely close to `p` (the closest triangle of
    /// a neighbouring query): its distance bounds the search from the start, so fewer nodes are
    /// opened. The result is the same as without the hint: every triangle at the smallest distance
    /// is still visited, in the same order.
    pub fn closest_point_near(&self, p: Vec3, max_dist: f32, hint: Option<u32>) -> Option<ClosestPoint> {
        // A NaN point's box distances compare false with everything: it would visit every node.
        if !p.is_finite() {
            return None;
        }
        let mut best: Option<ClosestPoint> = None;
        let mut best_d2 = if max_dist.is_finite() { max_dist * max_dist } else { f32::INFINITY };
        if let Some(t) = hint.filter(|&t| (t as usize) < self.mesh.triangles.len()) {
            let [a, b, c] = self.mesh.corners(t as usize);
            let (q, _) = closest_on_triangle(p, a, b, c);
            // a margin over the rounding of a node's box distance against its triangles' distances
            best_d2 = best_d2.min((q - p).length_squared() * (1.0 + 1e-5) + 1e-14);
        }
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            let d2 = (p - p.clamp(node.lo, node.hi)).length_squared();
            if d2 > best_d2 {
                continue;
            }
            if node.count > 0 {
                for &ti in &self.order[node.start as usize..(node.start + node.count) as usize] {
                    let [a, b, c] = self.mesh.corners(ti as usize);
                    let (q, bary) = closest_on_triangle(p, a, b, c);
                    let d2 = (q - p).length_squared();
                    if d2 <= best_d2 {
                        best_d2 = d2;
                        best = Some(ClosestPoint { point: q, distance: d2.sqrt(), triangle: ti, bary });
                    }
                }
            } else if sp + 2 <= stack.len() {
                // Visit the nearer child first: push it last.
                let l = self.nodes[node.start as usize];
                let r = self.nodes[node.start as usize + 1];
                let dl = (p - p.clamp(l.lo, l.hi)).length_squared();
                let dr = (p - p.clamp(r.lo, r.hi)).length_squared();
                if dl < dr {
                    stack[sp] = node.start + 1;
                    stack[sp + 1] = node.start;
                } else {
                    stack[sp] = node.start;
                    stack[sp + 1] = node.start + 1;
                }
                sp += 2;
            }
        }
        best
    }

    /// Signed distance to the mesh within `max_dist`: negative inside (behind the outward
    /// pseudo-normal of the closest feature), positive outside. `None` if nothing is within `max_dist`.
    ///
    /// An open mesh has no inside beyond its rim: when the closest feature is a boundary edge or a
    /// boundary vertex (an edge with one face), the point is outside (for example the space below
    /// a head mesh cut off at the neck, which the pseudo-normals of the rim would call inside).
    pub fn signed_distance(&self, p: Vec3, max_dist: f32) -> Option<f32> {
        self.signed_distance_near(p, max_dist, None).map(|(d, _)| d)
    }

    /// [`Bvh::signed_distance`] with a hint (see [`Bvh::closest_point_near`]); also returns the
    /// closest triangle, the hint for the next query nearby.
    pub fn signed_distance_near(&self, p: Vec3, max_dist: f32, hint: Option<u32>) -> Option<(f32, u32)> {
        let cp = self.closest_point_near(p, max_dist, hint)?;
        let t = cp.triangle;
        if self.on_boundary(&cp) {
            return Some((cp.distance, t));
        }
        if self.doubtful.get(cp.triangle as usize).copied().unwrap_or(false) {
            let n = folds::net_normal(self, cp.point, self.vote_radius);
            return Some((if (p - cp.point).dot(n) < 0.0 { -cp.distance } else { cp.distance }, t));
        }
        let n = self.pseudo_normal(&cp);
        let s = if (p - cp.point).dot(n) < 0.0 { -1.0 } else { 1.0 };
        Some((s * cp.distance, t))
    }

    /// Whether a closest point lies on the mesh's rim (a boundary edge or vertex), not inside a face.
    fn on_boundary(&self, cp: &ClosestPoint) -> bool {
        let topo = self.topology();
        let t = self.mesh.triangles[cp.triangle as usize].map(|v| topo.weld[v as usize]);
        let eps = 1e-6;
        let zero: Vec<usize> = (0..3).filter(|&k| cp.bary[k] <= eps).collect();
        match zero.len() {
            0 => false,
            1 => {
                let k = zero[0];
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                topo.edge_pn.get(&(a.min(b), a.max(b))).is_some_and(|e| e.1 == 1)
            }
            _ => {
                let k = (0..3).find(|k| !zero.contains(k)).unwrap_or(0);
                topo.boundary_vertex[t[k] as usize]
            }
        }
    }

    /// Outward pseudo-normal at a closest point: the face normal inside a face, the edge or vertex
    /// pseudo-normal on an edge or a corner.
    pub fn pseudo_normal(&self, cp: &ClosestPoint) -> Vec3 {
        let topo = self.topology();
        let t = self.mesh.triangles[cp.triangle as usize].map(|v| topo.weld[v as usize]);
        let eps = 1e-6;
        let zero: Vec<usize> = (0..3).filter(|&k| cp.bary[k] <= eps).collect();
        match zero.len() {
            0 => self.mesh.face_normal(cp.triangle as usize),
            1 => {
                let k = zero[0];
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                topo.edge_pn.get(&(a.min(b), a.max(b))).map_or(Vec3::ZERO, |e| e.0)
            }
            _ => {
                let k = (0..3).find(|k| !zero.contains(k)).unwrap_or(0);
                topo.vertex_pn[t[k] as usize]
            }
        }
    }

    /// Interpolates a per-vertex attribute at a closest point or ray hit given its triangle and
    /// barycentric weights.
    pub fn interpolate<T>(&self, values: &[T], triangle: u32, bary: Vec3) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let t = self.mesh.triangles[triangle as usize];
        values[t[0] as usize] * bary.x + values[t[1] as usize] * bary.y + values[t[2] as usize] * bary.z
    }
}

/// Closest point on triangle `abc` to `p` (Ericson §5.1.5). Returns the point and its barycentric
/// weights for (a, b, c).
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec3::X);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Vec3::new(1.0 - v, v, 0.0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Vec3::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Vec3::new(0.0, 1.0 - w, w));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Vec3::new(1.0 - v - w, v, w))
}

/// A closed unit cube centred at the origin (12 triangles, outward winding); handy in tests.
pub fn unit_cube() -> TriMesh {
    let v: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f32 - 0.5, ((i >> 1) & 1) as f32 - 0.5, ((i >> 2) & 1) as f32 - 0.5))
        .collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut t = Vec::new();
    for q in quads {
        t.push([q[0], q[1], q[2]]);
        t.push([q[0], q[2], q[3]]);
    }
    TriMesh { vertices: v, triangles: t, normals: None, uvs: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded xorshift stream of numbers uniform in [−half, half].
    pub(in crate::mesh) fn uniform(mut s: u32, half: f32) -> impl FnMut() -> f32 {
        move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32) * 2.0 * half - half
        }
    }

    /// A UV sphere of radius r, outward winding.
    fn sphere(r: f32, nu: usize, nv: usize) -> TriMesh {
        let mut v = vec![Vec3::new(0.0, 0.0, r)];
        for i in 1..nv {
            let th = std::f32::consts::PI * i as f32 / nv as f32;
            for j in 0..nu {
                let ph = std::f32::consts::TAU * j as f32 / nu as f32;
                v.push(r * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
            }
        }
        v.push(Vec3::new(0.0, 0.0, -r));
        let last = v.len() as u32 - 1;
        let idx = |i: usize, j: usize| (1 + (i - 1) * nu + (j % nu)) as u32;
        let mut t = Vec::new();
        for j in 0..nu {
            t.push([0, idx(1, j), idx(1, j + 1)]);
            t.push([last, idx(nv - 1, j + 1), idx(nv - 1, j)]);
        }
        for i in 1..nv - 1 {
            for j in 0..nu {
                t.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                t.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            }
        }
        TriMesh::new(v, t, None, None).unwrap()
    }

    #[test]
    fn queries_agree_with_brute_force_on_a_sphere() {
        let m = sphere(1.0, 32, 16);
        let bvh = Bvh::new(m.clone());
        // A NaN or zero ray hits nothing (NaN passes every box test and would visit every node).
        assert!(bvh.ray_cast(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, 0.0, f32::INFINITY).is_some());
        assert!(bvh.ray_cast(Vec3::new(0.0, 0.0, -3.0), Vec3::new(f32::NAN, 0.0, 1.0), 0.0, f32::INFINITY).is_none());
        assert!(bvh.ray_cast(Vec3::NAN, Vec3::Z, 0.0, f32::INFINITY).is_none());
        assert!(bvh.ray_cast(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, 0.0, f32::INFINITY).is_none());
        let mut rnd = uniform(12345, 2.0);
        for _ in 0..300 {
            let p = Vec3::new(rnd(), rnd(), rnd());
            let cp = bvh.closest_point(p, f32::INFINITY).unwrap();
            let brute = (0..m.triangles.len())
                .map(|i| {
                    let [a, b, c] = m.corners(i);
                    closest_on_triangle(p, a, b, c).0.distance(p)
                })
                .fold(f32::INFINITY, f32::min);
            assert!((cp.distance - brute).abs() < 1e-5, "{p:?}: {} vs {brute}", cp.distance);
            // Inside/outside agrees with the analytic sphere where not too close to the surface.
            let sd = bvh.signed_distance(p, f32::INFINITY).unwrap();
            if (p.length() - 1.0).abs() > 0.05 {
                assert_eq!(sd < 0.0, p.length() < 1.0, "{p:?} sd={sd}");
            }
            // A ray from outside toward the centre hits the sphere at about radius 1.
            if p.length() > 1.1 {
                let d = -p.normalize();
                let hit = bvh.ray_cast(p, d, 0.0, f32::INFINITY).unwrap();
                assert!(((p + d * hit.t).length() - 1.0).abs() < 0.02);
            }
        }
        assert!(bvh.ray_cast(Vec3::new(0.0, 0.0, 3.0), Vec3::X, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn a_hint_gives_the_same_closest_point_and_signed_distance() {
        // Points along rows, as the flow's distance pass queries them; hints from the last point's
        // closest triangle, from far triangles and out of range.
        let m = sphere(1.0, 48, 24);
        let bvh = Bvh::new(m.clone());
        let n = m.triangles.len() as u32;
        let mut rnd = uniform(777, 1.6);
        let mut other_triangle = 0;
        for _ in 0..60 {
            let start = Vec3::new(rnd(), rnd(), rnd());
            let mut last = None;
            for i in 0..20 {
                let p = start + Vec3::X * (0.03 * i as f32);
                for max_dist in [f32::INFINITY, 0.3] {
                    let plain = bvh.closest_point(p, max_dist);
                    for hint in [last, Some(0), Some(n / 2), Some(n + 5)] {
                        let near = bvh.closest_point_near(p, max_dist, hint);
                        assert_eq!(
                            plain.map(|c| (c.triangle, c.point, c.distance, c.bary)),
                            near.map(|c| (c.triangle, c.point, c.distance, c.bary)),
                            "{p:?} {hint:?}"
                        );
                        let sd = bvh.signed_distance(p, max_dist);
                        assert_eq!(sd, bvh.signed_distance_near(p, max_dist, hint).map(|(d, _)| d));
                    }
                }
                let cp = bvh.closest_point(p, f32::INFINITY).unwrap();
                if last.is_some_and(|t| t != cp.triangle) {
                    other_triangle += 1;
                }
                last = Some(cp.triangle);
            }
        }
        // the rows cross triangles, so most hints are a neighbour's triangle, not the answer itself
        assert!(other_triangle > 300, "{other_triangle}");
    }
    #[test]
    fn cube_is_closed_and_signed() {
        let bvh = Bvh::new(unit_cube());
        assert!(bvh.signed_distance(Vec3::ZERO, 10.0).unwrap() < 0.0);
        assert!((bvh.signed_distance(Vec3::new(0.0, 0.0, 0.9), 10.0).unwrap() - 0.4).abs() < 1e-6);
        // Near a corner, the vertex pseudo-normal decides.
        assert!(bvh.signed_distance(Vec3::splat(0.6), 10.0).unwrap() > 0.0);
        assert!(bvh.signed_distance(Vec3::splat(0.45), 10.0).unwrap() < 0.0);
    }

    #[test]
    fn open_mesh_has_no_inside_beyond_its_rim() {
        // A sphere with its bottom cap removed (like a head cut at the neck).
        let full = sphere(1.0, 32, 16);
        let keep: Vec<[u32; 3]> = full
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().map(|&i| full.vertices[i as usize].z).sum::<f32>() / 3.0 > -0.7)
            .collect();
        let bvh = Bvh::new(TriMesh::new(full.vertices.clone(), keep, None, None).unwrap());
        // Inside, far from the rim: negative, as for the closed sphere.
        assert!(bvh.signed_distance(Vec3::new(0.0, 0.0, 0.2), 10.0).unwrap() < 0.0);
        assert!(bvh.signed_distance(Vec3::new(0.3, 0.0, -0.3), 10.0).unwrap() < 0.0);
        // Below the cut, under the opening: the closest point is on the rim, so outside. The closed
        // sphere's pseudo-normals would call (0, 0, -1.5) inside of the rim's faces.
        for p in [Vec3::new(0.0, 0.0, -1.5), Vec3::new(0.2, 0.1, -2.0), Vec3::new(0.0, 0.0, -0.95)] {
            let sd = bvh.signed_distance(p, 10.0).unwrap();
            assert!(sd > 0.0, "{p:?} sd={sd}");
        }
        // Outside beside the sphere: positive.
        assert!(bvh.signed_distance(Vec3::new(1.5, 0.0, 0.0), 10.0).unwrap() > 0.0);

        // A closed sphere split along a seam (every triangle with its own three vertices, as a PLY
        // exported with per-face UVs) is still closed: inside stays inside right next to an edge.
        let mut v = Vec::new();
        let mut t = Vec::new();
        for tri in &full.triangles {
            let b = v.len() as u32;
            v.extend(tri.iter().map(|&i| full.vertices[i as usize]));
            t.push([b, b + 1, b + 2]);
        }
        let split = Bvh::new(TriMesh::new(v, t, None, None).unwrap());
        let closed = Bvh::new(full);
        let mut s = 7u32;
        for _ in 0..200 {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let u = (s >> 8) as f32 / (1 << 24) as f32;
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let w = (s >> 8) as f32 / (1 << 24) as f32;
            let dir = Vec3::new(
                (u * std::f32::consts::TAU).cos() * (1.0 - w * w).sqrt(),
                (u * std::f32::consts::TAU).sin() * (1.0 - w * w).sqrt(),
                w,
            );
            for r in [0.97, 1.03] {
                let p = dir * r;
                let (a, b) = (split.signed_distance(p, 10.0).unwrap(), closed.signed_distance(p, 10.0).unwrap());
                assert!((a - b).abs() < 1e-6, "{p:?}: split {a} closed {b}");
            }
        }
    }

    #[test]
    fn rejects_bad_meshes() {
        assert_eq!(TriMesh::new(vec![Vec3::ZERO; 3], vec![], None, None), Err(MeshError::NoFaces));
        assert!(matches!(
            TriMesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 3]], None, None),
            Err(MeshError::IndexOutOfRange { .. })
        ));
    }

    /// Vertex noise of a quarter of the edge length folds faces (about 5% of the edges here); the
    /// pseudo-normal alone then calls about 1% of points 2 cm outside "inside" (measured when this
    /// test was written). The vote at doubtful triangles must call every one right.
    #[test]
    fn inside_tests_survive_folded_faces() {
        let clean = sphere(0.1, 314, 157);
        assert_eq!(Bvh::with_fold_vote(clean.clone()).doubtful_fraction(), 0.0, "a clean sphere has no folds");
        let mut s = 99u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32).max(1e-9)
        };
        let mut gauss = || (-2.0 * rnd().ln()).sqrt() * (std::f32::consts::TAU * rnd()).cos();
        let noisy: Vec<Vec3> =
            clean.vertices.iter().map(|p| *p + 0.5e-3 * Vec3::new(gauss(), gauss(), gauss())).collect();
        let plain = Bvh::new(TriMesh::new(noisy.clone(), clean.triangles.clone(), None, None).unwrap());
        assert_eq!(plain.doubtful_fraction(), 0.0, "Bvh::new keeps the pseudo-normal everywhere");
        let bvh = Bvh::with_fold_vote(TriMesh::new(noisy, clean.triangles.clone(), None, None).unwrap());
        assert!(bvh.doubtful_fraction() > 0.05, "the noise folds faces: {}", bvh.doubtful_fraction());
        let mut wrong = Vec::new();
        for dist in [0.003f32, 0.02, -0.003, -0.02] {
            for _ in 0..3000 {
                let dir = Vec3::new(gauss(), gauss(), gauss()).normalize();
                let p = dir * (0.1 + dist);
                let sd = bvh.signed_distance(p, 1.0).unwrap();
                if sd.signum() != dist.signum() {
                    wrong.push((p, dist, sd));
                }
            }
        }
        assert!(wrong.is_empty(), "{} of 12000 signs wrong, e.g. {:?}", wrong.len(), &wrong[..wrong.len().min(3)]);
    }
}
