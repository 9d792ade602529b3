//! Stage 3: global direction: undirected oriented points made directed (root → tip).
//!
//! In: [`OrientedPoints`] from [`crate::points3d`] (lines, 180° ambiguous) and the [`Scalp`] with
//! S(p_s). Out: the same points with every direction's sign chosen, saved as
//! `points_directed.ply` and reloaded from there.
//!
//! Two solvers share the graph (k nearest neighbours within `max_edge`) and the anchors (points
//! near the scalp, signed by S(p_s)):
//!
//! - [`DirectionSolver::Tree`], the paper's global optimization (`docs/method.md` §2): a minimum
//!   spanning tree whose edge cost grows with distance and with the angle between the two lines,
//!   a virtual root joined to the anchors at zero cost, signs propagated down the tree so that each
//!   point agrees with its parent; components with no anchor point downward (gravity); a few rounds
//!   of confidence-weighted neighbour voting correct isolated flips.
//! - [`DirectionSolver::Diffusion`] (default): the signs relaxed to reals and found all at once, by
//!   minimising `Σ w_ij (x_i − σ_ij x_j)² + Σ u_i (x_i − p_i)²` (one sparse SPD solve, Jacobi CG),
//!   then `sign(x)`. `σ_ij` is the sign of `d_i · d_j`; the edge weight `w_ij` is high for parallel
//!   lines that lie one after the other along their direction and low for lines side by side
//!   (`|cos|⁴ (floor + colinearity⁴) e^(−d/scale)`), since two sides of one curl, or two strands
//!   of different phase, are side by side and run opposite ways. The priors `p_i`, `u_i` are the
//!   anchors (strong) and a weak pull downward for lines that are far from horizontal.
//!
//! Why not the tree alone: one wrong edge flips a whole subtree, and on tight curls wrong edges
//! are everywhere. Measured at commit 8ff3570 with `hairrecon reconstruct CAPTURE --out DIR
//! --stop-after direction` on the paper preset (agreement with the ground truth, [`crate::eval`],
//! `scores.direction` in `report.json`): curly 30.0% (tree) → 88% (diffusion), straight 99.98% →
//! 100%; every line pointed downward gives 86.9% and 99.8%.
//!
//! The ablation ("w/o global opt.") is [`gravity_directions`]: every direction points down (−Z).

use glam::Vec3;
use rayon::prelude::*;

use crate::points3d::OrientedPoints;
use crate::roots::{scalp_point, Scalp};
use hairrecon_core::spatial::PointIndex;

/// Parameters of the global direction optimization.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionParams {
    /// Neighbours per point in the graph.
    pub k: usize,
    /// Longest graph edge, metres.
    pub max_edge: f32,
    /// Points within this distance of the scalp are anchored by S(p_s), metres.
    pub anchor_dist: f32,
    /// An anchor needs |cos(direction, S)| at least this.
    pub anchor_min_cos: f32,
    /// Rounds of neighbour voting after the tree ([`DirectionSolver::Tree`] only).
    pub vote_rounds: usize,
    /// How the signs are found.
    pub solver: DirectionSolver,
    /// Diffusion: weight of an anchor's prior (an edge weighs at most 1).
    pub anchor_weight: f32,
    /// Diffusion: weight of the downward prior per unit of `|d_z| − gravity_min` (0: off).
    pub gravity_weight: f32,
    /// Diffusion: lines with `|d_z|` below this (near horizontal) get no downward prior.
    pub gravity_min: f32,
    /// Diffusion: edge weight of two lines side by side, relative to two lines end to end.
    pub side_weight: f32,
    /// Diffusion: edge weights fall off as `e^(−d/edge_scale)`, metres.
    pub edge_scale: f32,
    /// Diffusion: weight of a prior away from the scalp, per unit of `|d · n| − outward_min`, for
    /// lines within `outward_dist` of the scalp (`n`: its normal at the closest point); 0: off.
    /// Hair leaves the scalp, so a line that stands steeply off it (spiky hair, hair with volume)
    /// points away from it; hair that lies along the head or hangs below it gets no such prior.
    /// Measured at commit e67315b on the held-out spiky style's tuning seed with a raw mesh on the
    /// spikes' front (research/notes/volume-study.md, section 5): signs right 55.7% → 83.0% at 2
    /// (89.1% at 8), the initial strands' F1 at 2 mm/20° 26.1 → 26.4; off until measured on
    /// every style.
    #[serde(default)]
    pub outward_weight: f32,
    #[serde(default = "outward_min")]
    pub outward_min: f32,
    #[serde(default = "outward_dist")]
    pub outward_dist: f32,
    /// Diffusion: conjugate-gradient tolerance (relative residual) and iteration cap.
    pub tolerance: f32,
    pub max_iterations: usize,
}

