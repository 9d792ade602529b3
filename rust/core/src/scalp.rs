//! The scalp: where hair roots grow and in which direction they leave the skin.
//!
//! In: a scalp mesh (a triangle mesh of the region where roots may grow, in metres, world frame with
//! **+Z up** and the **face looking along −Y**, Blender's front view; see [`WORLD_UP`], [`FACE_DIR`]).
//! Out: the growth direction field S(p_s) and roots in blue noise on the mesh.
//!
//! **S(p_s)** is the boundary condition of Dr.Hair (Takimoto et al., CVPR 2024, Eq. 2 of the main
//! paper and Figure 11 of its supplement): the natural direction of the scalp pores, *not* the scalp
//! normal. The paper gives no formula, so ours is a geometric model of the hair whorl:
//! - the **whorl** is the scalp point furthest along the direction tilted [`WHORL_TILT_DEG`] from up
//!   toward the back of the head (the crown, a little behind the top);
//! - the tangential direction `t` points away from the whorl along the surface (the tangent-plane part
//!   of `p − whorl`), plus [`DOWN_WEIGHT`] times the tangent-plane part of "down", turned about the
//!   normal by a swirl of [`SWIRL_DEG`] that fades out with the distance from the whorl;
//! - `S = cos θ · n + sin θ · t`, where the tilt from the normal `θ` grows smoothly from 0 at the
//!   whorl to [`MAX_TILT_DEG`] at a distance of [`RAMP_FRACTION`] × the largest extent of the scalp.
//!
//! So S is the normal at the whorl, tilts forward at the front hairline and down-and-back at the
//! sides and the back, and always keeps a positive component `cos θ ≥ 0.5` along the normal.
//!
//! **Roots in blue noise** follow Yuksel, "Sample Elimination for Generating Poisson Disk Sample Sets"
//! (Computer Graphics Forum 34(2), Eurographics 2015): draw [`CANDIDATE_FACTOR`] × n area-weighted
//! random candidates on the mesh, then remove, one at a time, the candidate with the largest weight
//! `Σ_j (1 − d̂_ij / 2r_max)^8` over its neighbours closer than `2 r_max` (with the paper's weight
//! limiting for `d̂` and `r_max = sqrt(A / (2√3 n))`, the radius of hexagonal packing), updating its
//! neighbours, until n remain. Distances are Euclidean in 3D, which is what matters for hair density.
//!
//! Randomness is a counter-based hash (SplitMix64, Steele, Lea & Flood, "Fast splittable pseudorandom
//! number generators", OOPSLA 2014) of (seed, sample index), so the same seed gives the same roots on
//! any machine and with any number of threads.

use glam::{Vec2, Vec3};
use thiserror::Error;

use crate::mesh::{Bvh, TriMesh};

/// World up: +Z (Blender).
pub const WORLD_UP: Vec3 = Vec3::Z;
/// The direction the face looks: −Y (Blender's front view looks at the face along +Y).
pub const FACE_DIR: Vec3 = Vec3::NEG_Y;
/// The whorl is the scalp point furthest along the direction tilted this many degrees from up toward
/// the back of the head.
pub const WHORL_TILT_DEG: f32 = 30.0;
/// The largest angle between S and the normal, reached far from the whorl.
pub const MAX_TILT_DEG: f32 = 60.0;
/// The tilt ramps up over this fraction of the largest extent of the scalp's bounding box.
pub const RAMP_FRACTION: f32 = 0.35;
/// Weight of "down" (projected on the tangent plane) against "away from the whorl".
pub const DOWN_WEIGHT: f32 = 0.6;
/// Swirl of the tangential direction about the normal at the whorl (clockwise seen from above, the
/// common whorl); it fades out over the ramp.
pub const SWIRL_DEG: f32 = 35.0;
/// Candidates per root for sample elimination (Yuksel 2015 recommends 3 to 5 or more).
pub const CANDIDATE_FACTOR: usize = 5;

/// Why a scalp could not be used.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ScalpError {
    #[error("the scalp mesh has zero area; give a scalp mesh with non-degenerate triangles")]
    ZeroArea,
    #[error("asked for 0 roots; ask for at least one")]
    NoRoots,
    #[error("asked for {0} roots, more than this sampler supports (2^28); ask for fewer")]
    TooManyRoots(usize),
}

