//! The stages of `hairrecon reconstruct`, one module each: a typed output that saves itself into
//! the output folder and reloads itself from there (so that a run can resume from any stage), and
//! a `run` function from the earlier stages' outputs and the stage's part of the
//! [`crate::config::ReconstructConfig`]. The runner ([`crate::runner`]) calls them in order.
//!
//! Data flows one way: capture → [`head`] (the frame, head and scalp it lacks) → [`masks`] (the
//! hair masks it lacks) → [`orient2d`] (2D orientation maps) → [`orient3d`] (oriented 3D
//! points) → [`partings`] (the scalp, with the skin the views see) → [`direction`] (directed
//! points) → [`init`] (initial guides and children) → [`dr`] (strands optimized by differentiable
//! rendering).

pub mod direction;
pub mod dr;
pub mod head;
pub mod init;
pub mod masks;
pub mod orient2d;
pub mod orient3d;
pub mod partings;
pub mod sanity;

use std::cell::{OnceCell, RefCell};
use std::path::{Path, PathBuf};

use hairrecon_core::capture::Capture;
use hairrecon_core::Bvh;

use crate::config::Stage;
use crate::error::ReconError;
use crate::progress::Progress;

/// Files each stage writes (besides `masks/<view>.png` and `orient2d/<view>.exr|png`); `guides.hair` and `strands.hair`
/// are the last strand stage's. A run lists the files it actually wrote in `report.json`; this list
/// is what a report without that list (or an unreadable one) is assumed to have.
pub const OUTPUTS: [(Stage, &[&str]); 8] = [
    (Stage::Head, &["fitted_head.ply", "fitted_scalp.ply", "head_fit.json"]),
    (Stage::Masks, &["hair_region.ply", "masks.json"]),
    (Stage::Orient2d, &["orient2d/maps.bin"]),
    (Stage::Orient3d, &["points3d.ply"]),
    (Stage::Partings, &["partings.ply", "partings.json"]),
    (Stage::Direction, &["points_directed.ply"]),
    (Stage::Init, &["roots.ply", "flow.bin", "points_axes.ply", "init_guides.hair", "init_strands.hair", "init.json"]),
    (Stage::Dr, &["loss.csv", "loss.png", "guides.hair", "strands.hair"]),
];

/// What every stage sees: the capture, the output folder, progress, and the meshes (each read
/// once, when a stage first needs it).
pub struct Context<'a> {
    pub capture: &'a Capture,
    pub out_dir: &'a Path,
    pub progress: &'a dyn Progress,
    /// The files written since [`Context::take_written`] was last called, relative to `out_dir`.
    written: RefCell<Vec<String>>,
    raw: OnceCell<Bvh>,
    inner: OnceCell<Bvh>,
}

impl std::fmt::Debug for Context<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Context").field("capture", &self.capture.dir).field("out_dir", &self.out_dir).finish()
    }
}

impl<'a> Context<'a> {
    pub fn new(capture: &'a Capture, out_dir: &'a Path, progress: &'a dyn Progress) -> Self {
        Self { capture, out_dir, progress, written: RefCell::default(), raw: OnceCell::new(), inner: OnceCell::new() }
    }

    /// A file in the output folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.out_dir.join(name)
    }

    /// A file in the output folder that the running stage writes: listed, so that the run's report
    /// names every file of the result (and the next run in the folder knows what to clear).
    pub fn output(&self, name: &str) -> PathBuf {
        let mut w = self.written.borrow_mut();
        if !w.iter().any(|n| n == name) {
            w.push(name.to_string());
        }
        self.path(name)
    }

    /// Writes a result the user keeps (`strands.hair`, `guides.hair`) in the frame of the capture's
    /// files: an imported capture's own frame and units, though the run works in the canonical one.
    pub fn write_result(&self, name: &str, strands: &hairrecon_core::StrandSet) -> Result<(), ReconError> {
        let strands = self.capture.to_file_frame(strands).map_err(hairrecon_core::FormatError::from)?;
        hairrecon_core::formats::write_strands(self.output(name), &strands)?;
        Ok(())
    }

    /// The files [`Context::output`] handed out since the last call.
    pub fn take_written(&self) -> Vec<String> {
        self.written.take()
    }

    /// The raw mesh (the hair's outer surface), with its BVH.
    pub fn raw(&self) -> Result<&Bvh, ReconError> {
        if self.raw.get().is_none() {
            let _ = self.raw.set(Bvh::with_fold_vote(self.capture.read_mesh(&self.capture.raw_mesh)?));
        }
        Ok(self.raw.get().expect("set above"))
    }

    /// The raw mesh's bounding box: from its BVH when a stage has built it, else from the file
    /// (a run resumed at DR does not build a BVH for a box).
    pub fn raw_bbox(&self) -> Result<(glam::Vec3, glam::Vec3), ReconError> {
        match self.raw.get() {
            Some(bvh) => Ok(bvh.mesh().bbox()),
            None => Ok(self.capture.read_mesh(&self.capture.raw_mesh)?.bbox()),
        }
    }

    /// The scalp mesh's path.
    pub fn scalp_path(&self) -> Result<&Path, ReconError> {
        self.capture.scalp_mesh.as_deref().ok_or_else(|| ReconError::NoScalp { dir: self.capture.dir.clone() })
    }

    /// The head (else the scalp): what the partings' views and the flow see around, what hides
    /// strands in DR, and the body the strands must stay out of.
    pub fn inner(&self) -> Result<&Bvh, ReconError> {
        if self.inner.get().is_none() {
            let mesh = match &self.capture.head_mesh {
                Some(h) => self.capture.read_mesh(h)?,
                None => self.capture.read_mesh(self.scalp_path()?)?,
            };
            let _ = self.inner.set(Bvh::new(mesh));
        }
        Ok(self.inner.get().expect("set above"))
    }
}

/// A saved output that `--from later` needs, or the error that names the stage to run first.
pub(crate) fn need(ctx: &Context<'_>, from: Stage, made_by: Stage, name: &str) -> Result<PathBuf, ReconError> {
    let path = ctx.path(name);
    if path.exists() {
        Ok(path)
    } else {
        Err(ReconError::MissingStageOutput { from, needs: made_by, path })
    }
}

/// Removes a file of an earlier run (absent is fine).
pub(crate) fn remove(path: &Path) -> Result<(), ReconError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(ReconError::Write { path: path.into(), source: e }),
        _ => Ok(()),
    }
}

/// Writes `value` as pretty JSON, atomically.
pub(crate) fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), ReconError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| ReconError::Write { path: path.into(), source: std::io::Error::other(e) })?;
    Ok(hairrecon_core::formats::atomic_write(path, |w| Ok(std::io::Write::write_all(w, text.as_bytes())?))?)
}

/// Creates a folder.
pub(crate) fn mkdir(p: &Path) -> Result<(), ReconError> {
    std::fs::create_dir_all(p).map_err(|source| ReconError::OutDir { path: p.into(), source })
}
