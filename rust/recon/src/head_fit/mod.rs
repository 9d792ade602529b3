//! Head fitting, first part: the similarity (scale, rotation, translation) that takes a raw mesh
//! in a photogrammetry tool's frame to the canonical frame (metres, Z up, the face toward −Y), by
//! registering the bundled head template to it, without a learned model, and without landmarks
//! unless the user gives some ([`landmarks`]: then their pose replaces steps 2–4).
//!
//! Method:
//! 1. Normalise the raw mesh by its surface centre and radius of gyration (conditioning: any
//!    scale and offset become unit size at the origin) and build one [`surface::RawSurface`] on
//!    it (a BVH with smoothed normals).
//! 2. Coarse search ([`coarse`]): initial poses from the scale prior (the template's radius of
//!    gyration against the raw mesh's), a centre, and a near-uniform set of rotations of SO(3)
//!    (with cameras, a ring about their mean up vector first); each refined by a few iterations of
//!    trimmed ICP on a small sample of the template's skin, ranked by its trimmed residual.
//! 3. The best few refined fully by trimmed ICP ([`icp`]) on all samples, each step solved in
//!    closed form ([`umeyama`]: Umeyama, "Least-squares estimation of transformation parameters
//!    between two point patterns", PAMI 1991); the lowest trimmed residual wins.
//! 4. If that residual is too high (a backdrop or a torso made the scale and centre priors wrong),
//!    the search repeats over a ladder of smaller scales and the places where the surface is
//!    densest at a head's size. A fit whose residual stays too high is an error that says so.
//! 5. Under hair and clothes, the winner is tried at other scales about its centre and its face,
//!    then refined by ICP on the face's points alone (the one large patch of skin a capture
//!    shows; the clothes cannot hold it), each kept only when its cost says so.
//!
//! The template points (template → raw closest points, never the other way) make the fit blind to
//! what the raw mesh has beyond the head: hair, shoulders, a chair. Trimming ignores what the
//! template has beyond the raw mesh: holes, a missing crown, the scalp under hair.

pub mod capture_fit;
pub mod coarse;
pub mod compare;
pub mod icp;
pub mod landmarks;
pub mod nonrigid;
pub mod score;
pub mod surface;
pub mod template;
pub mod umeyama;

use glam::{DMat3, DVec3};
use hairrecon_core::{Camera, TriMesh};
use rayon::prelude::*;
use surface::RawSurface;
use thiserror::Error;

pub use hairrecon_core::similarity::{transform_mesh, Similarity};
pub use icp::{trimmed_icp, IcpMetric, IcpOptions, IcpOutcome, SurfaceSamples, Target};
pub use score::{score_pose, PoseScore};
pub use template::{HeadTemplate, SurfaceStats};

/// The parameters of [`fit_similarity`]. Lengths in millimetres are in the canonical frame.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Rotations of the coarse search (a super-Fibonacci set of SO(3)).
    pub rotations: usize,
    /// Template points each coarse candidate is refined with.
    pub coarse_points: usize,
    /// Raw-surface points the coarse search registers to (nearest points in a kd-tree).
    pub coarse_samples: usize,
    /// ICP iterations per coarse candidate.
    pub coarse_iterations: usize,
    /// The best coarse candidates refined fully.
    pub refine_best: usize,
    /// ICP iterations of a full refinement, at most.
    pub refine_iterations: usize,
    /// The fraction of uncovered template points that count in an ICP step (the rest, the
    /// farthest, are trimmed).
    pub keep: f64,
    /// A template point within this of the raw mesh is on it (seen); farther, it is covered or
    /// exposed ([`score`]).
    pub inlier_mm: f64,
    /// A fit with a smaller fraction of template points on the raw mesh fails.
    pub min_inlier_fraction: f64,
    /// A fit with a larger fraction of exposed template points (outside what the cameras saw)
    /// fails.
    pub max_exposed_fraction: f64,
    /// The scales of the second search, as fractions of the scale prior (for raw meshes with much
    /// more than the head: shoulders, a backdrop).
    pub fallback_scales: Vec<f64>,
    /// A first search that puts this fraction of the template's skin on the raw mesh is final
    /// (a clean head); below it, the second search runs.
    pub clean_fraction: f64,
    /// Times each raw vertex normal is averaged with its neighbours' ([`surface::RawSurface`]).
    pub normal_smoothing: usize,
    /// With cameras: the head's apparent size in the photos (twice the template's radius of
    /// gyration, as a fraction of the image height, the median over the views) must lie in this
    /// range; poses outside it lose to any inside, and a fit outside it fails.
    pub framing: (f64, f64),
    /// After the similarity, the template's shape fitted to the subject's ([`nonrigid`]); `None`
    /// keeps the template's own shape, scaled and turned.
    pub deform: Option<nonrigid::DeformOptions>,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            rotations: 240,
            coarse_points: 120,
            coarse_samples: 20_000,
            coarse_iterations: 8,
            refine_best: 3,
            refine_iterations: 30,
            keep: 0.8,
            inlier_mm: 5.0,
            min_inlier_fraction: 0.3,
            max_exposed_fraction: 0.25,
            fallback_scales: vec![1.0, 0.7, 0.5, 0.35, 0.25],
            clean_fraction: 0.9,
            normal_smoothing: 3,
            framing: (0.1, 3.0),
            deform: Some(nonrigid::DeformOptions::default()),
        }
    }
}