/// A point on the scalp with the direction in which hair grows there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Root {
    /// Position on the scalp mesh, metres.
    pub position: Vec3,
    /// Unit outward normal of the scalp (interpolated vertex normal, or the face normal).
    pub normal: Vec3,
    /// Unit growth direction S(p_s).
    pub direction: Vec3,
    /// Triangle of the scalp mesh that holds the root.
    pub triangle: u32,
    /// Barycentric weights of the triangle's three corners.
    pub bary: Vec3,
    /// Texture coordinate, when the scalp mesh has UVs.
    pub uv: Option<Vec2>,
}

/// The growth direction field S(p_s) (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrowthField {
    /// The whorl (crown) point.
    pub whorl: Vec3,
    /// Distance from the whorl over which the tilt grows from 0 to `max_tilt`, metres.
    pub ramp: f32,
    /// Largest angle between S and the normal, radians.
    pub max_tilt: f32,
    /// Weight of "down" against "away from the whorl" in the tangential part.
    pub down_weight: f32,
    /// Swirl angle about the normal at the whorl, radians (positive: clockwise seen from above).
    pub swirl: f32,
}

impl GrowthField {
    /// The field with the default constants of this module and the whorl found on `scalp`.
    fn from_mesh(scalp: &TriMesh) -> Self {
        let (lo, hi) = scalp.bbox();
        let centre = 0.5 * (lo + hi);
        let t = WHORL_TILT_DEG.to_radians();
        let dir = WORLD_UP * t.cos() - FACE_DIR * t.sin();
        let whorl = scalp
            .vertices
            .iter()
            .copied()
            .max_by(|a, b| (*a - centre).dot(dir).total_cmp(&(*b - centre).dot(dir)))
            .unwrap_or(centre);
        let extent = (hi - lo).max_element();
        Self {
            whorl,
            ramp: (RAMP_FRACTION * extent).max(1e-6),
            max_tilt: MAX_TILT_DEG.to_radians(),
            down_weight: DOWN_WEIGHT,
            swirl: SWIRL_DEG.to_radians(),
        }
    }

    /// S at the scalp point `p` with unit outward normal `n`: a unit vector with `S·n ≥ cos(max_tilt)`.
    pub fn direction(&self, p: Vec3, n: Vec3) -> Vec3 {
        let d = p - self.whorl;
        let dist = d.length();
        let w = smoothstep(dist / self.ramp);
        let tangential = |v: Vec3| v - n * n.dot(v);
        let away = tangential(d).normalize_or_zero();
        let down = tangential(-WORLD_UP);
        let mut t = (away + self.down_weight * down).normalize_or_zero();
        // Swirl: rotate about the normal, clockwise seen from above (negative about +n on top).
        let psi = -self.swirl * (1.0 - w);
        if psi != 0.0 && t != Vec3::ZERO {
            t = (t * psi.cos() + n.cross(t) * psi.sin()).normalize_or_zero();
        }
        let theta = self.max_tilt * w;
        if t == Vec3::ZERO {
            return n;
        }
        (n * theta.cos() + t * theta.sin()).normalize_or_zero()
    }
}

#[inline]
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Partings: bare skin inside the scalp (found where the cameras see the scalp's skin, see
/// `hairrecon_recon::parting`), which turns S beside it.
///
/// Hair beside a parting leaves it sideways: within `reach` of the skin, the tangential part of S is
/// turned toward *away from the skin* (the tangent-plane part of `Σ w(|p − q|) (p − q)/|p − q|`
/// over the skin points q, `w(d) = (1 − d/reach)²`, so along a strip of skin the pushes along it
/// cancel and those across it remain), by `strength × β` against S's own tangential direction,
/// and S's tilt from the normal grows toward [`MAX_TILT_DEG`] by `β`, where
/// `β = smoothstep(1 − d_min/reach) · |Σ w u| / Σ w` with `d_min` the distance to the nearest skin
/// point (hair at a parting lies flat); the second factor is 1 beside the skin and falls to 0 amid
/// it, where the pushes cancel and S stays as it was.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Partings {
    skin: Vec<Vec3>,
    reach: f32,
    strength: f32,
    /// Skin points by grid cell of size `reach` ([`sort_by_cell`]).
    cells: Vec<(Cell, usize, usize)>,
    order: Vec<u32>,
}

