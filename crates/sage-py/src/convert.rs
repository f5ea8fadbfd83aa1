//! Conversions at the Python boundary: errors, arguments, JSON values, points and NumPy arrays.

use glam::Vec2;
use numpy::ndarray::{Array, Dimension};
use numpy::{Element, IntoPyArray};
use pyo3::exceptions::{PyOSError, PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sage_core::ErrorKind;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::path::PathBuf;

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
/// is a `ValueError` naming it, as is a value of the wrong type. A path (`os.PathLike`) is
/// taken as its string, as the path arguments take it; any other value JSON cannot hold (a
/// set, an object) is a `TypeError` naming its keyword.
pub fn from_kwargs<T: DeserializeOwned>(
    py: Python<'_>,
    kwargs: Option<&Bound<'_, PyDict>>,
    what: &str,
) -> PyResult<T> {
    let dumps = py.import("json")?.getattr("dumps")?;
    let options = PyDict::new(py);
    options.set_item("default", py.import("os")?.getattr("fspath")?)?;
    // JSON has no NaN or infinity: refused here, each is named with its argument.
    options.set_item("allow_nan", false)?;
    let mut fields = Vec::new();
    for (k, v) in kwargs.into_iter().flat_map(|d| d.iter()) {
        if v.is_none() {
            continue;
        }
        let key: String = k.extract()?;
        // One value at a time, so that the one `json.dumps` refuses is named.
        let value: String = dumps
            .call((&v,), Some(&options))
            .map_err(|e| {
                if e.is_instance_of::<PyValueError>(py)
                    && e.to_string().contains("Out of range float")
                {
                    PyValueError::new_err(format!(
                        "{what}: `{key}`: expected finite numbers, got {}",
                        v.repr()
                            .map_or_else(|_| "NaN or infinity".into(), |r| r.to_string())
                    ))
                } else {
                    PyTypeError::new_err(format!(
                        "{what}: `{key}`: expected a JSON value (str, number, bool, list or \
                         dict) or a path, got {}",
                        type_name(&v)
                    ))
                }
            })?
            .extract()?;
        let key = serde_json::to_string(&key).map_err(|e| PyValueError::new_err(e.to_string()))?;
        fields.push(format!("{key}:{value}"));
    }
    from_json(&format!("{{{}}}", fields.join(",")), what)
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

/// The type of `obj` as Python names it (`str`, `NoneType` as `None`), for messages.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    if obj.is_none() {
        return "None".to_string();
    }
    obj.get_type()
        .name()
        .map_or_else(|_| "?".to_string(), |n| n.to_string())
}

/// The `TypeError` of an argument `what` (`find_path: start`) given `obj` where `expected`
/// was.
fn wrong_type(obj: &Bound<'_, PyAny>, what: &str, expected: &str) -> PyErr {
    PyTypeError::new_err(format!(
        "{what}: expected {expected}, got {}",
        type_name(obj)
    ))
}

/// A value of a Python argument, or a `TypeError` / `ValueError` that names the function and
/// the argument (`what`, such as `PathFinder.find_path: start`) and says what was expected.
/// PyO3's own conversion errors name neither in their message (it adds the argument as a note
/// of the exception, which `str(e)` leaves out). Arguments take it through `arg_extractors`.
pub trait Arg: Sized {
    /// Converts `obj`, the value given for `what`.
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self>;
}

impl<T: Arg> Arg for Option<T> {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if obj.is_none() {
            Ok(None)
        } else {
            T::arg(obj, what).map(Some)
        }
    }
}

impl Arg for PathBuf {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        obj.extract()
            .map_err(|_| wrong_type(obj, what, "a path (str or os.PathLike)"))
    }
}

impl Arg for String {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        obj.extract().map_err(|_| wrong_type(obj, what, "a string"))
    }
}

impl Arg for bool {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        obj.extract()
            .map_err(|_| wrong_type(obj, what, "True or False"))
    }
}

impl Arg for f32 {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        obj.extract().map_err(|_| wrong_type(obj, what, "a number"))
    }
}

/// Whole numbers: any Python integer (NumPy's too) is taken wide and then checked against the
/// type's range, so a negative or huge one is a `ValueError` naming the argument and the range
/// rather than PyO3's `OverflowError`, which names neither.
macro_rules! whole_number_args {
    ($($t:ty),*) => {$(
        impl Arg for $t {
            fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
                let out_of_range = |value: String| {
                    PyValueError::new_err(format!(
                        "{what}: expected a whole number within {}, got {value}",
                        stringify!($t)
                    ))
                };
                match obj.extract::<i128>() {
                    Ok(v) => <$t>::try_from(v).map_err(|_| out_of_range(v.to_string())),
                    Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
                        Err(out_of_range(obj.to_string()))
                    }
                    Err(_) => Err(wrong_type(obj, what, "a whole number")),
                }
            }
        }
    )*};
}
whole_number_args!(u16, u32, u64, usize);

/// A floor point from 2 (x, y) or 3 (x, y, z; z ignored) finite coordinates in the W frame.
impl Arg for Vec2 {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let p: Vec<f32> = obj.extract().map_err(|_| {
            wrong_type(
                obj,
                what,
                "[x, y] or [x, y, z] (a sequence of 2 or 3 numbers)",
            )
        })?;
        match p[..] {
            [x, y] | [x, y, _] if x.is_finite() && y.is_finite() => Ok(Vec2::new(x, y)),
            _ => Err(PyValueError::new_err(format!(
                "{what}: expected finite [x, y] or [x, y, z], got {p:?}"
            ))),
        }
    }
}

/// A Python callable given as an argument (a callback).
pub struct Callable(pub Py<PyAny>);

impl Arg for Callable {
    fn arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if obj.is_callable() {
            Ok(Callable(obj.clone().unbind()))
        } else {
            Err(wrong_type(obj, what, "a callable"))
        }
    }
}

/// Defines the functions that `#[pyo3(from_py_with = ...)]` names to convert an argument with
/// [`Arg`]: `name: Type = "function: argument";` defines `fn name(obj) -> PyResult<Type>`
/// whose errors name `function: argument`. (PyO3 takes only a path there, not a call with the
/// name.)
macro_rules! arg_extractors {
    ($($name:ident: $ty:ty = $what:literal;)*) => {$(
        #[doc = concat!("Converts `", $what, "` (see [`Arg`](crate::convert::Arg)).")]
        fn $name(obj: &pyo3::Bound<'_, pyo3::PyAny>) -> pyo3::PyResult<$ty> {
            <$ty as $crate::convert::Arg>::arg(obj, $what)
        }
    )*};
}
pub(crate) use arg_extractors;

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
