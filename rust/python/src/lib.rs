//! Python module `hairrecon`: thin bindings of the Rust library.
//!
//! Each function borrows its numpy inputs, releases the GIL while Rust works, and converts the
//! result back; no algorithm lives here. Errors become `hairrecon.Error` or one of its subclasses
//! `CaptureError`, `FormatError`, `InputError`, `Cancelled` (see the `error` module). File formats for
//! scripts (capture.json, PNG, OpenEXR) are in the `io` module; importing COLMAP, Metashape and
//! transforms.json calibrations in the `importer` module. Built by maturin with pyo3's `abi3-py311`, so
//! one wheel serves Blender 4.2+.
//!
//! ```python
//! import hairrecon
//! points, counts = hairrecon.read_strands("gt.hair")          # float32 (N, 3), uint32 (S,)
//! report = hairrecon.eval(points, counts, points, counts)    # {"directed": [...], "undirected": [...]}
//! ```

use std::path::PathBuf;

use glam::{Vec2, Vec3};
use hairrecon_core::capture::Capture;
use hairrecon_core::formats;
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::{StrandSet, TriMesh};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

mod error;
mod importer;
mod io;
mod job;

use error::{capture_err, format_err, guard, input_err, to_py};

/// Strands as numpy arrays: points float32 (N, 3) and counts uint32 (S,).
type StrandArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<u32>>);

/// Parses a JSON string into Python objects (dicts, lists, floats).
pub(crate) fn json_to_py(py: Python<'_>, value: &serde_json::Value) -> PyResult<PyObject> {
    let text = serde_json::to_string(value).map_err(to_py)?;
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

fn points_from(arr: &PyReadonlyArray2<'_, f32>, what: &str) -> PyResult<Vec<Vec3>> {
    let view = arr.as_array();
    if view.ncols() != 3 {
        return Err(input_err(format!("{what} must have shape (N, 3), got {:?}", view.shape())));
    }
    Ok(view.rows().into_iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect())
}

fn strands_from(
    points: &PyReadonlyArray2<'_, f32>,
    counts: &PyReadonlyArray1<'_, u32>,
    what: &str,
) -> PyResult<StrandSet> {
    let pts = points_from(points, &format!("{what} points"))?;
    let counts = counts.as_array().to_vec();
    StrandSet::new(pts, counts).map_err(|e| input_err(format!("{what} strands: {e}")))
}

fn points_to_py<'py>(py: Python<'py>, pts: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = pts.iter().flat_map(|p| p.to_array()).collect();
    PyArray1::from_vec(py, flat).reshape([pts.len(), 3])
}

/// Reads strands from a .hair, .data, .ply or .obj file. Returns `(points, counts)`: float32 (N, 3)
/// and uint32 (S,), each strand root first. A strand of one point is an error (`FormatError`), or
/// is dropped with `skip_short_strands=True` (.hair and .data files can hold them).
#[pyfunction]
#[pyo3(signature = (path, skip_short_strands=false))]
fn read_strands<'py>(py: Python<'py>, path: PathBuf, skip_short_strands: bool) -> PyResult<StrandArrays<'py>> {
    let options = formats::StrandReadOptions { skip_short_strands };
    let s =
        py.allow_threads(|| guard(|| formats::read_strands_with(&path, options).map(|(s, _)| s).map_err(format_err)))?;
    let (pts, counts) = s.into_parts();
    Ok((points_to_py(py, &pts)?, PyArray1::from_vec(py, counts)))
}

/// Writes strands (points float32 (N, 3), counts uint32 (S,)) to a file; the format follows the
/// extension (.hair, .data, .ply, .obj). The file is written atomically.
#[pyfunction]
fn write_strands(
    py: Python<'_>,
    path: PathBuf,
    points: PyReadonlyArray2<'_, f32>,
    counts: PyReadonlyArray1<'_, u32>,
) -> PyResult<()> {
    let s = strands_from(&points, &counts, "the")?;
    py.allow_threads(|| guard(|| formats::write_strands(&path, &s).map_err(format_err)))
}

