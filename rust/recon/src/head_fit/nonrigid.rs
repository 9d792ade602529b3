//! Head fitting, second part: the subject's own head shape. After the similarity
//! ([`super::fit_similarity`]) the template is the right size and pose but keeps its own
//! proportions; a real head differs by several per cent per axis and by bumps of a centimetre.
//!
//! The deformation is a smooth displacement field over the canonical frame,
//! `u(p) = B (p − c) + t + Σₖ φ(|p − gₖ|) aₖ`: an affine part (a head's anisotropic proportions
//! cost nothing to bend) plus compactly supported radial bumps (Wendland's C² function, positive
//! definite in 3D) at nodes `gₖ` spread over the template. Its roughness is the bumps' native
//! norm `Σₖₗ φ(|gₖ − gₗ|) aₖ·aₗ`; where there is no data (the scalp under hair) the bumps die
//! out and the affine part carries on, so the fitted face, ears and neck decide how the skull under
//! the hair is scaled. Each step matches the deformed template's samples to the raw mesh and solves
//! the linear least-squares problem for `(B, t, a)` in closed form (normal equations, Cholesky);
//! the stiffness falls over the steps (coarse to fine, as in Amberg et al., "Optimal step
//! nonrigid ICP algorithms for surface registration", CVPR 2007).
//!
//! What counts as data, since hair covers skin and a capture has holes:
//! - skin (face, ears, neck): point-to-plane distance to the closest raw point when it lies within
//!   a gate that narrows over the steps and the surfaces face the same way; a point the raw surface
//!   covers by more than the gate (hair over an ear, a collar) is left out;
//! - scalp: hair covers it, so the raw mesh is an outer bound, not a target. A scalp point outside
//!   the raw surface (the template pokes through the hair) is pulled onto it; one inside follows
//!   the field. Pulling covered points out onto the hair would inflate the head step by step, each
//!   step bringing more of the scalp near the hair's surface. Only when, after that fit, most of
//!   the scalp ([`DeformOptions::bald_fraction`]) or of its border with the skin
//!   ([`DeformOptions::bald_border_fraction`]) lies on the raw surface (a bald or shaved head),
//!   the levels run again with the scalp fitted as skin is. The border tells a bald crown of other
//!   proportions from hair: on a bald head the skin runs on over the scalp's edge, under hair the
//!   raw surface steps out there by the hair's thickness;
//! - only the nearest [`DeformOptions::keep`] share of the matches counts; the farthest are
//!   trimmed (holes, a backdrop). A bald head's second pass keeps them all
//!   ([`DeformOptions::bald_keep`]): there the farthest matches are the bumps it has to reach.

use glam::{DMat3, DVec3};
use hairrecon_core::TriMesh;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::icp::Target;
use super::template::{sample_surface_normals, scalp_triangles};

/// The parameters of [`fit_deformation`]. Lengths in metres (the canonical frame).
#[derive(Debug, Clone, PartialEq)]
pub struct DeformOptions {
    /// The spacing of the bumps' nodes over the template.
    pub node_spacing: f64,
    /// The radius of each bump's support.
    pub support: f64,
    /// Skin sample points (face, ears, neck).
    pub skin_samples: usize,
    /// Scalp sample points.
    pub scalp_samples: usize,
    /// The stiffness (weight of the bumps' roughness against the mean squared distance, m²) of
    /// each level, from stiff to supple. The first levels leave the bumps almost no freedom, so that
    /// the affine part takes the head's proportions before the bumps bend it locally.
    pub stiffness: Vec<f64>,
    /// Steps per stiffness level.
    pub steps_per_level: usize,
    /// The weight of the affine part's departure from the identity (`|B|²`).
    pub affine_weight: f64,
    /// The skin's gate at the first and the last level: matches farther are left out.
    pub skin_gate: (f64, f64),
    /// The same on a bald head (the second pass), skin and scalp: with no hair over the skin a
    /// wider gate is safe, and it reaches bumps the first pass could not.
    pub bald_skin_gate: (f64, f64),
    /// A scalp point within this of the raw surface (either side) is on it.
    pub bald_gate: f64,
    /// With this share of the scalp on the raw surface after the first fit, the head is taken as
    /// bald (its scalp seen) and fitted again with the scalp as skin.
    pub bald_fraction: f64,
    /// The scalp's border: its samples within this of a skin sample.
    pub border_width: f64,
    /// With this share of the scalp's border on the raw surface after the first fit, the head is
    /// taken as bald as well.
    pub bald_border_fraction: f64,
    /// A point outside the raw surface is pulled in from at most this far.
    pub outside_gate: f64,
    /// The share of the matches kept (the rest, the farthest, are trimmed).
    pub keep: f64,
    /// The same on a bald head (the second pass): the skin is seen everywhere, and the farthest
    /// matches are where the head differs most from the template, so none is trimmed.
    pub bald_keep: f64,
    /// Matches whose raw normal turns from the template's by more than acos of this are left out.
    pub min_cos: f64,
    /// Matches whose offset from the raw point turns from the raw normal by more than acos of this
    /// are left out (the raw point lies on a rim, not under the sample).
    pub min_cos_offset: f64,
    /// The weight of the point-to-point distance beside the point-to-plane one (keeps points from
    /// sliding along the surface where the field has freedom).
    pub point_weight: f64,
}