/// The solver of [`global_directions`] (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DirectionSolver {
    /// Minimum spanning tree and propagation (the paper).
    Tree,
    /// Least squares over the whole graph at once.
    Diffusion,
}

fn outward_min() -> f32 {
    0.5
}

fn outward_dist() -> f32 {
    0.05
}

impl Default for DirectionParams {
    fn default() -> Self {
        Self {
            k: 10,
            max_edge: 0.01,
            anchor_dist: 0.015,
            anchor_min_cos: 0.4,
            vote_rounds: 5,
            solver: DirectionSolver::Diffusion,
            anchor_weight: 10.0,
            gravity_weight: 0.5,
            gravity_min: 0.2,
            side_weight: 0.01,
            edge_scale: 0.003,
            outward_weight: 0.0,
            outward_min: outward_min(),
            outward_dist: outward_dist(),
            tolerance: 1e-5,
            max_iterations: 2000,
        }
    }
}

/// Statistics of a direction run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionStats {
    pub anchors: u64,
    pub components: u64,
    pub components_without_anchor: u64,
    pub flips_by_vote: u64,
    /// Diffusion: conjugate-gradient iterations and final relative residual.
    pub iterations: u64,
    pub residual: f32,
    /// Diffusion: points whose sign differs from "downward".
    pub against_gravity: u64,
}

/// The ablation: every direction made to point downward (−Z).
pub fn gravity_directions(points: &OrientedPoints) -> OrientedPoints {
    let mut out = points.clone();
    for d in &mut out.directions {
        if d.z > 0.0 {
            *d = -*d;
        }
    }
    out
}

struct Dsu(Vec<u32>);

impl Dsu {
    fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = p;
            x = p;
        }
        x
    }
    fn union(&mut self, a: u32, b: u32) -> bool {
        let (a, b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        self.0[a as usize] = b;
        true
    }
}

/// Chooses the sign of every direction (see the module doc).
pub fn global_directions(
    points: &OrientedPoints,
    scalp: &Scalp,
    params: &DirectionParams,
) -> (OrientedPoints, DirectionStats) {
    if points.is_empty() {
        return (points.clone(), DirectionStats::default());
    }
    let nbrs = knn_graph(points, params);
    let anchor = anchors(points, scalp, params);
    let (dirs, mut stats) = match params.solver {
        DirectionSolver::Tree => tree_signs(points, &nbrs, &anchor, params),
        DirectionSolver::Diffusion => {
            let outward = (params.outward_weight > 0.0).then(|| scalp_normals(points, scalp, params.outward_dist));
            diffusion_signs(points, &nbrs, &anchor, outward.as_deref(), params)
        }
    };
    stats.anchors = anchor.iter().filter(|a| **a != 0).count() as u64;
    (
        OrientedPoints { positions: points.positions.clone(), directions: dirs, confidence: points.confidence.clone() },
        stats,
    )
}

/// The k nearest neighbours of every point within `max_edge`, with their distances.
fn knn_graph(points: &OrientedPoints, params: &DirectionParams) -> Vec<Vec<(u32, f32)>> {
    let n = points.len();
    let index = PointIndex::new(points.positions.clone(), points.directions.clone());
    (0..n)
        .into_par_iter()
        .map(|i| {
            index
                .nearest(points.positions[i], params.k + 1)
                .into_iter()
                .filter(|&(j, d)| j != i && d <= params.max_edge)
                .map(|(j, d)| (j as u32, d))
                .collect()
        })
        .collect()
}

