//! Stage 5a: the interior flow of the hair volume by Laplace's equation.
//!
//! In: the raw mesh (outer hair surface, a BVH), the head (or scalp) mesh as the inner surface,
//! the directed points of [`crate::direction`] and the [`Scalp`] with S(p_s). Out: a [`FlowField`]
//! on a voxel grid: a unit 3-vector per voxel of the hair volume, with the signed distances to the
//! outer and inner surfaces that growing needs; saved as `flow.bin` and reloaded from there.
//!
//! Follows Dr.Hair's strand initialization (`docs/method.md` §3): the hair volume is the voxels
//! inside the raw mesh (up to `outer_margin` outside it, at most `band` inside it), outside the head,
//! and within `max_point_dist` of a directed point or `scalp_dist` of the scalp (so the face and
//! the neck are not hair); Dirichlet conditions
//! are the confidence-weighted mean direction of the directed points in a voxel, and S(p_s) at the
//! voxels within one voxel of the scalp; every other voxel of the volume satisfies the discrete
//! Laplace equation (6-neighbour graph Laplacian, zero flux across the volume's boundary). The three
//! components are solved together by matrix-free conjugate gradients (a tiny diagonal shift keeps
//! voxels cut off from every condition well posed), then normalised.

use std::io::Read;
use std::path::Path;

use glam::Vec3;
use hairrecon_core::Bvh;
use rayon::prelude::*;

use crate::points3d::{OrientedPoints, PointsError};
use crate::progress::{Cancelled, Progress};
use crate::roots::{scalp_point, Scalp};
use hairrecon_core::spatial::PointIndex;

/// A regular grid: voxel centres at `origin + voxel * (i, j, k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    pub origin: Vec3,
    pub voxel: f32,
    pub dims: [usize; 3],
}

impl Grid {
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    #[inline]
    pub fn centre(&self, idx: usize) -> Vec3 {
        let i = idx % self.dims[0];
        let j = (idx / self.dims[0]) % self.dims[1];
        let k = idx / (self.dims[0] * self.dims[1]);
        self.origin + self.voxel * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// The voxel containing `p` (nearest centre), if inside the grid.
    #[inline]
    pub fn voxel_of(&self, p: Vec3) -> Option<usize> {
        let q = ((p - self.origin) / self.voxel + 0.5).floor();
        if q.x < 0.0 || q.y < 0.0 || q.z < 0.0 {
            return None;
        }
        let (i, j, k) = (q.x as usize, q.y as usize, q.z as usize);
        if i >= self.dims[0] || j >= self.dims[1] || k >= self.dims[2] {
            return None;
        }
        Some(self.index(i, j, k))
    }

    /// Trilinear interpolation of a per-voxel value; `None` outside the grid.
    #[inline]
    pub fn trilinear<T>(&self, values: &[T], p: Vec3) -> Option<T>
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let q = (p - self.origin) / self.voxel;
        let f = q.floor();
        if f.x < 0.0 || f.y < 0.0 || f.z < 0.0 {
            return None;
        }
        let (i, j, k) = (f.x as usize, f.y as usize, f.z as usize);
        if i + 1 >= self.dims[0] || j + 1 >= self.dims[1] || k + 1 >= self.dims[2] {
            return None;
        }
        let t = q - f;
        let v = |a: usize, b: usize, c: usize| values[self.index(i + a, j + b, k + c)];
        let lx = |b: usize, c: usize| v(0, b, c) * (1.0 - t.x) + v(1, b, c) * t.x;
        let ly = |c: usize| lx(0, c) * (1.0 - t.y) + lx(1, c) * t.y;
        Some(ly(0) * (1.0 - t.z) + ly(1) * t.z)
    }

    /// The eight voxels [`Grid::trilinear`] reads at `p` (none outside the grid).
    pub fn stencil(&self, p: Vec3) -> impl Iterator<Item = usize> + '_ {
        let f = ((p - self.origin) / self.voxel).floor();
        let inside = f.x >= 0.0
            && f.y >= 0.0
            && f.z >= 0.0
            && (f.x as usize) + 1 < self.dims[0]
            && (f.y as usize) + 1 < self.dims[1]
            && (f.z as usize) + 1 < self.dims[2];
        let (i, j, k) = (f.x as usize, f.y as usize, f.z as usize);
        (0..if inside { 8 } else { 0 }).map(move |c| self.index(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)))
    }
}

