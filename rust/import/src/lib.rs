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

pub mod colmap;
pub mod error;
mod files;
pub mod metashape;
pub mod nerf;
pub mod pose;
pub mod scene;

pub use colmap::read_colmap;
pub use error::ImportError;
pub use metashape::read_metashape;
pub use nerf::read_nerf;

pub use scene::{Distortion, Intrinsics, Scene, SceneView, Units};
