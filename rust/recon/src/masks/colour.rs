//! Colour models of hair and of everything else: CIE L*a*b* (a perceptual space, where a
//! Euclidean step means about the same visible difference in dark hair and in pale skin) and
//! weighted Gaussian mixtures fitted by expectation-maximisation.

use glam::{DMat3, DVec3, Vec3};

/// Linear RGB (light, as a camera adds it) of an sRGB-encoded colour with channels in [0, 1].
pub fn srgb_to_linear(c: [f32; 3]) -> Vec3 {
    let lin = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    Vec3::new(lin(c[0]), lin(c[1]), lin(c[2]))
}

/// CIE L*a*b* (D65 white) of an sRGB-encoded colour with channels in [0, 1].
pub fn srgb_to_lab(c: [f32; 3]) -> Vec3 {
    linear_to_lab(srgb_to_linear(c))
}

/// CIE L*a*b* (D65 white) of a linear RGB colour ([`srgb_to_linear`]).
pub fn linear_to_lab(Vec3 { x: r, y: g, z: b }: Vec3) -> Vec3 {
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
    let f = |t: f32| {
        if t > 0.008856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    Vec3::new(116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz))
}

/// One Gaussian of a mixture, kept as what the density needs.
#[derive(Debug, Clone, Copy)]
struct Component {
    weight: f64,
    mean: DVec3,
    inv_cov: DMat3,
    /// log(weight) − ½ log det(2π Σ).
    log_norm: f64,
}

/// A Gaussian mixture over colours (L*a*b*), full covariances.
#[derive(Debug, Clone)]
pub struct Gmm {
    components: Vec<Component>,
}

/// The smallest variance per axis (L*a*b* units squared): a cluster of identical colours (a flat
/// rendered background) must not become a spike that claims everything near it.
const MIN_VARIANCE: f64 = 4.0;

impl Gmm {
    /// Fits `k` components to `samples` weighted by `weights` (same length): seeded k-means++
    /// centres, a few k-means steps, then `iterations` of weighted EM. `None` when the weights sum
    /// to (almost) nothing.
    pub fn fit(samples: &[Vec3], weights: &[f32], k: usize, iterations: usize, seed: u64) -> Option<Self> {
        let total: f64 = weights.iter().map(|&w| w.max(0.0) as f64).sum();
        if samples.is_empty() || total < 1e-6 || k == 0 {
            return None;
        }
        let x: Vec<DVec3> = samples.iter().map(|s| s.as_dvec3()).collect();
        let w: Vec<f64> = weights.iter().map(|&w| w.max(0.0) as f64).collect();
        let centres = kmeans_pp(&x, &w, k, seed);
        // Hard assignments to start the covariances.
        let mut resp = vec![0.0f64; x.len() * centres.len()];
        for (i, p) in x.iter().enumerate() {
            let j = nearest(&centres, *p);
            resp[i * centres.len() + j] = 1.0;
        }
        let mut gmm = Self::m_step(&x, &w, &resp, centres.len())?;
        for _ in 0..iterations {
            let kk = gmm.components.len();
            let mut resp = vec![0.0f64; x.len() * kk];
            for (i, p) in x.iter().enumerate() {
                let row = &mut resp[i * kk..(i + 1) * kk];
                let mut best = f64::NEG_INFINITY;
                for (j, c) in gmm.components.iter().enumerate() {
                    row[j] = c.log_density(*p);
                    best = best.max(row[j]);
                }
                let mut s = 0.0;
                for r in row.iter_mut() {
                    *r = (*r - best).exp();
                    s += *r;
                }
                for r in row.iter_mut() {
                    *r /= s;
                }
            }
            gmm = Self::m_step(&x, &w, &resp, kk)?;
        }
        Some(gmm)
    }

    fn m_step(x: &[DVec3], w: &[f64], resp: &[f64], k: usize) -> Option<Self> {
        let total: f64 = w.iter().sum();
        let mut comps = Vec::with_capacity(k);
        for j in 0..k {
            let (mut n, mut mean) = (0.0, DVec3::ZERO);
            for (i, p) in x.iter().enumerate() {
                let r = w[i] * resp[i * k + j];
                n += r;
                mean += r * *p;
            }
            if n < 1e-9 * total.max(1e-12) || n <= 0.0 {
                continue; // an empty component is dropped
            }
            mean /= n;
            let mut cov = DMat3::ZERO;
            for (i, p) in x.iter().enumerate() {
                let r = w[i] * resp[i * k + j];
                if r > 0.0 {
                    let d = *p - mean;
                    cov += r * outer(d, d);
                }
            }
            cov *= 1.0 / n;
            cov += DMat3::from_diagonal(DVec3::splat(MIN_VARIANCE));
            let det = cov.determinant();
            if !(det.is_finite() && det > 0.0) {
                continue;
            }
            let weight = n / total;
            let log_norm = weight.ln() - 0.5 * ((2.0 * std::f64::consts::PI).powi(3) * det).ln();
            comps.push(Component { weight, mean, inv_cov: cov.inverse(), log_norm });
        }
        (!comps.is_empty()).then_some(Self { components: comps })
    }

