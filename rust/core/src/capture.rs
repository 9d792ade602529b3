//! Capture folders: hairrecon's input format.
//!
//! A capture is a folder with a `capture.json` that lists calibrated views and the meshes of the
//! scene. Paths in the JSON are relative to the folder. Cameras follow the OpenCV convention
//! (`x_img = K (R X + t)`, pixel centres at integers).
//!
//! Frame and units are data. `units` is `"metres"` (also `"centimetres"`, `"millimetres"`,
//! `"inches"`, `"feet"`) or `"unknown"` (structure from motion without a scale bar, such as
//! COLMAP's). `frame` is `"canonical"` (the default: Z up, the face toward −Y, as the renderer and
//! the Blender add-on write) or `"imported"` (whatever frame a photogrammetry tool chose; see
//! [`Frame`]). The reconstruction runs in the canonical frame in metres
//! ([`Capture::is_canonical`]).
//!
//! ```json
//! {
//!   "version": 1,
//!   "units": "metres",
//!   "frame": "canonical",
//!   "convention": "opencv",
//!   "views": [
//!     { "name": "view_000", "image": "images/view_000.png", "mask": "masks/view_000.png",
//!       "width": 341, "height": 512,
//!       "K": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "R": [[...], [...], [...]], "t": [tx, ty, tz],
//!       "gt_orientation": "gt/orientation/view_000.exr", "gt_depth": "gt/depth/view_000.exr",
//!       "original": "/photos/IMG_0001.JPG" }
//!   ],
//!   "raw_mesh": "raw_mesh.ply",
//!   "head_mesh": "head.ply",
//!   "scalp_mesh": "scalp.ply",
//!   "gt_strands": "gt/strands.hair"
//! }
//! ```
//!
//! `mask`, `head_mesh`, `scalp_mesh`, `gt_*` and `original` (the photo an importer made `image`
//! from) are optional. [`CaptureSpec`] is this schema, the one
//! definition of it: [`Capture::load`] reads it and [`CaptureSpec::write`] writes it (the renderer and
//! the Blender add-on write theirs through it, from Python `hairrecon.write_capture`).
//!
//! Checks happen in two steps. [`CaptureSpec::validate`] checks what the JSON alone says: version,
//! units, convention, at least one view, unique view names, no empty paths, valid cameras (finite,
//! K a pinhole matrix, R a rotation). [`Capture::load`] does that and then checks the files: that
//! every named file exists and that each image and mask has the size its view states. Each problem is
//! one error that names the view and the file.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::camera::{Camera, CameraError};
pub use crate::capture_frame::FrameSpec;
use crate::formats::{atomic_write, FormatError, FormatErrorKind};
use crate::similarity::Similarity;

/// The capture format version this library reads and writes.
pub const CAPTURE_VERSION: u32 = 1;

/// Why a capture could not be loaded.
#[derive(Debug, Error)]
pub enum CaptureError {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path} is not a valid capture.json: {source}")]
    Json { path: PathBuf, source: serde_json::Error },
    #[error(
        "{path} is not a capture: give a capture folder (the one holding capture.json) or its capture.json \
         ({why})"
    )]
    NotACapture { path: PathBuf, why: &'static str },
    #[error("{path}: unsupported capture version {found} (this hairrecon reads version {CAPTURE_VERSION})")]
    Version { path: PathBuf, found: u32 },
    #[error(
        "{path}: unknown units {found:?}; give \"metres\", \"centimetres\", \"millimetres\", \"inches\", \"feet\" \
         or \"unknown\" (an arbitrary scale)"
    )]
    Units { path: PathBuf, found: String },
    #[error("{path}: unknown frame {found:?}; give \"canonical\" (Z up, face toward -Y) or \"imported\"")]
    Frame { path: PathBuf, found: String },
    #[error("{path}: convention must be \"opencv\" (found {found:?})")]
    Convention { path: PathBuf, found: String },
    #[error("{path}: the capture has no views; list at least one calibrated view")]
    NoViews { path: PathBuf },
    /// `problem` says what is there instead of a file ([`not_a_file`]).
    #[error("view {view:?}: its {what} file {file} {problem}")]
    MissingFile { view: String, what: &'static str, file: PathBuf, problem: &'static str },
    #[error("the capture's {what} file {file} {problem}")]
    MissingMesh { what: &'static str, file: PathBuf, problem: &'static str },
    #[error("view {view:?}: {file} is {got_w}x{got_h} pixels but capture.json says {width}x{height}")]
    SizeMismatch { view: String, file: PathBuf, width: u32, height: u32, got_w: u32, got_h: u32 },
    #[error("view {view:?}: cannot read the image {file}: {msg}")]
    BadImage { view: String, file: PathBuf, msg: String },
    #[error("view {view:?} in {path}: invalid camera: {source}")]
    Camera { view: String, path: PathBuf, source: CameraError },
    #[error("{path}: two views are named {view:?}; view names must be unique")]
    DuplicateView { path: PathBuf, view: String },
    #[error(
        "{path}: the view name {view:?} cannot be a file name (outputs are written as <name>.exr and <name>.png); \
         rename it without '/', '\\', control characters or any of <>:\"|?*, not \".\" or \"..\", at most 200 bytes"
    )]
    BadViewName { path: PathBuf, view: String },
    #[error("{path}: {what} is empty; give the file's path relative to the capture folder")]
    EmptyPath { path: PathBuf, what: String },
    #[error(
        "{path}: the {what} path {file} leads outside the capture folder; paths must be relative to the folder \
         and stay inside it: copy or link the file into the folder (or allow outside paths explicitly: \
         `hairrecon reconstruct --allow-outside-paths`)"
    )]
    OutsidePath { path: PathBuf, what: String, file: PathBuf },
    #[error("{path}: {msg}")]
    Spec { path: PathBuf, msg: String },
    #[error("cannot write the capture: {source}")]
    Write { source: FormatError },
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
    /// The photo `image` was made from, as an importer found it (for the record; never read).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub original: Option<PathBuf>,
}