/// A fitted similarity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitResult {
    /// Raw-mesh coordinates → canonical frame (metres).
    pub to_canonical: Similarity,
    /// RMS distance of the template's skin points on the raw mesh (within
    /// [`FitOptions::inlier_mm`]), canonical mm.
    pub residual_mm: f64,
    /// The pose's score on all template points.
    pub score: PoseScore,
    /// The best cost of a refined pose whose rotation differs from the winner's by more than 30°
    /// (how clearly the winner won, [`FitResult::close_call`]; `None` when every refined pose
    /// agreed).
    pub runner_up_cost: Option<f64>,
    /// The shape's fit after the similarity, when one ran ([`FitOptions::deform`]).
    pub shape: Option<nonrigid::DeformReport>,
    /// With landmarks: their RMS distance from the template's after the fit, canonical mm.
    pub landmarks_mm: Option<f64>,
    /// With landmarks: each one's distance from the template's after the fit, canonical mm, in
    /// [`landmarks::NAMES`]' order (`None` for those not given).
    pub each_landmark_mm: [Option<f64>; landmarks::NAMES.len()],
}

/// How close a runner-up's cost may come to the winner's before [`FitResult::close_call`] warns.
/// On the synthetic captures measured, the true pose won by 0.06 to 0.25.
pub const CLOSE_CALL: f64 = 0.03;

impl FitResult {
    /// With landmarks: each given one's name and distance from the template's after the fit
    /// (canonical mm), in [`landmarks::NAMES`]' order.
    pub fn landmark_distances(&self) -> Option<Vec<(&'static str, f64)>> {
        self.landmarks_mm?;
        Some(landmarks::NAMES.iter().zip(self.each_landmark_mm).filter_map(|(n, d)| Some((*n, d?))).collect())
    }

    /// A warning when a pose turned more than 30° from the fit's costs within [`CLOSE_CALL`] of it:
    /// the raw mesh then tells the two apart barely, and the fit may have taken the wrong one (the
    /// back of the head for the face, most often).
    pub fn close_call(&self) -> Option<String> {
        let r = self.runner_up_cost?;
        (r - self.score.cost < CLOSE_CALL).then(|| {
            format!(
                "the head fit barely won: a pose turned more than 30° from it costs {r:.3} against its {:.3}; \
                 check that the face of the fitted head (fitted_head.ply) lies on the raw mesh's face (open \
                 both in Blender); if it does not, place landmarks (landmarks.json beside capture.json, or in \
                 Blender empties named after them) or give the head and scalp by hand",
                self.score.cost
            )
        })
    }
}

/// Why no similarity was found.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FitError {
    #[error("the raw mesh has no area; give the capture's surface mesh")]
    EmptyRaw,
    #[error("the head template has no area or no skin outside its scalp; give the bundled head.ply")]
    EmptyTemplate,
    #[error(
        "the head template does not fit the raw mesh: at the best pose {on:.0}% of the template's skin lies \
         within {inlier_mm} mm of the mesh and {exposed:.0}% outside it (a fit needs at least {min_on:.0}% and at \
         most {max_exposed:.0}%); check that the mesh shows the face and is not cut to the hair only, or place \
         landmarks on it (landmarks.json beside capture.json, see `hairrecon fit-head --help`; in Blender, empties \
         named after them) or give a scalp by hand"
    )]
    Poor { on: f64, exposed: f64, inlier_mm: f64, min_on: f64, max_exposed: f64 },
    #[error(
        "the best pose of the head template would be {percent:.0}% of the photos' height (a capture of a head frames \
         it at {low:.0}% to {high:.0}%): the raw mesh and the cameras do not show a head the template fits; check \
         that they are in the same frame and that the mesh shows the face, or give a scalp and head by hand"
    )]
    Framing { percent: f64, low: f64, high: f64 },
}

