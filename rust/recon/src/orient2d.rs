//! Stage 1: 2D orientation maps with confidence, by a bank of oriented Gabor filters.
//!
//! In: a view's image (any 8/16-bit PNG, converted to luminance) and its hair mask (optional).
//! Out: an [`OrientationMap`] per view: per pixel the image-space strand angle θ ∈ [0, π) (x right,
//! y down, θ measured from +x towards +y) and a confidence in [0, 1]; pixels outside the hair mask
//! have confidence 0. Saved as `orient2d/<view>.exr` in the same layout as the capture's
//! `gt/orientation` maps (RGB = cos 2θ, sin 2θ, confidence) and reloaded from there, plus a picture
//! `orient2d/<view>.png` (hue = θ, brightness = confidence).
//!
//! Method: Paris, Briceño, Sillion, "Capture of Hair Geometry from Multiple Images" (SIGGRAPH 2004)
//! and the filter bank of `docs/method.md` §2 (there σ≈2, λ≈3, γ≈0.5, 64 orientations). Our
//! defaults are 24 orientations, σ = 3, λ = 6, γ = 0.5: on a rendered test-preset capture (16 views,
//! 171×256 px, straight hair) the mean error against `gt/orientation` was 22.6° against 32.1° for
//! σ = 2, λ = 3, and 24 orientations measured the same as 32. Each orientation's filter is a
//! quadrature pair (even and odd Gabor, zero mean); its response is the pair's energy, which does
//! not depend on whether strands appear brighter or darker than their gaps. The orientation is the
//! argmax over the bank, refined by a parabola through the three bins around it; the confidence is
//! `1 − mean/max` of the responses (a sharp peak over a flat floor is confident, an isotropic patch
//! is not). The kernels are stored as sparse tap lists cut where the Gaussian envelope falls below
//! 1e-3, and only hair pixels are filtered, in parallel over rows.
//!
//! Then (`smooth`, default σ = 8 px) the field is smoothed: the confidence-weighted doubled-angle
//! vectors are blurred by a Gaussian over the hair pixels and θ is read back (the confidence is
//! kept). On the paper-preset straight capture (58 views, 341×512) the mean error fell from 27.6°
//! to 18.3° (σ 4: 22.7°, σ 16: 13.0°) and on the test preset from 21.2° to 12.1°; larger σ
//! still helps straight hair but smooths away curls, so 8 is a compromise not yet checked on a
//! curly capture. Larger filters without smoothing measured worse per second (σ 4, λ 8: 24.1° at
//! 1.8× the time; σ 2, λ 3 as in the reference bank: 35.4°). The maps' error is not the figure to
//! tune σ on: on a wavy capture (colours preset) it falls from 30.5° at σ 4 to 27.7° at σ 16 while the
//! initial strands fall from 56.6 to 52.6 at 2 mm/20° (σ 8: 55.1), and straight hair's strands lose 4.6
//! points at σ 4 against 8 (docs/reconstruction.md, wavy hair's smoothing).

use std::f32::consts::PI;
use std::path::Path;

use rayon::prelude::*;
use thiserror::Error;

/// Why an orientation map could not be computed, read or written.
#[derive(Debug, Error)]
pub enum Orient2dError {
    #[error("cannot read the image {path}: {msg}")]
    ReadImage { path: std::path::PathBuf, msg: String },
    #[error("cannot write {path}: {msg}")]
    WriteImage { path: std::path::PathBuf, msg: String },
    #[error("{path} is {got_w}x{got_h} pixels but the view is {width}x{height}")]
    Size { path: std::path::PathBuf, width: u32, height: u32, got_w: u32, got_h: u32 },
}

/// Parameters of the Gabor filter bank.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GaborParams {
    /// Number of orientations over [0, π).
    pub orientations: usize,
    /// Gaussian σ across the strand, pixels.
    pub sigma: f32,
    /// Wavelength of the carrier across the strand, pixels.
    pub lambda: f32,
    /// Aspect ratio: σ along the strand is σ / γ.
    pub gamma: f32,
    /// σ (pixels) of a Gaussian smoothing of the orientation field after the bank (0: none): the
    /// confidence-weighted doubled-angle vectors (c cos 2θ, c sin 2θ) are averaged over the hair
    /// pixels around each pixel and θ is read back from the mean.
    #[serde(default)]
    pub smooth: f32,
}

