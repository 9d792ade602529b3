//! The hair region of the raw mesh: per vertex, the probability that it is hair, from geometry
//! (where it lies against the fitted head) and colour (a hair model against everything else,
//! learned from the capture itself), smoothed over the mesh.
//!
//! 1. **Geometry prior** ([`geometry_prior`]): a vertex on the fitted head's skin (face, ears,
//!    neck) is skin; one standing off the fitted scalp is hair; one on the scalp could be either
//!    (thin hair, a bald crown); one far from the head (shoulders, clothes, hair hanging down the
//!    back) is open.
//! 2. **Colour** ([`hair_probability`]): each vertex's mean L*a*b* colour over the views that see it.
//!    Two Gaussian mixtures, hair and not-hair, start from the confident vertices and are refitted
//!    by EM on the posterior; the posterior combines the prior's log-odds with the colour's
//!    log-likelihood ratio.
//! 3. **Smoothing**: the log-odds are averaged with the vertex's neighbours a few times, so that
//!    a speck of hair-coloured skin or a dark shadow in the face does not become a hole or an
//!    island.

use glam::Vec3;
use hairrecon_core::{Bvh, TriMesh};
use rayon::prelude::*;

use super::colour::Gmm;

/// The parameters of the hair region.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegionOptions {
    /// A vertex within this distance (mm) of the fitted head's skin is skin.
    pub skin_mm: f32,
    /// A vertex this far (mm) or farther outside the fitted scalp is hair.
    pub hair_mm: f32,
    /// Beyond this distance (mm) from the fitted head the geometry says nothing.
    pub far_mm: f32,
    /// Components of each colour mixture.
    pub components: usize,
    /// EM rounds (mixtures refitted on the posterior).
    pub rounds: usize,
    /// Colour samples the mixtures are fitted on at most (a regular subsample of the vertices).
    pub max_samples: usize,
    /// Averaging passes of the log-odds over mesh neighbours.
    pub smoothing: usize,
}

impl Default for RegionOptions {
    fn default() -> Self {
        Self { skin_mm: 2.0, hair_mm: 3.0, far_mm: 80.0, components: 4, rounds: 4, max_samples: 30_000, smoothing: 30 }
    }
}

/// Prior probabilities of hair, by where a vertex lies against the fitted head.
pub mod prior {
    /// Off the scalp by more than `hair_mm`.
    pub const OFF_SCALP: f32 = 0.9;
    /// On the scalp (thin hair or bare skin).
    pub const ON_SCALP: f32 = 0.6;
    /// On the skin of the face, ears or neck.
    pub const ON_SKIN: f32 = 0.1;
    /// Off the skin: hair over the face or neck, or a collar.
    pub const OFF_SKIN: f32 = 0.5;
    /// Far from the head, or inside it.
    pub const FAR: f32 = 0.5;
}

/// The geometry prior of every vertex of `raw` (see the module doc), and whether it lies farther
/// than [`RegionOptions::far_mm`] from the head (nothing of the face, neck or scalp near it).
/// `head` and `scalp` are the fitted head and its scalp, in the raw mesh's frame, in metres.
pub fn geometry_prior(raw: &TriMesh, head: &Bvh, scalp: &Bvh, opts: &RegionOptions) -> (Vec<f32>, Vec<bool>) {
    let far = opts.far_mm * 1e-3;
    raw.vertices
        .par_iter()
        .map(|&p| {
            let Some(d) = head.signed_distance(p, far) else {
                return (prior::FAR, true);
            };
            if d < -opts.hair_mm * 1e-3 {
                return (prior::FAR, false);
            }
            // The nearest part of the head is scalp when the scalp is (about) as near as the head.
            let head_dist = d.abs();
            let on_scalp = scalp.closest_point(p, head_dist + 1.5e-3).is_some();
            let prior = match (on_scalp, d * 1e3) {
                (true, mm) if mm >= opts.hair_mm => prior::OFF_SCALP,
                (true, _) => prior::ON_SCALP,
                (false, mm) if mm <= opts.skin_mm => prior::ON_SKIN,
                (false, _) => prior::OFF_SKIN,
            };
            (prior, false)
        })
        .unzip()
}

