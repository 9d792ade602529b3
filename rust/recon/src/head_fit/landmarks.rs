//! Landmarks: the help a user gives when the automatic pose fails. A few points placed on the raw
//! mesh (the nose tip, the chin, the outer corners of the eyes, the ear openings), in the capture's
//! own frame and units, give the template's pose in closed form (Umeyama's similarity between the
//! template's landmarks and the user's, as the paper's fit starts); the fit then refines that pose
//! as it refines the search's best (ICP on all the skin, the scale probes, the face), with no
//! search.
//!
//! The file: `landmarks.json` beside the capture's `capture.json` (or `hairrecon fit-head
//! --landmarks FILE`), an object from landmark names to `[x, y, z]`; any three or more of
//! [`NAMES`]. Left and right are the subject's own.

use std::path::{Path, PathBuf};

use glam::DVec3;
use thiserror::Error;

use super::umeyama::umeyama;
use super::Similarity;

/// The file a capture's landmarks are read from, beside its capture.json.
pub const LANDMARKS_JSON: &str = "landmarks.json";

/// The landmarks a user may give, and where they lie on the bundled head (canonical frame, metres;
/// read off `blend_fixtures/head.ply`: the nose's most forward point, the chin's most forward point
/// 7 cm below the nose, the outer corners of the eyelids, the bottom of each ear's opening by the
/// tragus).
pub const BUNDLED: [(&str, [f64; 3]); 6] = [
    ("nose_tip", [0.0, -0.1203, 0.0096]),
    ("chin", [0.0, -0.0926, -0.0598]),
    ("eye_outer_left", [0.0490, -0.0802, 0.0519]),
    ("eye_outer_right", [-0.0490, -0.0802, 0.0519]),
    ("ear_left", [0.0777, 0.0108, 0.0342]),
    ("ear_right", [-0.0777, 0.0108, 0.0342]),
];

/// The names [`BUNDLED`] knows.
pub const NAMES: [&str; 6] = [BUNDLED[0].0, BUNDLED[1].0, BUNDLED[2].0, BUNDLED[3].0, BUNDLED[4].0, BUNDLED[5].0];

/// A landmark placed farther than this (canonical mm) from where the others put it is an error:
/// a wrong name or a swapped side, not a head of another shape (heads differ by a few mm there).
pub const MAX_LANDMARK_ERROR_MM: f64 = 20.0;

/// Why landmarks could not be used.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LandmarkError {
    #[error("cannot read the landmarks {path}: {msg}")]
    Read { path: PathBuf, msg: String },
    #[error(
        "the landmarks {path}: {msg}; give an object of landmark names to [x, y, z] in the capture's frame, \
         three or more of {}",
        NAMES.join(", ")
    )]
    Format { path: PathBuf, msg: String },
    #[error(
        "the landmarks {path}: three or more landmarks not on one line are needed (got {given}); add others of {}",
        NAMES.join(", ")
    )]
    TooFew { path: PathBuf, given: usize },
    #[error(
        "the landmarks {path}: {name} lies {error_mm:.0} mm from where the others put it on the head (at most \
         {max_mm:.0} mm); check its name and its place (left and right are the subject's own: the left eye is on \
         the subject's left, the viewer's right)"
    )]
    Inconsistent { path: PathBuf, name: String, error_mm: f64, max_mm: f64 },
    #[error("the landmarks {path}: the head template given has no landmarks; use the bundled head with landmarks")]
    NoTemplateLandmarks { path: PathBuf },
}

/// Landmarks read from a file: names and points in the capture's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmarks {
    pub path: PathBuf,
    pub points: Vec<(String, DVec3)>,
}

