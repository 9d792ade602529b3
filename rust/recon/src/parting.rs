//! Stage 4a: partings, where the cameras see the scalp's skin.
//!
//! In: the capture's views (camera, hair mask), the head mesh as occluder, the [`Scalp`]. Out:
//! [`Partings`] (skin points on the scalp, saved as `partings.ply`), which turn S(p_s) beside them
//! (see [`Partings`]: hair beside a parting leaves it sideways), and the directed points cleared
//! from the hair just above them ([`clear_points`]).
//!
//! A scalp sample (blue noise, [`PartingParams::samples`]) is *seen as skin* in a view when the
//! view sees it (in the image, facing the camera by at least [`PartingParams::min_facing`], no head
//! between it and the camera) and the mask holds no hair within `margin_px` pixels of it. A sample
//! is skin when at least `min_views` views see it as skin, it has skin samples around it (a lone
//! one is noise) and it lies farther than `rim_dist` from the scalp mesh's rim: bare skin at the
//! rim is a hairline, not a parting, and hair there need not leave it.
//!
//! Why: on every synthetic capture the strands rooted beside the middle parting left forward along
//! it, where the ground truth's leave sideways, and the visual hull then cut many of them away,
//! leaving the parting bare and wider than it is (`docs/method.md`, "Partings"; the measurements in
//! research/notes/reconstruction-study.md, "The front of the crown"). The Gabor maps there carry no
//! strand texture and turn the points along the parting, so turning S alone did not move the
//! strands (measured at commit a3e5429): the points above the skin have to go too.
//! Masks that are see-through (sparse hair, [`crate::hull::HullParams::min_solid`]) say nothing.

use glam::Vec3;
use hairrecon_core::capture::Capture;
use hairrecon_core::scalp::{Partings, Root};
use hairrecon_core::{Bvh, Camera};
use rayon::prelude::*;

use crate::orient2d::{GrayImage, Orient2dError};
use crate::points3d::OrientedPoints;
use crate::progress::{Cancelled, Progress};
use crate::roots::Scalp;

/// Options of the parting stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PartingParams {
    /// Find partings and turn S beside them (false: `--no-parting`).
    pub enabled: bool,
    /// Scalp samples tested (blue noise; 20,000 lie about 2 mm apart on the bundled scalp).
    pub samples: usize,
    /// A sample is skin when at least this many views see it as skin.
    pub min_views: u32,
    /// A mask pixel holds hair when its coverage is at least this.
    pub mask_threshold: f32,
    /// Pixels each way around the sample's pixel that must hold no hair.
    pub margin_px: u32,
    /// A view sees a sample when the cosine between its normal and the direction to the camera is
    /// at least this (grazing views see the outline, not the skin).
    pub min_facing: f32,
    /// Skin samples need this many other skin samples within `neighbour_dist`.
    pub min_neighbours: usize,
    pub neighbour_dist: f32,
    /// Skin samples closer than this to the scalp mesh's rim are hairline, not parting, metres.
    pub rim_dist: f32,
    /// How far from the skin S turns, metres ([`Partings`]).
    pub reach: f32,
    /// How strongly S turns away from the skin ([`Partings`]).
    pub strength: f32,
    /// Directed points within `reach` of a skin point and closer than this to the scalp are
    /// dropped before the flow and the growth, metres.
    pub clear_height: f32,
    /// DR's orientation loss says nothing where the views see the head within `reach` of the skin
    /// ([`crate::dr::DrTargets::quiet_partings`]).
    pub quiet_orientation: bool,
}

impl Default for PartingParams {
    fn default() -> Self {
        Self {
            enabled: true,
            samples: 20000,
            min_views: 2,
            mask_threshold: 0.5,
            margin_px: 1,
            min_facing: 0.3,
            min_neighbours: 3,
            neighbour_dist: 0.005,
            rim_dist: 0.015,
            reach: 0.03,
            strength: 2.0,
            clear_height: 0.015,
            quiet_orientation: true,
        }
    }
}

/// What the parting stage found.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PartingStats {
    /// Views whose masks took part (solid ones).
    pub views: usize,
    pub samples: usize,
    /// Samples seen as skin in `min_views` views or more.
    pub seen_as_skin: usize,
    /// Of those, dropped as lone or at the rim.
    pub lone: usize,
    pub at_rim: usize,
    /// Skin points kept: the partings.
    pub skin: usize,
}

