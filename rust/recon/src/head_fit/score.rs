//! How well a pose explains the raw mesh, knowing that hair and clothes cover skin.
//!
//! A template point mapped onto the raw mesh is in one of three states (lengths in the template's
//! units):
//! - on the surface (within `tau` of it): the skin is seen; cost `(d / tau)²`;
//! - covered: a ray from the point along its outward normal meets the raw surface within
//!   [`COVER_DEPTH`] × the head's size: hair, a collar or a hat lies over the skin, possible
//!   anywhere, so a constant cost [`INSIDE_COST`], less than a violation;
//! - exposed: nothing lies over it, so the cameras would have seen the skin here and did not: the
//!   template pokes out of the capture (or the raw mesh has a hole); cost 1.
//!
//! Hair with volume hangs farther from the nape than [`COVER_DEPTH`] (4-5 cm behind the neck on the
//! volume style): a point whose ray meets the raw surface within [`HIDDEN_DEPTH`] costs as an
//! exposed one, as before, but is not counted in [`PoseScore::outside`], the fraction a fit is
//! refused for. The search ranks poses by the cost alone.
//!
//! A template shrunk inside the raw mesh pays the covered cost everywhere; the true pose pays it
//! only where hair lies, and nothing on the face, ears and neck that the capture shows. The side is
//! told by rays along the template's own normals, never by the raw mesh's: under hair the closest
//! raw triangle is often the inner side of the hair layer, facing the skin.

use glam::DVec3;
use rayon::prelude::*;

use super::icp::Target;
use super::Similarity;

/// The cost of a template point covered by the raw surface (inside it by more than `tau`).
pub const INSIDE_COST: f64 = 0.6;

/// A pose's score over the template points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseScore {
    /// The mean cost, in [0, 1]: lower is better.
    pub cost: f64,
    /// The fraction of points on the surface (within `tau`).
    pub on_surface: f64,
    /// The fraction inside (covered).
    pub inside: f64,
    /// The fraction outside (violations): exposed, with nothing over it within [`HIDDEN_DEPTH`].
    pub outside: f64,
    /// The RMS distance of the points on the surface, template units.
    pub rms_on_surface: f64,
}

/// How far out (template units, as a fraction of the template's radius of gyration) a covering
/// surface may lie: hair's thickness over the skin.
pub const COVER_DEPTH: f64 = 0.5;

/// How far out (as [`COVER_DEPTH`]) a surface over a point makes it hidden, not exposed, in
/// [`PoseScore::outside`]: hair hanging behind the neck. Its cost stays that of an exposed point.
pub const HIDDEN_DEPTH: f64 = 1.0;

/// Scores the pose `t` (template → raw) of `points` with outward unit `normals` (template frame)
/// against `bvh`; `tau` and `radius` (the template's size) in template units.
pub fn score_pose(
    points: &[DVec3],
    normals: &[DVec3],
    bvh: &(impl Target + ?Sized),
    t: &Similarity,
    tau: f64,
    radius: f64,
    parallel: bool,
) -> PoseScore {
    let reach = COVER_DEPTH * radius * t.scale;
    let hidden_reach = HIDDEN_DEPTH * radius * t.scale;
    let one = |(p, n): (&DVec3, &DVec3)| {
        let x = t.apply(*p);
        // Compared in the target's units: a miss reports the cap itself, which divided by the
        // scale could round to just under `tau` and count as on the surface.
        let cap = tau * t.scale;
        let m = bvh.closest(x, cap);
        let d = m.distance / t.scale;
        if m.distance < cap {
            (0u8, d)
        } else if bvh.crosses(x, t.rotation * *n, reach) {
            (1, d)
        } else if bvh.crosses(x, t.rotation * *n, hidden_reach) {
            (2, d)
        } else {
            (3, d)
        }
    };
    let states: Vec<(u8, f64)> = if parallel {
        points.par_iter().zip(normals).map(one).collect()
    } else {
        points.iter().zip(normals).map(one).collect()
    };
    let n = states.len().max(1) as f64;
    let (mut cost, mut on, mut inside, mut outside, mut sq) = (0.0, 0usize, 0usize, 0usize, 0.0);
    for &(s, d) in &states {
        match s {
            0 => {
                on += 1;
                sq += d * d;
                cost += (d / tau).powi(2);
            }
            1 => {
                inside += 1;
                cost += INSIDE_COST;
            }
            2 => cost += 1.0,
            _ => {
                outside += 1;
                cost += 1.0;
            }
        }
    }
    PoseScore {
        cost: cost / n,
        on_surface: on as f64 / n,
        inside: inside as f64 / n,
        outside: outside as f64 / n,
        rms_on_surface: if on > 0 { (sq / on as f64).sqrt() } else { f64::INFINITY },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::head_fit::icp::Match;
    use glam::DMat3;

    /// A target with nothing near anything: every query misses.
    struct Nothing;

    impl Target for Nothing {
        fn closest(&self, p: DVec3, cap: f64) -> Match {
            Match { point: p, normal: DVec3::ZERO, distance: cap }
        }
    }

    /// A plane `gap` above every point, along their normals (+Z): hair standing that far off.
    struct PlaneAbove {
        gap: f64,
    }

    impl Target for PlaneAbove {
        fn closest(&self, p: DVec3, cap: f64) -> Match {
            let d = self.gap.min(cap);
            Match { point: p + d * DVec3::Z, normal: DVec3::Z, distance: d }
        }
        fn crosses(&self, _p: DVec3, dir: DVec3, reach: f64) -> bool {
            dir.z > 0.0 && self.gap / dir.z <= reach
        }
    }

    /// Under a surface 0.3, 0.7 and 1.3 radii out, a point is covered (cost 0.6), hidden (cost 1,
    /// not counted as outside), and exposed (cost 1, outside).
    #[test]
    fn a_point_under_far_hair_costs_as_exposed_but_is_not_outside() {
        let points = vec![DVec3::ZERO; 4];
        let normals = vec![DVec3::Z; 4];
        let t = Similarity { scale: 1.0, rotation: DMat3::IDENTITY, translation: DVec3::ZERO };
        let radius = 0.1;
        let score = |gap_radii: f64| {
            score_pose(&points, &normals, &PlaneAbove { gap: gap_radii * radius }, &t, 0.005, radius, false)
        };
        let covered = score(0.3);
        assert_eq!((covered.inside, covered.outside, covered.cost), (1.0, 0.0, INSIDE_COST));
        let hidden = score(0.7);
        assert_eq!((hidden.inside, hidden.outside, hidden.cost), (0.0, 0.0, 1.0));
        let exposed = score(1.3);
        assert_eq!((exposed.inside, exposed.outside, exposed.cost), (0.0, 1.0, 1.0));
    }

    #[test]
    fn a_miss_is_never_on_the_surface_whatever_the_scale() {
        let points = vec![DVec3::new(0.01, 0.02, 0.03); 4];
        let normals = vec![DVec3::Z; 4];
        for i in 0..200 {
            let t = Similarity { scale: 0.01 + 0.37 * i as f64, rotation: DMat3::IDENTITY, translation: DVec3::ZERO };
            let s = score_pose(&points, &normals, &Nothing, &t, 0.005, 0.1, false);
            assert_eq!((s.on_surface, s.outside, s.cost), (0.0, 1.0, 1.0), "scale {}", t.scale);
        }
    }
}
