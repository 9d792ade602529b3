//! COLMAP's binary model: `cameras.bin`, `images.bin`, `points3D.bin`, little-endian.
//!
//! ```text
//! cameras.bin   u64 count, then per camera:
//!                 u32 camera_id, i32 model_id, u64 width, u64 height, f64 params[num_params(model)]
//! images.bin    u64 count, then per image:
//!                 u32 image_id, f64 qw qx qy qz, f64 tx ty tz, u32 camera_id,
//!                 name bytes ending with a NUL byte,
//!                 u64 num_points2D, then per point: f64 x, f64 y, i64 point3D_id   (24 bytes)
//! points3D.bin  u64 count, then per point:
//!                 u64 point3D_id, f64 x y z, u8 r g b, f64 error,
//!                 u64 track_length, then per element: u32 image_id, u32 point2D_idx  (8 bytes)
//! ```
//!
//! (COLMAP's `read_write_model.py` and `reconstruction_io.cc`.) A camera's parameter count comes
//! from its model, so a camera of an unknown model id cannot be skipped: it is an error. Counts are
//! checked against the bytes left before anything is reserved; bytes after the last item are an
//! error.

use std::path::Path;

use hairrecon_core::formats::bytes::{Cursor, Endian};
use hairrecon_core::FormatError;

use super::{model_by_id, RawCamera, RawImage, RawModel};
use crate::error::ImportError;
use crate::files::{create_dir, read_bytes, write_atomic};
use crate::scene::Scene;

const LE: Endian = Endian::Little;

/// Reads `cameras.bin`, `images.bin` and, if present, `points3D.bin` from `dir`.
pub(crate) fn read_model(dir: &Path) -> Result<RawModel, ImportError> {
    let cameras_path = dir.join("cameras.bin");
    let images_path = dir.join("images.bin");
    let points_path = dir.join("points3D.bin");
    let cameras = read_cameras(&cameras_path, &read_bytes(&cameras_path)?)?;
    let images = read_images(&images_path, &read_bytes(&images_path)?)?;
    let points =
        if points_path.is_file() { read_points(&points_path, &read_bytes(&points_path)?)? } else { Vec::new() };
    Ok(RawModel { cameras_path, images_path, cameras, images, points })
}

/// Runs `f` on a cursor over `data`, naming `path` and the cursor's offset in errors.
fn with_cursor<T>(
    path: &Path,
    data: &[u8],
    f: impl FnOnce(&mut Cursor) -> Result<T, Result<FormatError, ImportError>>,
) -> Result<T, ImportError> {
    let mut c = Cursor::new(data);
    match f(&mut c) {
        Ok(v) => Ok(v),
        Err(Ok(e)) => Err(ImportError::from_format(path, c.pos(), e)),
        Err(Err(e)) => Err(e),
    }
}

pub(crate) fn read_cameras(path: &Path, data: &[u8]) -> Result<Vec<RawCamera>, ImportError> {
    with_cursor(path, data, |c| {
        let count = c.u64_le("the number of cameras").map_err(Ok)?;
        let n = c.check_count(count, 24, "cameras").map_err(Ok)?;
        let mut cameras = Vec::with_capacity(n);
        for _ in 0..n {
            let start = c.pos();
            let id = c.u32(LE, "a camera id").map_err(Ok)?;
            let model_id = c.i32(LE, "a camera model id").map_err(Ok)?;
            let width = c.u64_le("a camera width").map_err(Ok)?;
            let height = c.u64_le("a camera height").map_err(Ok)?;
            let model = model_by_id(model_id).ok_or_else(|| {
                Err(ImportError::Binary {
                    path: path.to_path_buf(),
                    offset: start as u64 + 4,
                    msg: format!(
                        "camera {id} has the unknown model id {model_id} (known: 0..=10); \
                         the file is corrupt or from a newer COLMAP: export the model as text"
                    ),
                })
            })?;
            let mut params = Vec::with_capacity(model.num_params);
            for _ in 0..model.num_params {
                params.push(c.f64(LE, "a camera parameter").map_err(Ok)?);
            }
            cameras.push(RawCamera { id, model, width, height, params });
        }
        c.expect_end("camera").map_err(Ok)?;
        Ok(cameras)
    })
}