impl Partings {
    /// Skin points (on the scalp), how far from them S turns (metres, > 0) and how strongly (≥ 0).
    pub fn new(skin: Vec<Vec3>, reach: f32, strength: f32) -> Self {
        let reach = reach.max(1e-6);
        let (order, cells) = sort_by_cell(&skin, reach);
        Self { skin, reach, strength: strength.max(0.0), cells, order }
    }

    /// The skin points.
    pub fn skin(&self) -> &[Vec3] {
        &self.skin
    }

    pub fn reach(&self) -> f32 {
        self.reach
    }

    /// The skin points within `reach` of `p`.
    fn near(&self, p: Vec3) -> impl Iterator<Item = Vec3> + '_ {
        let (cx, cy, cz) = grid_cell(p, self.reach);
        let r2 = self.reach * self.reach;
        (-1..=1)
            .flat_map(move |dx| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dz| (cx + dx, cy + dy, cz + dz))))
            .filter_map(move |key| {
                self.cells.binary_search_by(|c| c.0.cmp(&key)).ok().map(|k| (self.cells[k].1, self.cells[k].2))
            })
            .flat_map(move |(s, e)| self.order[s..e].iter().map(move |&i| self.skin[i as usize]))
            .filter(move |q| q.distance_squared(p) < r2)
    }

    /// The distance from `p` to the nearest skin point, if one lies within `reach`.
    pub fn distance(&self, p: Vec3) -> Option<f32> {
        self.near(p).map(|q| q.distance(p)).min_by(f32::total_cmp)
    }

    /// S at the scalp point `p` (unit outward normal `n`), turned away from the skin (see the type).
    pub fn turn(&self, p: Vec3, n: Vec3, s: Vec3) -> Vec3 {
        let mut push = Vec3::ZERO;
        let mut total = 0.0;
        let mut d_min = f32::INFINITY;
        for q in self.near(p) {
            let d = p - q;
            let r = d.length();
            d_min = d_min.min(r);
            if r > 1e-6 {
                let w = 1.0 - r / self.reach;
                push += d * (w * w / r);
                total += w * w;
            }
        }
        let tangential = |v: Vec3| v - n * n.dot(v);
        let push = tangential(push);
        let away = push.normalize_or_zero();
        if away == Vec3::ZERO {
            return s;
        }
        // 1 with all the skin on one side, 0 amid it.
        let one_sided = (push.length() / total).min(1.0);
        let beta = smoothstep(1.0 - d_min / self.reach) * one_sided;
        let t_s = tangential(s).normalize_or(away);
        let t = (t_s + away * (self.strength * beta)).normalize_or(away);
        let theta = s.dot(n).clamp(-1.0, 1.0).acos();
        let max_tilt = MAX_TILT_DEG.to_radians();
        let theta = theta + (max_tilt - theta).max(0.0) * beta;
        (n * theta.cos() + t * theta.sin()).normalize_or(s)
    }
}

/// A scalp mesh made ready for queries: outward normals, the growth field, area sampling and a BVH.
#[derive(Debug, Clone)]
pub struct Scalp {
    bvh: Bvh,
    normals: Vec<Vec3>,
    field: GrowthField,
    /// Partings found on it, if any: they turn S beside them ([`Partings`]).
    partings: Option<Partings>,
    /// Cumulative triangle areas (f64 for 10^5+ triangles), last = total area.
    cdf: Vec<f64>,
}