impl Default for DeformOptions {
    fn default() -> Self {
        Self {
            node_spacing: 0.02,
            support: 0.05,
            skin_samples: 4000,
            scalp_samples: 2000,
            stiffness: vec![1.0, 0.1, 1e-2, 1e-3, 1e-4, 1e-5],
            steps_per_level: 5,
            affine_weight: 1e-6,
            skin_gate: (0.003, 0.002),
            bald_skin_gate: (0.012, 0.003),
            bald_gate: 0.005,
            bald_fraction: 0.5,
            border_width: 0.02,
            bald_border_fraction: 0.4,
            outside_gate: 0.015,
            keep: 0.9,
            bald_keep: 1.0,
            min_cos: 0.5,
            min_cos_offset: 0.8,
            point_weight: 0.1,
        }
    }
}

/// A fitted displacement field (canonical frame, metres).
#[derive(Debug, Clone)]
pub struct Deformation {
    centre: DVec3,
    affine: DMat3,
    shift: DVec3,
    nodes: Vec<DVec3>,
    weights: Vec<DVec3>,
    support: f64,
}

/// Wendland's C² function with support 1: `(1 − r)⁴ (4r + 1)`.
#[inline]
fn wendland(r: f64) -> f64 {
    if r >= 1.0 {
        0.0
    } else {
        let s = 1.0 - r;
        let s2 = s * s;
        s2 * s2 * (4.0 * r + 1.0)
    }
}

impl Deformation {
    /// The displacement at `p`.
    pub fn displacement(&self, p: DVec3) -> DVec3 {
        let mut u = self.affine * (p - self.centre) + self.shift;
        for (g, a) in self.nodes.iter().zip(&self.weights) {
            let phi = wendland((p - *g).length() / self.support);
            if phi > 0.0 {
                u += phi * *a;
            }
        }
        u
    }

    /// `p` moved by the field.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        p + self.displacement(p)
    }

    /// A mesh moved by the field; a mesh with vertex normals gets its moved surface's.
    pub fn mesh(&self, m: &TriMesh) -> TriMesh {
        let vertices = m.vertices.par_iter().map(|v| self.apply(v.as_dvec3()).as_vec3()).collect();
        let mut out = TriMesh { vertices, triangles: m.triangles.clone(), normals: None, uvs: m.uvs.clone() };
        if m.normals.is_some() {
            out.normals = Some(out.compute_vertex_normals());
        }
        out
    }

    /// The largest displacement over `points`.
    pub fn max_displacement(&self, points: &[DVec3]) -> f64 {
        points.iter().map(|&p| self.displacement(p).length()).fold(0.0, f64::max)
    }

    /// The affine part's axis scales (the singular values of `I + B`).
    pub fn axis_scales(&self) -> [f64; 3] {
        let m = DMat3::IDENTITY + self.affine;
        let mm = nalgebra::Matrix3::from_fn(|r, c| m.col(c)[r]);
        let mut s: Vec<f64> = mm.singular_values().iter().copied().collect();
        s.sort_by(f64::total_cmp);
        [s[0], s[1], s[2]]
    }
}

