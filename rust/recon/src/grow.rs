//! Stage 5b: guide strands grown through the flow, and child strands interpolated from them.
//!
//! In: the [`FlowField`] of [`crate::laplace`] and [`Roots`] on the scalp (guides and children).
//! Out: guide and child [`StrandSet`]s, root first, saved as `guides.hair` and `strands.hair`.
//!
//! Follows Dr.Hair's strand initialization (`docs/method.md` §3). A guide starts at its root along
//! S(p_s) and follows the unit field by midpoint (RK2) steps of `step` (going straight on through
//! gaps of up to `max_gap` where the field is missing); the field is read by
//! trilinear interpolation and a step never turns back on the last one (the field's sign is kept
//! continuous). At the outer surface (the raw mesh) a step that leaves it is projected back onto
//! it; growth ends there when the flow points out of the surface (cosine above `exit_cos`). Growth
//! also stops when the strand leaves the hair volume (more than `outer_margin`
//! outside the raw mesh, or into a voxel that is not hair), when the field vanishes, or when its
//! budget of steps (`max_length × grow_budget` of arc) runs out. Points that enter the head
//! are pushed back out along the gradient of its distance. A root that the raw
//! mesh's sign puts outside the hair starts free of the outer surface ([`GrowParams::root_gap`]).
//! Guides along which the directed points
//! agree (straight hair) are then smoothed along their length ([`smooth_guides`]): their wiggles
//! are tracing noise there, while on wavy and curly hair they carry the waves. Every guide is then
//! cut at `max_length` of arc. A child takes its `k` nearest guide
//! roots (among the guides at least `min_guide_fraction` of the median guide long) with
//! inverse-square-distance weights and follows their mean segment vectors step by step
//! (a guide that has ended drops out of the mean), so children keep their guides' shape with their
//! own root; its length is the weighted mean of the guides' lengths.
//!
//! The ablation ("w/o strand init.") is [`straight_strands`]: straight lines along the scalp
//! normal, all of one length.

use glam::Vec3;
use hairrecon_core::StrandSet;
use rayon::prelude::*;

use crate::laplace::FlowField;
use crate::metrics::PointIndex;
use crate::progress::{Cancelled, Progress};
use crate::roots::Roots;

/// How a child blends the guides, shared by [`interpolate_children`] and the DR's child map (so
/// that both pick the same guides with the same weights); see [`GuideBlend`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BlendParams {
    /// Guides per child. 2 on measurement (paper preset, `examples/init_stage ... children=50000
    /// k=K`, undirected F1 at 2 mm/20°): curly k = 1/2/3/4 gave 33.7/50.7/49.5/47.9 (one guide
    /// ends children wherever it ends; more guides blend curls of different phase into zig-zags),
    /// straight k = 2/4 gave 79.9/79.8 (1 mm/10°: 54.5/56.2).
    pub k: usize,
    /// Children blend only guides at least this fraction of the median guide's length (0: every
    /// guide): a guide that ended at its root, where the volume has no flow, would end its children
    /// there too. Relative, so that short styles keep their guides. Measured (`examples/init_stage
    /// ... children=50000 min_guide_fraction=F`, undirected F1 at 2 mm/20°): paper curly 50.7 → 52.8
    /// at 0.3 (recall 53.7 → 60.3; absolute minima of 2, 8, 15 cm gave 52.0, 52.6, 53.1), paper
    /// straight 79.9 → 79.8, the sparse test preset 56.2 → 54.3.
    pub min_guide_fraction: f32,
    /// Partings: where the `k` guides a child blends leave the scalp in nearly opposite directions
    /// (a parting or a crown whorl between them), the mean of their segment vectors nearly cancels
    /// and the child crumples at its root (segments 0.02 mm long for the first centimetres, which no
    /// resampling evens out). A child whose blend of the guides' leaving directions (unit chords
    /// over their first [`PARTING_ARC`], with the child's weights) is shorter than `parting_reach`
    /// follows its nearest guide alone (0: off). Measured in [`GuideBlend`].
    pub parting_reach: f32,
}

impl Default for BlendParams {
    fn default() -> Self {
        Self { k: 2, min_guide_fraction: 0.3, parting_reach: 0.5 }
    }
}

