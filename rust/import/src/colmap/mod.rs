//! COLMAP sparse models: [`read_colmap`] reads one into a [`Scene`]; [`write_text`] and
//! [`write_binary`] write a scene as one.
//!
//! A sparse model is a folder (`sparse/0` after COLMAP's mapper) holding `cameras`, `images` and
//! `points3D`, either as text (`.txt`, [`text`]) or binary (`.bin`, [`binary`]); see COLMAP's
//! documentation, "Output Format". When both forms are present the binary one is read, as COLMAP
//! itself does (the text files are usually an export of it). `cameras` and `images` are required;
//! `points3D` is optional (the scene then has no points).
//!
//! Conventions, converted exactly:
//! - Pixels: COLMAP puts the centre of the first pixel at (0.5, 0.5), hairrecon at (0, 0), so
//!   `cx = cx_colmap - 0.5` and `cy = cy_colmap - 0.5`; focal lengths are unchanged.
//! - Poses: each image stores `QW QX QY QZ TX TY TZ`, the world-to-camera rotation as a Hamilton
//!   quaternion and the translation, with OpenCV camera axes (x right, y down, z forward): exactly
//!   hairrecon's `R`, `t`. The quaternion is normalized; a non-finite or zero one is an error.
//! - Units: structure from motion has no scale, so [`Units::Unknown`].
//! - Names: a view is named after the image NAME's file name; its image path is NAME as written
//!   (it may hold sub-folders). Two images with the same file name are an error.
//!
//! Camera models (COLMAP's `camera_models.h`), all mapped onto [`Intrinsics`] + [`Distortion`]:
//!
//! | id | model          | parameters                                  |
//! |----|----------------|---------------------------------------------|
//! | 0  | SIMPLE_PINHOLE | f, cx, cy                                   |
//! | 1  | PINHOLE        | fx, fy, cx, cy                              |
//! | 2  | SIMPLE_RADIAL  | f, cx, cy, k                                |
//! | 3  | RADIAL         | f, cx, cy, k1, k2                           |
//! | 4  | OPENCV         | fx, fy, cx, cy, k1, k2, p1, p2              |
//! | 6  | FULL_OPENCV    | fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 |
//!
//! FULL_OPENCV's k4..k6 are the rational denominator, [`Distortion::d`]. The fisheye and other
//! models (5 OPENCV_FISHEYE, 7 FOV, 8 SIMPLE_RADIAL_FISHEYE, 9 RADIAL_FISHEYE,
//! 10 THIN_PRISM_FISHEYE, and any later ones) are refused with [`ImportError::UnsupportedModel`].
//!
//! The writers choose the smallest model that holds a view's camera: SIMPLE_PINHOLE (no distortion,
//! `fx == fy`), PINHOLE (no distortion), OPENCV (only k1, k2, p1, p2), FULL_OPENCV (k3 or a
//! denominator). COLMAP has no skew and no r⁸ term: a view with either cannot be written. Views with
//! identical cameras share one COLMAP camera; image ids are 1, 2, ... in the scene's order.

pub mod binary;
pub mod text;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use crate::error::ImportError;
use crate::files::file_name;
use crate::pose;
use crate::scene::{Distortion, Intrinsics, Scene, SceneView, Units};

/// The camera models the readers accept, for error messages.
pub const SUPPORTED_MODELS: &str = "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV";

/// A COLMAP camera model: its id in the binary files, its name in the text files and its number of
/// parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CameraModel {
    pub id: i32,
    pub name: &'static str,
    pub num_params: usize,
    /// Whether hairrecon can import it.
    pub supported: bool,
}

/// COLMAP's camera models by id.
pub const CAMERA_MODELS: [CameraModel; 11] = [
    CameraModel { id: 0, name: "SIMPLE_PINHOLE", num_params: 3, supported: true },
    CameraModel { id: 1, name: "PINHOLE", num_params: 4, supported: true },
    CameraModel { id: 2, name: "SIMPLE_RADIAL", num_params: 4, supported: true },
    CameraModel { id: 3, name: "RADIAL", num_params: 5, supported: true },
    CameraModel { id: 4, name: "OPENCV", num_params: 8, supported: true },
    CameraModel { id: 5, name: "OPENCV_FISHEYE", num_params: 8, supported: false },
    CameraModel { id: 6, name: "FULL_OPENCV", num_params: 12, supported: true },
    CameraModel { id: 7, name: "FOV", num_params: 5, supported: false },
    CameraModel { id: 8, name: "SIMPLE_RADIAL_FISHEYE", num_params: 4, supported: false },
    CameraModel { id: 9, name: "RADIAL_FISHEYE", num_params: 5, supported: false },
    CameraModel { id: 10, name: "THIN_PRISM_FISHEYE", num_params: 12, supported: false },
];

/// The model with this binary id.
pub fn model_by_id(id: i32) -> Option<&'static CameraModel> {
    CAMERA_MODELS.iter().find(|m| m.id == id)
}