/// A template sample: its place, outward normal, whether it is scalp (and on the scalp's border
/// with the skin), and the nodes whose bumps reach it with their values there.
struct Sample {
    p: DVec3,
    n: DVec3,
    scalp: bool,
    border: bool,
    bumps: Vec<(u32, f64)>,
}

/// Nodes spread over `mesh`'s vertices at least `spacing` apart (greedy, in vertex order on a grid
/// of cells: deterministic).
fn spread_nodes(meshes: &[&TriMesh], spacing: f64) -> Vec<DVec3> {
    let mut cells: std::collections::HashMap<[i64; 3], Vec<DVec3>> = std::collections::HashMap::new();
    let cell = |p: DVec3| (p / spacing).floor().as_i64vec3().to_array();
    let mut nodes = Vec::new();
    for m in meshes {
        for v in &m.vertices {
            let p = v.as_dvec3();
            let c = cell(p);
            let near = (-1..=1).any(|i| {
                (-1..=1).any(|j| {
                    (-1..=1).any(|k| {
                        cells
                            .get(&[c[0] + i, c[1] + j, c[2] + k])
                            .is_some_and(|ps| ps.iter().any(|q| q.distance(p) < spacing))
                    })
                })
            });
            if !near {
                cells.entry(c).or_default().push(p);
                nodes.push(p);
            }
        }
    }
    nodes
}

/// What [`fit_deformation`] reports beside the field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeformReport {
    /// The RMS point-to-plane distance of the kept skin matches at the last step (m).
    pub skin_rms: f64,
    /// The share of skin samples matched at the last step.
    pub skin_matched: f64,
    /// The share of scalp samples fitted to the raw surface at the last step.
    pub scalp_matched: f64,
    /// The share of scalp samples on the raw surface after the first fit ([`DeformOptions::bald_gate`]).
    pub scalp_on_surface: f64,
    /// The same share of the scalp's border samples ([`DeformOptions::border_width`]).
    pub border_on_surface: f64,
    /// Whether the scalp was fitted as skin (a bald head).
    pub bald: bool,
    /// The largest displacement of a template sample (m).
    pub max_displacement: f64,
}

