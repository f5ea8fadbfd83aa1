//! The benchmark from Python: dataset splits, the evaluator (built-in or Python agents, all
//! episodes or one shard), and the per-scene and merge steps that `sage3d.distributed` runs as
//! Ray tasks. Files are the CLI's: `sage3d eval` and `sage3d data build` write the same.

use crate::agent::PyAgent;
use crate::claim::FolderClaim;
use crate::convert::{PyResultExt, from_json, from_kwargs, to_py};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sage_agents::{AgentKind, AgentMaker};
use sage_core::{Error, Result};
use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::folder;
use sage_env::agents::Agent;
use sage_eval::{Runner, Summary};
use sage_pipeline::dataset::BuildSettings;
use sage_pipeline::evaluate::{Callbacks, EvalOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// The episodes of `split` in a dataset folder, as dicts (the JSONL schema).
#[pyfunction]
pub fn read_split<'py>(
    py: Python<'py>,
    dataset: PathBuf,
    split: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (_, episodes) = py
        .detach(|| sage_dataset::folder::split_episodes(&dataset, split))
        .py()?;
    to_py(py, &episodes)
}

/// An agent string as `sage3d eval --agent` takes it: its canonical form (as records store
/// it) and whether its episodes must run one at a time (a server holding one episode's state).
#[pyfunction]
pub fn agent_spec<'py>(py: Python<'py>, spec: &str) -> PyResult<Bound<'py, PyAny>> {
    let kind: AgentKind = spec.parse().py()?;
    let serial = kind.maker().py()?.serial();
    to_py(
        py,
        &serde_json::json!({"name": kind.to_string(), "serial": serial}),
    )
}

/// The split names of a dataset folder (those its `splits.json` lists; for a dataset written
/// before the list, its `episodes/*.jsonl`), sorted.
#[pyfunction]
pub fn list_splits(dataset: PathBuf) -> PyResult<Vec<String>> {
    sage_dataset::folder::splits(&dataset).py()
}

/// The scenes folder of an evaluation or render of `dataset`: `scenes` when given, else the
/// folder the dataset records (relative to the dataset first, then absolute).
#[pyfunction]
#[pyo3(signature = (dataset, scenes=None))]
pub fn scenes_folder(dataset: PathBuf, scenes: Option<PathBuf>) -> PyResult<PathBuf> {
    folder::scenes_folder(&dataset, scenes.as_deref()).py()
}

/// The scene folders under `root` (itself when it is one), sorted by name.
#[pyfunction]
pub fn scene_dirs(root: PathBuf) -> PyResult<Vec<PathBuf>> {
    sage_io::scenes::scene_dirs(&root).py()
}

