//! Array arguments: what the functions accept, and the one error that says what they expected.
//!
//! A float argument takes any numpy array or nested list of real numbers: float32 as it is,
//! float64, float16 and integers converted to float32. An index or count argument takes any numpy
//! array or list of integers (int64, Python ints, any integer dtype), each value checked to fit
//! uint32. An empty list is an empty array of the shape expected. A wrong dtype, shape or value is
//! an `InputError` naming the argument, the dtype and shape expected, and what was given.

use numpy::{PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::error::input_err;

/// The shape an argument must have: `(N, cols)`, or `(N,)` for `cols == None`; `rows` names N.
#[derive(Debug, Clone, Copy)]
pub struct Shape {
    pub rows: &'static str,
    pub cols: Option<usize>,
}

impl std::fmt::Display for Shape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.cols {
            Some(c) => write!(f, "({}, {c})", self.rows),
            None => write!(f, "({},)", self.rows),
        }
    }
}

/// `obj` as a numpy array of `shape` (an empty list or array as zero rows).
fn array<'py>(obj: &Bound<'py, PyAny>, name: &str, expected: &str, shape: Shape) -> PyResult<Bound<'py, PyAny>> {
    let py = obj.py();
    let wrong = |got: String| input_err(format!("{name} must be {expected} of shape {shape}, got {got}"));
    let arr = py.import("numpy")?.call_method1("asarray", (obj,)).map_err(|e| wrong(format!("{e}")))?;
    let Ok(untyped) = arr.downcast::<PyUntypedArray>() else {
        return Err(wrong(arr.get_type().name()?.to_string()));
    };
    let dims = untyped.shape().to_vec();
    if untyped.len() == 0 && dims.len() == 1 {
        let zero = match shape.cols {
            Some(c) => arr.call_method1("reshape", ((0usize, c),))?,
            None => arr,
        };
        return Ok(zero);
    }
    let ok = match shape.cols {
        Some(c) => dims.len() == 2 && dims[1] == c,
        None => dims.len() == 1,
    };
    if !ok {
        return Err(wrong(described(&arr)?));
    }
    Ok(arr)
}

/// A dtype as numpy prints it (`float64`, `int64`, `bool`), with `str` for text (`<U32`).
fn numpy_name(arr: &Bound<'_, PyUntypedArray>) -> PyResult<String> {
    let name = arr.dtype().str()?.to_string();
    Ok(if matches!(arr.dtype().kind(), b'U' | b'S') { "str".into() } else { name })
}

/// A shape as Python prints it: `(5, 2)`, `(2,)`.
fn tuple(dims: &[usize]) -> String {
    match dims {
        [d] => format!("({d},)"),
        _ => format!("({})", dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// The dtype and shape of an array for an error message.
fn described(arr: &Bound<'_, PyAny>) -> PyResult<String> {
    let a = arr.downcast::<PyUntypedArray>()?;
    Ok(format!("{} of shape {}", numpy_name(a)?, tuple(a.shape())))
}

/// A float argument (see the module doc), row-major: `rows × cols` values.
pub fn floats(obj: &Bound<'_, PyAny>, name: &str, shape: Shape) -> PyResult<Vec<f32>> {
    let expected = "a float32 array (float64, integers and lists are converted)";
    let arr = array(obj, name, expected, shape)?;
    let kind = arr.downcast::<PyUntypedArray>()?.dtype().kind();
    let is_empty = arr.downcast::<PyUntypedArray>()?.len() == 0;
    if !(matches!(kind, b'f' | b'i' | b'u') || is_empty) {
        return Err(input_err(format!("{name} must be {expected} of shape {shape}, got {}", described(&arr)?)));
    }
    let not_finite = |i: usize, v: &dyn std::fmt::Debug| {
        input_err(format!(
            "{name} holds {v:?} at flat index {i}, which is not a finite float32 (NaN, infinity, or beyond ±3.4e38)"
        ))
    };
    if let Ok(a) = arr.extract::<PyReadonlyArrayDyn<'_, f32>>() {
        let values: Vec<f32> = a.as_array().iter().copied().collect();
        return match values.iter().position(|v| !v.is_finite()) {
            Some(i) => Err(not_finite(i, &values[i])),
            None => Ok(values),
        };
    }
    // Through float64 (exact for every float16 and integer up to 2^53), then checked to fit
    // float32 here rather than by numpy's cast, whose overflow is only a warning.
    let wide = arr.call_method1("astype", ("float64",))?;
    let wide = wide.extract::<PyReadonlyArrayDyn<'_, f64>>()?;
    let mut values = Vec::with_capacity(wide.as_array().len());
    for (i, &v) in wide.as_array().iter().enumerate() {
        if !(v.is_finite() && v.abs() <= f32::MAX as f64) {
            return Err(not_finite(i, &v));
        }
        values.push(v as f32);
    }
    Ok(values)
}

/// An index or count argument (see the module doc), row-major.
pub fn indices(obj: &Bound<'_, PyAny>, name: &str, shape: Shape) -> PyResult<Vec<u32>> {
    let expected = "a uint32 array (int64, other integer types and lists of ints are converted)";
    let arr = array(obj, name, expected, shape)?;
    let kind = arr.downcast::<PyUntypedArray>()?.dtype().kind();
    let is_empty = arr.downcast::<PyUntypedArray>()?.len() == 0;
    if is_empty {
        return Ok(Vec::new());
    }
    if !matches!(kind, b'i' | b'u') {
        return Err(input_err(format!("{name} must be {expected} of shape {shape}, got {}", described(&arr)?)));
    }
    let checked = |i: usize, v: Option<u32>, shown: &dyn std::fmt::Display| {
        v.ok_or_else(|| {
            input_err(format!("{name} holds {shown} at flat index {i}, which does not fit uint32 (0 to {})", u32::MAX))
        })
    };
    let mut out = Vec::new();
    if kind == b'u' {
        let view = arr.call_method1("astype", ("uint64",))?;
        let view = view.extract::<PyReadonlyArrayDyn<'_, u64>>()?;
        for (i, &v) in view.as_array().iter().enumerate() {
            out.push(checked(i, u32::try_from(v).ok(), &v)?);
        }
    } else {
        let view = arr.call_method1("astype", ("int64",))?;
        let view = view.extract::<PyReadonlyArrayDyn<'_, i64>>()?;
        for (i, &v) in view.as_array().iter().enumerate() {
            out.push(checked(i, u32::try_from(v).ok(), &v)?);
        }
    }
    Ok(out)
}
