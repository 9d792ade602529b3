//! Curls: the axes of ringlets from the directed points, and helices swept about grown centrelines.
//!
//! On curly hair the points' directions are the strands' own tangents, which wind on a cone about the
//! ringlet's axis (the paper preset's curls: 62° from the axis). A flow grown from them follows
//! neither the strands nor the ringlets. Two facts give the axis back:
//! - the cameras see the outer side of each ringlet, where a helix of handedness `h` and pitch angle
//!   `θ` (tan θ = 2πr / period) has its tangent turned by `-h·θ` about the hair surface's outward
//!   normal from the axis; so turning each point's tangent by `+h·θ` about that normal gives the
//!   axis (the normal must be the hair surface's at the scale of the hairstyle, not of one ringlet:
//!   the raw mesh's normals blurred by [`CurlOptions::normal_sigma`]);
//! - averaging those turned directions over a few millimetres (their noise is independent) then
//!   gives a smooth axis field, from which the Laplace flow grows centrelines.
//!
//! The axes' signs come from the directed points, a seventh of which are wrong on curls; ringlets
//! hang, so [`hang`] points every axis down before the growth. The points lie on the ringlets'
//! outer side, a radius from their axes: [`onto_axes`] moves them there, so that the centrelines
//! grown through them run along the axes. [`sweep_helices`] then replaces each grown strand by a
//! helix about its own centreline.
//!
//! Measured on the paper curly preset (docs/curly-study.md, session 22): at the preset's own
//! pitch (62°) the axes of [`ringlet_axes`] lie within 20° of the ground truth's for 74% of the points
//! (their tangents: 1%; `examples/curl_stage`); `hairrecon reconstruct … --stop-after init` with
//! `--curl auto` (the default) picks right-handed curls of 9 mm and 22 mm and scores 66.3 undirected /
//! 63.9 directed F1 at 2 mm/20°, against 51.6 / 46.7 for strands grown from the tangents (`--curl off`);
//! with the axes hung (session 23) 67.3 / 65.2; with the points moved onto the axes (session 24)
//! 68.8 / 66.6, and 17.8 against 16.4 at 1 mm/10°. Since session 29 `auto` reads the period off the
//! hair surface's bumps ([`bump_period`]) and takes the radius of the nominal pitch: 6.1 mm and 22.1 mm
//! on that preset, init 71.7 / 70.5 (commit 6c0f495).

use glam::Vec3;
use hairrecon_core::mesh::TriMesh;
use hairrecon_core::strands::{StrandError, StrandSet};
use rayon::prelude::*;

use crate::points3d::OrientedPoints;

/// The curls of a hairstyle: round helices of one radius, period and handedness.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Curl {
    /// Helix radius, metres.
    pub radius: f32,
    /// Length of centreline per turn, metres.
    pub period: f32,
    /// +1 right-handed about the root-to-tip direction, -1 left-handed.
    pub hand: f32,
}

impl Curl {
    /// The angle between the strand and the ringlet's axis, radians.
    pub fn pitch_angle(&self) -> f32 {
        (std::f32::consts::TAU * self.radius / self.period).atan()
    }

    /// Checks the values; the message names the bad one.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.radius.is_finite() && self.radius > 0.0 && self.radius < 0.1) {
            return Err(format!("curl radius {} m: give a radius in (0, 100) mm", self.radius));
        }
        if !(self.period.is_finite() && self.period > 0.0 && self.period < 1.0) {
            return Err(format!("curl period {} m: give a period in (0, 1000) mm", self.period));
        }
        if self.hand != 1.0 && self.hand != -1.0 {
            return Err(format!("curl handedness {}: give 1 (right) or -1 (left)", self.hand));
        }
        Ok(())
    }
}

/// Whether and how the pipeline makes curls.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum CurlMode {
    /// Strands grow from the points' own directions, as for straight and wavy hair.
    Off,
    /// The pipeline decides from the images (`pipeline` docs): curls of the radius, period and
    /// handedness whose rendering fits the orientation maps best, or none when strands grown from
    /// the points' directions fit better.
    #[default]
    Auto,
    /// These curls.
    Fixed(Curl),
}

impl std::str::FromStr for CurlMode {
    type Err = String;

    /// `off`, `auto` or `RADIUS_MM,PERIOD_MM,HAND` (HAND 1 right-handed, -1 left-handed).
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(Self::Off),
            "auto" => Ok(Self::Auto),
            _ => {
                let v: Vec<f32> =
                    s.split(',').map(|x| x.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|_| {
                        format!("curl {s:?}: give off, auto or RADIUS_MM,PERIOD_MM,HAND (e.g. 6.5,22,1)")
                    })?;
                let [r, p, h] = v[..] else {
                    return Err(format!("curl {s:?}: give three numbers RADIUS_MM,PERIOD_MM,HAND (e.g. 6.5,22,1)"));
                };
                let c = Curl { radius: r / 1000.0, period: p / 1000.0, hand: h };
                c.validate()?;
                Ok(Self::Fixed(c))
            }
        }
    }
}