/// Reads a triangle mesh (.ply or .obj). Returns a dict with `vertices` float32 (V, 3),
/// `triangles` uint32 (T, 3), `uvs` float32 (V, 2) or None, `normals` float32 (V, 3) or None.
#[pyfunction]
fn read_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let m = py.allow_threads(|| guard(|| formats::read_mesh(&path).map_err(format_err)))?;
    let d = PyDict::new(py);
    d.set_item("vertices", points_to_py(py, &m.vertices)?)?;
    let tris: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    d.set_item("triangles", PyArray1::from_vec(py, tris).reshape([m.triangles.len(), 3])?)?;
    match &m.uvs {
        Some(uv) => {
            let flat: Vec<f32> = uv.iter().flat_map(|u| u.to_array()).collect();
            d.set_item("uvs", PyArray1::from_vec(py, flat).reshape([uv.len(), 2])?)?
        }
        None => d.set_item("uvs", py.None())?,
    }
    match &m.normals {
        Some(n) => d.set_item("normals", points_to_py(py, n)?)?,
        None => d.set_item("normals", py.None())?,
    }
    Ok(d)
}

/// Writes a triangle mesh (binary PLY for .ply, OBJ for .obj), atomically.
#[pyfunction]
#[pyo3(signature = (path, vertices, triangles, uvs=None))]
fn write_mesh(
    py: Python<'_>,
    path: PathBuf,
    vertices: PyReadonlyArray2<'_, f32>,
    triangles: PyReadonlyArray2<'_, u32>,
    uvs: Option<PyReadonlyArray2<'_, f32>>,
) -> PyResult<()> {
    let v = points_from(&vertices, "vertices")?;
    let t = triangles.as_array();
    if t.ncols() != 3 {
        return Err(input_err(format!("triangles must have shape (T, 3), got {:?}", t.shape())));
    }
    let tris: Vec<[u32; 3]> = t.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
    let uv = match &uvs {
        Some(a) => {
            let a = a.as_array();
            if a.ncols() != 2 {
                return Err(input_err(format!("uvs must have shape (V, 2), got {:?}", a.shape())));
            }
            Some(a.rows().into_iter().map(|r| Vec2::new(r[0], r[1])).collect())
        }
        None => None,
    };
    let mesh = TriMesh::new(v, tris, None, uv).map_err(|e| input_err(format!("{}: {e}", path.display())))?;
    py.allow_threads(|| guard(|| formats::write_mesh(&path, &mesh).map_err(format_err)))
}

/// Scores predicted strands against ground truth (the metric of docs/method.md). Returns
/// `{"directed": [...], "undirected": [...]}`, each a list of three dicts (1 mm/10°, 2 mm/20°,
/// 3 mm/30°) with `dist_mm`, `angle_deg`, `precision`, `recall`, `f1` in percent.
#[pyfunction]
#[pyo3(signature = (pred_points, pred_counts, gt_points, gt_counts, step_mm=1.0))]
fn eval(
    py: Python<'_>,
    pred_points: PyReadonlyArray2<'_, f32>,
    pred_counts: PyReadonlyArray1<'_, u32>,
    gt_points: PyReadonlyArray2<'_, f32>,
    gt_counts: PyReadonlyArray1<'_, u32>,
    step_mm: f32,
) -> PyResult<PyObject> {
    let pred = strands_from(&pred_points, &pred_counts, "predicted")?;
    let gt = strands_from(&gt_points, &gt_counts, "ground-truth")?;
    let report = py.allow_threads(|| {
        guard(|| evaluate(&pred, &gt, &MetricOptions { step: step_mm * 1e-3, ..Default::default() }).map_err(input_err))
    })?;
    json_to_py(py, &serde_json::to_value(&report).map_err(to_py)?)
}

/// Validates a capture folder (or capture.json) and returns a summary dict; raises
/// `CaptureError` naming the view and file of the first problem.
#[pyfunction]
fn load_capture<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let c = py.allow_threads(|| guard(|| Capture::load(&path).map_err(capture_err)))?;
    let d = PyDict::new(py);
    d.set_item("num_views", c.views.len())?;
    d.set_item("views", c.views.iter().map(|v| v.name.clone()).collect::<Vec<_>>())?;
    d.set_item("raw_mesh", c.raw_mesh)?;
    d.set_item("scalp_mesh", c.scalp_mesh)?;
    d.set_item("head_mesh", c.head_mesh)?;
    d.set_item("gt_strands", c.gt_strands)?;
    Ok(d)
}

#[pymodule]
fn hairrecon(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    error::register(m)?;
    m.add_function(wrap_pyfunction!(read_strands, m)?)?;
    m.add_function(wrap_pyfunction!(write_strands, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(write_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(eval, m)?)?;
    m.add_function(wrap_pyfunction!(load_capture, m)?)?;
    io::register(m)?;
    job::register(m)?;
    importer::register(m)?;
    Ok(())
}
