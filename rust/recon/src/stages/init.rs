//! Stage `init`: the initial strands. Roots on the scalp ([`crate::roots`]); with curls
//! ([`crate::curl_choice`]) the points turned into ringlet axes; the hair volume's flow
//! ([`crate::laplace`]) from the directed points (those beside a parting cleared); guides grown
//! through it and smoothed, children blended from them ([`crate::grow`]); helices swept about them
//! with curls; the children cut where a view sees no hair ([`crate::hull`]). The ablation
//! `strand_init = false` gives straight strands along the scalp normal instead.
//!
//! Saves `init_guides.hair`, `init_strands.hair` and `init.json` (the curl, which DR needs);
//! along the way `roots.ply` (the guides' roots), `flow.bin` and, with curls, `points_axes.ply`
//! (the points moved onto their ringlets' axes, which the flow grew from). The guides stay whole
//! (DR blends the children from them); the children are cut by the hull.

use hairrecon_core::formats::read_strands;
use hairrecon_core::spatial::PointIndex;
use hairrecon_core::Bvh;
use hairrecon_core::StrandSet;
use serde::{Deserialize, Serialize};

use crate::config::{ReconstructConfig, Stage};
use crate::curl::{growth_axes, onto_axes, sweep_helices, Curl, CurlMode};
use crate::curl_choice::{choose, CurlChoiceReport};
use crate::dr::DrTargets;
use crate::error::ReconError;
use crate::grow::{grow_guides, interpolate_children, smooth_guides, straight_strands, GrowStats, SmoothStats};
use crate::hull::{TrimStats, VisualHull};
use crate::laplace::{solve_flow, FlowField, LaplaceStats};
use crate::orient2d::OrientationMap;
use crate::oriented_points::OrientedPoints;
use crate::parting::clear_points;
use crate::raw_mesh::surface::smoothed;
use crate::roots::{sample_roots, Roots, Scalp};
use crate::stages::sanity::check_strands;
use crate::stages::{need, write_json, Context};

/// What the init stage measured along the way.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct InitStats {
    /// Directed points dropped beside partings before the flow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parting_points_cleared: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub laplace: Option<LaplaceStats>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grow: Option<GrowStats>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth: Option<SmoothStats>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curl_auto: Option<CurlChoiceReport>,
    /// Views of the visual hull (`None`: no trim asked).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hull_views: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hull_trim: Option<TrimStats>,
    /// Set when the hull would have cut too much and the children were kept whole.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hull_warning: Option<String>,
}

/// The curl of the strands (what `init.json` holds).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct InitInfo {
    /// The curl the helices were swept with (`None`: no curls).
    pub curl: Option<Curl>,
}

/// The initial strands.
#[derive(Debug, Clone)]
pub struct InitOut {
    pub guides: StrandSet,
    /// The children, cut by the visual hull.
    pub children: StrandSet,
    pub info: InitInfo,
    pub stats: InitStats,
    /// With curls: the hung ringlet axes where the cameras saw the hair (before the points moved
    /// onto them), for scoring; not saved.
    pub seen_axes: Option<OrientedPoints>,
}

const GUIDES: &str = "init_guides.hair";
const CHILDREN: &str = "init_strands.hair";
const INFO: &str = "init.json";

/// Growth from some directed points: the flow, the guides, the children and their statistics.
struct Grown {
    flow: FlowField,
    guides: StrandSet,
    children: StrandSet,
    cleared: Option<usize>,
    laplace: LaplaceStats,
    grow: GrowStats,
    smooth: SmoothStats,
}