/// How [`ringlet_axes`] and [`sweep_helices`] work, and which curls `auto` tries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurlOptions {
    /// Gaussian sigma of the blur of the raw mesh's normals, metres (the hair surface's scale).
    pub normal_sigma: f32,
    /// Gaussian sigma of the average of the turned directions, metres.
    pub axis_sigma: f32,
    /// Whether each point's direction loses its component along the blurred normal before it is
    /// turned ([`ringlet_axes`]): a point seen off the ringlet's outer side has a tangent that
    /// leaves the surface, and turning that part about the normal tilts the axis out of it. Off by
    /// default: on the paper curly capture it brings the axes within 20° of the ground truth's from
    /// 73.0% to 77.5% (median 12.2° to 10.1°), but the init's F1 stays where it was (19.6 · 71.4 · 90.1
    /// against 19.7 · 71.4 · 89.8; docs/curly-study.md, session 32).
    pub project_axes: bool,
    /// Window of the box mean that gives a grown strand's centreline, metres of arc.
    pub centre_window: f32,
    /// The helix grows to full radius over this arc length from the root, metres.
    pub ramp: f32,
    /// Spacing of the swept helix's points, metres.
    pub step: f32,
    /// `auto`: the pitch angle of the first axes (degrees), and of the curls when their period is
    /// read off the surface ([`bump_period`]); the growth's axes are made again at the chosen curl's
    /// pitch.
    pub nominal_pitch_deg: f32,
    /// `auto`: whether the period is read off the surface's bumps ([`bump_period`]), and how; when
    /// off, or when the surface shows none, the misfit chooses (`pipeline` docs).
    pub bump_period: bool,
    pub bumps: BumpOptions,
    /// `auto`: how much more the ringlet axes must point down than the points' directions (mean -z
    /// component) for the hair to count as curly.
    pub min_down_gain: f32,
    /// `auto`: the radii and periods tried (metres), every pair of them.
    pub radii: [f32; 3],
    pub periods: [f32; 3],
    /// `auto`: the images score every `score_every`-th child in `score_views` views spread evenly.
    pub score_every: usize,
    pub score_views: usize,
    /// Whether the growth's axes are made to point down ([`hang`]).
    pub hang: bool,
    /// Whether the growth's points are moved from the ringlets' visible side onto their axes
    /// ([`onto_axes`]).
    pub onto_axes: bool,
    /// [`fit_phases`] (a study, not in the pipeline: docs/curly-study.md, sessions 23 and 25): how many
    /// phases are tried, and the radius (metres) and angle (degrees) of a point's support.
    pub fit_phases: usize,
    pub fit_radius: f32,
    pub fit_angle_deg: f32,
}

impl Default for CurlOptions {
    fn default() -> Self {
        // The settings of the session-22 study (docs/curly-study.md): sigma 25 mm for the normals, 5 mm for the
        // axes, a 20 mm window; sigma 10 mm for the normals gave 43% of the axes within 20°, 25 mm 47%
        // (before the average, which raises it to 65%).
        Self {
            normal_sigma: 0.025,
            axis_sigma: 0.005,
            project_axes: false,
            centre_window: 0.020,
            ramp: 0.015,
            step: 0.001,
            nominal_pitch_deg: 60.0,
            bump_period: true,
            bumps: BumpOptions::default(),
            min_down_gain: 0.08,
            radii: [0.004, 0.0065, 0.009],
            periods: [0.015, 0.022, 0.030],
            score_every: 10,
            score_views: 8,
            hang: true,
            onto_axes: true,
            fit_phases: 16,
            fit_radius: 0.0015,
            fit_angle_deg: 20.0,
        }
    }
}

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
/// within 20° either way; `examples/curl_stage`). Not for deciding the handedness by [`mean_down`].
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
/// radius off the ground truth's. Measured on the paper curly preset (docs/curly-study.md,
/// session 24; `examples/curl_stage … onto=0,6.5,-6.5`): of the points seen on a ground-truth strand,
/// the median distance to that strand's centreline 6.58 → 1.45 mm at the preset's radius, within
/// 2 mm 3.5% → 68.1% (moved the wrong way: 12.87 mm).
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

