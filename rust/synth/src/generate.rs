//! The hairstyle generator: seeded, parallel over strands, never inside the head.
//!
//! In: the head mesh (for collisions), the scalp mesh (for roots), a [`StyleParams`], a strand
//! count, a point count and a seed. Out: a [`StrandSet`], root first, in metres.
//!
//! A procedural groom in the spirit of the hair-modelling tools that drape strands by "combing"
//! (e.g. Blender's hair curves with clump, curl and frizz nodes), in four steps:
//! 1. **Roots** in blue noise on the scalp ([`Scalp::sample_roots`]); **clump** centres are a second,
//!    sparser blue-noise set; each root joins its nearest clump.
//! 2. **Centrelines** are grown step by step from the root along S(p_s): the direction turns toward a
//!    target (gravity, a pull toward the back, away from a middle parting for roots at the front,
//!    ends turned under for a bob) over a bending length that is long (stiff) near the root and
//!    short further out, with a little random frizz. Every step is pushed out of the head to a
//!    distance that grows with the arc length already laid over the head (so hair from the crown
//!    lies over hair from lower down), which makes strands slide over the scalp and fall past it.
//! 3. **Curls and waves** are added around the centreline in a transported frame, as an ellipse
//!    swept with a fixed number of turns per clump (members curl in phase: ringlets).
//! 4. **Clumping** pulls each strand toward its clump's guide (a strand grown from the clump
//!    centre), more strongly toward the tip; a last pass pushes every point but the root at least
//!    [`FINAL_OFFSET`] outside the head.
//!
//! The face stays free: roots at the front are combed away from a middle parting (clumps never
//! straddle it), and a face guard (a box in front of the bundled head's face, [`FACE_GUARD_X`])
//! moves any point that would hang in front of the face out to its side.
//!
//! Each strand draws its random numbers from its own PCG stream seeded by (seed, strand index), so
//! the same seed gives the same bytes with any number of threads.

use glam::Vec3;
use hairrecon_core::scalp::{splitmix64, Root, Scalp};
use hairrecon_core::{StrandSet, TriMesh};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use crate::collide::HeadCollider;
use crate::error::SynthError;
use crate::style::{Style, StyleParams};

/// Default number of strands (the paper's benchmark).
pub const DEFAULT_STRANDS: usize = 50_000;
/// Default number of points per strand.
pub const DEFAULT_POINTS: usize = 100;
/// Least distance from the head of every point but the root after the last pass, metres.
pub const FINAL_OFFSET: f32 = 0.001;
/// A query near the head also looks this many steps ahead, so that the next ones can skip it.
const LOOKAHEAD: f32 = 3.0;
/// Arc length over which the layering offset grows, metres.
const LAYER_LENGTH: f32 = 0.08;
/// The face guard of the bundled head (metres, its frame): in front of `y = FACE_GUARD_Y`, from
/// the chin to the eyebrows, hair keeps at least `FACE_GUARD_X` from the middle.
pub const FACE_GUARD_Y: f32 = -0.03;
/// Heights of the face guard: below the chin, above the eyebrows.
pub const FACE_GUARD_Z: [f32; 2] = [-0.09, 0.075];
/// Half-width of the face guard.
pub const FACE_GUARD_X: f32 = 0.065;
/// Arc length over which a strand is combed back while it lies on the head, metres.
const NEAR_HEAD: f32 = 0.10;
/// Layered cuts ([`StyleParams::layers`]): roots above this height (metres) are cut shorter, fully
/// so `LAYERS_OVER_Z` higher.
const LAYERS_FROM_Z: f32 = 0.06;
const LAYERS_OVER_Z: f32 = 0.09;
/// A ponytail's strands aim at points within this radius of the tie, and fall once this close.
const TIE_RADIUS: f32 = 0.007;
const TIE_REACHED: f32 = 0.012;
/// How deep inside the head a coarse polyline's sample is looked for (metres).
const COARSE_REACH: f32 = 0.02;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthOptions {
    pub style: Style,
    /// The numbers of the style; [`Style::params`] unless tuned.
    pub params: StyleParams,
    pub strands: usize,
    pub points: usize,
    pub seed: u64,
}

impl SynthOptions {
    /// The defaults for a style: its preset, 50,000 strands of 100 points, seed 1.
    pub fn new(style: Style) -> Self {
        Self { style, params: style.params(), strands: DEFAULT_STRANDS, points: DEFAULT_POINTS, seed: 1 }
    }

    fn validate(&self) -> Result<(), SynthError> {
        self.params.validate()?;
        if self.strands == 0 {
            return Err(SynthError::Param("ask for at least one strand".into()));
        }
        if !(3..=100_000).contains(&self.points) {
            return Err(SynthError::Param(format!("points per strand must be 3 to 100000, got {}", self.points)));
        }
        Ok(())
    }
}

