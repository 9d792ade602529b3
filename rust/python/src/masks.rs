//! `hairrecon.make_masks`: hair masks of every view without ground truth
//! (`hairrecon_recon::masks`, the same as `hairrecon masks`).
//!
//! ```python
//! m = hairrecon.make_masks("capture/")                 # needs a head and scalp (fit_head(write=True))
//! m["alphas"][0]                                       # float32 (H, W) in [0, 1], view order
//! m["region"]                                          # float32 (N,): each raw-mesh vertex's hair probability
//! m["report"]["region"]["hair_colours"]                # what `hairrecon masks` prints
//! hairrecon.make_masks("capture/", write=True)["written"]   # masks/<view>.png, hair_region.ply, ...
//! ```
//!
//! Runs with the GIL released. A capture without a head raises `CaptureError` saying to run
//! `fit_head(write=True)` first.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::{Capture, CaptureSpec};
use hairrecon_recon::masks::capture_masks::{report, write_folder, write_into_capture};
use hairrecon_recon::masks::quality::score_views;
use hairrecon_recon::masks::{make_masks as make, MaskError, MaskOptions};
use hairrecon_recon::progress::NoProgress;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::error::{capture_err, format_err, guard, input_err, to_py};
use crate::json_to_py;

fn mask_err(e: MaskError) -> PyErr {
    match e {
        MaskError::Format(_) => format_err(e),
        _ => capture_err(e),
    }
}

/// Makes hair masks for every view of `capture` (its folder or capture.json), which needs a head
/// and a scalp (given, or from `fit_head(capture, write=True)`).
///
/// Returns a dict: `alphas` (one float32 (H, W) array in [0, 1] per view, in the capture's order),
/// `region` (float32 (N,), the hair probability of each raw-mesh vertex), `report` (what `hairrecon
/// masks` prints: the region's summary and colour models, options, seconds, and with `score=True`
/// the IoU, alpha error and off-hair share against the capture's own masks) and `written`. With
/// `write=True` the masks go into the capture for the views without one (a user's own are kept),
/// with hair_region.ply and masks.json, and capture.json names them; with `out=DIR` into DIR
/// instead. `matting=False` keeps the silhouettes' hard edges.
///
/// Raises `CaptureError` for a capture without head or scalp (run `fit_head(write=True)`), an
/// invalid capture or, with `score=True`, a view without a mask; `FormatError` when a file cannot
/// be read or written; `InputError` for `write=True` with `out`.
#[pyfunction]
#[pyo3(signature = (capture, write=false, out=None, score=false, matting=true))]
fn make_masks<'py>(
    py: Python<'py>,
    capture: PathBuf,
    write: bool,
    out: Option<PathBuf>,
    score: bool,
    matting: bool,
) -> PyResult<Bound<'py, PyDict>> {
    if write && out.is_some() {
        return Err(input_err("give write=True (into the capture) or out=DIR, not both"));
    }
    let json_path = CaptureSpec::json_path(&capture);
    let (set, text, written) = py.allow_threads(|| {
        guard(|| {
            let t0 = Instant::now();
            let cap = Capture::load(&json_path).map_err(capture_err)?;
            let working = cap.in_canonical_frame().map_err(capture_err)?.ok_or_else(|| {
                capture_err(format!(
                    "{}: the capture is in an imported frame with no to_canonical; run fit_head(capture, write=True) first",
                    json_path.display()
                ))
            })?;
            let opts = MaskOptions { matting, ..MaskOptions::default() };
            let set = make(&working, &opts, &NoProgress).map_err(mask_err)?;
            let names: Vec<String> = cap.views.iter().map(|v| v.name.clone()).collect();
            let given: Vec<Option<PathBuf>> = cap.views.iter().map(|v| v.mask.clone()).collect();
            let scores = if score { Some(score_views(&set.alphas, &names, &given).map_err(capture_err)?) } else { None };
            let value = report(&set, &names, scores.as_deref(), &opts, t0.elapsed().as_secs_f64());
            let text = serde_json::to_string_pretty(&value).map_err(to_py)?;
            let written = if write {
                let text_spec = std::fs::read_to_string(&json_path).map_err(format_err)?;
                let spec = CaptureSpec::from_json(serde_json::from_str(&text_spec).map_err(capture_err)?, &json_path)
                    .map_err(capture_err)?;
                write_into_capture(&json_path, &spec, &set, &text).map_err(format_err)?
            } else if let Some(dir) = &out {
                write_folder(dir, &names, &set, &cap.raw_mesh, &text).map_err(format_err)?
            } else {
                Vec::new()
            };
            Ok((set, value, written))
        })
    })?;
    let d = PyDict::new(py);
    let alphas = PyList::empty(py);
    for a in &set.alphas {
        alphas.append(PyArray1::from_slice(py, &a.data).reshape([a.height as usize, a.width as usize])?)?;
    }
    d.set_item("alphas", alphas)?;
    d.set_item("region", PyArray1::from_slice(py, &set.region))?;
    d.set_item("report", json_to_py(py, &text)?)?;
    d.set_item("written", written)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(make_masks, m)?)?;
    Ok(())
}