/// The model with this text name.
pub fn model_by_name(name: &str) -> Option<&'static CameraModel> {
    CAMERA_MODELS.iter().find(|m| m.name == name)
}

/// A camera as a COLMAP file stores it (before conversion).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RawCamera {
    pub id: u32,
    pub model: &'static CameraModel,
    pub width: u64,
    pub height: u64,
    pub params: Vec<f64>,
}

/// An image as a COLMAP file stores it (its 2D points skipped).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RawImage {
    pub id: u32,
    pub q: [f64; 4],
    pub t: [f64; 3],
    pub camera_id: u32,
    pub name: String,
}

/// The parsed files of a model and the paths that errors name.
#[derive(Debug)]
pub(crate) struct RawModel {
    pub cameras_path: PathBuf,
    pub images_path: PathBuf,
    pub cameras: Vec<RawCamera>,
    pub images: Vec<RawImage>,
    pub points: Vec<[f64; 3]>,
}

/// Reads the COLMAP sparse model in `sparse_dir` (binary if `cameras.bin` and `images.bin` are
/// there, else text), see the module documentation.
pub fn read_colmap(sparse_dir: &Path) -> Result<Scene, ImportError> {
    let has = |name: &str| sparse_dir.join(name).is_file();
    let raw = if has("cameras.bin") && has("images.bin") {
        binary::read_model(sparse_dir)?
    } else if has("cameras.txt") && has("images.txt") {
        text::read_model(sparse_dir)?
    } else {
        let found: Vec<&str> =
            ["cameras.bin", "images.bin", "points3D.bin", "cameras.txt", "images.txt", "points3D.txt"]
                .into_iter()
                .filter(|n| has(n))
                .collect();
        let found = if found.is_empty() { "none of them".to_string() } else { format!("only {}", found.join(", ")) };
        let msg = if sparse_dir.is_dir() {
            format!(
                "not a COLMAP sparse model: it needs cameras.bin and images.bin (and points3D.bin), or \
                 cameras.txt and images.txt (and points3D.txt), but has {found}; give the model folder \
                 (e.g. sparse/0), not the project folder"
            )
        } else {
            "the COLMAP model folder does not exist; give the folder holding cameras.bin/images.bin \
             (e.g. sparse/0)"
                .to_string()
        };
        return Err(ImportError::MissingFile { dir: sparse_dir.to_path_buf(), msg });
    };
    build_scene(raw)
}