/// The ringlet axis at each directed point (module docs). Confidence is kept; a point whose axis is
/// undefined (no mesh normal or no neighbours) keeps its own direction. `None` when the grid would be
/// too large (a scene far wider than a head).
pub fn ringlet_axes(points: &OrientedPoints, raw: &TriMesh, curl: &Curl, opts: &CurlOptions) -> Option<OrientedPoints> {
    let normals = raw.compute_vertex_normals();
    let ncell = (opts.normal_sigma / 4.0).max(0.002);
    let ngrid = BlurGrid::build(&raw.vertices, &normals, &points.positions, ncell, opts.normal_sigma)?;
    let angle = curl.hand * curl.pitch_angle();
    let turned: Vec<Vec3> = points
        .positions
        .par_iter()
        .zip(&points.directions)
        .map(|(p, d)| match ngrid.sample(*p).try_normalize() {
            Some(n) if opts.project_axes => match (*d - n * d.dot(n)).try_normalize() {
                Some(flat) => rotate(flat, n, angle),
                None => *d,
            },
            Some(n) => rotate(*d, n, angle),
            None => *d,
        })
        .collect();
    let acell = (opts.axis_sigma / 2.0).max(0.001);
    let agrid = BlurGrid::build(&points.positions, &turned, &points.positions, acell, opts.axis_sigma)?;
    let directions =
        points.positions.par_iter().zip(&turned).map(|(p, t)| agrid.sample(*p).try_normalize().unwrap_or(*t)).collect();
    Some(OrientedPoints { positions: points.positions.clone(), directions, confidence: points.confidence.clone() })
}

/// How [`bump_period`] reads the curls' period off the hair surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BumpOptions {
    /// Radius of each sample's neighbourhood, metres: the longest lag measured.
    pub radius: f32,
    /// Half-width of the strip along the axis whose heights are correlated, metres.
    pub strip: f32,
    /// Bin (and lag) width, metres.
    pub bin: f32,
    /// How many points are sampled (evenly through the point list).
    pub samples: usize,
    /// Fewest points in a strip for its sample to count.
    pub min_points: usize,
    /// How much higher the correlation's first maximum must be than its first minimum.
    pub min_contrast: f32,
    /// 0: correlate the heights; k: correlate their differences over k bins (a high-pass).
    pub diff: usize,
}

impl Default for BumpOptions {
    fn default() -> Self {
        Self { radius: 0.04, strip: 0.0015, bin: 0.001, samples: 3000, min_points: 50, min_contrast: 0.1, diff: 3 }
    }
}

/// What [`bump_period`] measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BumpReport {
    /// Samples whose strip held enough points.
    pub samples: usize,
    /// Correlation of the surface's height at lags of 0, 1, 2, … bins along the axes (1 at lag 0).
    pub correlation: Vec<f32>,
    /// The lag of the correlation's first minimum and of the maximum after it, metres (parabola fits);
    /// the second is the period.
    pub first_min: Option<f32>,
    pub period: Option<f32>,
}

