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
//!
//! Photo fusion also builds the sparse ends of long hair, where they hang free below the head, into
//! a sheet of their own, and that sheet's colour over the views is itself the blend (pale with the
//! backdrop behind it), so the region reads it as no hair and its own colour explains the pixel
//! with no hair at all. A surface far from the fitted head, on which the views disagree (each sees
//! other strands and another background through it), and whose own colour is a blend of the
//! hair's and the clear background's, is taken for such a sheet ([`BeyondOptions::loose_sheets`]):
//! its pixels blend with the background behind it instead, however far they lie from the
//! silhouette.

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
    /// A surface of the raw mesh far from the fitted head, whose colour varies over the views and is
    /// on average a blend of the hair's and the clear background's, is a sheet of sparse hair: its
    /// pixels blend with the background (module doc). A configuration without it replays without it.
    #[serde(default)]
    pub loose_sheets: bool,
}

impl Default for BeyondOptions {
    fn default() -> Self {
        Self { reach_mm: 30.0, min_contrast: 0.15, max_residual: 0.25, block_px: 16, on_mesh: true, loose_sheets: true }
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
    /// Per vertex: how much its colour varies over the views that see it (the RMS distance from
    /// its mean, linear RGB).
    pub spread: &'a [f32],
    /// Per vertex: it lies far from the fitted head (no face, neck or scalp near it).
    pub far: &'a [bool],
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

    /// Whether the ray of `hit` meets the raw mesh where it may be a sheet of sparse hair: all
    /// three corners far from the head, the views disagreeing on their colours.
    fn loose(&self, hit: &super::render::PixelHit) -> bool {
        let loose = |v: u32| {
            let v = v as usize;
            self.far.get(v).copied().unwrap_or(false) && self.spread.get(v).is_some_and(|&s| s >= SHEET_SPREAD)
        };
        hit.surface == Surface::Raw
            && self.raw.triangles.get(hit.triangle as usize).is_some_and(|t| t.iter().all(|&v| loose(v)))
    }
}

/// `c` read as a blend of `bg` and `fore`: the share of `fore`, when the two differ by at least
/// [`BeyondOptions::min_contrast`] and `c` lies within `max_residual` of their distance from the
/// segment between.
fn blend_share(c: Vec3, bg: Vec3, fore: Vec3, max_residual: f32, opts: &BeyondOptions) -> Option<f32> {
    let d = fore - bg;
    let len = d.length();
    if len < opts.min_contrast {
        return None;
    }
    let alpha = ((c - bg).dot(d) / (len * len)).clamp(0.0, 1.0);
    ((c - (bg + alpha * d)).length() <= max_residual * len).then_some(alpha)
}

/// The least share of hair in a loose surface's own colour for it to be taken for a sheet of sparse
/// hair (below, a pale surface is as likely a backdrop's own).
const MIN_SHEET_SHARE: f32 = 0.1;

/// A loose surface's own colour lies this close to the blend's segment, as a share of its length,
/// to be taken for a sheet of sparse hair: closer than a pixel's blend needs to, since skin and
/// clothes lie near the segment from dark hair to a pale backdrop (lit skin against brown hair and
/// white: 0.14), and what a sheet shows is a blend by construction (0.02 on the straight capture).
const SHEET_RESIDUAL: f32 = 0.08;

/// The least spread of a surface's colour over the views (RMS, linear RGB) for it to be taken
/// for a sheet of sparse hair. Opaque surfaces under the capture's light vary less: the clothed
/// torso of the red-haired clutter capture, whose colours lie on the segment from the hair to the
/// room, mostly under 0.01 (a threshold of 0.01 put 1.3 % of its masks off the hair, 0.02 none);
/// the sparse ends of the straight capture's hair are at 0.08 in the median.
const SHEET_SPREAD: f32 = 0.02;

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
        if *s >= 0.5 {
            continue;
        }
        let hit = &hits.hits[i];
        let within = from_hair[i] <= reach_px;
        // A sheet of sparse hair is hair however far it hangs from the silhouette.
        let may_be_sheet = opts.on_mesh && opts.loose_sheets && behind.loose(hit);
        if !(within || may_be_sheet) {
            continue;
        }
        let (x, y) = (i % w as usize, i / w as usize);
        let b = (y / block) * bw + x / block;
        let backdrop_here = back.as_ref().map(|(back, _)| back[b]);
        let bg = if missed(i) {
            match backdrop_here {
                Some(c) => c,
                None => continue,
            }
        } else if opts.on_mesh {
            match (behind.at(hit), backdrop_here) {
                // A sheet of sparse hair: its own colour is a blend of the hair and the backdrop.
                (Some(s), Some(bd))
                    if may_be_sheet
                        && blend_share(s, bd, fore[b], SHEET_RESIDUAL, opts).is_some_and(|a| a >= MIN_SHEET_SHARE) =>
                {
                    bd
                }
                (Some(s), _) if within => s,
                _ => continue,
            }
        } else {
            continue;
        };
        let c = pixel(image, i);
        if let Some(alpha) = blend_share(c, bg, fore[b], opts.max_residual, opts) {
            if alpha > *s + 1e-3 {
                *s = alpha;
                raised += 1;
            }
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

    /// A sheet of sparse hair as fusion builds it: its colour over the views is half hair, half
    /// the white backdrop seen through it.
    const SHEET: Vec3 = Vec3::new(0.475, 0.465, 0.46);

    /// The raw mesh behind the hair: triangle 0 skin, triangle 1 skin in shadow, triangle 2 a sheet
    /// of sparse hair, triangle 3 grey clothes of the sheet's colour (their vertices' colours over
    /// the views, and how much they vary: the sheet's much, the opaque surfaces' little).
    fn mesh() -> (TriMesh, Vec<Option<Vec3>>, Vec<f32>) {
        let triangles = vec![[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11]];
        let m = TriMesh { vertices: vec![Vec3::ZERO; 12], triangles, normals: None, uvs: None };
        let colours = [SKIN, SHADE, SHEET, SHEET].into_iter().flat_map(|c| [Some(c); 3]).collect();
        let spread = [0.005, 0.005, 0.08, 0.005].into_iter().flat_map(|s| [s; 3]).collect();
        (m, colours, spread)
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
        run_loose(behind, reach, o, false)
    }

    /// As [`run`], with every vertex of the raw mesh far from the head (`loose`) or none.
    fn run_loose(
        behind: impl Fn(usize, usize) -> (Vec3, Option<u32>),
        reach: f32,
        o: &BeyondOptions,
        loose: bool,
    ) -> (usize, Vec<f32>, Vec<f32>) {
        let (m, colours, spread) = mesh();
        let far = vec![loose; m.vertices.len()];
        let (mut sil, hits, image, truth) = view(behind);
        let behind = Behind { raw: &m, colours: &colours, spread: &spread, far: &far };
        let raised = extend(&mut sil, &hits, &image, &behind, reach, o);
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
    fn a_sheet_of_sparse_hair_far_from_the_head_blends_with_the_backdrop_behind_it() {
        // The top 10 rows show the white backdrop; the bottom 10 the sheet, whose own colour is a
        // blend, and the backdrop through it. Far from the head, the sheet's pixels blend with the
        // backdrop; near it (or without the option) with the sheet's own colour, which reads the
        // sheet's half share of hair as none.
        let sheet = |_: usize, y: usize| (WHITE, (y >= 10).then_some(2));
        let (raised, sil, truth) = run_loose(sheet, 8.0, &opts(), true);
        assert_eq!(raised, 80);
        assert_close(&sil, &truth);
        for (loose, o) in [(false, opts()), (true, BeyondOptions { loose_sheets: false, ..opts() })] {
            let (raised, sil, _) = run_loose(sheet, 8.0, &o, loose);
            assert_eq!(raised, 40 + 20, "the backdrop's half, and on the sheet only the two darkest columns");
            assert!(sil[10 * 40 + 20] < 0.7 && sil[10 * 40 + 22] == 0.0);
        }
        // Lit skin far from the head (a hand, a bare shoulder) is no sheet: its colour lies near the
        // segment from brown hair to white, but not near enough.
        let hand = |_: usize, y: usize| if y < 10 { (WHITE, None) } else { (SKIN, Some(0)) };
        let (raised, sil, truth) = run_loose(hand, 8.0, &opts(), true);
        assert_eq!(raised, 80);
        assert_close(&sil, &truth);
        // Grey clothes of the sheet's very colour, on which the views agree, are no sheet either:
        // hair over them blends with their own colour.
        let clothes = |_: usize, y: usize| if y < 10 { (WHITE, None) } else { (SHEET, Some(3)) };
        let (raised, sil, truth) = run_loose(clothes, 8.0, &opts(), true);
        assert_eq!(raised, 80, "as a sheet, the clothes' own pixels would take half a share of hair");
        assert_close(&sil, &truth);
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
