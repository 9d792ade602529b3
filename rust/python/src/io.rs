//! `hairrecon.write_capture`, `read_image`, `write_image`, `read_exr`: the file formats for Python
//! scripts, so that they read and write captures through the same code as the Rust pipeline.
//!
//! ```python
//! hairrecon.write_capture("out/capture", {"version": 1, "units": "metres", "convention": "opencv",
//!                                         "views": [...], "raw_mesh": "raw_mesh.ply"})
//! mask = hairrecon.read_image("out/capture/masks/view_000.png")   # uint16 (H, W)
//! hairrecon.write_image("depth.exr", depth[:, :, None].repeat(3, 2))   # float32 R G B
//! layers = hairrecon.read_exr("render.exr")   # {"ViewLayer.Combined.R": float32 (H, W), ...}
//! ```

use std::path::{Path, PathBuf};

use hairrecon_core::capture::CaptureSpec;
use hairrecon_core::image_io::{self, RawImage, Samples};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value;

use crate::error::{capture_err, format_err, guard, input_err};

/// Python values -> JSON, naming the offending entry (`spec['views'][0]['K'][0][2]`). Takes dicts
/// with string keys, lists, tuples, str, int, float (finite), bool, None, path-like objects (as
/// strings) and numpy arrays and scalars (through `tolist()`).
fn to_json(obj: &Bound<'_, PyAny>, at: &str) -> PyResult<Value> {
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = obj.downcast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(v) = obj.extract::<i64>() {
            return Ok(Value::from(v));
        }
        return Ok(Value::from(obj.extract::<u64>().map_err(|_| input_err(format!("{at} is too large an integer")))?));
    }
    if let Ok(f) = obj.downcast::<PyFloat>() {
        let v = f.value();
        return serde_json::Number::from_f64(v)
            .map(Value::Number)
            .ok_or_else(|| capture_err(format!("{at} is {v}; capture.json holds finite numbers only")));
    }
    if let Ok(s) = obj.downcast::<PyString>() {
        return Ok(Value::String(s.to_str()?.to_owned()));
    }
    if let Ok(d) = obj.downcast::<PyDict>() {
        let mut map = serde_json::Map::with_capacity(d.len());
        for (k, v) in d.iter() {
            let key: String =
                k.extract().map_err(|_| input_err(format!("{at} has a key {k:?} that is not a string")))?;
            let value = to_json(&v, &format!("{at}[{key:?}]"))?;
            map.insert(key, value);
        }
        return Ok(Value::Object(map));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let items = obj.try_iter()?.enumerate().map(|(i, item)| to_json(&item?, &format!("{at}[{i}]")));
        return Ok(Value::Array(items.collect::<PyResult<_>>()?));
    }
    if obj.hasattr("__fspath__")? {
        let p = obj.py().import("os")?.call_method1("fspath", (obj,))?;
        return to_json(&p, at);
    }
    if obj.hasattr("tolist")? {
        // numpy arrays and numpy scalars
        return to_json(&obj.call_method0("tolist")?, at);
    }
    let ty = obj.get_type().name()?;
    Err(input_err(format!("{at} is a {ty}, which cannot be written to capture.json")))
}

/// Checks a capture spec and writes it as capture.json, atomically. `spec` is a dict laid out as
/// capture.json (docs/capture-format.md; numpy arrays and path objects are accepted as values).
/// `path` is the capture folder (created if missing) or a `.json` file. The files the spec names need
/// not exist yet; `load_capture` checks them. Returns the path of the file written. Raises
/// `CaptureError` naming the view and field of the first problem (a missing or unknown field, an
/// invalid camera, an empty path, ...); nothing is written then.
#[pyfunction]
pub fn write_capture(py: Python<'_>, path: PathBuf, spec: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    if !spec.is_instance_of::<PyDict>() {
        let ty = spec.get_type().name()?;
        return Err(input_err(format!("write_capture: spec must be a dict laid out as capture.json, not a {ty}")));
    }
    let value = to_json(spec, "spec")?;
    py.allow_threads(|| {
        guard(|| {
            let spec = CaptureSpec::from_json(value, &CaptureSpec::json_path(&path)).map_err(capture_err)?;
            spec.write(&path).map_err(capture_err)
        })
    })
}