fn grow_from(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    outer: &Bvh,
    scalp: &Scalp,
    roots: (&Roots, &Roots),
    pts: &OrientedPoints,
) -> Result<Grown, ReconError> {
    // Beside partings the points above the skin go: the partings decide the hair there.
    let cleared = scalp.partings().map(|p| clear_points(pts, scalp, p, cfg.parting.clear_height));
    let pts = cleared.as_ref().map_or(pts, |c| &c.0);
    let (flow, laplace) = solve_flow(outer, ctx.inner()?, scalp, pts, &cfg.laplace, ctx.progress)?;
    let trace = (cfg.grow.trace_radius > 0.0).then(|| PointIndex::new(pts.positions.clone(), pts.directions.clone()));
    let (guides, grow) = grow_guides(&flow, trace.as_ref(), roots.0, &cfg.grow, ctx.progress)?;
    let (guides, smooth) = smooth_guides(&guides, trace.as_ref(), Some(&flow), &cfg.grow);
    let children = interpolate_children(&guides, roots.1, Some(&flow), &cfg.grow, ctx.progress)?;
    Ok(Grown { flow, guides, children, cleared: cleared.map(|c| c.1), laplace, grow, smooth })
}

/// The initial strands from the directed points; `maps` serve the curl choice's misfit.
pub fn run(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    directed: &OrientedPoints,
    scalp: &Scalp,
    maps: &[OrientationMap],
) -> Result<InitOut, ReconError> {
    let progress = ctx.progress;
    progress.check()?;
    progress.update("init", 0.0, "roots");
    let scalp_err = |source| ReconError::Scalp { path: ctx.capture.scalp_mesh.clone().unwrap_or_default(), source };
    let guide_roots = sample_roots(scalp, cfg.guides.max(1), cfg.seed).map_err(scalp_err)?;
    let child_roots = sample_roots(scalp, cfg.children.max(1), cfg.seed.wrapping_add(1)).map_err(scalp_err)?;
    guide_roots.to_points().save_ply(&ctx.output("roots.ply"))?;
    let roots = (&guide_roots, &child_roots);
    // The flow's outer surface (see `LaplaceParams::outer_smoothing`): built once for every growth
    // of this stage, and dropped with it.
    let smoothed = if cfg.strand_init && cfg.laplace.outer_smoothing > 0 {
        progress.update("init", 0.0, "smoothing the raw mesh");
        Some(Bvh::with_fold_vote(smoothed(ctx.raw()?.mesh(), cfg.laplace.outer_smoothing)))
    } else {
        None
    };
    let outer = match &smoothed {
        Some(b) => b,
        None => ctx.raw()?,
    };
    let mut stats = InitStats::default();
    let mut seen_axes = None;
    let (guides, children, curl) = if cfg.strand_init {
        let curl = match cfg.curl {
            CurlMode::Off => None,
            CurlMode::Fixed(c) | CurlMode::Fine(c) => Some(c),
            CurlMode::Auto => {
                let targets = || -> Result<DrTargets, ReconError> {
                    Ok(DrTargets::from_capture(ctx.capture, maps, Some(ctx.inner()?), progress)?)
                };
                let grow_children = |pts: &OrientedPoints| Ok(grow_from(ctx, cfg, outer, scalp, roots, pts)?.children);
                let (c, report) = choose(directed, ctx.raw()?.mesh(), cfg, &targets, &grow_children, progress)?;
                stats.curl_auto = Some(report);
                c
            }
        };
        // One growth: from the points' own directions, or with curls along the ringlet axes.
        let axes = match curl {
            None => None,
            Some(c) => {
                progress.update("init", 0.7, &format!("curls: growing along the ringlets ({c:?})"));
                let co = &cfg.curl_options;
                let fine = matches!(cfg.curl, CurlMode::Fine(_));
                let mut axes = growth_axes(directed, ctx.raw()?.mesh(), &c, fine, co).ok_or(ReconError::CurlGrid)?;
                seen_axes = Some(axes.clone());
                if co.onto_axes {
                    onto_axes(directed, &mut axes, &c);
                }
                axes.save_ply(&ctx.output("points_axes.ply"))?;
                Some(axes)
            }
        };
        let g = grow_from(ctx, cfg, outer, scalp, roots, axes.as_ref().unwrap_or(directed))?;
        g.flow.save(&ctx.output("flow.bin"))?;
        (stats.parting_points_cleared, stats.laplace, stats.grow, stats.smooth) =
            (g.cleared, Some(g.laplace), Some(g.grow), Some(g.smooth));
        match curl {
            None => (g.guides, g.children, None),
            Some(c) => (
                sweep_helices(&g.guides, &c, &cfg.curl_options, cfg.seed)?,
                sweep_helices(&g.children, &c, &cfg.curl_options, cfg.seed.wrapping_add(1))?,
                Some(c),
            ),
        }
    } else {
        let seg = (cfg.straight_length / cfg.grow.step).ceil() as usize;
        (
            straight_strands(&guide_roots, cfg.straight_length, seg),
            straight_strands(&child_roots, cfg.straight_length, seg),
            None,
        )
    };
    progress.check()?;
    let children = if cfg.hull_trim { trim(ctx, cfg, scalp, children, &mut stats)? } else { children };
    let raw_box = ctx.raw_bbox()?;
    check_strands(Stage::Init, "guides", &guides, raw_box)?;
    check_strands(Stage::Init, "strands", &children, raw_box)?;
    Ok(InitOut { guides, children, info: InitInfo { curl }, stats, seen_axes })
}

