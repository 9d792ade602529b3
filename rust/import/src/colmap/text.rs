//! COLMAP's text model: `cameras.txt`, `images.txt`, `points3D.txt`.
//!
//! Lines starting with `#` are comments; fields are separated by spaces.
//!
//! ```text
//! cameras.txt   CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]
//! images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME
//!               POINTS2D[] as (X Y POINT3D_ID)        <- always the next line, possibly empty
//! points3D.txt  POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID POINT2D_IDX)
//! ```
//!
//! NAME is the rest of the line after CAMERA_ID (so a name may hold spaces, which COLMAP itself does
//! not write). Only XYZ is kept from points3D; the 2D points of images are skipped.

use std::fmt::Write as _;
use std::path::Path;

use super::{model_by_name, RawCamera, RawImage, RawModel};
use crate::error::ImportError;
use crate::files::{create_dir, read_text, write_atomic};
use crate::scene::Scene;

/// Reads `cameras.txt`, `images.txt` and, if present, `points3D.txt` from `dir`.
pub(crate) fn read_model(dir: &Path) -> Result<RawModel, ImportError> {
    let cameras_path = dir.join("cameras.txt");
    let images_path = dir.join("images.txt");
    let points_path = dir.join("points3D.txt");
    let cameras = read_cameras(&cameras_path, &read_text(&cameras_path)?)?;
    let images = read_images(&images_path, &read_text(&images_path)?)?;
    let points = if points_path.is_file() { read_points(&points_path, &read_text(&points_path)?)? } else { Vec::new() };
    Ok(RawModel { cameras_path, images_path, cameras, images, points })
}

fn parse_err(path: &Path, line: usize, msg: String) -> ImportError {
    ImportError::Parse { path: path.to_path_buf(), line: line as u64 + 1, msg }
}

fn field<T: std::str::FromStr>(path: &Path, line: usize, tok: Option<&str>, what: &str) -> Result<T, ImportError> {
    let tok = tok.ok_or_else(|| parse_err(path, line, format!("the line ends before {what}")))?;
    tok.parse().map_err(|_| parse_err(path, line, format!("{what} must be a number, found {tok:?}")))
}

/// Lines that hold data: not empty, not comments, with their 0-based line numbers.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(i, l)| (i, l.trim())).filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

pub(crate) fn read_cameras(path: &Path, text: &str) -> Result<Vec<RawCamera>, ImportError> {
    let mut cameras = Vec::new();
    for (n, line) in data_lines(text) {
        let mut tok = line.split_whitespace();
        let id: u32 = field(path, n, tok.next(), "CAMERA_ID")?;
        let model_name = tok.next().ok_or_else(|| parse_err(path, n, "the line ends before MODEL".into()))?;
        let model = model_by_name(model_name).ok_or_else(|| ImportError::UnsupportedModel {
            path: path.to_path_buf(),
            camera_id: id.to_string(),
            model: model_name.to_string(),
            supported: super::SUPPORTED_MODELS,
        })?;
        let width = field(path, n, tok.next(), "WIDTH")?;
        let height = field(path, n, tok.next(), "HEIGHT")?;
        let params = tok.map(|t| field(path, n, Some(t), "a camera parameter")).collect::<Result<Vec<f64>, _>>()?;
        if params.len() != model.num_params {
            let msg = format!("{} needs {} parameters but the line has {}", model.name, model.num_params, params.len());
            return Err(parse_err(path, n, msg));
        }
        cameras.push(RawCamera { id, model, width, height, params });
    }
    Ok(cameras)
}

