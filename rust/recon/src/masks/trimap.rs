//! Trimaps from a rough per-pixel hair probability, and the exact Euclidean distance transform
//! that builds them.
//!
//! A trimap splits an image into pixels known to be hair ([`FOREGROUND`]), pixels known not to be
//! ([`BACKGROUND`]) and a band around the probability's 0.5 contour ([`UNKNOWN`]) whose alpha is
//! left to matting ([`super::matting::closed_form_matting`]). A rough probability is least
//! trustworthy near its contour, so the band's half-width (`band_px`) should cover the contour's
//! positional error; a wider band costs solve time and gives matting more room to drift.
//!
//! Reference for [`distance_to`]: P. F. Felzenszwalb, D. P. Huttenlocher, "Distance Transforms of
//! Sampled Functions", Theory of Computing 8 (2012) 415–428: the squared Euclidean distance
//! transform is separable, and each 1-D pass is the lower envelope of parabolas rooted at the
//! samples, found in linear time.

use rayon::prelude::*;

/// Trimap value of a pixel known to be background (alpha 0).
pub const BACKGROUND: u8 = 0;
/// Trimap value of a pixel whose alpha is unknown (to be solved by matting).
pub const UNKNOWN: u8 = 128;
/// Trimap value of a pixel known to be foreground (alpha 1).
pub const FOREGROUND: u8 = 255;

/// A trimap: one of [`BACKGROUND`], [`UNKNOWN`] or [`FOREGROUND`] per pixel, row-major
/// (`data[y * width + x]`, top row first).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Trimap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` values, row-major.
    pub data: Vec<u8>,
}

impl Trimap {
    /// From a per-pixel probability (len w*h): pixels of `prob >= 0.5` eroded by `band_px` are
    /// FOREGROUND, pixels of `prob < 0.5` eroded by `band_px` (i.e. farther than band_px from the
    /// region) are BACKGROUND, the rest UNKNOWN.
    ///
    /// Distances are between pixel centres and only pixels inside the image count (the border is
    /// not background), so a pixel of the region stays FOREGROUND when every pixel of the other
    /// class is more than `band_px` away; the band therefore reaches about `band_px - 0.5` pixels
    /// to either side of the contour that runs between the two classes. A negative or NaN
    /// `band_px` is taken as 0 (no unknown pixels); NaN probabilities count as below 0.5.
    ///
    /// # Panics
    /// If `prob.len() != width * height`.
    pub fn from_probability(prob: &[f32], width: u32, height: u32, band_px: f32) -> Trimap {
        let n = width as usize * height as usize;
        assert_eq!(prob.len(), n, "a {width}x{height} trimap needs {n} probabilities, got {}", prob.len());
        let inside: Vec<bool> = prob.iter().map(|&p| p >= 0.5).collect();
        let outside: Vec<bool> = inside.iter().map(|&b| !b).collect();
        let to_inside = distance_to(&inside, width, height);
        let to_outside = distance_to(&outside, width, height);
        let band = if band_px > 0.0 { band_px } else { 0.0 };
        let data = (0..n)
            .into_par_iter()
            .map(|i| {
                // Erosion by a disc of radius `band`: a pixel keeps its class when no pixel of the
                // other class lies within the disc (an image with one class only has no band).
                let (keep, class) =
                    if inside[i] { (to_outside[i] > band, FOREGROUND) } else { (to_inside[i] > band, BACKGROUND) };
                if keep {
                    class
                } else {
                    UNKNOWN
                }
            })
            .collect();
        Trimap { width, height, data }
    }

    /// The number of [`UNKNOWN`] pixels.
    pub fn unknown_count(&self) -> usize {
        self.data.iter().filter(|&&v| v == UNKNOWN).count()
    }
}

