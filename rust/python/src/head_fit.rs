//! `hairrecon.fit_head`: the bundled head (or the user's template) registered to a capture's raw
//! mesh (`hairrecon_recon::head_fit::capture_fit`, the same as `hairrecon fit-head`).
//!
//! ```python
//! fit = hairrecon.fit_head("capture/")                   # a capture folder or its capture.json
//! fit["to_canonical"]["scale"]                           # capture units -> metres
//! head_v, head_t = fit["head"]                           # float32 (N, 3), uint32 (M, 3), capture frame
//! scalp_v, scalp_t = fit["scalp"]
//! hairrecon.fit_head("capture/", write=True)["written"]  # fitted_head.ply, fitted_scalp.ply, ...
//! ```
//!
//! The fit runs with the GIL released (2-25 s). A poor fit raises `CaptureError` with its figures
//! and what to do; a capture that cannot be read raises `CaptureError` or `FormatError`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use hairrecon_core::TriMesh;
use hairrecon_recon::head_fit::capture_fit::{
    fit_capture, matrix_rows, write_into_capture, CaptureFit, CaptureFitError, Template,
};
use hairrecon_recon::head_fit::FitOptions;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::{capture_err, format_err, guard, input_err, to_py};
use crate::points_to_py;

/// A mesh as numpy arrays: vertices float32 (N, 3) and triangles uint32 (M, 3).
type MeshArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<u32>>);

fn mesh_to_py<'py>(py: Python<'py>, m: &TriMesh) -> PyResult<MeshArrays<'py>> {
    let tris: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    Ok((points_to_py(py, &m.vertices)?, PyArray1::from_vec(py, tris).reshape([m.triangles.len(), 3])?))
}

/// The Python exception of a failed fit: the capture, its raw mesh or the fit itself is the
/// problem (`CaptureError`), a file cannot be read or written (`FormatError`), the template given
/// has no skin (`InputError`).
fn fit_err(e: CaptureFitError) -> PyErr {
    match e {
        CaptureFitError::Capture(_) | CaptureFitError::Fit { .. } | CaptureFitError::Landmarks(_) => capture_err(e),
        CaptureFitError::Format(_) => format_err(e),
        CaptureFitError::Template => input_err(e),
    }
}

/// The template: the user's head with its scalp (`scalp.ply` beside it by default), or the bundled one.
fn template_of(template: Option<&Path>, scalp: Option<&Path>) -> PyResult<(Template, Option<PathBuf>)> {
    match (template, scalp) {
        (None, None) => Ok((Template::bundled(), None)),
        (None, Some(_)) => Err(input_err("scalp is the template's scalp: give template (the head) with it")),
        (Some(head), scalp) => {
            let scalp = scalp.map_or_else(|| head.with_file_name("scalp.ply"), Path::to_path_buf);
            let t = Template::from_files(head, &scalp).map_err(|e| {
                format_err(format!(
                    "cannot read the head template {} with its scalp {}: {e}",
                    head.display(),
                    scalp.display()
                ))
            })?;
            Ok((t, Some(scalp)))
        }
    }
}

fn result_to_py<'py>(py: Python<'py>, f: &CaptureFit, written: Option<Vec<PathBuf>>) -> PyResult<Bound<'py, PyDict>> {
    let s = f.fit.to_canonical;
    let frame = PyDict::new(py);
    frame.set_item("scale", s.scale)?;
    frame.set_item("rotation", matrix_rows(s.rotation).map(|r| r.to_vec()).to_vec())?;
    frame.set_item("translation", s.translation.to_array().to_vec())?;
    let d = PyDict::new(py);
    d.set_item("to_canonical", frame)?;
    d.set_item("residual_mm", f.fit.residual_mm)?;
    d.set_item("on_mesh_fraction", f.fit.score.on_surface)?;
    d.set_item("covered_fraction", f.fit.score.inside)?;
    d.set_item("exposed_fraction", f.fit.score.outside)?;
    d.set_item("cost", f.fit.score.cost)?;
    d.set_item("landmarks_rms_mm", f.fit.landmarks_mm)?;
    match f.fit.landmark_distances() {
        Some(distances) => {
            let each = PyDict::new(py);
            for (name, mm) in distances {
                each.set_item(name, mm)?;
            }
            d.set_item("landmarks_mm", each)?;
        }
        None => d.set_item("landmarks_mm", py.None())?,
    }
    d.set_item("runner_up_cost", f.fit.runner_up_cost)?;
    d.set_item("warning", f.fit.close_call())?;
    match f.scalp_error {
        Some(e) => {
            let se = PyDict::new(py);
            se.set_item("mean_mm", e.mean * 1e3)?;
            se.set_item("p95_mm", e.p95 * 1e3)?;
            se.set_item("max_mm", e.max * 1e3)?;
            d.set_item("scalp_error", se)?;
        }
        None => d.set_item("scalp_error", py.None())?,
    }
    d.set_item("head", mesh_to_py(py, &f.head)?)?;
    d.set_item("scalp", mesh_to_py(py, &f.scalp)?)?;
    d.set_item("written", written.unwrap_or_default())?;
    Ok(d)
}