/// Parameters of the volume and the solve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LaplaceParams {
    /// Voxel edge, metres.
    pub voxel: f32,
    /// Voxels up to this far outside the raw mesh belong to the hair volume, metres.
    pub outer_margin: f32,
    /// Voxels farther than this from every directed point are not hair (face, neck, bald scalp),
    /// metres.
    pub max_point_dist: f32,
    /// Voxels this close to the scalp are hair even far from the points, metres.
    pub scalp_dist: f32,
    /// Voxels farther than this from the raw mesh are never hair, metres.
    pub band: f32,
    pub max_iterations: usize,
    /// Relative residual at which CG stops.
    pub tolerance: f32,
    /// How much of S(p_s)'s normal component the scalp condition drops, in [0, 1]: hair leaves the
    /// pore along S but lies along the head a few millimetres above it, and a voxel next to the
    /// scalp is 4 mm thick; 0 keeps S itself, 1 keeps only its tangential part.
    pub scalp_tangent: f32,
    /// Weight of a prior that pulls every free voxel toward straight down (−Z), relative to the
    /// weight 1 of each neighbour: a screened Laplace equation. Far from every directed point the
    /// plain harmonic field is free to circle (the hair hanging below the head, between its outer
    /// layers, has no condition at all) and strands grown through it loop; the prior fades such a
    /// region into gravity over about 1/√gravity voxels and barely moves the field near a point.
    /// Off by default: on the paper preset (straight) 0.003–0.1 moved the init F1 by under one
    /// point (the init stage alone on saved directed points, measured at commit 0b98fa8); the loops
    /// sit where the points are.
    pub gravity: f32,
    /// Pairs of Taubin smoothing steps (λ = 0.5, μ = −0.53, uniform weights) applied to a copy of
    /// the raw mesh before its signed distance bounds the hair volume and the growth. A
    /// photogrammetry mesh with vertex noise near its edge length is crumpled: half a millimetre
    /// of noise on the 0.8 mm triangles of a synthetic capture's mesh folded 46 % of its edges, and
    /// guides grew to 0.24 m on average instead of 0.35 m; five pairs gave back 0.36 m (and the
    /// initial strands' F1 at 2 mm/20°, 48.7 → 49.5 against 50.1 on the clean mesh). The flow
    /// needs the hair's envelope at the voxel's scale, which smoothing keeps; the other stages
    /// (the points' depth test, the curl's bumps, scoring) read the raw mesh as given. 0 = none.
    #[serde(default = "default_outer_smoothing")]
    pub outer_smoothing: u32,
    /// Hair that stands off the head: the voxels whose cells the segment from a directed point
    /// down to its nearest scalp point (within `band`) passes are hair too, when that segment
    /// leaves the scalp within this many degrees of its normal (the point lies above the scalp,
    /// not beside it; 0: off, the default). Without it, a layer thicker than `scalp_dist +
    /// max_point_dist` has a hole in its middle where growth ends. Measured on the code of commit
    /// 2f6e1d5 (the init stage alone, undirected F1 at 2 mm/20°, off → 30°): the generator's
    /// volume style (colours preset, seed 2) with a raw mesh fused as the hair's envelope, where
    /// the hair stands 2–4 cm off the crown, 29.9 → 41.7 (guides ending in the hole 1413 → 1269 of
    /// 2000, mean length 10.2 → 12.4 cm); the straight test capture 63.4 → 62.4
    /// (research/notes/volume-study.md). Off until the benchmark's styles are measured with it.
    #[serde(default)]
    pub column_angle_deg: f32,
    /// Take-off where the hair stands off the head: where the raw mesh lies more than this above
    /// the scalp (metres, along the scalp's normal), the scalp condition turns from S(p_s) toward
    /// the normal, all the way at twice this height (0: off, the default). The flow between the
    /// scalp and the seen hair is harmonic, so a strand rises at the rate the scalp condition
    /// gives it, falling to none at the seen hair; S(p_s) leans up to 60° from the normal, and
    /// where the hair stands 2–4 cm off the crown the guides rose about half as fast as the
    /// ground truth's (9 mm above the head after 2 cm of arc, the ground truth 19 mm) and ended in
    /// the gap under the hair hanging behind the head. Measured on the code of commit 2f6e1d5 with
    /// 0.01 (as for [`LaplaceParams::column_angle_deg`], off → on): the volume style with columns
    /// 41.7 → 58.3 (its guides rooted on the crown 13 mm above the head after 2 cm of arc, their
    /// median length 16 → 45 cm against the ground truth's 31), without columns 29.9 → 41.3; the
    /// same style with the renderer's raw mesh (which lies on the scalp over the crown) with
    /// columns 57.2 → 58.2; straight hair (colours preset, seed 2) 87.2 → 87.0, with columns 86.7;
    /// the straight test capture 63.4 → 63.3, with columns 62.7.
    #[serde(default)]
    pub scalp_lift: f32,
}