impl Landmarks {
    /// Reads `path` (see the module's text).
    pub fn read(path: &Path) -> Result<Self, LandmarkError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| LandmarkError::Read { path: path.to_path_buf(), msg: e.to_string() })?;
        Self::parse(&text, path)
    }

    /// Parses the JSON `text` (from `path`, for the messages).
    pub fn parse(text: &str, path: &Path) -> Result<Self, LandmarkError> {
        let format = |msg: String| LandmarkError::Format { path: path.to_path_buf(), msg };
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| format(e.to_string()))?;
        let obj = value.as_object().ok_or_else(|| format("not a JSON object".into()))?;
        let mut points = Vec::new();
        for (name, v) in obj {
            if !NAMES.contains(&name.as_str()) {
                return Err(format(format!("unknown landmark {name:?}")));
            }
            let xyz: Option<Vec<f64>> = v.as_array().map(|a| a.iter().filter_map(|x| x.as_f64()).collect());
            match xyz.as_deref() {
                Some(&[x, y, z])
                    if v.as_array().is_some_and(|a| a.len() == 3) && [x, y, z].iter().all(|c| c.is_finite()) =>
                {
                    points.push((name.clone(), DVec3::new(x, y, z)))
                }
                _ => return Err(format(format!("{name} is not three finite numbers"))),
            }
        }
        points.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(Self { path: path.to_path_buf(), points })
    }

    /// The template's pose (template → capture frame) that puts `template`'s landmarks (name, point
    /// in the canonical frame) on these, by Umeyama's similarity, and the landmarks' RMS distance
    /// from it in canonical mm. An error when fewer than three usable landmarks are given or
    /// one lies farther than [`MAX_LANDMARK_ERROR_MM`] from its place.
    pub fn pose(&self, template: &[(String, DVec3)]) -> Result<(Similarity, f64), LandmarkError> {
        if template.is_empty() {
            return Err(LandmarkError::NoTemplateLandmarks { path: self.path.clone() });
        }
        let pairs: Vec<(&str, DVec3, DVec3)> = self
            .points
            .iter()
            .filter_map(|(n, q)| template.iter().find(|(m, _)| m == n).map(|(_, p)| (n.as_str(), *p, *q)))
            .collect();
        let too_few = LandmarkError::TooFew { path: self.path.clone(), given: pairs.len() };
        if pairs.len() < 3 || !spans_a_plane(&pairs.iter().map(|p| p.1).collect::<Vec<_>>()) {
            return Err(too_few);
        }
        let src: Vec<DVec3> = pairs.iter().map(|p| p.1).collect();
        let dst: Vec<DVec3> = pairs.iter().map(|p| p.2).collect();
        let t = umeyama(&src, &dst, true).ok_or(too_few)?;
        // Each landmark's distance from its place, in canonical mm.
        let errors: Vec<f64> = pairs.iter().map(|(_, p, q)| (t.apply(*p) - *q).length() / t.scale * 1e3).collect();
        let (worst, &error_mm) = errors.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).expect("three or more");
        if !t.scale.is_finite() || t.scale <= 0.0 || error_mm > MAX_LANDMARK_ERROR_MM {
            return Err(LandmarkError::Inconsistent {
                path: self.path.clone(),
                name: pairs[worst].0.to_string(),
                error_mm,
                max_mm: MAX_LANDMARK_ERROR_MM,
            });
        }
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        Ok((t, rms))
    }
}

impl Landmarks {
    /// The RMS distance (canonical mm) of these landmarks, mapped by `to_canonical`, from
    /// `template`'s of the same names (how well a fit agrees with them).
    pub fn rms_mm(&self, template: &[(String, DVec3)], to_canonical: &Similarity) -> f64 {
        let d: Vec<f64> = self.each_mm(template, to_canonical).into_iter().flatten().collect();
        (d.iter().map(|x| x * x).sum::<f64>() / d.len().max(1) as f64).sqrt()
    }

    /// Each landmark's distance (canonical mm), mapped by `to_canonical`, from `template`'s of the
    /// same name, in [`NAMES`]' order (`None` where either has none).
    pub fn each_mm(&self, template: &[(String, DVec3)], to_canonical: &Similarity) -> [Option<f64>; NAMES.len()] {
        NAMES.map(|name| {
            let q = self.points.iter().find(|(n, _)| n == name)?.1;
            let p = template.iter().find(|(m, _)| m == name)?.1;
            Some((to_canonical.apply(q) - p).length() * 1e3)
        })
    }
}

/// Whether the points span more than a line (a plane at least): three on a line leave the
/// rotation about it free.
fn spans_a_plane(points: &[DVec3]) -> bool {
    let size = points.iter().flat_map(|a| points.iter().map(move |b| (*a - *b).length())).fold(0.0, f64::max);
    points
        .iter()
        .any(|a| points.iter().any(|b| points.iter().any(|c| (*b - *a).cross(*c - *a).length() > 0.05 * size * size)))
}

