//! Importers of real captures: camera calibrations from photogrammetry tools and the photos that
//! go with them, turned into a hairrecon capture folder (`hairrecon_core::capture`).
//!
//! Data flows one way: a reader (`colmap`, `metashape`, `nerf`) turns a calibration file into a
//! [`Scene`] (views with pinhole intrinsics, a lens [`Distortion`] and an OpenCV pose, in the
//! file's own frame and units); `photo` loads each view's photo, undistorts it and scales it to the
//! working height; `capture_writer` writes the capture folder.
//!
//! Each reader has a writer that is its exact inverse (`colmap::write_text`,
//! `colmap::write_binary`, `metashape::write_xml`, `nerf::write_transforms`), for tests and for
//! users who move calibrations between tools.

pub mod capture_writer;
pub mod colmap;
pub mod distortion;
pub mod error;
mod files;
pub mod metashape;
pub mod nerf;
pub mod photo;
pub mod pose;
pub mod scene;

pub use colmap::read_colmap;
pub use error::ImportError;
pub use metashape::read_metashape;
pub use nerf::read_nerf;

pub use capture_writer::{write_capture, ImportProgress, WriteError, WriteOptions};
pub use scene::{Distortion, Intrinsics, Scene, SceneView, Units};

use std::path::{Path, PathBuf};

/// A calibration to import.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// A COLMAP sparse model folder (`cameras`, `images`, `points3D` as `.txt` or `.bin`).
    Colmap(PathBuf),
    /// An Agisoft Metashape cameras XML.
    Metashape(PathBuf),
    /// An instant-ngp / nerfstudio `transforms.json`.
    Nerf(PathBuf),
}

impl Source {
    /// Reads the calibration.
    pub fn read(&self) -> Result<Scene, ImportError> {
        match self {
            Source::Colmap(p) => read_colmap(p),
            Source::Metashape(p) => read_metashape(p),
            Source::Nerf(p) => read_nerf(p),
        }
    }
}

/// Why an import failed: the calibration, or writing the capture.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Read(#[from] ImportError),
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// What an import wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The capture's `capture.json`.
    pub capture_json: PathBuf,
    /// What the reader skipped or could not be sure of, one sentence each.
    pub warnings: Vec<String>,
}

/// Reads `source` and writes it as a capture folder at `out` ([`write_capture`]).
pub fn import_capture(
    source: &Source,
    opts: &WriteOptions,
    out: &Path,
    progress: ImportProgress,
) -> Result<Imported, Error> {
    let scene = source.read()?;
    let capture_json = write_capture(&scene, opts, out, progress)?;
    Ok(Imported { capture_json, warnings: scene.warnings })
}
