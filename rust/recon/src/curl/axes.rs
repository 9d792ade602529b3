//! Ringlet axes from the directed points: each tangent turned about the blurred hair-surface normal
//! by the pitch angle, averaged over a few millimetres; hung and moved onto the axes.

use glam::Vec3;
use hairrecon_core::mesh::TriMesh;
use rayon::prelude::*;

use super::{Curl, CurlOptions};
use crate::points3d::OrientedPoints;

/// A regular grid of Vec3 sums, blurred by a Gaussian and read back by trilinear interpolation.
struct BlurGrid {
    lo: Vec3,
    cell: f32,
    dims: [usize; 3],
    data: Vec<Vec3>,
}

impl BlurGrid {
    /// Splats `values` at `positions` (trilinearly) into a grid covering `positions` and `queries`
    /// with a margin of three sigmas, then blurs by `sigma` (metres).
    fn build(positions: &[Vec3], values: &[Vec3], queries: &[Vec3], cell: f32, sigma: f32) -> Option<Self> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in positions.iter().chain(queries) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let margin = 3.0 * sigma + 2.0 * cell;
        lo -= Vec3::splat(margin);
        hi += Vec3::splat(margin);
        let n = ((hi - lo) / cell).ceil();
        let dims = [n.x as usize + 1, n.y as usize + 1, n.z as usize + 1];
        if dims.iter().product::<usize>() > 64_000_000 {
            return None;
        }
        let mut g = Self { lo, cell, dims, data: vec![Vec3::ZERO; dims[0] * dims[1] * dims[2]] };
        for (p, v) in positions.iter().zip(values) {
            let (base, w) = g.corner_weights(*p);
            for (k, wk) in w.iter().enumerate() {
                let idx = base + g.corner_offset(k);
                g.data[idx] += *v * *wk;
            }
        }
        g.blur(sigma / cell);
        Some(g)
    }

    fn corner_offset(&self, k: usize) -> usize {
        let [nx, ny, _] = self.dims;
        (k & 1) + ((k >> 1) & 1) * nx + ((k >> 2) & 1) * nx * ny
    }

    /// The index of the lower corner of `p`'s cell and the eight trilinear weights.
    fn corner_weights(&self, p: Vec3) -> (usize, [f32; 8]) {
        let [nx, ny, nz] = self.dims;
        let u =
            ((p - self.lo) / self.cell).clamp(Vec3::ZERO, Vec3::new(nx as f32 - 2.0, ny as f32 - 2.0, nz as f32 - 2.0));
        let i = u.floor();
        let f = u - i;
        let (ix, iy, iz) = (i.x as usize, i.y as usize, i.z as usize);
        let mut w = [0.0f32; 8];
        for (k, wk) in w.iter_mut().enumerate() {
            let wx = if k & 1 == 1 { f.x } else { 1.0 - f.x };
            let wy = if k & 2 == 2 { f.y } else { 1.0 - f.y };
            let wz = if k & 4 == 4 { f.z } else { 1.0 - f.z };
            *wk = wx * wy * wz;
        }
        (ix + iy * nx + iz * nx * ny, w)
    }

    fn sample(&self, p: Vec3) -> Vec3 {
        let (base, w) = self.corner_weights(p);
        w.iter().enumerate().map(|(k, wk)| self.data[base + self.corner_offset(k)] * *wk).sum()
    }

    /// Separable Gaussian blur, `s` in cells, along x, y and z.
    fn blur(&mut self, s: f32) {
        if s <= 0.0 {
            return;
        }
        let r = (3.0 * s).ceil() as isize;
        let kernel: Vec<f32> = (-r..=r).map(|d| (-(d * d) as f32 / (2.0 * s * s)).exp()).collect();
        let [nx, ny, _] = self.dims;
        let strides = [1, nx, nx * ny];
        for axis in 0..3 {
            let len = self.dims[axis];
            let stride = strides[axis];
            // Every line along `axis`: its first index (the other two coordinates run over their range).
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let starts: Vec<usize> = (0..self.dims[a] * self.dims[b])
                .map(|i| (i % self.dims[a]) * strides[a] + (i / self.dims[a]) * strides[b])
                .collect();
            let src = self.data.clone();
            let lines: Vec<(usize, Vec<Vec3>)> = starts
                .par_iter()
                .map(|&s0| {
                    let line: Vec<Vec3> = (0..len)
                        .map(|j| {
                            let mut acc = Vec3::ZERO;
                            for (k, w) in kernel.iter().enumerate() {
                                let jj = j as isize + k as isize - r;
                                if jj >= 0 && (jj as usize) < len {
                                    acc += src[s0 + jj as usize * stride] * *w;
                                }
                            }
                            acc
                        })
                        .collect();
                    (s0, line)
                })
                .collect();
            for (s0, line) in lines {
                for (j, v) in line.into_iter().enumerate() {
                    self.data[s0 + j * stride] = v;
                }
            }
        }
    }
}