/// A refined candidate.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// Template → normalised raw.
    t: Similarity,
    score: PoseScore,
}

/// The similarity from the raw mesh's frame to the template's (canonical) one. `cameras`, in the
/// raw mesh's frame, are optional: their up vectors and the point they look at come first in the
/// search. Deterministic for given inputs.
pub fn fit_similarity(
    template: &HeadTemplate,
    raw: &TriMesh,
    cameras: Option<&[Camera]>,
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    fit_similarity_from(template, raw, cameras, None, opts)
}

/// [`fit_similarity`] from a known pose (template → raw; from [`landmarks`]) instead of the search:
/// the pose is refined by ICP on all the skin, then tried at other scales and on the face as the
/// search's finalists are. `start: None` is the search.
pub fn fit_similarity_from(
    template: &HeadTemplate,
    raw: &TriMesh,
    cameras: Option<&[Camera]>,
    start: Option<&Similarity>,
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    if template.points.len() < 3 {
        return Err(FitError::EmptyTemplate);
    }
    let raw_stats = SurfaceStats::of(raw).ok_or(FitError::EmptyRaw)?;
    // raw → normalised raw, unit radius at the origin.
    let norm = Similarity {
        scale: 1.0 / raw_stats.radius,
        rotation: DMat3::IDENTITY,
        translation: -raw_stats.centre / raw_stats.radius,
    };
    let normalised = TriMesh {
        vertices: raw.vertices.iter().map(|v| norm.apply(v.as_dvec3()).as_vec3()).collect(),
        triangles: raw.triangles.clone(),
        normals: None,
        uvs: None,
    };
    let bvh = RawSurface::new(normalised, opts.normal_smoothing);
    // The coarse search's samples carry the smoothed normals too.
    let samples = template::sample_surface(bvh.mesh(), |_| true, opts.coarse_samples, 0x5eed_c10d);
    let cloud = SurfaceSamples::new(
        samples
            .into_iter()
            .map(|p| (p, bvh.closest(p, f64::INFINITY).normal))
            .filter(|(_, n)| *n != DVec3::ZERO)
            .collect(),
    );
    let prior = cameras.and_then(coarse::camera_prior).map(|(up, c)| (up, norm.apply(c)));

    let tstats = template.stats;
    // Template → normalised raw with the template's centre at `centre` and scale ratio `f`.
    let pose = |rot: DMat3, centre: DVec3, f: f64| {
        let scale = f / tstats.radius;
        Similarity { scale, rotation: rot, translation: centre - scale * (rot * tstats.centre) }
    };
    let mut rotations = Vec::new();
    if let Some((up, _)) = prior {
        rotations.extend(coarse::up_ring(up, 24, 20f64.to_radians()));
    }
    rotations.extend(coarse::rotation_grid(opts.rotations));
    let mut centres = vec![DVec3::ZERO];
    if let Some((_, c)) = prior {
        centres.push(c);
    }
    let starts: Vec<Similarity> =
        centres.iter().flat_map(|&c| rotations.iter().map(move |&r| (r, c))).map(|(r, c)| pose(r, c, 1.0)).collect();
    let framing = cameras.and_then(|c| coarse::Framing::new(c, &norm));
    let ctx = Search { template, bvh: &bvh, cloud: &cloud, opts, tau: opts.inlier_mm * 1e-3, framing };
    if let Some(start) = start {
        // The given pose alone: normalised raw ← raw ← template.
        return ctx.finish(vec![ctx.refine(norm.then_after(start))], &norm);
    }
    let mut finalists = ctx.run(&starts);
    // Unless nearly all the skin is on the mesh already (a clean head), search again at a ladder
    // of smaller scales about the places where the surface is densest at a head's size: raw
    // meshes with much more than the head (shoulders, a backdrop) make the first priors wrong,
    // and hair over much of the skin makes a wrong pose's score close to the right one's.
    if finalists[0].score.on_surface < opts.clean_fraction {
        let samples = template::sample_surface(bvh.mesh(), |_| true, 4000, 0x5eed_b10b);
        let mut starts = Vec::new();
        for &f in &opts.fallback_scales {
            // Mean shift with a ball of 1.2 × the template's radius of gyration at this scale
            // (0.15 m on a real head), which holds the head's surface about its centre.
            let mut cs = coarse::blob_centres(&samples, 1.2 * f, 48, 3);
            if let Some((_, c)) = prior {
                cs.push(c);
            }
            for c in cs {
                starts.extend(rotations.iter().map(|&r| pose(r, c, f)));
            }
        }
        finalists.extend(ctx.run(&starts));
    }
    ctx.finish(finalists, &norm)
}

