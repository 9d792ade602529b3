//! The visual hull of the hair: strands cut where some view sees them where there is no hair.
//!
//! In: the capture's views (camera, hair mask) and the head mesh. A strand point is *outside* in a
//! view when it projects onto a pixel whose neighbourhood (`margin_px` pixels each way) holds no hair
//! and no head in front of the point: hair there would have been seen. Out: the strands cut at their
//! first point (past the root) that is outside in at least `min_views` views ([`VisualHull::trim`]).
//! Roots, the kept points and their segments are unchanged, so the strands stay simulation-ready.
//!
//! Why: growth and DR both leave some strand ends outside the silhouettes (growth follows the raw
//! mesh, which bulges past the masks where it misreads the hair; the silhouette loss pulls only on
//! what it renders). Hair there would have been seen unless it is thinner than the mask shows, and
//! those points are the least precise: on the paper straight result without the hull (commit
//! a77a14a), the 6.3% of points outside in some view (one pixel of margin) matched the ground truth
//! at 2 mm/20° 41–52% of the time, the rest 87%. The pipeline cuts the children before DR (whole
//! `hairrecon reconstruct` runs on the paper preset, undirected F1 at 2 mm/20°, without → with the
//! hull, measured at commit 0af8db7): before DR straight 85.9 → 86.8, curly 49.1 → 51.8, wavy
//! 55.3 → 55.9; after DR straight 87.1 → 88.4 (1 mm 62.9 → 64.0, 3 mm 94.0 → 95.0). Cutting DR's
//! result again cost 0.5 (straight) and 0.2 (curly): after DR the points outside the masks still
//! match thin hair there.
//!
//! Masks whose hair pixels are mostly partly covered (sparse hair, see
//! [`HullParams::min_solid`]) are skipped: a silhouette needs opaque hair.

use glam::{Vec2, Vec3};
use hairrecon_core::capture::Capture;
use hairrecon_core::{Bvh, Camera, StrandSet};
use rayon::prelude::*;

use crate::orient2d::{GrayImage, Orient2dError};
use crate::progress::{Cancelled, Progress};

/// Options of the visual hull.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HullParams {
    /// A mask pixel is hair when its coverage is at least this (0.5: the silhouette; 0.1 kept more
    /// of the ends and scored 87.8 · 50.6 where 0.5 scored 87.8 · 51.8, straight after DR · curly
    /// before it).
    pub mask_threshold: f32,
    /// Pixels of margin around each hair pixel (masks are anti-aliased, calibration is not exact).
    pub margin_px: u32,
    /// A point is cut when it is outside in at least this many views.
    pub min_views: u32,
    /// A view's mask takes part when the median coverage of its pixels above 1% is at least this
    /// (see [`VisualHull::from_capture`]; the paper-preset masks: 0.97–1.0, the sparse 2000-strand
    /// test preset: 0.22–0.25, where a threshold of 0.5 cut 99% of the points).
    pub min_solid: f32,
    /// [`VisualHull::trim_checked`] refuses a cut that removes more than this share of the points:
    /// then the masks or cameras disagree with the reconstruction (the paper preset's cuts: 11–20%;
    /// sparse masks that the Blender add-on once wrote sRGB-encoded: about half, at commit a240ec3).
    pub max_cut: f32,
    /// A point counts as behind the head when its depth exceeds the head's by more than this, metres.
    pub head_tolerance: f32,
    /// Points closer than this to the scalp and within `root_grace` of arc from their root are never
    /// outside, metres (0: no such band): hair lying on the scalp by its root can be too thin for the
    /// masks to show (a parting's edges, sparse hair on the crown), and a strand cut there is lost
    /// whole, leaving the scalp bare. Needs the scalp mesh ([`VisualHull::with_scalp`]). On the demo's
    /// capture (straight, 20,000 strands, 16 views of 384 px) the hull dropped 2,075 of the 20,000
    /// children without it, 1,400 of the 4,171 roots on the top of the head; none with it.
    pub near_scalp: f32,
    /// The arc from the root over which `near_scalp` holds, metres.
    pub root_grace: f32,
}

impl Default for HullParams {
    fn default() -> Self {
        Self {
            mask_threshold: 0.5,
            margin_px: 1,
            min_views: 1,
            min_solid: 0.5,
            max_cut: 0.5,
            head_tolerance: 0.002,
            near_scalp: 0.004,
            root_grace: 0.02,
        }
    }
}

