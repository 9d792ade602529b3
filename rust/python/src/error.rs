//! The one place where Rust errors become Python exceptions.
//!
//! Every domain error becomes `hairrecon.HairreconError` carrying the Rust error's message (which
//! names the file or view and what to do); a cancelled run becomes `hairrecon.Cancelled`, a
//! subclass. Panics never cross the boundary: entry points run under `catch_unwind`.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;

create_exception!(hairrecon, HairreconError, PyException, "An error from the hairrecon library.");
create_exception!(hairrecon, Cancelled, HairreconError, "The run was cancelled by the user.");

/// Converts any displayable Rust error into `HairreconError`.
pub fn to_py<E: std::fmt::Display>(e: E) -> PyErr {
    HairreconError::new_err(e.to_string())
}

/// Runs `f`, turning a panic into `HairreconError` instead of aborting the host (Blender).
pub fn guard<T>(f: impl FnOnce() -> Result<T, PyErr> + std::panic::UnwindSafe) -> Result<T, PyErr> {
    match std::panic::catch_unwind(f) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| p.downcast_ref::<&str>().copied())
                .unwrap_or("unknown panic");
            Err(HairreconError::new_err(format!("internal error in hairrecon (please report it): {msg}")))
        }
    }
}
