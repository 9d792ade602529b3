//! Masks against ground truth (a synthetic capture's renderer masks): IoU of the thresholded
//! masks, mean absolute alpha error, and the share of the mask that lies clearly off the hair
//! (on the backdrop, the clothes or the face).

use std::path::PathBuf;

use hairrecon_core::image_io::{read_gray_f32, GrayImage32};
use hairrecon_core::FormatError;
use thiserror::Error;

use super::trimap::distance_to;

/// A mask pixel farther than this (pixels) from any ground-truth hair counts as a false positive.
pub const OFF_HAIR_PX: f32 = 2.0;

/// One view's mask against its ground truth.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MaskScore {
    /// |A ∩ G| / |A ∪ G| of `alpha ≥ 0.5` and `gt ≥ 0.5`.
    pub iou: f32,
    /// Mean |alpha − gt| over the pixels where either is above zero.
    pub alpha_error: f32,
    /// Share of the mask's pixels (`alpha ≥ 0.5`) farther than [`OFF_HAIR_PX`] from every pixel
    /// of ground-truth coverage above zero.
    pub off_hair: f32,
    /// Pixels of `alpha ≥ 0.5` and of `gt ≥ 0.5`.
    pub area: usize,
    pub gt_area: usize,
}

/// Scores `alpha` against `gt` (the same size; the caller resamples).
pub fn score(alpha: &GrayImage32, gt: &GrayImage32) -> MaskScore {
    assert_eq!((alpha.width, alpha.height), (gt.width, gt.height), "the caller resamples the ground truth");
    let (mut inter, mut union, mut area, mut gt_area) = (0usize, 0usize, 0usize, 0usize);
    let (mut err, mut err_n) = (0.0f64, 0usize);
    for (&a, &g) in alpha.data.iter().zip(&gt.data) {
        let (ai, gi) = (a >= 0.5, g >= 0.5);
        inter += (ai && gi) as usize;
        union += (ai || gi) as usize;
        area += ai as usize;
        gt_area += gi as usize;
        if a > 0.0 || g > 0.0 {
            err += (a - g).abs() as f64;
            err_n += 1;
        }
    }
    let hair: Vec<bool> = gt.data.iter().map(|&g| g > 0.0).collect();
    let dist = distance_to(&hair, gt.width, gt.height);
    let off = alpha.data.iter().zip(&dist).filter(|(&a, &d)| a >= 0.5 && d > OFF_HAIR_PX).count();
    MaskScore {
        iou: if union == 0 { 1.0 } else { inter as f32 / union as f32 },
        alpha_error: if err_n == 0 { 0.0 } else { (err / err_n as f64) as f32 },
        off_hair: if area == 0 { 0.0 } else { off as f32 / area as f32 },
        area,
        gt_area,
    }
}

/// Area-averages `img` down to `width` × `height` (the ground truth of a wild capture is at the
/// photos' size; the importer scaled each axis by its own factor, width rounded). Each target
/// pixel is the mean of the source area it covers, partial pixels weighted by their overlap.
/// `None` when the target is empty or larger than the source.
pub fn downsample(img: &GrayImage32, width: u32, height: u32) -> Option<GrayImage32> {
    if width == 0 || height == 0 || width > img.width || height > img.height {
        return None;
    }
    // Per axis: for each target index, the (source index, weight) pairs it covers.
    let spans = |src: u32, dst: u32| -> Vec<Vec<(usize, f32)>> {
        let f = src as f64 / dst as f64;
        (0..dst)
            .map(|i| {
                let (lo, hi) = (i as f64 * f, (i + 1) as f64 * f);
                let mut v = Vec::new();
                let mut j = lo.floor() as usize;
                while (j as f64) < hi && j < src as usize {
                    let w = (hi.min(j as f64 + 1.0) - lo.max(j as f64)) / f;
                    if w > 0.0 {
                        v.push((j, w as f32));
                    }
                    j += 1;
                }
                v
            })
            .collect()
    };
    let (xs, ys) = (spans(img.width, width), spans(img.height, height));
    let mut data = vec![0.0f32; (width * height) as usize];
    for (y, row_spans) in ys.iter().enumerate() {
        for (x, col_spans) in xs.iter().enumerate() {
            let mut s = 0.0;
            for &(sy, wy) in row_spans {
                let row = sy * img.width as usize;
                for &(sx, wx) in col_spans {
                    s += wy * wx * img.data[row + sx];
                }
            }
            data[y * width as usize + x] = s;
        }
    }
    Some(GrayImage32 { width, height, data })
}