/// Why the hull could not be built.
#[derive(Debug, thiserror::Error)]
pub enum HullError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    #[error(transparent)]
    Mask(#[from] Orient2dError),
    #[error("view {view} has {got} mask pixels, its camera {width}×{height}")]
    Size { view: usize, got: usize, width: u32, height: u32 },
}

/// One view of the hull: where hair may be seen, and the head's depth.
#[derive(Debug, Clone)]
struct HullView {
    camera: Camera,
    /// Hair within `margin_px` of the pixel.
    hair: TiledBits,
    /// The nearest head depth (camera z) within `margin_px` of the pixel, `f32::INFINITY` where
    /// there is no head.
    head: Vec<f32>,
}

/// What [`VisualHull::trim`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrimStats {
    /// Strands cut short.
    pub cut: u64,
    /// Strands dropped because their first point past the root was outside.
    pub dropped: u64,
    /// Points removed (a dropped strand's root included), and all points before.
    pub points_removed: u64,
    pub points: u64,
}

/// The views' silhouettes of the hair with the head as occluder.
#[derive(Debug, Clone)]
pub struct VisualHull {
    views: Vec<HullView>,
    params: HullParams,
    /// The scalp, for [`HullParams::near_scalp`].
    scalp: Option<Bvh>,
}

/// `v` reduced by `pick` (e.g. `|` or `f32::min`) over a square of `r` pixels each way, as a
/// row pass then a column pass.
fn dilate<T: Copy + Send + Sync>(v: &[T], w: usize, h: usize, r: usize, pick: impl Fn(T, T) -> T + Sync) -> Vec<T> {
    if r == 0 {
        return v.to_vec();
    }
    let rows: Vec<T> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            (a..=b).map(|xx| v[y * w + xx]).reduce(&pick).unwrap_or(v[i])
        })
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
            (a..=b).map(|yy| rows[yy * w + x]).reduce(&pick).unwrap_or(rows[i])
        })
        .collect()
}

