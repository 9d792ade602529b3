//! Stage 6: strand optimization by differentiable rendering of line segments (Dr.Hair, Takimoto et
//! al., CVPR 2024, §3.2; `docs/method.md` §5; supplement §3.2 and §4.3).
//!
//! In: the initial guides and children of [`crate::grow`], [`DrTargets`] (per view: camera, hair
//! mask as coverage in [0, 1], the orientation `(cos 2θ, sin 2θ)` with confidence of
//! [`crate::orient2d`], optionally the head's depth as an occluder), the scalp and head BVHs, and
//! [`DrOptions`]. Out: [`DrResult`]: optimized guides and children (roots on the scalp, no point
//! inside the head, even segment lengths) and the loss curve. Entry point: [`optimize()`].
//!
//! One file per part:
//! - [`losses`]: L_m, L_o, R_c and the segment-length regularizer (R_root holds exactly: roots are
//!   fixed on the scalp).
//! - [`reparam`]: u = (I + λL) x with L = F (along strands) + N (between the k nearest strands),
//!   after Nicolet et al. 2021.
//! - [`adam`]: Adam, with the uniform variant of Nicolet et al.
//! - [`children`]: children as a linear function of the guides, for the guide stage.
//! - [`coarse`]: the strands thinned to every `stride`-th point for the steps, and the moves carried
//!   back to every point.
//! - [`downsample`]: the targets at a coarser image scale, for the guide stage.
//! - [`optimize`](mod@optimize): the hierarchy (guides, then children), random views per step,
//!   rayon over views, and the final simulation-ready pass.
//! - [`report`]: the loss curves as `loss.csv` and `loss.png`.
//!
//! Measured on the synthetic scene of `tests/dr.rs` (240 strands on a 9 cm sphere, 8 views of
//! 160 px; `cargo test --release -p hairrecon-recon --test integration dr:: -- --skip pipeline_dr
//! --nocapture`): with the defaults,
//! directed F1 at 2 mm/20° 70.4 → 89.8 and mean tip error 20.5 → 10.8 mm (without the
//! reparameterization 81.6 / 11.7 mm). The figures on the paper presets, by commit, are in
//! `docs/reconstruction.md`; the studies behind the defaults in
//! `research/notes/reconstruction-study.md`.
//!
//! The final pass evens the segments with points taken on each strand's input polyline: resampling
//! the resampled polyline in every pass cut the curls' corners (paper curly capture, undirected F1
//! at 2 mm/20° 47.9 → 41.5 from that pass alone, 45.3 with points on the input; measured at commit
//! 1ac3d7a).
//!
//! The regularizers are scaled by the mean hair area of a view over the number of optimized points
//! ([`optimize::regularizer_factor`]), so the guide and child stages weigh them alike against the
//! image terms. Known limit: strands cannot change their point count (they lengthen by longer
//! segments, which the length regularizer evens out).

pub mod adam;
pub mod children;
pub mod coarse;
pub mod downsample;
pub mod losses;
pub mod optimize;
pub mod reparam;
pub mod report;

use glam::{Vec2, Vec3};
use hairrecon_core::capture::Capture;
use hairrecon_core::{Bvh, Camera};
use hairrecon_raster::RasterError;
use rayon::prelude::*;
use thiserror::Error;

use crate::orient2d::{GrayImage, Orient2dError, OrientationMap};
use crate::progress::{Cancelled, Progress};

pub use losses::{LossTerms, LossWeights};
pub use optimize::{finalize, optimize};
pub use reparam::KnnKey;