/// Exact squared Euclidean distance transform (Felzenszwalb & Huttenlocher 2012, two 1-D passes), distance
/// in pixels from each pixel to the nearest pixel where `inside` is true (0 on those pixels; f32::INFINITY if none).
///
/// The squared distances are exact integers (computed in `f64`); the result is their square root,
/// row-major like `inside`. An empty image gives an empty vector.
///
/// # Panics
/// If `inside.len() != width * height`.
pub fn distance_to(inside: &[bool], width: u32, height: u32) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(inside.len(), w * h, "a {width}x{height} image needs {} mask values, got {}", w * h, inside.len());
    if w == 0 || h == 0 {
        return Vec::new();
    }
    // Pass 1 runs down the columns; its result is stored column-major so that each column is one
    // contiguous slice owned by one task. No reductions cross tasks, so the result does not depend
    // on the thread count.
    let mut columns = vec![0.0f64; w * h];
    columns.par_chunks_mut(h).enumerate().for_each_init(
        || Envelope::new(h),
        |env, (x, out)| {
            for y in 0..h {
                env.f[y] = if inside[y * w + x] { 0.0 } else { f64::INFINITY };
            }
            env.transform(out);
        },
    );
    // Pass 2 runs along the rows over the column pass's squared distances.
    let mut result = vec![0.0f32; w * h];
    result.par_chunks_mut(w).enumerate().for_each_init(
        || (Envelope::new(w), vec![0.0f64; w]),
        |(env, d2), (y, row)| {
            for x in 0..w {
                env.f[x] = columns[x * h + y];
            }
            env.transform(d2);
            for (out, &d) in row.iter_mut().zip(d2.iter()) {
                *out = d.sqrt() as f32;
            }
        },
    );
    result
}

