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

/// Any serialisable value as a Python object (dict, list, str, float, int, bool, None) through
/// its JSON text, parsed by Python's `json`: numbers come out as the files print them (an `f32`
/// as its shortest decimal, an `f64` exactly), so an episode or summary read here equals the
/// same one read from sage3d's files with `json`.
pub fn to_py<'py>(py: Python<'py>, value: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Removes, at any depth, the dict entries whose value is `None`: an undefined value becomes an
/// absent key, so every key keeps one type across steps and episodes (Gymnasium's vector info
/// batching types its arrays by the first value it sees).
pub fn drop_none(obj: &Bound<'_, PyAny>) -> PyResult<()> {
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut none = Vec::new();
        for (k, v) in d.iter() {
            if v.is_none() {
                none.push(k);
            } else {
                drop_none(&v)?;
            }
        }
        for k in none {
            d.del_item(k)?;
        }
    } else if let Ok(l) = obj.cast::<PyList>() {
        for v in l.iter() {
            drop_none(&v)?;
        }
    }
    Ok(())
}

/// Keyword arguments as the settings struct `T` (serde, its defaults for every absent or
/// `None` value), so a Python signature restates no default and an unknown or misspelt keyword
/// is a `ValueError` naming it.
pub fn from_kwargs<T: DeserializeOwned>(
    py: Python<'_>,
    kwargs: Option<&Bound<'_, PyDict>>,
    what: &str,
) -> PyResult<T> {
    let given = PyDict::new(py);
    for (k, v) in kwargs.into_iter().flat_map(|d| d.iter()) {
        if !v.is_none() {
            given.set_item(k, v)?;
        }
    }
    let text: String = py
        .import("json")?
        .call_method1("dumps", (given,))?
        .extract()?;
    from_json(&text, what)
}

/// The Python integer `value` of argument `name` as the unsigned `T`, or a `ValueError` naming
/// the argument and the type's range (PyO3's own `OverflowError` for a negative or huge int
/// names neither).
pub fn unsigned<T: TryFrom<i128>>(name: &str, value: i128) -> PyResult<T> {
    T::try_from(value).map_err(|_| {
        PyValueError::new_err(format!(
            "{name}: expected a whole number within {}, got {value}",
            std::any::type_name::<T>()
        ))
    })
}

/// Parses `text` (JSON written by the Python side) as `T`, naming `what` and the argument at
/// fault (`per_scene`, `sensors.width`) on failure.
pub fn from_json<T: DeserializeOwned>(text: &str, what: &str) -> PyResult<T> {
    serde_path_to_error::deserialize(&mut serde_json::Deserializer::from_str(text)).map_err(|e| {
        let path = e.path().to_string();
        let message = sage_io::files::json_message(e.inner());
        PyValueError::new_err(if path == "." {
            format!("{what}: {message}")
        } else {
            format!("{what}: `{path}`: {message}")
        })
    })
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