impl Default for GaborParams {
    fn default() -> Self {
        Self { orientations: 24, sigma: 3.0, lambda: 6.0, gamma: 0.5, smooth: 8.0 }
    }
}

/// A per-pixel orientation map of one view.
#[derive(Debug, Clone, PartialEq)]
pub struct OrientationMap {
    pub width: u32,
    pub height: u32,
    /// Strand angle in [0, π), row-major.
    pub theta: Vec<f32>,
    /// Confidence in [0, 1]; 0 outside the hair.
    pub confidence: Vec<f32>,
}

impl OrientationMap {
    /// θ and confidence interpolated bilinearly between the four nearest pixels, in the doubled
    /// angle (cos 2θ, sin 2θ) weighted by confidence, so that θ and π blend as the same line;
    /// confidence 0 outside the image.
    #[inline]
    pub fn sample_bilinear(&self, x: f32, y: f32) -> (f32, f32) {
        let (w, h) = (self.width as i64, self.height as i64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let (mut cx, mut sy, mut conf) = (0.0f32, 0.0f32, 0.0f32);
        for (dx, dy, wt) in
            [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
        {
            let (px, py) = (xi + dx, yi + dy);
            if px < 0 || py < 0 || px >= w || py >= h {
                continue;
            }
            let i = (py * w + px) as usize;
            let c = self.confidence[i] * wt;
            let (s2, c2) = (2.0 * self.theta[i]).sin_cos();
            cx += c * c2;
            sy += c * s2;
            conf += c;
        }
        if conf <= 0.0 {
            return (0.0, 0.0);
        }
        (0.5 * sy.atan2(cx).rem_euclid(std::f32::consts::TAU), conf)
    }

    /// θ and confidence at the nearest pixel; confidence 0 outside the image.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> (f32, f32) {
        let (xi, yi) = ((x + 0.5).floor() as i64, (y + 0.5).floor() as i64);
        if xi < 0 || yi < 0 || xi >= self.width as i64 || yi >= self.height as i64 {
            return (0.0, 0.0);
        }
        let i = yi as usize * self.width as usize + xi as usize;
        (self.theta[i], self.confidence[i])
    }

    /// Writes the map as an RGB float EXR (cos 2θ, sin 2θ, confidence), the `gt/orientation` layout.
    pub fn save_exr(&self, path: &Path) -> Result<(), Orient2dError> {
        let mut buf = Vec::with_capacity(self.theta.len() * 3);
        for (t, c) in self.theta.iter().zip(&self.confidence) {
            buf.extend_from_slice(&[(2.0 * t).cos(), (2.0 * t).sin(), *c]);
        }
        let img = image::Rgb32FImage::from_raw(self.width, self.height, buf)
            .ok_or_else(|| Orient2dError::WriteImage { path: path.into(), msg: "buffer size".into() })?;
        save_image(&image::DynamicImage::ImageRgb32F(img), image::ImageFormat::OpenExr, path)
    }

    /// Reads a map written by [`OrientationMap::save_exr`] or a capture's `gt/orientation` file
    /// (the third channel is read as the confidence/weight).
    pub fn load_exr(path: &Path) -> Result<Self, Orient2dError> {
        let img = image::open(path).map_err(|e| Orient2dError::ReadImage { path: path.into(), msg: e.to_string() })?;
        let img = img.to_rgb32f();
        let (width, height) = img.dimensions();
        let mut theta = Vec::with_capacity((width * height) as usize);
        let mut confidence = Vec::with_capacity((width * height) as usize);
        for p in img.pixels() {
            let [c2, s2, w] = p.0;
            let mut t = 0.5 * s2.atan2(c2);
            if t < 0.0 {
                t += PI;
            }
            theta.push(if t.is_finite() { t } else { 0.0 });
            confidence.push(if w.is_finite() { w.max(0.0) } else { 0.0 });
        }
        Ok(Self { width, height, theta, confidence })
    }

    /// Writes a picture: hue = θ, brightness = confidence (scaled so the 95th percentile is full).
    pub fn save_png(&self, path: &Path) -> Result<(), Orient2dError> {
        let mut conf: Vec<f32> = self.confidence.iter().copied().filter(|c| *c > 0.0).collect();
        let scale = if conf.is_empty() {
            1.0
        } else {
            let k = (conf.len() * 95 / 100).min(conf.len() - 1);
            conf.select_nth_unstable_by(k, f32::total_cmp);
            1.0 / conf[k].max(1e-6)
        };
        let mut img = image::RgbImage::new(self.width, self.height);
        for (i, px) in img.pixels_mut().enumerate() {
            let v = (self.confidence[i] * scale).clamp(0.0, 1.0);
            px.0 = hsv(self.theta[i] / PI, v);
        }
        save_image(&image::DynamicImage::ImageRgb8(img), image::ImageFormat::Png, path)
    }
}

/// Encodes `img` in memory, then writes it through a temporary file and a rename (an error or an
/// interrupt never leaves a half-written image).
fn save_image(img: &image::DynamicImage, format: image::ImageFormat, path: &Path) -> Result<(), Orient2dError> {
    let err = |msg: String| Orient2dError::WriteImage { path: path.into(), msg };
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, format).map_err(|e| err(e.to_string()))?;
    hairrecon_core::formats::atomic_write(path, |w| Ok(std::io::Write::write_all(w, bytes.get_ref())?))
        .map_err(|e| err(e.kind.to_string()))
}

