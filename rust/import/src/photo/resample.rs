//! The working copy of a photo: undistorted to a pinhole camera and scaled to a target height, with
//! an area filter so that large reductions (6000 → 512 pixels) do not alias.
//!
//! **Size.** The working copy is `H'` = the target height and `W' = round(W H' / H)` pixels; the
//! two scales `s_x = W'/W` and `s_y = H'/H` differ by the rounding.
//!
//! **Intrinsics.** With pixel centres at integers, pixel `u` covers `[u − ½, u + ½]`, so the image
//! spans `[−½, W − ½]` and the edge coordinate `u + ½` is what scales: `u' + ½ = s_x (u + ½)`.
//! Substituting `u = fx x + skew y + cx` gives
//!
//! ```text
//! fx' = s_x fx    skew' = s_x skew    cx' = s_x (cx + ½) − ½
//! fy' = s_y fy                        cy' = s_y (cy + ½) − ½
//! ```
//!
//! ([`scaled_intrinsics`]). The working copy's camera is this pinhole `K'` without distortion: the
//! same focal length and principal point as the scaled photo, so the two differ only by the lens
//! distortion and the field of view stays about the same.
//!
//! **Mapping.** For a point `(u', v')` of the working copy: `y = (v' − cy')/fy'`,
//! `x = (u' − cx' − skew' y)/fx'`, `(x_d, y_d) = distort(x, y)`, then the photo's pixel
//! `u = fx x_d + skew y_d + cx`, `v = fy y_d + cy`. Without distortion this is the affine map of the
//! scale alone. The geometry is computed in `f64` (a 6000-pixel photo needs sub-10⁻³-pixel
//! positions), the samples in `f32`.
//!
//! **Filter.** Each output pixel averages a `k × k` grid of bilinear samples of the photo, at the
//! points `(i + (a + ½)/k − ½, j + (b + ½)/k − ½)` of its own square, mapped into the photo: a box
//! filter over the pixel's footprint, which follows the distortion. `k` is the footprint's largest
//! extent in photo pixels (probed over the image), rounded up, so neighbouring samples are at most
//! one photo pixel apart; `k = 1` (a single bilinear tap) when enlarging. Bilinear sampling clamps to
//! the edge pixels within the photo's area `[−½, W − ½] × [−½, H − ½]`.
//!
//! **Coverage.** With the same focal length, barrel distortion (`k1 < 0`) makes the pinhole image
//! see less than the photo (the photo's corners are cropped away), and pincushion distortion
//! (`k1 > 0`) makes it see more: its corners map outside the photo. Where a working-copy pixel's
//! samples fall outside the photo or beyond the model's valid radius
//! ([`crate::scene::Distortion::valid_radius`]), they are missing: a pixel's value is the mean of
//! its samples that fall inside, 0 when none do, and [`Resampled::coverage`] gives the fraction that
//! did (1 everywhere for a photo without distortion). Callers mask or crop pixels below 1.
//!
//! **Values** are the photo's own samples divided by 255 or 65,535: no linearization, so the
//! average is taken on the encoded (sRGB) values, as image resizers usually do.

use hairrecon_core::image_io::{GrayImage32, RgbImage32};
use rayon::prelude::*;

use super::{PhotoError, PhotoPixels};
use crate::scene::{Distortion, Intrinsics};

/// Largest number of samples per axis of an output pixel.
pub const MAX_SAMPLES_PER_AXIS: u32 = 64;

/// A working copy of a photo.
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    /// The undistorted, scaled photo, values in `[0, 1]` in the photo's encoding.
    pub image: RgbImage32,
    /// Fraction of each pixel's samples that fell inside the photo (module docs).
    pub coverage: GrayImage32,
    /// The pinhole camera of `image` (no distortion).
    pub intrinsics: Intrinsics,
    /// Samples per axis of each output pixel (the filter's `k`).
    pub samples_per_axis: u32,
}

/// The working size of a `width` x `height` photo at `target_height`: `(round(W H'/H), H')`, at
/// least one pixel wide.
pub fn working_size(width: u32, height: u32, target_height: u32) -> (u32, u32) {
    let w = (width as f64 * target_height as f64 / height as f64).round().max(1.0);
    (w as u32, target_height)
}