/// Parameters of growing.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GrowParams {
    /// Integration step, metres.
    pub step: f32,
    /// The longest guide, metres of arc after smoothing ([`smooth_guides`] cuts the guides there).
    pub max_length: f32,
    /// Growth takes up to `max_length × grow_budget` of steps. Where a strand slides along the
    /// outer surface its steps zig-zag (the field there points mostly out of the surface, and what
    /// is left of it along the surface is noise), and smoothing takes that arc back: on the demo's
    /// capture 86% of the guides' steps lay on the outer surface, turning 36° per step, and with a
    /// budget of `max_length` alone a third of the guides ended at the shoulders (1.0: the old
    /// rule, the budget is the length).
    pub grow_budget: f32,
    /// Growth stops this far outside the raw mesh, metres.
    pub outer_margin: f32,
    /// Points are kept at least this far outside the head, metres.
    pub head_clearance: f32,
    /// How children blend the guides (shared with the DR's child map).
    pub blend: BlendParams,
    /// Growth goes straight on through up to this length of non-hair voxels, metres.
    pub max_gap: f32,
    /// At the outer surface, growth ends when the flow points out of it with a cosine above this;
    /// 1 (the default) turns the rule off: the strand slides along the surface instead, and ends
    /// only more than `outer_margin` outside it. Measured on the paper preset (straight), ending
    /// at 0.99 cut the guides to 27 cm mean against the ground truth's 45 cm.
    pub exit_cos: f32,
    /// Over the first this many metres of a strand the exit rule does not apply: the strand slides
    /// along the outer surface instead. Near the scalp the hair layer is a voxel or two thick and
    /// the flow there still leans out along S(p_s), while real hair turns to lie along the head.
    pub exit_after: f32,
    /// A strand that comes back within `loop_distance` of a point of its own at least `loop_window`
    /// metres of arc earlier circles in a vortex of the field: growth ends and the circle is cut
    /// off. A helical curl never comes back closer than its pitch (about a centimetre).
    pub loop_window: f32,
    pub loop_distance: f32,
    /// A strand caught in a vortex does not end there: the circle is cut and the strand leaves it
    /// under gravity (the field blended with straight down, `escape_gravity` of the way) for
    /// `escape_length` metres, then follows the field again; at most `max_escapes` times.
    pub escape_length: f32,
    pub escape_gravity: f32,
    pub max_escapes: u32,
    /// Tracing: within this radius of the directed 3D points (metres; 0: off), a strand also
    /// follows them: their mean direction (of those going its way) and a pull toward their centre,
    /// blended with the field by weight `w / (w + trace_weight)`. The field is smooth at the scale
    /// of its voxels; the points carry the curls. Measured (`examples/init_stage.rs … children=10000
    /// gt_every=5`, paper preset, undirected F1 at 2 mm/20°): off → on: straight 67.3 → 71.3, wavy
    /// 30.1 → 31.2, curly 22.8 → 23.8.
    pub trace_radius: f32,
    pub trace_weight: f32,
    /// Tracing: the pull toward the points' centre, per radius of offset.
    pub trace_pull: f32,
    /// Tracing: points whose tangent is within `acos(trace_min_cos)` of the strand's last step
    /// count, weighted by `cos^trace_power` (and by their distance). More selective tracing
    /// (0.7, power 8) lowered the paper straight proxy (see [`GuideBlend`]) from 74.6 to 71.7.
    pub trace_min_cos: f32,
    pub trace_power: f32,
    /// The largest turn per step, radians: no kinks for the simulation or the DR's segment evening.
    pub max_turn: f32,
    /// Smoothing of straight guides: a guide is smoothed along its length (its segment vectors by a
    /// Gaussian of `smooth_sigma` metres, the root kept) when the directed points along it are
    /// coherent: their mean angle to their local mean direction (within `trace_radius`) is at most
    /// `smooth_angles_deg[0]`; not at all from `smooth_angles_deg[1]` on, in between by a share of
    /// σ. Along the guides of the paper preset the points agree to a median 11° on straight hair,
    /// where the guides' wiggles are tracing noise, and 18° on wavy and curly hair, where they carry
    /// the waves and curls and smoothing them cost F1. Measured in [`smooth_guides`]. 0: off.
    pub smooth_sigma: f32,
    pub smooth_angles_deg: [f32; 2],
    /// Free starts on straight hair (0: off). Depth fusion puts the raw mesh's sign wrong in
    /// places (surface pieces inside the hair whose walls face inward), and a root whose nearest
    /// surface says it is more than `outer_margin` outside was projected onto that surface at its
    /// first step: at the nape of the straight paper capture the guides jumped 2–4 cm backward and
    /// their first 3 cm pointed back and out where the hair falls straight down (1% precise at
    /// 2 mm/20°, `examples/metric_by_arc` with `BY_ROOT=1`). The scalp is under the hair, so such a
    /// root's sign is doubted: its strand ignores the outer surface until it first gets inside or
    /// has grown `root_gap` metres, going straight on through missing field meanwhile. Measured
    /// (`examples/init_stage CAPTURE DIR OUT children=10000 gt_every=5`, undirected F1 at
    /// 2 mm/20°): straight 74.6 → 77.2 (0.05 m: 74.4; 0.3 m: 77.2); curly, grown then from its
    /// incoherent points, 31.2 → 26.7 and wavy 38.0 → 39.5 (session 13), so until session 39 it
    /// applied only where the median guide's points were coherent (straight hair, and curly hair
    /// grown along its ringlet axes since session 22). Wavy hair's points are not (18° against
    /// straight's 11°), and without free starts its guides at the back and sides left the scalp
    /// 47–53° off the ground truth's, level where it falls (session 39, docs/reconstruction.md,
    /// "Wavy hair's roots"); free starts now apply on every style.
    pub root_gap: f32,
    /// Gravity: beyond `climb_after` metres of arc, a step rises at most `max_climb` (the sine of
    /// its angle above the horizontal; 1: off), both the direction the field and the points give
    /// and the step that the outer surface's projection makes of it. Hair under gravity does not
    /// climb once it has left the scalp, but the strands did: on the paper preset 3–6% (straight),
    /// 10–11% (wavy) and 11–13% (curly) of their steps beyond 6 cm went up (the ground truth's:
    /// straight and wavy 0%, curly 1–9%, the helices; our directed points: 0% below 6 cm from the
    /// top), nearly all of them where the outer surface's projection pushed them (the raw mesh's
    /// surface pieces inside the hair), and a climbing step is one that matches the ground truth
    /// only reversed. Measured at full size (`examples/init_stage bench_out/paper_STYLE_brown
    /// DIR OUT children=50000 [max_climb=1]` on session 13's direction outputs; undirected /
    /// directed F1 at 2 mm/20°, off → on): straight 84.5 / 82.1 → 85.9 / 85.8, wavy 53.5 / 47.4 →
    /// 55.3 / 54.7, curly 51.9 / 40.8 → 49.1 / 44.5 (the curls' climbing steps matched reversed
    /// helices); test preset 56.9 / 53.7 → 60.0 / 60.0. Proxy (`children=10000 gt_every=5`),
    /// `climb_after` 1 / 3 / 6 cm: straight 77.9 / 78.3 / 78.4, wavy 39.9 / 39.7 / 39.4, curly
    /// 28.8 / 29.3 / 29.6 (off: 77.2, 38.0, 31.2; a first form of the rule, which kept a vertical
    /// step vertical: curly 29.2 as it is now); `max_climb` 0.1 / 0.2 / 0.3 at 1 cm: wavy
    /// 39.9 / 38.5 / 36.8, curly 29.2 / – / 31.3. Clamping the direction alone, not the projected
    /// step, left 7–9% of the curly steps climbing.
    pub max_climb: f32,
    pub climb_after: f32,
    /// Points trump the field: where the traced points' weight (see [`GrowParams::trace_radius`])
    /// is at least this, the strand follows them alone, with no field blend, no slide along the
    /// outer surface (it may end up to 1 cm outside it) and no climb limit; 0 (the default): off.
    /// Through ground-truth points everywhere (`examples/oracle_points … all`) the growth's rules
    /// cost most of the guides' precision on curly (`examples/guide_select`, pooled undirected
    /// precision at 2 mm/20°: defaults 63.9%, `trace_trumps=0.3` with `trace_pull=0,trace_power=4,
    /// trace_min_cos=0.5,trace_radius=0.002,step=0.001` 77.1%, `scripts/trace_points.py`, the
    /// points alone, 87.6% over shorter strands). Through our own points (session 15's curly run)
    /// `trace_trumps=1,max_climb=1` makes the guides 51.0 → 62.9% precise, but they keep to the
    /// visible surface (87% of their points within 2 mm of a directed point) and the children
    /// lose recall (`examples/init_stage … children=50000`, undirected P / R / F1 at 2 mm/20°:
    /// 43.3 / 56.6 / 49.1 → 50.7 / 42.8 / 46.4). Half the children from each set (the field's
    /// cover the volume, the traced ones the visible curls) score 51.8 with `loop_window=0`, and
    /// wavy 55.3 → 57.0, but directed F1 falls (curly 44.5 → 43.1): docs/curly-study.md, session 18.
    pub trace_trumps: f32,
}

impl Default for GrowParams {
    fn default() -> Self {
        Self {
            step: 0.002,
            max_length: 0.6,
            grow_budget: 1.5,
            outer_margin: 0.003,
            head_clearance: 0.001,
            blend: BlendParams::default(),
            max_gap: 0.02,
            exit_cos: 1.0,
            exit_after: 0.0,
            loop_window: 0.05,
            loop_distance: 0.004,
            escape_length: 0.05,
            escape_gravity: 0.8,
            max_escapes: 8,
            trace_radius: 0.0025,
            trace_weight: 0.05,
            trace_pull: 1.5,
            trace_min_cos: 0.3,
            trace_power: 2.0,
            max_turn: 40f32.to_radians(),
            smooth_sigma: 0.02,
            smooth_angles_deg: [12.0, 14.5],
            root_gap: 0.15,
            max_climb: 0.0,
            climb_after: 0.03,
            trace_trumps: 0.0,
        }
    }
}

/// Unit gradient of a per-voxel distance at `p` (central differences, half a voxel apart).
fn gradient(flow: &FlowField, values: &[f32], p: Vec3) -> Vec3 {
    let h = 0.5 * flow.grid.voxel;
    let d = flow.grid.trilinear(values, p).unwrap_or(0.0);
    let g = |a: Vec3| flow.grid.trilinear(values, p + a).unwrap_or(d);
    Vec3::new(g(Vec3::X * h) - g(-Vec3::X * h), g(Vec3::Y * h) - g(-Vec3::Y * h), g(Vec3::Z * h) - g(-Vec3::Z * h))
        .normalize_or_zero()
}

fn push_out(flow: &FlowField, p: Vec3, clearance: f32) -> Vec3 {
    let Some(d) = flow.grid.trilinear(&flow.sd_inner, p) else { return p };
    if d >= clearance {
        return p;
    }
    let h = 0.5 * flow.grid.voxel;
    let g = |a: Vec3| flow.grid.trilinear(&flow.sd_inner, p + a).unwrap_or(d);
    let grad =
        Vec3::new(g(Vec3::X * h) - g(-Vec3::X * h), g(Vec3::Y * h) - g(-Vec3::Y * h), g(Vec3::Z * h) - g(-Vec3::Z * h))
            .normalize_or_zero();
    p + grad * (clearance - d)
}