fn hsv(h: f32, v: f32) -> [u8; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let f = h6 - h6.floor();
    let (q, t) = (v * (1.0 - f), v * f);
    let (r, g, b) = match h6 as u32 {
        0 => (v, t, 0.0),
        1 => (q, v, 0.0),
        2 => (0.0, v, t),
        3 => (0.0, q, v),
        4 => (t, 0.0, v),
        _ => (v, 0.0, q),
    };
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

/// A grayscale image in [0, 1], row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl GrayImage {
    /// Reads any image the `image` crate reads and converts it to luminance in [0, 1].
    pub fn load(path: &Path) -> Result<Self, Orient2dError> {
        let img = image::open(path).map_err(|e| Orient2dError::ReadImage { path: path.into(), msg: e.to_string() })?;
        let (width, height) = (img.width(), img.height());
        let rgb = img.to_rgb32f();
        let data = rgb.pixels().map(|p| 0.2126 * p.0[0] + 0.7152 * p.0[1] + 0.0722 * p.0[2]).collect();
        Ok(Self { width, height, data })
    }
}

/// Reads a hair mask: a pixel is hair when its value (luminance, in [0, 1]) is at least `threshold`.
pub fn load_mask(path: &Path, width: u32, height: u32, threshold: f32) -> Result<Vec<bool>, Orient2dError> {
    let img = GrayImage::load(path)?;
    if (img.width, img.height) != (width, height) {
        return Err(Orient2dError::Size { path: path.into(), width, height, got_w: img.width, got_h: img.height });
    }
    Ok(img.data.iter().map(|&v| v >= threshold).collect())
}

/// One kernel tap: offset and even/odd weights.
#[derive(Debug, Clone, Copy)]
struct Tap {
    dx: i32,
    dy: i32,
    even: f32,
    odd: f32,
}

/// Hair pixels filtered together along a row (see [`GaborBank::compute`]).
const BLOCK: usize = 64;

/// The filter bank: per orientation a list of taps.
#[derive(Debug, Clone)]
pub struct GaborBank {
    params: GaborParams,
    radius: i32,
    taps: Vec<Vec<Tap>>,
}