/// The mesh's vertex neighbours (each edge once per direction), as CSR offsets and indices.
pub fn vertex_neighbours(mesh: &TriMesh) -> (Vec<u32>, Vec<u32>) {
    let n = mesh.vertices.len();
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 6);
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            pairs.push((a, b));
            pairs.push((b, a));
        }
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    let mut offsets = vec![0u32; n + 1];
    for &(a, _) in &pairs {
        offsets[a as usize + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    (offsets, pairs.into_iter().map(|(_, b)| b).collect())
}

/// A posterior this sure teaches the next round's models.
const CONFIDENT: f32 = 0.9;

/// log density of the "anything else" colour: uniform over the L*a*b* gamut (about 100 × 200 ×
/// 200). A colour that neither model has seen (a red sweater when only skin taught the other
/// model) is not called hair because the hair model is the lesser stranger.
const LOG_UNIFORM: f64 = -15.2;

/// The colour's log-likelihood ratio of hair against the rest (the other model or anything else).
fn colour_log_ratio(hair: &Gmm, other: &Gmm, c: Vec3) -> f32 {
    let h = hair.log_density(c);
    let o = other.log_density(c);
    let rest = o.max(LOG_UNIFORM) + (-(o - LOG_UNIFORM).abs()).exp().ln_1p();
    ((h - rest) as f32).clamp(-8.0, 8.0)
}

fn logit(p: f32) -> f32 {
    let p = p.clamp(1e-4, 1.0 - 1e-4);
    (p / (1.0 - p)).ln()
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// What the colour models learned, for the report.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegionSummary {
    pub vertices: usize,
    /// Vertices seen by at least one view.
    pub coloured: usize,
    /// Vertices of probability ≥ 0.5.
    pub hair_vertices: usize,
    /// The mixtures' component means (L*, a*, b*) and weights.
    pub hair_colours: Vec<[f64; 4]>,
    pub other_colours: Vec<[f64; 4]>,
}

/// The hair probability of every vertex from its geometry prior and its colour (L*a*b*, `None`
/// where no view sees it); see the module doc. Deterministic.
pub fn hair_probability(
    prior: &[f32],
    colours: &[Option<Vec3>],
    neighbours: &(Vec<u32>, Vec<u32>),
    opts: &RegionOptions,
) -> (Vec<f32>, Option<ColourModels>, RegionSummary) {
    let n = prior.len();
    let seen: Vec<usize> = (0..n).filter(|&i| colours[i].is_some()).collect();
    let stride = seen.len().div_ceil(opts.max_samples.max(1)).max(1);
    let sample: Vec<usize> = seen.iter().copied().step_by(stride).collect();
    let xs: Vec<Vec3> = sample.iter().map(|&i| colours[i].unwrap_or(Vec3::ZERO)).collect();
    let prior_logit: Vec<f32> = prior.iter().map(|&p| logit(p)).collect();
    // The first mixtures come from the vertices the geometry is sure of (hair off the scalp, skin
    // on the face); later ones from the vertices the posterior is sure of. Only confident vertices
    // teach a model: the open ones (far from the head, on the scalp) hold both hair and not-hair,
    // and would teach each model the other's colours.
    let mut w_hair: Vec<f32> = sample.iter().map(|&i| (prior[i] >= prior::OFF_SCALP) as u8 as f32).collect();
    let mut w_other: Vec<f32> = sample.iter().map(|&i| (prior[i] <= prior::ON_SKIN) as u8 as f32).collect();
    let mut models: Option<(Gmm, Gmm)> = None;
    let mut posterior_logit = prior_logit.clone();
    for round in 0..opts.rounds {
        let seed = round as u64;
        let hair = Gmm::fit(&xs, &w_hair, opts.components, 8, 11 + seed);
        let other = Gmm::fit(&xs, &w_other, opts.components, 8, 23 + seed);
        if let (None, Some(other)) = (&hair, &other) {
            // Nothing stands off the scalp (a bald or shaved head): no hair colour to learn. A
            // colour the skin explains better than chance is skin.
            if round == 0 {
                posterior_logit = (0..n)
                    .into_par_iter()
                    .map(|i| match colours[i] {
                        Some(c) => prior_logit[i] + ((LOG_UNIFORM - other.log_density(c)) as f32).clamp(-8.0, 8.0),
                        None => prior_logit[i],
                    })
                    .collect();
            }
            break;
        }
        let (Some(hair), Some(other)) = (hair, other) else {
            break;
        };
        posterior_logit = (0..n)
            .into_par_iter()
            .map(|i| match colours[i] {
                Some(c) => prior_logit[i] + colour_log_ratio(&hair, &other, c),
                None => prior_logit[i],
            })
            .collect();
        for (k, &i) in sample.iter().enumerate() {
            let p = sigmoid(posterior_logit[i]);
            w_hair[k] = (p >= CONFIDENT) as u8 as f32;
            w_other[k] = (p <= 1.0 - CONFIDENT) as u8 as f32;
        }
        models = Some((hair, other));
    }
    let (offsets, adj) = neighbours;
    for _ in 0..opts.smoothing {
        posterior_logit = (0..n)
            .into_par_iter()
            .map(|i| {
                let (a, b) = (offsets[i] as usize, offsets[i + 1] as usize);
                if a == b {
                    return posterior_logit[i];
                }
                let mean = adj[a..b].iter().map(|&j| posterior_logit[j as usize]).sum::<f32>() / (b - a) as f32;
                0.5 * (posterior_logit[i] + mean)
            })
            .collect();
    }
    let prob: Vec<f32> = posterior_logit.iter().map(|&l| sigmoid(l)).collect();
    let table = |g: &Gmm| g.means().iter().map(|(w, m)| [m.x, m.y, m.z, *w]).collect();
    let summary = RegionSummary {
        vertices: n,
        coloured: seen.len(),
        hair_vertices: prob.iter().filter(|&&p| p >= 0.5).count(),
        hair_colours: models.as_ref().map(|(h, _)| table(h)).unwrap_or_default(),
        other_colours: models.as_ref().map(|(_, o)| table(o)).unwrap_or_default(),
    };
    (prob, models.map(|(hair, other)| ColourModels { hair, other }), summary)
}

/// The colour models the region learned: hair against the rest.
#[derive(Debug, Clone)]
pub struct ColourModels {
    pub hair: Gmm,
    pub other: Gmm,
}

impl ColourModels {
    /// log p(hair colour) − log p(the rest), the rest being the other model or a uniform density over
    /// the gamut (whichever explains the colour), clamped to ±8.
    pub fn log_ratio(&self, lab: Vec3) -> f32 {
        colour_log_ratio(&self.hair, &self.other, lab)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of vertices in a row (each the neighbour of the next): the first half brown and
    /// marked hair by geometry, the second half pink skin; a brown vertex in the skin half whose
    /// geometry says skin, and a far brown vertex whose geometry says nothing.
    #[test]
    fn colour_decides_where_geometry_is_open_and_smoothing_removes_specks() {
        let n = 200;
        let brown = Vec3::new(30.0, 12.0, 20.0);
        let pink = Vec3::new(70.0, 15.0, 15.0);
        let mut prior = vec![0.0; n];
        let mut colours = vec![None; n];
        let mut state = 3u64;
        let mut jitter = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 4.0
        };
        for i in 0..n {
            let hair = i < n / 2;
            prior[i] = if hair { prior::OFF_SCALP } else { prior::ON_SKIN };
            let c = if hair { brown } else { pink };
            colours[i] = Some(c + Vec3::new(jitter(), jitter(), jitter()));
        }
        // Open geometry: far vertices, one brown, one pink.
        prior[60] = prior::FAR;
        prior[160] = prior::FAR;
        colours[160] = Some(pink);
        // A brown speck on skin.
        colours[150] = Some(brown);
        let mut offsets = vec![0u32];
        let mut adj = Vec::new();
        for i in 0..n {
            if i > 0 {
                adj.push(i as u32 - 1);
            }
            if i + 1 < n {
                adj.push(i as u32 + 1);
            }
            offsets.push(adj.len() as u32);
        }
        let opts = RegionOptions { components: 2, ..Default::default() };
        let (p, _, s) = hair_probability(&prior, &colours, &(offsets, adj), &opts);
        assert!(p[60] > 0.8, "a far brown vertex among hair is hair: {}", p[60]);
        assert!(p[160] < 0.2, "a far pink vertex is not: {}", p[160]);
        assert!(p[150] < 0.5, "one brown speck on the skin stays skin: {}", p[150]);
        assert!(p[10] > 0.9 && p[190] < 0.1, "{} {}", p[10], p[190]);
        assert_eq!(s.coloured, n);
        assert_eq!(s.hair_vertices, p.iter().filter(|&&x| x >= 0.5).count());
        assert!(s.hair_vertices.abs_diff(n / 2) <= 3, "{}", s.hair_vertices);
    }

    #[test]
    fn a_bald_head_has_no_hair_when_its_scalp_is_skin_coloured() {
        // Skin on the face (prior ON_SKIN) and on the scalp (ON_SCALP), nothing off the scalp.
        let n = 100;
        let prior: Vec<f32> = (0..n).map(|i| if i < 50 { prior::ON_SKIN } else { prior::ON_SCALP }).collect();
        let colours: Vec<Option<Vec3>> =
            (0..n).map(|i| Some(Vec3::new(70.0 + (i % 7) as f32, 15.0 + (i % 3) as f32, 15.0))).collect();
        let neighbours = (vec![0u32; n + 1], Vec::new());
        let (p, models, _) = hair_probability(&prior, &colours, &neighbours, &RegionOptions::default());
        assert!(models.is_none());
        assert!(p.iter().all(|&x| x < 0.1), "{:?}", &p[50..60]);
    }

    #[test]
    fn neighbours_of_a_cube_corner_are_its_edges_and_diagonals() {
        let cube = hairrecon_core::mesh::unit_cube();
        let (off, adj) = vertex_neighbours(&cube);
        assert_eq!(off.len(), cube.vertices.len() + 1);
        // Every cube vertex has 3 cube edges plus the face diagonals that triangulation adds.
        for v in 0..cube.vertices.len() {
            let k = (off[v + 1] - off[v]) as usize;
            assert!((3..=6).contains(&k), "vertex {v}: {k}");
            for &j in &adj[off[v] as usize..off[v + 1] as usize] {
                assert!(adj[off[j as usize] as usize..off[j as usize + 1] as usize].contains(&(v as u32)));
            }
        }
    }
}