impl ViewSpec {
    /// The files the view names (not `original`, which is never read), by field name.
    fn files(&self) -> [(&'static str, Option<&PathBuf>); 4] {
        [
            ("image", Some(&self.image)),
            ("mask", self.mask.as_ref()),
            ("gt_orientation", self.gt_orientation.as_ref()),
            ("gt_depth", self.gt_depth.as_ref()),
        ]
    }
}

/// capture.json as written on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureSpec {
    pub version: u32,
    /// See [`Units::parse`].
    pub units: String,
    /// `"canonical"` or `"imported"` ([`Frame`]); absent means canonical.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<String>,
    pub convention: String,
    pub views: Vec<ViewSpec>,
    pub raw_mesh: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head_mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scalp_mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt_strands: Option<PathBuf>,
    /// The similarity from the capture's frame to the canonical one (imported captures, after
    /// `hairrecon fit-head --write`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to_canonical: Option<FrameSpec>,
}

/// The length unit of a capture's world frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Units {
    /// Metres.
    Metres,
    /// Another named unit and its length in metres.
    Named { name: String, metres: f64 },
    /// An arbitrary scale (structure from motion without a scale bar).
    Unknown,
}

impl Units {
    /// Reads capture.json's `units`: `metres` (`meters`, `m`), `centimetres` (`cm`), `millimetres`
    /// (`mm`), `inches` (`in`), `feet` (`ft`), or `unknown`; British and American spellings alike.
    pub fn parse(s: &str) -> Option<Self> {
        let named = |name: &str, metres: f64| Some(Units::Named { name: name.into(), metres });
        match s.to_ascii_lowercase().as_str() {
            "metres" | "meters" | "m" => Some(Units::Metres),
            "centimetres" | "centimeters" | "cm" => named("centimetres", 0.01),
            "millimetres" | "millimeters" | "mm" => named("millimetres", 0.001),
            "inches" | "in" => named("inches", 0.0254),
            "feet" | "ft" => named("feet", 0.3048),
            "unknown" => Some(Units::Unknown),
            _ => None,
        }
    }

    /// The name capture.json stores.
    pub fn name(&self) -> &str {
        match self {
            Units::Metres => "metres",
            Units::Named { name, .. } => name,
            Units::Unknown => "unknown",
        }
    }
}

/// The world frame a capture is given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// Z up, the face toward −Y (the synthetic renderer's and the Blender add-on's frame).
    Canonical,
    /// As a photogrammetry tool chose it: any rotation, offset and (with unknown units) scale.
    Imported,
}

impl Frame {
    /// Reads capture.json's `frame` (absent: canonical).
    pub fn parse(s: Option<&str>) -> Option<Self> {
        match s.map(str::to_ascii_lowercase).as_deref() {
            None | Some("canonical") => Some(Frame::Canonical),
            Some("imported") => Some(Frame::Imported),
            _ => None,
        }
    }

