//! Stage 2: oriented 3D points near the hair surface (a simplified line-based MVS).
//!
//! In: the views' cameras and 2D orientation maps ([`crate::orient2d`]) and the raw mesh (a BVH).
//! Out: [`OrientedPoints`]: positions, undirected unit directions and a confidence, saved as
//! `points3d.ply` (binary PLY, the direction as the normal) and reloaded from there.
//!
//! Follows LPMVS (Nam, Wu, Kim, Sheffer, Cohen, "Strand-Accurate Multi-View Hair Capture", CVPR
//! 2019) in its cost, with the raw mesh as the depth prior (`docs/method.md` §2). What is built:
//! - every `stride`-th hair pixel of every view is a reference pixel; its ray is cast on the raw
//!   mesh for the prior depth t₀; pixels that miss the mesh are skipped;
//! - the hypotheses are 3D lines through the ray whose projection into the reference view follows
//!   the pixel's 2D orientation exactly (LPMVS's constraint: the direction lies in the plane spanned
//!   by the ray and the image direction); the in-plane angle φ is first chosen at the prior depth
//!   over `angle_steps` samples, then the depth among t₀ + `depth_offsets` by the photometric
//!   agreement (1 − NCC, mean over the visible neighbours) of a 5×3 patch laid in the plane of the
//!   line (across × along, one pixel apart), with a weak quadratic pull towards t₀ (offsets −1 to
//!   +4 mm in 1 mm steps: the raw mesh lies within 3 mm of most visible hair), then φ is refined at
//!   that depth;
//! - (`fit_direction`, default on) the direction is then refitted freely in 3D to the orientations
//!   of every view that sees the point, the reference included, by an iteratively reweighted
//!   least-squares intersection of their back-projected planes, and kept when its cost (over the
//!   neighbours and the reference) is lower: LPMVS's constraint trusts the reference view's θ,
//!   whose error goes straight into the 3D direction. On the paper-preset straight capture (58
//!   views, stride 2) it took the points from 134k at 85.6% precision / 42.6% coverage to 154k at
//!   84.6% / 46.7%;
//! - the cost of a hypothesis is the confidence-weighted mean of sin² of the angle between the
//!   line's projection and the 2D orientation in the `neighbours` nearest views where the prior
//!   point is visible (a ray cast on the raw mesh); a view where the point falls outside the hair
//!   costs 1 at a fixed weight;
//! - a point is kept when its cost is below `max_cost` and at least `min_agree` neighbouring views
//!   agree within `agree_angle`;
//!
//! Not built: LPMVS's final cross-view point filtering. A point-radius cross-view filter (points
//! of ≥ 2 other views within 1 mm) was tried and dropped: at 2.3 mm per pixel, points of different
//! views rarely lie that close (it kept 7% of the points); a line-based support test would be
//! needed. The orientation cost alone barely depends on depth, hence the photometric term for the
//! depth.

use glam::{Vec2, Vec3};
use hairrecon_core::{Bvh, Camera};
use rayon::prelude::*;

use crate::orient2d::{GrayImage, OrientationMap};
pub use crate::oriented_points::{OrientedPoints, PointsError};
use crate::progress::{Cancelled, Progress};

/// Parameters of the line MVS.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LineMvsParams {
    /// Use every `stride`-th pixel in x and y as a reference pixel.
    pub stride: usize,
    /// Number of neighbouring views that judge a hypothesis.
    pub neighbours: usize,
    /// Most angle (degrees) between the reference and a neighbour's viewing direction at the head.
    pub max_view_angle_deg: f32,
    /// Depth offsets (metres, along the ray) around the raw mesh's depth, searched photometrically.
    pub depth_offsets: Vec<f32>,
    /// Weight of a quadratic pull towards the raw mesh's depth (per 5 mm) in the depth search.
    pub depth_prior: f32,
    /// Samples of the in-plane angle over [0, π).
    pub angle_steps: usize,
    /// Reference pixels with a 2D confidence below this are skipped.
    pub min_confidence: f32,
    /// Largest accepted cost (mean sin²).
    pub max_cost: f32,
    /// Views that must agree within `agree_angle_deg`.
    pub min_agree: usize,
    pub agree_angle_deg: f32,
    /// A neighbour sees the point when the raw mesh is hit no nearer than this before it (metres).
    pub visibility_margin: f32,
    /// Refit the direction freely in 3D to every view's orientation, the reference included
    /// (see `fit_direction`), and keep it when its cost is lower.
    #[serde(default)]
    pub fit_direction: bool,
}