impl Scalp {
    /// Prepares a scalp mesh. Vertex normals are taken from the mesh when it has them (zero ones are
    /// replaced by computed ones), else computed from the faces; either way they are flipped if they
    /// point into the dome rather than out of it.
    pub fn new(mesh: TriMesh) -> Result<Self, ScalpError> {
        let mut cdf = Vec::with_capacity(mesh.triangles.len());
        let mut acc = 0.0f64;
        for i in 0..mesh.triangles.len() {
            acc += mesh.face_area(i) as f64;
            cdf.push(acc);
        }
        if acc <= 0.0 || !acc.is_finite() {
            return Err(ScalpError::ZeroArea);
        }
        let computed = mesh.compute_vertex_normals();
        let mut normals: Vec<Vec3> = match &mesh.normals {
            Some(n) => n
                .iter()
                .zip(&computed)
                .map(|(&a, &b)| if a.length_squared() > 1e-12 { a.normalize() } else { b })
                .collect(),
            None => computed,
        };
        // Orientation: area-weighted agreement of the normals with "away from the mean point".
        let mean = mesh.vertices.iter().copied().sum::<Vec3>() / mesh.vertices.len().max(1) as f32;
        let mut score = 0.0f64;
        for (i, t) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = mesh.corners(i);
            let nrm = normals[t[0] as usize] + normals[t[1] as usize] + normals[t[2] as usize];
            score += (mesh.face_area(i) * nrm.dot((a + b + c) / 3.0 - mean)) as f64;
        }
        if score < 0.0 {
            normals.iter_mut().for_each(|n| *n = -*n);
        }
        let field = GrowthField::from_mesh(&mesh);
        Ok(Self { bvh: Bvh::new(mesh), normals, field, partings: None, cdf })
    }

    pub fn mesh(&self) -> &TriMesh {
        self.bvh.mesh()
    }

    /// A BVH over the scalp mesh.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    pub fn field(&self) -> &GrowthField {
        &self.field
    }

    /// Replaces the growth field (for example to move the whorl).
    pub fn set_field(&mut self, field: GrowthField) {
        self.field = field;
    }

    /// Sets (or with `None` clears) the partings that turn S beside them.
    pub fn set_partings(&mut self, partings: Option<Partings>) {
        self.partings = partings.filter(|p| !p.skin.is_empty());
    }

    pub fn partings(&self) -> Option<&Partings> {
        self.partings.as_ref()
    }

    /// S at the scalp point `p` with unit outward normal `n`: the growth field, turned beside partings.
    pub fn direction(&self, p: Vec3, n: Vec3) -> Vec3 {
        let s = self.field.direction(p, n);
        match &self.partings {
            Some(parts) => parts.turn(p, n, s),
            None => s,
        }
    }

    /// Total area, m².
    pub fn area(&self) -> f32 {
        self.cdf.last().copied().unwrap_or(0.0) as f32
    }

    /// Outward unit vertex normals.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// The root at barycentric `bary` of `triangle`: position, normal, S and UV.
    pub fn root_at(&self, triangle: u32, bary: Vec3) -> Root {
        let mesh = self.mesh();
        let t = mesh.triangles[triangle as usize];
        let position = self.bvh.interpolate(&mesh.vertices, triangle, bary);
        let mut normal = self.bvh.interpolate(&self.normals, triangle, bary).normalize_or_zero();
        if normal == Vec3::ZERO {
            let f = mesh.face_normal(triangle as usize);
            let s = self.normals[t[0] as usize] + self.normals[t[1] as usize] + self.normals[t[2] as usize];
            normal = if f.dot(s) < 0.0 { -f } else { f };
        }
        let uv = mesh.uvs.as_ref().map(|uv| self.bvh.interpolate(uv, triangle, bary));
        Root { position, normal, direction: self.direction(position, normal), triangle, bary, uv }
    }

    /// The root at the scalp point closest to `p` (e.g. to read S near an arbitrary point).
    pub fn closest_root(&self, p: Vec3) -> Root {
        match self.bvh.closest_point(p, f32::INFINITY) {
            Some(cp) => self.root_at(cp.triangle, cp.bary),
            None => self.root_at(0, Vec3::splat(1.0 / 3.0)),
        }
    }

    /// The largest Poisson-disk radius `r_max = sqrt(A / (2√3 n))` for `n` samples on this scalp
    /// (Yuksel 2015, §3.2): hexagonal packing, where neighbours are `2 r_max` apart.
    pub fn poisson_radius(&self, n: usize) -> f32 {
        (self.area() / (2.0 * 3f32.sqrt() * n.max(1) as f32)).sqrt()
    }

    /// `n` roots in blue noise (Poisson-disk sample elimination), deterministic for a given `seed`.
    /// The roots come in a random order (that of their candidates), so any prefix is spread over
    /// the whole scalp.
    pub fn sample_roots(&self, n: usize, seed: u64) -> Result<Vec<Root>, ScalpError> {
        if n == 0 {
            return Err(ScalpError::NoRoots);
        }
        if n > 1 << 28 {
            return Err(ScalpError::TooManyRoots(n));
        }
        let m = n * CANDIDATE_FACTOR;
        let total = *self.cdf.last().unwrap_or(&0.0);
        let candidates: Vec<(u32, Vec3)> = (0..m as u64)
            .map(|k| {
                let u = unit_f64(seed, k, 0) * total;
                let tri = self.cdf.partition_point(|&c| c <= u).min(self.cdf.len() - 1);
                let (r1, r2) = (unit_f32(seed, k, 1), unit_f32(seed, k, 2));
                let s = r1.sqrt();
                (tri as u32, Vec3::new(1.0 - s, s * (1.0 - r2), s * r2))
            })
            .collect();
        let positions: Vec<Vec3> =
            candidates.iter().map(|&(t, b)| self.bvh.interpolate(&self.mesh().vertices, t, b)).collect();
        let keep = eliminate(&positions, n, self.poisson_radius(n));
        Ok(keep.into_iter().map(|i| self.root_at(candidates[i].0, candidates[i].1)).collect())
    }
}

