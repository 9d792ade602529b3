//! Splatting-style anti-aliasing (Cole et al., "Differentiable surface rendering via
//! non-differentiable sampling", ICCV 2021), for segment primitives.
//!
//! Every pixel centre `p` covered by a primitive is a surface sample; its screen position is
//! re-expressed from the primitive's corners with fixed local coordinates, `q_p = Σ_k w_k(t, σ)
//! corner_k` (bilinear in the position `t` along the axis and the signed fraction `σ` of the half
//! width; `q_p = p` in the forward pass). Background pixels are samples fixed at their centres with
//! colour 0. Each sample is splatted with a Gaussian kernel `k(x − q) = exp(−|x − q|² / (2 σ_k²))`,
//! `σ_k = 0.5` px, over the 3×3 neighbourhood, and normalised:
//!
//! `ĉ(x) = Σ_p k(x − q_p) c(p) / Σ_p k(x − q_p)`.
//!
//! Backward: `∂ĉ(x)/∂q_p = (c(p) − ĉ(x)) / W(x) · k(x − q_p) (x − q_p) / σ_k²`, then to the corners
//! through the bilinear weights.

use glam::Vec2;
use rayon::prelude::*;

use crate::aa_output::AaOutput;
use crate::image::Image;
use crate::rasterize::Buffers;
use crate::screen::{Screen, SegmentGrads};

const SIGMA: f32 = 0.5;

/// `k` at squared distances 0, 1 and 2 for σ_k = 0.5: exp(0), exp(−2), exp(−4).
const K: [f32; 3] = [1.0, 0.135_335_28, 0.018_315_64];

#[inline]
fn kernel(dx: i32, dy: i32) -> f32 {
    K[(dx * dx + dy * dy) as usize]
}

#[inline]
fn weight_sum(x: i32, y: i32, w: i32, h: i32) -> f32 {
    let mut s = 0.0;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (px, py) = (x + dx, y + dy);
            if px >= 0 && py >= 0 && px < w && py < h {
                s += kernel(dx, dy);
            }
        }
    }
    s
}

pub(crate) fn forward(_screen: &Screen, buf: &Buffers, out: &mut AaOutput) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as i32, a.height as i32, a.channels);
    out.image.reset(a.width, a.height, nch);
    out.edges.clear();
    out.vals.clear();
    out.image.data.par_chunks_mut(w as usize * nch).enumerate().for_each(|(y, img)| {
        let y = y as i32;
        for x in 0..w {
            let px = &mut img[x as usize * nch..(x as usize + 1) * nch];
            let ws = weight_sum(x, y, w, h);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (sx, sy) = (x + dx, y + dy);
                    if sx < 0 || sy < 0 || sx >= w || sy >= h {
                        continue;
                    }
                    let k = kernel(dx, dy) / ws;
                    let j = (sy * w + sx) as usize;
                    for c in 0..nch {
                        px[c] += k * a.data[j * nch + c];
                    }
                }
            }
        }
    });
}

