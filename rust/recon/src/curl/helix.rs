//! Helices swept about grown strands: each strand's centreline (a box mean over one turn of arc)
//! carries a round helix of the chosen curl, at a seeded random phase per strand.

use glam::Vec3;
use hairrecon_core::strands::{StrandError, StrandSet};
use rayon::prelude::*;

use super::{Curl, CurlOptions};

/// A deterministic phase in [0, 2π) for strand `i`.
pub(super) fn phase(seed: u64, i: usize) -> f32 {
    let mut z = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU
}

/// Replaces each strand by a helix of `curl` about its own centreline: the strand is resampled every
/// `opts.step`, its centreline is the mean over `opts.centre_window` of arc (shrinking at the ends;
/// the root is kept) resampled every `opts.step`, and the helix is swept about it in a frame carried
/// along it, at a random phase per strand (from `seed`), growing to full radius over `opts.ramp`.
/// Strands with fewer than 3 samples are kept as they are.
pub fn sweep_helices(
    strands: &StrandSet,
    curl: &Curl,
    opts: &CurlOptions,
    seed: u64,
) -> Result<StrandSet, StrandError> {
    let step = opts.step;
    let out: Vec<Vec<Vec3>> = (0..strands.num_strands())
        .into_par_iter()
        .map(|i| {
            let s = strands.strand(i);
            let Some(c) = centreline(s, opts.centre_window, step) else { return s.to_vec() };
            helix_about(&c, curl, opts, phase(seed, i))
        })
        .collect();
    let counts = out.iter().map(|s| s.len() as u32).collect();
    StrandSet::new(out.into_iter().flatten().collect(), counts)
}

/// A strand's centreline: the strand resampled every `step`, each sample replaced by the mean of the
/// samples within `window / 2` of arc on both sides (fewer near the ends; the root is kept), then
/// resampled every `step` again. A window of one turn of a round helix gives its axis exactly. `None`
/// for a strand shorter than three samples.
pub fn centreline(s: &[Vec3], window: f32, step: f32) -> Option<Vec<Vec3>> {
    let one = StrandSet::new(s.to_vec(), vec![s.len() as u32]).and_then(|x| x.resample_by_arclength(step)).ok()?;
    let r = one.points();
    if r.len() < 3 {
        return None;
    }
    let half = (window / step).round() as usize / 2;
    let n = r.len();
    let mut cs = vec![Vec3::ZERO; n + 1];
    for k in 0..n {
        cs[k + 1] = cs[k] + r[k];
    }
    let mut c: Vec<Vec3> = (0..n)
        .map(|k| {
            let h = half.min(k).min(n - 1 - k);
            (cs[k + h + 1] - cs[k - h]) / (2 * h + 1) as f32
        })
        .collect();
    c[0] = r[0];
    let c = StrandSet::new(c, vec![n as u32]).and_then(|x| x.resample_by_arclength(step)).ok()?;
    (c.num_points() >= 3).then(|| c.points().to_vec())
}

/// The helix about the centreline `c` (points every `opts.step` of arc).
fn helix_about(c: &[Vec3], curl: &Curl, opts: &CurlOptions, phi0: f32) -> Vec<Vec3> {
    let n = c.len();
    let tangent = |k: usize| {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (c[b] - c[a]).normalize_or_zero()
    };
    let t0 = tangent(0);
    let mut e1 = t0.cross(Vec3::Z);
    if e1.length() < 1e-6 {
        e1 = t0.cross(Vec3::X);
    }
    let mut e1 = e1.normalize_or_zero();
    let mut out = Vec::with_capacity(n);
    for (k, ck) in c.iter().enumerate() {
        let t = tangent(k);
        e1 = (e1 - t * t.dot(e1)).normalize_or(e1);
        let e2 = t.cross(e1);
        let s = k as f32 * opts.step;
        let x = if opts.ramp > 0.0 { (s / opts.ramp).min(1.0) } else { 1.0 };
        let r = curl.radius * x * x * (3.0 - 2.0 * x);
        let phi = phi0 + curl.hand * std::f32::consts::TAU * s / curl.period;
        out.push(*ck + (e1 * phi.cos() + e2 * phi.sin()) * r);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curl::test_util::CURL;

    #[test]
    fn sweep_makes_a_helix_of_the_curl_about_a_straight_strand() {
        let line: Vec<Vec3> = (0..=100).map(|k| Vec3::new(0.0, 0.0, -0.002 * k as f32)).collect();
        let set = StrandSet::new(line, vec![101]).unwrap();
        let out = sweep_helices(&set, &CURL, &CurlOptions::default(), 7).unwrap();
        let h = out.strand(0);
        // Past the ramp: at the radius from the axis, and turning right-handed about -z by one turn
        // per period.
        let past: Vec<&Vec3> = h.iter().filter(|p| p.z < -0.03 && p.z > -0.17).collect();
        assert!(past.len() > 100);
        for p in &past {
            let r = (p.x * p.x + p.y * p.y).sqrt();
            assert!((r - CURL.radius).abs() < 2e-4, "radius {r}");
        }
        let ang = |p: &Vec3| p.y.atan2(p.x);
        let (a, b) = (past[0], past[5]);
        let mut turn = ang(b) - ang(a);
        while turn > std::f32::consts::PI {
            turn -= std::f32::consts::TAU;
        }
        while turn < -std::f32::consts::PI {
            turn += std::f32::consts::TAU;
        }
        // Right-handed about -z is clockwise seen from +z: the angle about +z decreases.
        let expected = -std::f32::consts::TAU * (a.z - b.z) / CURL.period;
        assert!((turn - expected).abs() < 0.05, "turned {turn}, expected {expected}");
        // The root stays where it was; same seed, same output.
        assert!(h[0].distance(Vec3::ZERO) < 1e-6);
        assert_eq!(sweep_helices(&set, &CURL, &CurlOptions::default(), 7).unwrap(), out);
    }
}