/// The curls' period, read off the bumps of the hair surface along the ringlets' axes.
///
/// The strands of a ringlet curl in phase (a clump of helices), so the ringlet's visible side bulges
/// out once per turn, where its strands pass in front, and falls back half a turn later: the surface
/// seen by the cameras is corrugated across the axes with the curls' period, which the points'
/// tangents do not show (on the visible side they point the same way at every turn). For each of
/// `samples` points: its neighbours within `radius`, in the frame of its axis `a`, the surface's
/// normal `n` (the neighbourhood's least-spread direction, made normal to `a`) and `e = a × n`; their
/// heights along `n` less a quadratic surface fitted to them all; the heights in the strip |e| <
/// `strip` binned along `a`, differenced over `diff` bins (a high-pass: the residuals of a fit over a
/// finite neighbourhood correlate at lags near its radius, which gave straight and wavy hair false
/// periods at 25 mm), and the products of bins `lag` apart summed over all samples. The period is the
/// lag of the first maximum after the first (negative) minimum past `2 diff`, which must be
/// `min_contrast` lower. `None` when there is no such pair (a smooth surface: straight or wavy hair).
///
/// The axes' directions only need to be near the ringlets' (the axes at the nominal pitch of
/// [`ringlet_axes`] are within 20° for three quarters of the points on the paper curly preset): the
/// period seen along a direction δ off the axis is 1/cos δ longer (6% at 20°).
///
/// Measured (docs/curly-study.md, session 29; `examples/bump_period`): paper curly (period 22 mm)
/// 22.1 mm; a curly capture made with `hairrecon synth-hair --curl 4.5,16` 15.7 mm; straight and
/// wavy none; the same within 0.6 mm with neighbourhoods of 25 and 60 mm.
pub fn bump_period(positions: &[Vec3], axes: &[Vec3], opts: &BumpOptions) -> BumpReport {
    let n = positions.len().min(axes.len());
    let lags = (opts.radius / opts.bin).round() as usize;
    let nbins = 2 * lags + 1;
    let empty = BumpReport { samples: 0, correlation: Vec::new(), first_min: None, period: None };
    if n == 0 || lags < 4 {
        return empty;
    }
    let index = crate::metrics::PointIndex::new(positions[..n].to_vec(), Vec::new());
    let stride = (n / opts.samples.max(1)).max(1);
    let picks: Vec<usize> = (0..n).step_by(stride).collect();
    // Per sample: sums of products and counts of pairs by lag (collected in order, summed in order:
    // the same result with any number of threads).
    let per: Vec<Option<(Vec<f64>, Vec<f64>)>> = picks
        .par_iter()
        .map(|&i| {
            let a = axes[i].try_normalize()?;
            let p0 = positions[i];
            let nb = index.within(p0, opts.radius);
            if nb.len() < opts.min_points {
                return None;
            }
            let d: Vec<Vec3> = nb.iter().map(|&j| positions[j] - p0).collect();
            let mean = d.iter().copied().sum::<Vec3>() / d.len() as f32;
            let mut cov = nalgebra::Matrix3::<f64>::zeros();
            for q in &d {
                let c = (*q - mean).as_dvec3();
                cov += nalgebra::Vector3::new(c.x, c.y, c.z) * nalgebra::RowVector3::new(c.x, c.y, c.z);
            }
            let eig = cov.symmetric_eigen();
            let k = eig.eigenvalues.imin();
            let e = eig.eigenvectors.column(k);
            let nrm = Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32);
            let nrm = (nrm - a * nrm.dot(a)).try_normalize()?;
            let side = a.cross(nrm);
            // Heights less the least-squares quadratic surface in (s, u), scaled to about [-1, 1].
            let inv = 1.0 / opts.radius as f64;
            let basis = |s: f64, u: f64| [1.0, s, u, s * s, s * u, u * u];
            let mut ata = nalgebra::Matrix6::<f64>::zeros();
            let mut atb = nalgebra::Vector6::<f64>::zeros();
            let su: Vec<(f64, f64, f64)> =
                d.iter().map(|q| (q.dot(a) as f64 * inv, q.dot(side) as f64 * inv, q.dot(nrm) as f64)).collect();
            for &(s, u, h) in &su {
                let b = nalgebra::Vector6::from(basis(s, u));
                ata += b * b.transpose();
                atb += b * h;
            }
            let coef = ata.cholesky()?.solve(&atb);
            let mut sum = vec![0.0f64; nbins];
            let mut count = vec![0u32; nbins];
            let strip = opts.strip as f64 * inv;
            for &(s, u, h) in &su {
                if u.abs() >= strip {
                    continue;
                }
                let r = h - nalgebra::Vector6::from(basis(s, u)).dot(&coef);
                let b = ((s / (opts.bin as f64 * inv)).round() as i64 + lags as i64).clamp(0, nbins as i64 - 1);
                sum[b as usize] += r;
                count[b as usize] += 1;
            }
            if count.iter().map(|&c| c as usize).sum::<usize>() < opts.min_points {
                return None;
            }
            let heights: Vec<Option<f64>> =
                sum.iter().zip(&count).map(|(s, &c)| (c > 0).then(|| s / c as f64)).collect();
            // Differences over `diff` bins, less their mean (a high-pass), or the heights.
            let series: Vec<Option<f64>> = if opts.diff > 0 {
                let d: Vec<Option<f64>> =
                    heights.iter().zip(&heights[opts.diff.min(nbins)..]).map(|(x, y)| Some((*y)? - (*x)?)).collect();
                let (sum, n) = d.iter().flatten().fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
                let mean = if n > 0 { sum / n as f64 } else { 0.0 };
                d.into_iter().map(|v| v.map(|v| v - mean)).collect()
            } else {
                heights
            };
            let mut prod = vec![0.0f64; lags + 1];
            let mut pairs = vec![0.0f64; lags + 1];
            for (lag, (pr, pa)) in prod.iter_mut().zip(pairs.iter_mut()).enumerate() {
                for (x, y) in series.iter().zip(series.iter().skip(lag)) {
                    if let (Some(x), Some(y)) = (x, y) {
                        *pr += x * y;
                        *pa += 1.0;
                    }
                }
            }
            Some((prod, pairs))
        })
        .collect();
    let mut prod = vec![0.0f64; lags + 1];
    let mut pairs = vec![0.0f64; lags + 1];
    let mut samples = 0;
    for (pr, pa) in per.into_iter().flatten() {
        samples += 1;
        prod.iter_mut().zip(&pr).for_each(|(x, y)| *x += y);
        pairs.iter_mut().zip(&pa).for_each(|(x, y)| *x += y);
    }
    let raw: Vec<f64> = prod.iter().zip(&pairs).map(|(s, c)| if *c > 0.0 { s / c } else { 0.0 }).collect();
    if samples == 0 || raw[0] <= 0.0 {
        return BumpReport { samples, ..empty };
    }
    let correlation: Vec<f32> = raw.iter().map(|c| (c / raw[0]) as f32).collect();
    // Differences of noise correlate negatively at a lag of `diff` bins: the search starts past it.
    let (first_min, period) = first_min_and_max(&correlation, opts.min_contrast, (2 * opts.diff).max(2));
    BumpReport {
        samples,
        correlation,
        first_min: first_min.map(|l| l * opts.bin),
        period: period.map(|l| l * opts.bin),
    }
}

