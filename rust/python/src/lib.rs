//! Python module `hairrecon`: thin bindings of the Rust library.
//!
//! Each function borrows its numpy inputs, releases the GIL while Rust works, and converts the
//! result back; no algorithm lives here. Errors become `hairrecon.Error` or one of its subclasses
//! `CaptureError`, `FormatError`, `InputError`, `Cancelled` (see the `error` module). Array
//! arguments take float32/uint32 as they are and convert float64, int64 and lists (the `arrays`
//! module); a wrong dtype or shape is an `InputError` naming the argument. File formats for
//! scripts (capture.json, PNG, OpenEXR) are in the `io` module; importing COLMAP, Metashape and
//! transforms.json calibrations in the `importer` module; fitting the head template to a capture in the
//! `head_fit` module. Built by maturin with pyo3's `abi3-py311`, so
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
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

mod arrays;
mod error;
mod head_fit;
mod importer;
mod io;
mod job;
mod masks;

use arrays::Shape;
use error::{capture_err, format_err, guard, input_err, to_py};

/// Strands as numpy arrays: points float32 (N, 3) and counts uint32 (S,).
type StrandArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<u32>>);

/// Parses a JSON string into Python objects (dicts, lists, floats).
pub(crate) fn json_to_py(py: Python<'_>, value: &serde_json::Value) -> PyResult<PyObject> {
    let text = serde_json::to_string(value).map_err(to_py)?;
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

const POINTS: Shape = Shape { rows: "N", cols: Some(3) };
const COUNTS: Shape = Shape { rows: "S", cols: None };

fn points_from(obj: &Bound<'_, PyAny>, name: &str, rows: &'static str) -> PyResult<Vec<Vec3>> {
    let flat = arrays::floats(obj, name, Shape { rows, ..POINTS })?;
    Ok(flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

/// A strand set from the arguments named `points` and `counts`.
fn strands_from(points: (&Bound<'_, PyAny>, &str), counts: (&Bound<'_, PyAny>, &str)) -> PyResult<StrandSet> {
    let pts = points_from(points.0, points.1, "N")?;
    let c = arrays::indices(counts.0, counts.1, COUNTS)?;
    StrandSet::new(pts, c).map_err(|e| input_err(format!("the strands of {} and {}: {e}", points.1, counts.1)))
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

/// Writes strands (points float32 (N, 3), counts uint32 (S,); float64, int64 and lists are
/// converted) to a file; the format follows the extension (.hair, .data, .ply, .obj). Empty arrays
/// write a file of no strands. The file is written atomically.
#[pyfunction]
fn write_strands(py: Python<'_>, path: PathBuf, points: &Bound<'_, PyAny>, counts: &Bound<'_, PyAny>) -> PyResult<()> {
    let s = strands_from((points, "points"), (counts, "counts"))?;
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

/// Writes a triangle mesh (binary PLY for .ply, OBJ for .obj), atomically: `vertices` float32
/// (V, 3), `triangles` uint32 (T, 3), `uvs` float32 (V, 2) or None (float64, int64 and lists are
/// converted).
#[pyfunction]
#[pyo3(signature = (path, vertices, triangles, uvs=None))]
fn write_mesh(
    py: Python<'_>,
    path: PathBuf,
    vertices: &Bound<'_, PyAny>,
    triangles: &Bound<'_, PyAny>,
    uvs: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let v = points_from(vertices, "vertices", "V")?;
    let t = arrays::indices(triangles, "triangles", Shape { rows: "T", cols: Some(3) })?;
    let tris: Vec<[u32; 3]> = t.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect();
    let uv = match uvs {
        Some(a) => {
            let a = arrays::floats(a, "uvs", Shape { rows: "V", cols: Some(2) })?;
            Some(a.chunks_exact(2).map(|r| Vec2::new(r[0], r[1])).collect())
        }
        None => None,
    };
    let mesh = TriMesh::new(v, tris, None, uv).map_err(|e| input_err(format!("{}: {e}", path.display())))?;
    py.allow_threads(|| guard(|| formats::write_mesh(&path, &mesh).map_err(format_err)))
}

/// Scores predicted strands against ground truth (the metric of docs/method.md). Points are float32
/// (N, 3), counts uint32 (S,) (float64, int64 and lists are converted). Returns
/// `{"directed": [...], "undirected": [...]}`, each a list of three dicts (1 mm/10°, 2 mm/20°,
/// 3 mm/30°) with `dist_mm`, `angle_deg`, `precision`, `recall`, `f1` in percent. No strands on
/// either side is an `InputError` (a precision or recall of nothing is not a score).
#[pyfunction]
#[pyo3(signature = (pred_points, pred_counts, gt_points, gt_counts, step_mm=1.0))]
fn eval(
    py: Python<'_>,
    pred_points: &Bound<'_, PyAny>,
    pred_counts: &Bound<'_, PyAny>,
    gt_points: &Bound<'_, PyAny>,
    gt_counts: &Bound<'_, PyAny>,
    step_mm: f32,
) -> PyResult<PyObject> {
    let pred = strands_from((pred_points, "pred_points"), (pred_counts, "pred_counts"))?;
    let gt = strands_from((gt_points, "gt_points"), (gt_counts, "gt_counts"))?;
    for (s, counts, side) in [(&pred, "pred_counts", "predicted"), (&gt, "gt_counts", "ground-truth")] {
        if s.is_empty() {
            return Err(input_err(format!("{counts} is empty: there are no {side} strands to score")));
        }
    }
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
    head_fit::register(m)?;
    masks::register(m)?;
    Ok(())
}