/// The mean downward (-z) component of the directions: ringlets hang, so the right handedness's axes
/// point down more than the wrong one's (paper curly preset: 0.58 against -0.11, the tangents 0.42).
pub fn mean_down(points: &OrientedPoints) -> f32 {
    points.directions.iter().map(|d| -d.z).sum::<f32>() / points.len().max(1) as f32
}

/// Ringlets hang: every axis that rises is reversed, so that all point down (-z). On the paper curly
/// preset the axes' signs, carried over from the directed points (86.7% of them right), agree with
/// the ground truth's axes for 62.0% of the points, against 72.9% once they all point down (73.8% lie
/// within 20° either way; measured at commit 9415375). Not for deciding the handedness by
/// [`mean_down`].
pub fn hang(axes: &mut OrientedPoints) {
    axes.directions.iter_mut().filter(|d| d.z > 0.0).for_each(|d| *d = -*d);
}

/// Moves every point from the side of its ringlet onto the ringlet's axis. A helix of handedness `h`
/// about the unit axis `a` has at each point the tangent `t = cos θ a + h sin θ e_φ`, `e_φ = a × e_r`
/// with `e_r` the unit direction from the axis out to the point; so `e_r = h (t⊥ × a)` with `t⊥` the
/// unit part of `t` across `a` once `t` is turned to run along `a` (then `e_r` is the same whichever
/// way `t` and `a` point), and the axis lies at `p - r e_r`. `tangents` are the points' own
/// directions (as the line MVS gives them), `axes` the same points with the axes' directions
/// ([`ringlet_axes`]), moved in place. A point whose tangent lies within a degree of its axis (no
/// `e_r`) stays.
///
/// The cameras see the ringlets' outer side, so the points lie one radius outside the axes, and the
/// centrelines grown through them ran there; the helices swept about those centrelines then stood a
/// radius off the ground truth's. Measured on the paper curly preset at commit 9fcf1d6
/// (research/notes/curly-study.md): of the points seen on a ground-truth strand, the median distance
/// to that strand's centreline 6.58 mm unmoved → 1.45 mm moved at the preset's radius, within 2 mm
/// 3.5% → 68.1% (moved the wrong way: 12.87 mm).
pub fn onto_axes(tangents: &OrientedPoints, axes: &mut OrientedPoints, curl: &Curl) {
    let min_across = 1f32.to_radians().sin();
    axes.positions.par_iter_mut().zip(&axes.directions).zip(&tangents.directions).for_each(|((p, a), t)| {
        // The tangent turned to run along the axis: then e_r does not depend on either's sign.
        let t = if t.dot(*a) < 0.0 { -*t } else { *t };
        let across = t - *a * t.dot(*a);
        if across.length() > min_across * t.length() {
            let e_r = curl.hand * across.normalize().cross(*a).normalize_or_zero();
            *p -= curl.radius * e_r;
        }
    });
}

