//! Evaluation against ground truth, apart from the reconstruction: the runner hands each stage's
//! output to an [`Evaluator`] when the capture has ground truth, and the scores go into the run's
//! report ([`crate::report::Scores`]). No stage reads ground truth.
//!
//! Definitions (points matched at a distance and an angle, undirected = |cos|):
//! - 2D orientation maps: the mean undirected angle to `gt/orientation` over the pixels that are
//!   hair in both ([`crate::orient2d::summarize_errors`]).
//! - oriented points: *precision* = share of points with a ground-truth point within 2 mm whose
//!   tangent is within 20°; *coverage* = share of the ground-truth points of the visible hair
//!   surface (within 3 mm inside the raw mesh) that have such a point.
//! - directed points: *agreement* = among points matched (undirected, 2 mm/20°), the share whose
//!   direction also points the same way as the ground-truth tangent (dot > 0).
//! - ringlet axes (curly hair, [`crate::curl`]): each point is matched to the nearest ground-truth
//!   strand sample within 2 mm, whose axis is the tangent of that strand's centreline over one turn
//!   of arc; *within_20* = share of matched points whose axis is within 20° of it (undirected),
//!   *directed_within_20* the same with the sign.
//! - strands: the strand metric (precision/recall/F1 at 1/2/3 mm and 10/20/30°, directed and
//!   undirected) of [`hairrecon_core::metric`].

use std::cell::OnceCell;

use glam::Vec3;
use hairrecon_core::capture::Capture;
use hairrecon_core::metric::{evaluate, MetricOptions, MetricReport};
use hairrecon_core::spatial::PointIndex;
use hairrecon_core::{Bvh, StrandSet};
use rayon::prelude::*;

use crate::curl::Curl;
use crate::error::ReconError;
use crate::orient2d::{orientation_errors, summarize_errors, OrientationError, OrientationMap};
use crate::oriented_points::OrientedPoints;

/// Match distance and angle of the point scores.
const MATCH_DIST: f32 = 0.002;
const MATCH_ANGLE_DEG: f32 = 20.0;
/// Ground-truth points up to this far inside the raw mesh count as the visible hair surface.
const SURFACE_BAND: f32 = 0.003;

/// The capture's ground-truth strands, indexed.
#[derive(Debug)]
pub struct GroundTruth {
    pub strands: StrandSet,
    /// Points every millimetre with their tangents.
    pub index: PointIndex,
    /// Ground-truth points within the surface band of the raw mesh.
    pub surface: Vec<usize>,
}

impl GroundTruth {
    /// Loads and indexes the capture's ground-truth strands (`None` when it has none).
    pub fn load(capture: &Capture, raw: &Bvh) -> Result<Option<Self>, ReconError> {
        let Some(p) = &capture.gt_strands else { return Ok(None) };
        let strands = capture.read_strands(p)?;
        let index = PointIndex::from_strands(&strands, 0.001)?;
        let surface = (0..index.len())
            .into_par_iter()
            .filter(|&i| raw.signed_distance(index.points[i], 0.02).is_some_and(|d| d > -SURFACE_BAND))
            .collect();
        Ok(Some(Self { strands, index, surface }))
    }
}

/// The raw mesh with its BVH, built only when ground truth is scored (a capture without ground
/// truth, or a run resumed at DR, need not build it).
pub type RawMesh<'a> = dyn Fn() -> Result<&'a Bvh, ReconError> + 'a;

/// Scores stage outputs against a capture's ground truth (loaded once, when first needed).
pub struct Evaluator<'a> {
    capture: &'a Capture,
    raw: &'a RawMesh<'a>,
    gt: OnceCell<Option<GroundTruth>>,
}

impl std::fmt::Debug for Evaluator<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Evaluator").field("capture", &self.capture.dir).field("gt", &self.gt).finish_non_exhaustive()
    }
}

impl<'a> Evaluator<'a> {
    /// `raw` gives the capture's raw mesh; it is called once, the first time ground truth is loaded.
    pub fn new(capture: &'a Capture, raw: &'a RawMesh<'a>) -> Self {
        Self { capture, raw, gt: OnceCell::new() }
    }

    /// Whether the capture has ground-truth strands.
    pub fn has_strands(&self) -> bool {
        self.capture.gt_strands.is_some()
    }

    fn gt(&self) -> Result<Option<&GroundTruth>, ReconError> {
        if self.gt.get().is_none() {
            let loaded = match self.has_strands() {
                true => GroundTruth::load(self.capture, (self.raw)()?)?,
                false => None,
            };
            let _ = self.gt.set(loaded);
        }
        Ok(self.gt.get().and_then(Option::as_ref))
    }