/// The head and scalp made ready for generating many hairstyles.
#[derive(Debug, Clone)]
pub struct HairGenerator {
    collider: HeadCollider,
    scalp: Scalp,
}

/// Per clump: where it grows from and what its members share.
struct Clump {
    root: Root,
    length: f32,
    phase: f32,
    turns: f32,
    guide: Vec<Vec3>,
}

impl HairGenerator {
    /// Prepares the head (welded, with a BVH) and the scalp (normals, growth field, sampler).
    pub fn new(head: &TriMesh, scalp: TriMesh) -> Result<Self, SynthError> {
        Ok(Self { collider: HeadCollider::new(head), scalp: Scalp::new(scalp)? })
    }

    pub fn collider(&self) -> &HeadCollider {
        &self.collider
    }

    pub fn scalp(&self) -> &Scalp {
        &self.scalp
    }

    /// Generates a hairstyle. `progress` is called from worker threads with the number of strands
    /// finished so far (not in order).
    pub fn generate(&self, opts: &SynthOptions, progress: &(dyn Fn(usize) + Sync)) -> Result<StrandSet, SynthError> {
        opts.validate()?;
        let prm = &opts.params;
        let n = opts.points;
        let roots = self.scalp.sample_roots(opts.strands, opts.seed)?;
        let n_clumps = ((opts.strands as f32 / prm.clump_size).round() as usize).clamp(1, opts.strands);
        let clump_roots = self.scalp.sample_roots(n_clumps, splitmix64(opts.seed ^ 0xC1A5_0000))?;
        let clumps: Vec<Clump> = clump_roots
            .into_par_iter()
            .enumerate()
            .map(|(i, root)| {
                let mut rng = strand_rng(opts.seed, i as u64, 1);
                let length = prm.length
                    * (1.0 + prm.length_jitter * rng.random_range(-1.0f32..1.0))
                    * (1.0 - prm.layers * smoothstep((root.position.z - LAYERS_FROM_Z) / LAYERS_OVER_Z));
                // Waves line up across neighbouring clumps when the phase follows the root's height
                // (a strand reaches a given height after about its root's height of arc length).
                let spatial = -std::f32::consts::TAU * root.position.z / prm.curl_period;
                let phase = spatial * prm.wave_coherence
                    + rng.random_range(0.0..std::f32::consts::TAU) * (1.0 - prm.wave_coherence);
                let turns = length / prm.curl_period;
                let (guide, _) = self.strand(prm, &root, length, phase, turns, n, 0.6, &mut rng);
                Clump { root, length, phase, turns, guide }
            })
            .collect();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let strands: Vec<Vec<Vec3>> = roots
            .par_iter()
            .enumerate()
            .map(|(i, root)| {
                let mut rng = strand_rng(opts.seed, i as u64, 2);
                let c = &clumps[nearest(&clumps, root, prm)];
                let length = c.length * (1.0 + 0.06 * rng.random_range(-1.0f32..1.0));
                let phase = c.phase + 0.35 * rng.random_range(-1.0f32..1.0);
                let layer = rng.random_range(0.3f32..1.0);
                let (mut pts, bounds) = self.strand(prm, root, length, phase, c.turns, n, layer, &mut rng);
                // Clumping: toward the guide, more toward the tip.
                let strength = prm.clump_strength * rng.random_range(0.6f32..1.0);
                for (k, p) in pts.iter_mut().enumerate().skip(1) {
                    let t = k as f32 / (n - 1) as f32;
                    let w = strength * smoothstep(t / 0.6) * (0.5 + 0.5 * t);
                    let moved = p.lerp(c.guide[k], w);
                    let moved = face_guard(moved, side_of(*p)).unwrap_or(moved);
                    // The point was at least `offset` outside before this move: it can only have
                    // gone as deep as the move is long.
                    let step = moved.distance(*p);
                    *p = if bounds[k] - step >= FINAL_OFFSET {
                        moved
                    } else {
                        self.collider.push_out(moved, FINAL_OFFSET, step + FINAL_OFFSET)
                    };
                }
                let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if d.is_multiple_of(1024) || d == roots.len() {
                    progress(d);
                }
                pts
            })
            .collect();
        let counts = vec![n as u32; strands.len()];
        let hair = StrandSet::new(strands.concat(), counts)?;
        if prm.polyline_points < 2 {
            return Ok(hair);
        }
        // Coarse polylines: samples on the fine strand, pushed out where a sample cut across a
        // crease of the head (the ears).
        let (mut points, counts) = hair.resample_to_count(prm.polyline_points)?.into_parts();
        points.par_chunks_mut(prm.polyline_points).for_each(|s| {
            for p in &mut s[1..] {
                *p = self.collider.push_out(*p, FINAL_OFFSET, COARSE_REACH);
            }
        });
        Ok(StrandSet::new(points, counts)?)
    }

