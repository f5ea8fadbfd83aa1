//! Training data from Python: the render of `sage3d data render` (`sage-traindata`) in one
//! call, and its steps (plan, claim, one scene, finish) that `sage3d.distributed` runs as Ray
//! tasks. The steps take the render's settings as JSON (`sage_traindata::Settings`), made by
//! [`training_settings`] from the same keyword arguments [`render_training_data`] takes;
//! both, like the command line, turn them into settings with `sage_traindata::Options`.

use crate::convert::{PyResultExt, from_json, to_py};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sage_traindata::{Options, Plan, RouteDone, Settings};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Images per frame as Python passes them: `"rgb,depth"` or `["rgb", "depth"]`.
#[derive(FromPyObject)]
pub enum SensorList {
    /// Comma-separated names.
    Text(String),
    /// One name per item.
    Names(Vec<String>),
}

impl SensorList {
    fn joined(&self) -> String {
        match self {
            SensorList::Text(s) => s.clone(),
            SensorList::Names(v) => v.join(","),
        }
    }
}

/// The settings of a render as JSON (`sage_traindata::Settings`), from the keyword arguments
/// of [`render_training_data`] (without `out` and `force`): what the step functions take.
#[pyfunction]
#[pyo3(signature = (dataset, scenes, split="train", preset="navila_small", step=None, turn=None, max_actions=sage_traindata::preset::DEFAULT_MAX_ACTIONS, width=224, height=224, hfov=90.0, sensors=SensorList::Text("rgb".into()), format="navila", shard_size=None, limit=None, seed=0, agent="wheeled", image="jpg", jpeg_quality=90, keep_failed=false, preview=0, device="cpu"))]
#[allow(clippy::too_many_arguments)]
pub fn training_settings(
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    split: &str,
    preset: &str,
    step: Option<f32>,
    turn: Option<f32>,
    max_actions: usize,
    width: u32,
    height: u32,
    hfov: f32,
    sensors: SensorList,
    format: &str,
    shard_size: Option<usize>,
    limit: Option<usize>,
    seed: u64,
    agent: &str,
    image: &str,
    jpeg_quality: u8,
    keep_failed: bool,
    preview: usize,
    device: &str,
) -> PyResult<String> {
    let s = Options {
        dataset,
        scenes,
        split: split.into(),
        preset: preset.into(),
        step,
        turn,
        max_actions,
        width,
        height,
        hfov,
        sensors: sensors.joined(),
        format: format.into(),
        shard_size,
        limit,
        seed,
        agent: agent.into(),
        image: image.into(),
        jpeg_quality,
        keep_failed,
        preview,
        device: device.into(),
    }
    .settings()
    .py()?;
    serde_json::to_string(&s).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Renders (or resumes) a training set into `out`, as `sage3d data render DATASET --scenes
/// SCENES --out OUT ...` does (the same library function, the same files byte for byte;
/// `scenes=None`: the scenes folder the dataset records, as without `--scenes`):
/// the split's goal-directed episodes walked with the preset's discrete actions, a frame
/// rendered before every action, written as NaVILA annotation parts (`format="navila"`),
/// WebDataset shards (`"webdataset"`) or a folder tree (`"frames"`). `sensors`: `"rgb"`,
/// `"rgb,depth"` or a list of names (`rgb`, `depth`, `semantic`, `instance`); `shard_size`:
/// samples per NaVILA part (default 10000) or episodes per WebDataset shard (default 100);
/// `image`: `jpg` or `png`; `max_actions` (default 50): motions per walk at most; `step` and
/// `turn` override the preset's. A finished render in `out` with the same settings is
/// returned as it is; `force` replaces another render's output. `device` (`cpu`, `gpu` or
/// `auto`, as `--device`) is where the frames are rendered. Returns the manifest
/// (`manifest.json`).
#[pyfunction]
#[pyo3(signature = (dataset, scenes, out, split="train", preset="navila_small", step=None, turn=None, max_actions=sage_traindata::preset::DEFAULT_MAX_ACTIONS, width=224, height=224, hfov=90.0, sensors=SensorList::Text("rgb".into()), format="navila", shard_size=None, limit=None, seed=0, agent="wheeled", image="jpg", jpeg_quality=90, keep_failed=false, preview=0, force=false, device="cpu"))]
#[allow(clippy::too_many_arguments)]
pub fn render_training_data<'py>(
    py: Python<'py>,
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    out: PathBuf,
    split: &str,
    preset: &str,
    step: Option<f32>,
    turn: Option<f32>,
    max_actions: usize,
    width: u32,
    height: u32,
    hfov: f32,
    sensors: SensorList,
    format: &str,
    shard_size: Option<usize>,
    limit: Option<usize>,
    seed: u64,
    agent: &str,
    image: &str,
    jpeg_quality: u8,
    keep_failed: bool,
    preview: usize,
    force: bool,
    device: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let s = Options {
        dataset,
        scenes,
        split: split.into(),
        preset: preset.into(),
        step,
        turn,
        max_actions,
        width,
        height,
        hfov,
        sensors: sensors.joined(),
        format: format.into(),
        shard_size,
        limit,
        seed,
        agent: agent.into(),
        image: image.into(),
        jpeg_quality,
        keep_failed,
        preview,
        device: device.into(),
    }
    .settings()
    .py()?;
    let manifest = py
        .detach(|| sage_traindata::render(&s, &out, force, &|_: &RouteDone| {}))
        .py()?;
    to_py(py, &manifest)
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

/// The route folders of every scene, `{scene: [route, ...]}` (scenes sorted, routes in
/// dataset order): a route is done when `out/images/{scene}/{route}/route.json` holds a walk.
#[pyfunction]
pub fn training_plan_routes(
    py: Python<'_>,
    settings_json: &str,
) -> PyResult<BTreeMap<String, Vec<String>>> {
    Ok(plan(py, settings_json)?
        .routes
        .into_iter()
        .map(|(scene, routes)| (scene, routes.into_iter().map(|r| r.name).collect()))
        .collect())
}

/// Renders the routes of `scene` not done under `out` (frames and `route.json` per route
/// under `out/images/{scene}/`), as one step of the command line's render. Returns the
/// routes rendered (0 when all were done).
#[pyfunction]
pub fn training_render_scene(
    py: Python<'_>,
    settings_json: &str,
    scene: &str,
    out: PathBuf,
) -> PyResult<usize> {
    let plan = plan(py, settings_json)?;
    if !plan.routes.contains_key(scene) {
        return Err(PyValueError::new_err(format!(
            "scene '{scene}' has no episodes in this render (scenes: {})",
            plan.scenes().join(", ")
        )));
    }
    py.detach(|| sage_traindata::render_scene(&plan, scene, &out, &|_: &RouteDone| {}))
        .py()
}

/// Claims `out` for the render: a new or empty folder, or the folder of the same render
/// (resumed); `force` replaces another render's output. Writes the run record. Returns the
/// manifest when the same render already finished there, else `None`.
#[pyfunction]
#[pyo3(signature = (settings_json, out, force=false))]
pub fn training_claim<'py>(
    py: Python<'py>,
    settings_json: &str,
    out: PathBuf,
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let plan = plan(py, settings_json)?;
    let done = py
        .detach(|| sage_traindata::claim(&plan, &out, force))
        .py()?;
    to_py(py, &done)
}

/// Finishes the render in `out` once every scene's routes are there: the format's files, the
/// preview when asked for, then `manifest.json`. Returns the manifest.
#[pyfunction]
pub fn training_finish<'py>(
    py: Python<'py>,
    settings_json: &str,
    out: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let plan = plan(py, settings_json)?;
    let manifest = py.detach(|| sage_traindata::finish(&plan, &out)).py()?;
    to_py(py, &manifest)
}