/// Why the partings could not be found.
#[derive(Debug, thiserror::Error)]
pub enum PartingError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    #[error(transparent)]
    Mask(#[from] Orient2dError),
    #[error("the mask of view {view} is {got_w}×{got_h} pixels, its camera {width}×{height}; give masks of the images' size")]
    Size { view: String, got_w: u32, got_h: u32, width: u32, height: u32 },
    #[error("scalp: {0}")]
    Scalp(#[from] hairrecon_core::scalp::ScalpError),
}

/// The partings on `scalp` seen by the capture's views (`None` when no skin is found or no view's
/// mask is solid), with what was found. Reports as stage `stage`.
pub fn find_partings(
    capture: &Capture,
    scalp: &Scalp,
    head: &Bvh,
    params: &PartingParams,
    stage: &str,
    progress: &dyn Progress,
) -> Result<(Option<Partings>, PartingStats), PartingError> {
    let samples = scalp.sample_roots(params.samples.max(1), 0x9A27_1465)?;
    let mut stats = PartingStats { samples: samples.len(), ..Default::default() };
    let mut skin_votes = vec![0u32; samples.len()];
    let n = capture.views.len();
    for (vi, v) in capture.views.iter().enumerate() {
        progress.check()?;
        progress.update(stage, vi as f32 / n.max(1) as f32, &format!("partings: view {}/{n}", vi + 1));
        let Some(m) = &v.mask else { continue };
        let img = GrayImage::load(m)?;
        let cam = &v.camera;
        let (w, h) = (cam.width(), cam.height());
        if (img.width, img.height) != (w, h) {
            return Err(PartingError::Size {
                view: v.name.clone(),
                got_w: img.width,
                got_h: img.height,
                width: w,
                height: h,
            });
        }
        if !crate::views::solid(&img.data, crate::hull::HullParams::default().min_solid) {
            continue;
        }
        stats.views += 1;
        let votes = seen_as_skin(&samples, cam, &img.data, head, params);
        for (c, seen) in skin_votes.iter_mut().zip(votes) {
            *c += seen as u32;
        }
    }
    let positions: Vec<Vec3> = samples.iter().map(|s| s.position).collect();
    let kept = select_skin(&positions, &skin_votes, &scalp.bvh().rim_edges(), params, &mut stats);
    stats.skin = kept.len();
    progress.update(stage, 1.0, &format!("partings: {} skin points", kept.len()));
    if kept.is_empty() {
        return Ok((None, stats));
    }
    Ok((Some(Partings::new(kept, params.reach, params.strength)), stats))
}

/// Which of the scalp `samples` the view (camera, mask coverage row-major) sees as skin.
fn seen_as_skin(samples: &[Root], cam: &Camera, mask: &[f32], head: &Bvh, params: &PartingParams) -> Vec<bool> {
    let (w, h) = (cam.width() as i64, cam.height() as i64);
    let centre = cam.center();
    let r = params.margin_px as i64;
    samples
        .par_iter()
        .map(|s| {
            let to_cam = centre - s.position;
            let dist = to_cam.length();
            let dir = to_cam / dist.max(1e-9);
            if dir.dot(s.normal) < params.min_facing {
                return false;
            }
            let Some(pr) = cam.project(s.position) else { return false };
            let (x, y) = (pr.pixel.x.floor() as i64, pr.pixel.y.floor() as i64);
            if x < r || y < r || x + r >= w || y + r >= h {
                return false;
            }
            if head.occluded(s.position + s.normal * 0.001, dir, 0.0, dist) {
                return false;
            }
            (y - r..=y + r).all(|yy| (x - r..=x + r).all(|xx| mask[(yy * w + xx) as usize] < params.mask_threshold))
        })
        .collect()
}

/// The samples that are skin: seen as skin in `min_views` views or more, not alone, not at the rim.
fn select_skin(
    positions: &[Vec3],
    votes: &[u32],
    rim: &[(Vec3, Vec3)],
    params: &PartingParams,
    stats: &mut PartingStats,
) -> Vec<Vec3> {
    let skin: Vec<Vec3> =
        positions.iter().zip(votes).filter(|(_, &v)| v >= params.min_views.max(1)).map(|(&p, _)| p).collect();
    stats.seen_as_skin = skin.len();
    let nd2 = params.neighbour_dist * params.neighbour_dist;
    let rim2 = params.rim_dist * params.rim_dist;
    let mut kept = Vec::new();
    for (i, &p) in skin.iter().enumerate() {
        let neighbours = skin.iter().enumerate().filter(|&(j, q)| j != i && q.distance_squared(p) < nd2).count();
        if neighbours < params.min_neighbours {
            stats.lone += 1;
        } else if rim.iter().any(|&(a, b)| segment_distance_squared(p, a, b) < rim2) {
            stats.at_rim += 1;
        } else {
            kept.push(p);
        }
    }
    kept
}

fn segment_distance_squared(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-20)).clamp(0.0, 1.0);
    (a + ab * t).distance_squared(p)
}

