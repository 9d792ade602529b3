//! Hair beyond the raw mesh. Photo fusion leaves out what few views agree on: the fuzzy edge of
//! the hair and the sparse ends of long or curly hair. Where a pixel's ray misses the raw mesh the
//! silhouette says no hair, though the photo shows some there. Such a pixel's colour is a blend of
//! the hair's and of the background behind it, `c = α h + (1 − α) b` in linear RGB (as a camera
//! and a renderer add light), and the same view shows both clearly a little way off: the hair
//! inside the silhouette, the background farther out. So, per view:
//!
//! - `b`: the mean colour of the clear background pixels (rays that meet nothing, farther than
//!   [`BeyondOptions::reach_mm`] from the silhouette), per block of the image, each block without
//!   any taking its nearest block's;
//! - `h`: the same of the confident hair pixels (silhouette ≥ 0.9);
//! - each pixel under 0.5 within the reach of the silhouette takes `α = (c − b)·(h − b) / |h − b|²`,
//!   clamped to [0, 1], where the two colours differ enough to tell
//!   ([`BeyondOptions::min_contrast`]) and the blend explains the colour (its distance to the
//!   segment from `b` to `h` at most [`BeyondOptions::max_residual`] of `|h − b|`), when that is
//!   more than it had.
//!
//! The same holds where hair hangs in front of a surface the raw mesh does have (the face, the
//! neck, the shoulders, clothes): the ray meets the mesh outside the hair region, and `b` is that
//! surface's own colour, the mean over the views that see it (its vertices', interpolated). A
//! block mean would not do there: a neck in shadow is darker than the skin around it, and brown
//! hair over skin blends along nearly the line from lit to shaded skin. A pixel whose ray meets
//! the fitted head (a hole in the raw mesh) is left as it is.

use glam::Vec3;
use hairrecon_core::image_io::RgbImage32;
use hairrecon_core::TriMesh;

use super::colour::srgb_to_linear;
use super::render::{Surface, ViewHits};
use super::trimap::distance_to;

/// The parameters of the hair beyond the raw mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BeyondOptions {
    /// How far (mm, at the head's distance) beyond the silhouette hair may lie that the raw mesh
    /// left out; 0 turns this off.
    pub reach_mm: f32,
    /// The least distance between the hair's and the background's colours (linear RGB, each in
    /// [0, 1]) at which a blend of the two is told.
    pub min_contrast: f32,
    /// The largest distance of a pixel's colour from the blend's segment, as a share of the
    /// segment's length, at which the pixel counts as a blend.
    pub max_residual: f32,
    /// The side of the blocks (pixels) over which the colours are averaged.
    pub block_px: u32,
    /// Also where the ray meets the raw mesh outside the hair region (hair hanging in front of
    /// the face, the neck or the shoulders), against the colour of that surface.
    pub on_mesh: bool,
}

impl Default for BeyondOptions {
    fn default() -> Self {
        Self { reach_mm: 30.0, min_contrast: 0.15, max_residual: 0.25, block_px: 16, on_mesh: true }
    }
}

impl BeyondOptions {
    /// Off: what configurations written before this step replay.
    pub fn off() -> Self {
        Self { reach_mm: 0.0, ..Self::default() }
    }
}

/// What lies behind the hair where a ray meets the raw mesh: the mesh and its vertices' mean
/// colours over the views (linear RGB; `None` where no view sees a vertex).
#[derive(Debug)]
pub struct Behind<'a> {
    pub raw: &'a TriMesh,
    pub colours: &'a [Option<Vec3>],
}

impl Behind<'_> {
    /// The surface's colour where the ray of `hit` meets it, when it is the raw mesh and all
    /// three corners have one.
    fn at(&self, hit: &super::render::PixelHit) -> Option<Vec3> {
        if hit.surface != Surface::Raw {
            return None;
        }
        let t = self.raw.triangles.get(hit.triangle as usize)?;
        let c = |k: usize| self.colours.get(t[k] as usize).copied().flatten();
        Some((1.0 - hit.u - hit.v) * c(0)? + hit.u * c(1)? + hit.v * c(2)?)
    }
}

/// Linear RGB of pixel `i` of `image`.
fn pixel(image: &RgbImage32, i: usize) -> Vec3 {
    srgb_to_linear([image.data[3 * i], image.data[3 * i + 1], image.data[3 * i + 2]])
}