impl Default for LineMvsParams {
    fn default() -> Self {
        Self {
            stride: 1,
            neighbours: 8,
            max_view_angle_deg: 70.0,
            depth_offsets: (-1..=4).map(|k| k as f32 * 0.001).collect(),
            depth_prior: 0.05,
            angle_steps: 36,
            min_confidence: 0.05,
            max_cost: 0.09,
            min_agree: 2,
            agree_angle_deg: 15.0,
            visibility_margin: 0.004,
            fit_direction: true,
        }
    }
}

/// One view as the line MVS sees it.
#[derive(Debug, Clone, Copy)]
pub struct MvsView<'a> {
    pub camera: &'a Camera,
    pub map: &'a OrientationMap,
    /// The view's image, for the photometric depth search (skipped when `None`).
    pub image: Option<&'a GrayImage>,
}

impl<'a> MvsView<'a> {
    /// One view per capture view, with its orientation map and image (same order as the capture).
    pub fn for_capture(
        capture: &'a hairrecon_core::capture::Capture,
        maps: &'a [OrientationMap],
        images: &'a [GrayImage],
    ) -> Vec<Self> {
        capture
            .views
            .iter()
            .zip(maps)
            .zip(images)
            .map(|((v, map), img)| MvsView { camera: &v.camera, map, image: Some(img) })
            .collect()
    }
}

/// How a 3D line (a point and a direction) looks in one view.
enum Seen {
    /// The point is behind the camera.
    Behind,
    /// It projects onto a pixel without hair orientation (zero confidence).
    OffHair,
    /// It projects onto hair: the map's confidence there and the sin² of the angle between the line's
    /// projection and the map's orientation.
    Hair { confidence: f32, sin2: f32 },
}

impl MvsView<'_> {
    /// Projects the line through `p` along `d` into this view and compares it with the orientation
    /// map (nearest pixel) at the projection of `p`.
    fn see_line(&self, p: Vec3, d: Vec3) -> Seen {
        self.look(p).see(d)
    }

    /// What this view knows of the point `p`, for judging lines through it ([`Look::see`]).
    fn look(&self, p: Vec3) -> Look {
        let pc = self.camera.to_camera(p);
        if pc.z <= 1e-6 {
            return Look::Behind;
        }
        let pix = self.camera.camera_to_pixel(pc);
        let (th, confidence) = self.map.sample(pix.x, pix.y);
        if confidence <= 0.0 {
            return Look::OffHair;
        }
        let [a, b] = self.camera.camera_jacobian(pc);
        let (sin, cos) = th.sin_cos();
        Look::Hair { confidence, sin, cos, a, b }
    }
}

/// One view's look at a point: what [`MvsView::see_line`] needs of the point, computed once for
/// the many directions the search tries through it.
#[derive(Debug, Clone, Copy)]
enum Look {
    Behind,
    OffHair,
    /// The map's confidence, the sine and cosine of its angle, and the rows of the projection's
    /// Jacobian at the point.
    Hair {
        confidence: f32,
        sin: f32,
        cos: f32,
        a: Vec3,
        b: Vec3,
    },
}

