//! The evaluator (SPEC §10, `docs/evaluation.md`): runs an agent over a dataset split and
//! scores every episode.
//!
//! Episodes are grouped by scene so each scene's [`SceneContext`](sage_env::SceneContext)
//! loads once and is shared; scenes and the episodes within them run in parallel. Each finished
//! episode is appended to `RUN/episodes.jsonl` as one flushed line, so a crashed run resumes by
//! skipping the ids already recorded ([`records`]); the summary is computed from the records
//! sorted by episode id, so it does not depend on the thread count or finishing order
//! ([`summary`]). [`convert`] bridges dataset episodes, environment traces and metric records.

pub mod merge;
pub mod records;
pub mod summary;

use crate::agents::{AgentKind, AgentMaker};
use crate::dataset::slices::Slices;
use crate::dataset::{Episode, Task};
pub use merge::merge_shards;
use rayon::prelude::*;
use sage_core::{Error, Result, ResultExt};
use sage_env::SceneContext;
use sage_env::agents::{Agent, run_episode};
use sage_env::{Env, EnvConfig, SensorConfig, Termination};
use sage_io::run::RUN_RECORD;
use sage_lang::{InstructionType, Level};
use sage_metrics::{self, Dtw, EpisodeMetrics, EpisodeRecord, Mode, Scoring};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
pub use summary::Summary;

/// The per-episode records file of a run folder.
pub const RECORDS_FILE: &str = "episodes.jsonl";
/// The aggregate file of a run folder.
pub const SUMMARY_FILE: &str = "summary.json";

/// What an evaluation runs; a run folder only resumes a run with the same settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalSettings {
    /// Dataset folder (holds `episodes/{split}.jsonl`).
    pub dataset: PathBuf,
    /// One scene folder or a folder of scene folders, named as the episodes' `scene`.
    pub scenes: PathBuf,
    /// Dataset split.
    pub split: String,
    /// The agent.
    pub agent: AgentKind,
    /// Metric mode.
    pub mode: Mode,
    /// The alignment of nDTW (exact unless asked).
    #[serde(default)]
    pub dtw: Dtw,
    /// Seed of the agent (each episode mixes in its id).
    pub seed: u64,
    /// Environment preset (`sage` or `vlnce`).
    pub preset: String,
}

impl EvalSettings {
    /// How the run's records are scored.
    pub fn scoring(&self) -> Scoring {
        Scoring {
            mode: self.mode,
            dtw: self.dtw,
        }
    }
}

/// One finished episode: the line appended to `RUN/episodes.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalRecord {
    /// Episode id.
    pub episode_id: String,
    /// Scene name.
    pub scene: String,
    /// `vln` or `nogoal`.
    pub task: Task,
    /// Instruction level (absent for no-goal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<Level>,
    /// Instruction type.
    pub instruction_type: InstructionType,
    /// Complexity slices.
    pub slices: Slices,
    /// The agent's name.
    pub agent: String,
    /// Why the episode ended (absent when it failed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub termination: Option<Termination>,
    /// The metrics in the run's mode (absent when it failed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<EpisodeMetrics>,
    /// Why the episode failed (agent, reset or metric error); the run goes on without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Faults of a remote agent's server that retries made good (or that preceded `error`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<String>,
    /// Everything the metrics need, so any mode can be recomputed and paths drawn later.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record: Option<EpisodeRecord>,
}

/// What [`run`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// Episodes in the split.
    pub total: usize,
    /// Episodes already recorded when the run started.
    pub resumed: usize,
    /// Episodes run now.
    pub ran: usize,
    /// The aggregate written to `RUN/summary.json`.
    pub summary: Summary,
}

/// The splits of `dataset` (the names of its `episodes/*.jsonl`), sorted.
///
/// # Errors
///
/// An `invalid` error when `dataset` has no `episodes/` folder, or its read error.
pub fn dataset_splits(dataset: &Path) -> Result<Vec<String>> {
    let dir = dataset.join("episodes");
    if !dir.is_dir() {
        return Err(Error::invalid(
            "not a dataset folder (no episodes/ in it; make one with `sage3d data build`)",
        )
        .in_file(dataset));
    }
    let mut splits: Vec<String> = std::fs::read_dir(&dir)
        .map_err(|e| Error::io(&dir, e))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            e.file_name()
                .to_string_lossy()
                .strip_suffix(".jsonl")
                .map(str::to_string)
        })
        .collect();
    splits.sort();
    Ok(splits)
}