impl GaborBank {
    pub fn new(params: GaborParams) -> Self {
        let n = params.orientations.max(2);
        let sigma_along = params.sigma / params.gamma.max(1e-3);
        // Envelope below 1e-3 beyond ~3.7σ.
        let radius = (3.7 * params.sigma.max(sigma_along)).ceil() as i32;
        let taps = (0..n)
            .map(|k| {
                let th = k as f32 * PI / n as f32;
                let (s, c) = th.sin_cos();
                let mut taps = Vec::new();
                for dy in -radius..=radius {
                    for dx in -radius..=radius {
                        let (x, y) = (dx as f32, dy as f32);
                        let along = x * c + y * s;
                        let across = -x * s + y * c;
                        let env = (-0.5
                            * (across * across / (params.sigma * params.sigma)
                                + along * along / (sigma_along * sigma_along)))
                            .exp();
                        if env < 1e-3 {
                            continue;
                        }
                        let ph = 2.0 * PI * across / params.lambda;
                        taps.push(Tap { dx, dy, even: env * ph.cos(), odd: env * ph.sin() });
                    }
                }
                // Zero mean for the even part (the odd part is zero mean by symmetry).
                let mean = taps.iter().map(|t| t.even).sum::<f32>() / taps.len() as f32;
                let mut norm = 0.0;
                for t in &mut taps {
                    t.even -= mean;
                    norm += t.even.abs() + t.odd.abs();
                }
                for t in &mut taps {
                    t.even /= norm;
                    t.odd /= norm;
                }
                taps
            })
            .collect();
        Self { params, radius, taps }
    }

    pub fn params(&self) -> GaborParams {
        self.params
    }

    /// Filters `img` at the pixels where `mask` is true (all pixels when `None`).
    pub fn compute(&self, img: &GrayImage, mask: Option<&[bool]>) -> OrientationMap {
        let (w, h) = (img.width as usize, img.height as usize);
        let r = self.radius as usize;
        // Pad by edge replication so the inner loop needs no bounds checks.
        let pw = w + 2 * r;
        let ph = h + 2 * r;
        let mut pad = vec![0.0f32; pw * ph];
        for y in 0..ph {
            let sy = (y as i64 - r as i64).clamp(0, h as i64 - 1) as usize;
            for x in 0..pw {
                let sx = (x as i64 - r as i64).clamp(0, w as i64 - 1) as usize;
                pad[y * pw + x] = img.data[sy * w + sx];
            }
        }
        // Tap offsets as linear indices into the padded image.
        let lin: Vec<Vec<(isize, f32, f32)>> = self
            .taps
            .iter()
            .map(|ts| ts.iter().map(|t| (t.dy as isize * pw as isize + t.dx as isize, t.even, t.odd)).collect())
            .collect();
        let n = self.taps.len();
        let mut theta = vec![0.0f32; w * h];
        let mut confidence = vec![0.0f32; w * h];
        theta.par_chunks_mut(w).zip(confidence.par_chunks_mut(w)).enumerate().for_each(|(y, (trow, crow))| {
            // The responses of a block of consecutive hair pixels, orientation-major: `resp[k * BLOCK
            // + i]`. Each pixel's sums add the taps in the same order as one pixel at a time would,
            // so the maps are the same to the bit; running along the row instead of along the taps
            // lets the compiler vectorize and breaks the chain of dependent additions.
            let mut resp = vec![0.0f32; n * BLOCK];
            let (mut even, mut odd) = ([0.0f32; BLOCK], [0.0f32; BLOCK]);
            let row_mask = mask.map(|m| &m[y * w..(y + 1) * w]);
            let mut x = 0;
            while x < w {
                if row_mask.is_some_and(|m| !m[x]) {
                    x += 1;
                    continue;
                }
                let mut end = x + 1;
                while end < w && end - x < BLOCK && row_mask.is_none_or(|m| m[end]) {
                    end += 1;
                }
                let len = end - x;
                let centre = (y + r) * pw + x + r;
                for (k, taps) in lin.iter().enumerate() {
                    let (e, o) = (&mut even[..len], &mut odd[..len]);
                    e.fill(0.0);
                    o.fill(0.0);
                    for &(off, we, wo) in taps {
                        let start = (centre as isize + off) as usize;
                        for ((e, o), &v) in e.iter_mut().zip(o.iter_mut()).zip(&pad[start..start + len]) {
                            *e += we * v;
                            *o += wo * v;
                        }
                    }
                    for ((out, &e), &o) in resp[k * BLOCK..k * BLOCK + len].iter_mut().zip(e.iter()).zip(o.iter()) {
                        *out = e * e + o * o;
                    }
                }
                for i in 0..len {
                    let f = |k: usize| resp[k * BLOCK + i];
                    let (mut kmax, mut fmax, mut sum) = (0usize, 0.0f32, 0.0f32);
                    for k in 0..n {
                        let v = f(k);
                        sum += v;
                        if v > fmax {
                            fmax = v;
                            kmax = k;
                        }
                    }
                    let fm = f((kmax + n - 1) % n);
                    let fp = f((kmax + 1) % n);
                    let denom = fm - 2.0 * fmax + fp;
                    let delta = if denom < -1e-20 { (0.5 * (fm - fp) / denom).clamp(-0.5, 0.5) } else { 0.0 };
                    trow[x + i] = ((kmax as f32 + delta) * PI / n as f32).rem_euclid(PI);
                    let mean = sum / n as f32;
                    // Hair pixels keep a tiny positive confidence so that the mask survives a save.
                    crow[x + i] = if fmax > 1e-12 { (1.0 - mean / fmax).clamp(1e-4, 1.0) } else { 1e-4 };
                }
                x = end;
            }
        });
        let mut map = OrientationMap { width: img.width, height: img.height, theta, confidence };
        if self.params.smooth > 0.0 {
            smooth_orientations(&mut map, self.params.smooth);
        }
        map
    }
}

