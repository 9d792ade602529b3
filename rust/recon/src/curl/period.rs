//! The curls' period read off the hair surface: the autocorrelation of the surface's height along
//! the ringlet axes ([`bump_period`]).

use glam::Vec3;
use hairrecon_core::spatial::PointIndex;
use rayon::prelude::*;

/// How [`bump_period`] reads the curls' period off the hair surface.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
/// [`crate::curl::ringlet_axes`] are within 20° for three quarters of the points on the paper curly preset): the
/// period seen along a direction δ off the axis is 1/cos δ longer (6% at 20°).
///
/// Measured at commit cfcd40a on the ringlet axes of saved directed points
/// (research/notes/curly-study.md): paper curly (period 22 mm) 22.1 mm; a curly capture made with
/// `hairrecon synth-hair --curl 4.5,16` 15.7 mm; straight and wavy none; the same within 0.6 mm
/// with neighbourhoods of 25 and 60 mm.
pub fn bump_period(positions: &[Vec3], axes: &[Vec3], opts: &BumpOptions) -> BumpReport {
    let n = positions.len().min(axes.len());
    let lags = (opts.radius / opts.bin).round() as usize;
    let nbins = 2 * lags + 1;
    let empty = BumpReport { samples: 0, correlation: Vec::new(), first_min: None, period: None };
    if n == 0 || lags < 4 {
        return empty;
    }
    let index = PointIndex::new(positions[..n].to_vec(), Vec::new());
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curl::helix::phase;

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