impl VisualHull {
    /// From per-view cameras, hair masks (`true`: hair, row-major) and optional head depth maps
    /// (camera z per pixel, `f32::INFINITY` where no head).
    pub fn new(views: Vec<(Camera, Vec<bool>, Option<Vec<f32>>)>, params: HullParams) -> Result<Self, HullError> {
        let r = params.margin_px as usize;
        let views = views
            .into_iter()
            .enumerate()
            .map(|(i, (camera, mask, head))| {
                let (w, h) = (camera.width() as usize, camera.height() as usize);
                let bad = |got| HullError::Size { view: i, got, width: camera.width(), height: camera.height() };
                if mask.len() != w * h {
                    return Err(bad(mask.len()));
                }
                let head = match head {
                    Some(d) if d.len() != w * h => return Err(bad(d.len())),
                    Some(d) => dilate(&d, w, h, r, f32::min),
                    None => vec![f32::INFINITY; w * h],
                };
                let hair = TiledBits::new(&dilate(&mask, w, h, r, |a, b| a | b), w, h);
                Ok(HullView { camera, hair, head })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { views, params, scalp: None })
    }

    /// From a capture's views with hair masks, with `head` as occluder. Views without a mask, and
    /// views whose mask is see-through (the median coverage of its hair pixels below
    /// `min_solid`: sparse hair whose silhouette the mask does not fill), say nothing and are
    /// skipped; `None` when no view is left. Reports as stage `stage`.
    pub fn from_capture(
        capture: &Capture,
        head: Option<&Bvh>,
        params: HullParams,
        stage: &str,
        progress: &dyn Progress,
    ) -> Result<Option<Self>, HullError> {
        let mut views = Vec::new();
        let n = capture.views.len();
        for (i, v) in capture.views.iter().enumerate() {
            progress.check()?;
            progress.update(stage, i as f32 / n.max(1) as f32, &format!("visual hull: view {}/{n}", i + 1));
            let Some(m) = &v.mask else { continue };
            let img = GrayImage::load(m)?;
            let (w, h) = (v.camera.width(), v.camera.height());
            if (img.width, img.height) != (w, h) {
                return Err(HullError::Size { view: i, got: img.data.len(), width: w, height: h });
            }
            if !crate::views::solid(&img.data, params.min_solid) {
                continue;
            }
            let mask = img.data.iter().map(|&c| c >= params.mask_threshold).collect();
            let depth = head.map(|h| crate::views::head_depth_map(&v.camera, h));
            views.push((v.camera, mask, depth));
        }
        if views.is_empty() {
            return Ok(None);
        }
        Self::new(views, params).map(Some)
    }

    /// The scalp mesh, near which no point is outside by its root ([`HullParams::near_scalp`]).
    pub fn with_scalp(mut self, scalp: Option<Bvh>) -> Self {
        self.scalp = scalp;
        self
    }

    /// Whether `p` lies within [`HullParams::near_scalp`] of the scalp.
    fn near_scalp(&self, p: Vec3) -> bool {
        self.params.near_scalp > 0.0
            && self.scalp.as_ref().is_some_and(|h| h.closest_point(p, self.params.near_scalp).is_some())
    }

    pub fn num_views(&self) -> usize {
        self.views.len()
    }

    /// In how many views `p` is seen where neither hair nor the head in front of it is.
    pub fn views_outside(&self, p: Vec3) -> u32 {
        self.views_outside_up_to(p, u32::MAX)
    }

    /// [`VisualHull::views_outside`], counting no further than `enough`.
    fn views_outside_up_to(&self, p: Vec3, enough: u32) -> u32 {
        let mut n = 0;
        for v in &self.views {
            let Some(pr) = v.camera.project(p) else { continue };
            let Some((x, y)) = pixel(&v.camera, pr.pixel) else { continue };
            if v.hair.get(x, y) || pr.depth > v.head[y * v.camera.width() as usize + x] + self.params.head_tolerance {
                continue;
            }
            n += 1;
            if n >= enough {
                break;
            }
        }
        n
    }

    /// Each strand cut before its first point past the root that is outside in at least
    /// `min_views` views (points by the root on the scalp excepted, [`HullParams::near_scalp`]);
    /// strands left with the root alone are dropped.
    pub fn trim(&self, strands: &StrandSet) -> (StrandSet, TrimStats) {
        let min_views = self.params.min_views.max(1);
        let ends: Vec<usize> = strands
            .iter()
            .collect::<Vec<_>>()
            .par_iter()
            .map(|s| {
                let mut arc = 0.0;
                (1..s.len())
                    .find(|&j| {
                        arc += s[j].distance(s[j - 1]);
                        self.views_outside_up_to(s[j], min_views) >= min_views
                            && !(arc < self.params.root_grace && self.near_scalp(s[j]))
                    })
                    .unwrap_or(s.len())
            })
            .collect();
        let mut stats = TrimStats { points: strands.num_points() as u64, ..Default::default() };
        let mut points = Vec::with_capacity(strands.num_points());
        let mut counts = Vec::with_capacity(strands.num_strands());
        for (s, &end) in strands.iter().zip(&ends) {
            if end < 2 {
                stats.dropped += 1;
                stats.points_removed += s.len() as u64;
                continue;
            }
            stats.points_removed += (s.len() - end) as u64;
            if end < s.len() {
                stats.cut += 1;
            }
            points.extend_from_slice(&s[..end]);
            counts.push(end as u32);
        }
        let set = StrandSet::new(points, counts).unwrap_or_else(|_| StrandSet::empty());
        (set, stats)
    }
}

impl VisualHull {
    /// [`VisualHull::trim`], or `Err` with its statistics when it would remove more than `max_cut` of
    /// the points (the strands are then best kept whole, and the user told).
    pub fn trim_checked(&self, strands: &StrandSet) -> Result<(StrandSet, TrimStats), TrimStats> {
        let (set, stats) = self.trim(strands);
        if stats.points_removed as f64 > self.params.max_cut as f64 * stats.points as f64 {
            return Err(stats);
        }
        Ok((set, stats))
    }
}

/// The pixel `(x, y)` holding `px`, if inside the image.
fn pixel(camera: &Camera, px: Vec2) -> Option<(usize, usize)> {
    // The tests on `px` itself answer as they would on its floor (the bounds are whole numbers),
    // and `as usize` floors what passes them: no call to `floorf`, which the trim made millions of.
    let (x, y) = (px.x, px.y);
    if x < 0.0 || y < 0.0 || x >= camera.width() as f32 || y >= camera.height() as f32 {
        return None;
    }
    Some((x as usize, y as usize))
}

/// A mask as one bit a pixel in tiles of 8 × 8 pixels, one `u64` a tile. A strand's points fall on
/// nearby pixels of each view, and the trim asks every view about every point: as bytes, the
/// paper preset's 58 masks (10 MB) missed the cache on most questions (the trim was 40 % of the
/// init stage); as tiles they take 1.3 MB, and a strand running down the image stays in a tile for
/// several points.
#[derive(Debug, Clone)]
struct TiledBits {
    tiles_x: usize,
    bits: Vec<u64>,
}

impl TiledBits {
    fn new(mask: &[bool], w: usize, h: usize) -> Self {
        let tiles_x = w.div_ceil(8);
        let mut bits = vec![0u64; tiles_x * h.div_ceil(8)];
        for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
            let (x, y) = (i % w, i / w);
            bits[(y / 8) * tiles_x + x / 8] |= 1 << ((y % 8) * 8 + x % 8);
        }
        Self { tiles_x, bits }
    }

