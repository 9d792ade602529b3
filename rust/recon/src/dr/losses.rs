//! The losses of Dr.Hair's strand optimization (CVPR 2024, §3.2; supplement §3.2 lists them:
//! L_m, L_o, R_root, R_c and a regularizer that equalises segment lengths).
//!
//! - [`image_loss`]: per view, on the anti-aliased render `ĉ` (channels coverage and
//!   `(cos 2θ, sin 2θ)`, see `hairrecon_raster::channel`):
//!   `L_m = ½ w_m Σ_p (ĉ_cov − m)²` against the hair mask `m ∈ [0, 1]`, and
//!   `L_o = ½ w_o Σ_p κ_p ‖ĉ_o − ĉ_cov t_p‖²` against the Gabor orientation `t_p = (cos 2θ, sin 2θ)`
//!   with confidence `κ_p`. The rendered orientation channels are premultiplied by coverage
//!   (background renders 0), so comparing them with `ĉ_cov t` weights the orientation error by the
//!   rendered coverage, and a pixel the strands do not reach costs nothing. Where the target has a
//!   head depth map, a pixel whose nearest strand lies behind the head renders as background and
//!   sends no gradient (the head occludes it; ours).
//! - [`regularizers`]: `R_c = ½ w_c Σ ‖p_{i−1} − 2p_i + p_{i+1} − c_i‖² / s²` (curvature as second
//!   differences, against a reference `c` that is 0, or the second differences the strands started
//!   with: see [`second_differences`]) and `R_len = ½ w_len Σ (l_j − l̄)² / s²` per strand (segment lengths against their
//!   strand's mean; the mean's own derivative cancels since `Σ (l_j − l̄) = 0`), with `s` a fixed
//!   length scale (the median initial segment length), so the weights are dimensionless. R_root is
//!   exact: roots are not optimized (see [`crate::dr::reparam`]).

use glam::Vec3;
use hairrecon_raster::{channel, Image};

use super::DrView;

/// Weights of the losses.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LossWeights {
    pub mask: f32,
    pub orientation: f32,
    pub curvature: f32,
    pub length: f32,
}

impl Default for LossWeights {
    /// Curvature 0.05: with the uniform Adam's 0.99 quantile (points move, see `DrOptions::
    /// adam_quantile`) a weight of 0.5 straightened curls (paper curly, 20 guide steps: 50.7
    /// against 52.1 at 0.05, undirected F1 at 2 mm/20°) and 0.05 cost straight nothing (85.1 both).
    fn default() -> Self {
        Self { mask: 1.0, orientation: 0.5, curvature: 0.05, length: 0.5 }
    }
}

/// The value of each loss term (weighted, as they enter the total).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LossTerms {
    /// L_m, the silhouette term.
    pub mask: f64,
    /// L_o, the orientation term.
    pub orientation: f64,
    /// R_c, the curvature regularizer.
    pub curvature: f64,
    /// R_len, the segment-length regularizer.
    pub length: f64,
}

