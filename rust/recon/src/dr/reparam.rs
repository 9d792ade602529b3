//! The reparameterization of strand points u = (I + λL) x, after Nicolet, Jacobson, Jakob, "Large
//! Steps in Inverse Rendering of Geometry" (SIGGRAPH Asia 2021), for line segments as Dr.Hair
//! (CVPR 2024, supplement §4.3) describes it.
//!
//! In: the strand layout (offsets), the points, λ, and the Laplacian's parts: F, the chain
//! Laplacian along each strand, and optionally N, which ties point `j` of a strand to point `j` of
//! each of its `k` nearest strands (nearest by root or by the point at half the strand). Roots are
//! fixed (R_root holds exactly), so the system is the free points' block `M = (I + λL)_ff`, a
//! sparse symmetric positive definite matrix that acts on each coordinate alone (n_free × n_free,
//! three right-hand sides).
//!
//! Out: [`Reparam::solve`], `x = M⁻¹ b`, used twice per step: the gradient in u is `M⁻¹ ∂L/∂x` (M is
//! symmetric), and an Adam step Δu in u moves the points by `Δx = M⁻¹ Δu`, so u itself is never
//! stored.
//!
//! Solver (ours): conjugate gradients preconditioned by the exact inverse of each strand's own
//! tridiagonal block (F plus the diagonal of N), warm-started from the previous solution. Without N
//! the preconditioner is M⁻¹ itself and one iteration solves exactly; with N the spectrum of the
//! preconditioned matrix is tight and a handful of iterations reach 1e-5 relative residual. We chose
//! this over a sparse Cholesky factorization (Nicolet et al. use one): the kNN graph over strands is
//! a 3D graph (scalp 2D × strand index), whose Cholesky factor fills in heavily for 50,000 children,
//! and it needs no new dependency. Dot products are summed in f64 in a fixed order, so results do
//! not depend on the thread count.
//!
//! Memory and speed: `M` is held as each strand's neighbour list and one diagonal value per point
//! (its other entries are `-λ` and `-λw`), and the strands are laid out in the Morton order of
//! their N key point, so that the neighbours a product `M p` reads are near in memory. Each CG
//! iteration is three parallel passes over runs of whole strands (`cargo bench -p hairrecon-recon
//! --bench reparam`).

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use hairrecon_core::spatial::PointIndex;

/// Which point of a strand the nearest-strand search of N uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum KnnKey {
    Root,
    /// The point at half the strand's point count (the supplement's letters demo: "at 50% of the
    /// original length").
    Middle,
}

/// How the Laplacian is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaplacianParams {
    pub lambda: f32,
    /// Nearest strands tied by N; 0 disables N.
    pub k_neighbors: usize,
    /// Weight of an N edge relative to an F edge.
    pub neighbor_weight: f32,
    pub key: KnnKey,
}

/// The factored system `M = (I + λL)_ff` of the free (non-root) points.
///
/// `M` is not stored as a sparse matrix: its off-diagonal entries are `-λ` along each strand and
/// `-λw` between point `j` of a strand and point `j` of each strand N ties it to, so the strands'
/// neighbour lists ([`Reparam::neighbours`]) and one diagonal value per point hold it. For 50,000
/// children of ~160 points and k = 10 that is ~4 MB of neighbour lists where a CSR matrix held
/// ~1.1 GB (and ~2 GB while it was built).
#[derive(Debug, Clone)]
pub struct Reparam {
    /// Global point index of each free slot, in order (the free points of a strand are contiguous).
    free: Vec<u32>,
    /// Free slot of each global point, `u32::MAX` for roots.
    slot: Vec<u32>,
    /// Free-slot ranges per strand, the strands in the solver's spatial order (a strand's
    /// "position"); the slots follow that order.
    chains: Vec<(u32, u32)>,
    /// The parallel work items: runs of whole strands of about [`RUN`] free slots each.
    runs: Vec<Run>,
    /// The strands N ties each strand to (positions), ascending: position `s`'s are
    /// `adj[adj_ptr[s]..adj_ptr[s + 1]]`.
    adj_ptr: Vec<u32>,
    adj: Vec<u32>,
    /// `M`'s diagonal per free slot: `1 + λ · degree`.
    diag: Vec<f32>,
    /// `M`'s entry between neighbouring points of N: `-λw`.
    n_val: f32,
    /// Thomas factors of each strand's tridiagonal block: `cp` and `1/den` per slot, and the
    /// off-diagonal value (`-λ`, also `M`'s entry between consecutive points of a strand).
    cp: Vec<f32>,
    inv_den: Vec<f32>,
    off: f32,
    // Scratch of the solver.
    r: Vec<Vec3>,
    z: Vec<Vec3>,
    p: Vec<Vec3>,
    ap: Vec<Vec3>,
    /// Iterations of the last solve.
    pub last_iterations: usize,
    pub tolerance: f32,
    pub max_iterations: usize,
}

