//! Screen-space geometry of line segments, and the chain rule from screen back to 3D.
//!
//! In: 3D points (metres) with a [`Camera`], or 2D pixel positions directly, plus segments as pairs
//! of vertex indices. Out: a [`Screen`]: for each segment one convex primitive, the trapezoid with
//! corners `a ± n·hw_a`, `b ± n·hw_b` (`n` the unit normal of `b − a`, `hw` the half width in
//! pixels), or, for [`SegmentShape::Triangle`], the triangle with the root edge `a ± n·hw_a` and the
//! apex at `b` (Dr.Hair, Figure 5 of the main paper: a segment becomes a triangle). A segment is one
//! primitive with one id: a quad is never split into two triangles, so its diagonal can never be taken
//! for a separating edge (a weak spot named in `docs/method.md`).
//!
//! Backward: gradients with respect to the four corners of every primitive (from the anti-aliasing
//! ops) and to its screen direction `b − a` (from the orientation attribute) are mapped to per-vertex
//! pixel and half-width gradients ([`Screen::backward_vertices`]), then through the projection and
//! the depth-dependent width to 3D ([`Screen::backward_world`], using [`Camera::camera_jacobian`]).
//! Segments with a vertex behind the camera or shorter than 1e-6 px are dropped (no clipping).

use glam::{Vec2, Vec3};
use hairrecon_core::{Camera, StrandSet};

use crate::error::RasterError;

/// How wide a strand is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Width {
    /// A constant width in pixels.
    Pixels(f32),
    /// A width in world units (metres), drawn `w · f_y / z` pixels wide at camera depth `z`.
    World(f32),
}

/// The primitive a segment becomes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SegmentShape {
    /// A trapezoid: full width at both ends.
    #[default]
    Quad,
    /// A triangle: full width at the first vertex, zero at the second (the paper's conversion).
    Triangle,
}

/// Everything the projection needs besides the geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterSettings {
    pub width: Width,
    pub shape: SegmentShape,
    /// Also write the unit 3D direction of each segment (3 more attribute channels, no gradient).
    pub direction_3d: bool,
}

impl Default for RasterSettings {
    fn default() -> Self {
        Self { width: Width::Pixels(1.0), shape: SegmentShape::Quad, direction_3d: false }
    }
}

/// One segment's screen primitive. Kept small (44 bytes): the rasterizer streams millions of them
/// per view and DR's steps are bound by that traffic (64 more bytes per primitive made a DR step
/// 17% slower on the demo's capture, measured at commit b34ecd9), so the corners, the bounding
/// box and the orientation are derived on use, by the same arithmetic each time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Prim {
    /// First vertex (root side) in pixels.
    pub a: Vec2,
    /// Second vertex in pixels.
    pub b: Vec2,
    /// Unit normal, `perp(u) = (−u.y, u.x)` of the unit direction `u` of `b − a` (see [`Prim::u`]).
    pub n: Vec2,
    /// Length of `b − a` in pixels; 0 for an invalid primitive (see [`Prim::valid`]).
    pub len: f32,
    /// Half widths at `a` and at `b` (0 at `b` for triangles).
    pub hw0: f32,
    pub hw1: f32,
    /// Camera depths at `a` and `b`.
    pub z0: f32,
    pub z1: f32,
}

impl Prim {
    /// Unit direction of `b − a` (from the normal: `n = (−u.y, u.x)`, exactly).
    #[inline]
    pub fn u(&self) -> Vec2 {
        Vec2::new(self.n.y, -self.n.x)
    }

    /// Whether the segment is drawn: both ends in front of the camera and apart.
    #[inline]
    pub fn valid(&self) -> bool {
        self.len > 0.0
    }

    /// Corner `k` of `a + n·hw0`, `b + n·hw1`, `b − n·hw1`, `a − n·hw0`; edge `k` joins corner `k`
    /// and `k + 1`.
    #[inline]
    pub fn corner(&self, k: usize) -> Vec2 {
        match k & 3 {
            0 => self.a + self.n * self.hw0,
            1 => self.b + self.n * self.hw1,
            2 => self.b - self.n * self.hw1,
            _ => self.a - self.n * self.hw0,
        }
    }

