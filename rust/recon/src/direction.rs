//! Stage 3: global direction: undirected oriented points made directed (root → tip).
//!
//! In: [`OrientedPoints`] from [`crate::points3d`] (lines, 180° ambiguous) and the [`Scalp`] with
//! S(p_s). Out: the same points with every direction's sign chosen, saved as
//! `points_directed.ply` and reloaded from there.
//!
//! Follows the global optimization of Dr.Hair (`docs/method.md` §2): a graph over the points (k
//! nearest neighbours), a minimum spanning tree of it whose edge cost grows with distance and with
//! the angle between the two lines (so that the tree follows strands, not crosses them), the signs
//! fixed at points near the scalp by S(p_s) (a virtual root joined to those anchors at zero cost),
//! then propagated down the tree so that each point agrees with its parent. Components of the
//! graph with no anchor point downward (gravity). A few rounds of confidence-weighted majority
//! voting among the k neighbours (anchors held fixed) then correct isolated flips left by the tree.
//!
//! The ablation ("w/o global opt.") is [`gravity_directions`]: every direction points down (−Z).

use glam::Vec3;
use rayon::prelude::*;

use crate::metrics::PointIndex;
use crate::points3d::OrientedPoints;
use crate::roots::{scalp_point, Scalp};

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
    /// Rounds of neighbour voting after the tree.
    pub vote_rounds: usize,
}

impl Default for DirectionParams {
    fn default() -> Self {
        Self { k: 10, max_edge: 0.01, anchor_dist: 0.015, anchor_min_cos: 0.4, vote_rounds: 5 }
    }
}

/// Statistics of a direction run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionStats {
    pub anchors: u64,
    pub components: u64,
    pub components_without_anchor: u64,
    pub flips_by_vote: u64,
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
    let n = points.len();
    let mut stats = DirectionStats::default();
    if n == 0 {
        return (points.clone(), stats);
    }
    let index = PointIndex::new(points.positions.clone(), points.directions.clone());
    // kNN graph.
    let nbrs: Vec<Vec<(u32, f32)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            index
                .nearest(points.positions[i], params.k + 1)
                .into_iter()
                .filter(|&(j, d)| j != i && d <= params.max_edge)
                .map(|(j, d)| (j as u32, d))
                .collect()
        })
        .collect();
    // Anchors: sign given by S(p_s).
    let anchor: Vec<i8> = (0..n)
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
        .collect();
    stats.anchors = anchor.iter().filter(|a| **a != 0).count() as u64;
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
    (
        OrientedPoints { positions: points.positions.clone(), directions: dirs, confidence: points.confidence.clone() },
        stats,
    )
}