/// Strand pairs tied by N (each pair once, `a < b`).
pub fn neighbor_pairs(points: &[Vec3], offsets: &[usize], k: usize, key: KnnKey) -> Vec<(u32, u32)> {
    let ns = offsets.len().saturating_sub(1);
    if k == 0 || ns < 2 {
        return Vec::new();
    }
    let keys: Vec<Vec3> = (0..ns)
        .map(|s| match key {
            KnnKey::Root => points[offsets[s]],
            KnnKey::Middle => points[offsets[s] + (offsets[s + 1] - offsets[s]) / 2],
        })
        .collect();
    let index = PointIndex::new(keys.clone(), vec![Vec3::Z; ns]);
    let mut pairs: Vec<(u32, u32)> = (0..ns)
        .into_par_iter()
        .flat_map_iter(|s| {
            index
                .nearest(keys[s], k + 1)
                .into_iter()
                .filter(move |&(t, _)| t != s)
                .take(k)
                .map(move |(t, _)| (s.min(t) as u32, s.max(t) as u32))
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

impl Reparam {
    /// Builds `M` for strands with the given offsets (roots are each strand's first point).
    pub fn new(points: &[Vec3], offsets: &[usize], params: &LaplacianParams) -> Self {
        let n = points.len();
        let ns = offsets.len().saturating_sub(1);
        let lambda = params.lambda.max(0.0);
        // The strands in a spatial order, so that the strands N ties together lie near each
        // other in memory: chains, runs and neighbour lists index strands by their position in
        // `order`.
        let order = spatial_order(points, offsets, params.key);
        let mut pos = vec![0u32; ns];
        for (k, &s) in order.iter().enumerate() {
            pos[s as usize] = k as u32;
        }
        let mut slot = vec![u32::MAX; n];
        let mut free = Vec::with_capacity(n.saturating_sub(ns));
        let mut chains = Vec::with_capacity(ns);
        for &s in &order {
            let s = s as usize;
            let a = free.len() as u32;
            for i in offsets[s] + 1..offsets[s + 1] {
                slot[i] = free.len() as u32;
                free.push(i as u32);
            }
            chains.push((a, free.len() as u32));
        }
        let nf = free.len();
        // Diagonal of L per global point: the chain's edges, then N's.
        let mut degree = vec![0.0f32; n];
        for s in 0..ns {
            for i in offsets[s]..offsets[s + 1] - 1 {
                degree[i] += 1.0;
                degree[i + 1] += 1.0;
            }
        }
        let w = params.neighbor_weight;
        let pairs = if params.k_neighbors > 0 && w > 0.0 {
            neighbor_pairs(points, offsets, params.k_neighbors, params.key)
        } else {
            Vec::new()
        };
        // Each strand's neighbours (positions in `order`), ascending.
        let mut count = vec![0u32; ns + 1];
        for &(a, b) in &pairs {
            count[pos[a as usize] as usize] += 1;
            count[pos[b as usize] as usize] += 1;
        }
        let mut adj_ptr = Vec::with_capacity(ns + 1);
        let mut acc = 0u32;
        for c in &count[..ns] {
            adj_ptr.push(acc);
            acc += c;
        }
        adj_ptr.push(acc);
        let mut fill: Vec<u32> = adj_ptr[..ns].to_vec();
        let mut adj = vec![0u32; acc as usize];
        for &(a, b) in &pairs {
            let m = (offsets[a as usize + 1] - offsets[a as usize]).min(offsets[b as usize + 1] - offsets[b as usize]);
            // Point 0 (the roots) are fixed: tie the rest.
            for j in 1..m {
                degree[offsets[a as usize] + j] += w;
                degree[offsets[b as usize] + j] += w;
            }
            let (pa, pb) = (pos[a as usize] as usize, pos[b as usize] as usize);
            adj[fill[pa] as usize] = pb as u32;
            fill[pa] += 1;
            adj[fill[pb] as usize] = pa as u32;
            fill[pb] += 1;
        }
        drop((fill, count, pairs, pos));
        for s in 0..ns {
            adj[adj_ptr[s] as usize..adj_ptr[s + 1] as usize].sort_unstable();
        }
        let diag: Vec<f32> = free.iter().map(|&gi| 1.0 + lambda * degree[gi as usize]).collect();
        drop(degree);
        // Thomas factors of each chain's tridiagonal block.
        let off = -lambda;
        let mut cp = vec![0.0f32; nf];
        let mut inv_den = vec![0.0f32; nf];
        for &(a, b) in &chains {
            for f in a as usize..b as usize {
                let d = diag[f];
                let den = if f == a as usize { d } else { d - off * cp[f - 1] };
                inv_den[f] = 1.0 / den;
                cp[f] = off / den;
            }
        }
        Self {
            free,
            slot,
            runs: runs(&chains),
            chains,
            adj_ptr,
            adj,
            diag,
            n_val: -lambda * w,
            cp,
            inv_den,
            off,
            r: vec![Vec3::ZERO; nf],
            z: vec![Vec3::ZERO; nf],
            p: vec![Vec3::ZERO; nf],
            ap: vec![Vec3::ZERO; nf],
            last_iterations: 0,
            tolerance: 1e-5,
            max_iterations: 200,
        }
    }

    /// Number of free points (unknowns per coordinate).
    pub fn len(&self) -> usize {
        self.free.len()
    }

    pub fn is_empty(&self) -> bool {
        self.free.is_empty()
    }

    /// Global point index of each free slot.
    pub fn free(&self) -> &[u32] {
        &self.free
    }

    /// Free slot of a global point (`None` for a root).
    pub fn slot(&self, global: usize) -> Option<usize> {
        let s = self.slot[global];
        (s != u32::MAX).then_some(s as usize)
    }

    /// Non-zeros of `M`.
    pub fn nnz(&self) -> usize {
        let chain_len = |s: usize| (self.chains[s].1 - self.chains[s].0) as usize;
        let along: usize = (0..self.chains.len()).map(|s| (3 * chain_len(s)).saturating_sub(2)).sum();
        let across: usize = (0..self.chains.len())
            .flat_map(|s| self.neighbours(s).iter().map(move |&t| (s, t as usize)))
            .map(|(s, t)| chain_len(s).min(chain_len(t)))
            .sum();
        along + across
    }

    /// The strands N ties the strand at position `s` to (their positions), ascending.
    pub fn neighbours(&self, s: usize) -> &[u32] {
        &self.adj[self.adj_ptr[s] as usize..self.adj_ptr[s + 1] as usize]
    }

    /// `out = M x`. Each row sums its terms in the order of its columns (the neighbours before
    /// the strand, the strand's own three, the neighbours after it), whatever the thread count.
    pub fn apply(&self, x: &[Vec3], out: &mut [Vec3]) {
        self.apply_dot(x, out);
    }

    /// `out = M x`, and `x · out` per coordinate (summed per run, then over the runs in order).
    fn apply_dot(&self, x: &[Vec3], out: &mut [Vec3]) -> DVec3 {
        let (chains, diag, off, n_val) = (&self.chains, &self.diag, self.off, self.n_val);
        let parts: Vec<DVec3> = self
            .runs
            .par_iter()
            .zip(split_runs(&self.runs, out))
            .map(|(run, out)| {
                let base = run.slots.start;
                for s in run.chains.clone() {
                    let (a, b) = (chains[s].0 as usize, chains[s].1 as usize);
                    if a == b {
                        continue;
                    }
                    let o = &mut out[a - base..b - base];
                    o.iter_mut().for_each(|v| *v = Vec3::ZERO);
                    let nb = self.neighbours(s);
                    let split = nb.partition_point(|&t| (t as usize) < s);
                    let across = |o: &mut [Vec3], t: u32| {
                        let (ta, tb) = chains[t as usize];
                        let m = ((tb - ta) as usize).min(b - a);
                        for (v, xt) in o[..m].iter_mut().zip(&x[ta as usize..ta as usize + m]) {
                            *v += *xt * n_val;
                        }
                    };
                    for &t in &nb[..split] {
                        across(o, t);
                    }
                    for (i, v) in o.iter_mut().enumerate() {
                        let f = a + i;
                        if f > a {
                            *v += x[f - 1] * off;
                        }
                        *v += x[f] * diag[f];
                        if f + 1 < b {
                            *v += x[f + 1] * off;
                        }
                    }
                    for &t in &nb[split..] {
                        across(o, t);
                    }
                }
                dot(&x[run.slots.clone()], out)
            })
            .collect();
        parts.into_iter().sum()
    }

    /// The block-tridiagonal preconditioner on one run: `z = T⁻¹ r` for the run's strands (`r`
    /// and `z` are the run's slots).
    fn precondition_run(&self, run: &Run, r: &[Vec3], z: &mut [Vec3]) {
        let (cp, inv_den, off, base) = (&self.cp, &self.inv_den, self.off, run.slots.start);
        for &(a, b) in &self.chains[run.chains.clone()] {
            let (a, b) = (a as usize, b as usize);
            if a == b {
                continue;
            }
            z[a - base] = r[a - base] * inv_den[a];
            for f in a + 1..b {
                z[f - base] = (r[f - base] - z[f - 1 - base] * off) * inv_den[f];
            }
            for f in (a..b - 1).rev() {
                z[f - base] -= z[f + 1 - base] * cp[f];
            }
        }
    }

    /// Solves `M x = b` by preconditioned conjugate gradients, starting from `x` as given (warm
    /// start). Stops at a relative residual of [`Reparam::tolerance`] per coordinate.
    ///
    /// Each iteration makes three parallel passes over the runs: `M p` with `p · M p`; the
    /// update of `x` and `r` with the preconditioner and `r · z`, `r · r`; and the new `p`. Dot
    /// products are summed in f64 per run and then over the runs in order, so the result does
    /// not depend on the thread count.
    pub fn solve(&mut self, b: &[Vec3], x: &mut [Vec3]) {
        let n = self.free.len();
        debug_assert!(b.len() == n && x.len() == n);
        let mut r = std::mem::take(&mut self.r);
        let mut z = std::mem::take(&mut self.z);
        let mut p = std::mem::take(&mut self.p);
        let mut ap = std::mem::take(&mut self.ap);
        self.apply(x, &mut ap);
        let bn: DVec3 = self
            .runs
            .par_iter()
            .map(|run| dot(&b[run.slots.clone()], &b[run.slots.clone()]))
            .collect::<Vec<_>>()
            .into_iter()
            .sum();
        let tol2 = bn * (self.tolerance as f64).powi(2);
        // r = b − M x, z = T⁻¹ r, and (r · z, r · r).
        let (mut rz, mut rr) = self.update_and_precondition(&mut r, &mut z, None, |run, r, _| {
            let s = run.slots.clone();
            for ((r, b), ap) in r.iter_mut().zip(&b[s.clone()]).zip(&ap[s]) {
                *r = *b - *ap;
            }
        });
        p.copy_from_slice(&z);
        let mut iters = 0;
        while !(rr.x <= tol2.x && rr.y <= tol2.y && rr.z <= tol2.z) && iters < self.max_iterations {
            iters += 1;
            let pap = self.apply_dot(&p, &mut ap);
            let alpha = div(rz, pap).as_vec3();
            let (rz_new, rr_new) = self.update_and_precondition(&mut r, &mut z, Some(&mut *x), |run, r, x| {
                let s = run.slots.clone();
                if let Some(x) = x {
                    for (x, p) in x.iter_mut().zip(&p[s.clone()]) {
                        *x += *p * alpha;
                    }
                }
                for (r, ap) in r.iter_mut().zip(&ap[s]) {
                    *r -= *ap * alpha;
                }
            });
            let beta = div(rz_new, rz).as_vec3();
            (rz, rr) = (rz_new, rr_new);
            p.par_iter_mut().zip(z.par_iter()).with_min_len(1 << 14).for_each(|(p, z)| *p = *z + *p * beta);
        }
        self.last_iterations = iters;
        self.r = r;
        self.z = z;
        self.p = p;
        self.ap = ap;
    }

    /// Per run: `update(run, r, x)` on the run's slots of `r` (and of `x`, when given), then
    /// `z = T⁻¹ r` there; returns `(r · z, r · r)`.
    fn update_and_precondition<U>(
        &self,
        r: &mut [Vec3],
        z: &mut [Vec3],
        x: Option<&mut [Vec3]>,
        update: U,
    ) -> (DVec3, DVec3)
    where
        U: Fn(&Run, &mut [Vec3], Option<&mut [Vec3]>) + Sync,
    {
        let xs: Vec<Option<&mut [Vec3]>> = match x {
            Some(x) => split_runs(&self.runs, x).into_iter().map(Some).collect(),
            None => self.runs.iter().map(|_| None).collect(),
        };
        let parts: Vec<(DVec3, DVec3)> = self
            .runs
            .par_iter()
            .zip(split_runs(&self.runs, r))
            .zip(split_runs(&self.runs, z))
            .zip(xs)
            .map(|(((run, r), z), x)| {
                update(run, r, x);
                self.precondition_run(run, r, z);
                (dot(r, z), dot(r, r))
            })
            .collect();
        parts.into_iter().fold((DVec3::ZERO, DVec3::ZERO), |(a, b), (c, d)| (a + c, b + d))
    }
}

/// The strands sorted by the Morton code of their N key point (ties by index): strands near each
/// other in space come near each other in the order.
fn spatial_order(points: &[Vec3], offsets: &[usize], key: KnnKey) -> Vec<u32> {
    let ns = offsets.len().saturating_sub(1);
    let keys: Vec<Vec3> = (0..ns)
        .map(|s| match key {
            KnnKey::Root => points[offsets[s]],
            KnnKey::Middle => points[offsets[s] + (offsets[s + 1] - offsets[s]) / 2],
        })
        .collect();
    let (lo, hi) = keys.iter().fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), &k| (l.min(k), h.max(k)));
    let scale = ((1u32 << 21) - 1) as f32 / (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let spread = |v: u64| {
        // The 21 low bits of `v` moved to every third bit.
        let mut v = v & 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        (v | v << 2) & 0x1249_2492_4924_9249
    };
    let code = |k: Vec3| {
        let q = ((k - lo) * scale).max(Vec3::ZERO);
        spread(q.x as u64) | spread(q.y as u64) << 1 | spread(q.z as u64) << 2
    };
    let mut order: Vec<(u64, u32)> =
        keys.iter().enumerate().map(|(s, &k)| (if k.is_finite() { code(k) } else { u64::MAX }, s as u32)).collect();
    order.sort_unstable();
    order.into_iter().map(|(_, s)| s).collect()
}

/// Free slots per parallel work item of the solver.
const RUN: usize = 1 << 14;

/// A parallel work item: whole strands (`chains`, strand indices) holding about [`RUN`] free
/// slots (`slots`).
#[derive(Debug, Clone)]
struct Run {
    chains: std::ops::Range<usize>,
    slots: std::ops::Range<usize>,
}

/// Cuts the strands into runs at strand ends (the chains are contiguous and in order).
fn runs(chains: &[(u32, u32)]) -> Vec<Run> {
    let mut runs = Vec::new();
    let (mut base, mut i) = (0usize, 0usize);
    while i < chains.len() {
        let first = i;
        i += 1;
        while i < chains.len() && chains[i].1 as usize - base <= RUN {
            i += 1;
        }
        let end = chains[i - 1].1 as usize;
        runs.push(Run { chains: first..i, slots: base..end });
        base = end;
    }
    runs
}

/// `v` cut into the runs' slot ranges.
fn split_runs<'a>(runs: &[Run], v: &'a mut [Vec3]) -> Vec<&'a mut [Vec3]> {
    let mut out = Vec::with_capacity(runs.len());
    let mut rest = v;
    for run in runs {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(run.slots.len());
        out.push(head);
        rest = tail;
    }
    out
}

