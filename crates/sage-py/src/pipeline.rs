//! The pipelines from Python: the demo end to end and the dataset build, the same library
//! functions `sage3d demo` and `sage3d data build` call (`sage-pipeline`).

use crate::convert::{PyResultExt, to_py};
use pyo3::prelude::*;
use sage_dataset::build::{AssembleParams, SceneParams};
use sage_pipeline::demo::DemoSettings;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Runs the demo into `out` (synthetic scenes, or the scene folders of `from_dir`): scenes,
/// maps, collision bodies, the dataset, an evaluation with its report per agent and
/// `overview.png`. `out` must be new, empty or a demo's (rerunning resumes). Returns each
/// agent's summary, by agent.
#[pyfunction]
#[pyo3(signature = (out, scenes=3, seed=0, per_scene=12, gaussians=150_000, agents=None, split="test_balanced", from_dir=None))]
#[allow(clippy::too_many_arguments)]
pub fn demo<'py>(
    py: Python<'py>,
    out: PathBuf,
    scenes: usize,
    seed: u64,
    per_scene: usize,
    gaussians: usize,
    agents: Option<Vec<String>>,
    split: &str,
    from_dir: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings = DemoSettings {
        out,
        scenes,
        seed,
        per_scene,
        gaussians,
        agents: agents.unwrap_or_else(|| DemoSettings::default().agents),
        split: split.to_string(),
        from: from_dir,
    };
    let runs = py
        .detach(|| {
            sage_pipeline::demo_folder::claim(&settings, false)?;
            sage_pipeline::demo::run(&settings, &|_, _, _| {}, &|_| {}, &|_, _| {})
        })
        .py()?;
    let by_agent: BTreeMap<String, _> = runs.into_iter().collect();
    to_py(py, &by_agent)
}

/// Builds (or resumes) a dataset over the scene folders under `scenes` into `out` with the
/// offline grammar, as `sage3d data build` does. Returns the dataset's summary.
#[pyfunction]
#[pyo3(signature = (scenes, out, per_scene=20, seed=0, balanced=1000, scene_unseen=0.15, val=0.1))]
#[allow(clippy::too_many_arguments)]
pub fn build_dataset<'py>(
    py: Python<'py>,
    scenes: PathBuf,
    out: PathBuf,
    per_scene: usize,
    seed: u64,
    balanced: usize,
    scene_unseen: f32,
    val: f32,
) -> PyResult<Bound<'py, PyAny>> {
    let params = SceneParams::new(per_scene, seed);
    let assemble = AssembleParams::new(seed, balanced, scene_unseen, val);
    let report = py
        .detach(|| {
            sage_pipeline::dataset::build(&scenes, &out, &params, &assemble, false, &|_, _| {})
        })
        .py()?;
    to_py(py, &report.summary)
}