/// The options of an evaluation from keyword arguments (`sage3d eval`'s flags by name) and the
/// scenes folder given beside them.
fn eval_options(
    py: Python<'_>,
    scenes: Option<PathBuf>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<EvalOptions> {
    let given: EvalOptions = from_kwargs(py, options, "evaluation options")?;
    Ok(EvalOptions { scenes, ..given })
}

/// Checks the settings of a dataset build into `out` (`sage3d data build`'s flags by name)
/// before any work, then claims `out` for the build: a bad name or value is a `ValueError`
/// naming it, as [`build_dataset`](crate::pipeline::build_dataset) raises it, and a folder that
/// is neither new, empty nor a dataset build's is refused, naming a file it holds, as `sage3d
/// data build` refuses it without `--force` ([`sage_pipeline::dataset::claim_steps`]: the
/// folder is marked as the build's, unfinished until [`assemble_dataset`] finishes it).
/// Returns the claim ([`FolderClaim`]), which holds the folder's lock until it is released
/// (use it in a `with` block around the scenes' tasks and the assembly).
#[pyfunction]
#[pyo3(signature = (out, **settings))]
pub fn dataset_claim(
    py: Python<'_>,
    out: PathBuf,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<FolderClaim> {
    let (_, assemble) = build_params(py, &out, settings)?;
    let lock = py
        .detach(|| sage_pipeline::dataset::claim_steps(&out, assemble.seed))
        .py()?;
    Ok(FolderClaim::new(out, lock, None))
}

/// The options of an evaluation (`sage3d eval`'s flags by name) with every default filled in,
/// as a dict: what a driver that splits the evaluation needs to know of them (its split).
#[pyfunction]
#[pyo3(signature = (**options))]
pub fn evaluation_options<'py>(
    py: Python<'py>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    to_py(py, &eval_options(py, None, options)?)
}

/// Runs (or resumes) an evaluation into `out`, writes its report (`report.html`, unless
/// `report` is false: a shard of a distributed run) and returns `{total, resumed, ran,
/// summary, table}`. `agent` is a built-in name (`random`, `forward`, `oracle`, …) or a Python
/// factory called once per episode for a fresh agent object (see [`PyAgent`]) reported as
/// `agent_name`; `force` writes into a folder of other files (never replacing one), as `sage3d
/// eval --force`. With a built-in agent and no `overrides` or `scenes_only`, this is exactly
/// `sage3d eval` (the same pipeline function, the same files); otherwise the environment is
/// `preset` with `overrides` (JSON; a Python agent sees the preset's images) and only the
/// episodes of the scenes in `scenes_only` run. `scenes=None` runs in the scenes folder the
/// dataset records. The other keyword arguments are `sage3d eval`'s flags by name with their
/// defaults (`split`, `mode`, `dtw`, `seed`, `preset`, `device`); images are rendered on
/// `device` whatever `overrides` say.
#[pyfunction]
#[pyo3(signature = (dataset, scenes, out, agent, agent_name=None, overrides=None, scenes_only=None, strict=false, report=true, force=false, **options))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate<'py>(
    py: Python<'py>,
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    out: PathBuf,
    agent: &Bound<'py, PyAny>,
    agent_name: Option<String>,
    overrides: Option<&str>,
    scenes_only: Option<Vec<String>>,
    strict: bool,
    report: bool,
    force: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let options = eval_options(py, scenes, options)?;
    let builtin: Option<AgentKind> = match agent.extract::<String>() {
        Ok(name) => Some(name.parse().py()?),
        Err(_) => None,
    };
    let name = match (&builtin, agent_name) {
        (Some(kind), _) => kind.to_string(),
        (None, Some(n)) => n,
        (None, None) => return Err(PyValueError::new_err("a Python agent needs agent_name")),
    };
    // A Python agent has no built-in kind: its kind here only fills the field that
    // `Runner::agent_name` overrides in every file.
    let kind = builtin.clone().unwrap_or(AgentKind::Forward);
    let settings = options.settings(&dataset, kind).py()?;
    let seed = settings.seed;
    let factory = agent.clone().unbind();
    let maker = builtin.as_ref().map(AgentKind::maker).transpose().py()?;
    let overrides = overrides.map(|o| from_json(o, "overrides")).transpose()?;
    let config = sage_eval::evaluation_env(&settings, maker.as_ref(), overrides.as_ref()).py()?;
    let make = || -> Result<Box<dyn Agent>> {
        match &maker {
            Some(maker) => maker.build(seed),
            None => Python::attach(|py| {
                let obj = factory.bind(py).call0()?.unbind();
                Ok::<_, PyErr>(Box::new(PyAgent::new(obj, name.clone())) as Box<dyn Agent>)
            })
            .map_err(|e| Error::invalid(format!("python agent {name}: {e}"))),
        }
    };
    if let Some(names) = &scenes_only {
        // A name that matches nothing, or no name, would run no episode and say nothing.
        if names.is_empty() {
            return Err(PyValueError::new_err(
                "scenes_only: names no scene (None runs every scene of the split)",
            ));
        }
        let (_, episodes) =
            sage_dataset::folder::split_episodes(&settings.dataset, &settings.split).py()?;
        let present: std::collections::BTreeSet<&str> =
            episodes.iter().map(|e| e.scene.as_str()).collect();
        if let Some(missing) = names.iter().find(|n| !present.contains(n.as_str())) {
            return Err(PyValueError::new_err(format!(
                "scenes_only: '{missing}' has no episode in split '{}' (its scenes: {})",
                settings.split,
                present.into_iter().collect::<Vec<_>>().join(", ")
            )));
        }
    }
    let keep =
        |e: &sage_dataset::Episode| scenes_only.as_ref().is_none_or(|s| s.contains(&e.scene));
    let stop = AtomicBool::new(false);
    let runner = Runner {
        config,
        agent_name: name.clone(),
        agent: &make,
        shard: scenes_only
            .is_some()
            .then_some(&keep as &(dyn Fn(&_) -> bool + Sync)),
        serial: maker.as_ref().is_some_and(AgentMaker::serial),
        stop: Some(&stop),
    };
    // The run goes on a thread of its own while this one, Python's main thread, watches for
    // Ctrl-C (signals reach Python only there): once one arrives no episode starts, those in
    // flight are recorded, and the KeyboardInterrupt is raised; the folder resumes.
    let mut interrupted: Option<PyErr> = None;
    let result = py.detach(|| {
        std::thread::scope(|s| {
            let run = s.spawn(|| {
                sage_pipeline::evaluate::evaluate_with(
                    &settings,
                    &runner,
                    &out,
                    report,
                    force,
                    Callbacks::silent(),
                )
            });
            loop {
                let finished = run.is_finished();
                // Stopped while the GIL is held: an agent waiting on Python for the interrupt
                // to be handled cannot end its episode and start another before the stop.
                if interrupted.is_none()
                    && let Err(e) = Python::attach(|py| {
                        py.check_signals()
                            .inspect_err(|_| stop.store(true, Ordering::Relaxed))
                    })
                {
                    interrupted = Some(e);
                }
                if finished {
                    break;
                }
                std::thread::sleep(SIGNAL_POLL);
            }
            run.join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        })
    });
    if let Some(e) = interrupted {
        return Err(e);
    }
    let (outcome, _) = result.py()?;
    if strict {
        outcome.verdict(true).py()?;
    }
    to_py(
        py,
        &Evaluated {
            total: outcome.total,
            resumed: outcome.resumed,
            ran: outcome.ran,
            table: outcome.summary.table(),
            summary: outcome.summary,
            scene_changes: outcome.scene_changes,
        },
    )
}

