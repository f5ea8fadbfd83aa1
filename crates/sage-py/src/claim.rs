//! Output folders claimed by a Python driver ([`FolderClaim`]): the distributed dataset build
//! and training-data render run their scenes as Ray tasks in other processes, so the folder's
//! lock cannot live in a single pipeline call; the driver holds it in a claim from the first
//! step to the last, which keeps one writer per output folder across the steps.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sage_io::lock::FolderLock;
use std::path::{Path, PathBuf};

/// An output folder claimed by a driver ([`dataset_claim`](crate::bench::dataset_claim),
/// [`training_claim`](crate::training::training_claim)): holds the folder's lock
/// (`OUT/.sage3d.lock`) until its `release()`, the end of a `with` block, or the object's
/// collection, so that no other command (`sage3d data build`, `sage3d data render`, another
/// claim) writes the folder meanwhile. The steps that finish the work take it as proof that
/// the folder is still the driver's.
#[pyclass(module = "sage3d._sage3d", name = "FolderClaim")]
pub struct FolderClaim {
    out: PathBuf,
    lock: Option<FolderLock>,
    manifest: Option<serde_json::Value>,
}

impl FolderClaim {
    /// A claim of `out` holding `lock`, with what the folder already held finished (a
    /// training render's manifest), if anything.
    pub fn new(out: PathBuf, lock: FolderLock, manifest: Option<serde_json::Value>) -> Self {
        FolderClaim {
            out,
            lock: Some(lock),
            manifest,
        }
    }

    /// The lock of `out` that the claim holds: a `ValueError` when the claim was released or
    /// is another folder's.
    pub fn lock_of(&self, out: &Path) -> PyResult<&FolderLock> {
        let Some(lock) = &self.lock else {
            return Err(PyValueError::new_err(format!(
                "the claim of {} was released: claim the folder again",
                self.out.display()
            )));
        };
        if !lock.holds(out) {
            return Err(PyValueError::new_err(format!(
                "the claim holds {}, not {}",
                self.out.display(),
                out.display()
            )));
        }
        Ok(lock)
    }
}

#[pymethods]
impl FolderClaim {
    /// The folder claimed.
    #[getter]
    fn out(&self) -> PathBuf {
        self.out.clone()
    }

    /// The manifest when the same training-data render had already finished in the folder,
    /// else `None` (always `None` for a dataset build).
    #[getter]
    fn manifest<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::convert::to_py(py, &self.manifest)
    }

    /// True while the claim holds the folder's lock.
    #[getter]
    fn held(&self) -> bool {
        self.lock.is_some()
    }

    /// Lets go of the folder's lock (again: nothing).
    fn release(&mut self) {
        self.lock = None;
    }

    /// The claim itself, held for the `with` block.
    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// Lets go of the folder at the end of the `with` block; an exception raised in it goes on.
    #[pyo3(signature = (_kind=None, _value=None, _traceback=None))]
    fn __exit__(
        &mut self,
        _kind: Option<&Bound<'_, PyAny>>,
        _value: Option<&Bound<'_, PyAny>>,
        _traceback: Option<&Bound<'_, PyAny>>,
    ) {
        // Returning None (falsy) lets an exception raised in the block go on.
        self.release();
    }
}