    /// log p(colour) under the mixture.
    pub fn log_density(&self, c: Vec3) -> f64 {
        let p = c.as_dvec3();
        let logs: Vec<f64> = self.components.iter().map(|k| k.log_density(p)).collect();
        let best = logs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        best + logs.iter().map(|l| (l - best).exp()).sum::<f64>().ln()
    }

    /// The mixture's components: (weight, mean).
    pub fn means(&self) -> Vec<(f64, DVec3)> {
        self.components.iter().map(|c| (c.weight, c.mean)).collect()
    }
}

impl Component {
    fn log_density(&self, p: DVec3) -> f64 {
        let d = p - self.mean;
        self.log_norm - 0.5 * d.dot(self.inv_cov * d)
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

fn nearest(centres: &[DVec3], p: DVec3) -> usize {
    let mut best = (0, f64::INFINITY);
    for (j, c) in centres.iter().enumerate() {
        let d = c.distance_squared(p);
        if d < best.1 {
            best = (j, d);
        }
    }
    best.0
}

/// Weighted k-means++ seeding followed by five Lloyd steps; deterministic for a seed.
fn kmeans_pp(x: &[DVec3], w: &[f64], k: usize, seed: u64) -> Vec<DVec3> {
    let mut rng = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        rng = rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let pick = |scores: &[f64], u: f64| {
        let total: f64 = scores.iter().sum();
        let mut acc = 0.0;
        let target = u * total;
        for (i, s) in scores.iter().enumerate() {
            acc += s;
            if acc >= target && *s > 0.0 {
                return i;
            }
        }
        scores.iter().rposition(|s| *s > 0.0).unwrap_or(0)
    };
    let mut centres = vec![x[pick(w, next())]];
    let mut d2: Vec<f64> = x.iter().map(|p| p.distance_squared(centres[0])).collect();
    while centres.len() < k {
        let scores: Vec<f64> = d2.iter().zip(w).map(|(d, w)| d * w).collect();
        if scores.iter().sum::<f64>() <= 0.0 {
            break; // fewer distinct colours than components
        }
        let c = x[pick(&scores, next())];
        centres.push(c);
        for (d, p) in d2.iter_mut().zip(x) {
            *d = d.min(p.distance_squared(c));
        }
    }
    for _ in 0..5 {
        let mut sums = vec![(DVec3::ZERO, 0.0f64); centres.len()];
        for (p, &wi) in x.iter().zip(w) {
            let j = nearest(&centres, *p);
            sums[j].0 += wi * *p;
            sums[j].1 += wi;
        }
        for (c, (s, n)) in centres.iter_mut().zip(sums) {
            if n > 0.0 {
                *c = s / n;
            }
        }
    }
    centres
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_of_white_black_and_srgb_red_match_the_standard() {
        let w = srgb_to_lab([1.0, 1.0, 1.0]);
        assert!((w.x - 100.0).abs() < 0.05 && w.y.abs() < 0.05 && w.z.abs() < 0.05, "{w}");
        let k = srgb_to_lab([0.0, 0.0, 0.0]);
        assert!(k.length() < 0.01, "{k}");
        // sRGB red is L* 53.24, a* 80.09, b* 67.20 (Bruce Lindbloom's calculator).
        let r = srgb_to_lab([1.0, 0.0, 0.0]);
        assert!((r - Vec3::new(53.24, 80.09, 67.20)).length() < 0.2, "{r}");
    }

    #[test]
    fn a_two_cluster_mixture_finds_both_clusters_and_ranks_points_by_them() {
        // Two blobs in Lab, the second three times as heavy.
        let mut s = Vec::new();
        let mut state = 7u64;
        let mut u = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) as f32 / (1u64 << 31) as f32) - 0.5
        };
        for i in 0..400 {
            let c = if i % 4 == 0 { Vec3::new(30.0, 10.0, 20.0) } else { Vec3::new(70.0, -5.0, -10.0) };
            s.push(c + 6.0 * Vec3::new(u(), u(), u()));
        }
        let w = vec![1.0; s.len()];
        let g = Gmm::fit(&s, &w, 2, 10, 1).unwrap();
        let mut m = g.means();
        m.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        assert!((m[0].0 - 0.25).abs() < 0.02 && (m[1].0 - 0.75).abs() < 0.02, "{m:?}");
        assert!((m[0].1 - DVec3::new(30.0, 10.0, 20.0)).length() < 1.0, "{m:?}");
        assert!((m[1].1 - DVec3::new(70.0, -5.0, -10.0)).length() < 1.0, "{m:?}");
        assert!(g.log_density(Vec3::new(70.0, -5.0, -10.0)) > g.log_density(Vec3::new(50.0, 2.0, 5.0)) + 3.0);
    }
}
