//! Capture folders: hairrecon's input format.
//!
//! A capture is a folder with a `capture.json` that lists calibrated views and the meshes of the
//! scene. Paths in the JSON are relative to the folder. Units are metres; cameras follow the OpenCV
//! convention (`x_img = K (R X + t)`, pixel centres at integers).
//!
//! ```json
//! {
//!   "version": 1,
//!   "units": "metres",
//!   "convention": "opencv",
//!   "views": [
//!     { "name": "view_000", "image": "images/view_000.png", "mask": "masks/view_000.png",
//!       "width": 341, "height": 512,
//!       "K": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "R": [[...], [...], [...]], "t": [tx, ty, tz],
//!       "gt_orientation": "gt/orientation/view_000.exr", "gt_depth": "gt/depth/view_000.exr" }
//!   ],
//!   "raw_mesh": "raw_mesh.ply",
//!   "head_mesh": "head.ply",
//!   "scalp_mesh": "scalp.ply",
//!   "gt_strands": "gt/strands.hair"
//! }
//! ```
//!
//! `mask`, `head_mesh`, `scalp_mesh`, `gt_*` are optional. [`Capture::load`] checks everything a
//! later stage relies on, once: the JSON's shape, that every named file exists, that each image has
//! the size its view states, and that every camera is valid. Each problem is one error that names
//! the view and the file.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::camera::{Camera, CameraError};

/// The capture format version this library reads and writes.
pub const CAPTURE_VERSION: u32 = 1;

/// Why a capture could not be loaded.
#[derive(Debug, Error)]
pub enum CaptureError {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path} is not a valid capture.json: {source}")]
    Json { path: PathBuf, source: serde_json::Error },
    #[error("{path}: unsupported capture version {found} (this hairrecon reads version {CAPTURE_VERSION})")]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: units must be \"metres\" (found {found:?}); convert the capture to metres")]
    Units { path: PathBuf, found: String },
    #[error("{path}: convention must be \"opencv\" (found {found:?})")]
    Convention { path: PathBuf, found: String },
    #[error("{path}: the capture has no views; list at least one calibrated view")]
    NoViews { path: PathBuf },
    #[error("view {view:?}: its {what} file {file} does not exist")]
    MissingFile { view: String, what: &'static str, file: PathBuf },
    #[error("the capture's {what} file {file} does not exist")]
    MissingMesh { what: &'static str, file: PathBuf },
    #[error("view {view:?}: {file} is {got_w}x{got_h} pixels but capture.json says {width}x{height}")]
    SizeMismatch { view: String, file: PathBuf, width: u32, height: u32, got_w: u32, got_h: u32 },
    #[error("view {view:?}: cannot read the image {file}: {msg}")]
    BadImage { view: String, file: PathBuf, msg: String },
    #[error("view {view:?} in {path}: invalid camera: {source}")]
    Camera { view: String, path: PathBuf, source: CameraError },
    #[error("{path}: two views are named {view:?}; view names must be unique")]
    DuplicateView { path: PathBuf, view: String },
}

/// One view as written in capture.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewSpec {
    pub name: String,
    pub image: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<PathBuf>,
    pub width: u32,
    pub height: u32,
    #[serde(rename = "K")]
    pub k: [[f32; 3]; 3],
    #[serde(rename = "R")]
    pub r: [[f32; 3]; 3],
    pub t: [f32; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt_orientation: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt_depth: Option<PathBuf>,
}

/// capture.json as written on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureSpec {
    pub version: u32,
    pub units: String,
    pub convention: String,
    pub views: Vec<ViewSpec>,
    pub raw_mesh: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head_mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scalp_mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt_strands: Option<PathBuf>,
}

/// A validated view: its camera and the absolute paths of its files.
#[derive(Debug, Clone)]
pub struct View {
    pub name: String,
    pub camera: Camera,
    pub image: PathBuf,
    pub mask: Option<PathBuf>,
    pub gt_orientation: Option<PathBuf>,
    pub gt_depth: Option<PathBuf>,
}

/// A validated capture. Paths are absolute (joined to the capture folder).
#[derive(Debug, Clone)]
pub struct Capture {
    pub dir: PathBuf,
    pub views: Vec<View>,
    pub raw_mesh: PathBuf,
    pub head_mesh: Option<PathBuf>,
    pub scalp_mesh: Option<PathBuf>,
    pub gt_strands: Option<PathBuf>,
}

