//! NeRF-style `transforms.json` (instant-ngp, nerfstudio): [`read_nerf`] reads one into a
//! [`Scene`]; [`write_transforms`] writes a scene as one.
//!
//! ```json
//! { "camera_model": "OPENCV", "w": 640, "h": 480, "fl_x": 500.0, "fl_y": 500.0,
//!   "cx": 320.0, "cy": 240.0, "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
//!   "frames": [ { "file_path": "images/0001.png",
//!                 "transform_matrix": [[..4..], [..4..], [..4..], [0, 0, 0, 1]] } ] }
//! ```
//!
//! Conventions, converted exactly:
//! - Intrinsics may be given at the top level, per frame, or both (a frame's values win). `w` and
//!   `h` are required. The focal length is `fl_x` or, failing that, `0.5 w / tan(camera_angle_x / 2)`;
//!   `fl_y` likewise from `camera_angle_y`, else equal to the x focal length. `cx`, `cy` default to
//!   `w/2`, `h/2`.
//! - Pixels: both tools cast a pixel's ray through its centre at `(i + 0.5, j + 0.5)` (instant-ngp's
//!   `(x + 0.5) / w` screen coordinates, nerfstudio's `pixel_offset = 0.5`), so the first pixel's
//!   centre is at (0.5, 0.5) and `cx_hairrecon = cx - 0.5` (likewise cy); this is also why a
//!   COLMAP camera's cx is copied unchanged into transforms.json by nerfstudio's converter.
//! - Distortion: `k1 k2 k3 k4 p1 p2` in nerfstudio's OPENCV convention, which is
//!   [`Distortion`]'s (k4 is the r⁸ term). `camera_model` may be absent, `OPENCV`, `PINHOLE` or
//!   `SIMPLE_PINHOLE`; fisheye (`OPENCV_FISHEYE`, `is_fisheye`), `EQUIRECTANGULAR` and other models
//!   are refused.
//! - Poses: `transform_matrix` is camera-to-world with OpenGL/Blender camera axes (x right, y up,
//!   z backward); its y and z columns are negated to get OpenCV axes, then inverted. Its rotation
//!   part must be a rotation (to [`crate::pose::ORTHONORMAL_TOLERANCE`]; it is then made exact).
//! - Ignored: instant-ngp's `aabb_scale`, `scale`, `offset` (they place the scene in its training
//!   cube and do not change the cameras' frame as written) and nerfstudio's `applied_transform`
//!   (the poses are already written in the transformed frame).
//! - Units: [`Units::Unknown`]. Views are named after `file_path`'s file name; the image path is
//!   `file_path` as written (instant-ngp's synthetic scenes omit the extension: it is kept so).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde_json::{json, Map, Value};

use crate::error::ImportError;
use crate::files::{file_name, read_text, write_atomic};
use crate::pose::{self, Mat3};
use crate::scene::{Distortion, Intrinsics, Scene, SceneView, Units};

/// The camera models the reader accepts, for error messages.
pub const SUPPORTED_MODELS: &str = "OPENCV (or no camera_model), PINHOLE, SIMPLE_PINHOLE";