/// The intrinsics of a photo scaled from `from` = (W, H) to `to` = (W', H') pixels (module docs).
pub fn scaled_intrinsics(k: &Intrinsics, from: (u32, u32), to: (u32, u32)) -> Intrinsics {
    let sx = to.0 as f64 / from.0 as f64;
    let sy = to.1 as f64 / from.1 as f64;
    Intrinsics {
        fx: sx * k.fx,
        fy: sy * k.fy,
        cx: sx * (k.cx + 0.5) - 0.5,
        cy: sy * (k.cy + 0.5) - 0.5,
        skew: sx * k.skew,
    }
}

/// The map from working-copy pixels to photo pixels (module docs).
struct PixelMap {
    out: Intrinsics,
    src: Intrinsics,
    distortion: Distortion,
    distorted: bool,
    valid_radius2: f64,
}

impl PixelMap {
    /// The photo pixel seen at working-copy point `(u, v)`; `None` beyond the model's valid radius.
    #[inline]
    fn map(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        let y = (v - self.out.cy) / self.out.fy;
        let x = (u - self.out.cx - self.out.skew * y) / self.out.fx;
        let (xd, yd) = if self.distorted {
            if x * x + y * y > self.valid_radius2 {
                return None;
            }
            self.distortion.distort(x, y)
        } else {
            (x, y)
        };
        Some((self.src.fx * xd + self.src.skew * yd + self.src.cx, self.src.fy * yd + self.src.cy))
    }

    /// The largest extent, in photo pixels, of an output pixel's footprint, from central
    /// differences on a 33 x 33 grid of output points.
    fn max_footprint(&self, w: u32, h: u32) -> f64 {
        let mut worst: f64 = 0.0;
        let e = 0.25;
        for j in 0..=32 {
            for i in 0..=32 {
                let u = i as f64 / 32.0 * (w as f64 - 1.0);
                let v = j as f64 / 32.0 * (h as f64 - 1.0);
                let (Some(a), Some(b), Some(c), Some(d)) =
                    (self.map(u - e, v), self.map(u + e, v), self.map(u, v - e), self.map(u, v + e))
                else {
                    continue;
                };
                let (dudx, dvdx) = ((b.0 - a.0) / (2.0 * e), (b.1 - a.1) / (2.0 * e));
                let (dudy, dvdy) = ((d.0 - c.0) / (2.0 * e), (d.1 - c.1) / (2.0 * e));
                worst = worst.max(dudx.abs() + dudy.abs()).max(dvdx.abs() + dvdy.abs());
            }
        }
        worst
    }
}

/// A photo sample type and its full-scale value.
trait Sample: Copy + Send + Sync {
    const FULL: f32;
    fn to_f32(self) -> f32;
}

