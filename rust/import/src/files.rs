//! Reading and writing whole files with errors that name them.
//!
//! Writes go through `hairrecon_core::formats::atomic_write`: an error leaves no half-written file.

use std::io::Write;
use std::path::Path;

use hairrecon_core::formats::{atomic_write, FormatErrorKind};

use crate::error::ImportError;

/// The bytes of `path`.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, ImportError> {
    std::fs::read(path).map_err(|e| ImportError::io(path, e))
}

/// The text of `path`, which must be UTF-8.
pub(crate) fn read_text(path: &Path) -> Result<String, ImportError> {
    let bytes = read_bytes(path)?;
    String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..offset].iter().filter(|&&b| b == b'\n').count() as u64;
        ImportError::Parse {
            path: path.to_path_buf(),
            line,
            msg: "the text is not valid UTF-8; save the file as UTF-8".into(),
        }
    })
}

/// Writes `bytes` to `path` atomically.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ImportError> {
    atomic_write(path, |w| {
        w.write_all(bytes)?;
        Ok(())
    })
    .map_err(|e| match e.kind {
        FormatErrorKind::Io(source) => ImportError::io(path, source),
        other => ImportError::io(path, std::io::Error::other(other.to_string())),
    })
}

/// Creates the folder `dir` (and its parents) if it does not exist.
pub(crate) fn create_dir(dir: &Path) -> Result<(), ImportError> {
    std::fs::create_dir_all(dir).map_err(|e| ImportError::io(dir, e))
}

/// The file name part of a path as a tool wrote it: the text after the last `/` or `\`.
pub(crate) fn file_name(path: &str) -> &str {
    path.rsplit(['/', '\\']).next().unwrap_or(path)
}