pub(crate) fn read_images(path: &Path, text: &str) -> Result<Vec<RawImage>, ImportError> {
    let mut images = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((n, raw)) = lines.next() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut rest = line;
        let mut next = |what: &str| -> Result<&str, ImportError> {
            let s = rest.trim_start();
            if s.is_empty() {
                return Err(parse_err(path, n, format!("the line ends before {what}")));
            }
            let end = s.find(char::is_whitespace).unwrap_or(s.len());
            rest = &s[end..];
            Ok(&s[..end])
        };
        let id: u32 = field(path, n, Some(next("IMAGE_ID")?), "IMAGE_ID")?;
        let mut q = [0.0; 4];
        for (v, what) in q.iter_mut().zip(["QW", "QX", "QY", "QZ"]) {
            *v = field(path, n, Some(next(what)?), what)?;
        }
        let mut t = [0.0; 3];
        for (v, what) in t.iter_mut().zip(["TX", "TY", "TZ"]) {
            *v = field(path, n, Some(next(what)?), what)?;
        }
        let camera_id: u32 = field(path, n, Some(next("CAMERA_ID")?), "CAMERA_ID")?;
        let name = rest.trim().to_string();
        if name.is_empty() {
            return Err(parse_err(path, n, "the line ends before NAME".into()));
        }
        // The POINTS2D line follows every image line (it is empty for an image without points).
        if let Some((m, points)) = lines.next() {
            if points.split_whitespace().count() % 3 != 0 {
                return Err(parse_err(
                    path,
                    m,
                    format!("the 2D points of image {id} are not (X Y POINT3D_ID) triples"),
                ));
            }
        }
        images.push(RawImage { id, q, t, camera_id, name });
    }
    Ok(images)
}

pub(crate) fn read_points(path: &Path, text: &str) -> Result<Vec<[f64; 3]>, ImportError> {
    let mut points = Vec::new();
    for (n, line) in data_lines(text) {
        let mut tok = line.split_whitespace();
        let _id: u64 = field(path, n, tok.next(), "POINT3D_ID")?;
        let mut p = [0.0f64; 3];
        for (v, what) in p.iter_mut().zip(["X", "Y", "Z"]) {
            *v = field(path, n, tok.next(), what)?;
        }
        if p.iter().any(|v| !v.is_finite()) {
            return Err(parse_err(path, n, format!("the point {p:?} is not finite")));
        }
        let rest = tok.count();
        if rest < 4 || (rest - 4) % 2 != 0 {
            return Err(parse_err(path, n, "expected R G B ERROR and then (IMAGE_ID POINT2D_IDX) pairs".into()));
        }
        points.push(p);
    }
    Ok(points)
}

/// Writes `scene` as a COLMAP text model (`cameras.txt`, `images.txt`, `points3D.txt`) in `dir`,
/// creating it if needed. Numbers are printed in their shortest exact form, so reading the model
/// back gives the same values bit for bit (the pose up to the quaternion's rounding).
pub fn write_text(dir: &Path, scene: &Scene) -> Result<(), ImportError> {
    create_dir(dir)?;
    let (cameras, images) = super::to_raw(scene, &dir.join("cameras.txt"))?;
    let mut s = String::new();
    s.push_str("# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let _ = writeln!(s, "# Number of cameras: {}", cameras.len());
    for c in &cameras {
        let _ = write!(s, "{} {} {} {}", c.id, c.model.name, c.width, c.height);
        for p in &c.params {
            let _ = write!(s, " {p:?}");
        }
        s.push('\n');
    }
    write_atomic(&dir.join("cameras.txt"), s.as_bytes())?;

    let mut s = String::new();
    s.push_str("# Image list with two lines of data per image:\n");
    s.push_str("#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n");
    let _ = writeln!(s, "# Number of images: {}, mean observations per image: 0", images.len());
    for im in &images {
        let [qw, qx, qy, qz] = im.q;
        let [tx, ty, tz] = im.t;
        let _ =
            writeln!(s, "{} {qw:?} {qx:?} {qy:?} {qz:?} {tx:?} {ty:?} {tz:?} {} {}\n", im.id, im.camera_id, im.name);
    }
    write_atomic(&dir.join("images.txt"), s.as_bytes())?;

    let mut s = String::new();
    s.push_str("# 3D point list with one line of data per point:\n");
    s.push_str("#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n");
    let _ = writeln!(s, "# Number of points: {}, mean track length: 0", scene.points.len());
    for (i, [x, y, z]) in scene.points.iter().enumerate() {
        let _ = writeln!(s, "{} {x:?} {y:?} {z:?} 128 128 128 0", i + 1);
    }
    write_atomic(&dir.join("points3D.txt"), s.as_bytes())
}
