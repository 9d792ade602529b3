//! The whole reconstruction pipeline: capture → 2D orientation maps → oriented 3D points →
//! directed points → roots, flow and grown strands (init) → strands optimized by differentiable
//! rendering (DR).
//!
//! In: a validated [`Capture`] (images, optional masks, raw mesh, scalp mesh, optional head mesh
//! and ground truth) and [`ReconstructOptions`]. Out: every stage's result in the output folder,
//! [`ReconstructOutput`] with the paths of the strands, the time of each stage and, when the
//! capture has ground truth, the metrics of each stage (also written to `metrics.json`).
//!
//! Output folder: `orient2d/<view>.exr` (+ `.png` pictures), `points3d.ply`, `partings.ply`
//! (the skin the views see on the scalp, [`crate::parting`], when any), `points_directed.ply`, `roots.ply`, `flow.bin`, `guides.hair`, `strands.hair`, `metrics.json`
//! (with curls, [`crate::curl`], also `points_axes.ply`: the points moved onto their ringlets' axes, with
//! the axes' directions, that the flow grew from);
//! when DR runs also `init_guides.hair`, `init_strands.hair` (the strands before DR), `loss.csv`
//! and `loss.png`. `strands.hair` (children) and `guides.hair` are always the run's final answer:
//! after DR when it ran, else the initial strands. Each stage follows the paper named in its
//! module ([`crate::orient2d`], [`crate::points3d`], [`crate::parting`], [`crate::direction`], [`crate::roots`],
//! [`crate::laplace`], [`crate::grow`], [`crate::dr`]). The DR stage renders against the capture's
//! masks and the orientation maps of stage 1, with the head mesh (else the scalp) as occluder and
//! as the body the strands must stay out of.
//!
//! Cancellation: `progress.check()` runs between views, chunks, solver iterations and DR steps; a
//! cancelled run returns [`ReconError::Cancelled`] and writes no strands file. Strand files are
//! written only once the last strand stage has finished, each atomically; a run that will write
//! strands first removes the strand files and loss curves a previous run left in the folder, so
//! that none of them can pass for this run's result.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{atomic_write, read_mesh, read_strands, write_strands, FormatError};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::{Bvh, StrandSet};
use serde_json::json;
use thiserror::Error;

use crate::curl::{bump_period, hang, mean_down, onto_axes, ringlet_axes, sweep_helices, Curl, CurlMode, CurlOptions};
use crate::direction::{global_directions, gravity_directions, DirectionParams};
use crate::dr::optimize::orientation_misfit;
use crate::dr::{optimize as dr_optimize, DrError, DrOptions, DrTargets};
use crate::grow::{grow_guides, interpolate_children, smooth_guides, straight_strands, GrowParams};
use crate::hull::{HullError, HullParams, VisualHull};
use crate::laplace::{solve_flow, LaplaceParams};
use crate::metrics::{gt_axes, score_axes, score_directions, score_points, PointIndex};
use crate::orient2d::{
    load_mask, orientation_errors, summarize_errors, GaborBank, GaborParams, GrayImage, Orient2dError, OrientationMap,
};
use crate::parting::{clear_points, find_partings, PartingError, PartingParams};
use crate::points3d::{estimate, LineMvsParams, MvsView, OrientedPoints, PointsError};
use crate::progress::{Cancelled, Progress};
use crate::roots::{sample_roots, Scalp, ScalpError};

/// Why a reconstruction stopped.
#[derive(Debug, Error)]
pub enum ReconError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error(transparent)]
    Orient2d(#[from] Orient2dError),
    #[error(transparent)]
    Points(#[from] PointsError),
    #[error("cannot create the output folder {path}: {source}")]
    OutDir { path: PathBuf, source: std::io::Error },
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: std::io::Error },
    #[error("the capture {dir} has no scalp mesh; add \"scalp_mesh\" to its capture.json")]
    NoScalp { dir: PathBuf },
    #[error("the scalp mesh {path} cannot be used: {source}")]
    Scalp { path: PathBuf, source: ScalpError },
    #[error("stage {0:?} is unknown; use one of orient2d, orient3d, direction, init, dr")]
    UnknownStage(String),
    #[error("strand optimization (DR): {0}")]
    Dr(DrError),
    #[error("the visual hull: {0}")]
    Hull(HullError),
    #[error("the partings (--no-parting skips them): {0}")]
    Parting(PartingError),
    #[error("view {view} of the capture has no ground-truth orientation map (gt/orientation)")]
    NoGtOrientation { view: String },
    #[error(
        "the curl stage's grids would exceed 64 million cells: the raw mesh or the points span far more than a \
         head (check the raw mesh's units, metres expected), or run with --curl off"
    )]
    CurlGrid,
    #[error("the curled strands: {0}")]
    Curl(#[from] hairrecon_core::strands::StrandError),
}

