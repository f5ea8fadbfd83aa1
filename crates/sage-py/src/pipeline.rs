//! The pipelines from Python: the demo end to end and the dataset build, the same library
//! functions `sage3d demo` and `sage3d data build` call (`sage-pipeline`).

use crate::convert::{PyResultExt, arg_extractors, from_kwargs, to_py};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sage_pipeline::dataset::BuildSettings;
use sage_pipeline::demo::DemoSettings;
use std::collections::BTreeMap;
use std::path::PathBuf;

arg_extractors! {
    demo_out: PathBuf = "demo: out";
    build_scenes: PathBuf = "build_dataset: scenes";
    build_out: PathBuf = "build_dataset: out";
    build_force: bool = "build_dataset: force";
}

/// Runs the demo into `out` (synthetic scenes, or the scene folders of `from_dir`): scenes,
/// maps, collision bodies, the dataset, an evaluation with its report per agent and
/// `overview.png`. `out` must be new, empty or a demo's (rerunning resumes). The keyword
/// arguments are `sage3d demo`'s flags by name, with the same defaults (`scenes=3`, `seed=0`,
/// `per_scene=12`, `gaussians=150000`, `agents=["oracle", "random", "forward"]`,
/// `split="test_balanced"`, `from_dir=None`). Returns each agent's summary, by agent.
#[pyfunction]
#[pyo3(signature = (out, **settings))]
pub fn demo<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = demo_out)] out: PathBuf,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings = DemoSettings {
        out,
        ..from_kwargs(py, settings, "demo settings")?
    };
    let runs = py
        .detach(|| {
            let _lock = sage_pipeline::demo::claim(&settings, false)?;
            sage_pipeline::demo::run(&settings, &|_, _, _| {}, &|_| {}, &|_, _| {})
        })
        .py()?;
    let by_agent: BTreeMap<String, _> = runs.into_iter().collect();
    to_py(py, &by_agent)
}

/// Builds (or resumes) a dataset over the scene folders under `scenes` into `out`, as `sage3d
/// data build` does. The keyword arguments are its flags by name, with the same defaults
/// (`per_scene=20`, `seed=0`, `agent="wheeled"`, `length_mix=None`, `base_actions=None`,
/// `nogoal=1`, `high_per_type=1`, `balanced=1000`, `scene_unseen=0.15`, `val=0.1`, and
/// `llm_url`, `llm_model`, `llm_key_env`, `llm_concurrency`, `llm_cache` for an LLM's
/// high-level instructions); `force=True` writes into a folder of other files, never
/// replacing one of them. Returns the dataset's summary.
#[pyfunction]
#[pyo3(signature = (scenes, out, force=false, **settings))]
pub fn build_dataset<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = build_scenes)] scenes: PathBuf,
    #[pyo3(from_py_with = build_out)] out: PathBuf,
    #[pyo3(from_py_with = build_force)] force: bool,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: BuildSettings = from_kwargs(py, settings, "dataset build settings")?;
    let report = py
        .detach(|| sage_pipeline::dataset::build(&scenes, &out, &settings, force, &|_, _| {}))
        .py()?;
    to_py(py, &report.summary)
}