/// The lags (in bins, refined by a parabola through three bins) of the first negative local minimum
/// of `c` from lag `start` on and of the first local maximum after it that stands `min_contrast`
/// above it.
fn first_min_and_max(c: &[f32], min_contrast: f32, start: usize) -> (Option<f32>, Option<f32>) {
    let refine = |k: usize| {
        let (y0, y1, y2) = (c[k - 1], c[k], c[k + 1]);
        let den = y0 - 2.0 * y1 + y2;
        k as f32 + if den.abs() > 1e-12 { (0.5 * (y0 - y2) / den).clamp(-0.5, 0.5) } else { 0.0 }
    };
    let Some(m) =
        (start.max(1)..c.len().saturating_sub(1)).find(|&k| c[k] < 0.0 && c[k] <= c[k - 1] && c[k] <= c[k + 1])
    else {
        return (None, None);
    };
    let top = (m + 1..c.len().saturating_sub(1))
        .find(|&k| c[k] >= c[k - 1] && c[k] >= c[k + 1] && c[k] - c[m] >= min_contrast);
    (Some(refine(m)), top.map(refine))
}

/// A deterministic phase in [0, 2π) for strand `i`.
fn phase(seed: u64, i: usize) -> f32 {
    let mut z = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU
}

/// Replaces each strand by a helix of `curl` about its own centreline: the strand is resampled every
/// `opts.step`, its centreline is the mean over `opts.centre_window` of arc (shrinking at the ends;
/// the root is kept) resampled every `opts.step`, and the helix is swept about it in a frame carried
/// along it, at a random phase per strand (from `seed`), growing to full radius over `opts.ramp`.
/// Strands with fewer than 3 samples are kept as they are.
pub fn sweep_helices(
    strands: &StrandSet,
    curl: &Curl,
    opts: &CurlOptions,
    seed: u64,
) -> Result<StrandSet, StrandError> {
    sweep_helices_at(strands, curl, opts, seed, None)
}

/// [`sweep_helices`] at the given phases (from [`fit_phases`]; a strand without one gets the random
/// phase).
pub fn sweep_helices_at(
    strands: &StrandSet,
    curl: &Curl,
    opts: &CurlOptions,
    seed: u64,
    phases: Option<&[Option<f32>]>,
) -> Result<StrandSet, StrandError> {
    let step = opts.step;
    let out: Vec<Vec<Vec3>> = (0..strands.num_strands())
        .into_par_iter()
        .map(|i| {
            let s = strands.strand(i);
            let Some(c) = centreline(s, opts.centre_window, step) else { return s.to_vec() };
            let phi = phases.and_then(|p| p.get(i).copied().flatten()).unwrap_or_else(|| phase(seed, i));
            helix_about(&c, curl, opts, phi)
        })
        .collect();
    let counts = out.iter().map(|s| s.len() as u32).collect();
    StrandSet::new(out.into_iter().flatten().collect(), counts)
}

/// The directed points, bucketed by a grid of cubes of side `radius`, for [`fit_phases`]: how well a
/// helix point and its tangent are supported by the points near it.
#[derive(Debug)]
pub struct PointSupport {
    radius: f32,
    lo: Vec3,
    dims: [usize; 3],
    /// Per cube, the index of its first point in `pts` (one more entry than cubes).
    first: Vec<u32>,
    pts: Vec<(Vec3, Vec3, f32)>,
    min_cos: f32,
}

impl PointSupport {
    /// `None` when the grid would pass 64 million cubes (a scene far wider than a head).
    pub fn new(points: &OrientedPoints, radius: f32, max_angle_deg: f32) -> Option<Self> {
        let (lo, hi) =
            points.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        if !(lo.is_finite() && hi.is_finite() && radius > 0.0) {
            return None;
        }
        let n = ((hi - lo) / radius).floor();
        let dims = [n.x as usize + 1, n.y as usize + 1, n.z as usize + 1];
        if dims.iter().product::<usize>() > 64_000_000 {
            return None;
        }
        let mut s =
            Self { radius, lo, dims, first: Vec::new(), pts: Vec::new(), min_cos: max_angle_deg.to_radians().cos() };
        let mut keyed: Vec<(u32, u32)> =
            points.positions.iter().enumerate().map(|(i, p)| (s.cube(*p).unwrap_or(0) as u32, i as u32)).collect();
        keyed.sort_unstable();
        let ncubes = dims[0] * dims[1] * dims[2];
        s.first = vec![0u32; ncubes + 1];
        for &(c, _) in &keyed {
            s.first[c as usize + 1] += 1;
        }
        for c in 0..ncubes {
            s.first[c + 1] += s.first[c];
        }
        s.pts = keyed
            .iter()
            .map(|&(_, i)| {
                let i = i as usize;
                (points.positions[i], points.directions[i], points.confidence[i])
            })
            .collect();
        Some(s)
    }

    fn cube(&self, p: Vec3) -> Option<usize> {
        let c = ((p - self.lo) / self.radius).floor();
        let [i, j, k] = [c.x, c.y, c.z].map(|v| v as isize);
        let [nx, ny, nz] = self.dims.map(|d| d as isize);
        (i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz).then(|| (i + j * nx + k * nx * ny) as usize)
    }