/// Separable Gaussian blur of `data` (w × h, row-major) with the given normalised kernel
/// (`k.len()` = 2r + 1), zero outside the image. Rows then columns, each output a fixed-order sum.
fn blur(data: &[f32], w: usize, h: usize, k: &[f32]) -> Vec<f32> {
    let r = (k.len() / 2) as isize;
    let mut tmp = vec![0.0f32; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let src = &data[y * w..(y + 1) * w];
        for (x, o) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (j, &kv) in k.iter().enumerate() {
                let xx = x as isize + j as isize - r;
                if xx >= 0 && (xx as usize) < w {
                    s += kv * src[xx as usize];
                }
            }
            *o = s;
        }
    });
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (j, &kv) in k.iter().enumerate() {
            let yy = y as isize + j as isize - r;
            if yy < 0 || yy as usize >= h {
                continue;
            }
            let src = &tmp[yy as usize * w..(yy as usize + 1) * w];
            for (o, &v) in row.iter_mut().zip(src) {
                *o += kv * v;
            }
        }
    });
    out
}

/// Confidence-weighted Gaussian smoothing of θ in doubled-angle space over the hair pixels
/// (confidence > 0); the confidence is kept.
fn smooth_orientations(map: &mut OrientationMap, sigma: f32) {
    let (w, h) = (map.width as usize, map.height as usize);
    let r = (3.0 * sigma).ceil() as i32;
    let mut k: Vec<f32> = (-r..=r).map(|i| (-0.5 * (i as f32 / sigma).powi(2)).exp()).collect();
    let ks: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= ks);
    let vx: Vec<f32> = map.theta.iter().zip(&map.confidence).map(|(t, c)| c * (2.0 * t).cos()).collect();
    let vy: Vec<f32> = map.theta.iter().zip(&map.confidence).map(|(t, c)| c * (2.0 * t).sin()).collect();
    let (bx, by) = (blur(&vx, w, h, &k), blur(&vy, w, h, &k));
    for i in 0..w * h {
        if map.confidence[i] > 0.0 && (bx[i] != 0.0 || by[i] != 0.0) {
            map.theta[i] = (0.5 * by[i].atan2(bx[i])).rem_euclid(PI);
        }
    }
}

/// Undirected angle difference of two image angles (period π), in [0, π/2].
#[inline]
pub fn angle_diff(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d)
}

/// Error of an orientation map against a ground-truth map, on pixels that are hair in both.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OrientationError {
    /// Mean undirected angular error over all compared pixels, degrees.
    pub mean_deg: f64,
    /// The same over the most confident half of the compared pixels.
    pub mean_confident_half_deg: f64,
    /// Number of compared pixels.
    pub pixels: u64,
}

/// Per-pixel (error in radians, our confidence) on pixels that are hair in both maps.
pub fn orientation_errors(pred: &OrientationMap, gt: &OrientationMap) -> Vec<(f32, f32)> {
    pred.theta
        .iter()
        .zip(&pred.confidence)
        .zip(gt.theta.iter().zip(&gt.confidence))
        .filter(|((_, c), (_, g))| **c > 0.0 && **g > 0.0)
        .map(|((t, c), (tg, _))| (angle_diff(*t, *tg), *c))
        .collect()
}