/// Per block of `block` × `block` pixels, the mean linear colour of the pixels where `take` holds;
/// blocks without one take their nearest block's (by breadth-first search over the blocks, ties
/// by the search order). `None` when no pixel is taken.
fn block_means(image: &RgbImage32, take: &[bool], block: usize) -> Option<(Vec<Vec3>, usize)> {
    let (w, h) = (image.width as usize, image.height as usize);
    let (bw, bh) = (w.div_ceil(block), h.div_ceil(block));
    let mut sum = vec![Vec3::ZERO; bw * bh];
    let mut count = vec![0u32; bw * bh];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if take[i] {
                let b = (y / block) * bw + x / block;
                sum[b] += pixel(image, i);
                count[b] += 1;
            }
        }
    }
    let mut mean: Vec<Option<Vec3>> = sum.iter().zip(&count).map(|(&s, &n)| (n > 0).then(|| s / n as f32)).collect();
    let mut queue: std::collections::VecDeque<usize> = (0..bw * bh).filter(|&b| mean[b].is_some()).collect();
    if queue.is_empty() {
        return None;
    }
    while let Some(b) = queue.pop_front() {
        let (bx, by) = (b % bw, b / bw);
        let m = mean[b];
        let mut visit = |nx: usize, ny: usize| {
            let n = ny * bw + nx;
            if mean[n].is_none() {
                mean[n] = m;
                queue.push_back(n);
            }
        };
        if bx > 0 {
            visit(bx - 1, by);
        }
        if bx + 1 < bw {
            visit(bx + 1, by);
        }
        if by > 0 {
            visit(bx, by - 1);
        }
        if by + 1 < bh {
            visit(bx, by + 1);
        }
    }
    Some((mean.into_iter().map(|m| m.unwrap_or(Vec3::ZERO)).collect(), bw))
}