/// Why masks could not be scored.
#[derive(Debug, Error)]
pub enum ScoreError {
    #[error("view {view}: the capture has no mask to score against")]
    NoMask { view: String },
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("view {view}: the mask {path} is {found}, smaller than the view's {expected}")]
    TooSmall { view: String, path: PathBuf, found: String, expected: String },
}

/// Scores each view's `alphas[k]` (named `names[k]`) against the mask file `gt[k]`, area-averaged
/// to the view's size.
pub fn score_views(
    alphas: &[GrayImage32],
    names: &[String],
    gt: &[Option<PathBuf>],
) -> Result<Vec<(String, MaskScore)>, ScoreError> {
    let mut out = Vec::with_capacity(alphas.len());
    for ((alpha, name), path) in alphas.iter().zip(names).zip(gt) {
        let Some(path) = path else {
            return Err(ScoreError::NoMask { view: name.clone() });
        };
        let truth = read_gray_f32(path)?;
        let truth = downsample(&truth, alpha.width, alpha.height).ok_or_else(|| ScoreError::TooSmall {
            view: name.clone(),
            path: path.clone(),
            found: format!("{}x{}", truth.width, truth.height),
            expected: format!("{}x{}", alpha.width, alpha.height),
        })?;
        out.push((name.clone(), score(alpha, &truth)));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> GrayImage32 {
        let data = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect();
        GrayImage32 { width: w, height: h, data }
    }

    #[test]
    fn a_mask_shifted_by_two_columns_and_a_far_blob_score_as_counted_by_hand() {
        // Ground truth: a 10 × 10 square at (10..20, 10..20). Mask: the same square shifted right
        // by 2 columns, plus a 3 × 3 blob far away at (30..33, 30..33).
        let gt = img(40, 40, |x, y| ((10..20).contains(&x) && (10..20).contains(&y)) as u8 as f32);
        let a = img(40, 40, |x, y| {
            (((12..22).contains(&x) && (10..20).contains(&y)) || ((30..33).contains(&x) && (30..33).contains(&y))) as u8
                as f32
        });
        let s = score(&a, &gt);
        // Intersection 8 × 10 = 80; union 100 + 109 − 80 = 129.
        assert!((s.iou - 80.0 / 129.0).abs() < 1e-6, "{s:?}");
        assert_eq!((s.area, s.gt_area), (109, 100));
        // The shifted columns lie within 2 px of the square: only the blob is off the hair.
        assert!((s.off_hair - 9.0 / 109.0).abs() < 1e-6, "{s:?}");
        // |a − g| = 1 on the 20 + 9 pixels of the mask off the square and the 20 of the square
        // off the mask, over the 129 pixels where either is nonzero.
        assert!((s.alpha_error - 49.0 / 129.0).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn downsampling_averages_the_area_each_pixel_covers() {
        let big = img(6, 9, |x, y| (x + 10 * y) as f32);
        let small = downsample(&big, 2, 3).unwrap();
        // Block (0, 0): x 0..3, y 0..3 → mean x 1, mean y 1 → 11.
        assert!((small.data[0] - 11.0).abs() < 1e-4);
        assert!((small.data[5] - 74.0).abs() < 1e-4);
        // 3 columns onto 2: the first takes column 0 and half of column 1 (weights 2/3, 1/3).
        let row = img(3, 1, |x, _| [3.0, 6.0, 9.0][x as usize]);
        let two = downsample(&row, 2, 1).unwrap();
        assert!((two.data[0] - 4.0).abs() < 1e-5 && (two.data[1] - 8.0).abs() < 1e-5, "{:?}", two.data);
        assert!(downsample(&big, 7, 3).is_none());
    }
}