impl Look {
    /// How the line through the point along `d` looks.
    #[inline]
    fn see(&self, d: Vec3) -> Seen {
        match *self {
            Look::Behind => Seen::Behind,
            Look::OffHair => Seen::OffHair,
            Look::Hair { confidence, sin, cos, a, b } => {
                Seen::Hair { confidence, sin2: sin2(Vec2::new(a.dot(d), b.dot(d)), sin, cos) }
            }
        }
    }
}

/// Samples of the photometric patch: 5 across the line × 3 along it.
const PATCH: usize = 15;

/// Bilinear sample; `None` outside the image.
#[inline]
fn bilinear(img: &GrayImage, x: f32, y: f32) -> Option<f32> {
    let (w, h) = (img.width as usize, img.height as usize);
    if !(x >= 0.0 && y >= 0.0 && x < (w - 1) as f32 && y < (h - 1) as f32) {
        return None;
    }
    let (xi, yi) = (x as usize, y as usize);
    let (fx, fy) = (x - xi as f32, y - yi as f32);
    let i = yi * w + xi;
    let top = img.data[i] * (1.0 - fx) + img.data[i + 1] * fx;
    let bot = img.data[i + w] * (1.0 - fx) + img.data[i + w + 1] * fx;
    Some(top * (1.0 - fy) + bot * fy)
}

/// The patch around `p` in the plane of `across` and `along`, `fp` metres apart, seen by `cam`.
#[inline]
fn patch(img: &GrayImage, cam: &Camera, p: Vec3, across: Vec3, along: Vec3, fp: f32, out: &mut [f32; PATCH]) -> bool {
    let mut k = 0;
    for j in -1..=1 {
        for i in -2..=2 {
            let q = p + across * (i as f32 * fp) + along * (1.5 * j as f32 * fp);
            let pc = cam.to_camera(q);
            if pc.z <= 1e-6 {
                return false;
            }
            let px = cam.camera_to_pixel(pc);
            match bilinear(img, px.x, px.y) {
                Some(v) => out[k] = v,
                None => return false,
            }
            k += 1;
        }
    }
    true
}