    /// The four corners, see [`Prim::corner`].
    #[inline]
    pub fn corners(&self) -> [Vec2; 4] {
        [self.corner(0), self.corner(1), self.corner(2), self.corner(3)]
    }

    /// Pixel bounding box of the corners, `[xmin, ymin, xmax, ymax]`: the corners are
    /// `a ± n·hw0` and `b ± n·hw1`, so each end's extent is `|n|·hw` (the same numbers as the
    /// corners' own minimum and maximum).
    #[inline]
    pub fn bbox(&self) -> [f32; 4] {
        let (ea, eb) = (self.n.abs() * self.hw0.abs(), self.n.abs() * self.hw1.abs());
        let (lo, hi) = ((self.a - ea).min(self.b - eb), (self.a + ea).max(self.b + eb));
        [lo.x, lo.y, hi.x, hi.y]
    }

    /// `(cos 2θ, sin 2θ)` of the screen direction.
    #[inline]
    pub fn orient(&self) -> Vec2 {
        let u = self.u();
        Vec2::new(u.x * u.x - u.y * u.y, 2.0 * u.x * u.y)
    }

    /// Signed position of a point in the primitive's frame: `(t, s)` with `t` in `[0, 1]` along the axis.
    #[inline]
    pub fn local(&self, x: Vec2) -> (f32, f32) {
        let v = x - self.a;
        (v.dot(self.u()) / self.len, v.dot(self.n))
    }

    /// Whether a point is inside (boundary included).
    #[inline]
    pub fn contains(&self, x: Vec2) -> bool {
        let (t, s) = self.local(x);
        (0.0..=1.0).contains(&t) && s.abs() <= self.hw0 + (self.hw1 - self.hw0) * t
    }

    /// Depth at a point inside, interpolated linearly in screen space.
    #[inline]
    pub fn depth_at(&self, x: Vec2) -> f32 {
        let (t, _) = self.local(x);
        self.z0 + (self.z1 - self.z0) * t.clamp(0.0, 1.0)
    }

    /// Edge `k` as its two end corners; `None` for the zero-length tip edge of a triangle.
    #[inline]
    pub fn edge(&self, k: usize) -> Option<(Vec2, Vec2)> {
        let e0 = self.corner(k);
        let e1 = self.corner(k + 1);
        if (e1 - e0).length_squared() < 1e-12 {
            None
        } else {
            Some((e0, e1))
        }
    }

    /// The four edges, see [`Prim::edge`] (each corner computed once).
    #[inline]
    pub fn edges(&self) -> [Option<(Vec2, Vec2)>; 4] {
        let c = self.corners();
        std::array::from_fn(|k| {
            let (e0, e1) = (c[k], c[(k + 1) & 3]);
            if (e1 - e0).length_squared() < 1e-12 {
                None
            } else {
                Some((e0, e1))
            }
        })
    }

    fn build(a: Vec2, b: Vec2, hw0: f32, hw1: f32, z0: f32, z1: f32) -> Self {
        let d = b - a;
        let len = d.length();
        if len.is_nan() || len <= 1e-6 {
            return Prim::default();
        }
        let u = d / len;
        let n = Vec2::new(-u.y, u.x);
        Prim { a, b, n, len, hw0, hw1, z0, z1 }
    }
}

/// Per-segment gradients produced by the backward ops.
///
/// A view sees a small part of millions of segments (at most a few per pixel), so the gradients are
/// sparse: every write goes through [`SegmentGrads::add_corner`] or [`SegmentGrads::add_dir`], which
/// mark the segment, and [`SegmentGrads::reset`] and [`Screen::backward_vertices`] visit only the
/// marked segments, in their order, instead of all of them.
#[derive(Debug, Clone, Default)]
pub struct SegmentGrads {
    /// ∂L/∂corner for the four corners of each primitive.
    corners: Vec<[Vec2; 4]>,
    /// ∂L/∂(b − a), the screen direction (from the orientation attribute).
    dir: Vec<Vec2>,
    /// One bit per segment: written since the last reset.
    marks: Vec<u64>,
}

