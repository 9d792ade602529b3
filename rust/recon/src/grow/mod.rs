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

use hairrecon_core::spatial::PointIndex;

use crate::laplace::FlowField;
use crate::progress::{Cancelled, Progress};
use crate::roots::Roots;

mod children;
mod smooth;
#[cfg(test)]
mod tests;

pub use children::{interpolate_children, straight_strands, GuideBlend, PARTING_ARC};
pub use smooth::{cut_at_arc, smooth_guides, SmoothStats};

/// How a child blends the guides, shared by [`interpolate_children`] and the DR's child map (so
/// that both pick the same guides with the same weights); see [`GuideBlend`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BlendParams {
    /// Guides per child. 2 on measurement (paper preset, the init stage alone with 50,000 children,
    /// undirected F1 at 2 mm/20°, commit ade29e2): curly k = 1/2/3/4 gave 33.7/50.7/49.5/47.9 (one
    /// guide ends children wherever it ends; more guides blend curls of different phase into
    /// zig-zags), straight k = 2/4 gave 79.9/79.8 (1 mm/10°: 54.5/56.2).
    pub k: usize,
    /// Children blend only guides at least this fraction of the median guide's length (0: every
    /// guide): a guide that ended at its root, where the volume has no flow, would end its children
    /// there too. Relative, so that short styles keep their guides. Measured at commit cf7dab4 (the
    /// init stage alone with 50,000 children, undirected F1 at 2 mm/20°): paper curly 50.7 → 52.8
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
    /// Ends where the hair ends at the outer surface: where the directed points within
    /// `trace_radius` of a strand at the outer surface leave it, on average, at more than
    /// `acos(exit_points_cos)` from the surface (|cos| of their tangents with its normal), and the
    /// strand's own step leaves it at more than that too, past `exit_points_after` metres of arc.
    /// Hair that lies along the outer surface (long hair) never meets it; hair whose tips stand
    /// out of the surface (spiky hair) ends there instead of sliding on over the head (1: off).
    /// Measured at commit 72cbb8e (the init stage alone on the held-out spiky style's tuning seed,
    /// colours preset, undirected F1 at 2 mm/20°): at 0.5 the guides are 4.4 cm long on average
    /// against 22 cm (the ground truth's 5.5 cm), but F1 stays 10.6 → 10.3, the strands being in
    /// the wrong place (research/notes/volume-study.md, section 5); so it is off.
    #[serde(default = "off")]
    pub exit_points_cos: f32,
    #[serde(default = "one_cm")]
    pub exit_points_after: f32,
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
    /// of its voxels; the points carry the curls. Measured at commit 5403f75 (the init stage alone
    /// with 10,000 children scored against every 5th ground-truth strand, paper preset, undirected
    /// F1 at 2 mm/20°): off → on: straight 67.3 → 71.3, wavy 30.1 → 31.2, curly 22.8 → 23.8.
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
    /// 2 mm/20°, scored by root region). The scalp is under the hair, so such a root's sign is
    /// doubted: its strand ignores the outer surface until it first gets inside or has grown
    /// `root_gap` metres, going straight on through missing field meanwhile. Measured at commit
    /// 3cb7493 (the init stage alone with 10,000 children scored against every 5th ground-truth
    /// strand, undirected F1 at 2 mm/20°): straight 74.6 → 77.2 (0.05 m: 74.4; 0.3 m: 77.2); curly,
    /// grown then from its incoherent points, 31.2 → 26.7 and wavy 38.0 → 39.5, so earlier versions
    /// applied it only where the median guide's points were coherent (straight hair, and curly hair
    /// grown along its ringlet axes). Wavy hair's points are not (18° against straight's 11°), and
    /// without free starts its guides at the back and sides left the scalp 47–53° off the ground
    /// truth's, level where it falls (research/notes/reconstruction-study.md, "Wavy hair's roots");
    /// free starts apply on every style since commit 70cc3c0.
    pub root_gap: f32,
    /// Gravity: beyond `climb_after` metres of arc, a step rises at most `max_climb` (the sine of
    /// its angle above the horizontal; 1: off), both the direction the field and the points give
    /// and the step that the outer surface's projection makes of it. Hair under gravity does not
    /// climb once it has left the scalp, but the strands did: on the paper preset 3–6% (straight),
    /// 10–11% (wavy) and 11–13% (curly) of their steps beyond 6 cm went up (the ground truth's:
    /// straight and wavy 0%, curly 1–9%, the helices; our directed points: 0% below 6 cm from the
    /// top), nearly all of them where the outer surface's projection pushed them (the raw mesh's
    /// surface pieces inside the hair), and a climbing step is one that matches the ground truth
    /// only reversed. Measured at commit 33926ba, at full size (the init stage alone with 50,000
    /// children on the paper preset's saved directed points; undirected / directed F1 at 2 mm/20°,
    /// off → on): straight 84.5 / 82.1 → 85.9 / 85.8, wavy 53.5 / 47.4 → 55.3 / 54.7, curly 51.9 /
    /// 40.8 → 49.1 / 44.5 (the curls' climbing steps matched reversed helices); test preset 56.9 /
    /// 53.7 → 60.0 / 60.0. With 10,000 children scored against every 5th ground-truth strand,
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
    /// Measured at commit bf4970f on the paper curly capture (research/notes/curly-study.md): grown
    /// through ground-truth points everywhere, the growth's rules cost most of the guides' precision
    /// (pooled undirected precision of the guides at 2 mm/20°: defaults 63.9%, `trace_trumps=0.3`
    /// with `trace_pull=0, trace_power=4, trace_min_cos=0.5, trace_radius=0.002, step=0.001` 77.1%,
    /// strands traced through the points alone 87.6% over shorter strands). Through our own points
    /// `trace_trumps=1, max_climb=1` makes the guides 51.0 → 62.9% precise, but they keep to the
    /// visible surface (87% of their points within 2 mm of a directed point) and the children lose
    /// recall (50,000 children, undirected P / R / F1 at 2 mm/20°: 43.3 / 56.6 / 49.1 → 50.7 / 42.8
    /// / 46.4). Half the children from each set (the field's cover the volume, the traced ones the
    /// visible curls) score 51.8 with `loop_window=0`, and wavy 55.3 → 57.0, but directed F1 falls
    /// (curly 44.5 → 43.1).
    pub trace_trumps: f32,
}

fn off() -> f32 {
    1.0
}

fn one_cm() -> f32 {
    0.01
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
            exit_points_cos: off(),
            exit_points_after: one_cm(),
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

pub(super) fn push_out(flow: &FlowField, p: Vec3, clearance: f32) -> Vec3 {
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
pub(super) fn coherence_radius(params: &GrowParams) -> f32 {
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

/// The mean |cos| between the directed points' tangents within `r` of `p` and the outer surface's
/// normal `nrm` (how steeply the seen hair leaves the surface there), or `None` without points.
fn leaving(points: &PointIndex, p: Vec3, nrm: Vec3, r: f32) -> Option<f32> {
    let (mut sum, mut n) = (0.0f32, 0usize);
    for i in points.within(p, r) {
        sum += points.tangents[i].dot(nrm).abs();
        n += 1;
    }
    (n > 0).then(|| sum / n as f32)
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
            if params.exit_points_cos < 1.0
                && c > params.exit_points_cos
                && step_no as f32 * params.step >= params.exit_points_after
                && trace
                    .and_then(|t| leaving(t, p, nrm, params.trace_radius))
                    .is_some_and(|m| m > params.exit_points_cos)
            {
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