impl Sample for u8 {
    const FULL: f32 = 255.0;
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

impl Sample for u16 {
    const FULL: f32 = 65535.0;
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

/// Bilinear sample of interleaved RGB `data` at `(u, v)`, clamped to the edge pixels.
#[inline]
fn bilinear<T: Sample>(data: &[T], w: usize, h: usize, u: f32, v: f32) -> [f32; 3] {
    let u = u.clamp(0.0, (w - 1) as f32);
    let v = v.clamp(0.0, (h - 1) as f32);
    let x0 = (u as usize).min(w - 1);
    let y0 = (v as usize).min(h - 1);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let (fx, fy) = (u - x0 as f32, v - y0 as f32);
    let (i00, i10, i01, i11) = (3 * (y0 * w + x0), 3 * (y0 * w + x1), 3 * (y1 * w + x0), 3 * (y1 * w + x1));
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = data[i00 + c].to_f32() + fx * (data[i10 + c].to_f32() - data[i00 + c].to_f32());
        let bottom = data[i01 + c].to_f32() + fx * (data[i11 + c].to_f32() - data[i01 + c].to_f32());
        *o = top + fy * (bottom - top);
    }
    out
}

fn valid_intrinsics(k: &Intrinsics) -> bool {
    [k.fx, k.fy, k.cx, k.cy, k.skew].iter().all(|v| v.is_finite()) && k.fx > 0.0 && k.fy > 0.0
}

/// Undistorts `pixels` (a photo seen through `intrinsics` and `distortion`, in the orientation the
/// calibration used) and scales it to `target_height` pixels high, with the area filter and
/// coverage of the module docs. Deterministic; rows in parallel.
pub fn resample(
    pixels: &PhotoPixels,
    intrinsics: &Intrinsics,
    distortion: &Distortion,
    target_height: u32,
) -> Result<Resampled, PhotoError> {
    if target_height == 0 {
        return Err(PhotoError::BadTarget { target_height });
    }
    let valid_distortion =
        [&distortion.k[..], &distortion.d[..], &distortion.p[..]].concat().iter().all(|c| c.is_finite());
    if !valid_intrinsics(intrinsics) || !valid_distortion {
        return Err(PhotoError::BadIntrinsics { intrinsics: format!("{intrinsics:?}, {distortion:?}") });
    }
    let (w, h) = (pixels.width(), pixels.height());
    let (w2, h2) = working_size(w, h, target_height);
    let out_k = scaled_intrinsics(intrinsics, (w, h), (w2, h2));
    let distorted = !distortion.is_none();
    let valid_radius = if distorted { distortion.valid_radius() } else { f64::INFINITY };
    let map = PixelMap {
        out: out_k,
        src: *intrinsics,
        distortion: *distortion,
        distorted,
        valid_radius2: valid_radius * valid_radius,
    };
    let k = (map.max_footprint(w2, h2) - 1e-9).ceil().clamp(1.0, MAX_SAMPLES_PER_AXIS as f64) as u32;
    let (image, coverage) = match pixels {
        PhotoPixels::Rgb8(img) => filter(img.as_raw(), (w, h), (w2, h2), &map, k),
        PhotoPixels::Rgb16(img) => filter(img.as_raw(), (w, h), (w2, h2), &map, k),
    };
    Ok(Resampled {
        image: RgbImage32 { width: w2, height: h2, data: image },
        coverage: GrayImage32 { width: w2, height: h2, data: coverage },
        intrinsics: out_k,
        samples_per_axis: k,
    })
}

/// The box-filtered resampling of `data` (`src` = W x H) to `dst` = W' x H'; image and coverage.
fn filter<T: Sample>(data: &[T], src: (u32, u32), dst: (u32, u32), map: &PixelMap, k: u32) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (src.0 as usize, src.1 as usize);
    let (w2, h2) = (dst.0 as usize, dst.1 as usize);
    let (umax, vmax) = (w as f64 - 0.5, h as f64 - 0.5);
    let offsets: Vec<f64> = (0..k).map(|a| (a as f64 + 0.5) / k as f64 - 0.5).collect();
    let total = (k * k) as f32;
    let scale = 1.0 / T::FULL;
    let mut image = vec![0.0f32; 3 * w2 * h2];
    let mut coverage = vec![0.0f32; w2 * h2];
    image.par_chunks_mut(3 * w2).zip(coverage.par_chunks_mut(w2)).enumerate().for_each(|(j, (row, cov))| {
        for i in 0..w2 {
            let mut acc = [0.0f32; 3];
            let mut inside = 0u32;
            for &ob in &offsets {
                let v_out = j as f64 + ob;
                for &oa in &offsets {
                    let Some((u, v)) = map.map(i as f64 + oa, v_out) else { continue };
                    if !(-0.5..=umax).contains(&u) || !(-0.5..=vmax).contains(&v) {
                        continue;
                    }
                    let s = bilinear(data, w, h, u as f32, v as f32);
                    acc[0] += s[0];
                    acc[1] += s[1];
                    acc[2] += s[2];
                    inside += 1;
                }
            }
            if inside > 0 {
                let norm = scale / inside as f32;
                for c in 0..3 {
                    row[3 * i + c] = acc[c] * norm;
                }
            }
            cov[i] = inside as f32 / total;
        }
    });
    (image, coverage)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k(fx: f64, fy: f64, cx: f64, cy: f64) -> Intrinsics {
        Intrinsics { fx, fy, cx, cy, skew: 0.0 }
    }

