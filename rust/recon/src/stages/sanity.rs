//! The last check of a strand stage's output before it is saved: strands that no hair can be
//! (none at all, strands far outside the raw mesh, strands that barely
//! leave the scalp) stop the run with [`ReconError::Degenerate`] naming the stage and the likely
//! cause, instead of a result that only looks like one.

use glam::Vec3;
use hairrecon_core::StrandSet;

use crate::config::Stage;
use crate::error::ReconError;

/// How far strand points may lie outside the raw mesh's bounding box, as a fraction of its diagonal.
const OUTSIDE_MARGIN: f32 = 0.5;
/// The median strand length below which the strands are stubs, in metres.
const MIN_MEDIAN_LENGTH: f32 = 0.005;

/// Checks `strands` (the stage's `what`, e.g. "strands") against the raw mesh's box `(lo, hi)`.
pub fn check_strands(stage: Stage, what: &str, strands: &StrandSet, raw_box: (Vec3, Vec3)) -> Result<(), ReconError> {
    let fail = |msg: String| Err(ReconError::Degenerate { stage, msg: format!("{what}: {msg}") });
    if strands.num_strands() == 0 {
        return fail(
            "none were made; check that the scalp mesh lies under the raw mesh's hair and that the masks show hair"
                .into(),
        );
    }
    let (lo, hi) = raw_box;
    let margin = OUTSIDE_MARGIN * (hi - lo).length();
    let outside = strands.points().iter().map(|p| (*p - p.clamp(lo, hi)).length()).fold(0.0f32, f32::max);
    if outside > margin {
        return fail(format!(
            "points reach {outside:.3} m outside the raw mesh's box (more than half its diagonal); the strands \
             left the head: check that the scalp, the raw mesh and the cameras are in one frame and unit"
        ));
    }
    let median = strands.length_stats().map_or(0.0, |s| s.median);
    if median < MIN_MEDIAN_LENGTH {
        return fail(format!(
            "their median length is {:.1} mm; they barely leave the scalp: check that the raw mesh covers the hair \
             (not only the scalp) and that the masks show it",
            median * 1e3
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` strands of 21 points hanging down `length` metres from the top of a 0.2 m box.
    fn hanging(n: usize, length: f32) -> StrandSet {
        let mut pts = Vec::new();
        for i in 0..n {
            for j in 0..21 {
                pts.push(Vec3::new(0.01 * i as f32, 0.0, 0.2 - length * j as f32 / 20.0));
            }
        }
        StrandSet::new(pts, vec![21; n]).unwrap()
    }

    const BOX: (Vec3, Vec3) = (Vec3::new(-0.1, -0.1, 0.0), Vec3::new(0.1, 0.1, 0.2));

    fn message(r: Result<(), ReconError>) -> String {
        match r {
            Err(e @ ReconError::Degenerate { stage: Stage::Init, .. }) => e.to_string(),
            other => panic!("expected a degenerate init, got {other:?}"),
        }
    }

    #[test]
    fn plausible_strands_pass_and_each_kind_of_nonsense_is_named() {
        // Hair 0.3 m long hangs below the box: 0.1 m outside, within half the 0.35 m diagonal.
        check_strands(Stage::Init, "strands", &hanging(10, 0.3), BOX).unwrap();
        let empty = StrandSet::new(Vec::new(), Vec::new()).unwrap();
        assert!(message(check_strands(Stage::Init, "guides", &empty, BOX)).contains("guides: none were made"));
        // 150 m strands (a scalp in millimetres read as metres).
        let long = message(check_strands(Stage::Init, "strands", &hanging(10, 150.0), BOX));
        assert!(long.contains("149.8") && long.contains("outside the raw mesh"), "{long}");
        let stubs = message(check_strands(Stage::Init, "strands", &hanging(10, 0.002), BOX));
        assert!(stubs.contains("median length is 2.0 mm"), "{stubs}");
    }
}