    /// One strand: grown centreline plus curls, not yet clumped; with a lower bound on each
    /// point's distance from the head.
    fn strand(
        &self,
        prm: &StyleParams,
        root: &Root,
        length: f32,
        phase: f32,
        turns: f32,
        n: usize,
        layer: f32,
        rng: &mut Pcg64Mcg,
    ) -> (Vec<Vec3>, Vec<f32>) {
        let h = length / (n - 1) as f32;
        // A step from a point outside the head cannot end deeper inside than its length.
        let reach = 1.5 * h;
        let mut bound = 0.0f32;
        let curl_max = prm.curl_radius[0].max(prm.curl_radius[1]);
        let side = if root.position.x >= prm.parting_x { Vec3::X } else { Vec3::NEG_X };
        let front = front_weight(root.position, prm.part_back);
        // A ponytail: each strand aims at its own point of the tie, until it gets there.
        let mut tie = prm.tie.map(|t| {
            let a = rng.random_range(0.0..std::f32::consts::TAU);
            let r = TIE_RADIUS * rng.random_range(0.0f32..1.0).sqrt();
            t + Vec3::new(r * a.cos(), 0.0, r * a.sin())
        });
        // Combing back acts on hair from the top of the head, not on hair that already falls.
        let top = root.normal.z.max(0.0);
        // (A take-off of zero adds exact zeros: the other styles' bytes do not change.)
        let mut d = (root.direction + prm.takeoff * root.normal + 0.15 * rand_cube(rng)).normalize_or(root.direction);
        if d.dot(root.normal) < 0.2 {
            d = (d + 0.5 * root.normal).normalize_or(root.normal);
        }
        let mut c = Vec::with_capacity(n);
        c.push(root.position);
        // Lower bounds on each point's distance from the head.
        let mut bounds = Vec::with_capacity(n);
        bounds.push(0.0);
        let mut p = root.position;
        for k in 1..n {
            let s = k as f32 * h;
            let t = s / length;
            // Near the head: combed back, and away from the parting until beside the face.
            let near = 1.0 - smoothstep((s - NEAR_HEAD) / NEAR_HEAD);
            let beside = 1.0 - smoothstep((p.x.abs() - 0.04) / 0.05);
            let mut target =
                prm.gravity * Vec3::NEG_Z + prm.back * near * top * Vec3::Y + prm.part * front * beside * side;
            if let Some(t) = tie {
                if p.distance(t) < TIE_REACHED {
                    tie = None;
                } else {
                    target = (t - p).normalize_or(Vec3::Y) * 4.0 + 0.2 * Vec3::NEG_Z;
                }
            }
            if prm.tip_under > 0.0 {
                let radial = Vec3::new(p.x, p.y, 0.0).normalize_or_zero();
                target -= prm.tip_under * smoothstep((t - 0.6) / 0.4) * radial;
            }
            // Near the head, hair lies along it: drop the part of the target that leaves the scalp.
            target -= near * root.normal * target.dot(root.normal).max(0.0);
            let target = target.normalize_or(Vec3::NEG_Z);
            let bend = prm.bend_free + (prm.bend_root - prm.bend_free) * (-s / prm.stiff_len).exp();
            d = turn_toward(d, target, 1.0 - (-h / bend).exp(), root.normal);
            d = (d + prm.frizz * rand_cube(rng)).normalize_or(d);
            let off_full = prm.offset
                + curl_max * smoothstep(s / prm.curl_ramp)
                + prm.volume * layer * (1.0 - (-s / LAYER_LENGTH).exp());
            let off = off_full.min(prm.offset + 0.5 * s);
            let mut q = p + h * d;
            // `bound` is a lower bound on the distance from the head (distance is 1-Lipschitz):
            // ask the BVH only when a step may have come closer than `off`.
            bound -= h;
            if bound < off {
                let (pushed, b) = self.collider.push_out_bound(q, off, reach.max(off + LOOKAHEAD * h));
                bound = b;
                if pushed != q {
                    d = (pushed - p).normalize_or(d);
                    (q, bound) = self.collider.push_out_bound(p + h * d, off, reach);
                }
            }
            if let Some(g) = face_guard(q, side_of(p)) {
                d = (g - p).normalize_or(d);
                q = g;
                bound = 0.0;
            }
            c.push(q);
            bounds.push(bound);
            p = q;
        }
        if curl_max <= 0.0 {
            return (c, bounds);
        }
        // Curls: an ellipse swept around the centreline in a frame carried along it.
        let mut out = Vec::with_capacity(n);
        out.push(c[0]);
        let t0 = (c[1] - c[0]).normalize_or(root.direction);
        let mut e1 = root.normal.cross(t0).normalize_or_zero();
        if e1 == Vec3::ZERO {
            e1 = t0.any_orthonormal_vector();
        }
        for k in 1..n {
            let tan = (c[(k + 1).min(n - 1)] - c[k - 1]).normalize_or(t0);
            e1 = (e1 - tan * tan.dot(e1)).normalize_or(tan.any_orthonormal_vector());
            let e2 = tan.cross(e1);
            let u = k as f32 / (n - 1) as f32;
            let phi = phase + std::f32::consts::TAU * turns * u;
            let r = smoothstep(k as f32 * h / prm.curl_ramp);
            let off = prm.curl_radius[0] * phi.cos() * e1 + prm.curl_radius[1] * phi.sin() * e2;
            out.push(c[k] + r * off);
            bounds[k] -= r * off.length();
        }
        (out, bounds)
    }
}