    #[test]
    fn scaling_keeps_the_image_edges_and_centre() {
        // a centred principal point stays centred: cx = (W - 1)/2 -> (W' - 1)/2
        let s = scaled_intrinsics(&k(1000.0, 1000.0, 1999.5, 1499.5), (4000, 3000), (1000, 750));
        assert!((s.cx - 499.5).abs() < 1e-12 && (s.cy - 374.5).abs() < 1e-12, "{s:?}");
        assert!((s.fx - 250.0).abs() < 1e-12 && (s.fy - 250.0).abs() < 1e-12);
        // the left edge of the image (-0.5) stays the left edge
        let s = scaled_intrinsics(&k(1.0, 1.0, -0.5, -0.5), (4000, 3000), (1000, 750));
        assert!((s.cx + 0.5).abs() < 1e-12 && (s.cy + 0.5).abs() < 1e-12);
        assert_eq!(scaled_intrinsics(&k(3.0, 4.0, 5.0, 6.0), (7, 8), (7, 8)), k(3.0, 4.0, 5.0, 6.0));
        assert_eq!(working_size(6000, 4000, 512), (768, 512));
        assert_eq!(working_size(4000, 6000, 512), (341, 512));
    }

    #[test]
    fn halving_averages_two_by_two_blocks_exactly() {
        let img =
            image::RgbImage::from_fn(8, 6, |x, y| image::Rgb([(x * 30) as u8, (y * 40) as u8, ((x * y) * 5) as u8]));
        let pixels = PhotoPixels::Rgb8(img.clone());
        let r = resample(&pixels, &k(10.0, 10.0, 3.5, 2.5), &Distortion::default(), 3).unwrap();
        assert_eq!((r.image.width, r.image.height, r.samples_per_axis), (4, 3, 2));
        for j in 0..3 {
            for i in 0..4 {
                for c in 0..3 {
                    let mean: f32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|(a, b)| img.get_pixel(2 * i + a, 2 * j + b).0[c] as f32)
                        .sum::<f32>()
                        / 4.0
                        / 255.0;
                    assert!((r.image.get(i, j)[c] - mean).abs() < 1e-6, "({i}, {j}) channel {c}");
                }
                assert_eq!(r.coverage.get(i, j), 1.0);
            }
        }
    }

    #[test]
    fn the_same_size_without_distortion_copies_the_photo() {
        let img = Rgb16Pixels::from_fn(5, 4, |x, y| image::Rgb([(x * 13000) as u16, (y * 20000) as u16, 65535]));
        let r = resample(&PhotoPixels::Rgb16(img.clone()), &k(5.0, 5.0, 2.0, 1.5), &Distortion::default(), 4).unwrap();
        assert_eq!(r.samples_per_axis, 1);
        for (x, y, p) in img.enumerate_pixels() {
            let got = r.image.get(x, y);
            for c in 0..3 {
                assert!((got[c] - p.0[c] as f32 / 65535.0).abs() < 1e-6);
            }
        }
    }

    type Rgb16Pixels = super::super::Rgb16Image;

    #[test]
    fn pincushion_distortion_leaves_the_corners_uncovered_and_bad_input_is_an_error() {
        let img = image::RgbImage::from_pixel(40, 30, image::Rgb([200, 100, 50]));
        let d = Distortion { k: [0.3, 0.0, 0.0, 0.0], ..Default::default() };
        let r = resample(&PhotoPixels::Rgb8(img), &k(30.0, 30.0, 19.5, 14.5), &d, 30).unwrap();
        assert!(r.coverage.get(0, 0) < 1.0, "the pinhole image's corner lies outside the photo");
        let barrel = Distortion { k: [-0.3, 0.0, 0.0, 0.0], ..Default::default() };
        let img = image::RgbImage::from_pixel(40, 30, image::Rgb([200, 100, 50]));
        let r = resample(&PhotoPixels::Rgb8(img), &k(30.0, 30.0, 19.5, 14.5), &barrel, 30).unwrap();
        assert!(r.coverage.data.iter().all(|&c| c == 1.0), "barrel distortion crops: all covered");
        assert_eq!(r.coverage.get(20, 15), 1.0);
        assert!((r.image.get(20, 15)[0] - 200.0 / 255.0).abs() < 1e-6);
        let px = PhotoPixels::Rgb8(image::RgbImage::new(4, 4));
        assert!(matches!(resample(&px, &k(1.0, 1.0, 1.5, 1.5), &d, 0), Err(PhotoError::BadTarget { .. })));
        assert!(matches!(resample(&px, &k(0.0, 1.0, 1.5, 1.5), &d, 2), Err(PhotoError::BadIntrinsics { .. })));
    }
}