/// The directed points without those within `partings`' reach of a skin point and closer than
/// `clear_height` to the scalp: the hair there is what the partings decide, and the Gabor maps see
/// no strands on it. Returns the points kept and how many were dropped.
pub fn clear_points(
    points: &OrientedPoints,
    scalp: &Scalp,
    partings: &Partings,
    clear_height: f32,
) -> (OrientedPoints, usize) {
    let keep: Vec<bool> = points
        .positions
        .par_iter()
        .map(|&p| {
            let near_scalp = scalp.bvh().closest_point(p, clear_height).is_some();
            !(near_scalp && partings.distance(p).is_some())
        })
        .collect();
    let mut out = OrientedPoints::default();
    for (i, &k) in keep.iter().enumerate() {
        if k {
            out.positions.push(points.positions[i]);
            out.directions.push(points.directions[i]);
            out.confidence.push(points.confidence[i]);
        }
    }
    let dropped = points.len() - out.len();
    (out, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hairrecon_core::mesh::TriMesh;

    /// A 10 cm square of scalp at z = 0 (normal +z), two triangles.
    fn square() -> Scalp {
        let v = vec![
            Vec3::new(-0.05, -0.05, 0.0),
            Vec3::new(0.05, -0.05, 0.0),
            Vec3::new(0.05, 0.05, 0.0),
            Vec3::new(-0.05, 0.05, 0.0),
        ];
        let n = Some(vec![Vec3::Z; 4]);
        Scalp::new(TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]], n, None).unwrap()).unwrap()
    }

    /// A view from above the square (at `eye`) whose mask holds hair everywhere but over |x| < 3 mm.
    fn view(eye: Vec3) -> (Camera, Vec<f32>) {
        let cam = Camera::look_at(eye, Vec3::ZERO, Vec3::Y, 0.5, 200, 200).unwrap();
        let mut mask = vec![1.0f32; 200 * 200];
        for (i, m) in mask.iter_mut().enumerate() {
            let px = glam::Vec2::new((i % 200) as f32 + 0.5, (i / 200) as f32 + 0.5);
            // Where the pixel's ray meets z = 0.
            let d = cam.ray_direction(px);
            let p = eye + d * (-eye.z / d.z);
            if p.x.abs() < 0.003 {
                *m = 0.0;
            }
        }
        (cam, mask)
    }

    #[test]
    fn the_skin_strip_that_two_views_see_is_found_away_from_the_rim() {
        let scalp = square();
        let head = scalp.bvh().clone();
        let params = PartingParams::default();
        let samples = scalp.sample_roots(20000, 3).unwrap();
        let mut votes = vec![0u32; samples.len()];
        for eye in [Vec3::new(0.0, -0.05, 0.4), Vec3::new(0.05, 0.0, 0.4)] {
            let (cam, mask) = view(eye);
            for (v, s) in votes.iter_mut().zip(seen_as_skin(&samples, &cam, &mask, &head, &params)) {
                *v += s as u32;
            }
        }
        let positions: Vec<Vec3> = samples.iter().map(|s| s.position).collect();
        let mut stats = PartingStats::default();
        let skin = select_skin(&positions, &votes, &scalp.bvh().rim_edges(), &params, &mut stats);
        // 20,000 samples on 1 dm²: 0.7 mm apart; the strip is 6 mm wide, 70 mm long inside the rim's
        // 15 mm, less the margin pixel (0.7 mm here) each side: about 4.6 × 70 mm, some 650 samples.
        assert!(skin.len() > 400 && skin.len() < 900, "{} skin samples, {stats:?}", skin.len());
        assert!(skin.iter().all(|p| p.x.abs() < 0.003 && p.y.abs() < 0.035), "{stats:?}");
        assert!(stats.at_rim > 100, "the strip's ends at the rim are hairline: {stats:?}");
        // One view is not enough.
        let one: Vec<u32> = votes.iter().map(|&v| v.min(1)).collect();
        assert!(select_skin(&positions, &one, &[], &params, &mut stats).is_empty());
        // A view from below sees nothing of the scalp's outer side.
        let (cam, mask) = view(Vec3::new(0.0, 0.0, -0.4));
        assert!(!seen_as_skin(&samples, &cam, &mask, &head, &params).iter().any(|&s| s));
    }

    #[test]
    fn points_above_the_skin_are_cleared_and_the_rest_kept() {
        let scalp = square();
        let skin: Vec<Vec3> = (-20..=20).map(|k| Vec3::new(0.0, k as f32 * 0.001, 0.0)).collect();
        let partings = Partings::new(skin, 0.03, 2.0);
        let pts = OrientedPoints {
            positions: vec![
                Vec3::new(0.01, 0.0, 0.005),  // beside the skin, just above the scalp: cleared
                Vec3::new(0.01, 0.0, 0.03),   // beside it, but high above: kept
                Vec3::new(0.045, 0.0, 0.005), // beyond the reach: kept
            ],
            directions: vec![Vec3::Y; 3],
            confidence: vec![1.0; 3],
        };
        let (kept, dropped) = clear_points(&pts, &scalp, &partings, 0.015);
        assert_eq!(dropped, 1);
        assert_eq!(kept.positions, vec![Vec3::new(0.01, 0.0, 0.03), Vec3::new(0.045, 0.0, 0.005)]);
    }
}