/// Rotation of `v` about the unit `axis` by `angle` radians (right-handed).
fn rotate(v: Vec3, axis: Vec3, angle: f32) -> Vec3 {
    let (s, c) = angle.sin_cos();
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

/// The raw mesh's blurred unit normal at each point ([`CurlOptions::normal_sigma`]), zero where it
/// is undefined: what [`ringlet_axes_from_normals`] turns the tangents about, the same for every curl
/// tried. `None` when the grid would be too large (a scene far wider than a head).
pub fn surface_normals(points: &OrientedPoints, raw: &TriMesh, opts: &CurlOptions) -> Option<Vec<Vec3>> {
    let normals = raw.compute_vertex_normals();
    let ncell = (opts.normal_sigma / 4.0).max(0.002);
    let ngrid = BlurGrid::build(&raw.vertices, &normals, &points.positions, ncell, opts.normal_sigma)?;
    Some(points.positions.par_iter().map(|p| ngrid.sample(*p).normalize_or_zero()).collect())
}

/// The ringlet axis at each directed point (module docs). Confidence is kept; a point whose axis is
/// undefined (no mesh normal or no neighbours) keeps its own direction. `None` when the grid would be
/// too large (a scene far wider than a head).
pub fn ringlet_axes(points: &OrientedPoints, raw: &TriMesh, curl: &Curl, opts: &CurlOptions) -> Option<OrientedPoints> {
    ringlet_axes_from_normals(points, &surface_normals(points, raw, opts)?, curl, opts)
}

/// [`ringlet_axes`] with the surface's normals at the points given ([`surface_normals`]).
pub fn ringlet_axes_from_normals(
    points: &OrientedPoints,
    normals: &[Vec3],
    curl: &Curl,
    opts: &CurlOptions,
) -> Option<OrientedPoints> {
    let angle = curl.hand * curl.pitch_angle();
    let turned: Vec<Vec3> = points
        .directions
        .par_iter()
        .zip(normals)
        .map(|(d, &n)| {
            if n == Vec3::ZERO {
                *d
            } else if opts.project_axes {
                match (*d - n * d.dot(n)).try_normalize() {
                    Some(flat) => rotate(flat, n, angle),
                    None => *d,
                }
            } else {
                rotate(*d, n, angle)
            }
        })
        .collect();
    let acell = (opts.axis_sigma / 2.0).max(0.001);
    let agrid = BlurGrid::build(&points.positions, &turned, &points.positions, acell, opts.axis_sigma)?;
    let directions =
        points.positions.par_iter().zip(&turned).map(|(p, t)| agrid.sample(*p).try_normalize().unwrap_or(*t)).collect();
    Some(OrientedPoints { positions: points.positions.clone(), directions, confidence: points.confidence.clone() })
}

/// The directions the growth follows with curls `curl`: the ringlet axes from the points' tangents
/// ([`ringlet_axes`], hung when [`CurlOptions::hang`]), or, for curls finer than the photos
/// resolve (`fine`, [`crate::curl::CurlMode::Fine`]), the points' own directions, which follow the
/// ringlets' ropes and are signed as for plain hair. `None` when the blur grid would be too large.
pub fn growth_axes(
    points: &OrientedPoints,
    raw: &TriMesh,
    curl: &Curl,
    fine: bool,
    opts: &CurlOptions,
) -> Option<OrientedPoints> {
    if fine {
        return Some(points.clone());
    }
    let mut axes = ringlet_axes(points, raw, curl, opts)?;
    if opts.hang {
        hang(&mut axes);
    }
    Some(axes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curl::test_util::{helix, plane_facing_x, CURL};

    #[test]
    fn fine_curls_grow_along_the_points_and_resolved_ones_along_turned_tangents() {
        // Rope directions seen on fine coils: tilted 30° off -z, some pointing up (signed by the
        // direction stage, not by hanging). Fine curls keep them as they are; resolved ringlets turn
        // them by the pitch angle and hang them.
        let n = 200;
        let positions: Vec<Vec3> =
            (0..n).map(|k| Vec3::new(CURL.radius, -0.05 + 0.0005 * k as f32, -0.1 - 0.0003 * k as f32)).collect();
        let d = Vec3::new(0.0, 0.5, -(0.75f32).sqrt());
        let directions: Vec<Vec3> = (0..n).map(|k| if k % 4 == 0 { -d } else { d }).collect();
        let points = OrientedPoints { positions, directions, confidence: vec![1.0; n] };
        let raw = plane_facing_x(CURL.radius, [-0.1, 0.1], [-0.36, -0.06]);
        let opts = CurlOptions::default();
        let fine = growth_axes(&points, &raw, &CURL, true, &opts).unwrap();
        assert_eq!(fine, points);
        let turned = growth_axes(&points, &raw, &CURL, false, &opts).unwrap();
        let moved = turned.directions.iter().zip(&points.directions).filter(|(a, b)| a.dot(**b).abs() < 0.9).count();
        assert!(moved > n * 9 / 10, "{moved} of {n} turned");
        assert!(turned.directions.iter().all(|a| a.z <= 0.0), "hung: none points up");
    }

    #[test]
    fn turning_the_visible_tangents_gives_the_axis() {
        // Ringlets hanging along -z, seen from +x (the raw mesh: a big box whose +x face is the hair's
        // outer surface). The points: the helices' visible (x > 0.5 r) samples, with their tangents.
        let mut positions = Vec::new();
        let mut directions = Vec::new();
        for (j, y0) in [-0.03f32, -0.015, 0.0, 0.015, 0.03].iter().enumerate() {
            let h = helix(&CURL, 0.12, j as f32);
            for k in 1..h.len() - 1 {
                if h[k].x > 0.5 * CURL.radius {
                    positions.push(h[k] + Vec3::new(0.0, *y0, 0.0));
                    directions.push((h[k + 1] - h[k - 1]).normalize());
                }
            }
        }
        let n = positions.len();
        let points = OrientedPoints { positions, directions, confidence: vec![1.0; n] };
        // The hair surface: a plane x = r facing +x, in 5 mm quads.
        let raw = plane_facing_x(CURL.radius, [-0.1, 0.1], [-0.36, -0.06]);
        assert!(raw.face_normal(0).x > 0.99);
        let before: f32 = points.directions.iter().map(|d| d.dot(-Vec3::Z)).sum::<f32>() / n as f32;
        let axes = ringlet_axes(&points, &raw, &CURL, &CurlOptions::default()).unwrap();
        let after: Vec<f32> =
            axes.directions.iter().map(|d| d.dot(-Vec3::Z).clamp(-1.0, 1.0).acos().to_degrees()).collect();
        let within = after.iter().filter(|a| **a < 20.0).count() as f32 / n as f32;
        let mut sorted = after.clone();
        sorted.sort_by(f32::total_cmp);
        // The tangents sit on the 62° cone; the axes are within 20° of -z for most points (measured:
        // median 8.1°, 90% within 18.3°; the worst are the ends of the visible arcs of the outermost
        // ringlet, with neighbours on one side only).
        assert!(before < 0.6, "tangents' mean cosine to the axis {before}");
        assert!(sorted[n / 2] < 10.0, "median angle to the axis {}", sorted[n / 2]);
        assert!(within > 0.88, "share of axes within 20°: {within}");
        // The wrong handedness turns them away (by twice the pitch angle).
        let wrong = Curl { hand: -1.0, ..CURL };
        let axes = ringlet_axes(&points, &raw, &wrong, &CurlOptions::default()).unwrap();
        let within = axes.directions.iter().filter(|d| d.dot(-Vec3::Z) > 15f32.to_radians().cos()).count();
        assert_eq!(within, 0);
    }

    #[test]
    fn flattening_the_tangents_keeps_off_side_axes_in_the_surface() {
        // One ringlet along -z seen from +x, its samples 45-70° to either side of the outer side: there
        // the tangent leaves the surface (its x part is sin ψ sin φ), and turning it about the normal
        // without flattening it first tilts the axis out of the surface by about that much.
        let h = helix(&CURL, 0.12, 0.0);
        let mut positions = Vec::new();
        let mut directions = Vec::new();
        for k in 1..h.len() - 1 {
            let azimuth = h[k].y.atan2(h[k].x).to_degrees().abs();
            if (45.0..70.0).contains(&azimuth) {
                positions.push(h[k]);
                directions.push((h[k + 1] - h[k - 1]).normalize());
            }
        }
        let n = positions.len();
        assert!(n > 20, "{n} samples");
        let points = OrientedPoints { positions, directions, confidence: vec![1.0; n] };
        // The hair surface: the plane x = r facing +x (the normals' blur needs vertices near).
        let raw = plane_facing_x(CURL.radius, [-0.05, 0.05], [-0.2, 0.05]);
        assert!(raw.face_normal(0).x > 0.99);
        // No averaging to speak of: each point's own turned direction.
        let median_off = |project_axes: bool| {
            let opts = CurlOptions { project_axes, axis_sigma: 0.0001, ..CurlOptions::default() };
            let axes = ringlet_axes(&points, &raw, &CURL, &opts).unwrap();
            let mut deg: Vec<f32> =
                axes.directions.iter().map(|d| d.dot(-Vec3::Z).clamp(-1.0, 1.0).acos().to_degrees()).collect();
            deg.sort_by(f32::total_cmp);
            deg[n / 2]
        };
        let (flat, tilted) = (median_off(true), median_off(false));
        // Flattened, only the in-plane angle is off (atan(tan ψ cos φ) against ψ: 9-29°); unflattened,
        // the tangent's normal part (sin ψ sin φ) tilts the axis out of the surface by 39-56° on top.
        // Measured: medians 16.6° and 49.5° over 33 samples.
        assert!(flat + 10.0 < tilted, "median off the axis: flattened {flat}°, not {tilted}°");
    }

    #[test]
    fn points_move_onto_their_ringlets_axis() {
        // Two ringlets about (0, 0, z) and (0.02, 0, z), every sample (all sides), with the tangent
        // root-to-tip or reversed (the line MVS's lines are undirected before the direction stage) and
        // the axis pointing down or up: each point must land on its own ringlet's axis.
        let mut positions = Vec::new();
        let mut tangents = Vec::new();
        let mut axes = Vec::new();
        let mut own = Vec::new();
        let centres = [Vec3::ZERO, Vec3::new(0.02, 0.0, 0.0)];
        for (j, c) in centres.iter().enumerate() {
            let h = helix(&CURL, 0.08, 0.7 * j as f32);
            for k in 1..h.len() - 1 {
                own.push(*c);
                positions.push(h[k] + *c);
                let t = (h[k + 1] - h[k - 1]).normalize();
                tangents.push(if k % 3 == 0 { -t } else { t });
                axes.push(if k % 2 == 0 { -Vec3::Z } else { Vec3::Z });
            }
        }
        let n = positions.len();
        let conf = vec![1.0; n];
        let tangents = OrientedPoints { positions: positions.clone(), directions: tangents, confidence: conf.clone() };
        // Each point's distance from its own ringlet's axis.
        let radial = |pts: &OrientedPoints| -> Vec<f32> {
            pts.positions.iter().zip(&own).map(|(p, c)| (*p - *c).truncate().length()).collect()
        };
        let off_axis = |pts: &OrientedPoints| radial(pts).into_iter().fold(0.0, f32::max);
        let mut moved =
            OrientedPoints { positions: positions.clone(), directions: axes.clone(), confidence: conf.clone() };
        assert!((off_axis(&moved) - CURL.radius).abs() < 1e-4);
        onto_axes(&tangents, &mut moved, &CURL);
        // Central differences of 0.5 mm steps on a 6.5 mm helix: the tangent is exact in direction.
        assert!(off_axis(&moved) < 1e-4, "farthest from its axis: {} m", off_axis(&moved));
        for (a, b) in moved.positions.iter().zip(&positions) {
            assert!((a.z - b.z).abs() < 1e-6, "moved along the axis");
        }
        // The wrong handedness sends them out to twice the radius.
        let mut wrong = OrientedPoints { positions, directions: axes, confidence: conf };
        onto_axes(&tangents, &mut wrong, &Curl { hand: -1.0, ..CURL });
        let nearest = radial(&wrong).into_iter().fold(f32::INFINITY, f32::min);
        assert!((nearest - 2.0 * CURL.radius).abs() < 1e-4, "wrong handedness: nearest {nearest} m");
        // A point whose tangent runs along its axis has no side to move from.
        let along = OrientedPoints { positions: vec![Vec3::X], directions: vec![Vec3::Z], confidence: vec![1.0] };
        let mut same = along.clone();
        onto_axes(&along, &mut same, &CURL);
        assert_eq!(same.positions[0], Vec3::X);
    }

    #[test]
    fn hung_axes_point_down_and_keep_their_lines() {
        let d = [Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.0, 0.6, -0.8), Vec3::X];
        let mut axes =
            OrientedPoints { positions: vec![Vec3::ZERO; 3], directions: d.to_vec(), confidence: vec![1.0; 3] };
        hang(&mut axes);
        assert_eq!(axes.directions, vec![Vec3::new(-0.6, 0.0, -0.8), d[1], d[2]]);
    }
}