    #[inline]
    fn get(&self, x: usize, y: usize) -> bool {
        self.bits[(y / 8) * self.tiles_x + x / 8] >> ((y % 8) * 8 + x % 8) & 1 == 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40×40 camera at z = 1 m looking at the origin, focal length 40 px: a pixel is 2.5 cm at
    /// z = 0, world +x is image +x.
    fn camera() -> Camera {
        Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 2.0 * 0.5f32.atan(), 40, 40).unwrap()
    }

    /// Hair in the pixels whose x is below `x_max`.
    fn mask_left_of(x_max: u32) -> Vec<bool> {
        (0..40 * 40).map(|i| (i % 40) < x_max as usize).collect()
    }

    #[test]
    fn a_strand_is_cut_at_its_first_point_outside_the_mask_and_its_head_is_kept() {
        let cam = camera();
        let hull = VisualHull::new(vec![(cam, mask_left_of(20), None)], HullParams::default()).unwrap();
        // Points along +x at z = 0, 0.8 px apart from pixel x 17.9; the margin of one pixel lets hair
        // reach pixel 20, so the first point outside is the one at 21.1.
        let s: Vec<Vec3> = (0..8).map(|i| Vec3::new(-0.04 + 0.02 * i as f32, 0.001, 0.0)).collect();
        let px: Vec<f32> = s.iter().map(|p| cam.project(*p).unwrap().pixel.x).collect();
        let first_out = px.iter().position(|&x| x >= 21.0).unwrap();
        assert_eq!(first_out, 4, "pixels {px:?}");
        let set = StrandSet::new(s.clone(), vec![s.len() as u32]).unwrap();
        let (t, stats) = hull.trim(&set);
        assert_eq!(t.counts(), &[first_out as u32]);
        assert_eq!(t.strand(0), &s[..first_out]);
        assert_eq!(stats, TrimStats { cut: 1, dropped: 0, points_removed: (s.len() - first_out) as u64, points: 8 });
    }

    #[test]
    fn points_on_the_scalp_by_the_root_are_never_outside() {
        let cam = camera();
        // No hair anywhere; the scalp a 10 cm square at z = 0 (the camera sees it from z = 1 m).
        let scalp = Bvh::new(
            hairrecon_core::TriMesh::new(
                vec![
                    Vec3::new(-0.05, -0.05, 0.0),
                    Vec3::new(0.05, -0.05, 0.0),
                    Vec3::new(0.05, 0.05, 0.0),
                    Vec3::new(-0.05, 0.05, 0.0),
                ],
                vec![[0, 1, 2], [0, 2, 3]],
                None,
                None,
            )
            .unwrap(),
        );
        // A strand lying on the scalp (1 mm above it, 6 mm steps), then rising off it.
        let mut s: Vec<Vec3> = (0..7).map(|i| Vec3::new(-0.03 + 0.006 * i as f32, 0.0, 0.001)).collect();
        s.push(Vec3::new(0.01, 0.0, 0.01));
        let set = StrandSet::new(s.clone(), vec![s.len() as u32]).unwrap();
        let bare = VisualHull::new(vec![(cam, vec![false; 1600], None)], HullParams::default()).unwrap();
        assert_eq!(bare.trim(&set).1.dropped, 1, "without the scalp every point is outside");
        let hull = bare.with_scalp(Some(scalp));
        // Kept over the first 2 cm of arc (points 1–3, at 6, 12 and 18 mm), cut at the first point
        // past it (24 mm) although it still lies on the scalp.
        let (t, stats) = hull.trim(&set);
        assert_eq!(t.counts(), &[4]);
        assert_eq!(stats.cut, 1);
        // With no grace, the scalp saves nothing.
        let none = HullParams { root_grace: 0.0, ..Default::default() };
        let strict =
            VisualHull::new(vec![(cam, vec![false; 1600], None)], none).unwrap().with_scalp(hull.scalp.clone());
        assert_eq!(strict.trim(&set).1.dropped, 1);
    }