/// `n` roots in blue noise on `scalp` with their growth directions (see [`Scalp::sample_roots`]).
pub fn sample_roots(scalp: &TriMesh, n: usize, seed: u64) -> Result<Vec<Root>, ScalpError> {
    Scalp::new(scalp.clone())?.sample_roots(n, seed)
}

/// Yuksel's weighted sample elimination: keeps `n` of `points`, returned as sorted indices.
fn eliminate(points: &[Vec3], n: usize, r_max: f32) -> Vec<usize> {
    let m = points.len();
    if n >= m {
        return (0..m).collect();
    }
    // Weight limiting (Yuksel 2015, §3.3): gamma = 1.5, beta = 0.65.
    let r_min = r_max * (1.0 - (n as f32 / m as f32).powf(1.5)) * 0.65;
    let two_rmax = 2.0 * r_max;
    let weight = |d: f32| {
        let dh = if d > 2.0 * r_min { d.min(two_rmax) } else { 2.0 * r_min };
        (1.0 - dh / two_rmax).powi(8)
    };
    let neighbours = neighbour_lists(points, two_rmax);
    let mut w = vec![0.0f32; m];
    for i in 0..m {
        for &(_, d) in neighbours.of(i) {
            w[i] += weight(d);
        }
    }
    let mut heap = IndexedMaxHeap::new(w);
    let mut alive = vec![true; m];
    let mut left = m;
    while left > n {
        let Some(i) = heap.pop() else { break };
        alive[i] = false;
        left -= 1;
        for &(j, d) in neighbours.of(i) {
            if alive[j as usize] {
                heap.decrease(j as usize, weight(d));
            }
        }
    }
    (0..m).filter(|&i| alive[i]).collect()
}

/// Neighbours within a radius, stored compressed (CSR): `(index, distance)`.
struct Neighbours {
    start: Vec<usize>,
    items: Vec<(u32, f32)>,
}

impl Neighbours {
    fn of(&self, i: usize) -> &[(u32, f32)] {
        &self.items[self.start[i]..self.start[i + 1]]
    }
}

/// A cell of a uniform grid.
type Cell = (i32, i32, i32);

/// The cell of the grid of cell size `size` that holds `p`.
fn grid_cell(p: Vec3, size: f32) -> Cell {
    let c = (p / size).floor();
    (c.x as i32, c.y as i32, c.z as i32)
}

/// `points` sorted by their cell of a grid of cell size `size`: their indices in that order, and
/// each occupied cell with the range of the order it holds, sorted by cell.
fn sort_by_cell(points: &[Vec3], size: f32) -> (Vec<u32>, Vec<(Cell, usize, usize)>) {
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    order.sort_by_key(|&i| (grid_cell(points[i as usize], size), i));
    let mut cells = Vec::new();
    let mut s = 0;
    while s < order.len() {
        let key = grid_cell(points[order[s] as usize], size);
        let mut e = s + 1;
        while e < order.len() && grid_cell(points[order[e] as usize], size) == key {
            e += 1;
        }
        cells.push((key, s, e));
        s = e;
    }
    (order, cells)
}