    /// The name capture.json stores.
    pub fn name(self) -> &'static str {
        match self {
            Frame::Canonical => "canonical",
            Frame::Imported => "imported",
        }
    }
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
    pub units: Units,
    pub frame: Frame,
    pub views: Vec<View>,
    pub raw_mesh: PathBuf,
    pub head_mesh: Option<PathBuf>,
    pub scalp_mesh: Option<PathBuf>,
    pub gt_strands: Option<PathBuf>,
    /// capture.json's `to_canonical`.
    pub to_canonical: Option<Similarity>,
    /// The similarity from the frame of the files (meshes, strands) to this capture's frame:
    /// `None` as loaded; set by [`Capture::in_canonical_frame`] (see `capture_frame`).
    pub file_frame: Option<Similarity>,
}

impl Capture {
    /// Loads and validates `dir/capture.json` (or the given JSON file itself). Every path it names
    /// must stay inside the capture folder ([`Capture::load_allowing_outside_paths`] lifts that).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, CaptureError> {
        Self::load_with(path.as_ref(), false)
    }

    /// [`Capture::load`], accepting absolute paths and paths that leave the folder with `..`.
    pub fn load_allowing_outside_paths(path: impl AsRef<Path>) -> Result<Self, CaptureError> {
        Self::load_with(path.as_ref(), true)
    }

    fn load_with(path: &Path, outside_paths: bool) -> Result<Self, CaptureError> {
        let json = if path.is_dir() { path.join("capture.json") } else { path.to_path_buf() };
        let dir = json.parent().map(Path::to_path_buf).unwrap_or_default();
        if path.is_dir() && !json.exists() {
            return Err(CaptureError::NotACapture { path: path.into(), why: "the folder holds no capture.json" });
        }
        if let Some(why) = not_a_file(&json).filter(|_| json.exists()) {
            return Err(CaptureError::NotACapture { path: json, why });
        }
        let bytes = std::fs::read(&json).map_err(|source| CaptureError::Io { path: json.clone(), source })?;
        let named_json = json.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let text = match String::from_utf8(bytes) {
            Ok(text) => text,
            Err(_) if !named_json => {
                return Err(CaptureError::NotACapture { path: json, why: "it is a binary file, not JSON" })
            }
            Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
        };
        let spec: CaptureSpec = serde_json::from_str(&text).map_err(|source| {
            if named_json || text.trim_start().starts_with('{') {
                CaptureError::Json { path: json.clone(), source }
            } else {
                CaptureError::NotACapture { path: json.clone(), why: "it is not a JSON file" }
            }
        })?;
        if !outside_paths {
            spec.check_paths_inside(&json)?;
        }
        Self::from_spec(spec, &dir, &json)
    }

    /// Validates a parsed spec whose relative paths are under `dir`; `json` names the file in errors.
    pub fn from_spec(spec: CaptureSpec, dir: &Path, json: &Path) -> Result<Self, CaptureError> {
        let cameras = spec.validate(json)?;
        let units = Units::parse(&spec.units).expect("validated");
        let frame = Frame::parse(spec.frame.as_deref()).expect("validated");
        let mut views = Vec::with_capacity(spec.views.len());
        for (v, camera) in spec.views.into_iter().zip(cameras) {
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
                    if let Some(problem) = not_a_file(p) {
                        return Err(CaptureError::MissingFile { view: v.name.clone(), what, file: p.clone(), problem });
                    }
                }
            }
            views.push(View { name: v.name, camera, image, mask, gt_orientation, gt_depth });
        }
        let raw_mesh = dir.join(&spec.raw_mesh);
        if let Some(problem) = not_a_file(&raw_mesh) {
            return Err(CaptureError::MissingMesh { what: "raw_mesh", file: raw_mesh, problem });
        }
        let opt = |what: &'static str, p: Option<PathBuf>| -> Result<Option<PathBuf>, CaptureError> {
            match p.map(|p| dir.join(p)) {
                Some(f) => match not_a_file(&f) {
                    Some(problem) => Err(CaptureError::MissingMesh { what, file: f, problem }),
                    None => Ok(Some(f)),
                },
                None => Ok(None),
            }
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            units,
            frame,
            views,
            raw_mesh,
            head_mesh: opt("head_mesh", spec.head_mesh)?,
            scalp_mesh: opt("scalp_mesh", spec.scalp_mesh)?,
            gt_strands: opt("gt_strands", spec.gt_strands)?,
            to_canonical: spec.to_canonical.and_then(|f| f.similarity()),
            file_frame: None,
        })
    }
}

impl Capture {
    /// True when the capture is in the canonical frame and in metres, the frame the reconstruction
    /// works in. An imported capture needs the similarity to it first (head fitting).
    pub fn is_canonical(&self) -> bool {
        self.frame == Frame::Canonical && self.units == Units::Metres
    }
}

