//! Training data from Python: the render of `sage3d data render` (`sage-traindata`) in one
//! call, and its steps (plan, claim, one scene, finish) that `sage3d.distributed` runs as Ray
//! tasks. The steps take the render's settings as JSON (`sage_traindata::Settings`), made by
//! [`training_settings`] from the same keyword arguments [`render_training_data`] takes;
//! both, like the command line, turn them into settings with `sage_traindata::Options`. The
//! claim ([`FolderClaim`]) holds the output folder's lock for the driver until it lets go,
//! so that one writer per folder holds across the steps.

use crate::claim::FolderClaim;
use crate::convert::{PyResultExt, arg_extractors, from_json, from_kwargs, to_py};
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sage_traindata::{Options, Plan, RouteDone, SceneProgress, Settings};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The options of a render from its dataset, scenes folder and keyword arguments (those of
/// `sage_traindata::Options`, by name; absent ones take its defaults).
fn options(
    py: Python<'_>,
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Options> {
    let given: Options = from_kwargs(py, kwargs, "training-data options")?;
    Ok(Options {
        dataset,
        scenes,
        ..given
    })
}

/// The settings of a render as JSON (`sage_traindata::Settings`), from the keyword arguments
/// of [`render_training_data`] (without `out` and `force`): what the step functions take.
#[pyfunction]
#[pyo3(signature = (dataset, scenes, **options))]
pub fn training_settings(
    py: Python<'_>,
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<String> {
    let s = self::options(py, dataset, scenes, options)?
        .settings()
        .py()?;
    serde_json::to_string(&s).map_err(|e| PyValueError::new_err(e.to_string()))
}

arg_extractors! {
    render_dataset: PathBuf = "render_training_data: dataset";
    render_scenes: Option<PathBuf> = "render_training_data: scenes";
    render_out: PathBuf = "render_training_data: out";
    render_force: bool = "render_training_data: force";
}

/// Renders (or resumes) a training set into `out`, as `sage3d data render DATASET --scenes
/// SCENES --out OUT ...` does (the same pipeline function, the same files byte for byte;
/// `scenes=None`: the scenes folder the dataset records, as without `--scenes`). The keyword
/// arguments are the command's flags by name, with the same defaults: `split` (`"train"`),
/// `preset` (`"navila_small"`; `vlnce`, `navila_large`, `custom_small`), `step` and `turn`
/// (override the preset's), `max_actions` (50), `answers` (`"sage"`: `move forward 0.35 meter`
/// as SAGE-3D wrote them; `"navila"`: `move forward 35 cm` as stock NaVILA and its evaluator
/// speak, a step or turn not whole in centimetres or degrees refused), `width`/`height` (224),
/// `hfov` (90),
/// `sensors` (`"rgb"`, `"rgb,depth"` or a list of `rgb`, `depth`, `semantic`, `instance`),
/// `format` (`"navila"`, `"webdataset"`, `"frames"` or `"lerobot"`: LeRobot v3.0, frames
/// always PNG), `shard_size` (samples per NaVILA part, 10000, or episodes per WebDataset shard,
/// 100), `limit`, `seed` (0), `agent` (`"wheeled"`), `image` (`"jpg"` or `"png"`),
/// `jpeg_quality` (90), `keep_failed`, `preview` (0), `device` (`"cpu"`, `"gpu"` or `"auto"`)
/// and `splat_bodies` (`"auto"`, `"always"` or `"never"`: which objects get bodies recovered
/// from their Gaussians for the walks). A finished render in `out` with the same
/// settings is returned as it is; `force` replaces another render's output. Returns the
/// manifest (`manifest.json`).
#[pyfunction]
#[pyo3(signature = (dataset, scenes, out, force=false, **options))]
pub fn render_training_data<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = render_dataset)] dataset: PathBuf,
    #[pyo3(from_py_with = render_scenes)] scenes: Option<PathBuf>,
    #[pyo3(from_py_with = render_out)] out: PathBuf,
    #[pyo3(from_py_with = render_force)] force: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let options = self::options(py, dataset, scenes, options)?;
    let changes = std::sync::Mutex::new(Vec::new());
    let report = py
        .detach(|| {
            sage_pipeline::traindata::render(&options, &out, force, &|p| {
                if let sage_traindata::Progress::Planned { scene_changes, .. } = p {
                    *changes.lock().unwrap_or_else(|e| e.into_inner()) = scene_changes.to_vec();
                }
            })
        })
        .py()?;
    let changes = changes.into_inner().unwrap_or_else(|e| e.into_inner());
    if !changes.is_empty() {
        let message = format!(
            "scene files changed since the dataset was built ({}): its reference paths were planned on the files as they were; build the dataset again to walk the scenes as they are",
            changes.join(", ")
        );
        let message =
            std::ffi::CString::new(message).map_err(|e| PyValueError::new_err(e.to_string()))?;
        PyErr::warn(py, &py.get_type::<PyRuntimeWarning>(), &message, 1)?;
    }
    to_py(py, &report.manifest)
}

