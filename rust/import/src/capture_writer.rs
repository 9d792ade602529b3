//! Writes an imported [`Scene`] as a hairrecon capture folder: each view's photo undistorted and
//! scaled to the working height (`photo`), the raw mesh as binary PLY, and `capture.json` with
//! the views' pinhole cameras in the source's frame and units (`"frame": "imported"`).
//!
//! The folder appears whole or not at all: everything is written into a hidden folder beside
//! `out`, checked by loading it as a capture, then renamed to `out`. A failure or a cancel removes
//! the hidden folder; `out` is never half-written, and an existing non-empty `out` is refused.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use hairrecon_core::capture::{Capture, CaptureError, CaptureSpec, ViewSpec, CAPTURE_VERSION};
use hairrecon_core::formats::{read_mesh, write_mesh, FormatError};
use hairrecon_core::image_io::write_png8_rgb;
use rayon::prelude::*;
use thiserror::Error;

use crate::photo::{load_photo, resample, PhotoError, Prefer};
use crate::scene::{Scene, SceneView};

/// Extensions tried, in this order, for a photo named without one (Metashape labels, instant-ngp
/// `file_path`s).
const PHOTO_EXTENSIONS: &[&str] = &["jpg", "JPG", "jpeg", "JPEG", "png", "PNG", "tif", "TIF", "tiff", "TIFF"];

/// Why a capture folder could not be written.
#[derive(Debug, Error)]
pub enum WriteError {
    /// The output folder exists and holds files.
    #[error("{path} exists and is not empty; choose a new folder for the capture, or remove this one")]
    OutExists { path: PathBuf },
    /// The calibration lists no views.
    #[error("the calibration has no views: nothing to import")]
    NoViews,
    /// Two views would write the same working copy.
    #[error(
        "two views are both named {name:?} once their folders and extensions are dropped ({first} and {second}); \
         rename one of the photos and calibrate again"
    )]
    DuplicateName { name: String, first: PathBuf, second: PathBuf },
    /// A view's photo cannot be loaded or resampled.
    #[error("view {view:?}: {source}")]
    Photo { view: String, source: PhotoError },
    /// The raw mesh cannot be read (missing, not PLY/OBJ, no faces, ...).
    #[error("the raw mesh cannot be used: {0}")]
    Mesh(FormatError),
    /// A file of the capture cannot be written.
    #[error("cannot write the capture: {0}")]
    Write(FormatError),
    /// A folder cannot be created, removed or renamed.
    #[error("cannot {what} {path}: {source}")]
    Io { what: &'static str, path: PathBuf, source: std::io::Error },
    /// The written capture does not load (a bug: please report it with the calibration).
    #[error("the written capture does not load: {0}")]
    Capture(#[from] CaptureError),
    /// The user cancelled; nothing was written.
    #[error("the import was cancelled; nothing was written")]
    Cancelled,
}

/// Where the photos and the mesh are, and how the working copies are made.
#[derive(Debug, Clone)]
pub struct WriteOptions {
    /// The folder the calibration's photo paths are relative to.
    pub images: PathBuf,
    /// The raw mesh (PLY or OBJ; polygons are fan-triangulated).
    pub mesh: PathBuf,
    /// Height of the working copies in pixels (the width keeps the photo's aspect).
    pub height: u32,
    /// Which orientation to take when both a photo's stored pixels and its EXIF-rotated pixels
    /// have the calibration's size.
    pub prefer: Prefer,
}

/// Progress of an import: called after each view with (views done, views in all); returning
/// `false` cancels.
pub type ImportProgress<'a> = &'a (dyn Fn(usize, usize) -> bool + Sync);

/// Writes `scene` as a capture folder at `out` (module docs). Returns the path of its
/// `capture.json`.
pub fn write_capture(
    scene: &Scene,
    opts: &WriteOptions,
    out: &Path,
    progress: ImportProgress,
) -> Result<PathBuf, WriteError> {
    if scene.views.is_empty() {
        return Err(WriteError::NoViews);
    }
    if out.exists() && std::fs::read_dir(out).map(|mut d| d.next().is_some()).unwrap_or(true) {
        return Err(WriteError::OutExists { path: out.to_path_buf() });
    }
    let names = view_names(&scene.views)?;
    let staging = staging_dir(out);
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir_all(staging.join("images")).map_err(io("create", &staging))?;
    let result = write_into(scene, opts, &names, &staging, progress).and_then(|()| {
        if out.exists() {
            std::fs::remove_dir(out).map_err(io("replace the empty folder", out))?;
        }
        std::fs::rename(&staging, out).map_err(io("rename the finished capture to", out))
    });
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    Ok(out.join("capture.json"))
}

/// An I/O error on `path` while trying to `what` it.
fn io<'a>(what: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> WriteError + 'a {
    move |source| WriteError::Io { what, path: path.to_path_buf(), source }
}

/// The hidden folder beside `out` that the capture is written into first.
fn staging_dir(out: &Path) -> PathBuf {
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "capture".into());
    out.with_file_name(format!(".{name}.importing-{}", std::process::id()))
}

