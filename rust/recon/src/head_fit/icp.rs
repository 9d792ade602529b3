//! Trimmed ICP (Chetverikov et al., "The Trimmed Iterative Closest Point algorithm", ICPR 2002),
//! for a similarity.
//!
//! Each iteration maps the template's points by the current similarity, finds each one's closest
//! point on the raw mesh (exact, through core's [`Bvh`]), keeps the `keep` fraction with the
//! smallest distances (holes, a cut-off crown, hair over the scalp and clothes make the rest), and
//! solves a new similarity from the kept pairs:
//! - point to point ([`IcpMetric::Point`]): in closed form (Umeyama, PAMI 1991); robust from far,
//!   slow to settle (the points slide along the surface);
//! - point to plane ([`IcpMetric::Plane`]): the distances along the closest triangle's normal,
//!   linearised in a small rotation, scale change and translation about the kept points' centre
//!   (Chen & Medioni, "Object modelling by registration of multiple range images", 1992, with a
//!   scale): a 7 × 7 normal-equation solve, converging in a few iterations once near.
//!
//! The residual is the kept pairs' RMS distance divided by the similarity's scale: a length in the
//! template's frame, whatever the raw mesh's scale.

use glam::{DMat3, DVec3};
use hairrecon_core::Bvh;
use rayon::prelude::*;

use super::umeyama::umeyama;
use super::Similarity;

/// What an ICP step minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IcpMetric {
    /// Point-to-point distances, solved in closed form.
    Point,
    /// Point-to-plane distances, linearised.
    Plane,
}

/// The parameters of one ICP run.
#[derive(Debug, Clone, Copy)]
pub struct IcpOptions {
    pub metric: IcpMetric,
    /// At most this many iterations.
    pub iterations: usize,
    /// The fraction of pairs kept (the rest, the farthest, are trimmed), in (0, 1].
    pub keep: f64,
    /// Stop when an iteration moves no template point by more than this (template frame units).
    pub tolerance: f64,
    /// Query the mesh in parallel (for one long run; off when many runs go in parallel).
    pub parallel: bool,
    /// Leave out the points that something covers (see [`Cover`]); needs the points' normals.
    pub cover: Option<Cover>,
}

/// Which template points ICP leaves out as covered: farther than `gate` from the surface, with
/// the surface crossing the ray along their outward normal within `reach` (both in template
/// units). Hair over the scalp and the ears, a collar over the neck: the template's skin there
/// lies under the raw surface, and pulling it out onto the hair would inflate the fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cover {
    pub gate: f64,
    pub reach: f64,
}

/// What an ICP run ends with.
#[derive(Debug, Clone, Copy)]
pub struct IcpOutcome {
    /// Template frame → raw frame.
    pub transform: Similarity,
    /// Trimmed RMS distance in the template's frame.
    pub residual: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// A template point's match: its closest point on the mesh, the triangle's normal and the distance.
#[derive(Debug, Clone, Copy)]
pub struct Match {
    pub point: DVec3,
    pub normal: DVec3,
    pub distance: f64,
}

/// What ICP registers to: a surface that answers closest-point queries.
pub trait Target: Sync {
    /// The closest point to `p` within `cap` (beyond: `p` itself, no normal, `cap` away).
    fn closest(&self, p: DVec3, cap: f64) -> Match;

    /// Whether the surface crosses the ray from `p` along `dir` (unit) within `reach`. A target
    /// that cannot tell says no.
    fn crosses(&self, _p: DVec3, _dir: DVec3, _reach: f64) -> bool {
        false
    }
}

/// A mesh: exact closest points on its triangles, with the triangle's normal.
impl Target for Bvh {
    #[inline]
    fn closest(&self, p: DVec3, cap: f64) -> Match {
        match self.closest_point(p.as_vec3(), cap as f32) {
            Some(c) => Match {
                point: c.point.as_dvec3(),
                normal: self.mesh().face_normal(c.triangle as usize).as_dvec3(),
                distance: (c.point.as_dvec3() - p).length(),
            },
            None => Match { point: p, normal: DVec3::ZERO, distance: cap },
        }
    }