/// The plan of the render with `settings_json` (reads the split and the scenes folder).
fn plan(py: Python<'_>, settings_json: &str) -> PyResult<Plan> {
    let s: Settings = from_json(settings_json, "training settings")?;
    py.detach(|| Plan::new(&s)).py()
}

/// The scenes with episodes to render, sorted: one task each.
#[pyfunction]
pub fn training_plan_scenes(py: Python<'_>, settings_json: &str) -> PyResult<Vec<String>> {
    Ok(plan(py, settings_json)?.scenes())
}

/// Per scene, its route count and the records of the routes already done under `out`
/// (`{scene: {"routes": n, "done": ["images/{scene}/{route}/route.json", ...]}}`), as the
/// render itself tells a finished route.
#[pyfunction]
pub fn training_progress<'py>(
    py: Python<'py>,
    settings_json: &str,
    out: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let plan = plan(py, settings_json)?;
    let progress: BTreeMap<String, SceneProgress> = py.detach(|| plan.scene_progress(&out));
    to_py(py, &progress)
}

/// Renders the routes of `scene` not done under `out` (frames and `route.json` per route
/// under `out/images/{scene}/`), as one step of the command line's render. Returns `{"routes":
/// rendered, "frames": written, "errors": routes that could not be walked, "files": [...]}`,
/// `files` being what the routes rendered now wrote, relative to `out`, in the order to copy
/// them elsewhere (each route's record last).
#[pyfunction]
pub fn training_render_scene<'py>(
    py: Python<'py>,
    settings_json: &str,
    scene: &str,
    out: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let plan = plan(py, settings_json)?;
    if !plan.routes.contains_key(scene) {
        return Err(PyValueError::new_err(format!(
            "scene '{scene}' has no episodes in this render (scenes: {})",
            plan.scenes().join(", ")
        )));
    }
    let done = std::sync::Mutex::new(Vec::new());
    let rendered = py
        .detach(|| {
            sage_traindata::render_scene(&plan, scene, &out, &|r: &RouteDone| {
                done.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(r.clone());
            })?;
            let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
            done.sort_by(|a, b| a.route.cmp(&b.route));
            let mut files = Vec::new();
            for r in &done {
                files.extend(r.files(&out)?);
            }
            Ok::<_, sage_core::Error>(serde_json::json!({
                "routes": done.len(),
                "frames": done.iter().map(|r| r.frames).sum::<usize>(),
                "errors": done.iter().filter(|r| r.error.is_some()).count(),
                "files": files,
            }))
        })
        .py()?;
    to_py(py, &rendered)
}

/// Claims `out` for the render: a new or empty folder, or the folder of the same render
/// (resumed); `force` replaces another render's output. Writes the run record. Returns the
/// claim ([`FolderClaim`]), which holds the folder's lock until it is released (use it in a
/// `with` block) and whose `manifest` is the manifest when the same render already finished
/// there, else `None`.
#[pyfunction]
#[pyo3(signature = (settings_json, out, force=false))]
pub fn training_claim(
    py: Python<'_>,
    settings_json: &str,
    out: PathBuf,
    force: bool,
) -> PyResult<FolderClaim> {
    let plan = plan(py, settings_json)?;
    let (lock, manifest) = py
        .detach(|| sage_traindata::claim(&plan, &out, force))
        .py()?;
    let manifest = manifest
        .map(|m| serde_json::to_value(&m))
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("the manifest as JSON: {e}")))?;
    Ok(FolderClaim::new(out, lock, manifest))
}

/// Finishes the render in `out` once every scene's routes are there: the format's files, the
/// preview when asked for, then `manifest.json`. Holds the folder's lock meanwhile: `claim`'s
/// (a [`FolderClaim`] of `out` not released) when given, else its own. Returns the manifest.
#[pyfunction]
#[pyo3(signature = (settings_json, out, claim=None))]
pub fn training_finish<'py>(
    py: Python<'py>,
    settings_json: &str,
    out: PathBuf,
    claim: Option<PyRef<'py, FolderClaim>>,
) -> PyResult<Bound<'py, PyAny>> {
    let held = claim
        .as_ref()
        .map(|c| c.lock_of(&out))
        .transpose()?
        .is_some();
    let plan = plan(py, settings_json)?;
    let manifest = py
        .detach(|| {
            let _lock = if held {
                None
            } else {
                Some(sage_traindata::lock(&out)?)
            };
            sage_traindata::finish(&plan, &out)
        })
        .py()?;
    to_py(py, &manifest)
}