pub(crate) fn backward(
    screen: &Screen,
    buf: &Buffers,
    saved: &AaOutput,
    d_image: &Image,
    d_attrs: &mut Image,
    grads: &mut SegmentGrads,
) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as i32, a.height as i32, a.channels);
    let prims = &screen.prims;
    let g = &d_image.data;
    let chat = &saved.image.data;
    let parts: Vec<Vec<(u32, Vec2)>> = d_attrs
        .data
        .par_chunks_mut(w as usize * nch)
        .enumerate()
        .map(|(y, drow)| {
            let y = y as i32;
            let mut out = Vec::new();
            for x in 0..w {
                let i = (y * w + x) as usize;
                let d = &mut drow[x as usize * nch..(x as usize + 1) * nch];
                let cp = &a.data[i * nch..(i + 1) * nch];
                let mut gq = Vec2::ZERO;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (sx, sy) = (x + dx, y + dy);
                        if sx < 0 || sy < 0 || sx >= w || sy >= h {
                            continue;
                        }
                        let j = (sy * w + sx) as usize;
                        let kw = kernel(dx, dy) / weight_sum(sx, sy, w, h);
                        let mut dot = 0.0;
                        for c in 0..nch {
                            let gx = g[j * nch + c];
                            d[c] += kw * gx;
                            dot += gx * (cp[c] - chat[j * nch + c]);
                        }
                        // x − q_p = (dx, dy) at the forward point.
                        gq += Vec2::new(dx as f32, dy as f32) * (dot * kw / (SIGMA * SIGMA));
                    }
                }
                let id = buf.ids[i];
                if id == 0 || gq == Vec2::ZERO {
                    continue;
                }
                let p = &prims[id as usize - 1];
                let (t, s) = p.local(Vec2::new(x as f32, y as f32));
                let t = t.clamp(0.0, 1.0);
                let hw = p.hw0 + (p.hw1 - p.hw0) * t;
                let sg = if hw > 0.0 { (s / hw).clamp(-1.0, 1.0) } else { 0.0 };
                let base = (id - 1) * 4;
                out.push((base, gq * ((1.0 - t) * 0.5 * (1.0 + sg))));
                out.push((base + 1, gq * (t * 0.5 * (1.0 + sg))));
                out.push((base + 2, gq * (t * 0.5 * (1.0 - sg))));
                out.push((base + 3, gq * ((1.0 - t) * 0.5 * (1.0 - sg))));
            }
            out
        })
        .collect();
    crate::aa_output::scatter_corners(parts, grads);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::antialias::{antialias_backward, antialias_forward, AaMethod};
    use crate::rasterize::rasterize;
    use crate::screen::{RasterSettings, SegmentShape, Width};

    /// The splat with the samples' local coordinates frozen and their positions re-expressed from
    /// (possibly moved) corners: the function whose derivative the backward pass computes.
    fn frozen(buf: &Buffers, samples: &[(usize, [f32; 4])], corners: &[Vec2; 4], wts: &[f32]) -> f64 {
        let a = &buf.attrs;
        let (w, h, nch) = (a.width as i32, a.height as i32, a.channels);
        let k = |d: Vec2| (-d.length_squared() / (2.0 * SIGMA * SIGMA)).exp();
        let mut q: Vec<Vec2> = (0..w * h).map(|i| Vec2::new((i % w) as f32, (i / w) as f32)).collect();
        for (i, b) in samples {
            q[*i] = corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2] + corners[3] * b[3];
        }
        let mut l = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let (mut num, mut den) = ([0.0f32; 3], 0.0f32);
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (sx, sy) = (x + dx, y + dy);
                        if sx < 0 || sy < 0 || sx >= w || sy >= h {
                            continue;
                        }
                        let j = (sy * w + sx) as usize;
                        let kv = k(Vec2::new(x as f32, y as f32) - q[j]);
                        den += kv;
                        for c in 0..3 {
                            num[c] += kv * a.data[j * nch + c];
                        }
                    }
                }
                let i = (y * w + x) as usize;
                for c in 0..3 {
                    l += (wts[i * nch + c] * num[c] / den) as f64;
                }
            }
        }
        l
    }

    #[test]
    fn splat_gradient_matches_differences_with_frozen_samples() {
        let s = Screen::from_pixels(
            16,
            14,
            &[Vec2::new(2.3, 3.1), Vec2::new(12.6, 9.4)],
            None,
            &[[0, 1]],
            RasterSettings { width: Width::Pixels(1.7), shape: SegmentShape::Quad, direction_3d: false },
        )
        .unwrap();
        let mut buf = Buffers::new();
        rasterize(&s, &mut buf);
        let mut out = AaOutput::new(AaMethod::Splat);
        antialias_forward(&s, &buf, &mut out);
        let wts: Vec<f32> = (0..out.image.data.len()).map(|i| ((i * 7919) % 200) as f32 / 100.0 - 1.0).collect();
        let d = Image { width: 16, height: 14, channels: 3, data: wts.clone() };
        let mut d_attrs = Image::default();
        let mut g = SegmentGrads::default();
        g.reset(1);
        antialias_backward(&s, &buf, &out, &d, &mut d_attrs, &mut g).unwrap();
        let p = s.prims()[0];
        let mut samples = Vec::new();
        for (i, &id) in buf.ids.iter().enumerate() {
            if id != 0 {
                let c = Vec2::new((i % 16) as f32, (i / 16) as f32);
                let (t, sv) = p.local(c);
                let sg = sv / (p.hw0 + (p.hw1 - p.hw0) * t);
                let b = [
                    (1.0 - t) * 0.5 * (1.0 + sg),
                    t * 0.5 * (1.0 + sg),
                    t * 0.5 * (1.0 - sg),
                    (1.0 - t) * 0.5 * (1.0 - sg),
                ];
                samples.push((i, b));
            }
        }
        assert!(samples.len() > 5);
        let h = 1e-2f32;
        for k in 0..4 {
            for axis in 0..2 {
                let (mut cp, mut cm) = (p.corners(), p.corners());
                cp[k][axis] += h;
                cm[k][axis] -= h;
                let fd =
                    ((frozen(&buf, &samples, &cp, &wts) - frozen(&buf, &samples, &cm, &wts)) / (2.0 * h as f64)) as f32;
                let an = g.corners(0)[k][axis];
                assert!(
                    (an - fd).abs() <= 0.02 * an.abs().max(fd.abs()) + 1e-3,
                    "corner {k} axis {axis}: {an} vs {fd}"
                );
            }
        }
    }
}