/// Per point: the scalp's normal at its closest point within `max_dist`, else zero.
fn scalp_normals(points: &OrientedPoints, scalp: &Scalp, max_dist: f32) -> Vec<Vec3> {
    points.positions.par_iter().map(|&p| scalp_point(scalp, p, max_dist).map_or(Vec3::ZERO, |sp| sp.normal)).collect()
}

/// Per point: +1 or −1 where the sign is given by S(p_s) (near the scalp, not across S), else 0.
fn anchors(points: &OrientedPoints, scalp: &Scalp, params: &DirectionParams) -> Vec<i8> {
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            let Some(sp) = scalp_point(scalp, points.positions[i], params.anchor_dist) else { return 0 };
            let c = points.directions[i].dot(sp.growth);
            if c.abs() < params.anchor_min_cos {
                0
            } else if c > 0.0 {
                1
            } else {
                -1
            }
        })
        .collect()
}

/// The paper's tree solver: Kruskal, propagation, voting.
fn tree_signs(
    points: &OrientedPoints,
    nbrs: &[Vec<(u32, f32)>],
    anchor: &[i8],
    params: &DirectionParams,
) -> (Vec<Vec3>, DirectionStats) {
    let n = points.len();
    let mut stats = DirectionStats::default();
    // Kruskal over the graph plus a virtual root (index n) joined to anchors at cost 0.
    let mut edges: Vec<(f32, u32, u32)> = Vec::with_capacity(n * params.k / 2 + n);
    for i in 0..n {
        if anchor[i] != 0 {
            edges.push((0.0, i as u32, n as u32));
        }
        for &(j, d) in &nbrs[i] {
            if (j as usize) > i {
                let c = points.directions[i].dot(points.directions[j as usize]).abs();
                // Distance, stretched when the lines cross.
                edges.push((d * (1.0 + 4.0 * (1.0 - c)), i as u32, j));
            }
        }
    }
    edges.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut dsu = Dsu((0..=n as u32).collect());
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n + 1];
    for &(_, a, b) in &edges {
        if dsu.union(a, b) {
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
    }
    // Propagate signs from the virtual root; then the other components from a seed each.
    let mut dirs = points.directions.clone();
    let mut visited = vec![false; n + 1];
    let mut queue = std::collections::VecDeque::new();
    visited[n] = true;
    for &a in &adj[n] {
        let a = a as usize;
        visited[a] = true;
        if anchor[a] < 0 {
            dirs[a] = -dirs[a];
        }
        queue.push_back(a);
    }
    let bfs = |queue: &mut std::collections::VecDeque<usize>,
               visited: &mut Vec<bool>,
               dirs: &mut Vec<Vec3>,
               comp: &mut Vec<usize>| {
        while let Some(u) = queue.pop_front() {
            comp.push(u);
            for &v in &adj[u] {
                let v = v as usize;
                if v == n || visited[v] {
                    continue;
                }
                visited[v] = true;
                if dirs[v].dot(dirs[u]) < 0.0 {
                    dirs[v] = -dirs[v];
                }
                queue.push_back(v);
            }
        }
    };
    let mut comp = Vec::new();
    bfs(&mut queue, &mut visited, &mut dirs, &mut comp);
    if !comp.is_empty() {
        stats.components += 1;
    }
    for s in 0..n {
        if visited[s] {
            continue;
        }
        comp.clear();
        visited[s] = true;
        queue.push_back(s);
        bfs(&mut queue, &mut visited, &mut dirs, &mut comp);
        stats.components += 1;
        stats.components_without_anchor += 1;
        let down: f32 = comp.iter().map(|&i| -dirs[i].z * points.confidence[i].max(1e-3)).sum();
        if down < 0.0 {
            for &i in &comp {
                dirs[i] = -dirs[i];
            }
        }
    }
    // Majority voting among neighbours; anchors fixed.
    for _ in 0..params.vote_rounds {
        let flips: Vec<usize> = (0..n)
            .into_par_iter()
            .filter(|&i| {
                if anchor[i] != 0 {
                    return false;
                }
                let mut vote = 0.0f32;
                for &(j, _) in &nbrs[i] {
                    let j = j as usize;
                    vote += dirs[i].dot(dirs[j]) * points.confidence[j].max(1e-3);
                }
                vote < 0.0
            })
            .collect();
        if flips.is_empty() {
            break;
        }
        stats.flips_by_vote += flips.len() as u64;
        for i in flips {
            dirs[i] = -dirs[i];
        }
    }
    (dirs, stats)
}