impl From<HullError> for ReconError {
    fn from(e: HullError) -> Self {
        match e {
            HullError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Hull(e),
        }
    }
}

impl From<PartingError> for ReconError {
    fn from(e: PartingError) -> Self {
        match e {
            PartingError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Parting(e),
        }
    }
}

impl From<DrError> for ReconError {
    fn from(e: DrError) -> Self {
        match e {
            DrError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Dr(e),
        }
    }
}

/// A stage after which the pipeline may stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub enum Stage {
    Orient2d,
    Orient3d,
    Direction,
    Init,
    /// Strand optimization by differentiable rendering (the last stage).
    Dr,
}

impl FromStr for Stage {
    type Err = ReconError;
    fn from_str(s: &str) -> Result<Self, ReconError> {
        match s.to_ascii_lowercase().as_str() {
            "orient2d" => Ok(Stage::Orient2d),
            "orient3d" => Ok(Stage::Orient3d),
            "direction" => Ok(Stage::Direction),
            "init" => Ok(Stage::Init),
            "dr" => Ok(Stage::Dr),
            _ => Err(ReconError::UnknownStage(s.into())),
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stage::Orient2d => "orient2d",
            Stage::Orient3d => "orient3d",
            Stage::Direction => "direction",
            Stage::Init => "init",
            Stage::Dr => "dr",
        })
    }
}

/// Options of [`reconstruct`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructOptions {
    pub guides: usize,
    pub children: usize,
    pub stop_after: Option<Stage>,
    /// Global direction optimization (false: the gravity heuristic).
    pub global_opt: bool,
    /// Strand initialization by the Laplace flow (false: straight strands along the normal).
    pub strand_init: bool,
    pub seed: u64,
    pub gabor: GaborParams,
    /// A mask pixel is hair when its value (coverage in [0, 1]) is at least this.
    pub mask_threshold: f32,
    pub mvs: LineMvsParams,
    pub direction: DirectionParams,
    pub laplace: LaplaceParams,
    pub grow: GrowParams,
    /// Length of the straight strands of the `strand_init = false` ablation, metres.
    pub straight_length: f32,
    /// Write `orient2d/<view>.png` pictures besides the EXR maps.
    pub write_pictures: bool,
    /// Optimize the strands by differentiable rendering after init (false: the result is the
    /// initial strands, as with `stop_after = Some(Stage::Init)`).
    pub dr: bool,
    pub dr_options: DrOptions,
    /// When the init carries curls, DR keeps their shape ([`DrOptions::keeping_curls`]); false
    /// optimizes them with `dr_options` as they are (`--dr-plain-curls`).
    pub dr_keep_curls: bool,
    /// Cut the children before DR where a view sees no hair ([`crate::hull`]); false keeps them whole
    /// (`--no-hull-trim`).
    pub hull_trim: bool,
    pub hull: HullParams,
    /// Partings: where the views see the scalp's skin, S turns away from it ([`crate::parting`];
    /// `enabled = false`: `--no-parting`).
    pub parting: PartingParams,
    /// Curls ([`crate::curl`]): `Auto` lets the images decide.
    pub curl: CurlMode,
    pub curl_options: CurlOptions,
}

impl Default for ReconstructOptions {
    fn default() -> Self {
        Self {
            guides: 2000,
            children: 50000,
            stop_after: None,
            global_opt: true,
            strand_init: true,
            seed: 0,
            gabor: GaborParams::default(),
            mask_threshold: 0.1,
            mvs: LineMvsParams::default(),
            direction: DirectionParams::default(),
            laplace: LaplaceParams::default(),
            grow: GrowParams::default(),
            straight_length: 0.1,
            write_pictures: true,
            dr: true,
            dr_options: DrOptions::default(),
            dr_keep_curls: true,
            hull_trim: true,
            hull: HullParams::default(),
            parting: PartingParams::default(),
            curl: CurlMode::Auto,
            curl_options: CurlOptions::default(),
        }
    }
}

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructOutput {
    /// The final child strands (`strands.hair`), when the run reached the init stage.
    pub strands: Option<PathBuf>,
    /// The final guide strands (`guides.hair`).
    pub guides: Option<PathBuf>,
    /// The children before DR (`init_strands.hair`), when DR ran.
    pub init_strands: Option<PathBuf>,
    /// The guides before DR (`init_guides.hair`), when DR ran.
    pub init_guides: Option<PathBuf>,
    /// The loss curve (`loss.csv`; the plot is `loss.png` beside it), when DR ran.
    pub loss_csv: Option<PathBuf>,
    /// (stage, seconds) in order.
    pub stage_times: Vec<(String, f64)>,
    /// Per-stage metrics (an empty object without ground truth).
    pub metrics: serde_json::Value,
}