/// Fits the head template to the capture `capture` (its folder or capture.json): its raw mesh
/// and, with `use_cameras`, its cameras (they surround the head and give its up direction).
/// `template` is a head in the canonical frame (.ply or .obj; metres, Z up, the face toward −Y)
/// with its scalp `scalp` (default: scalp.ply beside it); default: the bundled head and scalp.
/// `landmarks` is a JSON file of landmarks placed on the raw mesh (names to `[x, y, z]` in the
/// capture's frame: nose_tip, chin, eye_outer_left, eye_outer_right, ear_left, ear_right, three or
/// more; left and right the subject's own): the fit starts from the pose they give instead of
/// searching. Default: the capture's landmarks.json, when it has one.
///
/// Returns a dict: `to_canonical` (`scale`, `rotation` as 3×3 rows, `translation`: capture
/// coordinates → canonical metres, x ↦ scale·R·x + t), `residual_mm`, `on_mesh_fraction`,
/// `covered_fraction`, `exposed_fraction`, `cost`, `runner_up_cost` (the best cost of a pose turned
/// more than 30° from the winner, or None), `warning` (when that pose came close: what to check,
/// else None), `landmarks_rms_mm` (with landmarks: their RMS
/// distance from the template's after the fit, canonical mm; else None), `landmarks_mm` (each given
/// landmark's distance, a dict of name to mm; else None), `scalp_error` (the fitted scalp's distance to
/// the capture's own scalp, `{"mean_mm", "p95_mm", "max_mm"}`, or None when it has none), `head`
/// and `scalp` (the fitted template as `(vertices float32 (N, 3), triangles uint32 (M, 3))` in the
/// capture's frame) and `written`. With `write=True`, the fitted head and scalp become the
/// capture's `head_mesh` and `scalp_mesh` where it has none (fitted_head.ply, fitted_scalp.ply),
/// the report is kept as head_fit.json and capture.json is rewritten; `written` lists the files.
///
/// Raises `CaptureError` when the template does not fit (the message gives the fit's figures and
/// what to do) or the capture is invalid, `FormatError` when a mesh cannot be read or a file
/// written, `InputError` for a scalp without a template or a template with no skin.
#[pyfunction]
#[pyo3(signature = (capture, write=false, template=None, scalp=None, use_cameras=true, landmarks=None))]
fn fit_head<'py>(
    py: Python<'py>,
    capture: PathBuf,
    write: bool,
    template: Option<PathBuf>,
    scalp: Option<PathBuf>,
    use_cameras: bool,
    landmarks: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let json_path = if capture.is_dir() { capture.join("capture.json") } else { capture };
    let (fitted, written) = py.allow_threads(|| {
        guard(|| {
            let t0 = Instant::now();
            let (tpl, scalp_path) = template_of(template.as_deref(), scalp.as_deref())?;
            let fitted = fit_capture(&json_path, &tpl, &FitOptions::default(), use_cameras, landmarks.as_deref())
                .map_err(fit_err)?;
            let written = if write {
                let report =
                    fitted.report(template.as_deref(), scalp_path.as_deref(), use_cameras, t0.elapsed().as_secs_f64());
                let text = serde_json::to_string_pretty(&report).map_err(to_py)?;
                Some(write_into_capture(&json_path, &fitted, &text).map_err(fit_err)?)
            } else {
                None
            };
            Ok((fitted, written))
        })
    })?;
    result_to_py(py, &fitted, written)
}

/// The landmarks `fit_head` accepts, with their places on the bundled head (canonical frame,
/// metres: Z up, the face toward −Y, the subject's left at +X): a dict of name to `[x, y, z]`.
#[pyfunction]
fn head_landmarks(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for (name, p) in hairrecon_recon::head_fit::landmarks::BUNDLED {
        d.set_item(name, p.to_vec())?;
    }
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_head, m)?)?;
    m.add_function(wrap_pyfunction!(head_landmarks, m)?)?;
    Ok(())
}