/// Fits the displacement field that takes the template (`head`, with its `scalp` triangles, both
/// in the canonical frame after the similarity) onto `raw` (the raw surface in the canonical
/// frame). Deterministic.
pub fn fit_deformation(
    head: &TriMesh,
    scalp: &TriMesh,
    raw: &(impl Target + ?Sized),
    opts: &DeformOptions,
) -> (Deformation, DeformReport) {
    let on_scalp = scalp_triangles(head, scalp);
    let skin = sample_surface_normals(head, |i| !on_scalp[i], opts.skin_samples, 0x5eed_5c1e);
    let top = sample_surface_normals(scalp, |_| true, opts.scalp_samples, 0x5eed_5ca1);
    let nodes = spread_nodes(&[head, scalp], opts.node_spacing);
    let centre = if head.vertices.is_empty() {
        DVec3::ZERO
    } else {
        head.vertices.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / head.vertices.len() as f64
    };
    let rho = opts.support;
    let bumps_at = |p: DVec3| -> Vec<(u32, f64)> {
        nodes
            .iter()
            .enumerate()
            .filter_map(|(k, g)| {
                let phi = wendland(g.distance(p) / rho);
                (phi > 0.0).then_some((k as u32, phi))
            })
            .collect()
    };
    let skin_points: Vec<DVec3> = skin.iter().map(|s| s.0).collect();
    let near_skin = |p: DVec3| skin_points.iter().any(|q| q.distance_squared(p) < opts.border_width.powi(2));
    let samples: Vec<Sample> = skin
        .iter()
        .map(|&s| (s, false))
        .chain(top.into_iter().map(|s| (s, true)))
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|((p, n), scalp)| Sample { p, n, scalp, border: scalp && near_skin(p), bumps: bumps_at(p) })
        .collect();
    let k = nodes.len();
    let dim = 12 + 3 * k;
    // The bumps' Gram matrix (their roughness), sparse by the support.
    let gram: Vec<(usize, usize, f64)> = (0..k)
        .flat_map(|i| {
            let nodes = &nodes;
            (0..k).filter_map(move |j| {
                let phi = wendland(nodes[i].distance(nodes[j]) / rho);
                (phi > 0.0).then_some((i, j, phi))
            })
        })
        .collect();

    let mut field = Deformation {
        centre,
        affine: DMat3::ZERO,
        shift: DVec3::ZERO,
        nodes: nodes.clone(),
        weights: vec![DVec3::ZERO; k],
        support: rho,
    };
    let levels = opts.stiffness.len().max(1);
    let mut report = DeformReport {
        skin_rms: 0.0,
        skin_matched: 0.0,
        scalp_matched: 0.0,
        scalp_on_surface: 0.0,
        border_on_surface: 0.0,
        bald: false,
        max_displacement: 0.0,
    };
    let (mut scalp_on_surface, mut border_on_surface) = (0.0, 0.0);
    for pass in 0..2 {
        let bald = pass == 1;
        if bald {
            scalp_on_surface = on_surface_share(&samples, |s| s.scalp, &field, raw, opts);
            border_on_surface = on_surface_share(&samples, |s| s.border, &field, raw, opts);
            if scalp_on_surface < opts.bald_fraction && border_on_surface < opts.bald_border_fraction {
                break;
            }
        }
        for level in 0..levels {
            let lambda = opts.stiffness.get(level).copied().unwrap_or(0.0);
            let f = if levels > 1 { level as f64 / (levels - 1) as f64 } else { 1.0 };
            let (g0, g1) = if bald { opts.bald_skin_gate } else { opts.skin_gate };
            let gate = g0 + f * (g1 - g0);
            for _ in 0..opts.steps_per_level.max(1) {
                let matches = match_samples(&samples, &field, raw, gate, bald, opts);
                let (nm, kept) = trim(&matches, if bald { opts.bald_keep } else { opts.keep });
                report = summarise(&samples, &matches, &kept);
                let Some(solved) = solve(&samples, &matches, &kept, nm, &field, &gram, dim, lambda, opts) else {
                    break;
                };
                field = solved;
            }
        }
        report.bald = bald;
    }
    report.scalp_on_surface = scalp_on_surface;
    report.border_on_surface = border_on_surface;
    let points: Vec<DVec3> = samples.iter().map(|s| s.p).collect();
    report.max_displacement = field.max_displacement(&points);
    (field, report)
}

/// A sample's match: the raw point and normal it is pulled to, or none.
#[derive(Clone, Copy)]
struct Pull {
    point: DVec3,
    normal: DVec3,
    distance: f64,
}

/// Each sample's match under the current field (in parallel; each result depends on its sample
/// alone).
fn match_samples(
    samples: &[Sample],
    field: &Deformation,
    raw: &(impl Target + ?Sized),
    gate: f64,
    bald: bool,
    opts: &DeformOptions,
) -> Vec<Option<Pull>> {
    let normal_map = (DMat3::IDENTITY + field.affine).inverse().transpose();
    samples
        .par_iter()
        .map(|s| {
            let x = s.p + displacement_of(field, s);
            let n = (normal_map * s.n).normalize_or(s.n);
            let reach = gate.max(opts.outside_gate);
            let m = raw.closest(x, reach);
            if m.normal == DVec3::ZERO || m.distance >= reach || m.normal.dot(n) < opts.min_cos {
                return None;
            }
            // A closest point off to the side (on a hole's rim, the raw mesh's cut edge) is no
            // match: on the surface itself the offset runs along its normal.
            let along = (x - m.point).dot(m.normal);
            if m.distance > 1e-4 && along.abs() < opts.min_cos_offset * m.distance {
                return None;
            }
            let outside = along > 0.0;
            let limit = match (outside, s.scalp && !bald) {
                (true, _) => opts.outside_gate,
                (false, false) => gate,
                (false, true) => 0.0,
            };
            (m.distance < limit).then_some(Pull { point: m.point, normal: m.normal, distance: m.distance })
        })
        .collect()
}