/// Reads a `transforms.json`; see the module documentation.
pub fn read_nerf(transforms: &Path) -> Result<Scene, ImportError> {
    let path = transforms;
    let text = read_text(path)?;
    let root: Value = serde_json::from_str(&text).map_err(|e| ImportError::Parse {
        path: path.to_path_buf(),
        line: e.line() as u64,
        msg: format!("not valid JSON: {e}"),
    })?;
    let invalid = |msg: String| ImportError::Invalid { path: path.to_path_buf(), msg };
    let root = root.as_object().ok_or_else(|| invalid("the top level is not a JSON object".into()))?;
    let frames = root
        .get("frames")
        .and_then(Value::as_array)
        .ok_or_else(|| invalid("there is no \"frames\" list; this is not a NeRF transforms.json".into()))?;
    if root.get("is_fisheye").and_then(Value::as_bool) == Some(true) {
        return Err(ImportError::UnsupportedModel {
            path: path.to_path_buf(),
            camera_id: "(all frames)".into(),
            model: "fisheye (is_fisheye)".into(),
            supported: SUPPORTED_MODELS,
        });
    }
    let mut views = Vec::with_capacity(frames.len());
    let mut names = HashSet::new();
    for (i, frame) in frames.iter().enumerate() {
        let frame = frame.as_object().ok_or_else(|| invalid(format!("frame {i} is not a JSON object")))?;
        let file = frame
            .get("file_path")
            .and_then(Value::as_str)
            .ok_or_else(|| invalid(format!("frame {i} has no \"file_path\" string")))?;
        let view = read_frame(path, i, file, root, frame)?;
        if !names.insert(view.name.clone()) {
            return Err(ImportError::DuplicateImage { path: path.to_path_buf(), name: view.name });
        }
        views.push(view);
    }
    if views.is_empty() {
        return Err(ImportError::NoViews { path: path.to_path_buf() });
    }
    Ok(Scene { views, points: Vec::new(), units: Units::Unknown, warnings: Vec::new() })
}

fn read_frame(
    path: &Path,
    i: usize,
    file: &str,
    root: &Map<String, Value>,
    frame: &Map<String, Value>,
) -> Result<SceneView, ImportError> {
    let invalid =
        |msg: String| ImportError::Invalid { path: path.to_path_buf(), msg: format!("frame {i} ({file:?}): {msg}") };
    // A frame's own value wins over the top level's.
    let get = |key: &str| frame.get(key).or_else(|| root.get(key));
    let num = |key: &str| -> Result<Option<f64>, ImportError> {
        match get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => match v.as_f64().filter(|v| v.is_finite()) {
                Some(x) => Ok(Some(x)),
                None => Err(invalid(format!("\"{key}\" is not a finite number ({v})"))),
            },
        }
    };
    if let Some(model) = get("camera_model") {
        let name = model.as_str().unwrap_or("");
        if !matches!(name, "OPENCV" | "PINHOLE" | "SIMPLE_PINHOLE") {
            return Err(ImportError::UnsupportedModel {
                path: path.to_path_buf(),
                camera_id: format!("frame {i} ({file:?})"),
                model: model.to_string(),
                supported: SUPPORTED_MODELS,
            });
        }
    }
    let size = |key: &str| -> Result<u32, ImportError> {
        match num(key)? {
            Some(v) if v >= 1.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) => Ok(v as u32),
            Some(v) => Err(invalid(format!("\"{key}\" = {v} is not a positive whole number of pixels"))),
            None => Err(invalid(
                "no image size: the importer needs \"w\" and \"h\" (at the top level or in the frame); add them"
                    .to_string(),
            )),
        }
    };
    let (w, h) = (size("w")?, size("h")?);
    let focal = |fl: &str, angle: &str, extent: u32| -> Result<Option<f64>, ImportError> {
        Ok(match (num(fl)?, num(angle)?) {
            (Some(f), _) => Some(f),
            (None, Some(a)) => Some(0.5 * f64::from(extent) / (0.5 * a).tan()),
            (None, None) => None,
        })
    };
    let fx = focal("fl_x", "camera_angle_x", w)?
        .ok_or_else(|| invalid("no focal length: give \"fl_x\" or \"camera_angle_x\"".into()))?;
    let fy = focal("fl_y", "camera_angle_y", h)?.unwrap_or(fx);
    if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite()) {
        return Err(invalid(format!("the focal length ({fx}, {fy}) is not positive")));
    }
    let cx = num("cx")?.unwrap_or(f64::from(w) / 2.0) - 0.5;
    let cy = num("cy")?.unwrap_or(f64::from(h) / 2.0) - 0.5;
    let z = |key: &str| -> Result<f64, ImportError> { Ok(num(key)?.unwrap_or(0.0)) };
    let distortion = Distortion { k: [z("k1")?, z("k2")?, z("k3")?, z("k4")?], d: [0.0; 3], p: [z("p1")?, z("p2")?] };

    let m = frame
        .get("transform_matrix")
        .and_then(Value::as_array)
        .ok_or_else(|| invalid("no \"transform_matrix\"".into()))?;
    let rows: Option<Vec<Vec<f64>>> =
        m.iter().map(|r| r.as_array().and_then(|r| r.iter().map(Value::as_f64).collect())).collect();
    let rows = rows
        .filter(|r| (r.len() == 3 || r.len() == 4) && r.iter().all(|row| row.len() == 4))
        .ok_or_else(|| invalid("\"transform_matrix\" is not a 4x4 (or 3x4) array of numbers".into()))?;
    let bad_pose = |msg: String| ImportError::BadPose { path: path.to_path_buf(), image: file.to_string(), msg };
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad_pose("the transform_matrix is not finite (NaN pose)".into()));
    }
    if rows.len() == 4 && rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(bad_pose(format!("the last row of transform_matrix is {:?}, not [0, 0, 0, 1]", rows[3])));
    }
    // OpenGL camera axes to OpenCV: negate the y and z columns of the camera-to-world rotation.
    let c2w: Mat3 = [0, 1, 2].map(|i| [rows[i][0], -rows[i][1], -rows[i][2]]);
    let c2w = pose::nearest_rotation(&c2w).map_err(bad_pose)?;
    let r = pose::transpose(&c2w);
    let t = pose::translation(&r, &[rows[0][3], rows[1][3], rows[2][3]]);
    Ok(SceneView {
        name: file_name(file).to_string(),
        image: PathBuf::from(file),
        width: w,
        height: h,
        intrinsics: Intrinsics { fx, fy, cx, cy, skew: 0.0 },
        distortion,
        r,
        t,
    })
}