/// Why a guide stopped growing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// More than `outer_margin` outside the raw mesh.
    Outside,
    /// In voxels that are not hair, or where the field vanishes, for longer than `max_gap`.
    NotHair,
    /// Out of the grid.
    Grid,
    MaxLength,
    /// Circling without progress (see [`GrowParams::loop_window`]).
    Loop,
}

/// How the guides stopped.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GrowStats {
    pub outside: u64,
    pub not_hair: u64,
    pub grid: u64,
    pub max_length: u64,
    pub loops: u64,
    pub mean_length: f64,
    /// Guides grown with a free start (see [`GrowParams::root_gap`]).
    #[serde(default)]
    pub free_starts: u64,
}

/// Whether `root` reads more than `outer_margin` outside the raw mesh (see [`GrowParams::root_gap`]).
fn reads_outside(flow: &FlowField, root: Vec3, params: &GrowParams) -> bool {
    flow.grid.trilinear(&flow.sd_outer, root).is_some_and(|d| d > params.outer_margin)
}

/// The radius within which [`guide_coherence`] looks at the points: the tracing radius, or 2.5 mm
/// when tracing is off.
fn coherence_radius(params: &GrowParams) -> f32 {
    if params.trace_radius > 0.0 {
        params.trace_radius
    } else {
        0.0025
    }
}

/// `d` turned back toward `prev` so that the angle between them is at most `max_turn`.
fn limit_turn(prev: Vec3, d: Vec3, max_turn: f32) -> Vec3 {
    let c = prev.dot(d).clamp(-1.0, 1.0);
    if c >= max_turn.cos() {
        return d;
    }
    let axis = prev.cross(d);
    let axis = if axis.length_squared() > 1e-12 { axis.normalize() } else { prev.any_orthonormal_vector() };
    glam::Quat::from_axis_angle(axis, max_turn) * prev
}

/// `v` with its rise above the horizontal limited to `max_climb` of its length (its horizontal
/// direction kept, or `fallback`'s if `v` is vertical; unchanged if both are).
fn limit_climb(v: Vec3, max_climb: f32, fallback: Vec3) -> Vec3 {
    let l = v.length();
    if l <= 0.0 || v.z <= max_climb * l {
        return v;
    }
    let h = Vec3::new(v.x, v.y, 0.0);
    let h = if h.length_squared() > 1e-12 * l * l { h } else { Vec3::new(fallback.x, fallback.y, 0.0) };
    let Some(h) = h.try_normalize() else { return v };
    (h * (1.0 - max_climb * max_climb).max(0.0).sqrt() + Vec3::Z * max_climb) * l
}

/// The direction the directed points near `p` give a strand going `prev`, and their weight.
fn traced(points: &PointIndex, p: Vec3, prev: Vec3, params: &GrowParams) -> Option<(Vec3, f32)> {
    let r = params.trace_radius;
    let (mut acc, mut cen, mut ws) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
    for i in points.within(p, r) {
        let t = points.tangents[i];
        let c = t.dot(prev);
        if c <= params.trace_min_cos {
            continue;
        }
        let off = points.points[i] - p;
        // c * c at the default power keeps the guides bit-identical to before the parameter existed.
        let cw = if params.trace_power == 2.0 { c * c } else { c.powf(params.trace_power) };
        let w = cw * (1.0 - off.length_squared() / (r * r)).max(0.0);
        acc += t * w;
        cen += off * w;
        ws += w;
    }
    if ws <= 1e-6 {
        return None;
    }
    let d = (acc / ws).normalize_or_zero() + (cen / ws) * (params.trace_pull / r);
    Some((d.normalize_or_zero(), ws))
}

/// Grows one guide from `root` with start direction `start`; `trace`: the directed 3D points to
/// follow besides the field (see [`GrowParams::trace_radius`]).
pub fn grow_one(
    flow: &FlowField,
    trace: Option<&PointIndex>,
    root: Vec3,
    start: Vec3,
    params: &GrowParams,
) -> (Vec<Vec3>, Stop) {
    let mut pts = vec![root];
    let mut p = root;
    let mut prev = start.normalize_or(Vec3::Z);
    let dir_at = |q: Vec3, prev: Vec3| -> Option<Vec3> {
        let v = flow.grid.voxel_of(q)?;
        if flow.label[v] == 0 {
            return None;
        }
        let f = flow.grid.trilinear(&flow.field, q)?;
        if f.length_squared() < 1e-6 {
            return None;
        }
        let f = f.normalize();
        Some(if f.dot(prev) < 0.0 { -f } else { f })
    };
    let max_steps = (params.max_length * params.grow_budget.max(1.0) / params.step).ceil() as usize;
    let max_gap = (params.max_gap / params.step).ceil() as usize;
    // Points since the field was last seen (dropped if growth ends inside a gap).
    let mut gap = 0usize;
    let mut stop = Stop::MaxLength;
    let (mut escapes, mut escaping) = (0u32, 0usize);
    let mut s = 0usize;
    // A free start (see `GrowParams::root_gap`): a root outside the raw mesh by more than
    // `outer_margin` ignores the outer surface until the strand first gets inside it or has grown
    // `root_gap`, and goes on through missing field meanwhile.
    let mut free = params.root_gap > 0.0 && reads_outside(flow, root, params);
    let free_steps = (params.root_gap / params.step).ceil() as usize;
    while s < max_steps {
        let step_no = s;
        s += 1;
        // Leave the root along S for the first steps, blending into the field.
        let blend = if step_no < 3 { 0.5 } else { 0.0 };
        let d = match dir_at(p, prev) {
            Some(d1) => {
                let d1 = (d1 * (1.0 - blend) + prev * blend).normalize();
                let mid = p + d1 * (0.5 * params.step);
                dir_at(mid, d1).map(|d2| (d2 * (1.0 - blend) + prev * blend).normalize())
            }
            None => None,
        };
        // The directed points near `p`, asked once: to blend with the field, or to trump it
        // (`trace_trumps`, also where the field is missing).
        let wants_trace =
            params.trace_radius > 0.0 && step_no >= 3 && escaping == 0 && (d.is_some() || params.trace_trumps > 0.0);
        let tr =
            trace.filter(|_| wants_trace).and_then(|t| traced(t, p, prev, params)).filter(|&(td, _)| td != Vec3::ZERO);
        let trumped = tr.filter(|&(_, w)| params.trace_trumps > 0.0 && w >= params.trace_trumps).map(|(td, _)| td);
        let d = match (trumped, d) {
            (Some(td), _) => {
                gap = 0;
                td
            }
            (None, Some(d)) if escaping > 0 => {
                gap = 0;
                escaping -= 1;
                (d * (1.0 - params.escape_gravity) + Vec3::NEG_Z * params.escape_gravity).normalize_or(d)
            }
            (None, Some(d)) => {
                gap = 0;
                match tr {
                    Some((td, w)) => {
                        let a = w / (w + params.trace_weight);
                        (d * (1.0 - a) + td * a).normalize_or(d)
                    }
                    None => d,
                }
            }
            (None, None) => {
                gap += 1;
                if gap > if free { free_steps } else { max_gap } {
                    stop = Stop::NotHair;
                    break;
                }
                prev
            }
        };
        // At the outer surface, the flow may slide along it but ends where it points out of it.
        let Some(so) = flow.grid.trilinear(&flow.sd_outer, p) else {
            stop = Stop::Grid;
            break;
        };
        // A strand bends by at most `max_turn` per step (a 6.5 mm curl turns 18° per 2 mm step).
        let mut d = limit_turn(prev, d, params.max_turn);
        let climb = trumped.is_none() && params.max_climb < 1.0 && step_no as f32 * params.step >= params.climb_after;
        if climb {
            d = limit_climb(d, params.max_climb, prev);
        }
        if free && (so <= 0.0 || step_no >= free_steps) {
            free = false;
        }
        let mut nrm = Vec3::ZERO;
        if !free && trumped.is_none() && so > -0.5 * flow.grid.voxel {
            nrm = gradient(flow, &flow.sd_outer, p);
            let c = d.dot(nrm);
            if params.exit_cos < 1.0 && c > params.exit_cos && step_no as f32 * params.step >= params.exit_after {
                stop = Stop::Outside;
                break;
            }
            if c > 0.0 {
                d = (d - nrm * c).normalize_or(d);
            }
        }
        let mut q = p + d * params.step;
        if nrm != Vec3::ZERO {
            if let Some(sq) = flow.grid.trilinear(&flow.sd_outer, q) {
                if sq > 0.0 {
                    q -= nrm * sq;
                }
            }
        }
        if climb {
            q = p + limit_climb(q - p, params.max_climb, d);
        }
        let q = push_out(flow, q, params.head_clearance);
        let Some(so) = flow.grid.trilinear(&flow.sd_outer, q) else {
            stop = Stop::Grid;
            break;
        };
        if so > params.outer_margin.max(if trumped.is_some() { 0.01 } else { 0.0 }) && !free {
            stop = Stop::Outside;
            break;
        }
        let seg = q - p;
        if seg.length_squared() < 1e-12 {
            stop = Stop::NotHair;
            break;
        }
        prev = seg.normalize();
        p = q;
        pts.push(p);
        let w = (params.loop_window / params.step).round() as usize;
        if w >= 2 && pts.len() > w {
            let d2 = params.loop_distance * params.loop_distance;
            if let Some(back) = pts[..pts.len() - 1 - w].iter().position(|q| q.distance_squared(p) < d2) {
                pts.truncate(back + 1);
                gap = 0;
                if escapes < params.max_escapes && params.escape_length > 0.0 {
                    escapes += 1;
                    escaping = (params.escape_length / params.step).ceil() as usize;
                    p = pts[back];
                    if back > 0 {
                        prev = (pts[back] - pts[back - 1]).normalize_or(prev);
                    }
                    s = pts.len() - 1;
                    continue;
                }
                stop = Stop::Loop;
                break;
            }
        }
    }
    if stop != Stop::MaxLength && gap > 0 {
        pts.truncate(pts.len().saturating_sub(gap).max(1));
    }
    if pts.len() < 2 {
        pts.push(root + start.normalize_or(Vec3::Z) * params.step);
    }
    (pts, stop)
}