/// Why the DR stage stopped.
#[derive(Debug, Error)]
pub enum DrError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    #[error("rendering failed: {0}")]
    Render(#[from] RasterError),
    #[error(transparent)]
    Orient2d(#[from] Orient2dError),
    #[error("no views to optimize against; give DrTargets at least one view")]
    NoViews,
    #[error("view {view}: {what} has {got} pixels but the camera is {width}x{height}")]
    Size { view: usize, what: &'static str, got: usize, width: u32, height: u32 },
    #[error("{0} views were given but {1} orientation maps; give one map per view")]
    MapCount(usize, usize),
    #[error("the strands have no points to optimize")]
    Empty,
    #[error("the targets at a coarser scale: {0}")]
    Downsample(String),
    #[error("the optimization diverged (non-finite loss at iteration {0}); lower the learning rate")]
    Diverged(usize),
}

/// What one view asks the render to look like.
#[derive(Debug, Clone)]
pub struct DrView {
    pub camera: Camera,
    /// Hair coverage in [0, 1], row-major.
    pub mask: Vec<f32>,
    /// Per pixel `[cos 2θ, sin 2θ, confidence]`.
    pub orientation: Vec<[f32; 3]>,
    /// Depth (camera z) of the head per pixel, `f32::INFINITY` where there is none; strands
    /// behind it are hidden.
    pub head_depth: Option<Vec<f32>>,
}

impl DrView {
    /// Checks the sizes against the camera.
    pub fn new(
        view: usize,
        camera: Camera,
        mask: Vec<f32>,
        orientation: Vec<[f32; 3]>,
        head_depth: Option<Vec<f32>>,
    ) -> Result<Self, DrError> {
        let (w, h) = (camera.width(), camera.height());
        let n = w as usize * h as usize;
        let check = |what, got: usize| {
            if got == n {
                Ok(())
            } else {
                Err(DrError::Size { view, what, got, width: w, height: h })
            }
        };
        check("the mask", mask.len())?;
        check("the orientation map", orientation.len())?;
        if let Some(d) = &head_depth {
            check("the head depth", d.len())?;
        }
        let mask = mask.into_iter().map(|m| if m.is_finite() { m.clamp(0.0, 1.0) } else { 0.0 }).collect();
        let orientation = orientation
            .into_iter()
            .map(
                |[c, s, k]| if c.is_finite() && s.is_finite() && k.is_finite() { [c, s, k.max(0.0)] } else { [0.0; 3] },
            )
            .collect();
        Ok(Self { camera, mask, orientation, head_depth })
    }
}

/// The targets of every view.
#[derive(Debug, Clone, Default)]
pub struct DrTargets {
    pub views: Vec<DrView>,
}

impl DrTargets {
    /// Targets from a capture and its orientation maps (one per view, as [`crate::orient2d`] or
    /// [`crate::stages::orient2d::Orient2dOut::load`] give them). The mask of a view is its hair
    /// mask (as coverage, the luminance in [0, 1]); without one, pixels with orientation confidence
    /// above 0 count as hair. With `head`, strands behind the head are hidden. Reports per view as
    /// stage "dr" and stops when `progress` is cancelled.
    pub fn from_capture(
        capture: &Capture,
        maps: &[OrientationMap],
        head: Option<&Bvh>,
        progress: &dyn Progress,
    ) -> Result<Self, DrError> {
        if maps.len() != capture.views.len() {
            return Err(DrError::MapCount(capture.views.len(), maps.len()));
        }
        let mut views = Vec::with_capacity(maps.len());
        for (i, (v, m)) in capture.views.iter().zip(maps).enumerate() {
            progress.check()?;
            progress.update("dr", 0.0, &format!("targets: view {}/{}", i + 1, maps.len()));
            let mask = match &v.mask {
                Some(p) => GrayImage::load(p)?.data,
                None => m.confidence.iter().map(|&c| if c > 0.0 { 1.0 } else { 0.0 }).collect(),
            };
            let orientation =
                m.theta.iter().zip(&m.confidence).map(|(t, c)| [(2.0 * t).cos(), (2.0 * t).sin(), *c]).collect();
            let depth = head.map(|h| crate::views::head_depth_map(&v.camera, h));
            views.push(DrView::new(i, v.camera, mask, orientation, depth)?);
        }
        Ok(Self { views })
    }
}

impl DrTargets {
    /// Zeroes the orientation's confidence where a view sees the head within the partings' reach of
    /// their skin ([`crate::parting`]): the Gabor maps there carry no strand texture and run along
    /// the parting (`docs/method.md`, "Partings"; research/notes/reconstruction-study.md, "The front
    /// of the crown"), so the orientation loss would turn the strands that leave the parting
    /// sideways back along it; the silhouette still holds them. Views without the head's depth are
    /// left as they are. Returns the pixels quieted.
    pub fn quiet_partings(&mut self, partings: &hairrecon_core::scalp::Partings) -> usize {
        self.views
            .iter_mut()
            .map(|v| {
                let Some(depth) = &v.head_depth else { return 0 };
                let w = v.camera.width() as usize;
                let camera = v.camera;
                v.orientation
                    .par_iter_mut()
                    .zip(depth.par_iter())
                    .enumerate()
                    .map(|(i, (o, &d))| {
                        if !d.is_finite() || o[2] == 0.0 {
                            return 0;
                        }
                        let p = camera.back_project(Vec2::new((i % w) as f32, (i / w) as f32), d);
                        if partings.distance(p).is_some() {
                            o[2] = 0.0;
                            1
                        } else {
                            0
                        }
                    })
                    .sum::<usize>()
            })
            .sum()
    }
}

/// Options of [`optimize()`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DrOptions {
    /// Adam steps on the guides (0 or `guide_opt = false`: no guide stage).
    pub iterations_guides: usize,
    /// Adam steps on the children.
    pub iterations_children: usize,
    /// Adam learning rate in u, metres per step (with the uniform Adam: the step of a point at
    /// `adam_quantile`, and the longest step of any point).
    pub lr: f32,
    /// The learning rate at a stage's last step, as a fraction of `lr`: the rate falls linearly
    /// over each stage from `lr` to `lr · lr_end` (1: constant). With a few random views per step
    /// the gradient is noisy, and at a constant rate the last steps leave that noise in the strands.
    /// Measured at commit 1b061f9 (DR alone on the saved inits of whole runs, as `hairrecon
    /// reconstruct --from dr` runs it; undirected F1 at 1 · 2 · 3 mm, constant → 0.1): straight
    /// 20,000 strands in 16 views of 384 px (the demo's capture) 45.5 · 79.2 · 90.2 → 47.6 · 80.3 ·
    /// 90.7 (init 49.3 · 80.2 · 90.1); paper preset (constant: the whole runs of the time) straight
    /// 69.9 · 90.4 · 95.9 → 70.5 · 90.6 · 96.1, curly (keeping the curls) 19.8 · 73.7 · 92.6 → 20.0
    /// · 73.5 · 92.2.
    pub lr_end: f32,
    /// λ of `u = (I + λL) x`.
    pub lambda: f32,
    /// k of the kNN Laplacian N (supplement: 10).
    pub k_neighbors: usize,
    /// Weight of an N edge against an F edge.
    pub neighbor_weight: f32,
    /// Which strand point the kNN search of N uses.
    pub knn_key: KnnKey,
    /// Strand width, metres (paper: 0.2 mm).
    pub width_m: f32,
    /// Views rendered per step (random, seeded).
    pub views_per_step: usize,
    /// Reparameterization on (false: Adam on the points, the "w/o reparam." ablation).
    pub reparam: bool,
    /// N in the Laplacian (false: F only, the "w/o N" ablation).
    pub neighbor_reparam: bool,
    /// The guide stage (false: children from the start, the "w/o guide opt." ablation).
    pub guide_opt: bool,
    /// The uniform Adam of Nicolet et al. (false: per-coordinate Adam).
    pub uniform_adam: bool,
    /// With the uniform Adam: the quantile of the points' second moments that scales the step (1:
    /// the maximum, as Nicolet et al.; below 1, longer steps are clamped to `lr`). With the maximum
    /// over 50,000 strands a few points with large gradients set the scale and the rest do not move:
    /// on the paper curly capture 20 guide steps moved the median point 0.05 mm (0.07 mm on
    /// straight), and F1 stayed where it was (51.9 → 51.9; straight 84.5 → 84.7). Per-coordinate
    /// Adam moves every point about `lr` per step, noise included: median 5 mm after 20 steps,
    /// straight 84.5 → 79.1, curly 51.9 → 48.6. The 0.99 quantile sits between (median 0.4–0.8 mm):
    /// straight 85.1, curly 52.1 with curvature weight 0.05 (the 0.9 quantile: straight 84.5).
    /// Measured at commit 6a05744: 20 guide steps of DR alone (no child stage, no final evening) on
    /// the saved paper-preset inits of the time, undirected F1 at 2 mm/20°.
    pub adam_quantile: f32,
    /// How the guide stage's child map blends the guides (the pipeline sets it to
    /// `GrowParams::blend`, so that it matches the init's children).
    pub child_blend: crate::grow::BlendParams,
    /// Points are kept at least this far outside the head, metres.
    pub head_clearance: f32,
    /// Points are pushed out of the head every this many steps (and at the end).
    pub project_every: usize,
    /// Resample every strand to equal segment lengths at the end.
    pub equalize_at_end: bool,
    /// R_c against the second differences each stage starts from (the init's curls kept, only their
    /// change penalized) instead of against straight strands.
    pub curvature_relative: bool,
    /// Relative residual at which the conjugate-gradient solves of the reparameterization stop.
    /// The solves are warm-started from the last step's solution, and a looser tolerance leaves a
    /// small error in a step that the next steps correct. 1e-3 → 1e-2 at commit c1bc034 (DR alone
    /// on the paper preset's inits, stride 2): CG iterations per solve 10.0 → 6.5 and a child step
    /// 7.3 → 6.2 s on the straight capture; undirected F1 at 1 · 2 · 3 mm on the curly capture
    /// 19.3 · 75.3 · 93.5 → 19.3 · 75.2 · 93.5 (docs/reconstruction.md).
    pub cg_tolerance: f32,
    /// The steps move every `stride`-th point of each strand (and its tip); the points between
    /// follow the two around them ([`coarse`]). 1: every point. The init's strands have a point
    /// every ~1.6 mm, and DR's time and memory follow the points it moves. DR alone on the colours
    /// preset's inits (60 + 20 steps; undirected F1 at 1 · 2 · 3 mm, peak memory), stride 1 → 2:
    /// straight 63.3 · 88.2 · 95.3, 4.05 GiB → 63.9 · 88.7 · 95.5, 2.27 GiB; curly 18.9 · 73.5 · 92.6
    /// at 2 (docs/reconstruction.md). The default 3 since commit c1bc034: on the paper preset's
    /// inits (DR alone, guide stage at stride 4) straight 72.0 · 91.6 · 96.3 at 2 and at 3, curly
    /// 19.3 · 75.3 · 93.5 → 19.3 · 75.2 · 93.5, a child step 20% shorter. A configuration without
    /// it (a run's from before it) replays at 1.
    #[serde(default = "one")]
    pub stride: usize,
    /// The guide stage renders and compares at an image scale this many times smaller in both
    /// directions ([`downsample`]); the child stage at full scale. 1: full scale. A configuration
    /// without it (a run's from before it) replays at 1.
    #[serde(default = "one")]
    pub guide_downsample: usize,
    /// The guide stage's stride (0: `stride`): the guide stage renders the children through their
    /// map on points this far apart, the child stage on points `stride` apart. A guide step renders
    /// every child, and its time follows their points. With `guide_downsample` 2, a guide step on
    /// the paper straight capture 7.1 → 3.2 CPU seconds (stride 2 at full size → 4 at half size);
    /// DR alone on the colours preset's inits, undirected F1 at 1 · 2 · 3 mm, straight 63.9 · 88.7
    /// · 95.5 → 64.0 · 88.8 · 95.6, curly 18.9 · 73.5 · 92.6 → 18.8 · 73.3 · 92.6
    /// (docs/reconstruction.md). A configuration without it (a run's from before it) replays with 0.
    #[serde(default)]
    pub guide_stride: usize,
    pub weights: LossWeights,
    pub seed: u64,
}

fn one() -> usize {
    1
}

impl Default for DrOptions {
    fn default() -> Self {
        Self {
            iterations_guides: 60,
            iterations_children: 20,
            lr: 2e-3,
            lr_end: 0.1,
            lambda: 10.0,
            k_neighbors: 10,
            neighbor_weight: 0.05,
            knn_key: KnnKey::Middle,
            // 0.2 mm as the CLI has always computed it (0.2 × 1e-3 in f32, one ulp above 0.0002).
            width_m: 0.2 * 1e-3,
            views_per_step: 4,
            reparam: true,
            neighbor_reparam: true,
            guide_opt: true,
            uniform_adam: true,
            adam_quantile: 0.99,
            child_blend: crate::grow::BlendParams::default(),
            head_clearance: 0.001,
            project_every: 10,
            equalize_at_end: true,
            curvature_relative: false,
            cg_tolerance: 1e-2,
            stride: 3,
            guide_downsample: 2,
            guide_stride: 4,
            weights: LossWeights::default(),
            seed: 0,
        }
    }
}

/// R_c's weight when DR keeps curls ([`DrOptions::keeping_curls`]).
pub const CURL_CURVATURE_WEIGHT: f32 = 5.0;
/// The learning rate's factor when DR keeps curls ([`DrOptions::keeping_curls`]).
pub const CURL_LR_SCALE: f32 = 0.5;

impl DrOptions {
    /// The options for strands that carry curls (helices swept about ringlet axes, `--curl`): R_c
    /// against the init's own curvature with weight [`CURL_CURVATURE_WEIGHT`] (the curls' shape
    /// kept, only its change penalized) and the learning rate times [`CURL_LR_SCALE`]. DR's moves
    /// across the strands (1.9 mm at the median on the paper curly capture with the plain options,
    /// 1.1 mm with these) carry no information at 1 mm and draw the helices out. DR alone on the
    /// saved paper curly init (undirected F1 at 1 · 2 · 3 mm, measured at commit e4c0c5e): these
    /// options 18.8 · 72.8 · 92.3 (directed 71.3 at 2 mm), the plain options 17.3 · 71.4 · 92.1
    /// (69.5); R_c relative at weight 5 alone 18.1 · 72.2 · 92.3, half the rate alone 18.4 · 72.6 ·
    /// 92.3 (research/notes/curly-study.md).
    pub fn keeping_curls(&self) -> Self {
        let mut o = self.clone();
        o.curvature_relative = true;
        o.weights.curvature = CURL_CURVATURE_WEIGHT;
        o.lr *= CURL_LR_SCALE;
        o
    }
}

/// A stage of the hierarchy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DrStage {
    /// Guides optimized, children following them.
    Guides,
    /// Every child on its own.
    Children,
}