impl Search<'_> {
    /// The finalists' comparison and the checks: the fit, or why it failed. `norm` takes the raw
    /// mesh to the normalised frame the search ran in.
    fn finish(&self, mut finalists: Vec<Candidate>, norm: &Similarity) -> Result<FitResult, FitError> {
        let (ctx, opts) = (self, self.opts);
        // The finalists distinct in rotation, cheapest first. Under hair and clothes a pose's scale
        // is the last thing ICP gets right (a true pose held 15 % too large by a collar costs more
        // than a wrong one at its own best scale), so each that passes and costs at most
        // [`PROBE_WITHIN`] more than the cheapest is refined in scale and on the face before they are
        // compared; only a pose that passes is, and only by probes that pass: a probe must not turn a
        // rejected fit, a sphere's say, into an accepted one.
        finalists.sort_by(|a, b| a.score.cost.total_cmp(&b.score.cost));
        let mut distinct: Vec<Candidate> = Vec::new();
        for c in finalists {
            if distinct.iter().all(|d| d.t.rotation_angle_to(&c.t) > PICK_APART_DEGREES) {
                distinct.push(c);
            }
        }
        let cheapest = distinct[0].score.cost;
        let mut done: Vec<Candidate> = distinct
            .into_iter()
            .map(|c| {
                if acceptable(&c.score, opts)
                    && c.score.on_surface < opts.clean_fraction
                    && c.score.cost <= cheapest + PROBE_WITHIN
                {
                    ctx.refine_on_face(ctx.probe_scales(c, opts), opts)
                } else {
                    c
                }
            })
            .collect();
        done.sort_by(|a, b| a.score.cost.total_cmp(&b.score.cost));
        let best = done[0];
        let runner_up = done[1..].iter().find(|c| c.t.rotation_angle_to(&best.t) > PICK_APART_DEGREES).copied();
        if let Some(f) = ctx.framing_of(&best.t) {
            if !(opts.framing.0..=opts.framing.1).contains(&f) {
                return Err(FitError::Framing {
                    percent: 100.0 * f,
                    low: 100.0 * opts.framing.0,
                    high: 100.0 * opts.framing.1,
                });
            }
        }
        let score = best.score;
        if !acceptable(&score, opts) {
            return Err(FitError::Poor {
                on: 100.0 * score.on_surface,
                exposed: 100.0 * score.outside,
                inlier_mm: opts.inlier_mm,
                min_on: 100.0 * opts.min_inlier_fraction,
                max_exposed: 100.0 * opts.max_exposed_fraction,
            });
        }
        // canonical → normalised raw → raw; inverted.
        let to_raw = norm.inverse().then_after(&best.t);
        Ok(FitResult {
            to_canonical: to_raw.inverse(),
            residual_mm: score.rms_on_surface * 1e3,
            score,
            runner_up_cost: runner_up.map(|c| c.score.cost),
            shape: None,
            landmarks_mm: None,
            each_landmark_mm: [None; landmarks::NAMES.len()],
        })
    }
}

/// The score ([`score_pose`]) of a given frame: `to_canonical` takes the raw mesh's coordinates to
/// the canonical frame (a fit's, or one known otherwise, as a synthetic capture's true frame).
pub fn score_frame(template: &HeadTemplate, raw: &TriMesh, to_canonical: &Similarity, opts: &FitOptions) -> PoseScore {
    let bvh = RawSurface::new(raw.clone(), opts.normal_smoothing);
    let t = to_canonical.inverse();
    let r = template.stats.radius;
    score_pose(&template.points, &template.normals, &bvh, &t, opts.inlier_mm * 1e-3, r, true)
}

fn acceptable(score: &PoseScore, opts: &FitOptions) -> bool {
    score.on_surface >= opts.min_inlier_fraction && score.outside <= opts.max_exposed_fraction
}

/// The coarse ICP's target: the raw surface's samples for closest points (fast), its mesh for
/// whether something covers a point.
struct CoarseTarget<'a> {
    cloud: &'a SurfaceSamples,
    bvh: &'a RawSurface,
}

impl Target for CoarseTarget<'_> {
    #[inline]
    fn closest(&self, p: DVec3, cap: f64) -> icp::Match {
        self.cloud.closest(p, cap)
    }
    #[inline]
    fn crosses(&self, p: DVec3, dir: DVec3, reach: f64) -> bool {
        self.bvh.crosses(p, dir, reach)
    }
}