fn dot(a: &[Vec3], b: &[Vec3]) -> DVec3 {
    let mut acc = DVec3::ZERO;
    for (x, y) in a.iter().zip(b) {
        acc += (*x * *y).as_dvec3();
    }
    acc
}

fn div(a: DVec3, b: DVec3) -> DVec3 {
    let f = |x: f64, y: f64| if y.abs() > 0.0 { x / y } else { 0.0 };
    DVec3::new(f(a.x, b.x), f(a.y, b.y), f(a.z, b.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strands() -> (Vec<Vec3>, Vec<usize>) {
        let mut pts = Vec::new();
        let mut offsets = vec![0];
        for s in 0..12 {
            let n = 5 + s % 4;
            for j in 0..n {
                pts.push(Vec3::new(s as f32 * 0.01, (s % 3) as f32 * 0.01, -(j as f32) * 0.01));
            }
            offsets.push(pts.len());
        }
        (pts, offsets)
    }

    /// Solves `M x = b` for a fixed `b` from zero: `x`, `M x` and the largest residual `|M x − b|`.
    fn solve_fixed(m: &mut Reparam) -> (Vec<Vec3>, Vec<Vec3>, f32) {
        let n = m.len();
        let b: Vec<Vec3> = (0..n).map(|i| Vec3::new((i as f32).sin(), (i as f32 * 0.7).cos(), 1.0)).collect();
        let mut x = vec![Vec3::ZERO; n];
        m.solve(&b, &mut x);
        let mut mx = vec![Vec3::ZERO; n];
        m.apply(&x, &mut mx);
        let err = mx.iter().zip(&b).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
        (x, mx, err)
    }

    #[test]
    fn solve_inverts_apply_with_and_without_n() {
        let (pts, offsets) = strands();
        for k in [0, 3] {
            let params = LaplacianParams { lambda: 20.0, k_neighbors: k, neighbor_weight: 1.0, key: KnnKey::Middle };
            let mut m = Reparam::new(&pts, &offsets, &params);
            let n = m.len();
            let (x, mx, err) = solve_fixed(&mut m);
            assert!(err < 1e-3, "k = {k}: residual {err}, {} iterations", m.last_iterations);
            if k == 0 {
                assert!(m.last_iterations <= 2, "the preconditioner is exact without N");
            }
            // Symmetry: ⟨Mx, y⟩ = ⟨x, My⟩.
            let y: Vec<Vec3> = (0..n).map(|i| Vec3::splat((i as f32 * 0.3).cos())).collect();
            let mut my = vec![Vec3::ZERO; n];
            m.apply(&y, &mut my);
            let (a, c) = (dot(&mx, &y), dot(&x, &my));
            assert!((a - c).abs().max_element() < 1e-3 * a.abs().max_element().max(1.0));
        }
    }

    /// `apply` is `(I + λL)_ff` as the module doc defines it: the matrix built densely from the
    /// definition (chain edges of weight 1, N edges of weight w between point j of tied strands,
    /// roots removed) times a vector, against `apply`; and `nnz` counts its non-zeros.
    #[test]
    fn apply_is_the_matrix_of_the_definition() {
        let (pts, offsets) = strands();
        let (lambda, w, k) = (7.0f32, 0.3f32, 3);
        let m = Reparam::new(
            &pts,
            &offsets,
            &LaplacianParams { lambda, k_neighbors: k, neighbor_weight: w, key: KnnKey::Root },
        );
        let n = pts.len();
        let mut l = vec![vec![0.0f64; n]; n];
        let mut edge = |i: usize, j: usize, wt: f64| {
            l[i][i] += wt;
            l[j][j] += wt;
            l[i][j] -= wt;
            l[j][i] -= wt;
        };
        for s in 0..offsets.len() - 1 {
            for i in offsets[s]..offsets[s + 1] - 1 {
                edge(i, i + 1, 1.0);
            }
        }
        let pairs = neighbor_pairs(&pts, &offsets, k, KnnKey::Root);
        assert!(pairs.len() >= 12, "every strand has neighbours");
        for &(a, b) in &pairs {
            let (oa, ob) = (offsets[a as usize], offsets[b as usize]);
            let len = (offsets[a as usize + 1] - oa).min(offsets[b as usize + 1] - ob);
            for j in 1..len {
                edge(oa + j, ob + j, w as f64);
            }
        }
        // The free slots are the points that are not roots, in the solver's order.
        let free: Vec<usize> = m.free().iter().map(|&i| i as usize).collect();
        let mut sorted = free.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).filter(|i| !offsets.contains(i)).collect::<Vec<_>>());
        assert!(free.iter().enumerate().all(|(f, &gi)| m.slot(gi) == Some(f)));
        let x: Vec<Vec3> =
            (0..free.len()).map(|i| Vec3::new((i as f32 * 1.3).sin(), (i as f32).cos(), i as f32 * 0.01)).collect();
        let mut got = vec![Vec3::ZERO; free.len()];
        m.apply(&x, &mut got);
        let mut nnz = 0;
        for (r, &gi) in free.iter().enumerate() {
            let mut want = x[r].as_dvec3();
            for (c, &gj) in free.iter().enumerate() {
                want += x[c].as_dvec3() * (lambda as f64 * l[gi][gj]);
                nnz += usize::from(gi == gj || l[gi][gj] != 0.0);
            }
            assert!(
                (got[r].as_dvec3() - want).length() < 1e-4 * want.length().max(1.0),
                "row {r}: {} vs {want}",
                got[r]
            );
        }
        assert_eq!(m.nnz(), nnz);
    }

    /// The preconditioner's strands run in parallel in runs cut at strand ends: over many runs,
    /// with a strand longer than a run and strands that are only a root, it is still `M⁻¹`
    /// exactly without N (one iteration solves).
    #[test]
    fn the_preconditioner_is_exact_across_its_parallel_runs() {
        let mut pts = Vec::new();
        let mut offsets = vec![0];
        for s in 0..3000 {
            let n = match s {
                7 => 40_000,
                11 | 2999 => 1,
                _ => 2 + s % 37,
            };
            for j in 0..n {
                pts.push(Vec3::new(s as f32 * 1e-3, (s % 5) as f32 * 1e-3, -(j as f32) * 1e-3));
            }
            offsets.push(pts.len());
        }
        let params = LaplacianParams { lambda: 20.0, k_neighbors: 0, neighbor_weight: 1.0, key: KnnKey::Root };
        let mut m = Reparam::new(&pts, &offsets, &params);
        let n = m.len();
        assert!(n > 4 << 14, "{n} free points: several runs");
        let (_, _, err) = solve_fixed(&mut m);
        assert!(err < 1e-3 && m.last_iterations <= 2, "residual {err} after {} iterations", m.last_iterations);
    }
}