    #[test]
    fn points_behind_the_head_are_not_outside_but_points_in_front_of_it_are() {
        let cam = camera();
        // No hair anywhere; the head at depth 1 m (the plane z = 0) everywhere.
        let hull =
            VisualHull::new(vec![(cam, vec![false; 1600], Some(vec![1.0; 1600]))], HullParams::default()).unwrap();
        assert_eq!(hull.views_outside(Vec3::new(0.0, 0.0, -0.01)), 0, "1 cm behind the head");
        assert_eq!(hull.views_outside(Vec3::new(0.0, 0.0, 0.01)), 1, "1 cm in front of it");
        // Outside the image: no view says anything.
        assert_eq!(hull.views_outside(Vec3::new(5.0, 0.0, 0.0)), 0);
    }

    #[test]
    fn tiled_bits_hold_every_pixel_of_a_mask() {
        let (w, h) = (19, 11);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 5 < 2).collect();
        let bits = TiledBits::new(&mask, w, h);
        for y in 0..h {
            for x in 0..w {
                assert_eq!(bits.get(x, y), mask[y * w + x], "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn min_views_counts_the_views_that_agree() {
        let cam = camera();
        let views = vec![(cam, mask_left_of(20), None), (cam, mask_left_of(40), None)];
        let p = Vec3::new(0.2, 0.0, 0.0);
        let one = VisualHull::new(views.clone(), HullParams::default()).unwrap();
        assert_eq!(one.views_outside(p), 1);
        let two = VisualHull::new(views, HullParams { min_views: 2, ..Default::default() }).unwrap();
        let set = StrandSet::new(vec![Vec3::ZERO, p], vec![2]).unwrap();
        assert_eq!(one.trim(&set).0.num_strands(), 0, "dropped: only its root is inside");
        assert_eq!(two.trim(&set).0.num_points(), 2, "one view of two is not enough");
    }

    #[test]
    fn a_see_through_mask_is_not_solid_but_a_filled_one_is() {
        // Sparse hair: most hair pixels partly covered.
        let sparse: Vec<f32> = (0..100).map(|i| if i % 4 == 0 { 0.9 } else { 0.2 }).collect();
        let filled: Vec<f32> = (0..100).map(|i| if i % 4 == 0 { 0.2 } else { 1.0 }).collect();
        assert!(!crate::views::solid(&sparse, 0.5));
        assert!(crate::views::solid(&filled, 0.5));
        assert!(!crate::views::solid(&[0.0; 10], 0.5), "no hair at all says nothing");
    }

    #[test]
    fn a_cut_of_more_than_max_cut_is_refused() {
        let hull = VisualHull::new(vec![(camera(), mask_left_of(20), None)], HullParams::default()).unwrap();
        // Half of each strand's points outside: 2 of 4 removed is allowed at 0.5, 3 of 4 is not.
        let half: Vec<Vec3> = [-0.1, -0.05, 0.2, 0.3].iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect();
        let most: Vec<Vec3> = [-0.1, 0.2, 0.25, 0.3].iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect();
        let ok = hull.trim_checked(&StrandSet::new(half, vec![4]).unwrap()).unwrap();
        assert_eq!(ok.0.num_points(), 2);
        let err = hull.trim_checked(&StrandSet::new(most, vec![4]).unwrap()).unwrap_err();
        assert_eq!((err.points_removed, err.dropped), (4, 1), "the strand would be dropped whole");
    }

    #[test]
    fn a_mask_of_the_wrong_size_is_an_error_naming_the_view() {
        let e = VisualHull::new(vec![(camera(), vec![true; 10], None)], HullParams::default()).unwrap_err();
        assert!(e.to_string().contains("view 0 has 10 mask pixels"), "{e}");
    }
}