/// The numpy array of a raw image: (H, W) for one channel, else (H, W, C).
fn raw_to_py<'py>(py: Python<'py>, img: RawImage) -> PyResult<Bound<'py, PyAny>> {
    let (h, w, c) = (img.height as usize, img.width as usize, img.channels);
    let shape: Vec<usize> = if c == 1 { vec![h, w] } else { vec![h, w, c] };
    Ok(match img.samples {
        Samples::U8(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
        Samples::U16(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
        Samples::F32(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
    })
}

/// Reads a PNG or OpenEXR image (the type is taken from the file's first bytes) with its own
/// values: PNG as uint8 or uint16 (8- or 16-bit files), EXR as float32 (channels R G B [A], else
/// Y [A], else its only channel; other channels: `read_exr`). Shape (H, W) for one channel, else
/// (H, W, C), top row first. Raises `FormatError`.
#[pyfunction]
pub fn read_image<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let img = py.allow_threads(|| guard(|| image_io::read_image(&path).map_err(format_err)))?;
    raw_to_py(py, img)
}

/// Every channel of an OpenEXR file, over all its layers (Blender's multilayer renders), as
/// `{name: float32 (H, W)}`. Raises `FormatError`.
#[pyfunction]
pub fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let exr = py.allow_threads(|| guard(|| image_io::read_exr_channels(&path).map_err(format_err)))?;
    let (h, w) = (exr.height as usize, exr.width as usize);
    let d = PyDict::new(py);
    for (name, values) in exr.channels {
        d.set_item(name, PyArray1::from_vec(py, values).reshape([h, w])?)?;
    }
    Ok(d)
}

/// The samples of an array in row-major order (any strides), with its shape.
fn samples_of<T: numpy::Element + Copy>(a: &PyReadonlyArrayDyn<'_, T>) -> (Vec<usize>, Vec<T>) {
    let view = a.as_array();
    (view.shape().to_vec(), view.iter().copied().collect())
}

fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default()
}

/// Writes an image, by the extension: `.png` from uint8 (8-bit) or uint16 (16-bit) arrays, values
/// unchanged; `.exr` from float arrays (written as 32-bit float, values unchanged) with channels
/// named `channels`, by default Y, Y A, R G B or R G B A. `array` is (H, W) or (H, W, C) with 1 to 4
/// channels (gray, gray + alpha, RGB, RGBA), top row first. Atomic: an error leaves no file. Raises
/// `InputError` for a bad array or arguments, `FormatError` when the file cannot be written.
#[pyfunction]
#[pyo3(signature = (path, array, channels=None))]
pub fn write_image(
    py: Python<'_>,
    path: PathBuf,
    array: &Bound<'_, PyAny>,
    channels: Option<Vec<String>>,
) -> PyResult<()> {
    let Ok(arr) = array.downcast::<PyUntypedArray>() else {
        let ty = array.get_type().name()?;
        return Err(input_err(format!("write_image: array must be a numpy array, not a {ty}")));
    };
    let dtype = arr.dtype().str()?.to_string();
    let ext = extension(&path);
    let (shape, samples) = match ext.as_str() {
        "png" => {
            if channels.is_some() {
                return Err(input_err("write_image: channel names are for .exr; a PNG's channels are gray, gray + alpha, RGB or RGBA by their count"));
            }
            if let Ok(a) = array.extract::<PyReadonlyArrayDyn<'_, u8>>() {
                let (s, v) = samples_of(&a);
                (s, Samples::U8(v))
            } else if let Ok(a) = array.extract::<PyReadonlyArrayDyn<'_, u16>>() {
                let (s, v) = samples_of(&a);
                (s, Samples::U16(v))
            } else {
                return Err(input_err(format!(
                    "write_image: a PNG takes uint8 or uint16 values, got {dtype}; convert them (e.g. \
                     np.round(x * 65535).astype(np.uint16)) or write .exr"
                )));
            }
        }
        "exr" => {
            if let Ok(a) = array.extract::<PyReadonlyArrayDyn<'_, f32>>() {
                let (s, v) = samples_of(&a);
                (s, Samples::F32(v))
            } else if let Ok(a) = array.extract::<PyReadonlyArrayDyn<'_, f64>>() {
                let (s, v) = samples_of(&a);
                (s, Samples::F32(v.into_iter().map(|x| x as f32).collect()))
            } else {
                return Err(input_err(format!(
                    "write_image: an OpenEXR file takes float32 or float64 values, got {dtype}"
                )));
            }
        }
        other => {
            return Err(input_err(format!(
                "write_image: {} has the extension {other:?}; write .png or .exr",
                path.display()
            )))
        }
    };
    let (h, w, c) = match shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c] if (1..=4).contains(&c) => (h, w, c),
        _ => {
            return Err(input_err(format!(
                "write_image: array must have shape (H, W) or (H, W, C) with 1 to 4 channels, got {shape:?}"
            )))
        }
    };
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(input_err(format!("write_image: the image is too large ({w}x{h})")));
    };
    let img = RawImage::new(w32, h32, c, samples).map_err(|e| input_err(format!("write_image: {}", e.kind)))?;
    if let Some(n) = &channels {
        if n.len() != c {
            return Err(input_err(format!("write_image: {} channel names for an array of {c} channels", n.len())));
        }
    }
    py.allow_threads(|| guard(|| image_io::write_image(&path, &img, channels.as_deref()).map_err(format_err)))
}

/// Exposes the functions of this file.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(write_capture, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(write_image, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    Ok(())
}