/// Grows one guide per root, in parallel (cancellable between chunks); the roots that read outside
/// the raw mesh start free ([`GrowParams::root_gap`]).
pub fn grow_guides(
    flow: &FlowField,
    trace: Option<&PointIndex>,
    roots: &Roots,
    params: &GrowParams,
    progress: &dyn Progress,
) -> Result<(StrandSet, GrowStats), Cancelled> {
    let mut points = Vec::new();
    let mut counts = Vec::new();
    let mut stats = GrowStats::default();
    let chunk = 256;
    let mut all = Vec::with_capacity(roots.len());
    for (ci, c) in (0..roots.len()).collect::<Vec<_>>().chunks(chunk).enumerate() {
        progress.check()?;
        progress.update("init", (ci * chunk) as f32 / roots.len().max(1) as f32, "growing guides");
        let grown: Vec<(Vec<Vec3>, Stop)> =
            c.par_iter().map(|&i| grow_one(flow, trace, roots.positions[i], roots.growth[i], params)).collect();
        all.extend(grown);
    }
    if params.root_gap > 0.0 {
        stats.free_starts = roots.positions.iter().filter(|&&r| reads_outside(flow, r, params)).count() as u64;
    }
    for (g, stop) in all {
        match stop {
            Stop::Outside => stats.outside += 1,
            Stop::NotHair => stats.not_hair += 1,
            Stop::Grid => stats.grid += 1,
            Stop::MaxLength => stats.max_length += 1,
            Stop::Loop => stats.loops += 1,
        }
        counts.push(g.len() as u32);
        points.extend(g);
    }
    let set = StrandSet::new(points, counts).unwrap_or_else(|_| StrandSet::empty());
    if !set.is_empty() {
        stats.mean_length =
            (0..set.num_strands()).map(|i| set.strand_length(i) as f64).sum::<f64>() / set.num_strands() as f64;
    }
    Ok((set, stats))
}

/// How coherent the directed points along a guide are: the mean angle (radians) of their tangents
/// to their local mean direction, over the guide's points with at least 5 points within `radius`.
fn guide_coherence(guide: &[Vec3], points: &PointIndex, radius: f32) -> Option<f32> {
    let (mut sum, mut n) = (0.0f32, 0u32);
    for (k, p) in guide.iter().enumerate().step_by(2) {
        let near = points.within(*p, radius);
        if near.len() < 5 {
            continue;
        }
        let along = guide[(k + 1).min(guide.len() - 1)] - guide[k.saturating_sub(1)];
        let sign = |t: Vec3| if t.dot(along) < 0.0 { -t } else { t };
        let mean = near.iter().map(|&i| sign(points.tangents[i])).sum::<Vec3>().normalize_or_zero();
        if mean == Vec3::ZERO {
            continue;
        }
        let a: f32 = near.iter().map(|&i| points.tangents[i].dot(mean).abs().min(1.0).acos()).sum();
        sum += a / near.len() as f32;
        n += 1;
    }
    (n > 0).then(|| sum / n as f32)
}

/// `s` with its segment vectors smoothed by a Gaussian of `sigma` segments (weights renormalized at
/// the ends; none shorter than half its own length), rebuilt from its root.
fn smooth_strand(s: &[Vec3], sigma: f32) -> Vec<Vec3> {
    if sigma < 0.1 || s.len() < 3 {
        return s.to_vec();
    }
    let seg: Vec<Vec3> = s.windows(2).map(|w| w[1] - w[0]).collect();
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r).map(|j| (-0.5 * (j as f32 / sigma).powi(2)).exp()).collect();
    let mut out = Vec::with_capacity(s.len());
    out.push(s[0]);
    let mut p = s[0];
    for i in 0..seg.len() as isize {
        let (mut acc, mut ws) = (Vec3::ZERO, 0.0f32);
        for (j, &kw) in (-r..=r).zip(&kernel) {
            if (0..seg.len() as isize).contains(&(i + j)) {
                acc += seg[(i + j) as usize] * kw;
                ws += kw;
            }
        }
        // The mean segment (shorter than the segments where they wiggle: a straightened wiggle
        // does not reach farther), but at least half the segment's own length: where the strand
        // turns back, mean segments near zero would make a cusp the DR's evening cannot even out.
        let (own, mean) = (seg[i as usize], acc / ws);
        let l = mean.length();
        p += if l > 1e-9 { mean * (l.clamp(0.5 * own.length(), own.length()) / l) } else { own };
        out.push(p);
    }
    out
}

/// How many guides [`smooth_guides`] smoothed, and how.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SmoothStats {
    /// Guides smoothed with the whole σ, with part of it, not at all.
    pub full: u64,
    pub partly: u64,
    pub none: u64,
    /// Median coherence angle of the guides' points, degrees (see [`GrowParams::smooth_angles_deg`]).
    pub median_angle_deg: f32,
}