/// Each view's capture name: its photo's file name without folder and extension.
fn view_names(views: &[SceneView]) -> Result<Vec<String>, WriteError> {
    let mut seen = std::collections::HashMap::new();
    let mut names = Vec::with_capacity(views.len());
    for v in views {
        let stem = Path::new(&v.name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let stem = if stem.is_empty() { v.name.clone() } else { stem };
        if let Some(first) = seen.insert(stem.clone(), v.image.clone()) {
            return Err(WriteError::DuplicateName { name: stem, first, second: v.image.clone() });
        }
        names.push(stem);
    }
    Ok(names)
}

/// The photo file of a view: its path under `images`, or with a photo extension when the
/// calibration names it without one.
fn find_photo(images: &Path, view: &SceneView) -> PathBuf {
    let path = images.join(&view.image);
    if path.is_file() || path.extension().is_some() {
        return path;
    }
    PHOTO_EXTENSIONS.iter().map(|e| path.with_extension(e)).find(|p| p.is_file()).unwrap_or(path)
}

fn write_into(
    scene: &Scene,
    opts: &WriteOptions,
    names: &[String],
    staging: &Path,
    progress: ImportProgress,
) -> Result<(), WriteError> {
    let mesh = read_mesh(&opts.mesh).map_err(WriteError::Mesh)?;
    write_mesh(staging.join("raw_mesh.ply"), &mesh).map_err(WriteError::Write)?;
    drop(mesh);
    let done = AtomicUsize::new(0);
    let cancelled = AtomicBool::new(false);
    let n = scene.views.len();
    let views: Vec<ViewSpec> = scene
        .views
        .par_iter()
        .zip(names)
        .map(|(v, name)| {
            if cancelled.load(Ordering::Relaxed) {
                return Err(WriteError::Cancelled);
            }
            let spec = write_view(v, name, opts, staging)?;
            if !progress(done.fetch_add(1, Ordering::SeqCst) + 1, n) {
                cancelled.store(true, Ordering::Relaxed);
                return Err(WriteError::Cancelled);
            }
            Ok(spec)
        })
        .collect::<Result<_, _>>()?;
    let spec = CaptureSpec {
        version: CAPTURE_VERSION,
        units: scene.units.name().into(),
        frame: Some("imported".into()),
        convention: "opencv".into(),
        views,
        raw_mesh: "raw_mesh.ply".into(),
        head_mesh: None,
        scalp_mesh: None,
        gt_strands: None,
        to_canonical: None,
    };
    spec.write(staging)?;
    Capture::load(staging)?;
    Ok(())
}

/// Loads, orients, undistorts and scales one view's photo, writes it, and returns its entry.
fn write_view(v: &SceneView, name: &str, opts: &WriteOptions, staging: &Path) -> Result<ViewSpec, WriteError> {
    let photo_err = |source| WriteError::Photo { view: v.name.clone(), source };
    let path = find_photo(&opts.images, v);
    let photo = load_photo(&path).map_err(photo_err)?;
    let pixels = photo.oriented_to_preferring(v.width, v.height, opts.prefer).map_err(photo_err)?;
    let work = resample(&pixels, &v.intrinsics, &v.distortion, opts.height).map_err(photo_err)?;
    drop(pixels);
    let image = PathBuf::from("images").join(format!("{name}.png"));
    write_png8_rgb(staging.join(&image), &work.image).map_err(WriteError::Write)?;
    let f = |m: [[f64; 3]; 3]| m.map(|r| r.map(|x| x as f32));
    let original = std::path::absolute(&path).unwrap_or(path);
    Ok(ViewSpec {
        name: name.into(),
        image,
        mask: None,
        width: work.image.width,
        height: work.image.height,
        k: f(work.intrinsics.k()),
        r: f(v.r),
        t: v.t.map(|x| x as f32),
        gt_orientation: None,
        gt_depth: None,
        original: Some(original),
    })
}