/// Generates a hairstyle on `head` with roots on `scalp` (see [`HairGenerator`]).
pub fn generate(head: &TriMesh, scalp: &TriMesh, opts: &SynthOptions) -> Result<StrandSet, SynthError> {
    HairGenerator::new(head, scalp.clone())?.generate(opts, &|_| {})
}

/// Index of the clump whose centre is nearest to `root`, on the same side of the middle parting
/// when either lies at the front (so that no clump pulls hair across the face).
fn nearest(clumps: &[Clump], root: &Root, prm: &StyleParams) -> usize {
    let p = root.position;
    let (px, back) = (prm.parting_x, prm.part_back);
    let mut best = (f32::INFINITY, 0);
    for (i, c) in clumps.iter().enumerate() {
        let q = c.root.position;
        let split = (p.x >= px) != (q.x >= px) && (front_weight(p, back) > 0.0 || front_weight(q, back) > 0.0);
        let d = q.distance_squared(p) + if split { 1.0 } else { 0.0 };
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// How much a root counts as "at the front" (combed away from the parting): 1 in front of
/// `part_back − 0.08` m, 0 behind `part_back` (the default 0.06 m: near the whorl).
fn front_weight(p: Vec3, part_back: f32) -> f32 {
    smoothstep((part_back - p.y) / 0.08)
}

/// The side of the middle parting that `p` is on.
fn side_of(p: Vec3) -> Vec3 {
    if p.x >= 0.0 {
        Vec3::X
    } else {
        Vec3::NEG_X
    }
}

/// The face guard: a point in front of the face (`y < FACE_GUARD_Y`, between `FACE_GUARD_Z`) that
/// is closer to the middle than `FACE_GUARD_X` is moved sideways, to the given side (that of the
/// point before it, so the move is short), onto that half-width. Returns `None` when the point is not in front of the face.
fn face_guard(p: Vec3, side: Vec3) -> Option<Vec3> {
    let inside = p.y < FACE_GUARD_Y && p.z > FACE_GUARD_Z[0] && p.z < FACE_GUARD_Z[1] && p.x.abs() < FACE_GUARD_X;
    inside.then(|| Vec3::new(side.x * FACE_GUARD_X, p.y, p.z))
}

/// `d` turned toward `target` by the fraction `frac` of the angle between them (both unit). When
/// they are opposite, the turn is about an axis perpendicular to `d` and `hint`.
fn turn_toward(d: Vec3, target: Vec3, frac: f32, hint: Vec3) -> Vec3 {
    let cos = d.dot(target).clamp(-1.0, 1.0);
    let angle = cos.acos();
    if angle < 1e-6 {
        return target;
    }
    let mut axis = d.cross(target);
    if axis.length_squared() < 1e-10 {
        axis = d.cross(hint);
        if axis.length_squared() < 1e-10 {
            axis = d.any_orthonormal_vector();
        }
    }
    glam::Quat::from_axis_angle(axis.normalize(), angle * frac) * d
}

/// The random stream of one strand: PCG-64 (MCG variant) seeded from (seed, index, stream).
fn strand_rng(seed: u64, index: u64, stream: u64) -> Pcg64Mcg {
    let s = splitmix64(splitmix64(seed) ^ splitmix64(index.wrapping_mul(8).wrapping_add(stream)));
    Pcg64Mcg::seed_from_u64(s)
}

fn rand_cube(rng: &mut Pcg64Mcg) -> Vec3 {
    Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
}

#[inline]
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}