/// Smooths the guides along which the directed points are coherent (straight hair), see
/// [`GrowParams::smooth_sigma`]; points that the smoothing takes into the head are pushed out.
/// A guide without points near it takes the median coherence of the others. Measured
/// (`examples/init_stage … children=10000 gt_every=5`, paper preset, undirected F1 at 2 mm/20°,
/// 1 mm/10° in brackets): smoothing every guide by σ = 4 mm: straight 71.9 → 74.5 (39.5 → 45.7),
/// wavy 38.0 → 33.0, curly 32.0 → 18.2 (their zig-zags offer tangents that the curls' cone of
/// tangents matches; smooth strands along the curls' axis match none). The guides' median
/// coherence angle: straight 11.1°, wavy 18.0°, curly 17.9°. With the default thresholds 12°/14.5°
/// (1246 / 337 / 417 straight guides smoothed fully / partly / not; curly 20 / 169 / 1811): straight
/// 71.9 → 73.9 (39.5 → 44.0), curly 32.0 → 31.6; thresholds 13°/16°: straight 74.5, wavy 38.0 →
/// 38.5, curly 31.1. Session 10, σ (default thresholds) 4 → 8 / 12 / 20 mm: straight 73.9 → 74.8 /
/// 75.2 / **75.6**, curly 31.6 → 31.3 at 12 and 20 mm, wavy 38.3 → 38.2 at 12 mm; σ 20 mm with
/// thresholds 14°/17° gave straight 76.2 but curly 29.4, σ 30 mm with 15°/18° straight 75.3. At
/// full size (`children=50000`) σ 20 mm lifts straight from 81.8 to 83.7 (1 mm/10° 59.7 → 63.3,
/// directed 79.4 → 81.3): the straight guides' wiggles are tracing noise over centimetres. The
/// default since session 11, when the DR test's one uneven strand (`tests/pipeline_dr.rs`, a
/// max/min segment ratio of 2.02) turned out to be a child blending two guides on either side of a
/// parting, now prevented by [`BlendParams::parting_reach`].
pub fn smooth_guides(
    guides: &StrandSet,
    points: Option<&PointIndex>,
    flow: Option<&FlowField>,
    params: &GrowParams,
) -> (StrandSet, SmoothStats) {
    let mut stats = SmoothStats::default();
    let (Some(points), true) = (points, params.smooth_sigma > 0.0 && params.step > 0.0) else {
        stats.none = guides.num_strands() as u64;
        return (cut_at_arc(guides, params.max_length), stats);
    };
    let radius = coherence_radius(params);
    let angles: Vec<Option<f32>> =
        (0..guides.num_strands()).into_par_iter().map(|g| guide_coherence(guides.strand(g), points, radius)).collect();
    let mut known: Vec<f32> = angles.iter().flatten().copied().collect();
    known.sort_by(f32::total_cmp);
    let median = known.get(known.len() / 2).copied().unwrap_or(f32::INFINITY);
    stats.median_angle_deg = median.to_degrees();
    let [lo, hi] = params.smooth_angles_deg.map(f32::to_radians);
    let share = |a: f32| ((hi - a) / (hi - lo).max(1e-6)).clamp(0.0, 1.0);
    let shares: Vec<f32> = angles.iter().map(|a| share(a.unwrap_or(median))).collect();
    let sigma = params.smooth_sigma / params.step;
    let smoothed: Vec<Vec<Vec3>> = (0..guides.num_strands())
        .into_par_iter()
        .map(|g| {
            let mut s = smooth_strand(guides.strand(g), sigma * shares[g]);
            if let Some(flow) = flow {
                for p in s[1..].iter_mut() {
                    *p = push_out(flow, *p, params.head_clearance);
                }
            }
            s
        })
        .collect();
    for &f in &shares {
        match f {
            f if f >= 1.0 => stats.full += 1,
            f if f <= 0.0 => stats.none += 1,
            _ => stats.partly += 1,
        }
    }
    let counts = smoothed.iter().map(|s| s.len() as u32).collect();
    let set = StrandSet::new(smoothed.concat(), counts).unwrap_or_else(|_| guides.clone());
    (cut_at_arc(&set, params.max_length), stats)
}

/// Every strand cut at `max_length` metres of arc (the last point interpolated on its segment).
pub fn cut_at_arc(strands: &StrandSet, max_length: f32) -> StrandSet {
    let mut points = Vec::with_capacity(strands.points().len());
    let mut counts = Vec::with_capacity(strands.num_strands());
    for s in strands.iter() {
        let start = points.len();
        points.push(s[0]);
        let mut arc = 0.0f32;
        for w in s.windows(2) {
            let l = w[0].distance(w[1]);
            if arc + l >= max_length {
                if max_length - arc > 1e-6 {
                    points.push(w[0] + (w[1] - w[0]) * ((max_length - arc) / l.max(1e-12)));
                }
                break;
            }
            arc += l;
            points.push(w[1]);
        }
        if points.len() - start < 2 {
            points.truncate(start);
            points.extend_from_slice(&s[..s.len().min(2)]);
        }
        counts.push((points.len() - start) as u32);
    }
    StrandSet::new(points, counts).unwrap_or_else(|_| strands.clone())
}

/// Interpolates children from guides (see the module doc).
pub fn interpolate_children(
    guides: &StrandSet,
    roots: &Roots,
    flow: Option<&FlowField>,
    params: &GrowParams,
    progress: &dyn Progress,
) -> Result<StrandSet, Cancelled> {
    if guides.is_empty() {
        return Ok(StrandSet::empty());
    }
    let blend = GuideBlend::new(guides, &params.blend);
    let mut points = Vec::new();
    let mut counts = Vec::new();
    let chunk = 4096;
    for (ci, c) in (0..roots.len()).collect::<Vec<_>>().chunks(chunk).enumerate() {
        progress.check()?;
        progress.update("init", (ci * chunk) as f32 / roots.len().max(1) as f32, "interpolating children");
        let made: Vec<Vec<Vec3>> = c
            .par_iter()
            .map(|&i| {
                let root = roots.positions[i];
                let w = blend.weights(root, params.blend.k);
                let len: f32 = w.iter().map(|&(g, wt)| guides.strand(g).len() as f32 * wt).sum();
                let n = (len.round() as usize).max(2);
                let mut pts = Vec::with_capacity(n);
                pts.push(root);
                let mut p = root;
                for k in 1..n {
                    let (mut acc, mut wa) = (Vec3::ZERO, 0.0);
                    for &(g, wt) in &w {
                        let s = guides.strand(g);
                        if k < s.len() {
                            acc += (s[k] - s[k - 1]) * wt;
                            wa += wt;
                        }
                    }
                    if wa <= 0.0 {
                        break;
                    }
                    p += acc / wa;
                    if let Some(f) = flow {
                        p = push_out(f, p, params.head_clearance);
                    }
                    pts.push(p);
                }
                if pts.len() < 2 {
                    pts.push(root + roots.growth[i] * params.step);
                }
                pts
            })
            .collect();
        for g in made {
            counts.push(g.len() as u32);
            points.extend(g);
        }
    }
    Ok(StrandSet::new(points, counts).unwrap_or_else(|_| StrandSet::empty()))
}

/// Arc length over which a guide's leaving direction is taken for [`BlendParams::parting_reach`].
pub const PARTING_ARC: f32 = 0.02;

/// Which guides a child blends, and how much: its `k` nearest guide roots among the guides at least
/// `fraction` of the median guide length long (every guide when none is), weights `1/d²` summing to
/// one; only the nearest when the guides part (see [`BlendParams::parting_reach`]). Shared by
/// [`interpolate_children`] and the DR's child map, so that both pick the same guides.
///
/// The parting rule, measured in session 11 on the freshly rendered paper straight capture
/// (`examples/init_stage bench_out/paper_straight_brown DIR OUT children=10000 gt_every=5
/// parting_reach=R`, DIR a `hairrecon reconstruct` output; undirected F1 at 2 mm/20°): off 74.5,
/// reach 0.3 74.6, **0.5** 74.6; dropping every guide that leaves more than 90° away from the
/// nearest one instead cost recall (74.1). On the DR test's sphere (`tests/pipeline_dr.rs`) it
/// takes the worst max/min segment ratio after DR from 2.02 to 1.008.
#[derive(Debug)]
pub struct GuideBlend {
    eligible: Vec<usize>,
    index: PointIndex,
    /// Unit chord from each eligible guide's root over its first [`PARTING_ARC`].
    leaving: Vec<Vec3>,
    parting_reach: f32,
}

