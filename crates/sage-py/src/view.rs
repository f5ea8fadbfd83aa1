//! The browser viewer from Python: `sage3d.view(path)` serves what `sage3d view PATH` serves
//! (`sage-view`), until Ctrl-C.

use crate::convert::{Callable, PyResultExt, arg_extractors};
use pyo3::prelude::*;
use sage_core::{Error, ResultExt};
use sage_view::ViewOptions;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

arg_extractors! {
    view_path: PathBuf = "view: path";
    view_scenes: Option<PathBuf> = "view: scenes";
    view_split: Option<String> = "view: split";
    view_play: Option<PathBuf> = "view: play";
    view_force: bool = "view: force";
    view_preset: String = "view: preset";
    view_mode: String = "view: mode";
    view_device: String = "view: device";
    view_host: String = "view: host";
    view_port: u16 = "view: port";
    view_public: bool = "view: public";
    view_on_ready: Option<Callable> = "view: on_ready";
}

/// Serves the viewer over `path` (a scene, a folder of scenes, a dataset or an evaluation run)
/// until interrupted (Ctrl-C, which is raised as `KeyboardInterrupt` when the server has
/// stopped). The keyword arguments are `sage3d view`'s flags by name; `on_ready(url)` is
/// called once the server listens, before it answers (default: print the URL); an exception
/// it raises stops the server and is raised here. `play=RUN` records human play of the
/// dataset split into the run folder RUN.
#[pyfunction]
#[pyo3(
    signature = (
        path, *, scenes=None, split=None, play=None, force=false, preset="sage".to_string(),
        mode="sage".to_string(), device="cpu".to_string(), host="127.0.0.1".to_string(),
        port=8765, public=false, on_ready=None
    ),
    // PyO3 shows a default it cannot print as a Python literal (`"sage".to_string()`) as `...`:
    // the signature `help()` and `inspect.signature` read is written out here.
    text_signature = "(path, *, scenes=None, split=None, play=None, force=False, preset='sage', \
                      mode='sage', device='cpu', host='127.0.0.1', port=8765, public=False, \
                      on_ready=None)"
)]
#[allow(clippy::too_many_arguments)]
pub fn view(
    py: Python<'_>,
    #[pyo3(from_py_with = view_path)] path: PathBuf,
    #[pyo3(from_py_with = view_scenes)] scenes: Option<PathBuf>,
    #[pyo3(from_py_with = view_split)] split: Option<String>,
    #[pyo3(from_py_with = view_play)] play: Option<PathBuf>,
    #[pyo3(from_py_with = view_force)] force: bool,
    #[pyo3(from_py_with = view_preset)] preset: String,
    #[pyo3(from_py_with = view_mode)] mode: String,
    #[pyo3(from_py_with = view_device)] device: String,
    #[pyo3(from_py_with = view_host)] host: String,
    #[pyo3(from_py_with = view_port)] port: u16,
    #[pyo3(from_py_with = view_public)] public: bool,
    #[pyo3(from_py_with = view_on_ready)] on_ready: Option<Callable>,
) -> PyResult<()> {
    let opts = ViewOptions {
        scenes,
        split,
        play,
        force,
        preset,
        mode: mode.parse().within("mode").py()?,
        device: device.parse().within("device").py()?,
        host: host
            .parse()
            .map_err(|_| Error::invalid(format!("host: '{host}' is not an IP address")))
            .py()?,
        port,
        public,
        ..ViewOptions::new(path)
    };
    // The exception that stopped the server (an interrupt, or `on_ready`'s), raised once it
    // has.
    let interrupted: Arc<Mutex<Option<PyErr>>> = Arc::default();
    let keep = |e: PyErr| {
        if let Ok(mut slot) = interrupted.lock() {
            slot.get_or_insert(e);
        }
    };
    py.detach(|| {
        sage_view::serve(
            &opts,
            |server| {
                Python::attach(|py| match &on_ready {
                    Some(Callable(f)) => {
                        if let Err(e) = f.call1(py, (server.url.clone(),)) {
                            keep(e);
                        }
                    }
                    None => println!("{}", server.announcement()),
                })
            },
            || {
                let failed = interrupted.lock().is_ok_and(|slot| slot.is_some());
                !failed
                    && Python::attach(|py| match py.check_signals() {
                        Ok(()) => true,
                        Err(e) => {
                            keep(e);
                            false
                        }
                    })
            },
        )
    })
    .py()?;
    let raised = interrupted.lock().ok().and_then(|mut e| e.take());
    raised.map_or(Ok(()), Err)
}