/// Writes `scene` as a nerfstudio-style `transforms.json` with `camera_model` OPENCV and every
/// frame's intrinsics in the frame. Numbers are written in their shortest exact form.
///
/// transforms.json has no skew and no rational distortion: a view with either cannot be written.
pub fn write_transforms(path: &Path, scene: &Scene) -> Result<(), ImportError> {
    let mut frames = Vec::with_capacity(scene.views.len());
    for v in &scene.views {
        let unwritable =
            |msg: &str| ImportError::Unwritable { path: path.to_path_buf(), view: v.name.clone(), msg: msg.into() };
        let (k, d) = (&v.intrinsics, &v.distortion);
        if k.skew != 0.0 {
            return Err(unwritable("has skew, which transforms.json cannot hold"));
        }
        if d.d != [0.0; 3] {
            return Err(unwritable("has a rational distortion denominator, which transforms.json cannot hold"));
        }
        let file = v.image.to_str().ok_or_else(|| unwritable("has an image path that is not UTF-8"))?;
        let c2w = pose::transpose(&v.r);
        let c = pose::centre(&v.r, &v.t);
        let m: Vec<Vec<f64>> = (0..3)
            .map(|i| vec![c2w[i][0], -c2w[i][1], -c2w[i][2], c[i]])
            .chain(std::iter::once(vec![0.0, 0.0, 0.0, 1.0]))
            .collect();
        frames.push(json!({
            "file_path": file.replace('\\', "/"),
            "w": v.width,
            "h": v.height,
            "fl_x": k.fx,
            "fl_y": k.fy,
            "cx": k.cx + 0.5,
            "cy": k.cy + 0.5,
            "k1": d.k[0],
            "k2": d.k[1],
            "k3": d.k[2],
            "k4": d.k[3],
            "p1": d.p[0],
            "p2": d.p[1],
            "transform_matrix": m,
        }));
    }
    let doc = json!({ "camera_model": "OPENCV", "frames": frames });
    let mut text = serde_json::to_string_pretty(&doc).expect("JSON values always serialize");
    text.push('\n');
    write_atomic(path, text.as_bytes())
}