fn default_outer_smoothing() -> u32 {
    5
}

impl Default for LaplaceParams {
    fn default() -> Self {
        Self {
            voxel: 0.003,
            outer_margin: 0.004,
            max_point_dist: 0.015,
            scalp_dist: 0.012,
            band: 0.04,
            max_iterations: 400,
            tolerance: 1e-4,
            scalp_tangent: 0.0,
            gravity: 0.0,
            outer_smoothing: default_outer_smoothing(),
            column_angle_deg: 0.0,
            scalp_lift: 0.0,
        }
    }
}

/// The solved flow and the distances growing needs.
#[derive(Debug, Clone, PartialEq)]
pub struct FlowField {
    pub grid: Grid,
    /// Unit direction per voxel (zero outside the hair volume where nothing reached).
    pub field: Vec<Vec3>,
    /// Signed distance to the raw mesh (negative inside), metres.
    pub sd_outer: Vec<f32>,
    /// Signed distance to the head/scalp (negative inside the head), metres.
    pub sd_inner: Vec<f32>,
    /// 1 for voxels of the hair volume, 2 for constrained ones, 0 elsewhere.
    pub label: Vec<u8>,
}

/// Statistics of a solve.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LaplaceStats {
    pub voxels: u64,
    pub volume_voxels: u64,
    pub point_constraints: u64,
    pub scalp_constraints: u64,
    pub iterations: u64,
    pub residual: f32,
}

/// The voxels of the hair volume's `label` whose cells a segment from a directed point down to its
/// nearest scalp point passes (the voxels growth's trilinear reads there use) within `band`, where that segment leaves the scalp within `max_angle_deg`
/// of its normal (see [`LaplaceParams::column_angle_deg`]).
fn columns(
    grid: &Grid,
    scalp: &Scalp,
    points: &OrientedPoints,
    label: &[u8],
    band: f32,
    max_angle_deg: f32,
) -> Vec<bool> {
    let mut column = vec![false; label.len()];
    if max_angle_deg <= 0.0 {
        return column;
    }
    let min_cos = max_angle_deg.to_radians().cos();
    let step = 0.5 * grid.voxel;
    let marked: Vec<usize> = points
        .positions
        .par_iter()
        .flat_map_iter(|&p| {
            let seg = scalp_point(scalp, p, band).and_then(|sp| {
                let v = p - sp.point;
                let len = v.length();
                (len > step && v.dot(sp.normal) >= min_cos * len).then_some((sp.point, v, len))
            });
            seg.into_iter().flat_map(move |(a, v, len)| {
                let k = (len / step).ceil() as usize;
                (0..=k).flat_map(move |j| grid.stencil(a + v * (j as f32 / k as f32)))
            })
        })
        .filter(|&v| label[v] == 1)
        .collect();
    for v in marked {
        column[v] = true;
    }
    column
}