    /// The maps against `gt/orientation` (`None` when no view has one).
    pub fn orient2d(&self, maps: &[OrientationMap]) -> Result<Option<OrientationError>, ReconError> {
        let mut errs = Vec::new();
        let mut have_gt = false;
        for (v, map) in self.capture.views.iter().zip(maps) {
            let Some(g) = &v.gt_orientation else { continue };
            have_gt = true;
            let gt = OrientationMap::load_exr(g)?;
            if (gt.width, gt.height) == (map.width, map.height) {
                errs.extend(orientation_errors(map, &gt));
            }
        }
        Ok(have_gt.then(|| summarize_errors(errs)))
    }

    /// The oriented 3D points.
    pub fn points(&self, p: &OrientedPoints) -> Result<Option<PointsScore>, ReconError> {
        Ok(self.gt()?.map(|g| {
            score_points(&p.positions, &p.directions, &g.index, &g.surface, MATCH_DIST, MATCH_ANGLE_DEG.to_radians())
        }))
    }

    /// The directed points.
    pub fn directions(&self, p: &OrientedPoints) -> Result<Option<DirectionScore>, ReconError> {
        Ok(self
            .gt()?
            .map(|g| score_directions(&p.positions, &p.directions, &g.index, MATCH_DIST, MATCH_ANGLE_DEG.to_radians())))
    }

    /// Ringlet axes (where the cameras saw the hair) of the curl `c`.
    pub fn axes(&self, axes: &OrientedPoints, c: &Curl) -> Result<Option<AxisScore>, ReconError> {
        Ok(self.gt()?.map(|g| {
            let gt_ax = gt_axes(&g.strands, c.period / c.pitch_angle().cos(), 0.001);
            score_axes(&axes.positions, &axes.directions, &gt_ax, MATCH_DIST)
        }))
    }

    /// The strand metric (`None` without ground truth or when a set is empty).
    pub fn strands(&self, set: &StrandSet) -> Result<Option<MetricReport>, ReconError> {
        Ok(self.gt()?.and_then(|g| evaluate(set, &g.strands, &MetricOptions::default()).ok()))
    }
}

/// Precision and coverage of oriented points.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PointsScore {
    pub points: u64,
    /// Percent of points matched by the ground truth (undirected).
    pub precision: f64,
    /// Percent of visible ground-truth surface points matched by some point (undirected).
    pub coverage: f64,
    /// Number of ground-truth points counted as the visible surface.
    pub surface_points: u64,
}

/// Scores oriented points against ground truth at `dist`/`angle` (radians). `surface` is the
/// subset of ground-truth point indices that counts as the visible hair surface.
pub fn score_points(
    positions: &[Vec3],
    directions: &[Vec3],
    gt: &PointIndex,
    surface: &[usize],
    dist: f32,
    angle: f32,
) -> PointsScore {
    if positions.is_empty() {
        return PointsScore { surface_points: surface.len() as u64, ..Default::default() };
    }
    let matched = positions
        .par_iter()
        .zip(directions)
        .filter(|(p, d)| gt.match_undirected(**p, **d, dist, angle).is_some())
        .count();
    let pred = PointIndex::new(positions.to_vec(), directions.to_vec());
    let covered = surface
        .par_iter()
        .filter(|&&i| pred.match_undirected(gt.points[i], gt.tangents[i], dist, angle).is_some())
        .count();
    PointsScore {
        points: positions.len() as u64,
        precision: 100.0 * matched as f64 / positions.len() as f64,
        coverage: if surface.is_empty() { 0.0 } else { 100.0 * covered as f64 / surface.len() as f64 },
        surface_points: surface.len() as u64,
    }
}

/// Direction agreement of directed points.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionScore {
    /// Points matched undirected (2 mm/20°) and so judged.
    pub judged: u64,
    /// Percent of judged points whose direction agrees with the ground truth.
    pub agreement: f64,
}

/// How well points' directions follow the ground truth's ringlet axes.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxisScore {
    /// Points within the match distance of a ground-truth strand, and so judged.
    pub judged: u64,
    /// Percent of judged points within 20° of the axis, undirected.
    pub within_20: f64,
    /// The same, directed.
    pub directed_within_20: f64,
    /// Median undirected angle to the axis, degrees.
    pub median_deg: f64,
}

/// The ground truth's ringlet axes: every strand's samples (every `step`) with the tangent of its
/// centreline over `turn_arc` of arc ([`crate::curl::centreline`]), as an index.
pub fn gt_axes(gt: &StrandSet, turn_arc: f32, step: f32) -> PointIndex {
    let per: Vec<(Vec<Vec3>, Vec<Vec3>)> = gt
        .iter()
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|s| {
            let one = StrandSet::new(s.to_vec(), vec![s.len() as u32]).ok()?.resample_by_arclength(step).ok()?;
            let r = one.points();
            let c = crate::curl::centreline(s, turn_arc, step)?;
            // The centreline is resampled along its own (shorter) arc: pair by arc fraction.
            let n = r.len().min(c.len());
            let tangent = |k: usize| (c[(k + 1).min(c.len() - 1)] - c[k.saturating_sub(1)]).normalize_or_zero();
            let pts = r[..n].to_vec();
            let tans = (0..n).map(|k| tangent(k * (c.len() - 1) / (r.len() - 1).max(1))).collect();
            Some((pts, tans))
        })
        .collect();
    let (mut points, mut tangents) = (Vec::new(), Vec::new());
    for (p, t) in per {
        points.extend(p);
        tangents.extend(t);
    }
    PointIndex::new(points, tangents)
}