impl SegmentGrads {
    /// Zeroes the gradients for `n` segments, reusing the allocations (when the size is the same, only
    /// the segments written since the last reset are zeroed).
    pub fn reset(&mut self, n: usize) {
        if self.corners.len() == n && self.dir.len() == n && self.marks.len() == n.div_ceil(64) {
            for k in 0..self.marks.len() {
                for i in marked_in(k, self.marks[k]) {
                    self.corners[i] = [Vec2::ZERO; 4];
                    self.dir[i] = Vec2::ZERO;
                }
                self.marks[k] = 0;
            }
        } else {
            self.corners.clear();
            self.corners.resize(n, [Vec2::ZERO; 4]);
            self.dir.clear();
            self.dir.resize(n, Vec2::ZERO);
            self.marks.clear();
            self.marks.resize(n.div_ceil(64), 0);
        }
    }

    /// The number of segments the gradients are sized for.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// Whether the gradients are sized for no segment.
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// ∂L/∂corner of segment `i`'s four corners.
    pub fn corners(&self, i: usize) -> [Vec2; 4] {
        self.corners[i]
    }

    /// ∂L/∂(b − a) of segment `i`.
    pub fn dir(&self, i: usize) -> Vec2 {
        self.dir[i]
    }

    /// Adds `g` to corner `code & 3` of segment `code >> 2`.
    #[inline]
    pub fn add_corner(&mut self, code: u32, g: Vec2) {
        let s = code >> 2;
        self.corners[s as usize][(code & 3) as usize] += g;
        self.marks[(s >> 6) as usize] |= 1 << (s & 63);
    }

    /// Adds `g` to ∂L/∂(b − a) of segment `s`.
    #[inline]
    pub fn add_dir(&mut self, s: u32, g: Vec2) {
        self.dir[s as usize] += g;
        self.marks[(s >> 6) as usize] |= 1 << (s & 63);
    }

    /// The segments written since the last reset, ascending.
    fn marked(&self) -> impl Iterator<Item = usize> + '_ {
        self.marks.iter().enumerate().filter(|(_, &w)| w != 0).flat_map(|(k, &w)| marked_in(k, w))
    }
}

/// The segments whose bits are set in word `k` of a mark bitset, ascending.
fn marked_in(k: usize, mut word: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        if word == 0 {
            return None;
        }
        let bit = word.trailing_zeros() as usize;
        word &= word - 1;
        Some(64 * k + bit)
    })
}

/// Per-vertex screen gradients: ∂L/∂pixel position and ∂L/∂half width.
#[derive(Debug, Clone, Default)]
pub struct VertexGrads {
    pub pos: Vec<Vec2>,
    pub hw: Vec<f32>,
}

/// The screen-space primitives of one view.
#[derive(Debug, Clone, Default)]
pub struct Screen {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) pos: Vec<Vec2>,
    pub(crate) depth: Vec<f32>,
    pub(crate) hw: Vec<f32>,
    pub(crate) valid: Vec<bool>,
    pub(crate) segs: Vec<[u32; 2]>,
    pub(crate) prims: Vec<Prim>,
    /// Unit 3D direction of each segment, with `direction_3d` (else empty).
    pub(crate) dir3: Vec<Vec3>,
    pub(crate) settings: RasterSettings,
    /// `f_y`, for the depth-dependent world width.
    pub(crate) fy: f32,
}

/// The segments of a strand set: consecutive points of each strand, root first.
pub fn strand_segments(strands: &StrandSet) -> Vec<[u32; 2]> {
    let mut segs = Vec::with_capacity(strands.num_points().saturating_sub(strands.num_strands()));
    for w in strands.offsets().windows(2) {
        for i in w[0]..w[1] - 1 {
            segs.push([i as u32, i as u32 + 1]);
        }
    }
    segs
}

fn check_segments(segs: &[[u32; 2]], count: usize) -> Result<(), RasterError> {
    for (i, s) in segs.iter().enumerate() {
        for &v in s {
            if v as usize >= count {
                return Err(RasterError::BadSegment { segment: i, vertex: v, count });
            }
        }
    }
    Ok(())
}

fn check_width(w: Width) -> Result<f32, RasterError> {
    let v = match w {
        Width::Pixels(v) | Width::World(v) => v,
    };
    if !(v.is_finite() && v > 0.0) {
        return Err(RasterError::BadWidth(v));
    }
    Ok(v)
}