    /// The support of a point `p` with unit tangent `t`: the sum over the points within `radius` of
    /// confidence × (1 - d²/radius²) × how far their (undirected) direction lies inside the angle
    /// (1 when parallel, 0 at the angle and beyond).
    pub fn support(&self, p: Vec3, t: Vec3) -> f32 {
        let c = ((p - self.lo) / self.radius).floor();
        let [ci, cj, ck] = [c.x, c.y, c.z].map(|v| v as isize);
        let [nx, ny, nz] = self.dims.map(|d| d as isize);
        let r2 = self.radius * self.radius;
        let mut sum = 0.0;
        for k in (ck - 1).max(0)..=(ck + 1).min(nz - 1) {
            for j in (cj - 1).max(0)..=(cj + 1).min(ny - 1) {
                let (i0, i1) = ((ci - 1).max(0), (ci + 1).min(nx - 1));
                if i0 > i1 {
                    continue;
                }
                let row = (j * nx + k * nx * ny) as usize;
                let (a, b) = (self.first[row + i0 as usize] as usize, self.first[row + i1 as usize + 1] as usize);
                for (q, d, w) in &self.pts[a..b] {
                    let d2 = (*q - p).length_squared();
                    if d2 < r2 {
                        let cos = d.dot(t).abs();
                        if cos > self.min_cos {
                            sum += w * (1.0 - d2 / r2) * (cos - self.min_cos) / (1.0 - self.min_cos);
                        }
                    }
                }
            }
        }
        sum
    }
}

/// The phase of each strand's helix that the directed points support best, or `None` where no
/// phase has support (the ringlet's hidden side). Every strand's centreline (as [`sweep_helices`]
/// makes it) gets helices at `opts.fit_phases` phases; each is scored by the summed
/// [`PointSupport::support`] of its points. The phase is one per strand: a ringlet's strands curl in
/// step, and the visible side fixes it.
pub fn fit_phases(strands: &StrandSet, curl: &Curl, opts: &CurlOptions, support: &PointSupport) -> Vec<Option<f32>> {
    let n = opts.fit_phases.max(1);
    (0..strands.num_strands())
        .into_par_iter()
        .map(|i| {
            let c = centreline(strands.strand(i), opts.centre_window, opts.step)?;
            let mut best: Option<(f32, f32)> = None;
            for j in 0..n {
                let phi = j as f32 * std::f32::consts::TAU / n as f32;
                let h = helix_about(&c, curl, opts, phi);
                let mut score = 0.0;
                for k in 1..h.len() - 1 {
                    if let Some(t) = (h[k + 1] - h[k - 1]).try_normalize() {
                        score += support.support(h[k], t);
                    }
                }
                if score > 0.0 && best.is_none_or(|(s, _)| score > s) {
                    best = Some((score, phi));
                }
            }
            best.map(|b| b.1)
        })
        .collect()
}

/// A strand's centreline: the strand resampled every `step`, each sample replaced by the mean of the
/// samples within `window / 2` of arc on both sides (fewer near the ends; the root is kept), then
/// resampled every `step` again. A window of one turn of a round helix gives its axis exactly. `None`
/// for a strand shorter than three samples.
pub fn centreline(s: &[Vec3], window: f32, step: f32) -> Option<Vec<Vec3>> {
    let one = StrandSet::new(s.to_vec(), vec![s.len() as u32]).and_then(|x| x.resample_by_arclength(step)).ok()?;
    let r = one.points();
    if r.len() < 3 {
        return None;
    }
    let half = (window / step).round() as usize / 2;
    let n = r.len();
    let mut cs = vec![Vec3::ZERO; n + 1];
    for k in 0..n {
        cs[k + 1] = cs[k] + r[k];
    }
    let mut c: Vec<Vec3> = (0..n)
        .map(|k| {
            let h = half.min(k).min(n - 1 - k);
            (cs[k + h + 1] - cs[k - h]) / (2 * h + 1) as f32
        })
        .collect();
    c[0] = r[0];
    let c = StrandSet::new(c, vec![n as u32]).and_then(|x| x.resample_by_arclength(step)).ok()?;
    (c.num_points() >= 3).then(|| c.points().to_vec())
}