/// Scratch space for one 1-D distance transform of length `n`: the sampled function `f` and the
/// lower envelope of the parabolas `(q - p)^2 + f[p]` (their roots `v`, and `z[k]`, where parabola
/// `v[k]` starts to be the lowest).
struct Envelope {
    f: Vec<f64>,
    v: Vec<usize>,
    z: Vec<f64>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Self { f: vec![0.0; n], v: Vec::with_capacity(n), z: Vec::with_capacity(n + 1) }
    }

    /// `out[q] = min_p (q - p)^2 + f[p]`, infinite where every `f[p]` is.
    fn transform(&mut self, out: &mut [f64]) {
        let f = &self.f;
        self.v.clear();
        self.z.clear();
        // Samples at infinity contribute no parabola; skipping them (instead of using a large
        // finite stand-in) keeps the intersections free of inf - inf and the result exact.
        for q in 0..f.len() {
            let fq = f[q];
            if !fq.is_finite() {
                continue;
            }
            let qf = q as f64;
            let mut s = f64::NEG_INFINITY;
            while let Some(&p) = self.v.last() {
                let pf = p as f64;
                // Where the parabolas rooted at p and q intersect.
                s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
                if s <= *self.z.last().expect("z and v have equal lengths") {
                    self.v.pop();
                    self.z.pop();
                    s = f64::NEG_INFINITY;
                } else {
                    break;
                }
            }
            self.v.push(q);
            self.z.push(s);
        }
        if self.v.is_empty() {
            out.fill(f64::INFINITY);
            return;
        }
        self.z.push(f64::INFINITY);
        let mut k = 0;
        for (q, o) in out.iter_mut().enumerate() {
            let qf = q as f64;
            while self.z[k + 1] < qf {
                k += 1;
            }
            let p = self.v[k];
            let d = qf - p as f64;
            *o = d * d + f[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::masks::tests::Lcg;

    fn brute_force(inside: &[bool], w: usize, h: usize) -> Vec<f32> {
        let mut out = vec![f32::INFINITY; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut best = i64::MAX;
                for (j, _) in inside.iter().enumerate().filter(|(_, &b)| b) {
                    let (dx, dy) = ((j % w) as i64 - x as i64, (j / w) as i64 - y as i64);
                    best = best.min(dx * dx + dy * dy);
                }
                if best != i64::MAX {
                    out[y * w + x] = (best as f64).sqrt() as f32;
                }
            }
        }
        out
    }

    #[test]
    fn distance_transform_equals_brute_force() {
        let (w, h) = (37usize, 23usize);
        let mut rng = Lcg(12345);
        // Sparse and dense masks: sparse ones have long distances and many popped parabolas.
        for density in [0.02f32, 0.1, 0.5] {
            let inside: Vec<bool> = (0..w * h).map(|_| rng.next_f32() < density).collect();
            assert!(inside.iter().any(|&b| b));
            let fast = distance_to(&inside, w as u32, h as u32);
            let slow = brute_force(&inside, w, h);
            for i in 0..w * h {
                assert_eq!(fast[i], slow[i], "density {density}, pixel ({}, {})", i % w, i / w);
            }
        }
        // One lone pixel in a corner: the distance grows to the far corner.
        let mut one = vec![false; w * h];
        one[w * h - 1] = true;
        assert_eq!(distance_to(&one, w as u32, h as u32), brute_force(&one, w, h));
        let d = distance_to(&one, w as u32, h as u32);
        assert!((d[0] - ((36.0f32 * 36.0) + 22.0 * 22.0).sqrt()).abs() < 1e-4);
    }

    #[test]
    fn distance_transform_edge_cases() {
        assert!(distance_to(&[false; 6], 3, 2).iter().all(|d| d.is_infinite()));
        assert!(distance_to(&[true; 6], 2, 3).iter().all(|&d| d == 0.0));
        assert!(distance_to(&[], 0, 5).is_empty());
        assert_eq!(distance_to(&[false, false, true, false], 4, 1), vec![2.0, 1.0, 0.0, 1.0]);
        assert_eq!(distance_to(&[false, true, false], 1, 3), vec![1.0, 0.0, 1.0]);
    }

    #[test]
    fn trimap_band_around_a_disc() {
        let (w, h) = (100u32, 100u32);
        let (cx, cy, radius, band) = (50.0f32, 50.0f32, 30.0f32, 4.0f32);
        let r = |i: usize| ((i % 100) as f32 - cx).hypot((i / 100) as f32 - cy);
        let prob: Vec<f32> = (0..(w * h) as usize).map(|i| if r(i) <= radius { 0.9 } else { 0.1 }).collect();
        let trimap = Trimap::from_probability(&prob, w, h, band);
        assert_eq!(trimap.data.len(), (w * h) as usize);
        // A pixel at distance s from the circle is unknown when s plus the gap between the circle
        // and the nearest pixel centre of the other class is at most `band`. That gap lies between
        // 0 and about half a pixel (less on average, as the nearest centre may sit off the normal),
        // so the band is an annulus of half-width between band - 0.5 and band; its middle,
        // band - 0.25, should match the count to within a few percent.
        let annulus = |half: f32| std::f32::consts::PI * ((radius + half).powi(2) - (radius - half).powi(2));
        let unknown = trimap.unknown_count() as f32;
        assert!(unknown > annulus(band - 0.5) && unknown < annulus(band), "{unknown} unknown pixels");
        let mid = annulus(band - 0.25);
        assert!((unknown / mid - 1.0).abs() < 0.03, "{unknown} unknown pixels, annulus area {mid}");
        for (i, &t) in trimap.data.iter().enumerate() {
            let d = r(i) - radius;
            match t {
                UNKNOWN => assert!(d.abs() <= band + 0.5, "unknown pixel {d} px from the edge"),
                FOREGROUND => assert!(d < -(band - 1.5), "foreground pixel {d} px from the edge"),
                BACKGROUND => assert!(d > band - 1.5, "background pixel {d} px from the edge"),
                other => panic!("trimap value {other}"),
            }
            if d < -(band + 1.0) {
                assert_eq!(t, FOREGROUND);
            }
            if d > band + 1.0 {
                assert_eq!(t, BACKGROUND);
            }
        }
        // The band's width follows band_px: no band at 0, a wider one at 8.
        assert_eq!(Trimap::from_probability(&prob, w, h, 0.0).unknown_count(), 0);
        let wide = Trimap::from_probability(&prob, w, h, 8.0).unknown_count() as f32;
        assert!((wide / unknown - 7.5 / 3.5).abs() < 0.1, "{wide} vs {unknown}");
    }

    #[test]
    fn trimap_of_one_class_has_no_band() {
        let all_in = Trimap::from_probability(&[0.7; 12], 4, 3, 5.0);
        assert!(all_in.data.iter().all(|&t| t == FOREGROUND));
        let all_out = Trimap::from_probability(&[0.2, f32::NAN, 0.0, 0.49], 2, 2, 5.0);
        assert!(all_out.data.iter().all(|&t| t == BACKGROUND));
    }
}
