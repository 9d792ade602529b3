//! Why a calibration could not be imported or exported.
//!
//! Every message names the file concerned, says what is wrong in it and what to do about it.
//! Text positions are 1-based line numbers; binary positions are byte offsets from the start of the
//! file.

use std::path::PathBuf;

use hairrecon_core::{FormatError, FormatErrorKind};
use thiserror::Error;

/// An error of the calibration readers and writers (`colmap`, `metashape`, `nerf`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ImportError {
    #[error("cannot read or write {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}, line {line}: {msg}")]
    Parse { path: PathBuf, line: u64, msg: String },
    #[error("{path}, byte {offset}: {msg}")]
    Binary { path: PathBuf, offset: u64, msg: String },
    #[error(
        "{path} ends after {len} bytes while reading {what} (which needs {needed} bytes from byte {offset}); \
         the file is truncated or a count in it is wrong: export the model again"
    )]
    Truncated { path: PathBuf, what: String, offset: u64, needed: u64, len: u64 },
    #[error(
        "{path}: camera {camera_id} uses the camera model {model}, which hairrecon cannot import; \
         supported models: {supported}. Undistort the images with the tool (e.g. COLMAP's image_undistorter) \
         or calibrate again with a supported model"
    )]
    UnsupportedModel { path: PathBuf, camera_id: String, model: String, supported: &'static str },
    #[error("{dir}: {msg}")]
    MissingFile { dir: PathBuf, msg: String },
    #[error("{path}: two views are named {name:?} (view names are the photos' file names and must be unique); rename one of the photos")]
    DuplicateImage { path: PathBuf, name: String },
    #[error("{path}: image {image:?} has an invalid pose: {msg}")]
    BadPose { path: PathBuf, image: String, msg: String },
    #[error("{path}: image {image:?} refers to camera {camera_id}, which the model does not define; the model's files do not belong together")]
    UnknownCamera { path: PathBuf, image: String, camera_id: String },
    #[error("{path}: invalid camera {camera_id}: {msg}")]
    BadCamera { path: PathBuf, camera_id: String, msg: String },
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
    #[error("{path}: the file has no calibrated views; align the photos in the tool and export the cameras again")]
    NoViews { path: PathBuf },
    #[error("cannot write {path}: view {view:?} {msg}; write it in a format that holds it, or undistort it first")]
    Unwritable { path: PathBuf, view: String, msg: String },
}

impl ImportError {
    /// Attaches `path` to an error of the core byte reader ([`hairrecon_core::formats::bytes::Cursor`]).
    /// `offset` is where the reader was when the error happened (used when the error has none).
    pub(crate) fn from_format(path: &std::path::Path, offset: usize, e: FormatError) -> Self {
        let path = path.to_path_buf();
        match e.kind {
            FormatErrorKind::Truncated { what, offset, needed, len } => {
                ImportError::Truncated { path, what, offset, needed, len }
            }
            FormatErrorKind::Io(source) => ImportError::Io { path, source },
            kind => ImportError::Binary { path, offset: offset as u64, msg: format!("{kind}; export the model again") },
        }
    }

    /// An I/O error on `path`.
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        ImportError::Io { path: path.to_path_buf(), source }
    }
}