/// The text of the per-episode records file of the run folder `run` (`episodes.jsonl`), as a
/// shard of a distributed evaluation hands it to the merge.
#[pyfunction]
pub fn run_records(run: PathBuf) -> PyResult<String> {
    let path = run.join(sage_eval::folder::RECORDS_FILE);
    std::fs::read_to_string(&path)
        .map_err(|e| sage_core::Error::io(&path, e))
        .py()
}

/// How often [`evaluate`] looks for Ctrl-C while a run goes on.
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// What [`evaluate`] returns to Python.
#[derive(serde::Serialize)]
struct Evaluated {
    total: usize,
    resumed: usize,
    ran: usize,
    summary: Summary,
    table: String,
    scene_changes: Vec<String>,
}

/// Merges the records of evaluation shards (the text of each shard's `episodes.jsonl`) into one
/// run folder `out`: `episodes.jsonl` sorted by episode id, `summary.json` and
/// `sage3d_run.json`, the same bytes as one `sage3d eval` over the union writes them, then
/// its report.
/// Returns the summary. An episode recorded by two shards is an error. `device` is the one the
/// shards rendered on (their run records name it when it is not the CPU); `overrides` those
/// they ran with ([`evaluate`]'s) and `python_agent` whether the agent was a Python one (not a
/// built-in agent named `agent_name`), so that the run record holds their environment
/// ([`sage_eval::evaluation_env`]).
#[pyfunction]
#[pyo3(signature = (dataset, scenes, out, agent_name, shards, overrides=None, python_agent=false, **options))]
#[allow(clippy::too_many_arguments)]
pub fn merge_eval<'py>(
    py: Python<'py>,
    dataset: PathBuf,
    scenes: Option<PathBuf>,
    out: PathBuf,
    agent_name: String,
    shards: Vec<String>,
    overrides: Option<&str>,
    python_agent: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    // A built-in agent's records bear its name (`AgentKind`'s words).
    let builtin: Option<AgentKind> = (!python_agent).then(|| agent_name.parse().ok()).flatten();
    let kind = builtin.clone().unwrap_or(AgentKind::Forward);
    let settings = eval_options(py, scenes, options)?
        .settings(&dataset, kind)
        .py()?;
    let overrides = overrides.map(|o| from_json(o, "overrides")).transpose()?;
    // A built-in agent that cannot be made here (its replay file is where the shards ran)
    // and ran without overrides leaves the environment to the merge, which records none.
    let maker = builtin.as_ref().and_then(|k| k.maker().ok());
    let env = (python_agent || maker.is_some() || overrides.is_some())
        .then(|| sage_eval::evaluation_env(&settings, maker.as_ref(), overrides.as_ref()))
        .transpose()
        .py()?;
    let (summary, _) = py
        .detach(|| {
            sage_pipeline::evaluate::merge(
                &settings,
                &agent_name,
                env.as_ref(),
                &shards,
                &out,
                &|_, _| {},
            )
        })
        .py()?;
    to_py(py, &summary)
}