/// The episodes file of `split` in `dataset`.
///
/// # Errors
///
/// An `invalid` error listing the dataset's splits when `split` has no file, or the file's
/// read error.
pub fn split_episodes(dataset: &Path, split: &str) -> Result<(PathBuf, Vec<Episode>)> {
    let splits = dataset_splits(dataset)?;
    let file = dataset.join("episodes").join(format!("{split}.jsonl"));
    if !file.is_file() {
        return Err(Error::invalid(format!(
            "unknown split '{split}' (this dataset has: {})",
            splits.join(", ")
        ))
        .in_file(dataset));
    }
    let episodes = crate::dataset::formats::jsonl::read(&file)?;
    Ok((file, episodes))
}

/// The environment of an evaluation: the preset with RGB only (at the preset's size) for
/// agents that read images (remote models), without images for the others, which do not
/// read them (rendering does not change the motion); and the action space the agent needs
/// (ground velocities for pose replays), else the preset's.
pub fn env_config(preset: &str, agent: &AgentMaker) -> Result<EnvConfig> {
    let config = EnvConfig::preset(preset)?;
    Ok(EnvConfig {
        sensors: SensorConfig {
            rgb: agent.reads_images(),
            depth: false,
            semantic: false,
            instance: false,
            ..config.sensors
        },
        actions: agent.action_space().unwrap_or(config.actions),
        ..config
    })
}

/// What [`run_with`] takes from its caller instead of deriving it from the settings: the
/// environment, the agents and the episodes of the split to run. [`run`] fills it from the
/// settings; other front ends (the Python package) bring their own agents or run one shard.
pub struct Runner<'a> {
    /// The environment every episode runs in.
    pub config: EnvConfig,
    /// The agent's name in the records, the summary and the run record.
    pub agent_name: String,
    /// A fresh agent for each episode.
    pub agent: &'a (dyn Fn() -> Result<Box<dyn Agent>> + Sync),
    /// Which episodes of the split this run covers (`None`: all); the records, resume and
    /// summary then concern those alone.
    pub shard: Option<&'a (dyn Fn(&Episode) -> bool + Sync)>,
}

/// The record of episode `e` before it runs: its tags, no outcome yet.
fn blank_record(runner: &Runner, e: &Episode) -> EvalRecord {
    EvalRecord {
        episode_id: e.episode_id.clone(),
        scene: e.scene.clone(),
        task: e.task,
        level: e.level,
        instruction_type: e.instruction_type,
        slices: e.slices.clone(),
        agent: runner.agent_name.clone(),
        termination: None,
        metrics: None,
        error: None,
        faults: Vec::new(),
        record: None,
    }
}

/// Runs one episode to its record; a failure is recorded, not returned.
fn run_one(
    ctx: &Arc<sage_env::SceneContext>,
    runner: &Runner,
    scoring: Scoring,
    e: &Episode,
) -> EvalRecord {
    let mut rec = blank_record(runner, e);
    let mut agent = None;
    let result = (|| {
        let mut env = Env::new(ctx.clone(), runner.config.clone())?;
        let agent = agent.insert((runner.agent)()?);
        let trace = run_episode(&mut env, agent.as_mut(), &e.env_episode())?;
        let record = sage_env::scoring::metric_record(ctx, &trace);
        let m = sage_metrics::evaluate(&record, scoring)?;
        Ok::<_, Error>((trace.termination, m, record))
    })();
    match result {
        Ok((termination, m, record)) => {
            rec.termination = termination;
            rec.metrics = Some(m);
            rec.record = Some(record);
        }
        Err(err) => rec.error = Some(err.to_string()),
    }
    rec.faults = agent.map(|mut a| a.take_faults()).unwrap_or_default();
    rec
}

/// Checks a run folder's earlier settings against `settings` (a folder resumes only the same
/// run) and writes the run record.
fn claim_run_folder(out: &Path, settings: &serde_json::Value, dataset_hash: &str) -> Result<()> {
    let path = out.join(RUN_RECORD);
    if path.is_file() {
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let old: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format("sage3d_run.json", e.to_string()).in_file(&path))?;
        // The folders may be named from another working directory; the hash says which data.
        let run_of = |v: Option<&serde_json::Value>| {
            let mut v = v.cloned().unwrap_or_default();
            if let Some(o) = v.as_object_mut() {
                o.remove("dataset");
                o.remove("scenes");
                // Runs recorded before the DTW choice existed used exact DTW.
                o.entry("dtw").or_insert_with(|| Dtw::Exact.as_str().into());
            }
            v
        };
        let same = run_of(old.get("settings")) == run_of(Some(settings))
            && old.get("dataset_hash").and_then(|h| h.as_str()) == Some(dataset_hash);
        if !same {
            return Err(Error::invalid(
                "this run folder holds a run with other settings or another dataset; use a new --out",
            )
            .in_file(&path));
        }
    }
    write_run_record(out, settings, dataset_hash)
}