/// [`BUNDLED`] as (name, point) pairs.
pub fn bundled() -> Vec<(String, DVec3)> {
    BUNDLED.iter().map(|(n, p)| (n.to_string(), DVec3::from_array(*p))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    fn frame() -> Similarity {
        Similarity {
            scale: 24.6,
            rotation: DMat3::from_axis_angle(DVec3::new(0.2, -0.9, 0.4).normalize(), 2.5),
            translation: DVec3::new(3.0, -40.0, 7.5),
        }
    }

    fn file(points: &[(&str, DVec3)]) -> String {
        let obj: serde_json::Map<String, serde_json::Value> =
            points.iter().map(|(n, p)| (n.to_string(), serde_json::json!(p.to_array()))).collect();
        serde_json::Value::Object(obj).to_string()
    }

    #[test]
    fn three_landmarks_in_a_capture_frame_give_its_pose() {
        let to_capture = frame();
        let mut given: Vec<(&str, DVec3)> =
            BUNDLED[..3].iter().map(|(n, p)| (*n, to_capture.apply(DVec3::from_array(*p)))).collect();
        // 3 mm of placement error (canonical) on the chin.
        given[1].1 += to_capture.rotation * DVec3::new(0.003, 0.0, 0.0) * to_capture.scale;
        let lm = Landmarks::parse(&file(&given), Path::new("landmarks.json")).unwrap();
        let (t, rms) = lm.pose(&bundled()).unwrap();
        assert!(t.rotation_angle_to(&to_capture) < 3.0, "{}", t.rotation_angle_to(&to_capture));
        assert!((t.scale / to_capture.scale - 1.0).abs() < 0.05, "{}", t.scale);
        assert!(rms > 0.5 && rms < 3.0, "{rms}");
        // Against the true frame: the chin is the 3 mm it was moved, the others on their places, the
        // three not given have no figure, and the RMS is theirs.
        let each = lm.each_mm(&bundled(), &to_capture.inverse());
        assert!(
            (each[1].unwrap() - 3.0).abs() < 1e-6 && each[0].unwrap() < 1e-6 && each[2].unwrap() < 1e-6,
            "{each:?}"
        );
        assert_eq!(each[3..], [None, None, None]);
        assert!((lm.rms_mm(&bundled(), &to_capture.inverse()) - 3.0 / 3f64.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn swapped_sides_name_the_landmark_and_the_convention() {
        let to_capture = frame();
        let place = |n: &str| to_capture.apply(bundled().into_iter().find(|(m, _)| m == n).unwrap().1);
        // The user's left and right taken from the viewer's side.
        let given = [
            ("nose_tip", place("nose_tip")),
            ("chin", place("chin")),
            ("eye_outer_left", place("eye_outer_right")),
            ("eye_outer_right", place("eye_outer_left")),
            ("ear_left", place("ear_right")),
            ("ear_right", place("ear_left")),
        ];
        let lm = Landmarks::parse(&file(&given), Path::new("lm.json")).unwrap();
        let err = lm.pose(&bundled()).unwrap_err().to_string();
        assert!(err.contains("lm.json") && err.contains("subject's own"), "{err}");
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let p = Path::new("x.json");
        let msg = |t: &str| Landmarks::parse(t, p).unwrap_err().to_string();
        assert!(msg(r#"{"nose": [0, 0, 0]}"#).contains("unknown landmark \"nose\""));
        assert!(msg(r#"{"chin": [0, 0]}"#).contains("chin is not three finite numbers"));
        assert!(msg("[1, 2]").contains("not a JSON object"));
        let two = Landmarks::parse(r#"{"chin": [0, 0, 0], "nose_tip": [0, 1, 0]}"#, p).unwrap();
        assert!(matches!(two.pose(&bundled()), Err(LandmarkError::TooFew { given: 2, .. })));
        let none = Landmarks::parse(r#"{"chin": [0, 0, 0], "nose_tip": [0, 1, 0], "ear_left": [1, 0, 0]}"#, p).unwrap();
        assert!(matches!(none.pose(&[]), Err(LandmarkError::NoTemplateLandmarks { .. })));
    }
}