/// Normalised cross-correlation of two patches; 0 when either is flat.
#[inline]
fn ncc(a: &[f32; PATCH], b: &[f32; PATCH]) -> f32 {
    let n = PATCH as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0f32, 0.0f32, 0.0f32);
    for k in 0..PATCH {
        let (x, y) = (a[k] - ma, b[k] - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    if saa < 1e-8 || sbb < 1e-8 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
}

/// Neighbour views of each view: nearest viewing directions towards `centre`.
pub fn neighbour_views(cameras: &[&Camera], centre: Vec3, k: usize, max_angle_deg: f32) -> Vec<Vec<usize>> {
    let dirs: Vec<Vec3> = cameras.iter().map(|c| (c.center() - centre).normalize_or_zero()).collect();
    let cmin = max_angle_deg.to_radians().cos();
    (0..cameras.len())
        .map(|i| {
            let mut cand: Vec<(usize, f32)> = (0..cameras.len())
                .filter(|&j| j != i)
                .map(|j| (j, dirs[i].dot(dirs[j])))
                .filter(|&(_, c)| c >= cmin)
                .collect();
            cand.sort_by(|a, b| b.1.total_cmp(&a.1));
            cand.truncate(k);
            cand.into_iter().map(|c| c.0).collect()
        })
        .collect()
}

/// sin² of the angle between a projected 2D direction `a` and the image angle whose sine and
/// cosine are `s` and `c`.
#[inline]
fn sin2(a: Vec2, s: f32, c: f32) -> f32 {
    let l2 = a.length_squared();
    if l2 <= 1e-20 {
        return 1.0;
    }
    let cr = a.x * s - a.y * c;
    cr * cr / l2
}

/// The 3D direction through `p` that best agrees with the 2D orientations of the views `ids`:
/// each view's orientation θ at the projection of `p` back-projects to a plane of directions
/// (normal n = a sin θ − b cos θ, with a, b the projection's Jacobian rows), and the direction
/// minimises Σ w (n̂·d)², the smallest eigenvector of Σ w n̂ n̂ᵀ. The weights are the confidences,
/// reweighted three times from `init` by a Cauchy function of the residual (scale² `scale_s2`) so
/// that a view whose orientation is wrong there barely counts. Returns `init` when fewer than two
/// views see hair at `p`.
fn fit_direction(views: &[MvsView], ids: impl Iterator<Item = usize>, p: Vec3, init: Vec3, scale_s2: f32) -> Vec3 {
    let mut obs = [(Vec3::ZERO, 0.0f32); 24];
    let mut n = 0;
    for j in ids {
        if n == obs.len() {
            break;
        }
        let cam = views[j].camera;
        let pc = cam.to_camera(p);
        if pc.z <= 1e-6 {
            continue;
        }
        let pix = cam.camera_to_pixel(pc);
        let (th, c) = views[j].map.sample(pix.x, pix.y);
        if c <= 0.0 {
            continue;
        }
        let [a, b] = cam.camera_jacobian(pc);
        let (s, co) = th.sin_cos();
        let nrm = (a * s - b * co).normalize_or_zero();
        if nrm != Vec3::ZERO {
            obs[n] = (nrm, c);
            n += 1;
        }
    }
    if n < 2 {
        return init;
    }
    let obs = &obs[..n];
    let mut d = init;
    for _ in 0..3 {
        let mut m = nalgebra::Matrix3::<f32>::zeros();
        for &(nv, c) in obs {
            let r2 = nv.dot(d).powi(2);
            let w = c / (1.0 + r2 / scale_s2);
            let v = nalgebra::Vector3::new(nv.x, nv.y, nv.z);
            m += v * v.transpose() * w;
        }
        let eig = m.symmetric_eigen();
        let k = eig.eigenvalues.imin();
        let e = eig.eigenvectors.column(k);
        let nd = Vec3::new(e[0], e[1], e[2]).normalize_or_zero();
        if nd == Vec3::ZERO {
            break;
        }
        d = nd;
    }
    d
}

/// Weight of a view where the point falls outside the hair.
const OFF_HAIR_WEIGHT: f32 = 0.3;

/// The cost of the line through `p` along `d` in `judges`: the confidence-weighted mean sin² of its
/// angle to the views' orientation maps, a view where it falls outside the hair counting
/// [`OFF_HAIR_WEIGHT`]; 1 when no view judges it.
fn line_cost(views: &[MvsView], judges: impl Iterator<Item = usize>, p: Vec3, d: Vec3) -> f32 {
    cost_of(judges.map(|j| views[j].see_line(p, d)))
}

/// [`line_cost`] from the judges' looks at the line's point.
fn looks_cost(looks: &[Look], d: Vec3) -> f32 {
    cost_of(looks.iter().map(|l| l.see(d)))
}

/// The confidence-weighted mean sin² of what the judges see (see [`line_cost`]).
#[inline]
fn cost_of(seen: impl Iterator<Item = Seen>) -> f32 {
    let (mut sum, mut wsum) = (0.0f32, 0.0f32);
    for s in seen {
        match s {
            Seen::Behind => {}
            Seen::OffHair => {
                sum += OFF_HAIR_WEIGHT;
                wsum += OFF_HAIR_WEIGHT;
            }
            Seen::Hair { confidence, sin2 } => {
                sum += confidence * sin2;
                wsum += confidence;
            }
        }
    }
    if wsum > 0.0 {
        sum / wsum
    } else {
        1.0
    }
}

/// Largest number of neighbouring views kept per reference pixel.
const MAX_VIS: usize = 16;

/// One reference pixel during the search: its ray, the raw mesh's depth there, the neighbouring
/// views that see that point, the basis of its constraint plane, and its current hypothesis.
#[derive(Debug, Clone, Copy)]
struct Cell {
    ray: Vec3,
    /// `e1` and `ray` span the directions whose projection follows the pixel's θ; a hypothesis's
    /// direction is `e1 cos φ + ray sin φ`.
    e1: Vec3,
    vis: [u16; MAX_VIS],
    nvis: u8,
    t: f32,
    phi: f32,
}

impl Cell {
    fn vis(&self) -> impl Iterator<Item = usize> + '_ {
        self.vis[..self.nvis as usize].iter().map(|&j| j as usize)
    }

    fn dir(&self, phi: f32) -> Vec3 {
        self.e1 * phi.cos() + self.ray * phi.sin()
    }
}