impl Capture {
    /// Loads and validates `dir/capture.json` (or the given JSON file itself).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, CaptureError> {
        let path = path.as_ref();
        let json = if path.is_dir() { path.join("capture.json") } else { path.to_path_buf() };
        let dir = json.parent().map(Path::to_path_buf).unwrap_or_default();
        let text = std::fs::read_to_string(&json).map_err(|source| CaptureError::Io { path: json.clone(), source })?;
        let spec: CaptureSpec =
            serde_json::from_str(&text).map_err(|source| CaptureError::Json { path: json.clone(), source })?;
        Self::from_spec(spec, &dir, &json)
    }

    /// Validates a parsed spec whose relative paths are under `dir`; `json` names the file in errors.
    pub fn from_spec(spec: CaptureSpec, dir: &Path, json: &Path) -> Result<Self, CaptureError> {
        if spec.version != CAPTURE_VERSION {
            return Err(CaptureError::Version { path: json.into(), found: spec.version });
        }
        if spec.units != "metres" && spec.units != "meters" {
            return Err(CaptureError::Units { path: json.into(), found: spec.units });
        }
        if !spec.convention.eq_ignore_ascii_case("opencv") {
            return Err(CaptureError::Convention { path: json.into(), found: spec.convention });
        }
        if spec.views.is_empty() {
            return Err(CaptureError::NoViews { path: json.into() });
        }
        let mut names = std::collections::HashSet::new();
        let mut views = Vec::with_capacity(spec.views.len());
        for v in spec.views {
            if !names.insert(v.name.clone()) {
                return Err(CaptureError::DuplicateView { path: json.into(), view: v.name });
            }
            let camera = Camera::new(v.k, v.r, v.t, v.width, v.height).map_err(|source| CaptureError::Camera {
                view: v.name.clone(),
                path: json.into(),
                source,
            })?;
            let image = dir.join(&v.image);
            check_image(&v.name, "image", &image, v.width, v.height)?;
            let mask = v.mask.map(|m| dir.join(m));
            if let Some(m) = &mask {
                check_image(&v.name, "mask", m, v.width, v.height)?;
            }
            let gt_orientation = v.gt_orientation.map(|p| dir.join(p));
            let gt_depth = v.gt_depth.map(|p| dir.join(p));
            for (what, p) in [("gt_orientation", &gt_orientation), ("gt_depth", &gt_depth)] {
                if let Some(p) = p {
                    if !p.is_file() {
                        return Err(CaptureError::MissingFile { view: v.name.clone(), what, file: p.clone() });
                    }
                }
            }
            views.push(View { name: v.name, camera, image, mask, gt_orientation, gt_depth });
        }
        let raw_mesh = dir.join(&spec.raw_mesh);
        if !raw_mesh.is_file() {
            return Err(CaptureError::MissingMesh { what: "raw_mesh", file: raw_mesh });
        }
        let opt = |what: &'static str, p: Option<PathBuf>| -> Result<Option<PathBuf>, CaptureError> {
            match p.map(|p| dir.join(p)) {
                Some(f) if !f.is_file() => Err(CaptureError::MissingMesh { what, file: f }),
                other => Ok(other),
            }
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            views,
            raw_mesh,
            head_mesh: opt("head_mesh", spec.head_mesh)?,
            scalp_mesh: opt("scalp_mesh", spec.scalp_mesh)?,
            gt_strands: opt("gt_strands", spec.gt_strands)?,
        })
    }
}

fn check_image(view: &str, what: &'static str, file: &Path, width: u32, height: u32) -> Result<(), CaptureError> {
    if !file.is_file() {
        return Err(CaptureError::MissingFile { view: view.into(), what, file: file.into() });
    }
    let (got_w, got_h) = image::image_dimensions(file).map_err(|e| CaptureError::BadImage {
        view: view.into(),
        file: file.into(),
        msg: e.to_string(),
    })?;
    if (got_w, got_h) != (width, height) {
        return Err(CaptureError::SizeMismatch { view: view.into(), file: file.into(), width, height, got_w, got_h });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_png(path: &Path, w: u32, h: u32) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        image::RgbImage::new(w, h).save(path).unwrap();
    }

    fn spec() -> CaptureSpec {
        CaptureSpec {
            version: 1,
            units: "metres".into(),
            convention: "opencv".into(),
            views: vec![ViewSpec {
                name: "v0".into(),
                image: "images/v0.png".into(),
                mask: Some("masks/v0.png".into()),
                width: 4,
                height: 6,
                k: [[10.0, 0.0, 1.5], [0.0, 10.0, 2.5], [0.0, 0.0, 1.0]],
                r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                t: [0.0, 0.0, 1.0],
                gt_orientation: None,
                gt_depth: None,
            }],
            raw_mesh: "raw_mesh.ply".into(),
            head_mesh: None,
            scalp_mesh: None,
            gt_strands: None,
        }
    }

    fn setup(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("hairrecon-capture-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        write_png(&dir.join("images/v0.png"), 4, 6);
        write_png(&dir.join("masks/v0.png"), 4, 6);
        std::fs::write(dir.join("raw_mesh.ply"), b"ply\n").unwrap();
        dir
    }

    fn load(dir: &Path, s: &CaptureSpec) -> Result<Capture, CaptureError> {
        std::fs::write(dir.join("capture.json"), serde_json::to_string_pretty(s).unwrap()).unwrap();
        Capture::load(dir)
    }

    #[test]
    fn loads_a_valid_capture_and_names_each_problem() {
        let dir = setup("valid");
        let c = load(&dir, &spec()).unwrap();
        assert_eq!(c.views.len(), 1);
        assert_eq!(c.views[0].camera.width(), 4);

        let mut s = spec();
        s.views[0].width = 5;
        let e = load(&dir, &s).unwrap_err().to_string();
        assert!(e.contains("\"v0\"") && e.contains("v0.png") && e.contains("4x6"), "{e}");

        let mut s = spec();
        s.views[0].mask = Some("masks/missing.png".into());
        let e = load(&dir, &s).unwrap_err().to_string();
        assert!(e.contains("mask") && e.contains("missing.png"), "{e}");

        let mut s = spec();
        s.views[0].r[0][0] = 0.5;
        let e = load(&dir, &s).unwrap_err().to_string();
        assert!(e.contains("\"v0\"") && e.contains("rotation"), "{e}");

        let mut s = spec();
        s.views[0].k[1][1] = 0.0;
        assert!(matches!(load(&dir, &s), Err(CaptureError::Camera { .. })));

        let mut s = spec();
        s.units = "millimetres".into();
        assert!(matches!(load(&dir, &s), Err(CaptureError::Units { .. })));

        // NaN cannot be written as JSON; a null where a number belongs is a parse error.
        std::fs::write(dir.join("capture.json"), "{\"version\": 1, \"views\": [}").unwrap();
        assert!(matches!(Capture::load(&dir), Err(CaptureError::Json { .. })));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