impl GuideBlend {
    pub fn new(guides: &StrandSet, params: &BlendParams) -> Self {
        let (fraction, parting_reach) = (params.min_guide_fraction, params.parting_reach);
        let lengths: Vec<f32> = (0..guides.num_strands()).map(|g| guides.strand_length(g)).collect();
        let mut sorted = lengths.clone();
        sorted.sort_by(f32::total_cmp);
        let min_length = sorted.get(sorted.len() / 2).map_or(0.0, |m| m * fraction);
        let mut eligible: Vec<usize> = (0..guides.num_strands()).filter(|&g| lengths[g] >= min_length).collect();
        if eligible.is_empty() {
            eligible = (0..guides.num_strands()).collect();
        }
        let roots: Vec<Vec3> = eligible.iter().map(|&g| guides.strand(g)[0]).collect();
        let leaving = eligible.iter().map(|&g| leaving_direction(guides.strand(g), PARTING_ARC)).collect();
        let index = PointIndex::new(roots, vec![Vec3::Z; eligible.len()]);
        Self { eligible, index, leaving, parting_reach }
    }

    /// How many guides a child can blend.
    pub fn len(&self) -> usize {
        self.eligible.len()
    }

    pub fn is_empty(&self) -> bool {
        self.eligible.is_empty()
    }

    /// (guide index, weight) of the guides a child rooted at `root` blends, nearest first: its `k`
    /// nearest, or the nearest alone where they part.
    pub fn weights(&self, root: Vec3, k: usize) -> Vec<(usize, f32)> {
        let found = self.index.nearest(root, k);
        let ws: f32 = found.iter().map(|&(_, d)| 1.0 / (d * d + 1e-8)).sum();
        let mut w: Vec<(usize, f32)> = found.iter().map(|&(g, d)| (g, 1.0 / (d * d + 1e-8) / ws)).collect();
        if w.len() > 1 {
            let reach = w.iter().map(|&(g, wt)| self.leaving[g] * wt).sum::<Vec3>().length();
            if reach < self.parting_reach {
                w.truncate(1);
                w[0].1 = 1.0;
            }
        }
        w.into_iter().map(|(g, wt)| (self.eligible[g], wt)).collect()
    }
}

/// The unit chord from a strand's root to its point `arc` metres along (or its tip, if shorter);
/// zero for a strand of one point.
fn leaving_direction(s: &[Vec3], arc: f32) -> Vec3 {
    let mut walked = 0.0;
    for w in s.windows(2) {
        walked += (w[1] - w[0]).length();
        if walked >= arc {
            return (w[1] - s[0]).normalize_or_zero();
        }
    }
    s.last().map_or(Vec3::ZERO, |&t| (t - s[0]).normalize_or_zero())
}