pub(crate) fn read_images(path: &Path, data: &[u8]) -> Result<Vec<RawImage>, ImportError> {
    with_cursor(path, data, |c| {
        let count = c.u64_le("the number of images").map_err(Ok)?;
        let n = c.check_count(count, 73, "images").map_err(Ok)?;
        let mut images = Vec::with_capacity(n);
        for _ in 0..n {
            let id = c.u32(LE, "an image id").map_err(Ok)?;
            let mut q = [0.0; 4];
            for v in &mut q {
                *v = c.f64(LE, "an image quaternion").map_err(Ok)?;
            }
            let mut t = [0.0; 3];
            for v in &mut t {
                *v = c.f64(LE, "an image translation").map_err(Ok)?;
            }
            let camera_id = c.u32(LE, "an image's camera id").map_err(Ok)?;
            let name_start = c.pos();
            let mut name = Vec::new();
            loop {
                match c.u8("an image name (NUL-terminated)").map_err(Ok)? {
                    0 => break,
                    b => name.push(b),
                }
            }
            let name = String::from_utf8(name).map_err(|_| {
                Err(ImportError::Binary {
                    path: path.to_path_buf(),
                    offset: name_start as u64,
                    msg: format!("the name of image {id} is not UTF-8 text"),
                })
            })?;
            let num_points = c.u64_le("an image's number of 2D points").map_err(Ok)?;
            let np = c.check_count(num_points, 24, "2D points").map_err(Ok)?;
            c.take(np * 24, "an image's 2D points").map_err(Ok)?;
            images.push(RawImage { id, q, t, camera_id, name });
        }
        c.expect_end("image").map_err(Ok)?;
        Ok(images)
    })
}

pub(crate) fn read_points(path: &Path, data: &[u8]) -> Result<Vec<[f64; 3]>, ImportError> {
    with_cursor(path, data, |c| {
        let count = c.u64_le("the number of 3D points").map_err(Ok)?;
        let n = c.check_count(count, 51, "3D points").map_err(Ok)?;
        let mut points = Vec::with_capacity(n);
        for _ in 0..n {
            let start = c.pos();
            let _id = c.u64_le("a 3D point id").map_err(Ok)?;
            let mut p = [0.0; 3];
            for v in &mut p {
                *v = c.f64(LE, "a 3D point's coordinates").map_err(Ok)?;
            }
            if p.iter().any(|v| !v.is_finite()) {
                return Err(Err(ImportError::Binary {
                    path: path.to_path_buf(),
                    offset: start as u64,
                    msg: format!("the 3D point {p:?} is not finite"),
                }));
            }
            c.take(3 + 8, "a 3D point's colour and error").map_err(Ok)?;
            let track = c.u64_le("a 3D point's track length").map_err(Ok)?;
            let nt = c.check_count(track, 8, "track elements").map_err(Ok)?;
            c.take(nt * 8, "a 3D point's track").map_err(Ok)?;
            points.push(p);
        }
        c.expect_end("3D point").map_err(Ok)?;
        Ok(points)
    })
}

/// A little-endian `u64`, which the core cursor does not read.
trait U64Le {
    fn u64_le(&mut self, what: &str) -> Result<u64, FormatError>;
}

impl U64Le for Cursor<'_> {
    fn u64_le(&mut self, what: &str) -> Result<u64, FormatError> {
        let b = self.take(8, what)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
}

/// Writes `scene` as a COLMAP binary model (`cameras.bin`, `images.bin`, `points3D.bin`) in `dir`,
/// creating it if needed; values are written exactly.
pub fn write_binary(dir: &Path, scene: &Scene) -> Result<(), ImportError> {
    create_dir(dir)?;
    let (cameras, images) = super::to_raw(scene, &dir.join("cameras.bin"))?;
    let mut b = Vec::new();
    b.extend((cameras.len() as u64).to_le_bytes());
    for c in &cameras {
        b.extend(c.id.to_le_bytes());
        b.extend(c.model.id.to_le_bytes());
        b.extend(c.width.to_le_bytes());
        b.extend(c.height.to_le_bytes());
        for p in &c.params {
            b.extend(p.to_le_bytes());
        }
    }
    write_atomic(&dir.join("cameras.bin"), &b)?;

    let mut b = Vec::new();
    b.extend((images.len() as u64).to_le_bytes());
    for im in &images {
        b.extend(im.id.to_le_bytes());
        for v in im.q.iter().chain(&im.t) {
            b.extend(v.to_le_bytes());
        }
        b.extend(im.camera_id.to_le_bytes());
        b.extend(im.name.as_bytes());
        b.push(0);
        b.extend(0u64.to_le_bytes());
    }
    write_atomic(&dir.join("images.bin"), &b)?;

    let mut b = Vec::new();
    b.extend((scene.points.len() as u64).to_le_bytes());
    for (i, p) in scene.points.iter().enumerate() {
        b.extend((i as u64 + 1).to_le_bytes());
        for v in p {
            b.extend(v.to_le_bytes());
        }
        b.extend([128u8, 128, 128]);
        b.extend(0f64.to_le_bytes());
        b.extend(0u64.to_le_bytes());
    }
    write_atomic(&dir.join("points3D.bin"), &b)
}