/// Scores `directions` at `positions` against the ground-truth axes of [`gt_axes`].
pub fn score_axes(positions: &[Vec3], directions: &[Vec3], axes: &PointIndex, dist: f32) -> AxisScore {
    let mut cosines: Vec<f32> = positions
        .par_iter()
        .zip(directions)
        .filter_map(|(p, d)| {
            let (i, r) = *axes.nearest(*p, 1).first()?;
            (r <= dist).then(|| axes.tangents[i].dot(*d))
        })
        .collect();
    let n = cosines.len();
    if n == 0 {
        return AxisScore::default();
    }
    let c20 = 20f32.to_radians().cos();
    let within = cosines.iter().filter(|c| c.abs() >= c20).count();
    let directed = cosines.iter().filter(|c| **c >= c20).count();
    cosines.iter_mut().for_each(|c| *c = c.abs());
    cosines.sort_by(|a, b| b.total_cmp(a));
    AxisScore {
        judged: n as u64,
        within_20: 100.0 * within as f64 / n as f64,
        directed_within_20: 100.0 * directed as f64 / n as f64,
        median_deg: cosines[n / 2].clamp(-1.0, 1.0).acos().to_degrees() as f64,
    }
}

/// Share of points (among those matched undirected) whose direction agrees with the ground truth.
pub fn score_directions(
    positions: &[Vec3],
    directions: &[Vec3],
    gt: &PointIndex,
    dist: f32,
    angle: f32,
) -> DirectionScore {
    let (judged, agree) = positions
        .par_iter()
        .zip(directions)
        .filter_map(|(p, d)| {
            gt.match_undirected(*p, *d, dist, angle).map(|i| (1u64, (gt.tangents[i].dot(*d) > 0.0) as u64))
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    DirectionScore { judged, agreement: if judged == 0 { 0.0 } else { 100.0 * agree as f64 / judged as f64 } }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_strand_match_it() {
        let s = StrandSet::new(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.1)], vec![2]).unwrap();
        let gt = PointIndex::from_strands(&s, 0.001).unwrap();
        assert_eq!(gt.len(), 101, "every millimetre, root and tip");
        let pos = vec![Vec3::new(0.001, 0.0, -0.05), Vec3::new(0.01, 0.0, -0.05), Vec3::new(0.0, 0.0, -0.02)];
        let dir = vec![Vec3::Z, Vec3::Z, Vec3::X];
        let all: Vec<usize> = (0..gt.len()).collect();
        let sc = score_points(&pos, &dir, &gt, &all, 0.002, 20f32.to_radians());
        assert!((sc.precision - 100.0 / 3.0).abs() < 1e-6, "{sc:?}");
        assert!(sc.coverage > 2.0 && sc.coverage < 6.0, "{sc:?}");
        let d = score_directions(&pos, &dir, &gt, 0.002, 20f32.to_radians());
        assert_eq!(d.judged, 1);
        assert_eq!(d.agreement, 0.0);
    }

    #[test]
    fn the_raw_mesh_is_asked_for_only_with_ground_truth() {
        let cap = Capture {
            dir: "capture".into(),
            units: hairrecon_core::capture::Units::Metres,
            frame: hairrecon_core::capture::Frame::Canonical,
            views: Vec::new(),
            raw_mesh: "raw_mesh.ply".into(),
            head_mesh: None,
            scalp_mesh: None,
            gt_strands: None,
            to_canonical: None,
            file_frame: None,
        };
        let asked = std::cell::Cell::new(0);
        let raw = || -> Result<&Bvh, ReconError> {
            asked.set(asked.get() + 1);
            Err(ReconError::Cancelled(crate::progress::Cancelled))
        };
        let s = StrandSet::new(vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.1)], vec![2]).unwrap();
        let ev = Evaluator::new(&cap, &raw);
        assert!(ev.strands(&s).unwrap().is_none());
        assert!(ev.strands(&s).unwrap().is_none());
        assert_eq!(asked.get(), 0, "no ground truth: nothing to build the raw mesh for");
        let with_gt = Capture { gt_strands: Some("gt.hair".into()), ..cap.clone() };
        let ev = Evaluator::new(&with_gt, &raw);
        assert!(matches!(ev.strands(&s), Err(ReconError::Cancelled(_))), "the raw mesh's error is the scoring's");
        assert_eq!(asked.get(), 1);
    }
}