/// Summarises (error, confidence) pairs pooled over views.
pub fn summarize_errors(mut errs: Vec<(f32, f32)>) -> OrientationError {
    if errs.is_empty() {
        return OrientationError::default();
    }
    let n = errs.len();
    let mean = errs.iter().map(|e| e.0 as f64).sum::<f64>() / n as f64;
    errs.sort_by(|a, b| b.1.total_cmp(&a.1));
    let half = n.div_ceil(2);
    let mean_half = errs[..half].iter().map(|e| e.0 as f64).sum::<f64>() / half as f64;
    OrientationError { mean_deg: mean.to_degrees(), mean_confident_half_deg: mean_half.to_degrees(), pixels: n as u64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parallel anti-aliased stripes at angle `t`, period `period` px.
    fn stripes(w: u32, h: u32, t: f32, period: f32) -> GrayImage {
        let (s, c) = t.sin_cos();
        let data = (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    let across = -(x as f32) * s + y as f32 * c;
                    0.5 + 0.5 * (2.0 * PI * across / period).cos()
                })
            })
            .collect();
        GrayImage { width: w, height: h, data }
    }

    #[test]
    fn stripes_give_their_angle() {
        // The bank alone: smoothing a 48×40 image mixes in the edges' padding.
        let bank = GaborBank::new(GaborParams { smooth: 0.0, ..Default::default() });
        for &deg in &[0.0f32, 17.0, 45.0, 90.0, 133.0, 171.0] {
            let t = deg.to_radians();
            let img = stripes(48, 40, t, 3.5);
            let map = bank.compute(&img, None);
            let i = 20 * 48 + 24;
            let err = angle_diff(map.theta[i], t).to_degrees();
            assert!(err < 2.0, "angle {deg}: got {} ({err}°)", map.theta[i].to_degrees());
            assert!(map.confidence[i] > 0.5, "angle {deg}: confidence {}", map.confidence[i]);
        }
    }

    /// A field of one angle with seeded ±40° noise on the left half of the image, no hair on the
    /// right: smoothing brings the hair back to the angle and leaves the rest alone.
    #[test]
    fn smoothing_averages_noise() {
        let (w, h, t0) = (64usize, 48usize, 2.8f32);
        let mut state = 12345u64;
        let mut map =
            OrientationMap { width: w as u32, height: h as u32, theta: vec![0.0; w * h], confidence: vec![0.0; w * h] };
        for i in 0..w * h {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let u = (state >> 40) as f32 / (1u64 << 24) as f32;
            if i % w < w / 2 {
                map.theta[i] = (t0 + (2.0 * u - 1.0) * 40f32.to_radians()).rem_euclid(PI);
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                map.confidence[i] = 0.5 + 0.5 * (state >> 40) as f32 / (1u64 << 24) as f32;
            }
        }
        let mean_err = |m: &OrientationMap| {
            let e: Vec<f32> = (0..w * h).filter(|i| i % w < w / 2).map(|i| angle_diff(m.theta[i], t0)).collect();
            e.iter().sum::<f32>().to_degrees() / e.len() as f32
        };
        let before = mean_err(&map);
        let mut sm = map.clone();
        smooth_orientations(&mut sm, 4.0);
        let after = mean_err(&sm);
        eprintln!("mean error {before}° → {after}°");
        assert!(before > 15.0 && after < 3.0, "mean error {before}° → {after}°");
        assert_eq!(sm.confidence, map.confidence);
        assert!((0..w * h).filter(|i| i % w >= w / 2).all(|i| sm.theta[i] == 0.0));
    }

    #[test]
    fn saves_and_reloads() {
        let bank = GaborBank::new(GaborParams::default());
        let map = bank.compute(&stripes(20, 12, 0.3, 4.0), None);
        let dir = std::env::temp_dir().join(format!("hairrecon-orient2d-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("m.exr");
        map.save_exr(&p).unwrap();
        map.save_png(&dir.join("m.png")).unwrap();
        let back = OrientationMap::load_exr(&p).unwrap();
        for i in 0..map.theta.len() {
            assert!(angle_diff(map.theta[i], back.theta[i]) < 1e-4);
            assert!((map.confidence[i] - back.confidence[i]).abs() < 1e-5);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
