//! `sage-py`: the native half of the Python package `sage3d` (module `sage3d._sage3d`).
//!
//! It exposes what Python users drive: scenes with their path finder ([`scene`]), the
//! environment as a single or batched simulator handing out NumPy arrays that own the Rust
//! buffers ([`sim`]), datasets, the evaluator with agents written in Python, and the per-scene
//! steps of dataset generation and evaluation that `sage3d.distributed` spreads over a Ray
//! cluster ([`bench`](mod@bench)), with the output folder claims their drivers hold
//! ([`claim`]), and the pipelines the CLI runs ([`pipeline`]: the demo, the dataset build), and
//! the training-data render with its per-scene steps ([`training`]), and the browser viewer
//! ([`view`]). Long calls release the GIL. The Gymnasium classes are pure Python on top of this
//! module (`python/sage3d/`).

pub mod agent;
pub mod bench;
pub mod claim;
pub mod convert;
pub mod pipeline;
pub mod scene;
pub mod sim;
pub mod training;
pub mod view;

use pyo3::prelude::*;

/// The extension module `sage3d._sage3d`.
#[pymodule]
fn _sage3d(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<scene::PyScene>()?;
    m.add_class::<scene::PyPathFinder>()?;
    m.add_class::<sim::Sim>()?;
    m.add_class::<sim::VecSim>()?;
    m.add_class::<claim::FolderClaim>()?;
    m.add_function(wrap_pyfunction!(sim::env_config, m)?)?;
    m.add_function(wrap_pyfunction!(bench::read_split, m)?)?;
    m.add_function(wrap_pyfunction!(bench::list_splits, m)?)?;
    m.add_function(wrap_pyfunction!(bench::scenes_folder, m)?)?;
    m.add_function(wrap_pyfunction!(bench::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(bench::agent_spec, m)?)?;
    m.add_function(wrap_pyfunction!(bench::merge_eval, m)?)?;
    m.add_function(wrap_pyfunction!(bench::run_records, m)?)?;
    m.add_function(wrap_pyfunction!(bench::evaluation_options, m)?)?;
    m.add_function(wrap_pyfunction!(bench::dataset_claim, m)?)?;
    m.add_function(wrap_pyfunction!(bench::build_scene, m)?)?;
    m.add_function(wrap_pyfunction!(bench::assemble_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(bench::scene_dirs, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::demo, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::build_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(training::render_training_data, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_settings, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_plan_scenes, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_progress, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_render_scene, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_claim, m)?)?;
    m.add_function(wrap_pyfunction!(training::training_finish, m)?)?;
    m.add_function(wrap_pyfunction!(view::view, m)?)?;
    Ok(())
}