/// The fraction of the face's points [`Search::refine_on_face`] keeps in each ICP step (the rest,
/// the farthest: a beard, a fringe over the brow, a hand).
const FACE_KEEP: f64 = 0.7;

/// How much more than the best pose's cost the face's own fit may cost and still replace it.
const FACE_SLACK: f64 = 0.01;

/// How far apart in rotation the poses [`Search::run`] refines are: nearer ones converge to the
/// same pose, and a few turned by a similar amount (the head's back taken for its face, a little
/// off each way) would crowd out a different pose.
const PICK_APART_DEGREES: f64 = 30.0;

/// How much more than the cheapest finalist a finalist of another rotation may cost and still be
/// refined in scale: on a clothed capture's mesh the scale probes took the true pose from 0.547
/// to 0.462, past a wrong one at 0.533.
const PROBE_WITHIN: f64 = 0.1;

/// The scale factors [`Search::probe_scales`] tries about the best pose.
const SCALE_PROBES: [f64; 7] = [0.75, 0.8, 0.85, 0.9, 0.95, 1.05, 1.1];

/// One search over start poses (template → normalised raw).
struct Search<'a> {
    template: &'a HeadTemplate,
    bvh: &'a RawSurface,
    cloud: &'a SurfaceSamples,
    opts: &'a FitOptions,
    /// On-surface distance, template units.
    tau: f64,
    /// How the cameras frame a head (with cameras).
    framing: Option<coarse::Framing>,
}