    #[inline]
    fn crosses(&self, p: DVec3, dir: DVec3, reach: f64) -> bool {
        self.occluded(p.as_vec3(), dir.as_vec3(), 0.0, reach as f32)
    }
}

/// A dense sample of a surface (points with normals) in a kd-tree: the nearest sample point and
/// its normal. Several times faster than exact closest points, for the coarse search.
#[derive(Debug)]
pub struct SurfaceSamples {
    points: Vec<(DVec3, DVec3)>,
    tree: kiddo::ImmutableKdTree<f32, 3>,
}

impl SurfaceSamples {
    /// The kd-tree of `points` (position, unit normal; at least one).
    pub fn new(points: Vec<(DVec3, DVec3)>) -> Self {
        let arr: Vec<[f32; 3]> = points.iter().map(|p| p.0.as_vec3().to_array()).collect();
        let tree = kiddo::ImmutableKdTree::new_from_slice(&arr);
        Self { points, tree }
    }
}

impl Target for SurfaceSamples {
    #[inline]
    fn closest(&self, p: DVec3, cap: f64) -> Match {
        let n = self.tree.nearest_one::<kiddo::SquaredEuclidean>(&p.as_vec3().to_array());
        let (q, normal) = self.points[n.item as usize];
        let distance = (q - p).length();
        if distance <= cap {
            Match { point: q, normal, distance }
        } else {
            Match { point: p, normal: DVec3::ZERO, distance: cap }
        }
    }
}

/// Each point's match (distances capped at `cap`) after mapping by `t`.
pub(crate) fn match_points<T: Target + ?Sized>(
    points: &[DVec3],
    t: &Similarity,
    target: &T,
    cap: f64,
    parallel: bool,
) -> Vec<Match> {
    let one = |p: &DVec3| target.closest(t.apply(*p), cap);
    if parallel {
        points.par_iter().map(one).collect()
    } else {
        points.iter().map(one).collect()
    }
}

fn kept(n: usize, keep: f64) -> usize {
    ((n as f64 * keep).round() as usize).clamp(3.min(n), n)
}

/// Trimmed ICP of `points` (template frame) onto `target` from `init` (template → raw). `cap`
/// bounds the closest-point search (raw frame units); farther points count as `cap` away.
/// Point-to-plane needs a target with normals (a [`Bvh`]). `normals` (the points' outward unit
/// normals) are needed by [`IcpOptions::cover`].
pub fn trimmed_icp<T: Target + ?Sized>(
    points: &[DVec3],
    normals: Option<&[DVec3]>,
    target: &T,
    init: Similarity,
    cap: f64,
    opts: &IcpOptions,
) -> IcpOutcome {
    let mut t = init;
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    let mut order: Vec<usize> = Vec::with_capacity(points.len());
    for it in 0..opts.iterations {
        iterations = it + 1;
        let m = match_points(points, &t, target, cap, opts.parallel);
        order.clear();
        match (opts.cover, normals) {
            (Some(c), Some(normals)) => {
                let covered = |i: usize| {
                    m[i].distance > c.gate * t.scale
                        && target.crosses(t.apply(points[i]), t.rotation * normals[i], c.reach * t.scale)
                };
                let keep: Vec<bool> = if opts.parallel {
                    (0..points.len()).into_par_iter().map(|i| !covered(i)).collect()
                } else {
                    (0..points.len()).map(|i| !covered(i)).collect()
                };
                order.extend((0..points.len()).filter(|&i| keep[i]));
            }
            _ => order.extend(0..points.len()),
        }
        if order.len() < 7 {
            break;
        }
        order.sort_unstable_by(|&a, &b| m[a].distance.total_cmp(&m[b].distance).then(a.cmp(&b)));
        let k = kept(order.len(), opts.keep);
        let sel = &order[..k];
        residual = (sel.iter().map(|&i| m[i].distance * m[i].distance).sum::<f64>() / k as f64).sqrt() / t.scale;
        let src: Vec<DVec3> = sel.iter().map(|&i| points[i]).collect();
        let next = match opts.metric {
            IcpMetric::Point => {
                let dst: Vec<DVec3> = sel.iter().map(|&i| m[i].point).collect();
                umeyama(&src, &dst, true)
            }
            IcpMetric::Plane => {
                let pairs: Vec<(DVec3, Match)> = sel.iter().map(|&i| (t.apply(points[i]), m[i])).collect();
                plane_step(&pairs).map(|inc| inc.then_after(&t))
            }
        };
        let Some(next) = next else { break };
        let moved = src.iter().map(|&p| (next.apply(p) - t.apply(p)).length()).fold(0.0, f64::max) / t.scale;
        t = next;
        if moved < opts.tolerance {
            break;
        }
    }
    IcpOutcome { transform: t, residual, iterations }
}

/// One point-to-plane step: the small similarity (about the points' centre) that best moves each
/// mapped point `x` onto the plane of its match, Σ (n · (x′ − q))², linearised in the rotation
/// vector ω, the log-scale σ and the translation τ. `None` when the system is singular.
fn plane_step(pairs: &[(DVec3, Match)]) -> Option<Similarity> {
    use nalgebra::{SMatrix, SVector};
    let used: Vec<&(DVec3, Match)> = pairs.iter().filter(|(_, m)| m.normal != DVec3::ZERO).collect();
    if used.len() < 7 {
        return None;
    }
    let c = used.iter().map(|(x, _)| *x).sum::<DVec3>() / used.len() as f64;
    // Unit-free unknowns: lengths relative to the points' spread.
    let spread = (used.iter().map(|(x, _)| (*x - c).length_squared()).sum::<f64>() / used.len() as f64).sqrt();
    if spread.is_nan() || spread <= 0.0 {
        return None;
    }
    let mut a = SMatrix::<f64, 7, 7>::zeros();
    let mut b = SVector::<f64, 7>::zeros();
    for (x, m) in used {
        let d = (*x - c) / spread;
        let n = m.normal;
        let cr = d.cross(n);
        let j = SVector::<f64, 7>::from_column_slice(&[cr.x, cr.y, cr.z, d.dot(n), n.x, n.y, n.z]);
        let r = n.dot(*x - m.point) / spread;
        a += j * j.transpose();
        b -= j * r;
    }
    let sol = a.cholesky()?.solve(&b);
    if !sol.iter().all(|v| v.is_finite()) {
        return None;
    }
    let omega = DVec3::new(sol[0], sol[1], sol[2]);
    let rotation = if omega.length() > 1e-15 {
        DMat3::from_axis_angle(omega.normalize(), omega.length())
    } else {
        DMat3::IDENTITY
    };
    let scale = sol[3].exp();
    let tau = DVec3::new(sol[4], sol[5], sol[6]) * spread;
    // y ↦ scale · R (y − c) + c + τ.
    let step = Similarity { scale, rotation, translation: c + tau - scale * (rotation * c) };
    // A near-singular system can ask for a log-scale change so large that exp() overflows or
    // underflows; the step is then no step.
    (step.scale.is_finite() && step.scale > 0.0 && step.translation.is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a double cone with its apex at their centre (x · n = 0 for every point), each
    /// moved 1e-12 along its normal and matched 1 cm further along it: the scale's column of the
    /// system is rounding-sized and nothing else explains the residual, so the solve asks for a
    /// log-scale of about 1e10, which exp() turns into an infinite scale (and the pose into NaN,
    /// whose closest-point queries then visited every node of the raw mesh's tree). Such a step
    /// must come back as no step, never as a non-finite one.
    #[test]
    fn a_degenerate_set_of_pairs_never_gives_a_non_finite_step() {
        let mut pairs = Vec::new();
        for nappe in [1.0, -1.0] {
            for i in 0..12 {
                let phi = std::f64::consts::TAU * i as f64 / 12.0;
                for r in [0.02, 0.05, 0.08] {
                    let n = DVec3::new(phi.cos(), phi.sin(), -nappe) / 2f64.sqrt();
                    let x = DVec3::new(r * phi.cos(), r * phi.sin(), nappe * r) + 1e-12 * n;
                    let q = x - 0.01 * n;
                    pairs.push((x, Match { point: q, normal: n, distance: 0.01 }));
                }
            }
        }
        let step = plane_step(&pairs);
        if let Some(s) = step {
            assert!(s.scale.is_finite() && s.scale > 0.0 && s.translation.is_finite(), "{s:?}");
        }
        // An ellipsoid's points matched to the same ellipsoid 10 % larger: a regular system, whose
        // step is the linearised scale change, exp(0.1).
        let mut pairs = Vec::new();
        for i in 1..8 {
            for j in 0..12 {
                let (th, ph) = (std::f64::consts::PI * i as f64 / 8.0, std::f64::consts::TAU * j as f64 / 12.0);
                let x = DVec3::new(0.08 * th.sin() * ph.cos(), 0.06 * th.sin() * ph.sin(), 0.1 * th.cos());
                let n = (x / DVec3::new(0.0064, 0.0036, 0.01)).normalize();
                pairs.push((x, Match { point: 1.1 * x, normal: n, distance: 0.1 * x.length() }));
            }
        }
        let s = plane_step(&pairs).expect("a regular system");
        assert!((s.scale - 0.1f64.exp()).abs() < 1e-6, "{s:?}");
    }
}
