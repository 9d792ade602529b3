//! The head template as the fit uses it: seeded, area-weighted sample points of its skin (the head
//! without the scalp, which hair hides on a capture), and the whole head's surface centre and
//! radius of gyration (the scale prior of the coarse search).

use glam::DVec3;
use hairrecon_core::TriMesh;

/// Area-weighted surface statistics of a mesh: its centre and radius of gyration (the RMS
/// distance of the surface from its centre), exact for flat triangles however large.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceStats {
    pub centre: DVec3,
    pub radius: f64,
    pub area: f64,
}

impl SurfaceStats {
    /// The statistics of a mesh's surface. `None` if its area is zero.
    pub fn of(mesh: &TriMesh) -> Option<Self> {
        let tri = |i: usize| mesh.corners(i).map(|c| c.as_dvec3());
        let mut area = 0.0;
        let mut first = DVec3::ZERO;
        for i in 0..mesh.triangles.len() {
            let [a, b, c] = tri(i);
            let w = 0.5 * (b - a).cross(c - a).length();
            area += w;
            first += w * (a + b + c) / 3.0;
        }
        if area.is_nan() || area <= 0.0 {
            return None;
        }
        let centre = first / area;
        let mut second = 0.0;
        for i in 0..mesh.triangles.len() {
            let [a, b, c] = tri(i);
            let w = 0.5 * (b - a).cross(c - a).length();
            let g = (a + b + c) / 3.0;
            // E|x − μ|² over a triangle = |g − μ|² + (1/12) Σ |vᵢ − g|².
            let spread = ((a - g).length_squared() + (b - g).length_squared() + (c - g).length_squared()) / 12.0;
            second += w * ((g - centre).length_squared() + spread);
        }
        let radius = (second / area).sqrt();
        (radius > 0.0 && radius.is_finite()).then_some(Self { centre, radius, area })
    }
}

/// A small seeded generator (SplitMix64) for the samples.
#[derive(Debug, Clone)]
pub(crate) struct Rng(u64);

impl Rng {
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub(crate) fn f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let z = hairrecon_core::scalp::splitmix64(self.0);
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` points on the triangles `keep` admits, area-weighted, in random order (any prefix is itself
/// a uniform sample).
pub(crate) fn sample_surface(mesh: &TriMesh, keep: impl Fn(usize) -> bool, n: usize, seed: u64) -> Vec<DVec3> {
    sample_surface_normals(mesh, keep, n, seed).into_iter().map(|(p, _)| p).collect()
}

/// As [`sample_surface`], with each point's triangle normal.
pub(crate) fn sample_surface_normals(
    mesh: &TriMesh,
    keep: impl Fn(usize) -> bool,
    n: usize,
    seed: u64,
) -> Vec<(DVec3, DVec3)> {
    let mut cdf = Vec::with_capacity(mesh.triangles.len());
    let mut ids = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for i in 0..mesh.triangles.len() {
        if keep(i) {
            total += mesh.face_area(i) as f64;
            cdf.push(total);
            ids.push(i);
        }
    }
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let x = rng.f64() * total;
            let k = cdf.partition_point(|&c| c < x).min(ids.len() - 1);
            let [a, b, c] = mesh.corners(ids[k]).map(|v| v.as_dvec3());
            let (mut u, mut v) = (rng.f64(), rng.f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            (a + u * (b - a) + v * (c - a), mesh.face_normal(ids[k]).as_dvec3())
        })
        .collect()
}

/// Per triangle of `head`, whether it belongs to `scalp`: its three corners are scalp vertices,
/// matched by position.
pub(crate) fn scalp_triangles(head: &TriMesh, scalp: &TriMesh) -> Vec<bool> {
    let key = |v: glam::Vec3| v.to_array().map(f32::to_bits);
    let scalp_vertices: std::collections::HashSet<[u32; 3]> = scalp.vertices.iter().map(|&v| key(v)).collect();
    (0..head.triangles.len()).map(|i| head.corners(i).iter().all(|&v| scalp_vertices.contains(&key(v)))).collect()
}

/// The template of [`super::fit_similarity`].
#[derive(Debug, Clone)]
pub struct HeadTemplate {
    /// Skin points in the canonical frame (metres), area-weighted, in random order.
    pub(crate) points: Vec<DVec3>,
    /// Their outward unit normals.
    pub(crate) normals: Vec<DVec3>,
    /// The whole head's surface statistics (scale and centre prior).
    pub(crate) stats: SurfaceStats,
    /// As many points again on the face alone ([`FACE_FACING`], [`FACE_LOWEST`]), with their
    /// outward unit normals.
    pub(crate) face_points: Vec<DVec3>,
    pub(crate) face_normals: Vec<DVec3>,
}

/// A template triangle is on the face when its outward normal turns at least this far toward the
/// front (its cosine with −Y, the canonical frame's facing direction)...
pub const FACE_FACING: f64 = 0.5;

/// ...and its centroid lies above the chin: higher than this many radii of gyration under the head's centre
/// (on the bundled head, 8 cm under its centre, about the jaw line; the front of the neck below is
/// what a collar covers).
pub const FACE_LOWEST: f64 = 0.7;

impl HeadTemplate {
    /// `samples` seeded points of `head` (canonical frame, metres) without the triangles of `scalp`
    /// (triangles whose three corners are scalp vertices, matched by position): the skin regions
    /// (face, ears, neck) that a capture shows. Without a scalp, the whole head. `None` if the head
    /// has no area.
    pub fn new(head: &TriMesh, scalp: Option<&TriMesh>, samples: usize, seed: u64) -> Option<Self> {
        let stats = SurfaceStats::of(head)?;
        let on_scalp = scalp.map(|s| scalp_triangles(head, s)).unwrap_or_default();
        let is_skin = |i: usize| !on_scalp.get(i).copied().unwrap_or(false);
        let (points, normals): (Vec<DVec3>, Vec<DVec3>) =
            sample_surface_normals(head, is_skin, samples.max(16), seed).into_iter().unzip();
        let chin = stats.centre.z - FACE_LOWEST * stats.radius;
        let on_face = |i: usize| {
            let centroid = head.corners(i).iter().map(|c| c.as_dvec3()).sum::<DVec3>() / 3.0;
            is_skin(i) && head.face_normal(i).as_dvec3().dot(DVec3::NEG_Y) >= FACE_FACING && centroid.z > chin
        };
        let (face_points, face_normals) =
            sample_surface_normals(head, on_face, samples.max(16), seed ^ 0xface).into_iter().unzip();
        let t = Self { points, normals, stats, face_points, face_normals };
        (!t.points.is_empty()).then_some(t)
    }

    /// The skin sample points (canonical frame, metres), in random order.
    pub fn points(&self) -> &[DVec3] {
        &self.points
    }

    /// Their outward unit normals.
    pub fn normals(&self) -> &[DVec3] {
        &self.normals
    }

    /// The number of sample points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no sample points (never, for a template that [`HeadTemplate::new`] made).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}