/// The children cut at the visual hull, unless it would cut too much (then a warning). DR's
/// result is not cut again: its points outside the masks still match thin hair there.
fn trim(
    ctx: &Context<'_>,
    cfg: &ReconstructConfig,
    scalp: &Scalp,
    children: StrandSet,
    stats: &mut InitStats,
) -> Result<StrandSet, ReconError> {
    let hull = VisualHull::from_capture(ctx.capture, Some(ctx.inner()?), cfg.hull, "init", ctx.progress)?
        .map(|h| h.with_scalp(Some(scalp.bvh().clone())));
    stats.hull_views = Some(hull.as_ref().map_or(0, |h| h.num_views()));
    Ok(match hull.as_ref().map(|h| h.trim_checked(&children)) {
        Some(Ok((set, trim))) => {
            stats.hull_trim = Some(trim);
            set
        }
        Some(Err(trim)) => {
            let msg = format!(
                "the visual hull would cut {:.0}% of the strand points: the masks or the cameras disagree with the \
                 reconstruction, so the strands are kept whole (check the masks; --no-hull-trim silences this)",
                100.0 * trim.points_removed as f64 / trim.points.max(1) as f64
            );
            ctx.progress.update("init", 1.0, &msg);
            stats.hull_warning = Some(msg);
            children
        }
        None => children,
    })
}

impl InitOut {
    pub fn save(&self, ctx: &Context<'_>) -> Result<(), ReconError> {
        // In the frame of the capture's files, as the final strands are.
        ctx.write_result(GUIDES, &self.guides)?;
        ctx.write_result(CHILDREN, &self.children)?;
        write_json(&ctx.output(INFO), &self.info)
    }

    pub fn load(ctx: &Context<'_>, from: Stage) -> Result<Self, ReconError> {
        let info_path = need(ctx, from, Stage::Init, INFO)?;
        let read = |name| -> Result<StrandSet, ReconError> {
            let s = read_strands(need(ctx, from, Stage::Init, name)?)?;
            Ok(ctx.capture.from_file_frame(&s).map_err(hairrecon_core::FormatError::from)?)
        };
        let (guides, children) = (read(GUIDES)?, read(CHILDREN)?);
        let bad = |msg: String| ReconError::StageFile { stage: Stage::Init, path: info_path.clone(), msg };
        let text = std::fs::read_to_string(&info_path).map_err(|e| bad(e.to_string()))?;
        let info: InitInfo = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        Ok(Self { guides, children, info, stats: InitStats::default(), seen_axes: None })
    }
}