/// Converts a parsed model into a scene.
pub(crate) fn build_scene(raw: RawModel) -> Result<Scene, ImportError> {
    let mut cameras: HashMap<u32, (u32, u32, Intrinsics, Distortion)> = HashMap::new();
    for c in &raw.cameras {
        let bad =
            |msg: String| ImportError::BadCamera { path: raw.cameras_path.clone(), camera_id: c.id.to_string(), msg };
        let (w, h) = match (u32::try_from(c.width), u32::try_from(c.height)) {
            (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
            _ => return Err(bad(format!("the image size {}x{} is not a positive 32-bit size", c.width, c.height))),
        };
        let (k, d) = to_intrinsics(&raw.cameras_path, c)?;
        if cameras.insert(c.id, (w, h, k, d)).is_some() {
            return Err(bad("the camera id appears twice; the file is corrupt".into()));
        }
    }
    let mut images: Vec<&RawImage> = raw.images.iter().collect();
    images.sort_by_key(|i| i.id);
    let mut names = HashSet::new();
    let mut views = Vec::with_capacity(images.len());
    for im in images {
        let path = &raw.images_path;
        let &(width, height, intrinsics, distortion) =
            cameras.get(&im.camera_id).ok_or_else(|| ImportError::UnknownCamera {
                path: path.clone(),
                image: im.name.clone(),
                camera_id: im.camera_id.to_string(),
            })?;
        let bad_pose = |msg: String| ImportError::BadPose { path: path.clone(), image: im.name.clone(), msg };
        let r = pose::rotation_from_quaternion(im.q).map_err(bad_pose)?;
        if im.t.iter().any(|v| !v.is_finite()) {
            return Err(bad_pose(format!("the translation {:?} is not finite (NaN pose)", im.t)));
        }
        let name = file_name(&im.name).to_string();
        if name.is_empty() {
            return Err(bad_pose("the image name is empty; every image needs its photo's file name".into()));
        }
        if !names.insert(name.clone()) {
            return Err(ImportError::DuplicateImage { path: path.clone(), name });
        }
        views.push(SceneView {
            name,
            image: PathBuf::from(&im.name),
            width,
            height,
            intrinsics,
            distortion,
            r,
            t: im.t,
        });
    }
    if views.is_empty() {
        return Err(ImportError::NoViews { path: raw.images_path });
    }
    Ok(Scene { views, points: raw.points, units: Units::Unknown, warnings: Vec::new() })
}

/// The intrinsics and distortion of a COLMAP camera, pixel centres moved to integers.
fn to_intrinsics(path: &Path, c: &RawCamera) -> Result<(Intrinsics, Distortion), ImportError> {
    let bad = |msg: String| ImportError::BadCamera { path: path.to_path_buf(), camera_id: c.id.to_string(), msg };
    if !c.model.supported {
        return Err(ImportError::UnsupportedModel {
            path: path.to_path_buf(),
            camera_id: c.id.to_string(),
            model: c.model.name.to_string(),
            supported: SUPPORTED_MODELS,
        });
    }
    let p = &c.params;
    if p.len() != c.model.num_params {
        return Err(bad(format!("{} needs {} parameters but {} are given", c.model.name, c.model.num_params, p.len())));
    }
    if let Some(v) = p.iter().find(|v| !v.is_finite()) {
        return Err(bad(format!("a parameter is not finite ({v})")));
    }
    let mut d = Distortion::default();
    let (fx, fy, cx, cy) = match c.model.name {
        "SIMPLE_PINHOLE" => (p[0], p[0], p[1], p[2]),
        "PINHOLE" => (p[0], p[1], p[2], p[3]),
        "SIMPLE_RADIAL" => {
            d.k[0] = p[3];
            (p[0], p[0], p[1], p[2])
        }
        "RADIAL" => {
            d.k[0] = p[3];
            d.k[1] = p[4];
            (p[0], p[0], p[1], p[2])
        }
        "OPENCV" | "FULL_OPENCV" => {
            d.k[0] = p[4];
            d.k[1] = p[5];
            d.p = [p[6], p[7]];
            if c.model.name == "FULL_OPENCV" {
                d.k[2] = p[8];
                d.d = [p[9], p[10], p[11]];
            }
            (p[0], p[1], p[2], p[3])
        }
        other => unreachable!("model {other} is marked supported but has no conversion"),
    };
    if fx <= 0.0 || fy <= 0.0 {
        return Err(bad(format!("the focal length ({fx}, {fy}) is not positive")));
    }
    Ok((Intrinsics { fx, fy, cx: cx - 0.5, cy: cy - 0.5, skew: 0.0 }, d))
}

/// The COLMAP model and parameters that hold a view's camera (see the module documentation).
fn from_view(v: &SceneView) -> Result<(&'static CameraModel, Vec<f64>), String> {
    let k = &v.intrinsics;
    let d = &v.distortion;
    if k.skew != 0.0 {
        return Err(format!("has skew {} and COLMAP cameras have none", k.skew));
    }
    if d.k[3] != 0.0 {
        return Err(format!("has an r⁸ distortion term (k4 = {}) and COLMAP's models have none", d.k[3]));
    }
    let (cx, cy) = (k.cx + 0.5, k.cy + 0.5);
    let named = |n: &str| model_by_name(n).expect("a COLMAP model name");
    Ok(if d.is_none() {
        if k.fx == k.fy {
            (named("SIMPLE_PINHOLE"), vec![k.fx, cx, cy])
        } else {
            (named("PINHOLE"), vec![k.fx, k.fy, cx, cy])
        }
    } else if d.k[2] == 0.0 && d.d == [0.0; 3] {
        (named("OPENCV"), vec![k.fx, k.fy, cx, cy, d.k[0], d.k[1], d.p[0], d.p[1]])
    } else {
        let p = vec![k.fx, k.fy, cx, cy, d.k[0], d.k[1], d.p[0], d.p[1], d.k[2], d.d[0], d.d[1], d.d[2]];
        (named("FULL_OPENCV"), p)
    })
}

/// The cameras and images that represent `scene` in COLMAP (cameras shared by identical views).
pub(crate) fn to_raw(scene: &Scene, path: &Path) -> Result<(Vec<RawCamera>, Vec<RawImage>), ImportError> {
    let mut cameras: Vec<RawCamera> = Vec::new();
    let mut images = Vec::with_capacity(scene.views.len());
    for (i, v) in scene.views.iter().enumerate() {
        let unwritable = |msg: String| ImportError::Unwritable { path: path.to_path_buf(), view: v.name.clone(), msg };
        let (model, params) = from_view(v).map_err(unwritable)?;
        let (width, height) = (u64::from(v.width), u64::from(v.height));
        let camera_id = match cameras
            .iter()
            .find(|c| c.model == model && c.width == width && c.height == height && c.params == params)
        {
            Some(c) => c.id,
            None => {
                let id = cameras.len() as u32 + 1;
                cameras.push(RawCamera { id, model, width, height, params });
                id
            }
        };
        let name = v.image.to_str().ok_or_else(|| unwritable("has an image path that is not UTF-8".into()))?;
        let name = name.replace('\\', "/");
        if name.is_empty() || name.contains(['\n', '\r', '\0']) {
            return Err(unwritable(format!("has the image path {name:?}, which a COLMAP model cannot hold")));
        }
        images.push(RawImage { id: i as u32 + 1, q: pose::quaternion_from_rotation(&v.r), t: v.t, camera_id, name });
    }
    Ok((cameras, images))
}

pub use binary::write_binary;
pub use text::write_text;