/// All pairs closer than `r`, by a uniform grid of cell size `r` (points sorted by cell).
fn neighbour_lists(points: &[Vec3], r: f32) -> Neighbours {
    let cell = |p: Vec3| grid_cell(p, r);
    let (order, runs) = sort_by_cell(points, r);
    let cells: std::collections::HashMap<Cell, (usize, usize)> =
        runs.into_iter().map(|(k, s, e)| (k, (s, e))).collect();
    let r2 = r * r;
    let mut start = Vec::with_capacity(points.len() + 1);
    let mut items = Vec::new();
    start.push(0);
    for (i, &p) in points.iter().enumerate() {
        let (cx, cy, cz) = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(&(a, b)) = cells.get(&(cx + dx, cy + dy, cz + dz)) {
                        for &j in &order[a..b] {
                            let d2 = points[j as usize].distance_squared(p);
                            if j as usize != i && d2 < r2 {
                                items.push((j, d2.sqrt()));
                            }
                        }
                    }
                }
            }
        }
        start.push(items.len());
    }
    Neighbours { start, items }
}

/// A binary max-heap over indices `0..n` keyed by `f32` weights that can decrease. Ties break by
/// the larger index, so the result does not depend on anything but the input.
struct IndexedMaxHeap {
    key: Vec<f32>,
    heap: Vec<u32>,
    pos: Vec<usize>,
}

impl IndexedMaxHeap {
    fn new(key: Vec<f32>) -> Self {
        let n = key.len();
        let mut h = Self { key, heap: (0..n as u32).collect(), pos: (0..n).collect() };
        for i in (0..n / 2).rev() {
            h.sift_down(i);
        }
        h
    }

    #[inline]
    fn above(&self, a: u32, b: u32) -> bool {
        let (ka, kb) = (self.key[a as usize], self.key[b as usize]);
        ka > kb || (ka == kb && a > b)
    }

    fn swap(&mut self, i: usize, j: usize) {
        self.heap.swap(i, j);
        self.pos[self.heap[i] as usize] = i;
        self.pos[self.heap[j] as usize] = j;
    }

    fn sift_down(&mut self, mut i: usize) {
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut best = i;
            if l < self.heap.len() && self.above(self.heap[l], self.heap[best]) {
                best = l;
            }
            if r < self.heap.len() && self.above(self.heap[r], self.heap[best]) {
                best = r;
            }
            if best == i {
                return;
            }
            self.swap(i, best);
            i = best;
        }
    }

    fn pop(&mut self) -> Option<usize> {
        let top = *self.heap.first()?;
        let last = self.heap.len() - 1;
        self.swap(0, last);
        self.heap.pop();
        self.pos[top as usize] = usize::MAX;
        if !self.heap.is_empty() {
            self.sift_down(0);
        }
        Some(top as usize)
    }

    /// Lowers the key of `i` by `by` (a removed index is ignored).
    fn decrease(&mut self, i: usize, by: f32) {
        let p = self.pos[i];
        if p == usize::MAX {
            return;
        }
        self.key[i] -= by;
        self.sift_down(p);
    }
}

/// SplitMix64 finaliser (Steele, Lea & Flood 2014).
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A hash of (seed, index, stream): the counter-based random source of this module.
#[inline]
fn hash3(seed: u64, k: u64, stream: u64) -> u64 {
    splitmix64(splitmix64(seed ^ 0x5CA1_9000_0000_0000) ^ k.wrapping_mul(4).wrapping_add(stream))
}