/// The diffusion solver: `(D + U − W_σ) x = U p` by Jacobi-preconditioned CG, then `sign(x)`.
fn diffusion_signs(
    points: &OrientedPoints,
    nbrs: &[Vec<(u32, f32)>],
    anchor: &[i8],
    outward: Option<&[Vec3]>,
    params: &DirectionParams,
) -> (Vec<Vec3>, DirectionStats) {
    let n = points.len();
    let mut stats = DirectionStats::default();
    let pos = &points.positions;
    let dir = &points.directions;
    // Signed edge weight of i → j (the kNN lists are not symmetric; the matrix is (W + Wᵀ)/2).
    let weight = |i: usize, j: usize, d: f32| -> f32 {
        let c = dir[i].dot(dir[j]);
        let e = (pos[j] - pos[i]).normalize_or_zero();
        let col = 0.5 * (e.dot(dir[i]).abs() + e.dot(dir[j]).abs());
        let w = c.powi(4) * (params.side_weight + col.powi(4)) * (-d / params.edge_scale.max(1e-6)).exp();
        0.5 * w * c.signum()
    };
    // Symmetric adjacency in CSR form: i's own neighbours, then those that have i as a neighbour.
    let mut count = vec![0u32; n + 1];
    for (i, l) in nbrs.iter().enumerate() {
        count[i + 1] += l.len() as u32;
        for &(j, _) in l {
            count[j as usize + 1] += 1;
        }
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let start = count;
    let mut fill: Vec<u32> = start[..n].to_vec();
    let nnz = start[n] as usize;
    let mut col = vec![0u32; nnz];
    let mut val = vec![0.0f32; nnz];
    for (i, l) in nbrs.iter().enumerate() {
        for &(j, d) in l {
            let w = weight(i, j as usize, d);
            let a = &mut fill[i];
            col[*a as usize] = j;
            val[*a as usize] = w;
            *a += 1;
            let b = &mut fill[j as usize];
            col[*b as usize] = i as u32;
            val[*b as usize] = w;
            *b += 1;
        }
    }
    // Priors: anchors, else a pull downward for lines far from horizontal.
    let (u, p): (Vec<f32>, Vec<f32>) = (0..n)
        .map(|i| {
            if anchor[i] != 0 {
                (params.anchor_weight, anchor[i] as f32)
            } else {
                let dz = dir[i].z;
                let w = params.gravity_weight * (dz.abs() - params.gravity_min).max(0.0);
                let down = if dz > 0.0 { -1.0 } else { 1.0 };
                let Some(c) = outward.map(|o| dir[i].dot(o[i])).filter(|c| c.abs() > params.outward_min) else {
                    return (w + 1e-4, down);
                };
                // Both priors: the weighted mean of their signs.
                let wo = params.outward_weight * (c.abs() - params.outward_min);
                (w + wo + 1e-4, (w * down + wo * c.signum()) / (w + wo))
            }
        })
        .unzip();
    let diag: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|i| u[i] + val[start[i] as usize..start[i + 1] as usize].iter().map(|w| w.abs()).sum::<f32>())
        .collect();
    let apply = |x: &[f32], out: &mut [f32]| {
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            let r = start[i] as usize..start[i + 1] as usize;
            let off: f32 = col[r.clone()].iter().zip(&val[r]).map(|(&j, &w)| w * x[j as usize]).sum();
            *o = diag[i] * x[i] - off;
        });
    };
    // Sums over fixed chunks in order: the same result whatever the thread count.
    let dot = |a: &[f32], b: &[f32]| -> f64 {
        let parts: Vec<f64> = a
            .par_chunks(4096)
            .zip(b.par_chunks(4096))
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| (*x as f64) * (*y as f64)).sum())
            .collect();
        parts.into_iter().sum()
    };
    let rhs: Vec<f32> = u.iter().zip(&p).map(|(u, p)| u * p).collect();
    let mut x = vec![0.0f32; n];
    let mut r = rhs.clone();
    let mut z: Vec<f32> = r.iter().zip(&diag).map(|(r, d)| r / d).collect();
    let mut q = z.clone();
    let mut aq = vec![0.0f32; n];
    let mut rz = dot(&r, &z);
    let b_norm = dot(&rhs, &rhs).sqrt().max(1e-30);
    for it in 0..params.max_iterations {
        apply(&q, &mut aq);
        let qaq = dot(&q, &aq);
        if qaq <= 1e-30 {
            break;
        }
        let alpha = (rz / qaq) as f32;
        x.par_iter_mut().zip(&q).for_each(|(x, q)| *x += alpha * q);
        r.par_iter_mut().zip(&aq).for_each(|(r, aq)| *r -= alpha * aq);
        let res = (dot(&r, &r).sqrt() / b_norm) as f32;
        stats.iterations = it as u64 + 1;
        stats.residual = res;
        if res < params.tolerance {
            break;
        }
        z.par_iter_mut().zip(&r).zip(&diag).for_each(|((z, r), d)| *z = r / d);
        let rz_new = dot(&r, &z);
        let beta = if rz > 1e-300 { (rz_new / rz) as f32 } else { 0.0 };
        rz = rz_new;
        q.par_iter_mut().zip(&z).for_each(|(q, z)| *q = z + beta * *q);
    }
    let dirs: Vec<Vec3> = (0..n)
        .map(|i| {
            // Anchors keep their sign; a point the solve left at zero falls back to its prior.
            let s = if anchor[i] != 0 {
                anchor[i] as f32
            } else if x[i].abs() > 1e-12 {
                x[i].signum()
            } else {
                p[i]
            };
            dir[i] * s
        })
        .collect();
    stats.against_gravity = dirs.iter().filter(|d| d.z > 0.0).count() as u64;
    (dirs, stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hairrecon_core::TriMesh;

    /// A deterministic number in [0, 1) from an integer (a hash, for test data).
    fn rnd(i: u32) -> f32 {
        let mut x = i.wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
        x ^= x >> 15;
        x = x.wrapping_mul(0x2C1B_3C6D);
        x ^= x >> 12;
        (x >> 8) as f32 / (1u32 << 24) as f32
    }

    /// A vertical square of scalp in the plane x = 0 (normal +X), 20 cm wide, z in [0, 0.2].
    fn wall_scalp() -> Scalp {
        let v = vec![
            Vec3::new(0.0, -0.1, 0.0),
            Vec3::new(0.0, 0.1, 0.0),
            Vec3::new(0.0, 0.1, 0.2),
            Vec3::new(0.0, -0.1, 0.2),
        ];
        let mesh = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]], Some(vec![Vec3::X; 4]), None).unwrap();
        Scalp::new(mesh).unwrap()
    }

    /// Points along the polylines with root→tip directions; every line's sign then randomised.
    fn lines(strands: &[Vec<Vec3>]) -> (OrientedPoints, Vec<Vec3>) {
        let mut pts = OrientedPoints::default();
        let mut truth = Vec::new();
        for s in strands {
            for w in s.windows(2) {
                let d = (w[1] - w[0]).normalize();
                let flip = if rnd(pts.len() as u32 + 77) < 0.5 { -1.0 } else { 1.0 };
                pts.positions.push(w[0]);
                pts.directions.push(d * flip);
                pts.confidence.push(1.0);
                truth.push(d);
            }
        }
        (pts, truth)
    }

    fn agreement(got: &OrientedPoints, truth: &[Vec3]) -> f32 {
        let ok = got.directions.iter().zip(truth).filter(|(a, b)| a.dot(**b) > 0.0).count();
        100.0 * ok as f32 / truth.len() as f32
    }

    #[test]
    fn signs_travel_from_the_scalp_along_level_strands() {
        // Strands leave the wall along S(p_s) made level and run 15 cm: only their first 15 mm are
        // anchored, and level lines get no downward prior, so the rest must come along the graph.
        let scalp = wall_scalp();
        let mut strands = Vec::new();
        for a in 0..6 {
            for b in 0..6 {
                let root = Vec3::new(0.001, -0.05 + 0.02 * a as f32, 0.05 + 0.02 * b as f32);
                let s = scalp.closest_root(root).direction;
                let h = Vec3::new(s.x, s.y, 0.0).normalize();
                strands.push((0..150).map(|k| root + h * (0.001 * k as f32)).collect());
            }
        }
        let (pts, truth) = lines(&strands);
        for solver in [DirectionSolver::Diffusion, DirectionSolver::Tree] {
            let params = DirectionParams { solver, ..DirectionParams::default() };
            let (got, stats) = global_directions(&pts, &scalp, &params);
            assert!(stats.anchors > 0);
            assert_eq!(agreement(&got, &truth), 100.0, "{solver:?}");
        }
    }

    #[test]
    fn spikes_standing_off_the_scalp_point_away_from_it_with_the_outward_prior() {
        // Spikes rise off the wall at 37° above the horizontal, seen from 2 cm out (no anchor
        // within reach): "downward" makes them all point at the scalp; the prior away from the
        // scalp turns them round.
        let scalp = wall_scalp();
        let d = Vec3::new(0.8, 0.0, 0.6);
        let mut strands = Vec::new();
        for a in 0..6 {
            for b in 0..6 {
                let root = Vec3::new(0.02, -0.05 + 0.02 * a as f32, 0.05 + 0.02 * b as f32);
                strands.push((0..30).map(|k| root + d * (0.001 * k as f32)).collect());
            }
        }
        let (pts, truth) = lines(&strands);
        let (got, stats) = global_directions(&pts, &scalp, &DirectionParams::default());
        assert_eq!(stats.anchors, 0);
        assert_eq!(agreement(&got, &truth), 0.0, "the downward prior alone");
        let params = DirectionParams { outward_weight: 2.0, ..DirectionParams::default() };
        let (got, _) = global_directions(&pts, &scalp, &params);
        assert_eq!(agreement(&got, &truth), 100.0, "with the outward prior");
    }

    #[test]
    fn hanging_curls_side_by_side_get_their_signs_from_their_own_turns() {
        // Helical curls 9 mm apart, of either handedness and random phase, bobbing up and down
        // along the way so that a fifth of each strand climbs: lines side by side run opposite
        // ways, and "downward" alone is wrong where a curl climbs. No scalp nearby. Where two curls
        // pass 1 mm apart running opposite ways the graph has wrong edges that no solver can tell
        // from right ones, so a few percent stay wrong.
        let scalp = wall_scalp();
        let mut strands = Vec::new();
        for a in 0..5 {
            for b in 0..5 {
                let id = (a * 5 + b) as u32;
                let hand = if rnd(id) < 0.5 { -1.0 } else { 1.0 };
                let phase = std::f32::consts::TAU * rnd(id + 1000);
                let centre = Vec3::new(1.0 + 0.009 * a as f32, 0.009 * b as f32, 0.0);
                strands.push(
                    (0..400)
                        .map(|k| {
                            let t = k as f32 * 0.25; // radians; 4 mm radius ⇒ 1 mm steps
                            let th = hand * t + phase;
                            let z = -0.0015 * t + 0.004 * (0.5 * t).sin();
                            centre + Vec3::new(0.004 * th.cos(), 0.004 * th.sin(), z)
                        })
                        .collect(),
                );
            }
        }
        let (pts, truth) = lines(&strands);
        let gravity = agreement(&gravity_directions(&pts), &truth);
        let (got, stats) = global_directions(&pts, &scalp, &DirectionParams::default());
        assert_eq!(stats.anchors, 0);
        let a = agreement(&got, &truth);
        assert!(gravity < 85.0, "the test data should climb in places: downward alone agrees {gravity}%");
        let (tree, _) =
            global_directions(&pts, &scalp, &DirectionParams { solver: DirectionSolver::Tree, ..Default::default() });
        eprintln!("agreement: diffusion {a}%, tree {}%, downward {gravity}%", agreement(&tree, &truth));
        // Measured: diffusion 94.1%, tree 52.0%, downward 77.4%.
        assert!(a >= 92.0 && a >= gravity + 12.0, "diffusion agrees {a}% (downward alone {gravity}%), {stats:?}");
    }
}
