//! Trimmed ICP with Umeyama steps (Chetverikov et al., "The Trimmed Iterative Closest Point
//! algorithm", ICPR 2002; Umeyama, PAMI 1991).
//!
//! Each iteration maps the template's points by the current similarity, finds each one's closest
//! point on the raw mesh (exact, through core's [`Bvh`]), keeps the `keep` fraction with the
//! smallest distances (holes, a cut-off crown, hair over the scalp and clothes make the rest), and
//! solves the similarity from the kept pairs in closed form. The residual is the kept pairs' RMS
//! distance divided by the similarity's scale: a length in the template's frame, whatever the raw
//! mesh's scale.

use glam::DVec3;
use hairrecon_core::Bvh;
use rayon::prelude::*;

use super::umeyama::umeyama;
use super::Similarity;

/// The parameters of one ICP run.
#[derive(Debug, Clone, Copy)]
pub struct IcpOptions {
    /// At most this many iterations.
    pub iterations: usize,
    /// The fraction of pairs kept (the rest, the farthest, are trimmed), in (0, 1].
    pub keep: f64,
    /// Stop when an iteration moves no template point by more than this (template frame units).
    pub tolerance: f64,
    /// Query the mesh in parallel (for one long run; off when many runs go in parallel).
    pub parallel: bool,
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

/// The closest point of the mesh to `p` within `cap` (the capped distance's point is `p` itself).
#[inline]
pub(crate) fn closest(bvh: &Bvh, p: DVec3, cap: f64) -> (DVec3, f64) {
    match bvh.closest_point(p.as_vec3(), cap as f32) {
        Some(c) => (c.point.as_dvec3(), (c.point.as_dvec3() - p).length()),
        None => (p, cap),
    }
}

/// Each point's mapped position, closest point and distance (capped at `cap`).
pub(crate) fn match_points(
    points: &[DVec3],
    t: &Similarity,
    bvh: &Bvh,
    cap: f64,
    parallel: bool,
) -> Vec<(DVec3, f64)> {
    let one = |p: &DVec3| closest(bvh, t.apply(*p), cap);
    if parallel {
        points.par_iter().map(one).collect()
    } else {
        points.iter().map(one).collect()
    }
}

/// The trimmed RMS of distances: the `keep` fraction of smallest ones. Reorders `d`.
pub(crate) fn trimmed_rms(d: &mut [f64], keep: f64) -> f64 {
    let k = kept(d.len(), keep);
    if k < d.len() {
        d.select_nth_unstable_by(k, f64::total_cmp);
    }
    (d[..k].iter().map(|x| x * x).sum::<f64>() / k as f64).sqrt()
}

fn kept(n: usize, keep: f64) -> usize {
    ((n as f64 * keep).round() as usize).clamp(3.min(n), n)
}

/// Trimmed ICP of `points` (template frame) onto the mesh of `bvh` from `init` (template → raw).
/// `cap` bounds the closest-point search (raw frame units); farther points count as `cap` away.
pub fn trimmed_icp(points: &[DVec3], bvh: &Bvh, init: Similarity, cap: f64, opts: &IcpOptions) -> IcpOutcome {
    let mut t = init;
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    let k = kept(points.len(), opts.keep);
    let mut order: Vec<usize> = (0..points.len()).collect();
    for it in 0..opts.iterations {
        iterations = it + 1;
        let m = match_points(points, &t, bvh, cap, opts.parallel);
        order.sort_unstable_by(|&a, &b| m[a].1.total_cmp(&m[b].1).then(a.cmp(&b)));
        let sel = &order[..k];
        residual = (sel.iter().map(|&i| m[i].1 * m[i].1).sum::<f64>() / k as f64).sqrt() / t.scale;
        let src: Vec<DVec3> = sel.iter().map(|&i| points[i]).collect();
        let dst: Vec<DVec3> = sel.iter().map(|&i| m[i].0).collect();
        let Some(next) = umeyama(&src, &dst, true) else { break };
        let moved = src.iter().map(|&p| (next.apply(p) - t.apply(p)).length()).fold(0.0, f64::max) / t.scale;
        t = next;
        if moved < opts.tolerance {
            break;
        }
    }
    IcpOutcome { transform: t, residual, iterations }
}