impl LossTerms {
    /// The names of the terms, in the order of [`LossTerms::values`].
    pub const NAMES: [&'static str; 4] = ["mask", "orientation", "curvature", "length"];

    pub fn values(&self) -> [f64; 4] {
        [self.mask, self.orientation, self.curvature, self.length]
    }

    pub fn total(&self) -> f64 {
        self.values().iter().sum()
    }
}

impl std::ops::AddAssign for LossTerms {
    fn add_assign(&mut self, o: Self) {
        self.mask += o.mask;
        self.orientation += o.orientation;
        self.curvature += o.curvature;
        self.length += o.length;
    }
}

impl std::ops::Mul<f64> for LossTerms {
    type Output = Self;
    fn mul(self, s: f64) -> Self {
        Self {
            mask: self.mask * s,
            orientation: self.orientation * s,
            curvature: self.curvature * s,
            length: self.length * s,
        }
    }
}

/// L_m + L_o of one view (in `mask` and `orientation`; the regularizers are 0); writes ∂L/∂ĉ into
/// `d_image` (same shape as `img`). `strand_depth` is the hard raster's depth per pixel
/// (`f32::INFINITY` for background).
pub fn image_loss(img: &Image, strand_depth: &[f32], view: &DrView, w: &LossWeights, d_image: &mut Image) -> LossTerms {
    let nch = img.channels;
    d_image.reset(img.width, img.height, nch);
    let (mut lm, mut lo) = (0.0f64, 0.0f64);
    for p in 0..img.num_pixels() {
        let c = &img.data[p * nch..p * nch + 3];
        let hidden = view.head_depth.as_ref().is_some_and(|h| strand_depth[p] > h[p]);
        let (cov, oc, os) =
            if hidden { (0.0, 0.0, 0.0) } else { (c[channel::COVERAGE], c[channel::COS2], c[channel::SIN2]) };
        let [tc, ts, conf] = view.orientation[p];
        let em = cov - view.mask[p];
        let (rc, rs) = (oc - cov * tc, os - cov * ts);
        let wo = w.orientation * conf;
        lm += 0.5 * (w.mask * em * em) as f64;
        lo += 0.5 * (wo * (rc * rc + rs * rs)) as f64;
        if hidden {
            continue;
        }
        let d = &mut d_image.data[p * nch..p * nch + 3];
        d[channel::COVERAGE] = w.mask * em - wo * (rc * tc + rs * ts);
        d[channel::COS2] = wo * rc;
        d[channel::SIN2] = wo * rs;
    }
    LossTerms { mask: lm, orientation: lo, ..Default::default() }
}

/// The second differences `p_{i−1} − 2p_i + p_{i+1}` of strands with the given offsets, one per
/// point (0 at roots and tips): the reference of R_c that keeps the strands' own curvature (curls
/// included) and penalizes only its change.
pub fn second_differences(points: &[Vec3], offsets: &[usize]) -> Vec<Vec3> {
    let mut c = vec![Vec3::ZERO; points.len()];
    for w in offsets.windows(2) {
        for i in w[0] + 1..w[1].saturating_sub(1) {
            c[i] = points[i - 1] - points[i] * 2.0 + points[i + 1];
        }
    }
    c
}

/// R_c + R_len over strands with the given offsets (in `curvature` and `length`; the image terms
/// are 0); adds the gradient into `grad`. `reference`: per point, the second difference R_c pulls
/// toward (see [`second_differences`]); None: 0, straight strands.
pub fn regularizers(
    points: &[Vec3],
    offsets: &[usize],
    scale: f32,
    w: &LossWeights,
    reference: Option<&[Vec3]>,
    grad: &mut [Vec3],
) -> LossTerms {
    let inv_s2 = 1.0 / (scale * scale).max(1e-20);
    let (wc, wl) = (w.curvature * inv_s2, w.length * inv_s2);
    let (mut lc, mut ll) = (0.0f64, 0.0f64);
    for s in 0..offsets.len().saturating_sub(1) {
        let (o, e) = (offsets[s], offsets[s + 1]);
        let p = &points[o..e];
        let g = &mut grad[o..e];
        let n = p.len();
        if wl > 0.0 && n >= 3 {
            let mean = p.windows(2).map(|q| (q[1] - q[0]).length()).sum::<f32>() / (n - 1) as f32;
            for i in 0..n - 1 {
                let v = p[i + 1] - p[i];
                let l = v.length().max(1e-12);
                let e = l - mean;
                ll += 0.5 * (wl * e * e) as f64;
                let gv = v * (wl * e / l);
                g[i + 1] += gv;
                g[i] -= gv;
            }
        }
        if wc > 0.0 {
            for i in 1..n.saturating_sub(1) {
                let c0 = reference.map_or(Vec3::ZERO, |r| r[o + i]);
                let c = p[i - 1] - p[i] * 2.0 + p[i + 1] - c0;
                lc += 0.5 * (wc * c.length_squared()) as f64;
                let gc = c * wc;
                g[i - 1] += gc;
                g[i] -= gc * 2.0;
                g[i + 1] += gc;
            }
        }
    }
    LossTerms { curvature: lc, length: ll, ..Default::default() }
}

/// The median segment length of strands with the given offsets (the length scale `s`).
pub fn median_segment_length(points: &[Vec3], offsets: &[usize]) -> f32 {
    let mut l: Vec<f32> = Vec::with_capacity(points.len());
    for s in 0..offsets.len().saturating_sub(1) {
        l.extend(points[offsets[s]..offsets[s + 1]].windows(2).map(|q| (q[1] - q[0]).length()));
    }
    if l.is_empty() {
        return 1e-3;
    }
    let k = l.len() / 2;
    l.select_nth_unstable_by(k, f32::total_cmp);
    l[k].max(1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regularizer_gradient_matches_finite_differences() {
        let pts: Vec<Vec3> = (0..7)
            .map(|i| Vec3::new((i as f32 * 0.9).sin() * 0.003, 0.002 * i as f32, -0.001 * (i * i) as f32))
            .collect();
        let offsets = [0usize, 3, 7];
        let w = LossWeights { mask: 0.0, orientation: 0.0, curvature: 0.7, length: 1.3 };
        let s = 0.002;
        // A reference from other strands, so that the relative R_c has a gradient to check.
        let other: Vec<Vec3> = pts.iter().map(|p| Vec3::new(p.y, -p.x, 0.5 * p.z)).collect();
        let reference = second_differences(&other, &offsets);
        for r in [None, Some(reference.as_slice())] {
            let mut g = vec![Vec3::ZERO; pts.len()];
            regularizers(&pts, &offsets, s, &w, r, &mut g);
            let h = 1e-6f32;
            for i in 0..pts.len() {
                for c in 0..3 {
                    let (mut a, mut b) = (pts.clone(), pts.clone());
                    a[i][c] += h;
                    b[i][c] -= h;
                    let mut scratch = vec![Vec3::ZERO; pts.len()];
                    let fd = (regularizers(&a, &offsets, s, &w, r, &mut scratch).total()
                        - regularizers(&b, &offsets, s, &w, r, &mut scratch).total())
                        / (2.0 * h as f64);
                    let err = (fd as f32 - g[i][c]).abs();
                    assert!(err <= 0.02 * fd.abs() as f32 + 0.5, "point {i} coord {c}: fd {fd} analytic {}", g[i][c]);
                }
            }
        }
    }

    #[test]
    fn relative_curvature_is_zero_at_the_reference_and_positive_off_it() {
        // A helix (a curl of 6 mm radius) costs R_c against straightness but nothing against its own
        // second differences; a kink of 0.5 mm at one point costs only the kink against them.
        let helix: Vec<Vec3> = (0..40)
            .map(|i| {
                let t = i as f32 * 0.25;
                Vec3::new(0.006 * t.cos(), 0.006 * t.sin(), -0.0035 * t)
            })
            .collect();
        let offsets = [0usize, 40];
        let w = LossWeights { mask: 0.0, orientation: 0.0, curvature: 1.0, length: 0.0 };
        let reference = second_differences(&helix, &offsets);
        let mut g = vec![Vec3::ZERO; helix.len()];
        let absolute = regularizers(&helix, &offsets, 0.001, &w, None, &mut g).curvature;
        let relative = regularizers(&helix, &offsets, 0.001, &w, Some(&reference), &mut g).curvature;
        // Σ over 38 interior points of ½‖c‖²/s², ‖c‖ = 2r(1 − cos 0.25) = 3.73e-4 m: 38 · ½ · 0.139.
        assert!((absolute - 2.64).abs() < 0.03, "absolute R_c {absolute}");
        assert!(relative.abs() < 1e-9, "relative R_c at its reference {relative}");
        let mut kinked = helix.clone();
        kinked[20].x += 0.0005;
        // The kink changes three second differences by (1, −2, 1) · 0.5 mm: ½ · (0.25 + 1 + 0.25) = 0.75.
        let rel_kink = regularizers(&kinked, &offsets, 0.001, &w, Some(&reference), &mut g).curvature;
        assert!((rel_kink - 0.75).abs() < 1e-3, "relative R_c of the kink {rel_kink}");
    }
}
