//! Conversions at the Python boundary: errors, JSON values, points and NumPy arrays.

use glam::Vec2;
use numpy::ndarray::{Array, Dimension};
use numpy::{Element, IntoPyArray};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sage_core::ErrorKind;
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Turns sage3d errors into Python exceptions: `OSError` for file-system failures,
/// `ValueError` for bad input, with the error's full message (file, field, what was expected).
pub trait PyResultExt<T> {
    /// The result with its error as a Python exception.
    fn py(self) -> PyResult<T>;
}

impl<T> PyResultExt<T> for sage_core::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| match e.kind() {
            ErrorKind::Io => PyOSError::new_err(e.to_string()),
            _ => PyValueError::new_err(e.to_string()),
        })
    }
}

/// A JSON value as the equivalent Python object (dict, list, str, float, int, bool, None).
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// Any serialisable value as a Python object, through its JSON form.
pub fn to_py<'py>(py: Python<'py>, value: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    json_to_py(py, &v)
}

/// Parses `text` (JSON written by the Python side) as `T`, naming `what` on failure.
pub fn from_json<T: DeserializeOwned>(text: &str, what: &str) -> PyResult<T> {
    serde_json::from_str(text).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

/// A floor point from 2 (x, y) or 3 (x, y, z; z ignored) coordinates in the W frame.
pub fn point(p: &[f32], what: &str) -> PyResult<Vec2> {
    match p {
        [x, y] | [x, y, _] if x.is_finite() && y.is_finite() => Ok(Vec2::new(*x, *y)),
        _ => Err(PyValueError::new_err(format!(
            "{what}: expected finite [x, y] or [x, y, z], got {p:?}"
        ))),
    }
}

/// A NumPy array of `shape` that owns `data` (no copy): the Rust buffer becomes the array's.
pub fn array<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: D,
    data: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let a = Array::from_shape_vec(shape, data)
        .map_err(|e| PyValueError::new_err(format!("array shape: {e}")))?;
    Ok(a.into_pyarray(py).into_any())
}