impl CaptureSpec {
    /// The meshes and strand files the capture names, by field name.
    fn mesh_files(&self) -> [(&'static str, Option<&PathBuf>); 4] {
        [
            ("raw_mesh", Some(&self.raw_mesh)),
            ("head_mesh", self.head_mesh.as_ref()),
            ("scalp_mesh", self.scalp_mesh.as_ref()),
            ("gt_strands", self.gt_strands.as_ref()),
        ]
    }

    /// Checks everything that capture.json alone tells, without looking at the files it names:
    /// the version, units and convention, at least one view, unique view names, no empty paths, and
    /// every camera (see [`Camera::new`]). Returns the views' cameras, in order. `json` names the
    /// file in errors.
    pub fn validate(&self, json: &Path) -> Result<Vec<Camera>, CaptureError> {
        if self.version != CAPTURE_VERSION {
            return Err(CaptureError::Version { path: json.into(), found: self.version });
        }
        if Units::parse(&self.units).is_none() {
            return Err(CaptureError::Units { path: json.into(), found: self.units.clone() });
        }
        if Frame::parse(self.frame.as_deref()).is_none() {
            return Err(CaptureError::Frame { path: json.into(), found: self.frame.clone().unwrap_or_default() });
        }
        if !self.convention.eq_ignore_ascii_case("opencv") {
            return Err(CaptureError::Convention { path: json.into(), found: self.convention.clone() });
        }
        if self.views.is_empty() {
            return Err(CaptureError::NoViews { path: json.into() });
        }
        let empty = |what: String| CaptureError::EmptyPath { path: json.into(), what };
        let mut names = std::collections::HashSet::new();
        let mut cameras = Vec::with_capacity(self.views.len());
        for v in &self.views {
            if !is_plain_name(&v.name) {
                return Err(CaptureError::BadViewName { path: json.into(), view: v.name.clone() });
            }
            if !names.insert(v.name.as_str()) {
                return Err(CaptureError::DuplicateView { path: json.into(), view: v.name.clone() });
            }
            for (what, p) in v.files() {
                if p.is_some_and(|p| p.as_os_str().is_empty()) {
                    return Err(empty(format!("view {:?}: its {what}", v.name)));
                }
            }
            let camera = Camera::new(v.k, v.r, v.t, v.width, v.height).map_err(|source| CaptureError::Camera {
                view: v.name.clone(),
                path: json.into(),
                source,
            })?;
            cameras.push(camera);
        }
        for (what, p) in self.mesh_files() {
            if p.is_some_and(|p| p.as_os_str().is_empty()) {
                return Err(empty(what.to_string()));
            }
        }
        if let Some(f) = &self.to_canonical {
            f.validate(self.frame.as_deref(), json)?;
        }
        Ok(cameras)
    }

    /// Checks that every path the spec names (images, masks, meshes, ground truth; not `original`,
    /// which is never read) is relative and stays inside the capture folder, by its components:
    /// no root, no drive prefix, no `..` that climbs above the folder. `json` names the file in errors.
    pub fn check_paths_inside(&self, json: &Path) -> Result<(), CaptureError> {
        let check = |what: String, p: &Path| -> Result<(), CaptureError> {
            let mut depth = 0usize;
            for c in p.components() {
                match c {
                    std::path::Component::Normal(_) => depth += 1,
                    std::path::Component::CurDir => {}
                    std::path::Component::ParentDir if depth > 0 => depth -= 1,
                    _ => return Err(CaptureError::OutsidePath { path: json.into(), what, file: p.into() }),
                }
            }
            Ok(())
        };
        for v in &self.views {
            for (what, p) in v.files() {
                if let Some(p) = p {
                    check(format!("view {:?}: {what}", v.name), p)?;
                }
            }
        }
        for (what, p) in self.mesh_files() {
            if let Some(p) = p {
                check(what.into(), p)?;
            }
        }
        Ok(())
    }

    /// A spec from parsed JSON, strictly: errors name the view and the field (`views[2] "view_002":
    /// missing field image`), and a field that the schema does not have (a misspelt `"gt_strand"`) is an error
    /// rather than silently dropped. `json` names the file in errors. Does not validate; see
    /// [`CaptureSpec::validate`].
    pub fn from_json(value: serde_json::Value, json: &Path) -> Result<Self, CaptureError> {
        use serde_json::Value;
        let spec_err = |msg: String| CaptureError::Spec { path: json.into(), msg };
        let Value::Object(mut top) = value else {
            return Err(spec_err(format!("capture.json must be a JSON object, not {}", json_kind(&value))));
        };
        let views_value = match top.remove("views") {
            Some(Value::Array(v)) => v,
            Some(other) => {
                return Err(spec_err(format!("\"views\" must be a list of views, not {}", json_kind(&other))))
            }
            None => return Err(spec_err("missing field `views`".into())),
        };
        let mut views = Vec::with_capacity(views_value.len());
        for (i, v) in views_value.into_iter().enumerate() {
            let label = match v.get("name").and_then(Value::as_str) {
                Some(name) => format!("views[{i}] {name:?}"),
                None => format!("views[{i}]"),
            };
            let view: ViewSpec = serde_json::from_value(v.clone()).map_err(|e| spec_err(format!("{label}: {e}")))?;
            check_unknown_fields(&v, &view).map_err(|f| spec_err(format!("{label}: {f}")))?;
            views.push(view);
        }
        top.insert("views".into(), Value::Array(Vec::new()));
        let top = Value::Object(top);
        let mut spec: CaptureSpec = serde_json::from_value(top.clone()).map_err(|e| spec_err(e.to_string()))?;
        check_unknown_fields(&top, &spec).map_err(spec_err)?;
        spec.views = views;
        Ok(spec)
    }

    /// The file [`CaptureSpec::write`] writes for `path`: `path` itself when it ends in `.json` and is
    /// not a folder, else the folder's `capture.json`.
    pub fn json_path(path: &Path) -> PathBuf {
        if !path.is_dir() && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            path.to_path_buf()
        } else {
            path.join("capture.json")
        }
    }