/// Uniform in [0, 1) with 24 bits.
#[inline]
fn unit_f32(seed: u64, k: u64, stream: u64) -> f32 {
    (hash3(seed, k, stream) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Uniform in [0, 1) with 53 bits.
#[inline]
fn unit_f64(seed: u64, k: u64, stream: u64) -> f64 {
    (hash3(seed, k, stream) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of radius `r` centred at the origin, keeping only the part with z ≥ `z_min`
    /// (a dome like a scalp), outward normals, CCW seen from outside.
    fn dome(r: f32, z_min: f32, rings: usize, segs: usize) -> TriMesh {
        let mut v = Vec::new();
        let mut nrm = Vec::new();
        for i in 0..=rings {
            let th = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segs {
                let ph = std::f32::consts::TAU * j as f32 / segs as f32;
                let n = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                v.push(n * r);
                nrm.push(n);
            }
        }
        let mut t = Vec::new();
        for i in 0..rings {
            for j in 0..segs {
                let a = (i * segs + j) as u32;
                let b = (i * segs + (j + 1) % segs) as u32;
                let c = a + segs as u32;
                let d = b + segs as u32;
                for tri in [[a, c, d], [a, d, b]] {
                    let m = (v[tri[0] as usize] + v[tri[1] as usize] + v[tri[2] as usize]) / 3.0;
                    let area = (v[tri[1] as usize] - v[tri[0] as usize])
                        .cross(v[tri[2] as usize] - v[tri[0] as usize])
                        .length();
                    if m.z >= z_min && area > 0.0 {
                        t.push(tri);
                    }
                }
            }
        }
        TriMesh::new(v, t, Some(nrm), None).unwrap()
    }

    #[test]
    fn a_parting_turns_s_away_from_it_on_both_sides_and_nowhere_else() {
        let mut scalp = Scalp::new(dome(0.08, -0.02, 48, 96)).unwrap();
        // A strip of skin along y over the top (x = 0, y from -4 to +4 cm), one point per mm.
        let skin: Vec<Vec3> = (-40..=40)
            .map(|k| {
                let y = k as f32 * 0.001;
                Vec3::new(0.0, y, (0.08f32 * 0.08 - y * y).sqrt())
            })
            .collect();
        let at = |scalp: &Scalp, x: f32, y: f32| {
            let p = Vec3::new(x, y, (0.08f32 * 0.08 - x * x - y * y).sqrt());
            let n = p.normalize();
            (scalp.direction(p, n), n)
        };
        let before: Vec<(Vec3, Vec3)> = [0.008, -0.008, 0.0, 0.06].iter().map(|&x| at(&scalp, x, -0.01)).collect();
        scalp.set_partings(Some(Partings::new(skin, 0.03, 2.0)));
        let after: Vec<(Vec3, Vec3)> = [0.008, -0.008, 0.0, 0.06].iter().map(|&x| at(&scalp, x, -0.01)).collect();
        // Without the parting S leaves the front of the top forward (−y), hardly sideways.
        assert!(before[0].0.x.abs() < 0.2 && before[0].0.y < -0.3, "{:?}", before[0].0);
        // Beside it, S leaves sideways, away from it, and lies flatter; still out of the skin.
        for (k, sign) in [(0usize, 1.0f32), (1, -1.0)] {
            let (s, n) = after[k];
            assert!(s.x * sign > 0.5, "side {sign}: {s:?}");
            assert!(s.dot(n) < before[k].0.dot(n) && s.dot(n) > 0.45, "tilt {s:?} before {:?}", before[k].0);
            assert!((s.length() - 1.0).abs() < 1e-5);
        }
        // On its middle line the pushes cancel: S as it was; beyond its reach, S as it was.
        assert!(after[2].0.distance(before[2].0) < 0.05, "{:?} vs {:?}", after[2].0, before[2].0);
        assert_eq!(after[3].0, before[3].0);
        // Roots read S through the same turn.
        let cp = scalp.bvh().closest_point(Vec3::new(0.008, -0.01, 0.079), 0.01).unwrap();
        assert!(scalp.root_at(cp.triangle, cp.bary).direction.x > 0.5);
        assert!(scalp.partings().unwrap().distance(Vec3::new(0.008, -0.01, 0.0795)).unwrap() < 0.0085);
        // No skin, no partings.
        scalp.set_partings(Some(Partings::new(Vec::new(), 0.03, 2.0)));
        assert!(scalp.partings().is_none());
    }

    #[test]
    fn whorl_is_top_back_and_s_tilts_the_right_way() {
        let scalp = Scalp::new(dome(0.08, -0.02, 48, 96)).unwrap();
        let f = *scalp.field();
        // The whorl sits on the upper back: z high, y > 0 (the back, since the face looks at -Y).
        assert!(f.whorl.z > 0.06 && f.whorl.y > 0.01, "whorl {:?}", f.whorl);
        let at = |p: Vec3| {
            let n = p.normalize();
            (n, f.direction(p * 0.08, n))
        };
        // At the whorl S is the normal.
        let (n, s) = at(f.whorl / 0.08);
        assert!(s.dot(n) > 0.999, "{s:?}");
        // Sides (ears are at ±X) and back (+Y): S points down, still out of the skin.
        for p in [Vec3::new(1.0, 0.1, 0.15), Vec3::new(-1.0, 0.1, 0.15), Vec3::new(0.0, 1.0, 0.1)] {
            let (n, s) = at(p.normalize());
            assert!(s.z < -0.3, "S at {p:?} = {s:?}");
            assert!((s.dot(n) - MAX_TILT_DEG.to_radians().cos()).abs() < 0.02, "{p:?}: S·n = {}", s.dot(n));
        }
        // Front hairline: S points forward (−Y).
        let (_, s) = at(Vec3::new(0.0, -1.0, 0.6).normalize());
        assert!(s.y < -0.3, "front S = {s:?}");
        // Everywhere: unit length and a positive normal component.
        for r in scalp.sample_roots(500, 3).unwrap() {
            assert!((r.direction.length() - 1.0).abs() < 1e-4);
            assert!(r.direction.dot(r.normal) >= 0.49, "{r:?}");
        }
    }

    #[test]
    fn roots_are_blue_noise_on_the_scalp_and_deterministic() {
        let mesh = dome(0.08, -0.02, 48, 96);
        let scalp = Scalp::new(mesh.clone()).unwrap();
        let n = 2000;
        let roots = scalp.sample_roots(n, 42).unwrap();
        assert_eq!(roots.len(), n);
        assert_eq!(roots, sample_roots(&mesh, n, 42).unwrap());
        assert_ne!(roots, scalp.sample_roots(n, 43).unwrap());
        let bvh = Bvh::new(mesh);
        for r in &roots {
            let d = bvh.closest_point(r.position, f32::INFINITY).unwrap().distance;
            assert!(d < 1e-6, "root off the scalp by {d}");
            assert!(r.normal.dot(r.position.normalize()) > 0.99, "normal not outward: {r:?}");
            assert!((r.bary.element_sum() - 1.0).abs() < 1e-5 && r.bary.min_element() >= 0.0);
        }
        let nearest = |pts: &[Vec3]| -> Vec<f32> {
            (0..pts.len())
                .map(|i| {
                    (0..pts.len()).filter(|&j| j != i).map(|j| pts[i].distance(pts[j])).fold(f32::INFINITY, f32::min)
                })
                .collect()
        };
        // Hexagonal packing of n points puts neighbours 2 r_max apart: the ideal spacing.
        let spacing = 2.0 * scalp.poisson_radius(n);
        let pos: Vec<Vec3> = roots.iter().map(|r| r.position).collect();
        let nn = nearest(&pos);
        let min = nn.iter().copied().fold(f32::INFINITY, f32::min) / spacing;
        let mean = nn.iter().sum::<f32>() / n as f32 / spacing;
        // Plain area-weighted random samples for comparison (the first n candidates).
        let white: Vec<Vec3> = (0..n as u64)
            .map(|k| {
                let u = unit_f64(42, k, 0) * *scalp.cdf.last().unwrap();
                let t = scalp.cdf.partition_point(|&c| c <= u).min(scalp.cdf.len() - 1);
                let s = unit_f32(42, k, 1).sqrt();
                let r2 = unit_f32(42, k, 2);
                scalp.root_at(t as u32, Vec3::new(1.0 - s, s * (1.0 - r2), s * r2)).position
            })
            .collect();
        let wmin = nearest(&white).into_iter().fold(f32::INFINITY, f32::min) / spacing;
        // Measured: min 0.694, mean 0.792 of the ideal spacing; white noise: min 0.0045.
        println!("ideal spacing {spacing:.5} m; blue noise: min {min:.3}, mean {mean:.3}; white: min {wmin:.4}");
        assert!(min > 0.6, "closest pair at {min} of the ideal spacing");
        assert!(mean > 0.7 && mean < 1.0, "mean nearest distance {mean} of the ideal spacing");
        assert!(wmin < 0.1);
    }

    #[test]
    fn inward_normals_are_flipped_and_errors_are_typed() {
        let mut m = dome(1.0, 0.0, 12, 24);
        m.normals = m.normals.map(|n| n.into_iter().map(|v| -v).collect());
        let s = Scalp::new(m).unwrap();
        let r = s.closest_root(Vec3::new(0.0, 0.0, 2.0));
        assert!(r.normal.z > 0.99 && r.position.z > 0.95, "{r:?}");
        assert_eq!(s.sample_roots(0, 1), Err(ScalpError::NoRoots));
        let flat = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]], None, None).unwrap();
        assert_eq!(Scalp::new(flat).err(), Some(ScalpError::ZeroArea));
    }
}