impl std::fmt::Display for DrStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DrStage::Guides => "guides",
            DrStage::Children => "children",
        })
    }
}

/// The loss of one step (before the step, in the views it rendered).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LossRecord {
    pub stage: DrStage,
    /// Step within the stage, from 0.
    pub iteration: usize,
    pub terms: LossTerms,
    /// Wall time of the step, seconds.
    pub seconds: f32,
}

/// What [`optimize()`] returns.
#[derive(Debug, Clone)]
pub struct DrResult {
    pub guides: hairrecon_core::StrandSet,
    pub children: hairrecon_core::StrandSet,
    /// One record per step: the guide stage first, then the children's.
    pub loss_curve: Vec<LossRecord>,
    /// Mean conjugate-gradient iterations per solve.
    pub mean_cg_iterations: f32,
}

/// Each strand's points of `points` (laid out by `offsets`, a strand set's), as one mutable slice a
/// strand, to work on in parallel.
pub(crate) fn strands_mut<'a>(points: &'a mut [Vec3], offsets: &[usize]) -> Vec<&'a mut [Vec3]> {
    let mut parts = Vec::with_capacity(offsets.len().saturating_sub(1));
    let mut rest = points;
    for w in offsets.windows(2) {
        let (a, b) = rest.split_at_mut(w[1] - w[0]);
        parts.push(a);
        rest = b;
    }
    parts
}