fn mkdir(p: &Path) -> Result<(), ReconError> {
    std::fs::create_dir_all(p).map_err(|source| ReconError::OutDir { path: p.into(), source })
}

/// The 2D orientation stage over every view; returns the maps and, with ground truth, the error.
pub fn orient2d_stage(
    capture: &Capture,
    out_dir: &Path,
    opts: &ReconstructOptions,
    progress: &dyn Progress,
) -> Result<(Vec<OrientationMap>, Option<serde_json::Value>), ReconError> {
    let dir = out_dir.join("orient2d");
    mkdir(&dir)?;
    let bank = GaborBank::new(opts.gabor);
    let mut maps = Vec::with_capacity(capture.views.len());
    let mut errs = Vec::new();
    let mut have_gt = false;
    for (i, v) in capture.views.iter().enumerate() {
        progress.check()?;
        progress.update("orient2d", i as f32 / capture.views.len() as f32, &v.name);
        let img = GrayImage::load(&v.image)?;
        let mask = match &v.mask {
            Some(m) => Some(load_mask(m, img.width, img.height, opts.mask_threshold)?),
            None => None,
        };
        let map = bank.compute(&img, mask.as_deref());
        map.save_exr(&dir.join(format!("{}.exr", v.name)))?;
        if opts.write_pictures {
            map.save_png(&dir.join(format!("{}.png", v.name)))?;
        }
        if let Some(g) = &v.gt_orientation {
            have_gt = true;
            let gt = OrientationMap::load_exr(g)?;
            if (gt.width, gt.height) == (map.width, map.height) {
                errs.extend(orientation_errors(&map, &gt));
            }
        }
        maps.push(map);
    }
    progress.update("orient2d", 1.0, "");
    let metric = have_gt.then(|| serde_json::to_value(summarize_errors(errs)).unwrap_or_default());
    Ok((maps, metric))
}

/// Reloads the maps of [`orient2d_stage`] from `out_dir/orient2d`.
pub fn load_orient2d(capture: &Capture, out_dir: &Path) -> Result<Vec<OrientationMap>, ReconError> {
    capture
        .views
        .iter()
        .map(|v| {
            OrientationMap::load_exr(&out_dir.join("orient2d").join(format!("{}.exr", v.name))).map_err(Into::into)
        })
        .collect()
}

/// The capture's ground-truth orientation maps (`gt/orientation`), one per view, in the layout of
/// [`load_orient2d`]: for the tuning examples that ask what perfect 2D orientation would change.
pub fn load_gt_orient2d(capture: &Capture) -> Result<Vec<OrientationMap>, ReconError> {
    capture
        .views
        .iter()
        .map(|v| {
            let path = v.gt_orientation.as_ref().ok_or_else(|| ReconError::NoGtOrientation { view: v.name.clone() })?;
            OrientationMap::load_exr(path).map_err(Into::into)
        })
        .collect()
}

/// Ground truth used by the metrics.
struct Gt {
    strands: StrandSet,
    index: PointIndex,
    /// Ground-truth points within the surface band of the raw mesh.
    surface: Vec<usize>,
}

const MATCH_DIST: f32 = 0.002;
const MATCH_ANGLE_DEG: f32 = 20.0;
/// Ground-truth points up to this far inside the raw mesh count as the visible hair surface.
const SURFACE_BAND: f32 = 0.003;

fn load_gt(capture: &Capture, raw: &Bvh) -> Result<Option<Gt>, ReconError> {
    let Some(p) = &capture.gt_strands else { return Ok(None) };
    let strands = read_strands(p)?;
    let index = PointIndex::from_strands(&strands, 0.001);
    use rayon::prelude::*;
    let surface = (0..index.len())
        .into_par_iter()
        .filter(|&i| raw.signed_distance(index.points[i], 0.02).is_some_and(|d| d > -SURFACE_BAND))
        .collect();
    Ok(Some(Gt { strands, index, surface }))
}

/// The process's peak resident memory so far in bytes (Linux `VmHWM`; `None` elsewhere).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Records the peak resident memory at the end of `stage` (before its scoring) in
/// `metrics["peak_rss_mb"][stage]`: the peak is a running maximum, so the first stage whose value
/// jumps is the one that needed the memory.
fn note_peak_memory(metrics: &mut serde_json::Map<String, serde_json::Value>, stage: &str) {
    let Some(b) = peak_rss_bytes() else { return };
    let entry = metrics.entry("peak_rss_mb").or_insert_with(|| json!({}));
    if let Some(m) = entry.as_object_mut() {
        m.insert(stage.into(), json!((b as f64 / (1 << 20) as f64).round()));
    }
}

fn strand_metric(pred: &StrandSet, gt: &StrandSet) -> serde_json::Value {
    let opts = MetricOptions::default();
    match evaluate(pred, gt, &opts) {
        Ok(r) => serde_json::to_value(r).unwrap_or_default(),
        Err(e) => json!({ "error": e.to_string() }),
    }
}

