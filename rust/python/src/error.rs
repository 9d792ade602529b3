//! The one place where Rust errors become Python exceptions.
//!
//! ```text
//! hairrecon.Error              (also named hairrecon.HairreconError, the same class)
//! ├── hairrecon.CaptureError   a capture folder or its capture.json is wrong
//! ├── hairrecon.FormatError    a file cannot be read or written
//! ├── hairrecon.InputError     an argument has a bad value (shape, dtype, range)
//! └── hairrecon.Cancelled      the user cancelled the run
//! ```
//!
//! Every exception carries the Rust error's message, which names the file or view and says what to
//! do. Map errors with the functions below ([`capture_err`], [`format_err`], [`input_err`],
//! [`cancelled_err`]); a reconstruction's error is classified by [`Class::of`] (the job keeps the
//! class and the message until Python asks, then [`Class::raise`]); an import's error by
//! [`import_err`]. Panics never cross the boundary: entry points run under [`guard`].
//!
//! Imports (`hairrecon.import_colmap`, ...) map their errors by what the user has to fix:
//!
//! ```text
//! InputError    an argument names no calibration (a folder that is not a COLMAP model, a calibration
//!               file that does not exist), the capture folder exists and is not empty, a bad height
//! FormatError   the calibration cannot be read or is invalid (syntax, camera model, pose, no views);
//!               a photo or the raw mesh is missing or cannot be decoded; the capture cannot be written
//! CaptureError  the files read but do not make a capture: a photo's size does not match its camera,
//!               two views would get one name (or the written capture does not load: a bug)
//! Cancelled     the progress callback returned False
//! ```

use hairrecon_import::capture_writer::WriteError;
use hairrecon_import::photo::PhotoError;
use hairrecon_import::ImportError;
use hairrecon_recon::ReconError;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::PyErr;

create_exception!(hairrecon, Error, PyException, "An error from the hairrecon library (base of all of its errors).");
create_exception!(hairrecon, CaptureError, Error, "A capture folder or its capture.json is wrong.");
create_exception!(hairrecon, FormatError, Error, "A file cannot be read or written.");
create_exception!(hairrecon, InputError, Error, "An argument has a bad value (shape, dtype, range).");
create_exception!(hairrecon, Cancelled, Error, "The run was cancelled by the user.");

/// The base class under its older name; `hairrecon.HairreconError is hairrecon.Error`.
pub type HairreconError = Error;

/// Adds the exception classes to the module (and the `HairreconError` alias).
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("HairreconError", py.get_type::<Error>())?;
    m.add("CaptureError", py.get_type::<CaptureError>())?;
    m.add("FormatError", py.get_type::<FormatError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("Cancelled", py.get_type::<Cancelled>())?;
    Ok(())
}

/// A capture folder or capture.json problem: `hairrecon.CaptureError`.
pub fn capture_err(e: impl std::fmt::Display) -> PyErr {
    CaptureError::new_err(e.to_string())
}

/// A file that cannot be read or written: `hairrecon.FormatError`.
pub fn format_err(e: impl std::fmt::Display) -> PyErr {
    FormatError::new_err(e.to_string())
}

/// A bad argument value: `hairrecon.InputError`.
pub fn input_err(e: impl std::fmt::Display) -> PyErr {
    InputError::new_err(e.to_string())
}

/// The user cancelled: `hairrecon.Cancelled`.
pub fn cancelled_err(e: impl std::fmt::Display) -> PyErr {
    Cancelled::new_err(e.to_string())
}

/// The Python exception class of a failed reconstruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Capture,
    Format,
    Input,
    Cancelled,
    Other,
}

impl Class {
    /// What kind of failure a pipeline error is.
    pub fn of(e: &ReconError) -> Self {
        match e {
            ReconError::Cancelled(_) => Class::Cancelled,
            ReconError::Format(_) | ReconError::Orient2d(_) | ReconError::Points(_) => Class::Format,
            ReconError::StageFile { .. } => Class::Format,
            ReconError::OutDir { .. } | ReconError::Write { .. } => Class::Format,
            ReconError::NoScalp { .. }
            | ReconError::Scalp { .. }
            | ReconError::NotCanonical { .. }
            | ReconError::Capture(_)
            | ReconError::Implausible { .. }
            | ReconError::EmptyStage { .. }
            | ReconError::Degenerate { .. }
            | ReconError::HeadFit(_)
            | ReconError::Masks(_) => Class::Capture,
            ReconError::Config(_)
            | ReconError::EmptyPlan { .. }
            | ReconError::MissingStageOutput { .. }
            | ReconError::ForeignOutDir { .. }
            | ReconError::Busy { .. } => Class::Input,
            _ => Class::Other,
        }
    }

    /// The exception of this class with `msg`.
    pub fn raise(self, msg: impl std::fmt::Display) -> PyErr {
        match self {
            Class::Capture => capture_err(msg),
            Class::Format => format_err(msg),
            Class::Input => input_err(msg),
            Class::Cancelled => cancelled_err(msg),
            Class::Other => to_py(msg),
        }
    }
}

/// The exception of a failed import (the module docs' table), with the Rust message.
pub fn import_err(e: &hairrecon_import::Error) -> PyErr {
    let class = match e {
        hairrecon_import::Error::Read(e) => match e {
            ImportError::MissingFile { .. } => Class::Input,
            ImportError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => Class::Input,
            _ => Class::Format,
        },
        hairrecon_import::Error::Write(e) => match e {
            WriteError::OutExists { .. } => Class::Input,
            WriteError::Cancelled => Class::Cancelled,
            WriteError::DuplicateName { .. } | WriteError::Capture(_) => Class::Capture,
            WriteError::Photo { source, .. } => match source {
                PhotoError::SizeMismatch { .. } => Class::Capture,
                PhotoError::BadTarget { .. } => Class::Input,
                _ => Class::Format,
            },
            WriteError::NoViews | WriteError::Mesh(_) | WriteError::Write(_) | WriteError::Io { .. } => Class::Format,
        },
    };
    class.raise(e)
}

/// Converts any displayable Rust error into the base `hairrecon.Error` (for errors of no more
/// specific kind, e.g. a poisoned lock).
pub fn to_py<E: std::fmt::Display>(e: E) -> PyErr {
    Error::new_err(e.to_string())
}

/// Runs `f`, turning a panic into `hairrecon.Error` instead of aborting the host (Blender).
pub fn guard<T>(f: impl FnOnce() -> Result<T, PyErr> + std::panic::UnwindSafe) -> Result<T, PyErr> {
    match std::panic::catch_unwind(f) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| p.downcast_ref::<&str>().copied())
                .unwrap_or("unknown panic");
            Err(Error::new_err(format!("internal error in hairrecon (please report it): {msg}")))
        }
    }
}