/// Points deeper inside the head than this are left alone by [`push_out_of_head`]: on a head mesh
/// with holes (a cut neck) the pseudo-normal sign can be wrong far from the surface, and moving such
/// a point up to 5 cm onto the surface did more harm than good (measured on the test-preset
/// capture: 37 guide points moved by up to 50 mm, and the loss rose from 924 to 1475). 10 mm
/// because children blend 2 guides: a child between two guides that part around the head can be
/// pulled 5–10 mm into it during the guide stage (the sphere head of `tests/pipeline_dr.rs` had a
/// point 5.6 mm inside at a limit of 5 mm, none at 10 mm; measured at commit ade29e2).
pub(crate) const MAX_PUSH_DEPTH: f32 = 0.01;

/// A point is moved out of the head to `clearance` outside it if it is closer or inside (by at
/// most [`MAX_PUSH_DEPTH`]).
pub(crate) fn push_out_of_head(head: &Bvh, p: Vec3, clearance: f32) -> Vec3 {
    let Some(cp) = head.closest_point(p, MAX_PUSH_DEPTH.max(clearance) + 1e-4) else { return p };
    let n = head.pseudo_normal(&cp);
    let signed = if (p - cp.point).dot(n) < 0.0 { -cp.distance } else { cp.distance };
    if signed >= clearance || signed < -MAX_PUSH_DEPTH {
        p
    } else {
        cp.point + n.normalize_or_zero() * clearance
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hairrecon_core::scalp::Partings;

    #[test]
    fn the_orientation_is_quiet_where_the_view_sees_the_head_by_a_parting_and_nowhere_else() {
        // A 40×40 view from z = 1 m down onto the head's plane z = 0 (a pixel is 2.5 cm there).
        let camera =
            Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 2.0 * 0.5f32.atan(), 40, 40).unwrap();
        let n = 40 * 40;
        let mut depth = vec![1.0f32; n];
        // No head in the first row: nothing to quiet there.
        depth[..40].iter_mut().for_each(|d| *d = f32::INFINITY);
        let view = DrView::new(0, camera, vec![1.0; n], vec![[1.0, 0.0, 0.8]; n], Some(depth)).unwrap();
        let mut targets = DrTargets { views: vec![view.clone(), DrView { head_depth: None, ..view }] };
        // Skin at the head point seen by pixel (20, 20), reach 3 cm: that pixel and its four
        // neighbours (2.5 cm away) see the head within reach, the diagonal ones (3.5 cm) do not.
        let skin = camera.back_project(Vec2::new(20.0, 20.0), 1.0);
        let quiet = targets.quiet_partings(&Partings::new(vec![skin], 0.03, 2.0));
        let zero: Vec<usize> = (0..n).filter(|&i| targets.views[0].orientation[i][2] == 0.0).collect();
        assert_eq!(quiet, 5);
        assert_eq!(zero, vec![19 * 40 + 20, 20 * 40 + 19, 20 * 40 + 20, 20 * 40 + 21, 21 * 40 + 20]);
        // The orientation itself is kept; a view without the head's depth is left alone.
        assert_eq!(targets.views[0].orientation[20 * 40 + 20][..2], [1.0, 0.0]);
        assert!(targets.views[1].orientation.iter().all(|o| o[2] == 0.8));
    }
}