/// The settings as the run record stores them: `settings` with the agent's recorded name.
fn recorded_settings(settings: &EvalSettings, agent: &str) -> Result<serde_json::Value> {
    let mut recorded =
        serde_json::to_value(settings).map_err(|e| Error::invalid(format!("settings: {e}")))?;
    recorded["agent"] = agent.into();
    Ok(recorded)
}

/// Writes an evaluation's run record: its recorded settings and the split file's hash.
fn write_run_record(out: &Path, recorded: &serde_json::Value, dataset_hash: &str) -> Result<()> {
    sage_io::run::write_run_record(
        out,
        "eval",
        recorded.get("seed").and_then(serde_json::Value::as_u64),
        serde_json::json!({
            "settings": recorded,
            "dataset_hash": dataset_hash,
        }),
    )
}

/// Runs (or resumes) an evaluation into `out`, calling `on_done(record, to_run)` after each
/// episode is recorded (`to_run`: the episodes this call runs), then writes `out/summary.json`.
///
/// # Errors
///
/// Bad settings (unknown split or preset, scene missing), a run folder of another run, a
/// corrupt records file or a write error. An episode's own failure (a scene that cannot be
/// loaded, an agent or a metric error) is recorded on it instead.
pub fn run(
    settings: &EvalSettings,
    out: &Path,
    on_done: &(dyn Fn(&EvalRecord, usize) + Sync),
) -> Result<RunOutcome> {
    let maker = settings.agent.maker()?;
    let runner = Runner {
        config: env_config(&settings.preset, &maker).within("preset")?,
        agent_name: settings.agent.to_string(),
        agent: &|| maker.build(settings.seed),
        shard: None,
    };
    run_with(settings, &runner, out, on_done)
}

/// [`run`] with the environment, agents and shard given by `runner` (the settings still name
/// the dataset, scenes, split, mode, seed and preset).
///
/// # Errors
///
/// As [`run`].
pub fn run_with(
    settings: &EvalSettings,
    runner: &Runner,
    out: &Path,
    on_done: &(dyn Fn(&EvalRecord, usize) + Sync),
) -> Result<RunOutcome> {
    let (file, mut episodes) = split_episodes(&settings.dataset, &settings.split)?;
    if let Some(keep) = runner.shard {
        episodes.retain(|e| keep(e));
    }
    let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
    let dataset_hash = sage_io::hash::fnv1a64_hex(&bytes);
    let dirs = sage_io::scenes::scene_dirs_by_name(&settings.scenes)?;
    if let Some(e) = episodes.iter().find(|e| !dirs.contains_key(&e.scene)) {
        return Err(Error::invalid(format!(
            "scene '{}' of episode {} is not among the scenes",
            e.scene, e.episode_id
        ))
        .in_file(&settings.scenes));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let recorded = recorded_settings(settings, &runner.agent_name)?;
    claim_run_folder(out, &recorded, &dataset_hash)?;
    let ids: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    let records_path = out.join(RECORDS_FILE);
    let done = records::resume(&records_path, &ids)?;
    let mut groups: BTreeMap<&str, Vec<&Episode>> = BTreeMap::new();
    for e in episodes
        .iter()
        .filter(|e| !done.contains(e.episode_id.as_str()))
    {
        groups.entry(e.scene.as_str()).or_default().push(e);
    }
    let ran: usize = groups.values().map(Vec::len).sum();
    let writer = Mutex::new(records::Appender::open(&records_path)?);
    groups.par_iter().try_for_each(|(scene, eps)| {
        // A scene that cannot be loaded fails its episodes, with the reason; the run goes on.
        let ctx = SceneContext::load(&dirs[*scene], None)
            .within(format!("scene {scene}"))
            .map(Arc::new);
        eps.par_iter().try_for_each(|e| {
            let rec = match &ctx {
                Ok(ctx) => run_one(ctx, runner, settings.scoring(), e),
                Err(err) => EvalRecord {
                    error: Some(err.to_string()),
                    ..blank_record(runner, e)
                },
            };
            writer
                .lock()
                .map_err(|_| Error::invalid("records writer poisoned"))?
                .append(&rec)?;
            on_done(&rec, ran);
            Ok::<_, Error>(())
        })
    })?;
    let all = records::read(&records_path, &ids)?;
    let summary = Summary {
        agent: runner.agent_name.clone(),
        ..Summary::of(settings, &all)
    };
    sage_io::files::write_json(&out.join(SUMMARY_FILE), &summary)?;
    Ok(RunOutcome {
        total: episodes.len(),
        resumed: done.len(),
        ran,
        summary,
    })
}