/// Runs the pipeline (see the module doc).
pub fn reconstruct(
    capture: &Capture,
    out_dir: &Path,
    opts: &ReconstructOptions,
    progress: &dyn Progress,
) -> Result<ReconstructOutput, ReconError> {
    mkdir(out_dir)?;
    let mut times: Vec<(String, f64)> = Vec::new();
    let mut metrics = serde_json::Map::new();
    let stop = opts.stop_after.unwrap_or(Stage::Dr);
    let run_dr = opts.dr && stop >= Stage::Dr;
    if stop >= Stage::Init {
        for name in STRAND_OUTPUTS {
            let p = out_dir.join(name);
            match std::fs::remove_file(&p) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(ReconError::Write { path: p, source: e });
                }
                _ => {}
            }
        }
    }
    let write_metrics = |m: &serde_json::Map<String, serde_json::Value>| -> Result<(), ReconError> {
        if m.is_empty() {
            return Ok(());
        }
        let text = serde_json::to_string_pretty(m).unwrap_or_default();
        Ok(atomic_write(out_dir.join("metrics.json"), |w| Ok(std::io::Write::write_all(w, text.as_bytes())?))?)
    };

    // Stage 1: 2D orientation.
    let t = Instant::now();
    let (maps, m) = orient2d_stage(capture, out_dir, opts, progress)?;
    times.push(("orient2d".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "orient2d");
    if let Some(m) = m {
        metrics.insert("orient2d".into(), m);
    }
    let done = |times: Vec<(String, f64)>, metrics: serde_json::Map<String, serde_json::Value>| ReconstructOutput {
        strands: None,
        guides: None,
        init_strands: None,
        init_guides: None,
        loss_csv: None,
        stage_times: times,
        metrics: serde_json::Value::Object(metrics),
    };
    if stop == Stage::Orient2d {
        write_metrics(&metrics)?;
        return Ok(done(times, metrics));
    }

    // Stage 2: oriented 3D points.
    let t = Instant::now();
    progress.update("orient3d", 0.0, "loading the raw mesh");
    let raw = Bvh::new(read_mesh(&capture.raw_mesh)?);
    progress.check()?;
    let images: Vec<GrayImage> = capture.views.iter().map(|v| GrayImage::load(&v.image)).collect::<Result<_, _>>()?;
    let views = MvsView::for_capture(capture, &maps, &images);
    let points = estimate(&views, &raw, &opts.mvs, progress)?;
    points.save_ply(&out_dir.join("points3d.ply"))?;
    times.push(("orient3d".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "orient3d");
    let gt = load_gt(capture, &raw)?;
    if let Some(g) = &gt {
        let s = score_points(
            &points.positions,
            &points.directions,
            &g.index,
            &g.surface,
            MATCH_DIST,
            MATCH_ANGLE_DEG.to_radians(),
        );
        metrics.insert("orient3d".into(), serde_json::to_value(s).unwrap_or_default());
    }
    if stop == Stage::Orient3d {
        write_metrics(&metrics)?;
        return Ok(done(times, metrics));
    }

    // Stage 3: global direction.
    let t = Instant::now();
    progress.update("partings", 0.0, "");
    let scalp_path = capture.scalp_mesh.as_ref().ok_or_else(|| ReconError::NoScalp { dir: capture.dir.clone() })?;
    let mut scalp =
        Scalp::new(read_mesh(scalp_path)?).map_err(|source| ReconError::Scalp { path: scalp_path.clone(), source })?;
    progress.check()?;
    // The head (else the scalp): what the partings' views and the flow see around, and DR keeps the
    // strands out of.
    let inner = match &capture.head_mesh {
        Some(h) => Bvh::new(read_mesh(h)?),
        None => scalp.bvh().clone(),
    };
    // Partings: S turns away from the skin the views see on the scalp (crate::parting).
    let partings_path = out_dir.join("partings.ply");
    let found = if opts.parting.enabled {
        let (p, stats) = find_partings(capture, &scalp, &inner, &opts.parting, "partings", progress)?;
        metrics.insert("parting_stats".into(), serde_json::to_value(stats).unwrap_or_default());
        p
    } else {
        None
    };
    match &found {
        Some(p) => OrientedPoints {
            positions: p.skin().to_vec(),
            directions: p.skin().iter().map(|&q| scalp.closest_root(q).normal).collect(),
            confidence: vec![1.0; p.skin().len()],
        }
        .save_ply(&partings_path)?,
        None => match std::fs::remove_file(&partings_path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(ReconError::Write { path: partings_path, source: e });
            }
            _ => {}
        },
    }
    scalp.set_partings(found);
    times.push(("partings".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "partings");
    let t = Instant::now();
    progress.update("direction", 0.0, "");
    let directed = if opts.global_opt {
        let (d, stats) = global_directions(&points, &scalp, &opts.direction);
        metrics.insert("direction_stats".into(), serde_json::to_value(stats).unwrap_or_default());
        d
    } else {
        gravity_directions(&points)
    };
    directed.save_ply(&out_dir.join("points_directed.ply"))?;
    times.push(("direction".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "direction");
    if let Some(g) = &gt {
        let s = score_directions(
            &directed.positions,
            &directed.directions,
            &g.index,
            MATCH_DIST,
            MATCH_ANGLE_DEG.to_radians(),
        );
        metrics.insert("direction".into(), serde_json::to_value(s).unwrap_or_default());
    }
    if stop == Stage::Direction {
        write_metrics(&metrics)?;
        return Ok(done(times, metrics));
    }

    // Stage 4 + 5: roots, flow, growing.
    let t = Instant::now();
    progress.check()?;
    progress.update("init", 0.0, "roots");
    let scalp_err = |source| ReconError::Scalp { path: scalp_path.clone(), source };
    let guide_roots = sample_roots(&scalp, opts.guides.max(1), opts.seed).map_err(scalp_err)?;
    let child_roots = sample_roots(&scalp, opts.children.max(1), opts.seed.wrapping_add(1)).map_err(scalp_err)?;
    guide_roots.to_points().save_ply(&out_dir.join("roots.ply"))?;
    // Growth from some directed points: the flow (saved as flow.bin by the caller), the guides
    // and the children.
    let grow_from = |pts: &OrientedPoints, metrics: &mut Metrics| -> Result<Grown, ReconError> {
        // Beside partings the points above the skin go: the partings decide the hair there.
        let cleared = scalp.partings().map(|p| clear_points(pts, &scalp, p, opts.parting.clear_height));
        let pts = match &cleared {
            Some((c, n)) => {
                metrics.insert("parting_points_cleared".into(), json!(n));
                c
            }
            None => pts,
        };
        let (flow, stats) = solve_flow(&raw, &inner, &scalp, pts, &opts.laplace, progress)?;
        metrics.insert("laplace_stats".into(), serde_json::to_value(stats).unwrap_or_default());
        let trace =
            (opts.grow.trace_radius > 0.0).then(|| PointIndex::new(pts.positions.clone(), pts.directions.clone()));
        let (guides, gstats) = grow_guides(&flow, trace.as_ref(), &guide_roots, &opts.grow, progress)?;
        metrics.insert("grow_stats".into(), serde_json::to_value(gstats).unwrap_or_default());
        let (guides, sstats) = smooth_guides(&guides, trace.as_ref(), Some(&flow), &opts.grow);
        metrics.insert("smooth_stats".into(), serde_json::to_value(sstats).unwrap_or_default());
        let children = interpolate_children(&guides, &child_roots, Some(&flow), &opts.grow, progress)?;
        Ok((flow, guides, children))
    };
    let mut dr_targets: Option<DrTargets> = None;
    // Whether the strands carry curls (then DR keeps them, see `dr_keep_curls`).
    let mut curled = false;
    let (guides, children) = if opts.strand_init {
        let curl = match opts.curl {
            CurlMode::Off => None,
            CurlMode::Fixed(c) => Some(c),
            CurlMode::Auto => {
                // The misfit's targets, when it is needed, are the DR's too.
                let make_targets = || {
                    progress.update("init", 0.5, "curls: targets");
                    DrTargets::from_capture(capture, &maps, Some(&inner), progress).map_err(ReconError::from)
                };
                let targets = (&make_targets as &dyn Fn() -> Result<DrTargets, ReconError>, &mut dr_targets);
                choose_curl(&directed, raw.mesh(), targets, opts, &grow_from, &mut metrics, progress)?
            }
        };
        // One growth: from the points' own directions, or with curls along the ringlet axes.
        let axes = match curl {
            None => None,
            Some(c) => {
                progress.update("init", 0.7, &format!("curls: growing along the ringlets ({c:?})"));
                let mut axes =
                    ringlet_axes(&directed, raw.mesh(), &c, &opts.curl_options).ok_or(ReconError::CurlGrid)?;
                if opts.curl_options.hang {
                    hang(&mut axes);
                }
                // The metric judges the axes where the cameras saw the hair (it matches ground-truth
                // strand points, and none lie on a ringlet's axis), so before they are moved there.
                if let Some(g) = &gt {
                    let gt_ax = gt_axes(&g.strands, c.period / c.pitch_angle().cos(), 0.001);
                    let s = score_axes(&axes.positions, &axes.directions, &gt_ax, MATCH_DIST);
                    metrics.insert("axes".into(), serde_json::to_value(s).unwrap_or_default());
                }
                if opts.curl_options.onto_axes {
                    onto_axes(&directed, &mut axes, &c);
                }
                axes.save_ply(&out_dir.join("points_axes.ply"))?;
                Some(axes)
            }
        };
        let (flow, guides, children) = grow_from(axes.as_ref().unwrap_or(&directed), &mut metrics)?;
        flow.save(&out_dir.join("flow.bin"))?;
        match curl {
            None => (guides, children),
            Some(c) => {
                curled = true;
                metrics.insert(
                    "curl".into(),
                    json!({"radius_mm": c.radius * 1e3, "period_mm": c.period * 1e3, "hand": c.hand}),
                );
                (
                    sweep_helices(&guides, &c, &opts.curl_options, opts.seed)?,
                    sweep_helices(&children, &c, &opts.curl_options, opts.seed.wrapping_add(1))?,
                )
            }
        }
    } else {
        let seg = (opts.straight_length / opts.grow.step).ceil() as usize;
        (
            straight_strands(&guide_roots, opts.straight_length, seg),
            straight_strands(&child_roots, opts.straight_length, seg),
        )
    };
    progress.check()?;
    // The hull: the children are cut before DR; the guides, from which DR blends the children, stay
    // whole (so `--no-dr` gives the same files as the init of a DR run). DR's result is not cut again:
    // from the cut init, cutting it cost 0.5 (straight) and 0.2 (curly) of F1 at 2 mm/20°, its points
    // outside the masks still matching thin hair there (examples/hull_check on examples/dr_on_capture's
    // output, session 15).
    let hull = if opts.hull_trim {
        let hull = VisualHull::from_capture(capture, Some(&inner), opts.hull, "init", progress)?
            .map(|h| h.with_scalp(Some(scalp.bvh().clone())));
        metrics.insert("hull_views".into(), json!(hull.as_ref().map_or(0, |h| h.num_views())));
        hull
    } else {
        None
    };
    let children = match hull.as_ref().map(|h| h.trim_checked(&children)) {
        Some(Ok((set, stats))) => {
            metrics.insert("hull_trim_init_strands".into(), serde_json::to_value(stats).unwrap_or_default());
            set
        }
        Some(Err(stats)) => {
            let msg = format!(
                "the visual hull would cut {:.0}% of the strand points: the masks or the cameras disagree \
                 with the reconstruction, so the strands are kept whole (check the masks; --no-hull-trim \
                 silences this)",
                100.0 * stats.points_removed as f64 / stats.points.max(1) as f64
            );
            progress.update("init", 1.0, &msg);
            metrics.insert("hull_warning".into(), json!(msg));
            children
        }
        None => children,
    };
    let guides_path = out_dir.join("guides.hair");
    let strands_path = out_dir.join("strands.hair");
    times.push(("init".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "init");
    if !run_dr {
        write_strands(&guides_path, &guides)?;
        write_strands(&strands_path, &children)?;
        if let Some(g) = &gt {
            progress.update("metrics", 0.0, "scoring strands");
            metrics.insert("init_guides".into(), strand_metric(&guides, &g.strands));
            metrics.insert("init_strands".into(), strand_metric(&children, &g.strands));
        }
        write_metrics(&metrics)?;
        progress.update("init", 1.0, "");
        return Ok(ReconstructOutput {
            strands: Some(strands_path),
            guides: Some(guides_path),
            init_strands: None,
            init_guides: None,
            loss_csv: None,
            stage_times: times,
            metrics: serde_json::Value::Object(metrics),
        });
    }

    // Stage 6: DR. Nothing is written until it has finished.
    let t = Instant::now();
    progress.update("dr", 0.0, "targets");
    let mut targets = match dr_targets {
        Some(t) => t,
        None => DrTargets::from_capture(capture, &maps, Some(&inner), progress)?,
    };
    if let Some(p) = scalp.partings() {
        if opts.parting.quiet_orientation {
            metrics.insert("parting_pixels_quieted".into(), json!(targets.quiet_partings(p)));
        }
    }
    let t_targets = t.elapsed().as_secs_f64();
    let t_opt = Instant::now();
    // The guide stage's child map blends as many guides as growing did.
    let keep_curls = curled && opts.dr_keep_curls;
    let base = if keep_curls { opts.dr_options.keeping_curls() } else { opts.dr_options.clone() };
    let dr_options = DrOptions { child_blend: opts.grow.blend, ..base };
    metrics.insert("dr_keeps_curls".into(), json!(keep_curls));
    let r = dr_optimize(&guides, &children, &targets, scalp.bvh(), Some(&inner), &dr_options, progress)?;
    let t_opt = t_opt.elapsed().as_secs_f64();
    progress.check()?;
    drop(targets);
    let init_guides_path = out_dir.join("init_guides.hair");
    let init_strands_path = out_dir.join("init_strands.hair");
    let loss_csv = out_dir.join("loss.csv");
    write_strands(&init_guides_path, &guides)?;
    write_strands(&init_strands_path, &children)?;
    crate::dr::report::write_loss_csv(&loss_csv, &r.loss_curve)?;
    crate::dr::report::write_loss_png(&out_dir.join("loss.png"), &r.loss_curve)?;
    write_strands(&guides_path, &r.guides)?;
    write_strands(&strands_path, &r.children)?;
    times.push(("dr".into(), t.elapsed().as_secs_f64()));
    note_peak_memory(&mut metrics, "dr");
    let steps = r.loss_curve.len();
    let first_last = |stage| {
        let recs: Vec<_> = r.loss_curve.iter().filter(|x| x.stage == stage).collect();
        let secs: f64 = recs.iter().map(|x| x.seconds as f64).sum();
        json!({
            "steps": recs.len(),
            "first_loss": recs.first().map(|x| x.terms.total()),
            "last_loss": recs.last().map(|x| x.terms.total()),
            "seconds_per_step": if recs.is_empty() { 0.0 } else { secs / recs.len() as f64 },
        })
    };
    metrics.insert(
        "dr_stats".into(),
        json!({
            "steps": steps,
            "targets_seconds": t_targets,
            "optimize_seconds": t_opt,
            "seconds_per_step": if steps > 0 { t_opt / steps as f64 } else { 0.0 },
            "mean_cg_iterations": r.mean_cg_iterations,
            "guides": first_last(crate::dr::DrStage::Guides),
            "children": first_last(crate::dr::DrStage::Children),
        }),
    );
    if let Some(g) = &gt {
        progress.update("metrics", 0.0, "scoring strands");
        metrics.insert("init_guides".into(), strand_metric(&guides, &g.strands));
        metrics.insert("init_strands".into(), strand_metric(&children, &g.strands));
        progress.update("metrics", 0.5, "scoring strands");
        metrics.insert("dr_guides".into(), strand_metric(&r.guides, &g.strands));
        metrics.insert("dr_strands".into(), strand_metric(&r.children, &g.strands));
    }
    write_metrics(&metrics)?;
    progress.update("dr", 1.0, "");
    Ok(ReconstructOutput {
        strands: Some(strands_path),
        guides: Some(guides_path),
        init_strands: Some(init_strands_path),
        init_guides: Some(init_guides_path),
        loss_csv: Some(loss_csv),
        stage_times: times,
        metrics: serde_json::Value::Object(metrics),
    })
}

/// The grown strands of the init stage: flow, guides, children.
type Grown = (crate::laplace::FlowField, StrandSet, StrandSet);
type Metrics = serde_json::Map<String, serde_json::Value>;
/// Growth from some directed points, recording its statistics in the metrics.
type GrowFn<'a> = dyn Fn(&OrientedPoints, &mut Metrics) -> Result<Grown, ReconError> + 'a;

/// `--curl auto` ([`crate::curl`]). Ringlets hang: the handedness whose ringlet axes (at the nominal
/// pitch) point down more is the hair's, and the hair is curly only when those axes point down
/// clearly more (by `CurlOptions::min_down_gain`) than the points' own directions, which on straight
/// hair are the strands' and hang the most (paper curly preset: axes 0.59, tangents 0.42).
///
/// Then the period is read off the hair surface's bumps along those axes
/// ([`crate::curl::bump_period`]: paper curly 22.1 mm, the preset's 22), and the radius is the one
/// that gives the nominal pitch at that period (`CurlOptions::nominal_pitch_deg`, 60°: 6.1 mm at 22 mm;
/// the preset's curls have 61.7°). The pitch is assumed, not measured: the points see the ringlets'
/// visible side only, where the tangents are the same at every turn and lie at the pitch from an axis
/// that nothing else gives (docs/curly-study.md, session 29).
///
/// When the surface shows no period (or `CurlOptions::bump_period` is off), strands are grown along
/// the axes and the curl (of the radii and periods of `opts.curl_options`) whose helices about them
/// fit the Gabor orientation maps best ([`crate::dr::optimize::orientation_misfit`], on a subset of
/// children and views) is chosen. That misfit does not measure the radius: helices about the ground
/// truth's own centrelines, scored against its own orientation maps, rank the radii by how densely
/// they are drawn (every 25th strand: 11 mm best, 1.346 against 1.427 at the preset's 6.5 mm; all
/// 50,000: 4 mm best, 1.084 against 1.369; docs/curly-study.md, session 25): on paper curly it chose
/// 9 mm / 22 mm, the widest radius it tries. The candidates are scored on strands grown through the
/// points where the cameras saw them; scored through points moved onto the axes it chose 9 mm /
/// 15 mm (session 24).
///
/// The images cannot decide between curls and no curls: strands that follow the visible tangents
/// fit the orientation maps better than any helix at a random phase (paper curly: misfit 1.08
/// against 1.36-1.56), although the helices score far higher against the ground truth.
///
/// Everything measured goes to `metrics` as `curl_auto`. `targets`: how to make the DR's targets,
/// which the misfit needs, and where to keep them for the DR.
#[allow(clippy::too_many_arguments)]
fn choose_curl(
    directed: &OrientedPoints,
    raw: &hairrecon_core::mesh::TriMesh,
    targets: (&dyn Fn() -> Result<DrTargets, ReconError>, &mut Option<DrTargets>),
    opts: &ReconstructOptions,
    grow_from: &GrowFn<'_>,
    metrics: &mut Metrics,
    progress: &dyn Progress,
) -> Result<Option<Curl>, ReconError> {
    let co = &opts.curl_options;
    let tan_nominal = co.nominal_pitch_deg.to_radians().tan();
    let nominal =
        |hand: f32| Curl { radius: co.periods[1] * tan_nominal / std::f32::consts::TAU, period: co.periods[1], hand };
    progress.update("init", 0.55, "curls: handedness");
    let right = ringlet_axes(directed, raw, &nominal(1.0), co).ok_or(ReconError::CurlGrid)?;
    let left = ringlet_axes(directed, raw, &nominal(-1.0), co).ok_or(ReconError::CurlGrid)?;
    let (down_right, down_left, down_tangents) = (mean_down(&right), mean_down(&left), mean_down(directed));
    let (hand, axes, down) = if down_right >= down_left { (1.0, right, down_right) } else { (-1.0, left, down_left) };
    let mut report = json!({
        "down_right": down_right, "down_left": down_left, "down_tangents": down_tangents, "hand": hand,
    });
    if down < down_tangents + co.min_down_gain {
        metrics.insert("curl_auto".into(), report);
        return Ok(None);
    }
    let mut axes = axes;
    if co.hang {
        hang(&mut axes);
    }
    if co.bump_period {
        progress.check()?;
        progress.update("init", 0.58, "curls: period from the surface");
        let bumps = bump_period(&directed.positions, &axes.directions, &co.bumps);
        report["bumps"] = serde_json::to_value(&bumps).unwrap_or_default();
        if let Some(period) = bumps.period {
            let c = Curl { radius: period * tan_nominal / std::f32::consts::TAU, period, hand };
            if c.validate().is_ok() {
                report["chosen_by"] = json!("bumps");
                metrics.insert("curl_auto".into(), report);
                return Ok(Some(c));
            }
        }
    }
    let (make_targets, slot) = targets;
    let targets: &DrTargets = match slot {
        Some(t) => t,
        None => slot.insert(make_targets()?),
    };
    progress.update("init", 0.6, "curls: growing along the ringlets");
    let (_, _, centre) = grow_from(&axes, &mut serde_json::Map::new())?;
    let nv = targets.views.len();
    let k = co.score_views.clamp(1, nv.max(1));
    let views: Vec<usize> = (0..k).map(|i| i * nv / k).collect();
    let centre = centre.select(&(0..centre.num_strands()).step_by(co.score_every.max(1)).collect::<Vec<_>>());
    let mut best: (f64, Option<Curl>) = (f64::INFINITY, None);
    let mut tried = Vec::new();
    let n = co.radii.len() * co.periods.len();
    for (i, &radius) in co.radii.iter().enumerate() {
        for (j, &period) in co.periods.iter().enumerate() {
            progress.check()?;
            progress.update("init", 0.6 + 0.1 * (i * co.periods.len() + j) as f32 / n as f32, "curls: scoring");
            let c = Curl { radius, period, hand };
            let misfit =
                orientation_misfit(&sweep_helices(&centre, &c, co, opts.seed)?, targets, &views, &opts.dr_options)?;
            tried.push(json!({"radius_mm": radius * 1e3, "period_mm": period * 1e3, "misfit": misfit}));
            if misfit < best.0 {
                best = (misfit, Some(c));
            }
        }
    }
    report["tried"] = json!(tried);
    report["chosen_by"] = json!("misfit");
    metrics.insert("curl_auto".into(), report);
    Ok(best.1)
}

/// The files of the strand stages (and the curl axes of [`crate::curl`]), removed at the start of a run
/// that writes strands.
const STRAND_OUTPUTS: [&str; 7] =
    ["strands.hair", "guides.hair", "init_strands.hair", "init_guides.hair", "loss.csv", "loss.png", "points_axes.ply"];

/// Reloads oriented points saved by a stage (`points3d.ply` or `points_directed.ply`).
pub fn load_points(out_dir: &Path, name: &str) -> Result<OrientedPoints, ReconError> {
    Ok(OrientedPoints::load_ply(&out_dir.join(name))?)
}