    /// Validates the spec ([`CaptureSpec::validate`]) and writes it as capture.json, atomically (an
    /// error leaves no file and keeps an existing one). `path` is the capture folder (created if
    /// missing; the file is its `capture.json`) or, when it ends in `.json` and is not a folder, the
    /// file itself. The files the spec names need not exist yet: [`Capture::load`] checks them.
    /// Returns the path written.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<PathBuf, CaptureError> {
        let json = Self::json_path(path.as_ref());
        self.validate(&json)?;
        let write_err = |source: FormatError| CaptureError::Write { source };
        if let Some(dir) = json.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| write_err(FormatError::from(e).in_file(dir)))?;
        }
        let mut text = serde_json::to_string_pretty(self)
            .map_err(|e| write_err(FormatError::from(FormatErrorKind::Invalid(e.to_string())).in_file(&json)))?;
        text.push('\n');
        atomic_write(&json, |w| {
            use std::io::Write;
            Ok(w.write_all(text.as_bytes())?)
        })
        .map_err(write_err)?;
        Ok(json)
    }
}

/// "an object", "a list", ... for error messages.
fn json_kind(v: &serde_json::Value) -> &'static str {
    use serde_json::Value;
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

/// An error naming the first field of `input` (with a non-null value) that `parsed` does not have
/// once serialized again: a field the schema does not know. Keeps the schema in the serde types.
fn check_unknown_fields<T: Serialize>(input: &serde_json::Value, parsed: &T) -> Result<(), String> {
    let (Some(input), Ok(serde_json::Value::Object(known))) = (input.as_object(), serde_json::to_value(parsed)) else {
        return Ok(());
    };
    match input.iter().find(|(k, v)| !v.is_null() && !known.contains_key(*k)) {
        Some((k, _)) => Err(format!("unknown field {k:?}; capture.json has no such field (a misspelling?)")),
        None => Ok(()),
    }
}

fn check_image(view: &str, what: &'static str, file: &Path, width: u32, height: u32) -> Result<(), CaptureError> {
    if let Some(problem) = not_a_file(file) {
        return Err(CaptureError::MissingFile { view: view.into(), what, file: file.into(), problem });
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

/// What is at `path` when it is not a regular file (following links), for an error message.
pub fn not_a_file(path: &Path) -> Option<&'static str> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => None,
        Ok(m) if m.is_dir() => Some("is a folder, not a file"),
        Ok(_) => Some("is not a regular file (a pipe, socket or device); give a file"),
        Err(_) if path.symlink_metadata().is_ok() => Some("is a link to nothing (a broken symbolic link)"),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some("does not exist"),
        Err(_) => Some("cannot be read (check its permissions)"),
    }
}

/// Whether a view name can be a file name in any folder: stages write `<name>.exr` and
/// `<name>.png`, so a name must not reach outside the folder (no `/` or `\\`, not `.` or `..`) and
/// must be a valid file name on Linux, macOS and Windows (no control characters, none of `<>:"|?*`).
fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 200
        && name != "."
        && name != ".."
        && !name.chars().any(|c| c.is_control() || matches!(c, '/' | '\\' | '<' | '>' | ':' | '"' | '|' | '?' | '*'))
}

#[cfg(test)]
mod tests;