/// Mean (1 − NCC) between the reference view's patch and each visible neighbour's, for the line
/// through `p` along `d`; `None` when no neighbour (or the reference) has the whole patch.
fn photo_cost(views: &[MvsView], vi: usize, cell: &Cell, p: Vec3, d: Vec3, fp: f32) -> Option<f32> {
    let ref_img = views[vi].image?;
    let across = d.cross(cell.ray).normalize_or_zero();
    let mut ref_patch = [0.0f32; PATCH];
    let mut other = [0.0f32; PATCH];
    if !patch(ref_img, views[vi].camera, p, across, d, fp, &mut ref_patch) {
        return None;
    }
    let (mut sum, mut cnt) = (0.0f32, 0usize);
    for j in cell.vis() {
        let Some(img) = views[j].image else { continue };
        if patch(img, views[j].camera, p, across, d, fp, &mut other) {
            sum += 1.0 - ncc(&ref_patch, &other);
            cnt += 1;
        }
    }
    (cnt > 0).then(|| sum / cnt as f32)
}

/// Estimates oriented points from every view. Checks for cancellation once per view.
///
/// Per view: (1) every reference pixel gets its hypothesis by the per-pixel search of the module
/// doc; (2) the direction refit, the cost and agreement tests.
pub fn estimate(
    views: &[MvsView],
    raw: &Bvh,
    params: &LineMvsParams,
    progress: &dyn Progress,
) -> Result<OrientedPoints, Cancelled> {
    let (lo, hi) = raw.mesh().bbox();
    let centre = 0.5 * (lo + hi);
    let cams: Vec<&Camera> = views.iter().map(|v| v.camera).collect();
    let nbrs = neighbour_views(&cams, centre, params.neighbours, params.max_view_angle_deg);
    let mut out = OrientedPoints::default();
    let steps = params.angle_steps.max(4);
    let agree_s2 = params.agree_angle_deg.to_radians().sin().powi(2);
    for (vi, view) in views.iter().enumerate() {
        progress.check()?;
        progress.update("orient3d", vi as f32 / views.len() as f32, &format!("view {}/{}", vi + 1, views.len()));
        let cam = view.camera;
        let map = view.map;
        let o = cam.center();
        let fx = cam.k().col(0).x;
        let (w, h) = (map.width as usize, map.height as usize);
        let s = params.stride.max(1);
        let (gw, gh) = (w.div_ceil(s), h.div_ceil(s));
        let nb = &nbrs[vi];
        // The visible neighbours' looks at the point at depth `t` of the cell's ray.
        let looks_at = |c: &Cell, t: f32| -> [Look; MAX_VIS] {
            let p = o + c.ray * t;
            let mut looks = [Look::Behind; MAX_VIS];
            for (l, j) in looks.iter_mut().zip(c.vis()) {
                *l = views[j].look(p);
            }
            looks
        };
        // 1. Per-pixel search, on a grid of the reference pixels (None: skipped).
        let grid: Vec<Option<Cell>> = (0..gw * gh)
            .into_par_iter()
            .map(|gi| {
                let (x, y) = ((gi % gw) * s, (gi / gw) * s);
                if map.confidence[y * w + x] < params.min_confidence {
                    return None;
                }
                let px = Vec2::new(x as f32, y as f32);
                let ray = cam.ray_direction(px);
                let hit = raw.ray_cast(o, ray, 0.0, f32::INFINITY)?;
                let x0 = o + ray * hit.t;
                // Visible neighbours at the prior point.
                let mut vis = [0u16; MAX_VIS];
                let mut nvis = 0;
                for &j in nb.iter() {
                    if nvis == vis.len() {
                        break;
                    }
                    let cj = views[j].camera;
                    let Some(pj) = cj.project(x0) else { continue };
                    if !cj.contains(pj.pixel) {
                        continue;
                    }
                    let oj = cj.center();
                    let dj = x0 - oj;
                    let dist = dj.length();
                    let dj = dj / dist;
                    let occluded = raw.occluded(oj, dj, 0.0, dist - params.visibility_margin);
                    if !occluded {
                        vis[nvis] = j as u16;
                        nvis += 1;
                    }
                }
                if nvis < params.min_agree {
                    return None;
                }
                // The plane of directions whose projection follows θ in the reference view.
                let theta = map.theta[y * w + x];
                let [ju, jv] = cam.project_jacobian(x0)?;
                let nimg = Vec2::new(-theta.sin(), theta.cos());
                let g = ju * nimg.x + jv * nimg.y;
                let e1 = g.cross(ray).normalize_or_zero();
                if e1 == Vec3::ZERO {
                    return None;
                }
                let mut c = Cell { ray, e1, vis, nvis: nvis as u8, t: hit.t, phi: 0.0 };
                // 1a. The direction at the prior depth (the orientation cost barely depends on depth).
                let nv = c.nvis as usize;
                let mut looks = looks_at(&c, hit.t);
                let mut best = (f32::INFINITY, hit.t, 0.0f32);
                for k in 0..steps {
                    let phi = -std::f32::consts::FRAC_PI_2 + (k as f32 + 0.5) * std::f32::consts::PI / steps as f32;
                    let cst = looks_cost(&looks[..nv], c.dir(phi));
                    if cst < best.0 {
                        best = (cst, hit.t, phi);
                    }
                }
                // 1b. The depth: photometric agreement of a small patch in the plane of the line.
                let phi = best.2;
                if view.image.is_some() {
                    let d = c.dir(phi);
                    let mut best_photo = f32::INFINITY;
                    let mut best_t = hit.t;
                    for &dt in &params.depth_offsets {
                        let t = hit.t + dt;
                        let Some(ph) = photo_cost(views, vi, &c, o + ray * t, d, hit.t / fx) else { continue };
                        let photo = ph + params.depth_prior * (dt / 0.005).powi(2);
                        if photo < best_photo {
                            best_photo = photo;
                            best_t = t;
                        }
                    }
                    if best_t != hit.t {
                        looks = looks_at(&c, best_t);
                    }
                    best = (looks_cost(&looks[..nv], c.dir(phi)), best_t, phi);
                }
                // 1c. Local refinement of φ.
                let mut dphi = 0.5 * std::f32::consts::PI / steps as f32;
                for _ in 0..4 {
                    for a in [dphi, -dphi] {
                        let cst = looks_cost(&looks[..nv], c.dir(best.2 + a));
                        if cst < best.0 {
                            best = (cst, best.1, best.2 + a);
                        }
                    }
                    dphi *= 0.5;
                }
                (c.t, c.phi) = (best.1, best.2);
                Some(c)
            })
            .collect();
        // 2. The direction refit and the tests.
        let found: Vec<(Vec3, Vec3, f32)> = (0..gw * gh)
            .into_par_iter()
            .filter_map(|gi| {
                let c = grid[gi].as_ref()?;
                let (x, y) = ((gi % gw) * s, (gi / gw) * s);
                let p = o + c.ray * c.t;
                let d = c.dir(c.phi);
                // A free 3D direction fitted to every view that sees the point, the reference
                // included (its θ is as noisy as the others'), judged by the same cost plus the
                // reference view.
                let (best_cost, d) = if params.fit_direction {
                    let judge = |d: Vec3| line_cost(views, c.vis().chain(std::iter::once(vi)), p, d);
                    let fitted = fit_direction(views, c.vis().chain(std::iter::once(vi)), p, d, agree_s2);
                    let (c0, c1) = (judge(d), judge(fitted));
                    if c1 < c0 {
                        (c1, fitted)
                    } else {
                        (c0, d)
                    }
                } else {
                    (line_cost(views, c.vis(), p, d), d)
                };
                if best_cost > params.max_cost {
                    return None;
                }
                // Agreement count.
                let mut agree = 0;
                for j in c.vis() {
                    if matches!(views[j].see_line(p, d), Seen::Hair { sin2, .. } if sin2 <= agree_s2) {
                        agree += 1;
                    }
                }
                if agree < params.min_agree {
                    return None;
                }
                let conf = (1.0 - best_cost / params.max_cost.max(1e-6)).clamp(0.0, 1.0) * map.confidence[y * w + x];
                Some((p, d.normalize(), conf))
            })
            .collect();
        for (p, d, c) in found {
            out.positions.push(p);
            out.directions.push(d);
            out.confidence.push(c);
        }
    }
    progress.update("orient3d", 1.0, &format!("{} points", out.len()));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::progress::NoProgress;
    use hairrecon_core::TriMesh;

    /// The ground-truth strand direction on the synthetic plane: it turns with x, `rate` radians
    /// per metre.
    fn field_turning(p: Vec3, rate: f32) -> Vec3 {
        let a = 0.4 + rate * p.x;
        Vec3::new(a.cos(), a.sin(), 0.3).normalize()
    }

    /// A square hair sheet (z = 0, 0.2 m wide), seven 96×96 cameras 0.5 m away (one above, six at
    /// 35° tilt) with a field of view of `fov_deg` (30°: 2.8 mm per pixel on the sheet; 10°:
    /// 0.9 mm), orientation maps rendered from `field_turning(·, rate)` with a seeded uniform angle
    /// noise of ±`noise_deg`, and the raw mesh (the depth prior): the same sheet `mesh_z` metres
    /// up.
    fn scene_with(noise_deg: f32, rate: f32, mesh_z: f32, fov_deg: f32) -> (Bvh, Vec<Camera>, Vec<OrientationMap>) {
        let h = 0.1;
        let sheet = |z: f32| {
            let verts = vec![Vec3::new(-h, -h, z), Vec3::new(h, -h, z), Vec3::new(h, h, z), Vec3::new(-h, h, z)];
            Bvh::new(TriMesh::new(verts, vec![[0, 1, 2], [0, 2, 3]], None, None).unwrap())
        };
        let (truth, raw) = (sheet(0.0), sheet(mesh_z));
        let mut eyes = vec![Vec3::new(0.0, 0.0, 0.5)];
        for k in 0..6 {
            let a = k as f32 * std::f32::consts::TAU / 6.0;
            let t = 35f32.to_radians();
            eyes.push(0.5 * Vec3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos()));
        }
        let cams: Vec<Camera> = eyes
            .iter()
            .map(|&e| Camera::look_at(e, Vec3::ZERO, Vec3::Y, fov_deg.to_radians(), 96, 96).unwrap())
            .collect();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let maps = cams
            .iter()
            .map(|cam| {
                let n = 96 * 96;
                let (mut theta, mut confidence) = (vec![0.0; n], vec![0.0; n]);
                for i in 0..n {
                    let px = Vec2::new((i % 96) as f32, (i / 96) as f32);
                    let (o, r) = (cam.center(), cam.ray_direction(px));
                    let Some(hit) = truth.ray_cast(o, r, 0.0, f32::INFINITY) else { continue };
                    let p = o + r * hit.t;
                    let [a, b] = cam.project_jacobian(p).unwrap();
                    let d = field_turning(p, rate);
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let u = (state >> 40) as f32 / (1u64 << 24) as f32;
                    let noise = (2.0 * u - 1.0) * noise_deg.to_radians();
                    theta[i] = (b.dot(d).atan2(a.dot(d)) + noise).rem_euclid(std::f32::consts::PI);
                    confidence[i] = 1.0;
                }
                OrientationMap { width: 96, height: 96, theta, confidence }
            })
            .collect();
        (raw, cams, maps)
    }

    /// What one run on a synthetic sheet gives: the number of points, the median and 95th percentile
    /// of the direction error (degrees), and the largest distance to the sheet (m).
    struct SheetRun {
        points: usize,
        err_median: f32,
        err_p95: f32,
        far: f32,
    }

    /// Runs the line MVS on [`scene_with`]`(noise_deg, rate, mesh_z, fov_deg)` without images.
    fn run_sheet(noise_deg: f32, rate: f32, mesh_z: f32, fov_deg: f32, params: &LineMvsParams) -> SheetRun {
        let (raw, cams, maps) = scene_with(noise_deg, rate, mesh_z, fov_deg);
        let views: Vec<MvsView> =
            cams.iter().zip(&maps).map(|(camera, map)| MvsView { camera, map, image: None }).collect();
        let pts = estimate(&views, &raw, params, &NoProgress).unwrap();
        let sorted = |mut v: Vec<f32>| {
            v.sort_by(f32::total_cmp);
            v
        };
        let q = |v: &[f32], f: f32| v.get(((v.len() as f32 * f) as usize).min(v.len().max(1) - 1)).copied();
        let err = sorted(
            pts.positions
                .iter()
                .zip(&pts.directions)
                .map(|(p, d)| d.dot(field_turning(*p, rate)).abs().min(1.0).acos().to_degrees())
                .collect(),
        );
        let z = sorted(pts.positions.iter().map(|p| p.z.abs()).collect());
        SheetRun {
            points: pts.len(),
            err_median: q(&err, 0.5).unwrap_or(90.0),
            err_p95: q(&err, 0.95).unwrap_or(90.0),
            far: z.last().copied().unwrap_or(0.0),
        }
    }

    /// (points, median and 95th-percentile direction error in degrees, largest distance to the sheet)
    /// on the default sheet (field turning 6 rad/m, raw mesh on the sheet, 30° field of view).
    fn run(noise_deg: f32, params: &LineMvsParams) -> (usize, f32, f32, f32) {
        let r = run_sheet(noise_deg, 6.0, 0.0, 30.0, params);
        (r.points, r.err_median, r.err_p95, r.far)
    }

    #[test]
    fn recovers_lines_from_exact_maps() {
        let params = LineMvsParams { stride: 2, ..Default::default() };
        let (n, med, p95, far) = run(0.0, &params);
        eprintln!("exact maps: {n} points, direction error median {med:.2}°, 95% {p95:.2}°, off the sheet {far:.1e} m");
        assert!(n > 6000, "{n} points");
        assert!(med < 0.5 && p95 < 1.5, "direction error median {med}°, 95% {p95}°");
        assert!(far < 1e-4, "{far} m off the sheet");
    }

    /// Noisy maps: fitting the direction to every view, the reference included, beats trusting
    /// the reference view's orientation.
    #[test]
    fn direction_fit_averages_noise() {
        let fit = LineMvsParams { stride: 2, max_cost: 1.0, min_agree: 0, fit_direction: true, ..Default::default() };
        let nofit = LineMvsParams { fit_direction: false, ..fit.clone() };
        let (n1, med1, p1, _) = run(15.0, &fit);
        let (n0, med0, p0, _) = run(15.0, &nofit);
        eprintln!("noise ±15°: fit {n1} points median {med1:.2}° 95% {p1:.2}°; no fit {n0} points median {med0:.2}° 95% {p0:.2}°");
        assert!(med1 < 0.85 * med0 && p1 < p0, "fit median {med1}° 95% {p1}° vs {med0}° {p0}°");
    }
}