/// The ablation: straight strands along the scalp normal, `length` long, `segments` segments.
pub fn straight_strands(roots: &Roots, length: f32, segments: usize) -> StrandSet {
    let segments = segments.max(1);
    let mut points = Vec::with_capacity(roots.len() * (segments + 1));
    for i in 0..roots.len() {
        for s in 0..=segments {
            points.push(roots.positions[i] + roots.normals[i] * (length * s as f32 / segments as f32));
        }
    }
    StrandSet::new(points, vec![segments as u32 + 1; roots.len()]).unwrap_or_else(|_| StrandSet::empty())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplace::Grid;

    /// A 20 cm box of hair (no head, outer surface far away) with `field(p)` per voxel.
    fn flow(field: impl Fn(Vec3) -> Vec3) -> FlowField {
        let voxel = 0.004;
        let dims = [51, 51, 151];
        let grid = Grid { origin: Vec3::new(-0.1, -0.1, -0.5), voxel, dims };
        let n = grid.len();
        let field = (0..n).map(|i| field(grid.centre(i))).collect();
        FlowField { grid, field, sd_outer: vec![-0.05; n], sd_inner: vec![0.05; n], label: vec![1; n] }
    }

    #[test]
    fn cut_at_arc_keeps_the_first_max_length_of_each_strand() {
        let long: Vec<Vec3> = (0..=4).map(|i| Vec3::new(0.1 * i as f32, 0.0, 0.0)).collect();
        let short = vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.05)];
        let set = StrandSet::new([long, short.clone()].concat(), vec![5, 2]).unwrap();
        let cut = cut_at_arc(&set, 0.25);
        assert_eq!(cut.strand(0).len(), 4);
        assert!(cut.strand(0)[3].distance(Vec3::new(0.25, 0.0, 0.0)) < 1e-6);
        assert!((cut.strand_length(0) - 0.25).abs() < 1e-6);
        assert_eq!(cut.strand(1), &short[..]);
    }

    #[test]
    fn growth_takes_its_budget_and_the_guides_are_cut_at_max_length() {
        // Straight down: the strand grows max_length × grow_budget of steps, and smoothing's cut
        // leaves max_length of arc.
        let f = flow(|_| Vec3::NEG_Z);
        let params = GrowParams { max_length: 0.1, grow_budget: 1.5, ..GrowParams::default() };
        let (pts, stop) = grow_one(&f, None, Vec3::ZERO, Vec3::NEG_Z, &params);
        assert_eq!(stop, Stop::MaxLength);
        let grown: f32 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
        assert!((grown - 0.15).abs() < 1e-4, "grew {grown} m");
        let set = StrandSet::new(pts, vec![76]).unwrap();
        let (cut, _) = smooth_guides(&set, None, Some(&f), &params);
        assert!((cut.strand_length(0) - 0.1).abs() < 1e-5, "kept {} m", cut.strand_length(0));
    }

    #[test]
    fn a_zig_zag_guide_smoothed_reaches_as_far_as_max_length_allows() {
        // A guide that zig-zags down (2 mm steps 45° either side of straight down, as guides sliding
        // along the outer surface do) over its budget, with coherent points along it: smoothed and
        // cut, it keeps max_length of arc, which reaches about max_length down. Cut at the old
        // budget (the steps of max_length), the same guide reached only cos 45° of that.
        let params = GrowParams { max_length: 0.2, grow_budget: 1.5, ..GrowParams::default() };
        let steps = (params.max_length * params.grow_budget / params.step).round() as usize;
        let h = params.step * std::f32::consts::FRAC_1_SQRT_2;
        let zig: Vec<Vec3> =
            (0..=steps).map(|i| Vec3::new(if i % 2 == 1 { h } else { 0.0 }, 0.0, -h * i as f32)).collect();
        let points = PointIndex::new(
            (0..400).map(|i| Vec3::new(0.5 * h, 0.0, -0.001 * i as f32)).collect(),
            vec![Vec3::NEG_Z; 400],
        );
        let reach = |guide: &[Vec3]| {
            let set = StrandSet::new(guide.to_vec(), vec![guide.len() as u32]).unwrap();
            let (out, stats) = smooth_guides(&set, Some(&points), None, &params);
            assert_eq!(stats.full, 1);
            (out.strand_length(0), -out.strand(0).last().unwrap().z)
        };
        let (arc, down) = reach(&zig);
        assert!((arc - 0.2).abs() < 1e-4, "kept {arc} m of arc");
        assert!(down > 0.19, "reached {down} m down");
        let old_budget = (params.max_length / params.step).round() as usize;
        let (_, down_old) = reach(&zig[..=old_budget]);
        assert!(down_old < 0.15, "the old budget reached {down_old} m down");
    }

    #[test]
    fn a_vortex_ends_as_a_loop_and_the_circle_is_cut() {
        // Circles about the z axis: without the loop rule a strand circles until max_length.
        let f = flow(|p| Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X));
        let params = GrowParams { max_escapes: 0, ..GrowParams::default() };
        let root = Vec3::new(0.02, 0.0, 0.0);
        let (pts, stop) = grow_one(&f, None, root, Vec3::Y, &params);
        assert_eq!(stop, Stop::Loop);
        // A 2 cm radius circle is 12.6 cm around: the strand is cut back to where it came round.
        let len: f32 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
        assert!(len < 0.02, "kept {len} m of a vortex");
        let (_, stop) = grow_one(&f, None, root, Vec3::Y, &GrowParams { loop_window: 0.0, ..params });
        assert_eq!(stop, Stop::MaxLength);
    }

    #[test]
    fn a_strand_escapes_a_vortex_under_gravity_and_keeps_no_circle() {
        // The same vortex, with the default escapes: each time the strand comes round, the circle is
        // cut and it leaves downwards for `escape_length`; it ends far below its root, and nothing
        // of what it kept comes back near itself.
        let f = flow(|p| Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X));
        let params = GrowParams::default();
        let (pts, stop) = grow_one(&f, None, Vec3::new(0.02, 0.0, 0.0), Vec3::Y, &params);
        let low = pts.last().unwrap().z;
        assert!(low < -0.15, "ended at z = {low} ({stop:?})");
        let w = (params.loop_window / params.step).round() as usize;
        for (i, p) in pts.iter().enumerate().skip(w + 1) {
            let back = pts[..i - w].iter().map(|q| q.distance(*p)).fold(f32::MAX, f32::min);
            assert!(back >= params.loop_distance, "point {i} comes back within {back} m");
        }
    }

    #[test]
    fn a_tight_helix_is_not_a_loop() {
        // A helix of radius 5 mm and pitch 1 cm about the z axis, descending.
        let pitch = 0.01f32;
        let r = 0.005f32;
        let f = flow(|p| {
            let tangential = Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X) * (std::f32::consts::TAU * r);
            (tangential - Vec3::Z * pitch).normalize()
        });
        let params = GrowParams { max_length: 0.3, ..GrowParams::default() };
        let (pts, stop) = grow_one(&f, None, Vec3::new(r, 0.0, 0.0), Vec3::new(0.0, 0.95, -0.3), &params);
        assert_eq!(stop, Stop::MaxLength, "{} points", pts.len());
        assert!(pts.last().unwrap().z < -0.06);
    }

    #[test]
    fn beyond_climb_after_no_step_climbs_even_where_the_outer_surface_slopes_up() {
        // Flow down and to +x; the outer surface a plane facing down and +x (the underside of a
        // hair mass) 4 mm from the root: the strand meets it at once and its projection onto the
        // plane slides it up along it. With `max_climb` 0 no step beyond `climb_after` rises (the
        // strand leaves the surface level and ends outside); with the rule off it climbs.
        let root = Vec3::new(-0.08, 0.0, -0.2);
        let n = Vec3::new(1.0, 0.0, -1.0).normalize();
        let mut f = flow(|_| Vec3::new(1.0, 0.0, -0.3).normalize());
        for i in 0..f.grid.len() {
            f.sd_outer[i] = (f.grid.centre(i) - root - Vec3::X * 0.004).dot(n);
        }
        let rises = |params: &GrowParams| {
            let (pts, _) = grow_one(&f, None, root, Vec3::new(1.0, 0.0, -0.3), params);
            let mut arc = 0.0f32;
            let mut rise = f32::MIN;
            for w in pts.windows(2) {
                if arc >= params.climb_after {
                    rise = rise.max(w[1].z - w[0].z);
                }
                arc += w[0].distance(w[1]);
            }
            (rise, pts.len())
        };
        let params = GrowParams { trace_radius: 0.0, max_length: 0.1, ..GrowParams::default() };
        let (rise, n_on) = rises(&params);
        assert!(rise <= 1e-6, "a step beyond climb_after rose {rise} m ({n_on} points)");
        let (rise, n_off) = rises(&GrowParams { max_climb: 1.0, ..params });
        assert!(
            rise > 0.0005,
            "with the rule off the strand should climb the surface; largest rise {rise} m ({n_off} points)"
        );
    }

    /// Flow straight down; an inward-facing wall of the raw mesh 2 cm behind (+y) the root, so that the
    /// root reads 2 cm outside. Directed points along the line down from the root and along the
    /// wall, with tangents from `tangent(i)`.
    fn wrong_sign_scene(tangent: impl Fn(usize) -> Vec3) -> (FlowField, PointIndex, Roots) {
        let root = Vec3::new(0.0, 0.0, -0.05);
        let mut f = flow(|_| Vec3::NEG_Z);
        for i in 0..f.grid.len() {
            f.sd_outer[i] = root.y + 0.02 - f.grid.centre(i).y;
        }
        let (mut pos, mut dir) = (Vec::new(), Vec::new());
        for k in 0..300 {
            for (x, y) in [(-0.001, 0.0), (0.001, 0.0), (0.0, 0.001), (-0.001, 0.02), (0.001, 0.02), (0.0, 0.019)] {
                pos.push(Vec3::new(x, y, root.z - 0.001 * k as f32));
                dir.push(tangent(pos.len()));
            }
        }
        let roots = Roots { positions: vec![root], normals: vec![Vec3::Z], growth: vec![Vec3::NEG_Z] };
        (f, PointIndex::new(pos, dir), roots)
    }

    #[test]
    fn a_root_read_outside_the_raw_mesh_starts_free_whatever_the_points() {
        let params = GrowParams { trace_radius: 0.0, ..GrowParams::default() };
        let first = |g: &StrandSet| (g.strand(0)[1] - g.strand(0)[0]).normalize();
        // Without a free start the first step jumps onto the wall: back (+y), not down.
        let (f, points, roots) = wrong_sign_scene(|_| Vec3::NEG_Z);
        let off = GrowParams { root_gap: 0.0, ..params };
        let (g, stats) = grow_guides(&f, Some(&points), &roots, &off, &crate::progress::NoProgress).unwrap();
        assert!(first(&g).y > 0.9, "first step {:?}", first(&g));
        assert_eq!(stats.free_starts, 0);
        // With it the guide goes straight down for `root_gap`, whether the points agree (straight
        // hair) or their tangents go all round (wavy hair's points are incoherent, session 39).
        let incoherent = |i: usize| {
            let a = i as f32 * 2.4;
            Vec3::new(a.cos(), a.sin(), 0.3 * (1.7 * a).sin()).normalize()
        };
        for (f, points, roots) in [wrong_sign_scene(|_| Vec3::NEG_Z), wrong_sign_scene(incoherent)] {
            let (g, stats) = grow_guides(&f, Some(&points), &roots, &params, &crate::progress::NoProgress).unwrap();
            assert_eq!(stats.free_starts, 1);
            let s = g.strand(0);
            let n = (params.root_gap / params.step) as usize;
            assert!(s.len() > n);
            for p in &s[..n] {
                assert!(p.y.abs() < 1e-4 && p.x.abs() < 1e-4, "left the line at {p:?}");
            }
            assert!((s[n].z - (roots.positions[0].z - params.root_gap)).abs() < 1e-3);
        }
    }

    #[test]
    fn the_exit_rule_waits_for_exit_after() {
        // Flow straight up (+z) through an outer surface at z = 0 (sd_outer = z): growth ends at the
        // surface, unless the exit rule is held off, in which case the strand slides (and, with a
        // purely normal flow, has nowhere to go but stays on the surface).
        let mut f = flow(|_| Vec3::Z);
        for i in 0..f.grid.len() {
            f.sd_outer[i] = f.grid.centre(i).z;
        }
        let params = GrowParams { exit_cos: 0.99, ..GrowParams::default() };
        let root = Vec3::new(0.0, 0.0, -0.05);
        let (pts, stop) = grow_one(&f, None, root, Vec3::Z, &params);
        assert_eq!(stop, Stop::Outside);
        let top = pts.iter().map(|p| p.z).fold(f32::MIN, f32::max);
        assert!(top.abs() < 0.004, "stopped at z = {top}");
    }

    #[test]
    fn tracing_follows_the_points_where_the_field_is_smooth() {
        // The field points straight down; directed points lie along a helix of 6 mm radius that
        // hangs from the root. Without tracing a strand goes straight down; with it, it keeps to
        // the helix.
        let f = flow(|_| Vec3::NEG_Z);
        let helix = |t: f32| Vec3::new(0.006 * t.cos(), 0.006 * t.sin(), -0.004 * t);
        let (mut pts, mut tans) = (Vec::new(), Vec::new());
        for k in 0..3000 {
            let t = k as f32 * 0.01;
            pts.push(helix(t));
            tans.push((helix(t + 0.001) - helix(t)).normalize());
        }
        let index = PointIndex::new(pts.clone(), tans.clone());
        let off_helix = |strand: &[Vec3]| -> f32 {
            let near: Vec<f32> =
                strand.iter().map(|p| index.nearest(*p, 1).first().map(|n| n.1).unwrap_or(f32::MAX)).collect();
            near.iter().sum::<f32>() / near.len() as f32
        };
        let params = GrowParams { max_length: 0.15, grow_budget: 1.0, ..GrowParams::default() };
        let (with, _) = grow_one(&f, Some(&index), helix(0.0), tans[0], &params);
        let (without, _) = grow_one(&f, None, helix(0.0), tans[0], &params);
        let (a, b) = (off_helix(&with), off_helix(&without));
        assert!(a < 0.001, "traced strand {a} m from the helix on average");
        assert!(b > 0.003, "untraced strand {b} m from the helix on average");
    }

    #[test]
    fn where_points_trump_a_strand_follows_them_out_through_the_outer_surface() {
        // The field points straight down; the outer surface is the plane x = 5 mm; directed points
        // fill the plane y = 0, all pointing 45° outward and down. By default the strand blends
        // the field with them and slides along the surface; where the points trump, it follows
        // them out through it (up to 1 cm). Points whose signs run against the strand never trump.
        let mut f = flow(|_| Vec3::NEG_Z);
        for i in 0..f.grid.len() {
            f.sd_outer[i] = f.grid.centre(i).x - 0.005;
        }
        let d = Vec3::new(1.0, 0.0, -1.0).normalize();
        let plane: Vec<Vec3> =
            (0..1600).map(|k| Vec3::new(-0.01 + (k % 40) as f32 * 0.001, 0.0, -((k / 40) as f32) * 0.001)).collect();
        let along = PointIndex::new(plane.clone(), vec![d; plane.len()]);
        let against = PointIndex::new(plane, vec![-d; 1600]);
        let base = GrowParams { max_length: 0.03, max_climb: 1.0, ..GrowParams::default() };
        let trump = GrowParams { trace_trumps: 0.5, ..base };
        let tip_x =
            |index: &PointIndex, p: &GrowParams| grow_one(&f, Some(index), Vec3::ZERO, d, p).0.last().unwrap().x;
        let (x_base, x_trump, x_against) = (tip_x(&along, &base), tip_x(&along, &trump), tip_x(&against, &trump));
        assert!(x_base < 0.0065, "default: tip {x_base} m out, should slide along x = 5 mm");
        assert!(x_trump > 0.012, "trumped: tip {x_trump} m out, should follow the points out of the surface");
        assert!(x_against < 0.0065, "points against the strand: tip {x_against} m out");
    }

    #[test]
    fn straight_guides_are_smoothed_and_curly_ones_kept() {
        // A guide straight down with a 0.5 mm zig-zag, among points all along it. Where their
        // tangents agree (straight hair) the zig-zag is tracing noise and goes; where they spread
        // by 30° (curls crossing) the guide is kept as it is.
        let guide: Vec<Vec3> = (0..100).map(|k| Vec3::new(0.0005 * (k % 2) as f32, 0.0, -0.002 * k as f32)).collect();
        let guides = StrandSet::new(guide.clone(), vec![100]).unwrap();
        let pts: Vec<Vec3> = (0..2000)
            .map(|i| {
                Vec3::new(0.001 * ((i % 5) as f32 - 2.0) * 0.5, 0.0005 * ((i / 5 % 3) as f32 - 1.0), -0.0001 * i as f32)
            })
            .collect();
        let params = GrowParams::default();
        // The largest sideways step away from the ends (3σ = 6 segments): 0.5 mm before smoothing.
        let zigzag = |s: &[Vec3]| s[8..s.len() - 8].windows(2).map(|w| (w[1].x - w[0].x).abs()).fold(0.0f32, f32::max);

        let straight = PointIndex::new(pts.clone(), vec![Vec3::NEG_Z; pts.len()]);
        let (smoothed, stats) = smooth_guides(&guides, Some(&straight), None, &params);
        assert_eq!((stats.full, stats.partly, stats.none), (1, 0, 0));
        assert!(stats.median_angle_deg < 1.0, "{stats:?}");
        let s = smoothed.strand(0);
        assert_eq!(s[0], guide[0], "the root moved");
        assert_eq!(s.len(), guide.len());
        assert!(zigzag(&guide) > 0.00049);
        assert!(zigzag(s) < 0.00005, "zig-zag {} m left of 0.0005", zigzag(s));

        let spread = |i: usize| {
            let a = if i % 2 == 0 { 30f32 } else { -30f32 }.to_radians();
            let t = Vec3::new(a.sin(), 0.0, -a.cos());
            if i % 4 < 2 {
                t
            } else {
                Vec3::new(t.y, t.x, t.z)
            }
        };
        let curly = PointIndex::new(pts.clone(), (0..pts.len()).map(spread).collect());
        let (kept, stats) = smooth_guides(&guides, Some(&curly), None, &params);
        assert_eq!((stats.full, stats.partly, stats.none), (0, 0, 1));
        assert!((stats.median_angle_deg - 30.0).abs() < 3.0, "{stats:?}");
        assert_eq!(kept.strand(0), guide.as_slice());
    }

    #[test]
    fn a_child_between_guides_that_part_follows_its_nearest_guide() {
        // Two guides 10 cm long whose roots are 1 cm apart: one leaves along +x, the other along -x
        // (a parting between them). A child rooted 0.4 mm nearer the first one.
        let guide = |x0: f32, dir: f32| (0..51).map(move |j| Vec3::new(x0 + dir * 0.002 * j as f32, 0.0, 0.0));
        let guides = StrandSet::new(guide(0.0, 1.0).chain(guide(0.01, -1.0)).collect(), vec![51, 51]).unwrap();
        let root = Vec3::new(0.0046, 0.001, 0.0);
        let roots = Roots { positions: vec![root], normals: vec![Vec3::Z], growth: vec![Vec3::X] };
        let child = |parting_reach: f32| {
            let params =
                GrowParams { blend: BlendParams { parting_reach, ..BlendParams::default() }, ..GrowParams::default() };
            let c = interpolate_children(&guides, &roots, None, &params, &crate::progress::NoProgress).unwrap();
            c.strand(0).to_vec()
        };
        let reach = |s: &[Vec3]| (s[s.len() - 1] - s[0]).length();

        // Blending both (weights 0.58 and 0.42), the segment vectors cancel but for 0.15 of a step.
        let blended = child(0.0);
        assert!(reach(&blended) < 0.03, "reach {} m", reach(&blended));
        // With the parting rule the child takes the nearer guide's shape: 10 cm along +x, 2 mm steps.
        let parted = child(0.5);
        assert_eq!(parted.len(), 51);
        assert!((parted[50] - (root + Vec3::X * 0.1)).length() < 1e-5, "tip {:?}", parted[50]);
        for w in parted.windows(2) {
            assert!(((w[1] - w[0]).length() - 0.002).abs() < 1e-6);
        }
        // Guides that leave 90° apart blend to a reach of 0.72 with these weights: kept at 0.5,
        // the nearest alone at 0.8.
        let side: Vec<Vec3> = guide(0.0, 1.0).chain((0..51).map(|j| Vec3::new(0.01, 0.002 * j as f32, 0.0))).collect();
        let guides = StrandSet::new(side, vec![51, 51]).unwrap();
        let blend = |reach: f32| {
            GuideBlend::new(&guides, &BlendParams { k: 2, min_guide_fraction: 0.0, parting_reach: reach })
                .weights(root, 2)
        };
        assert_eq!(blend(0.5).len(), 2);
        assert_eq!(blend(0.8), vec![(0, 1.0)]);
    }
}