/// The scalp condition `growth` at the scalp point `point` (outward unit `normal`), turned toward
/// the normal where the raw mesh lies more than [`LaplaceParams::scalp_lift`] above it along the
/// normal (unchanged when the lift is off). The guides' roots keep S(p_s) as their first step:
/// lifting those too (on the code of commit 2f6e1d5, the volume capture of the lift's figures) gave
/// 57.8 against 58.3.
fn lifted(raw: &Bvh, point: Vec3, normal: Vec3, growth: Vec3, lift: f32, band: f32) -> Vec3 {
    if lift <= 0.0 {
        return growth;
    }
    // The layer's thickness: from the scalp along its normal to the raw mesh (up to `band`).
    let h = raw.ray_cast(point + normal * 1e-4, normal, 0.0, band).map_or(0.0, |hit| hit.t);
    let w = ((h - lift) / lift).clamp(0.0, 1.0);
    (growth * (1.0 - w) + normal * w).normalize_or(growth)
}

/// Builds the hair volume and solves the flow.
pub fn solve_flow(
    raw: &Bvh,
    inner: &Bvh,
    scalp: &Scalp,
    points: &OrientedPoints,
    params: &LaplaceParams,
    progress: &dyn Progress,
) -> Result<(FlowField, LaplaceStats), Cancelled> {
    let (lo, hi) = raw.mesh().bbox();
    let pad = 2.0 * params.voxel + params.outer_margin;
    let origin = lo - Vec3::splat(pad);
    let ext = hi + Vec3::splat(pad) - origin;
    let dims = [
        (ext.x / params.voxel).ceil() as usize + 1,
        (ext.y / params.voxel).ceil() as usize + 1,
        (ext.z / params.voxel).ceil() as usize + 1,
    ];
    let grid = Grid { origin, voxel: params.voxel, dims };
    let n = grid.len();
    let mut stats = LaplaceStats { voxels: n as u64, ..Default::default() };
    // Signed distances, slab by slab (cancellable).
    let slab = dims[0] * dims[1];
    let mut sd_outer = vec![0.0f32; n];
    let mut sd_inner = vec![0.0f32; n];
    // Only voxels within `band` of the raw mesh can be hair; the rest are marked far outside.
    let band = params.band.max(2.0 * params.voxel);
    for k in 0..dims[2] {
        progress.check()?;
        progress.update("init", 0.4 * k as f32 / dims[2] as f32, "distances");
        let r = k * slab..(k + 1) * slab;
        // Row by row along x, each query bounded by the last voxel's distance plus the step (a
        // distance changes by at most the step between neighbours): the same closest points, with
        // fewer of the BVH's nodes opened.
        let step_bound =
            |last: Option<(f32, u32)>| last.map_or(f32::INFINITY, |(d, _)| (d.abs() + params.voxel) * 1.001 + 1e-6);
        sd_outer[r.clone()]
            .par_chunks_mut(dims[0])
            .zip(sd_inner[r.clone()].par_chunks_mut(dims[0]))
            .enumerate()
            .for_each(|(j, (row_outer, row_inner))| {
                // The last voxel's (signed distance, closest triangle): the triangle starts the next
                // query (the same results, fewer nodes).
                let (mut last_outer, mut last_inner) = (None, None);
                for (i, (so, si)) in row_outer.iter_mut().zip(row_inner.iter_mut()).enumerate() {
                    let p = grid.centre(grid.index(i, j, k));
                    last_outer =
                        raw.signed_distance_near(p, band.min(step_bound(last_outer)), last_outer.map(|(_, t)| t));
                    *so = last_outer.map_or(band, |(d, _)| d);
                    // Beyond the outer margin the value only serves growing's push-out, far from the head.
                    let reach = if *so <= params.outer_margin { f32::INFINITY } else { band };
                    last_inner =
                        inner.signed_distance_near(p, reach.min(step_bound(last_inner)), last_inner.map(|(_, t)| t));
                    *si = last_inner.map_or(band, |(d, _)| d);
                }
            });
    }
    // Labels: inside the raw mesh, outside the head, near the seen hair or the scalp.
    let mut label = vec![0u8; n];
    for i in 0..n {
        if sd_outer[i] <= params.outer_margin && sd_inner[i] >= -0.5 * params.voxel {
            label[i] = 1;
        }
    }
    progress.check()?;
    let column = columns(&grid, scalp, points, &label, band, params.column_angle_deg);
    let index = PointIndex::new(points.positions.clone(), points.directions.clone());
    let not_hair: Vec<usize> = (0..n)
        .into_par_iter()
        .filter(|&i| label[i] == 1 && !column[i])
        .filter(|&i| {
            let c = grid.centre(i);
            index.nearest(c, 1).first().is_none_or(|&(_, d)| d > params.max_point_dist)
                && scalp.bvh().closest_point(c, params.scalp_dist).is_none()
        })
        .collect();
    for i in not_hair {
        label[i] = 0;
    }
    stats.volume_voxels = label.iter().filter(|l| **l > 0).count() as u64;
    let mut fixed = vec![Vec3::ZERO; n];
    let mut wsum = vec![0.0f32; n];
    for i in 0..points.len() {
        if let Some(v) = grid.voxel_of(points.positions[i]) {
            if label[v] > 0 {
                let w = points.confidence[i].max(1e-3);
                fixed[v] += points.directions[i] * w;
                wsum[v] += w;
            }
        }
    }
    for i in 0..n {
        if wsum[i] > 0.0 {
            fixed[i] = fixed[i].normalize_or_zero();
            if fixed[i] != Vec3::ZERO {
                label[i] = 2;
                stats.point_constraints += 1;
            }
        }
    }
    progress.check()?;
    let scalp_fixed: Vec<(usize, Vec3)> = (0..n)
        .into_par_iter()
        .filter(|&i| label[i] == 1)
        .filter_map(|i| {
            let sp = scalp_point(scalp, grid.centre(i), params.voxel)?;
            let g = sp.growth - sp.normal * (sp.growth.dot(sp.normal) * params.scalp_tangent.clamp(0.0, 1.0));
            Some((i, lifted(raw, sp.point, sp.normal, g.normalize_or(sp.growth), params.scalp_lift, band)))
        })
        .collect();
    for (i, g) in scalp_fixed {
        fixed[i] = g;
        label[i] = 2;
        stats.scalp_constraints += 1;
    }
    // Free unknowns.
    let free: Vec<usize> = (0..n).filter(|&i| label[i] == 1).collect();
    let mut slot = vec![u32::MAX; n];
    for (s, &i) in free.iter().enumerate() {
        slot[i] = s as u32;
    }
    let strides = [1isize, dims[0] as isize, slab as isize];
    let nb_of = |i: usize| -> [Option<usize>; 6] {
        let c = [i % dims[0], (i / dims[0]) % dims[1], i / slab];
        let mut out = [None; 6];
        for a in 0..3 {
            if c[a] > 0 {
                out[2 * a] = Some((i as isize - strides[a]) as usize);
            }
            if c[a] + 1 < dims[a] {
                out[2 * a + 1] = Some((i as isize + strides[a]) as usize);
            }
        }
        out
    };
    // Per free voxel: degree, and rhs from fixed neighbours.
    let eps = 1e-4f32;
    let (deg, rhs): (Vec<f32>, Vec<Vec3>) = free
        .par_iter()
        .map(|&i| {
            let g = params.gravity.max(0.0);
            let mut d = eps + g;
            let mut b = Vec3::NEG_Z * g;
            for j in nb_of(i).into_iter().flatten() {
                match label[j] {
                    1 => d += 1.0,
                    2 => {
                        d += 1.0;
                        b += fixed[j];
                    }
                    _ => {}
                }
            }
            (d, b)
        })
        .unzip();
    let apply = |x: &[Vec3], out: &mut [Vec3]| {
        out.par_iter_mut().enumerate().for_each(|(s, o)| {
            let i = free[s];
            let mut acc = x[s] * deg[s];
            for j in nb_of(i).into_iter().flatten() {
                let t = slot[j];
                if t != u32::MAX {
                    acc -= x[t as usize];
                }
            }
            *o = acc;
        });
    };
    // Fixed chunks summed in order: the same sums whatever the thread count or schedule.
    let dot3 = |a: &[Vec3], b: &[Vec3]| -> Vec3 {
        let parts: Vec<Vec3> = a
            .par_chunks(4096)
            .zip(b.par_chunks(4096))
            .map(|(a, b)| a.iter().zip(b).fold(Vec3::ZERO, |acc, (x, y)| acc + *x * *y))
            .collect();
        parts.into_iter().fold(Vec3::ZERO, |acc, p| acc + p)
    };
    // Jacobi-preconditioned CG, the three components at once.
    let m = free.len();
    let mut x = vec![Vec3::ZERO; m];
    let mut r = rhs.clone();
    let mut z: Vec<Vec3> = r.iter().zip(&deg).map(|(r, d)| *r / *d).collect();
    let mut p = z.clone();
    let mut ap = vec![Vec3::ZERO; m];
    let mut rz = dot3(&r, &z);
    let b_norm = dot3(&rhs, &rhs).max_element().sqrt().max(1e-20);
    for it in 0..params.max_iterations {
        if it % 20 == 0 {
            progress.check()?;
            progress.update("init", 0.4 + 0.4 * it as f32 / params.max_iterations as f32, "Laplace");
        }
        apply(&p, &mut ap);
        let pap = dot3(&p, &ap);
        let alpha = Vec3::select(pap.cmpgt(Vec3::splat(1e-30)), rz / pap, Vec3::ZERO);
        x.par_iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * *p);
        r.par_iter_mut().zip(&ap).for_each(|(r, ap)| *r -= alpha * *ap);
        let res = dot3(&r, &r).max_element().sqrt() / b_norm;
        stats.iterations = it as u64 + 1;
        stats.residual = res;
        if res < params.tolerance {
            break;
        }
        z.par_iter_mut().zip(&r).zip(&deg).for_each(|((z, r), d)| *z = *r / *d);
        let rz_new = dot3(&r, &z);
        let beta = Vec3::select(rz.cmpgt(Vec3::splat(1e-30)), rz_new / rz, Vec3::ZERO);
        rz = rz_new;
        p.par_iter_mut().zip(&z).for_each(|(p, z)| *p = *z + beta * *p);
    }
    let mut field = vec![Vec3::ZERO; n];
    for i in 0..n {
        if label[i] == 2 {
            field[i] = fixed[i];
        }
    }
    for (s, &i) in free.iter().enumerate() {
        field[i] = x[s].normalize_or_zero();
    }
    Ok((FlowField { grid, field, sd_outer, sd_inner, label }, stats))
}