impl Screen {
    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn prims(&self) -> &[Prim] {
        &self.prims
    }
    pub fn segments(&self) -> &[[u32; 2]] {
        &self.segs
    }
    /// Pixel positions of the vertices.
    pub fn positions(&self) -> &[Vec2] {
        &self.pos
    }
    pub fn settings(&self) -> &RasterSettings {
        &self.settings
    }

    /// Screen geometry straight from pixel positions (depth 1 everywhere unless given), for 2D work
    /// such as the toy of supplement 3.1. `settings.width` must be [`Width::Pixels`].
    pub fn from_pixels(
        width: u32,
        height: u32,
        pos: &[Vec2],
        depth: Option<&[f32]>,
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<Self, RasterError> {
        let mut s = Screen::default();
        s.set_pixels(width, height, pos, depth, segs, settings)?;
        Ok(s)
    }

    /// Like [`Screen::from_pixels`], reusing this screen's allocations.
    pub fn set_pixels(
        &mut self,
        width: u32,
        height: u32,
        pos: &[Vec2],
        depth: Option<&[f32]>,
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<(), RasterError> {
        let w = check_width(settings.width)?;
        check_segments(segs, pos.len())?;
        if let Some(i) = pos.iter().position(|p| !p.is_finite()) {
            return Err(RasterError::NotFinite { index: i, value: [pos[i].x, pos[i].y, 0.0] });
        }
        self.width = width;
        self.height = height;
        self.settings = settings;
        self.fy = 1.0;
        self.pos.clear();
        self.pos.extend_from_slice(pos);
        self.depth.clear();
        match depth {
            Some(d) => self.depth.extend(d.iter().copied().take(pos.len())),
            None => self.depth.resize(pos.len(), 1.0),
        }
        self.depth.resize(pos.len(), 1.0);
        self.hw.clear();
        self.hw.resize(pos.len(), 0.5 * w);
        self.valid.clear();
        self.valid.resize(pos.len(), true);
        self.segs.clear();
        self.segs.extend_from_slice(segs);
        self.build_prims(None);
        Ok(())
    }

    /// Projects 3D points with a camera and builds the primitives of the given segments.
    pub fn project(
        camera: &Camera,
        points: &[Vec3],
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<Self, RasterError> {
        let mut s = Screen::default();
        s.set_projected(camera, points, segs, settings)?;
        Ok(s)
    }

    /// Like [`Screen::project`], reusing this screen's allocations.
    pub fn set_projected(
        &mut self,
        camera: &Camera,
        points: &[Vec3],
        segs: &[[u32; 2]],
        settings: RasterSettings,
    ) -> Result<(), RasterError> {
        use rayon::prelude::*;
        let w = check_width(settings.width)?;
        check_segments(segs, points.len())?;
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(RasterError::NotFinite { index: i, value: points[i].to_array() });
        }
        self.width = camera.width();
        self.height = camera.height();
        self.settings = settings;
        self.fy = camera.k().col(1).y;
        let n = points.len();
        self.pos.resize(n, Vec2::ZERO);
        self.depth.resize(n, 0.0);
        self.hw.resize(n, 0.0);
        self.valid.resize(n, false);
        let fy = self.fy;
        let hw_of = |z: f32| match settings.width {
            Width::Pixels(_) => 0.5 * w,
            Width::World(_) => 0.5 * w * fy / z,
        };
        self.pos
            .par_iter_mut()
            .zip(self.depth.par_iter_mut())
            .zip(self.hw.par_iter_mut())
            .zip(self.valid.par_iter_mut())
            .zip(points.par_iter())
            .for_each(|((((p, d), h), v), x)| {
                let pc = camera.to_camera(*x);
                if pc.z > 1e-6 {
                    *p = camera.camera_to_pixel(pc);
                    *d = pc.z;
                    *h = hw_of(pc.z);
                    *v = true;
                } else {
                    *v = false;
                }
            });
        self.segs.clear();
        self.segs.extend_from_slice(segs);
        self.build_prims(if settings.direction_3d { Some(points) } else { None });
        Ok(())
    }

    fn build_prims(&mut self, points: Option<&[Vec3]>) {
        use rayon::prelude::*;
        let shape = self.settings.shape;
        let (pos, depth, hw, valid) = (&self.pos, &self.depth, &self.hw, &self.valid);
        self.prims.resize(self.segs.len(), Prim::default());
        self.prims.par_iter_mut().zip(self.segs.par_iter()).with_min_len(1024).for_each(|(p, s)| {
            let (ia, ib) = (s[0] as usize, s[1] as usize);
            if !(valid[ia] && valid[ib]) {
                *p = Prim::default();
                return;
            }
            let hw1 = match shape {
                SegmentShape::Quad => hw[ib],
                SegmentShape::Triangle => 0.0,
            };
            *p = Prim::build(pos[ia], pos[ib], hw[ia], hw1, depth[ia], depth[ib]);
        });
        self.dir3.clear();
        if let Some(x) = points {
            self.dir3.par_extend(self.segs.par_iter().zip(self.prims.par_iter()).map(|(s, p)| {
                if p.valid() {
                    (x[s[1] as usize] - x[s[0] as usize]).normalize_or_zero()
                } else {
                    Vec3::ZERO
                }
            }));
        }
    }

    /// Maps per-segment gradients (corners, screen direction) to per-vertex pixel and half-width
    /// gradients. `out` is overwritten. Only the segments that received a gradient are visited, in
    /// their order (a segment without one would add zeros).
    pub fn backward_vertices(&self, g: &SegmentGrads, out: &mut VertexGrads) {
        out.pos.clear();
        out.pos.resize(self.pos.len(), Vec2::ZERO);
        out.hw.clear();
        out.hw.resize(self.pos.len(), 0.0);
        let tri = self.settings.shape == SegmentShape::Triangle;
        for i in g.marked() {
            let (Some(p), Some(s)) = (self.prims.get(i), self.segs.get(i)) else { break };
            if !p.valid() {
                continue;
            }
            let gc = g.corners[i];
            let gdir = g.dir[i];
            let mut ga = gc[0] + gc[3];
            let mut gb = gc[1] + gc[2];
            let g03 = gc[0] - gc[3];
            let g12 = gc[1] - gc[2];
            let gn = g03 * p.hw0 + g12 * p.hw1;
            // n = perp(u) = P u with P = [[0, −1], [1, 0]]: ∂L/∂u = Pᵀ ∂L/∂n.
            let gu = Vec2::new(gn.y, -gn.x);
            let u = p.u();
            let gd = (gu - u * u.dot(gu)) / p.len + gdir;
            ga -= gd;
            gb += gd;
            let (ia, ib) = (s[0] as usize, s[1] as usize);
            out.pos[ia] += ga;
            out.pos[ib] += gb;
            out.hw[ia] += p.n.dot(g03);
            if !tri {
                out.hw[ib] += p.n.dot(g12);
            }
        }
    }

    /// Maps per-vertex screen gradients to 3D: `∂L/∂X = Jᵀ ∂L/∂pixel + ∂L/∂hw · ∂hw/∂X` (the second
    /// term only for [`Width::World`]). Adds into `out` (one entry per point).
    pub fn backward_world(&self, camera: &Camera, points: &[Vec3], g: &VertexGrads, out: &mut [Vec3]) {
        use rayon::prelude::*;
        let world = matches!(self.settings.width, Width::World(_));
        let rz = camera.r().row(2);
        out.par_iter_mut().enumerate().with_min_len(4096).for_each(|(i, o)| {
            if !self.valid[i] {
                return;
            }
            let (gp, gh) = (g.pos[i], g.hw[i]);
            if gp == Vec2::ZERO && gh == 0.0 {
                return;
            }
            let pc = camera.to_camera(points[i]);
            let j = camera.camera_jacobian(pc);
            let mut v = j[0] * gp.x + j[1] * gp.y;
            if world {
                v += rz * (-gh * self.hw[i] / pc.z);
            }
            *o += v;
        });
    }
}

/// Distance from `q` to the line through `e0`, `e1`, and its gradient with respect to `e0` and `e1`.
#[inline]
pub(crate) fn line_distance(q: Vec2, e0: Vec2, e1: Vec2) -> (f32, Vec2, Vec2) {
    let d = e1 - e0;
    let v = q - e0;
    let l = d.length();
    let cr = d.x * v.y - d.y * v.x;
    let sg = if cr >= 0.0 { 1.0 } else { -1.0 };
    let r = cr.abs() / l;
    // ∂cr/∂v = (−d.y, d.x); ∂cr/∂d = (v.y, −v.x); ∂l/∂d = d / l.
    let dr_dv = Vec2::new(-d.y, d.x) * (sg / l);
    let dr_dd = Vec2::new(v.y, -v.x) * (sg / l) - d * (r / (l * l));
    (r, -dr_dd - dr_dv, dr_dd)
}

/// Distance from `q` to the segment `e0`–`e1` (to its nearer end beyond the ends), and its gradient
/// with respect to `e0` and `e1`.
#[inline]
pub(crate) fn segment_distance(q: Vec2, e0: Vec2, e1: Vec2) -> (f32, Vec2, Vec2) {
    let d = e1 - e0;
    let t = (q - e0).dot(d) / d.length_squared();
    if t <= 0.0 {
        let v = e0 - q;
        let r = v.length();
        (r, if r > 0.0 { v / r } else { Vec2::ZERO }, Vec2::ZERO)
    } else if t >= 1.0 {
        let v = e1 - q;
        let r = v.length();
        (r, Vec2::ZERO, if r > 0.0 { v / r } else { Vec2::ZERO })
    } else {
        line_distance(q, e0, e1)
    }
}

/// Where the segment `p0 → p1` crosses the segment `e0 → e1`: the parameter along `p0 → p1`.
#[inline]
pub(crate) fn crossing(p0: Vec2, p1: Vec2, e0: Vec2, e1: Vec2) -> Option<f32> {
    let r = p1 - p0;
    let s = e1 - e0;
    let den = r.perp_dot(s);
    if den.abs() < 1e-12 {
        return None;
    }
    let w = e0 - p0;
    let (nt, nu) = (w.perp_dot(s), w.perp_dot(r));
    // Most segments miss most edges: settle those without the two divisions, where the quotients
    // below would surely fall outside [0, 1] too (so the result is the same).
    if surely_outside_unit(nt, den) || surely_outside_unit(nu, den) {
        return None;
    }
    let t = nt / den;
    let u = nu / den;
    if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u) {
        Some(t)
    } else {
        None
    }
}

/// Whether the f32 quotient `num / den` (`|den| ≥ 1e-12`) surely lies outside `[0, 1]`: its magnitude
/// exceeds 1 by more than rounding, or its sign is negative and it is too large to round to −0.
/// `false` leaves the question to the division (NaN, zeros, and quotients near 0 or 1 go there).
#[inline]
fn surely_outside_unit(num: f32, den: f32) -> bool {
    let (a, d) = (num.abs(), den.abs());
    // a ≥ d·(1 + 2⁻²⁰) (the product rounded by at most 2⁻²⁴): the quotient rounds above 1 in magnitude.
    // Signs differ and a ≥ d·1e-30: the quotient is negative and far above the smallest normal f32.
    a >= d * (1.0 + 1.0 / 1_048_576.0) || ((num < 0.0) != (den < 0.0) && a >= d * 1e-30)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box from the ends' extents is the corners' own box, for segments in every direction
    /// and of unequal widths.
    #[test]
    fn the_bounding_box_is_the_corners_box() {
        for k in 0..64 {
            let t = k as f32 * 0.41;
            let a = Vec2::new(10.0 + t.cos() * 3.0, -2.0 + t.sin());
            let b = a + Vec2::new((t * 1.7).cos(), (t * 1.3).sin()) * (0.01 + k as f32 * 0.3);
            let p = Prim::build(a, b, 0.1 + 0.01 * k as f32, 0.7 - 0.01 * k as f32, 1.0, 2.0);
            let mut want = [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
            for c in p.corners() {
                want = [want[0].min(c.x), want[1].min(c.y), want[2].max(c.x), want[3].max(c.y)];
            }
            assert_eq!(p.bbox(), want, "segment {k}");
        }
    }

    #[test]
    fn line_distance_gradient_matches_finite_differences() {
        let q = Vec2::new(0.3, 0.7);
        let e0 = Vec2::new(-0.4, 0.1);
        let e1 = Vec2::new(1.2, -0.3);
        let (_, g0, g1) = line_distance(q, e0, e1);
        let h = 1e-3;
        for k in 0..2 {
            let mut dx = Vec2::ZERO;
            dx[k] = h;
            let f0 = (line_distance(q, e0 + dx, e1).0 - line_distance(q, e0 - dx, e1).0) / (2.0 * h);
            let f1 = (line_distance(q, e0, e1 + dx).0 - line_distance(q, e0, e1 - dx).0) / (2.0 * h);
            assert!((f0 - g0[k]).abs() < 1e-3, "{f0} {g0:?}");
            assert!((f1 - g1[k]).abs() < 1e-3, "{f1} {g1:?}");
        }
    }

    /// The shortcut of [`crossing`] rejects exactly what the divisions reject: compared with the
    /// quotients themselves on random segments, near-parallel ones, shared and touching ends, and
    /// quotients a rounding away from 0 and 1.
    #[test]
    fn crossing_shortcut_agrees_with_the_division() {
        let division = |p0: Vec2, p1: Vec2, e0: Vec2, e1: Vec2| {
            let (r, s) = (p1 - p0, e1 - e0);
            let den = r.perp_dot(s);
            if den.abs() < 1e-12 {
                return None;
            }
            let w = e0 - p0;
            let (t, u) = (w.perp_dot(s) / den, w.perp_dot(r) / den);
            ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
        };
        let mut seed = 17u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32
        };
        let (mut hits, mut cases) = (0, 0);
        for k in 0..400_000 {
            let p0 = Vec2::new((rnd() * 8.0).floor(), (rnd() * 8.0).floor());
            let p1 = p0 + Vec2::new((rnd() * 3.0).floor() - 1.0, (rnd() * 3.0).floor() - 1.0);
            let mut e0 = Vec2::new(rnd() * 8.0, rnd() * 8.0);
            let mut e1 = e0 + Vec2::new(rnd() - 0.5, rnd() - 0.5) * 6.0;
            match k % 5 {
                // Ends on the pixel segment, or a pixel centre on the edge.
                1 => e0 = p0.lerp(p1, rnd()),
                2 => e1 = p1,
                3 => e0 = p0 + (e1 - p0) * (1.0 + (rnd() - 0.5) * 1e-6),
                // Nearly parallel to the pixel segment.
                4 => e1 = e0 + (p1 - p0) * (rnd() * 4.0 - 2.0) + Vec2::new(rnd() - 0.5, rnd() - 0.5) * 1e-5,
                _ => {}
            }
            let want = division(p0, p1, e0, e1);
            assert_eq!(crossing(p0, p1, e0, e1).map(f32::to_bits), want.map(f32::to_bits), "{p0} {p1} {e0} {e1}");
            hits += want.is_some() as usize;
            cases += 1;
        }
        assert!(hits > cases / 20 && hits < cases / 2, "{hits} of {cases}");
    }

    /// What `surely_outside_unit` calls outside is outside for the division, at the edges too:
    /// numerators a few ulps from ±den and from ±0, and tiny numerators of the other sign.
    #[test]
    fn surely_outside_means_the_quotient_is_outside() {
        let mut seed = 5u64;
        let (mut outside, mut cases) = (0, 0);
        for _ in 0..20_000 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let den = f32::from_bits(0x2B8C_BCCC + ((seed >> 33) as u32 % 0x2000_0000)); // 1e-12 .. 1e7
            let den = if seed & 1 == 0 { den } else { -den };
            let b = den.abs().to_bits();
            let mut nums = Vec::new();
            for k in 0..4u32 {
                for m in [f32::from_bits(b + k), f32::from_bits(b - k), f32::from_bits(k), den.abs() * 1e-30] {
                    nums.extend([m, -m]);
                }
            }
            for num in nums {
                let q = num / den;
                if surely_outside_unit(num, den) {
                    assert!(!(0.0..=1.0).contains(&q), "{num} / {den} = {q}");
                    outside += 1;
                }
                cases += 1;
            }
        }
        assert!(outside > cases / 4, "{outside} of {cases}");
    }

    #[test]
    fn crossing_finds_the_parameter() {
        let t = crossing(Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(0.25, -1.0), Vec2::new(0.25, 1.0));
        assert!((t.unwrap() - 0.25).abs() < 1e-6);
        assert!(crossing(Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(2.0, -1.0), Vec2::new(2.0, 1.0)).is_none());
    }
}