/// The share of the samples `which` picks within [`DeformOptions::bald_gate`] of the raw surface
/// (either side, facing the same way) under `field`.
fn on_surface_share(
    samples: &[Sample],
    which: impl Fn(&Sample) -> bool + Sync,
    field: &Deformation,
    raw: &(impl Target + ?Sized),
    opts: &DeformOptions,
) -> f64 {
    let normal_map = (DMat3::IDENTITY + field.affine).inverse().transpose();
    let (on, all) = samples
        .par_iter()
        .filter(|s| which(s))
        .map(|s| {
            let x = s.p + displacement_of(field, s);
            let n = (normal_map * s.n).normalize_or(s.n);
            let m = raw.closest(x, opts.bald_gate);
            ((m.distance < opts.bald_gate && m.normal.dot(n) >= opts.min_cos) as usize, 1usize)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    on as f64 / all.max(1) as f64
}

/// The field's displacement at a sample, through its precomputed bumps.
#[inline]
fn displacement_of(field: &Deformation, s: &Sample) -> DVec3 {
    let mut u = field.affine * (s.p - field.centre) + field.shift;
    for &(k, phi) in &s.bumps {
        u += phi * field.weights[k as usize];
    }
    u
}

/// The number of matches and, per sample, whether its match is kept (the nearest `keep` share).
fn trim(matches: &[Option<Pull>], keep: f64) -> (usize, Vec<bool>) {
    let mut d: Vec<f64> = matches.iter().flatten().map(|m| m.distance).collect();
    if d.is_empty() {
        return (0, vec![false; matches.len()]);
    }
    d.sort_by(f64::total_cmp);
    let cut = d[((d.len() as f64 * keep.clamp(0.0, 1.0)).ceil() as usize).clamp(1, d.len()) - 1];
    let kept: Vec<bool> = matches.iter().map(|m| m.is_some_and(|m| m.distance <= cut)).collect();
    (kept.iter().filter(|&&k| k).count(), kept)
}

fn summarise(samples: &[Sample], matches: &[Option<Pull>], kept: &[bool]) -> DeformReport {
    let (mut skin, mut skin_kept, mut sq, mut scalp, mut scalp_kept) = (0usize, 0usize, 0.0, 0usize, 0usize);
    for ((s, m), &k) in samples.iter().zip(matches).zip(kept) {
        if s.scalp {
            scalp += 1;
            scalp_kept += k as usize;
        } else {
            skin += 1;
            if let (true, Some(m)) = (k, m) {
                skin_kept += 1;
                sq += m.distance * m.distance;
            }
        }
    }
    DeformReport {
        skin_rms: if skin_kept > 0 { (sq / skin_kept as f64).sqrt() } else { 0.0 },
        skin_matched: skin_kept as f64 / skin.max(1) as f64,
        scalp_matched: scalp_kept as f64 / scalp.max(1) as f64,
        scalp_on_surface: 0.0,
        border_on_surface: 0.0,
        bald: false,
        max_displacement: 0.0,
    }
}

/// The least-squares field for the kept matches: normal equations over `(B, t, a)`, accumulated
/// in fixed chunks in parallel and summed in order (deterministic), solved by Cholesky. `None`
/// when nothing is matched or the system is singular.
#[allow(clippy::too_many_arguments)]
fn solve(
    samples: &[Sample],
    matches: &[Option<Pull>],
    kept: &[bool],
    matched: usize,
    field: &Deformation,
    gram: &[(usize, usize, f64)],
    dim: usize,
    lambda: f64,
    opts: &DeformOptions,
) -> Option<Deformation> {
    if matched == 0 {
        return None;
    }
    let w = 1.0 / matched as f64;
    const CHUNK: usize = 512;
    let partial: Vec<(DMatrix<f64>, DVector<f64>)> = (0..samples.len().div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut a = DMatrix::<f64>::zeros(dim, dim);
            let mut b = DVector::<f64>::zeros(dim);
            let mut row: Vec<(usize, f64)> = Vec::new();
            let end = ((c + 1) * CHUNK).min(samples.len());
            for i in c * CHUNK..end {
                let (Some(m), true) = (matches[i], kept[i]) else { continue };
                let s = &samples[i];
                let q = s.p - field.centre;
                // The displacement's coefficients along a direction `d`: dᵀ u(p) = row · θ.
                let mut add = |d: DVec3, target: f64, weight: f64| {
                    row.clear();
                    for r in 0..3 {
                        if d[r] == 0.0 {
                            continue;
                        }
                        for c in 0..3 {
                            row.push((3 * r + c, d[r] * q[c]));
                        }
                        row.push((9 + r, d[r]));
                        for &(k, phi) in &s.bumps {
                            row.push((12 + 3 * k as usize + r, d[r] * phi));
                        }
                    }
                    for &(i, vi) in &row {
                        b[i] += weight * vi * target;
                        for &(j, vj) in &row {
                            a[(i, j)] += weight * vi * vj;
                        }
                    }
                };
                let goal = m.point - s.p;
                add(m.normal, m.normal.dot(goal), w);
                if opts.point_weight > 0.0 {
                    for (r, axis) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
                        add(axis, goal[r], w * opts.point_weight);
                    }
                }
            }
            (a, b)
        })
        .collect();
    let mut a = DMatrix::<f64>::zeros(dim, dim);
    let mut b = DVector::<f64>::zeros(dim);
    for (pa, pb) in partial {
        a += pa;
        b += pb;
    }
    for i in 0..9 {
        a[(i, i)] += opts.affine_weight;
    }
    for &(i, j, phi) in gram {
        for r in 0..3 {
            a[(12 + 3 * i + r, 12 + 3 * j + r)] += lambda * phi;
        }
    }
    // A floor under the bumps' diagonal: nodes that no sample reaches stay at zero.
    for i in 12..dim {
        a[(i, i)] += 1e-12;
    }
    let x = a.cholesky()?.solve(&b);
    if x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let affine =
        DMat3::from_cols(DVec3::new(x[0], x[3], x[6]), DVec3::new(x[1], x[4], x[7]), DVec3::new(x[2], x[5], x[8]));
    let weights = (0..field.nodes.len()).map(|k| DVec3::new(x[12 + 3 * k], x[13 + 3 * k], x[14 + 3 * k])).collect();
    Some(Deformation { affine, shift: DVec3::new(x[9], x[10], x[11]), weights, ..field.clone() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wendland_is_one_at_the_centre_and_zero_at_the_edge() {
        assert_eq!(wendland(0.0), 1.0);
        assert_eq!(wendland(1.0), 0.0);
        assert_eq!(wendland(1.5), 0.0);
        // (1 − 0.5)⁴ (4 · 0.5 + 1) = 0.1875.
        assert!((wendland(0.5) - 0.1875).abs() < 1e-15);
    }

    #[test]
    fn the_affine_part_moves_points_as_a_matrix_does() {
        let f = Deformation {
            centre: DVec3::new(1.0, 0.0, 0.0),
            affine: DMat3::from_diagonal(DVec3::new(0.1, -0.1, 0.0)),
            shift: DVec3::new(0.0, 0.0, 0.5),
            nodes: vec![DVec3::new(10.0, 0.0, 0.0)],
            weights: vec![DVec3::ONE],
            support: 1.0,
        };
        // (3, 2, 1) − centre = (2, 2, 1) → B · = (0.2, −0.2, 0), + shift; the node is out of reach.
        assert!(f.apply(DVec3::new(3.0, 2.0, 1.0)).distance(DVec3::new(3.2, 1.8, 1.5)) < 1e-12);
        // At the node its whole weight is added.
        let at = f.displacement(DVec3::new(10.0, 0.0, 0.0));
        assert!(at.distance(DVec3::new(0.9, 0.0, 0.5) + DVec3::ONE) < 1e-12, "{at}");
        let s = f.axis_scales();
        assert!((s[0] - 0.9).abs() < 1e-12 && (s[1] - 1.0).abs() < 1e-12 && (s[2] - 1.1).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn nodes_keep_their_spacing() {
        let mut m = hairrecon_core::mesh::unit_cube();
        m.vertices.extend((0..200).map(|i| glam::Vec3::splat(i as f32 * 0.01)));
        let nodes = spread_nodes(&[&m], 0.3);
        for (i, a) in nodes.iter().enumerate() {
            for b in &nodes[i + 1..] {
                assert!(a.distance(*b) >= 0.3);
            }
        }
        // Every vertex has a node within the spacing.
        for v in &m.vertices {
            assert!(nodes.iter().any(|n| n.distance(v.as_dvec3()) < 0.3));
        }
    }
}