impl Search<'_> {
    fn cap(&self, t: &Similarity) -> f64 {
        0.5 * t.scale * self.template.stats.radius
    }

    fn cover(&self) -> Option<icp::Cover> {
        Some(icp::Cover { gate: self.tau, reach: score::COVER_DEPTH * self.template.stats.radius })
    }

    /// The score of a pose on the first `points` template points.
    /// A pose whose head the cameras would not frame ([`FitOptions::framing`]) costs one more
    /// than any pose they would.
    fn score(&self, t: &Similarity, points: usize, parallel: bool) -> PoseScore {
        let n = points.clamp(3, self.template.points.len());
        let mut s = score_pose(
            &self.template.points[..n],
            &self.template.normals[..n],
            self.bvh,
            t,
            self.tau,
            self.template.stats.radius,
            parallel,
        );
        if self.framing_of(t).is_some_and(|f| !(self.opts.framing.0..=self.opts.framing.1).contains(&f)) {
            s.cost += 1.0;
        }
        s
    }

    /// The head's apparent diameter (its template's radius of gyration, doubled) as a fraction of
    /// the photos' height, the median over the views (with cameras).
    fn framing_of(&self, t: &Similarity) -> Option<f64> {
        let f = self.framing.as_ref()?;
        f.fraction(t.apply(self.template.stats.centre), t.scale * self.template.stats.radius)
    }

    /// Brief point-to-plane ICP on the surface samples from each start, in parallel, ranked by
    /// score (ties by start, for determinism).
    fn brief(&self, starts: &[(usize, Similarity)], points: usize, iterations: usize) -> Vec<(usize, Candidate)> {
        let n = points.clamp(3, self.template.points.len());
        let (pts, nrm) = (&self.template.points[..n], &self.template.normals[..n]);
        let target = CoarseTarget { cloud: self.cloud, bvh: self.bvh };
        let o = IcpOptions {
            metric: IcpMetric::Plane,
            iterations,
            keep: self.opts.keep,
            tolerance: 0.0,
            parallel: false,
            cover: self.cover(),
        };
        let mut out: Vec<(usize, Candidate)> = starts
            .par_iter()
            .map(|&(i, s)| {
                let r = trimmed_icp(pts, Some(nrm), &target, s, self.cap(&s), &o);
                (i, Candidate { t: r.transform, score: self.score(&r.transform, 2 * n, false) })
            })
            .collect();
        out.sort_by(|a, b| a.1.score.cost.total_cmp(&b.1.score.cost).then(a.0.cmp(&b.0)));
        out
    }

    /// ICP settles at the nearest scale that fits, and under hair and clothes a head of the wrong
    /// size can fit nearly as well as the true one (a clothed torso over the neck held one at 1.15
    /// times the true size). So the best pose is tried again from larger and smaller scales about
    /// its own centre, each as it is and refined on all points; the lowest cost of the probes that
    /// pass ([`acceptable`]) wins.
    fn probe_scales(&self, best: Candidate, opts: &FitOptions) -> Candidate {
        // About the template's centre, and about the skin the pose has on the mesh (the face,
        // mostly): a head of the wrong size that matches the face scales best about the face.
        let cap = self.tau * best.t.scale;
        let on: Vec<DVec3> = self
            .template
            .points
            .iter()
            .filter(|&&p| self.bvh.closest(best.t.apply(p), cap).distance < cap)
            .copied()
            .collect();
        let mut anchors = vec![self.template.stats.centre];
        if !on.is_empty() {
            anchors.push(on.iter().sum::<DVec3>() / on.len() as f64);
        }
        let plane = IcpOptions {
            metric: IcpMetric::Plane,
            iterations: self.opts.refine_iterations,
            keep: self.opts.keep,
            tolerance: 1e-7,
            parallel: false,
            cover: self.cover(),
        };
        let starts: Vec<(DVec3, f64)> = anchors.iter().flat_map(|&c| SCALE_PROBES.map(|k| (c, k))).collect();
        let probes: Vec<Candidate> = starts
            .par_iter()
            .flat_map_iter(|&(c, k)| {
                let m = best.t.apply(c);
                let scale = best.t.scale * k;
                let start =
                    Similarity { scale, rotation: best.t.rotation, translation: m - scale * (best.t.rotation * c) };
                let o = trimmed_icp(
                    &self.template.points,
                    Some(&self.template.normals),
                    self.bvh,
                    start,
                    self.cap(&start),
                    &plane,
                );
                [start, o.transform].map(|t| Candidate { t, score: self.score(&t, usize::MAX, false) })
            })
            .collect();
        probes.into_iter().filter(|p| acceptable(&p.score, opts)).fold(best, |a, b| {
            if b.score.cost < a.score.cost {
                b
            } else {
                a
            }
        })
    }

    /// Under hair and a collar, the face is the one large patch of skin a capture shows, and ICP on
    /// all the skin lets the clothes hold a head a tenth too large (the collar takes the neck, the
    /// trimming drops the face's misfit). So the best pose is refined once more by ICP on the
    /// face's points alone ([`template::FACE_FACING`]), keeping [`FACE_KEEP`] of them; the result
    /// replaces the pose when it passes and costs at most
    /// [`FACE_SLACK`] more on all the points.
    fn refine_on_face(&self, best: Candidate, opts: &FitOptions) -> Candidate {
        let (points, normals) = (&self.template.face_points, &self.template.face_normals);
        if points.len() < 3 {
            return best;
        }
        let o = IcpOptions {
            metric: IcpMetric::Plane,
            iterations: 2 * opts.refine_iterations,
            keep: FACE_KEEP,
            tolerance: 1e-7,
            parallel: true,
            cover: self.cover(),
        };
        let r = trimmed_icp(points, Some(normals), self.bvh, best.t, self.cap(&best.t), &o);
        let c = Candidate { t: r.transform, score: self.score(&r.transform, usize::MAX, true) };
        if acceptable(&c.score, opts) && c.score.cost <= best.score.cost + FACE_SLACK {
            c
        } else {
            best
        }
    }

    /// ICP on all the template's points from `t`, scored.
    fn refine(&self, t: Similarity) -> Candidate {
        let o = IcpOptions {
            metric: IcpMetric::Plane,
            iterations: self.opts.refine_iterations,
            keep: self.opts.keep,
            tolerance: 1e-7,
            parallel: true,
            cover: self.cover(),
        };
        let r = trimmed_icp(&self.template.points, Some(&self.template.normals), self.bvh, t, self.cap(&t), &o);
        Candidate { t: r.transform, score: self.score(&r.transform, usize::MAX, true) }
    }

    /// The pose `t` turned half a turn about the template's up axis (+Z) through its centre.
    fn turned_about_up(&self, t: &Similarity) -> Similarity {
        let c = self.template.stats.centre;
        let rotation = t.rotation * DMat3::from_rotation_z(std::f64::consts::PI);
        Similarity { scale: t.scale, rotation, translation: t.apply(c) - t.scale * (rotation * c) }
    }

    /// Brief ICP from every start, then full ICP from the best few; the best and the best whose
    /// rotation differs from it by more than [`PICK_APART_DEGREES`], each refined on all points,
    /// cheapest first.
    fn run(&self, starts: &[Similarity]) -> Vec<Candidate> {
        let opts = self.opts;
        // Every start briefly on half the points; the most promising quarter on further.
        let all: Vec<(usize, Similarity)> = starts.iter().copied().enumerate().collect();
        let first = self.brief(&all, opts.coarse_points / 2, opts.coarse_iterations / 2);
        let promising: Vec<(usize, Similarity)> =
            first.iter().take(first.len().div_ceil(4).max(opts.refine_best)).map(|(i, c)| (*i, c.t)).collect();
        let coarse = self.brief(&promising, opts.coarse_points, opts.coarse_iterations);
        // The best few, distinct in rotation (near-duplicates converge to the same pose).
        let mut picked: Vec<Candidate> = Vec::new();
        for (_, c) in &coarse {
            if picked.len() >= opts.refine_best.max(1) {
                break;
            }
            if picked.iter().all(|p| p.t.rotation_angle_to(&c.t) > PICK_APART_DEGREES) {
                picked.push(*c);
            }
        }
        // Under hair a head's outline is nearly the same from the front and from the back, and
        // the face is the one patch of skin that tells them apart: the best start's twin, turned
        // half a turn about the template's up axis, is refined too.
        if let Some(b) = picked.first() {
            picked.push(Candidate { t: self.turned_about_up(&b.t), score: b.score });
        }
        // The picked few on the mesh itself with more points, then the best of them on all points.
        let n = (4 * opts.coarse_points).clamp(3, self.template.points.len());
        let plane = IcpOptions {
            metric: IcpMetric::Plane,
            iterations: opts.refine_iterations,
            keep: opts.keep,
            tolerance: 1e-5,
            parallel: false,
            cover: self.cover(),
        };
        let mut refined: Vec<Candidate> = picked
            .par_iter()
            .map(|c| {
                let o = trimmed_icp(
                    &self.template.points[..n],
                    Some(&self.template.normals[..n]),
                    self.bvh,
                    c.t,
                    self.cap(&c.t),
                    &plane,
                );
                Candidate { t: o.transform, score: self.score(&o.transform, usize::MAX, false) }
            })
            .collect();
        refined.sort_by(|a, b| a.score.cost.total_cmp(&b.score.cost));
        // The best, and the best of another rotation (the briefer refinement may leave the true
        // pose short of its minimum, a few degrees off, and behind a wrong one), each on all points.
        let runner_up = refined[1..].iter().find(|c| c.t.rotation_angle_to(&refined[0].t) > PICK_APART_DEGREES);
        let mut finals: Vec<Candidate> = std::iter::once(&refined[0])
            .chain(runner_up)
            .map(|c| {
                let o = trimmed_icp(
                    &self.template.points,
                    Some(&self.template.normals),
                    self.bvh,
                    c.t,
                    self.cap(&c.t),
                    &IcpOptions { tolerance: 1e-7, parallel: true, ..plane },
                );
                let full = Candidate { t: o.transform, score: self.score(&o.transform, usize::MAX, true) };
                if full.score.cost <= c.score.cost {
                    full
                } else {
                    *c
                }
            })
            .collect();
        finals.sort_by(|a, b| a.score.cost.total_cmp(&b.score.cost));
        finals
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::head_fit::capture_fit::Template;

    /// The head under hair 2 cm thick over the top, the sides and the back, down to the nape (the
    /// face and the throat bare): the skin the rest of the fit would hold on to is under it.
    fn under_hair(head: &TriMesh) -> TriMesh {
        let normals = head.compute_vertex_normals();
        let vertices: Vec<glam::Vec3> = head
            .vertices
            .iter()
            .zip(&normals)
            .map(|(&v, &n)| if v.z > -0.1 && (v.y > -0.02 || v.x.abs() > 0.06) { v + 0.02 * n } else { v })
            .collect();
        TriMesh::new(vertices, head.triangles.clone(), None, None).unwrap()
    }

    /// A runner-up within [`CLOSE_CALL`] of the winner's cost is a warning that names both costs;
    /// a clear win, or no runner-up, is none.
    #[test]
    fn a_close_runner_up_is_a_warning() {
        let score = PoseScore { cost: 0.5, on_surface: 0.5, inside: 0.3, outside: 0.2, rms_on_surface: 0.001 };
        let fit = |r: Option<f64>| FitResult {
            to_canonical: Similarity { scale: 1.0, rotation: DMat3::IDENTITY, translation: DVec3::ZERO },
            residual_mm: 1.0,
            score,
            runner_up_cost: r,
            shape: None,
            landmarks_mm: None,
            each_landmark_mm: [None; landmarks::NAMES.len()],
        };
        let w = fit(Some(0.52)).close_call().expect("a warning");
        assert!(w.contains("0.520") && w.contains("0.500") && w.contains("fitted_head.ply"), "{w}");
        assert!(w.contains("place landmarks (landmarks.json"), "{w}");
        assert!(fit(Some(0.56)).close_call().is_none());
        assert!(fit(None).close_call().is_none());
    }

    /// The twin [`Search::run`] refines beside its best start: the same head turned half a turn about
    /// its own up axis, through its own centre (the face where the back of the head was), at the
    /// same scale; turned twice, the start again.
    #[test]
    fn the_twin_of_a_pose_has_its_face_at_the_back() {
        let t = Template::bundled();
        let template = HeadTemplate::new(&t.head, Some(&t.scalp), 500, 7).unwrap();
        let bvh = RawSurface::new(t.head.clone(), 0);
        let cloud = SurfaceSamples::new(vec![(DVec3::ZERO, DVec3::Z)]);
        let opts = FitOptions::default();
        let ctx = Search { template: &template, bvh: &bvh, cloud: &cloud, opts: &opts, tau: 0.005, framing: None };
        let pose = Similarity {
            scale: 3.5,
            rotation: DMat3::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 1.1),
            translation: DVec3::new(0.3, -0.2, 1.7),
        };
        let twin = ctx.turned_about_up(&pose);
        let c = template.stats.centre;
        assert!(twin.apply(c).distance(pose.apply(c)) < 1e-12);
        assert!((twin.scale - pose.scale).abs() < 1e-12);
        assert!((twin.rotation_angle_to(&pose) - 180.0).abs() < 1e-6);
        // The up axis stays; the face (−Y in the template) goes where the back (+Y) was.
        let up = pose.rotation * DVec3::Z;
        assert!((twin.rotation * DVec3::Z).distance(up) < 1e-12);
        let nose = DVec3::new(0.0, -0.1, 0.03);
        let back = DVec3::new(2.0 * c.x - nose.x, 2.0 * c.y - nose.y, nose.z);
        assert!(twin.apply(nose).distance(pose.apply(back)) < 1e-12);
        let again = ctx.turned_about_up(&twin);
        assert!(again.rotation_angle_to(&pose) < 1e-6 && again.translation.distance(pose.translation) < 1e-12);
    }

    /// The bundled head under hair with a collar (a closed box from the shoulders to the jaw) in the
    /// canonical frame, and a start 12 % too large about the face and turned 3°: the refinement on
    /// the face brings it back to the true pose (the identity).
    #[test]
    fn the_face_alone_brings_a_head_held_by_a_collar_back_to_its_size() {
        let t = Template::bundled();
        let template = HeadTemplate::new(&t.head, Some(&t.scalp), 2000, 7).unwrap();
        assert!(template.face_points.len() == 2000);
        let collar = {
            let (lo, hi) = (glam::Vec3::new(-0.075, -0.035, -0.17), glam::Vec3::new(0.075, 0.12, -0.09));
            // The eight corners, twelve triangles, outward.
            let c = |i: usize| {
                glam::Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            };
            let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
            let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
            TriMesh::new((0..8).map(c).collect(), triangles, None, None).unwrap()
        };
        let hair = under_hair(&t.head);
        let mut vertices = hair.vertices.clone();
        let base = vertices.len() as u32;
        vertices.extend_from_slice(&collar.vertices);
        let mut triangles = hair.triangles.clone();
        triangles.extend(collar.triangles.iter().map(|tr| tr.map(|i| i + base)));
        let raw = TriMesh::new(vertices, triangles, None, None).unwrap();
        let bvh = RawSurface::new(raw, 0);
        let cloud = SurfaceSamples::new(vec![(DVec3::ZERO, DVec3::Z)]);
        let opts = FitOptions::default();
        let ctx = Search { template: &template, bvh: &bvh, cloud: &cloud, opts: &opts, tau: 0.005, framing: None };
        let truth = Similarity { scale: 1.0, rotation: DMat3::IDENTITY, translation: DVec3::ZERO };
        // About the nose (the face's front), larger and turned about the vertical.
        let nose = DVec3::new(0.0, -0.1, 0.03);
        let (scale, rotation) = (1.12, DMat3::from_rotation_z(3f64.to_radians()));
        let start = Similarity { scale, rotation, translation: nose - scale * (rotation * nose) };
        let best = Candidate { t: start, score: ctx.score(&start, usize::MAX, true) };
        let refined = ctx.refine_on_face(best, &opts);
        let (angle, ratio) = (refined.t.rotation_angle_to(&truth), refined.t.scale);
        let moved = refined.t.apply(template.stats.centre).distance(template.stats.centre);
        assert!(angle < 0.3 && (ratio - 1.0).abs() < 0.005 && moved < 1e-3, "{angle}° {ratio} {moved} m");
        assert!(refined.score.cost < best.score.cost);
    }
}