impl FlowField {
    /// Writes the field: a small header then little-endian arrays.
    pub fn save(&self, path: &Path) -> Result<(), PointsError> {
        let mut buf = Vec::with_capacity(self.grid.len() * 21 + 64);
        buf.extend_from_slice(b"HRFLOW01");
        for d in self.grid.dims {
            buf.extend_from_slice(&(d as u64).to_le_bytes());
        }
        for v in [self.grid.origin.x, self.grid.origin.y, self.grid.origin.z, self.grid.voxel] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        for i in 0..self.grid.len() {
            let f = self.field[i];
            for v in [f.x, f.y, f.z, self.sd_outer[i], self.sd_inner[i]] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            buf.push(self.label[i]);
        }
        crate::oriented_points::write_atomically(path, &[&buf])
    }

    /// Reads a field written by [`FlowField::save`].
    pub fn load(path: &Path) -> Result<Self, PointsError> {
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|source| PointsError::Read { path: path.into(), source })?;
        let ferr = |msg: &str| PointsError::Format { path: path.into(), msg: msg.into() };
        if bytes.len() < 48 || &bytes[..8] != b"HRFLOW01" {
            return Err(ferr("not a hairrecon flow file"));
        }
        let u = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap_or([0; 8])) as usize;
        let f = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]));
        let dims = [u(8), u(16), u(24)];
        let grid = Grid { origin: Vec3::new(f(32), f(36), f(40)), voxel: f(44), dims };
        let n = grid.len();
        if bytes.len() != 48 + n * 21 {
            return Err(ferr("truncated"));
        }
        let mut out = FlowField {
            grid,
            field: Vec::with_capacity(n),
            sd_outer: Vec::with_capacity(n),
            sd_inner: Vec::with_capacity(n),
            label: Vec::with_capacity(n),
        };
        for i in 0..n {
            let o = 48 + i * 21;
            out.field.push(Vec3::new(f(o), f(o + 4), f(o + 8)));
            out.sd_outer.push(f(o + 12));
            out.sd_inner.push(f(o + 16));
            out.label.push(bytes[o + 20]);
        }
        Ok(out)
    }
}