/// The settings of a dataset build from keyword arguments (`sage3d data build`'s flags by
/// name), resolved for the output folder `out`.
fn build_params(
    py: Python<'_>,
    out: &Path,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<(SceneParams, AssembleParams)> {
    let settings: BuildSettings = from_kwargs(py, settings, "dataset build settings")?;
    settings.params(out).py()
}

/// Builds (or resumes) one scene's episode file `out/scenes/{scene}.json` as `sage3d data
/// build` does with the same settings (keyword arguments as
/// [`build_dataset`](crate::pipeline::build_dataset) takes them), high-level instructions from
/// the LLM endpoint when `llm_url` names one ([`sage_pipeline::dataset::build_scene`]); returns
/// `{scene, status, episodes, reason?}`, the file's path relative to `out` and its text (for a
/// driver without a shared file system). A scene folder whose name is not a plain name is a
/// `ValueError` naming it.
#[pyfunction]
#[pyo3(signature = (scene_dir, out, **settings))]
pub fn build_scene<'py>(
    py: Python<'py>,
    scene_dir: PathBuf,
    out: PathBuf,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyAny>, PathBuf, Option<String>)> {
    let (params, _) = build_params(py, &out, settings)?;
    let (outcome, file, text) = py
        .detach(|| {
            let o = sage_pipeline::dataset::build_scene(&scene_dir, &out, &params)?;
            let file = build::scene_file(Path::new(""), &o.scene);
            let text = std::fs::read_to_string(out.join(&file)).ok();
            Ok::<_, Error>((o, file, text))
        })
        .py()?;
    Ok((to_py(py, &outcome)?, file, text))
}

/// Assembles a dataset from its scene files (`out/scenes/*.json`, one per folder in `scenes`):
/// splits, balanced test selection, JSONL / GVLN / R2R files and the summary, between two run
/// records (naming `root`, the folder the scene folders were found in), unfinished before
/// and finished after, as `sage3d data build` ends: an assembly cut short leaves a folder no
/// reader takes for a dataset. `out` must be a folder [`dataset_claim`] claimed (or an
/// earlier build's); its lock is held meanwhile: `claim`'s (a [`FolderClaim`] of `out` not
/// released) when given, else its own ([`sage_pipeline::dataset::assemble`]). Returns the
/// summary.
#[pyfunction]
#[pyo3(signature = (out, scenes, root, claim=None, **settings))]
pub fn assemble_dataset<'py>(
    py: Python<'py>,
    out: PathBuf,
    scenes: Vec<PathBuf>,
    root: PathBuf,
    claim: Option<PyRef<'py, FolderClaim>>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let held = claim.as_ref().map(|c| c.lock_of(&out)).transpose()?;
    let (params, assemble) = build_params(py, &out, settings)?;
    let summary = py
        .detach(|| sage_pipeline::dataset::assemble(&out, &root, &scenes, &params, &assemble, held))
        .py()?;
    to_py(py, &summary)
}