/// The helix about the centreline `c` (points every `opts.step` of arc).
fn helix_about(c: &[Vec3], curl: &Curl, opts: &CurlOptions, phi0: f32) -> Vec<Vec3> {
    let n = c.len();
    let tangent = |k: usize| {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (c[b] - c[a]).normalize_or_zero()
    };
    let t0 = tangent(0);
    let mut e1 = t0.cross(Vec3::Z);
    if e1.length() < 1e-6 {
        e1 = t0.cross(Vec3::X);
    }
    let mut e1 = e1.normalize_or_zero();
    let mut out = Vec::with_capacity(n);
    for (k, ck) in c.iter().enumerate() {
        let t = tangent(k);
        e1 = (e1 - t * t.dot(e1)).normalize_or(e1);
        let e2 = t.cross(e1);
        let s = k as f32 * opts.step;
        let x = if opts.ramp > 0.0 { (s / opts.ramp).min(1.0) } else { 1.0 };
        let r = curl.radius * x * x * (3.0 - 2.0 * x);
        let phi = phi0 + curl.hand * std::f32::consts::TAU * s / curl.period;
        out.push(*ck + (e1 * phi.cos() + e2 * phi.sin()) * r);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const CURL: Curl = Curl { radius: 0.0065, period: 0.022, hand: 1.0 };

    /// The plane `x = x` over `y` and `z` (metres), facing +x, in 5 mm quads.
    fn plane_facing_x(x: f32, y: [f32; 2], z: [f32; 2]) -> TriMesh {
        let ny = ((y[1] - y[0]) / 0.005).round() as usize + 1;
        let nz = ((z[1] - z[0]) / 0.005).round() as usize + 1;
        let vertices: Vec<Vec3> = (0..nz)
            .flat_map(|iz| (0..ny).map(move |iy| Vec3::new(x, y[0] + 0.005 * iy as f32, z[0] + 0.005 * iz as f32)))
            .collect();
        let mut triangles = Vec::new();
        for iz in 0..nz - 1 {
            for iy in 0..ny - 1 {
                let a = (iz * ny + iy) as u32;
                let (b, c, d) = (a + 1, a + ny as u32, a + ny as u32 + 1);
                triangles.push([a, b, c]);
                triangles.push([b, d, c]);
            }
        }
        TriMesh::new(vertices, triangles, None, None).unwrap()
    }

    /// A helix of `curl` about the z axis, downward from z = 0 (root to tip along -z).
    fn helix(curl: &Curl, len: f32, phi0: f32) -> Vec<Vec3> {
        let n = (len / 0.0005) as usize;
        (0..n)
            .map(|k| {
                let s = k as f32 * 0.0005; // metres of axis
                let phi = phi0 + curl.hand * std::f32::consts::TAU * s / curl.period;
                // Right-handed about the root-to-tip direction -z: (e1, e2) with e1 × e2 = -z.
                Vec3::new(curl.radius * phi.cos(), -curl.radius * phi.sin(), -s)
            })
            .collect()
    }

    #[test]
    fn curl_modes_parse_and_bad_ones_say_what_to_give() {
        assert_eq!("off".parse::<CurlMode>(), Ok(CurlMode::Off));
        assert_eq!("auto".parse::<CurlMode>(), Ok(CurlMode::Auto));
        assert_eq!(" 6.5, 22 ,1".parse::<CurlMode>(), Ok(CurlMode::Fixed(CURL)));
        assert!("6.5,22".parse::<CurlMode>().unwrap_err().contains("three numbers"));
        assert!("6.5,0,1".parse::<CurlMode>().unwrap_err().contains("period"));
        assert!("0,22,1".parse::<CurlMode>().unwrap_err().contains("radius"));
        assert!("6.5,22,0".parse::<CurlMode>().unwrap_err().contains("handedness"));
    }

    #[test]
    fn pitch_angle_of_the_paper_curls() {
        assert!((CURL.pitch_angle().to_degrees() - 61.7).abs() < 0.1);
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
    fn sweep_makes_a_helix_of_the_curl_about_a_straight_strand() {
        let line: Vec<Vec3> = (0..=100).map(|k| Vec3::new(0.0, 0.0, -0.002 * k as f32)).collect();
        let set = StrandSet::new(line, vec![101]).unwrap();
        let out = sweep_helices(&set, &CURL, &CurlOptions::default(), 7).unwrap();
        let h = out.strand(0);
        // Past the ramp: at the radius from the axis, and turning right-handed about -z by one turn
        // per period.
        let past: Vec<&Vec3> = h.iter().filter(|p| p.z < -0.03 && p.z > -0.17).collect();
        assert!(past.len() > 100);
        for p in &past {
            let r = (p.x * p.x + p.y * p.y).sqrt();
            assert!((r - CURL.radius).abs() < 2e-4, "radius {r}");
        }
        let ang = |p: &Vec3| p.y.atan2(p.x);
        let (a, b) = (past[0], past[5]);
        let mut turn = ang(b) - ang(a);
        while turn > std::f32::consts::PI {
            turn -= std::f32::consts::TAU;
        }
        while turn < -std::f32::consts::PI {
            turn += std::f32::consts::TAU;
        }
        // Right-handed about -z is clockwise seen from +z: the angle about +z decreases.
        let expected = -std::f32::consts::TAU * (a.z - b.z) / CURL.period;
        assert!((turn - expected).abs() < 0.05, "turned {turn}, expected {expected}");
        // The root stays where it was; same seed, same output.
        assert!(h[0].distance(Vec3::ZERO) < 1e-6);
        assert_eq!(sweep_helices(&set, &CURL, &CurlOptions::default(), 7).unwrap(), out);
    }

    #[test]
    fn fitted_phase_puts_the_helix_on_its_visible_side() {
        // A ringlet about a straight centreline along -z; the points: its side facing +x (x > 0.3 r)
        // with tangents. Fitting phases to them recovers the ringlet's own phase within one step of
        // the 16 tried; a strand on the far side of no points gets none.
        let line: Vec<Vec3> = (0..=100).map(|k| Vec3::new(0.0, 0.0, -0.002 * k as f32)).collect();
        let set = StrandSet::new(line.clone(), vec![101]).unwrap();
        let opts = CurlOptions::default();
        let c = centreline(&line, opts.centre_window, opts.step).unwrap();
        let truth = 2.0f32;
        let h = helix_about(&c, &CURL, &opts, truth);
        let (mut positions, mut directions) = (Vec::new(), Vec::new());
        for k in 1..h.len() - 1 {
            if h[k].x > 0.3 * CURL.radius {
                positions.push(h[k]);
                directions.push((h[k + 1] - h[k - 1]).normalize());
            }
        }
        let n = positions.len();
        let points = OrientedPoints { positions, directions, confidence: vec![1.0; n] };
        let support = PointSupport::new(&points, opts.fit_radius, opts.fit_angle_deg).unwrap();
        let far = StrandSet::new(line.iter().map(|p| *p + Vec3::new(0.5, 0.0, 0.0)).collect(), vec![101]).unwrap();
        let got = fit_phases(&set, &CURL, &opts, &support)[0].unwrap();
        let d = (got - truth).rem_euclid(std::f32::consts::TAU);
        let d = d.min(std::f32::consts::TAU - d);
        assert!(d <= std::f32::consts::TAU / 32.0 + 1e-4, "fitted {got}, truth {truth}");
        assert_eq!(fit_phases(&far, &CURL, &opts, &support), vec![None]);
        // Swept at the fitted phase, the helix lies on the points.
        let swept = sweep_helices_at(&set, &CURL, &opts, 0, Some(&[Some(got)])).unwrap();
        let on = points.positions.iter().filter(|q| swept.strand(0).iter().any(|p| p.distance(**q) < 1e-3)).count();
        assert_eq!(on, n);
    }

    #[test]
    fn hung_axes_point_down_and_keep_their_lines() {
        let d = [Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.0, 0.6, -0.8), Vec3::X];
        let mut axes =
            OrientedPoints { positions: vec![Vec3::ZERO; 3], directions: d.to_vec(), confidence: vec![1.0; 3] };
        hang(&mut axes);
        assert_eq!(axes.directions, vec![Vec3::new(-0.6, 0.0, -0.8), d[1], d[2]]);
    }

    /// A hair surface seen from the cameras: a piece of a cylinder (radius 0.1 m about the z axis,
    /// facing +y) corrugated along z with `period` (amplitude 1.5 mm) in 10 mm wide clumps, each at
    /// its own phase, with 0.3 mm of noise, every 0.5 mm; the axes all -z.
    fn corrugated(period: f32) -> (Vec<Vec3>, Vec<Vec3>) {
        let (mut pos, mut axes) = (Vec::new(), Vec::new());
        for i in 0..240 {
            let x = -0.06 + i as f32 * 0.0005;
            let clump = ((x + 0.06) / 0.010) as usize;
            for k in 0..200 {
                let z = -(k as f32) * 0.0005;
                let n = i * 200 + k;
                let noise = 0.0003 * (phase(7, n) / std::f32::consts::PI - 1.0);
                let bump = if period > 0.0 {
                    0.0015 * (std::f32::consts::TAU * z / period + phase(3, clump)).cos()
                } else {
                    0.0
                };
                let r = 0.1 + bump + noise;
                let a = x / 0.1;
                pos.push(Vec3::new(r * a.sin(), r * a.cos(), z));
                axes.push(-Vec3::Z);
            }
        }
        (pos, axes)
    }

    #[test]
    fn bumps_give_the_period_of_a_corrugated_surface_and_none_of_a_smooth_one() {
        let opts = BumpOptions { samples: 400, ..BumpOptions::default() };
        for period in [0.016f32, 0.022, 0.030] {
            let (pos, axes) = corrugated(period);
            let rep = bump_period(&pos, &axes, &opts);
            let got = rep.period.unwrap_or_else(|| panic!("no period found for {period}: {rep:?}"));
            assert!((got / period - 1.0).abs() < 0.05, "period {period}: got {got}");
            let m = rep.first_min.unwrap();
            assert!((m / (0.5 * period) - 1.0).abs() < 0.15, "period {period}: first minimum at {m}");
        }
        let (pos, axes) = corrugated(0.0);
        let rep = bump_period(&pos, &axes, &opts);
        assert_eq!(rep.period, None, "{:?}", rep.correlation);
        assert!(rep.samples > 300, "{}", rep.samples);
    }
}