/// Raises `silhouette` (the region's probability per pixel of the view) within `reach_px` of it
/// where the photo shows a blend of hair and what lies behind (module doc).
/// Returns how many pixels it raised.
pub fn extend(
    silhouette: &mut [f32],
    hits: &ViewHits,
    image: &RgbImage32,
    behind: &Behind,
    reach_px: f32,
    opts: &BeyondOptions,
) -> usize {
    let (w, h) = (hits.width, hits.height);
    let n = w as usize * h as usize;
    if reach_px <= 0.0 || n == 0 || silhouette.len() != n || image.data.len() != 3 * n {
        return 0;
    }
    let hair: Vec<bool> = silhouette.iter().map(|&p| p >= 0.5).collect();
    let from_hair = distance_to(&hair, w, h);
    let missed = |i: usize| hits.hits[i].surface == Surface::None;
    let backdrop: Vec<bool> = (0..n).map(|i| missed(i) && from_hair[i] > reach_px).collect();
    let sure: Vec<bool> = silhouette.iter().map(|&p| p >= 0.9).collect();
    let block = opts.block_px.max(1) as usize;
    let Some((fore, bw)) = block_means(image, &sure, block) else { return 0 };
    let back = block_means(image, &backdrop, block);
    let mut raised = 0;
    for (i, s) in silhouette.iter_mut().enumerate() {
        if *s >= 0.5 || from_hair[i] > reach_px {
            continue;
        }
        let (x, y) = (i % w as usize, i / w as usize);
        let b = (y / block) * bw + x / block;
        let bg = if missed(i) {
            match &back {
                Some((back, _)) => back[b],
                None => continue,
            }
        } else if opts.on_mesh {
            match behind.at(&hits.hits[i]) {
                Some(c) => c,
                None => continue,
            }
        } else {
            continue;
        };
        let d = fore[b] - bg;
        let len = d.length();
        if len < opts.min_contrast {
            continue;
        }
        let c = pixel(image, i);
        let alpha = ((c - bg).dot(d) / (len * len)).clamp(0.0, 1.0);
        let residual = (c - (bg + alpha * d)).length();
        if residual <= opts.max_residual * len && alpha > *s + 1e-3 {
            *s = alpha;
            raised += 1;
        }
    }
    raised
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::masks::render::PixelHit;

    const HAIR: Vec3 = Vec3::new(0.05, 0.03, 0.02);
    const WHITE: Vec3 = Vec3::new(0.9, 0.9, 0.9);
    const SKIN: Vec3 = Vec3::new(0.6, 0.4, 0.3);
    const SHADE: Vec3 = Vec3::new(0.2, 0.13, 0.1);

    /// The raw mesh behind the hair: triangle 0 skin, triangle 1 skin in shadow (their vertices'
    /// colours over the views).
    fn mesh() -> (TriMesh, Vec<Option<Vec3>>) {
        let m =
            TriMesh { vertices: vec![Vec3::ZERO; 6], triangles: vec![[0, 1, 2], [3, 4, 5]], normals: None, uvs: None };
        (m, [SKIN, SKIN, SKIN, SHADE, SHADE, SHADE].map(Some).to_vec())
    }

    /// A 40 × 20 view: the raw mesh met in the hair region on the left half (silhouette 1), dark
    /// brown hair there; on the right, `behind(x, y)` gives what lies behind (its linear colour and
    /// the raw mesh's triangle the ray meets, if any); in columns 20 to 24 the photo blends hair
    /// into it, the hair's share falling 0.8, 0.6, ... 0.
    fn view(behind: impl Fn(usize, usize) -> (Vec3, Option<u32>)) -> (Vec<f32>, ViewHits, RgbImage32, Vec<f32>) {
        let (w, h) = (40usize, 20usize);
        let enc = |v: f32| if v <= 0.0031308 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        let (mut data, mut truth, mut hits, mut sil) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let (back, met) = behind(x, y);
                let a = if x < 20 { 1.0 } else { (1.0 - 0.2 * (x as f32 - 19.0)).max(0.0) };
                let c = a * HAIR + (1.0 - a) * back;
                data.extend([enc(c.x), enc(c.y), enc(c.z)]);
                truth.push(a);
                let (surface, triangle) = match (x < 20, met) {
                    (true, _) => (Surface::Raw, 0),
                    (false, Some(t)) => (Surface::Raw, t),
                    (false, None) => (Surface::None, u32::MAX),
                };
                hits.push(PixelHit { depth: 1.0, surface, triangle, u: 0.2, v: 0.3 });
                sil.push(if x < 20 { 1.0 } else { 0.0 });
            }
        }
        let hits = ViewHits { width: w as u32, height: h as u32, hits };
        (sil, hits, RgbImage32 { width: w as u32, height: h as u32, data }, truth)
    }

    fn opts() -> BeyondOptions {
        BeyondOptions { block_px: 8, ..BeyondOptions::default() }
    }

    fn run(
        behind: impl Fn(usize, usize) -> (Vec3, Option<u32>),
        reach: f32,
        o: &BeyondOptions,
    ) -> (usize, Vec<f32>, Vec<f32>) {
        let (m, colours) = mesh();
        let (mut sil, hits, image, truth) = view(behind);
        let raised = extend(&mut sil, &hits, &image, &Behind { raw: &m, colours: &colours }, reach, o);
        (raised, sil, truth)
    }

    fn assert_close(sil: &[f32], truth: &[f32]) {
        for (i, (&s, &t)) in sil.iter().zip(truth).enumerate() {
            assert!((s - t).abs() < 0.02, "pixel ({}, {}): {s} against {t}", i % 40, i / 40);
        }
    }

    #[test]
    fn a_blend_of_hair_and_background_gets_the_hair_s_share() {
        let (raised, sil, truth) = run(|_, _| (WHITE, None), 8.0, &opts());
        // Columns 20..=23 hold 0.8, 0.6, 0.4, 0.2 of hair, 20 rows each (column 24 is background).
        assert_eq!(raised, 80);
        assert_close(&sil, &truth);
    }

    #[test]
    fn hair_in_front_of_the_mesh_blends_with_the_surface_s_own_colour() {
        // The top 10 rows show a white backdrop; the bottom 10 a neck on the mesh, in shadow
        // next to the hair (columns up to 29) and lit beyond. Each pixel blends with what lies
        // behind it, and the shaded skin, darker than the lit skin around, is no hair.
        let neck = |x: usize, y: usize| match (y < 10, x < 30) {
            (true, _) => (WHITE, None),
            (false, true) => (SHADE, Some(1)),
            (false, false) => (SKIN, Some(0)),
        };
        let (raised, sil, truth) = run(neck, 8.0, &opts());
        assert_eq!(raised, 80);
        assert_close(&sil, &truth);
        // Without `on_mesh` only the backdrop's half is raised.
        let (raised, sil, _) = run(neck, 8.0, &BeyondOptions { on_mesh: false, ..opts() });
        assert_eq!(raised, 40);
        assert!(sil[10 * 40..].iter().enumerate().all(|(i, &s)| i % 40 < 20 || s == 0.0));
    }

    #[test]
    fn nothing_is_raised_without_contrast_or_beyond_the_reach() {
        // A backdrop as dark as the hair: no blend can be told.
        let (raised, sil, _) = run(|_, _| (Vec3::new(0.06, 0.03, 0.02), None), 8.0, &BeyondOptions::default());
        assert_eq!(raised, 0);
        assert!(sil.iter().enumerate().all(|(i, &s)| s == if i % 40 < 20 { 1.0 } else { 0.0 }));
        // A reach of 2 px: only the first two columns outside may change.
        let (raised, sil, _) = run(|_, _| (WHITE, None), 2.0, &opts());
        assert_eq!(raised, 40);
        assert!(sil.iter().enumerate().all(|(i, &s)| i % 40 < 22 || s == 0.0));
        // Off.
        assert_eq!(run(|_, _| (WHITE, None), 0.0, &opts()).0, 0);
    }
}
