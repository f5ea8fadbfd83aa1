//! The evaluator (SPEC §10, `docs/evaluation.md`): runs an agent over a dataset split and
//! scores every episode.
//!
//! Episodes are grouped by scene so each scene's [`SceneContext`]
//! loads once and is shared; scenes and the episodes within them run in parallel. Each finished
//! episode is appended to `RUN/episodes.jsonl` as one flushed line, so a crashed run resumes by
//! skipping the ids already recorded ([`records`]); the summary is computed from the records
//! sorted by episode id, so it does not depend on the thread count or finishing order
//! ([`summary`](crate::summary)); at the end the records file itself is rewritten in episode-id order, so it
//! is the same bytes however the run went (threads, resumes, shards merged). Agents whose server holds one episode's state (NaVid) run their episodes one
//! at a time.

use crate::folder::{COMMAND, RECORDS_FILE, RUN_OUTPUTS, SUMMARY_FILE, mark_finished};
use crate::records::{self, EvalRecord, Failure};
use crate::report::{ReportJob, ReportOutcome};
use crate::settings::EvalSettings;
use crate::summary::Summary;
use rayon::prelude::*;
use sage_agents::AgentMaker;
use sage_core::{Error, Result, ResultExt};
use sage_dataset::Episode;
use sage_dataset::folder::{non_empty_splits, split_episodes};
use sage_env::SceneContext;
use sage_env::agents::{Agent, run_episode};
use sage_env::{Env, EnvConfig, EpisodeTrace, SensorConfig};
use sage_io::lock::FolderLock;
use sage_io::run::{RUN_RECORD, UNFINISHED};
use sage_metrics::{Dtw, Scoring};
use sage_physics::SplatBodies;
use sage_scene::LoadOptions;
use sage_splat::Device;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

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
    /// The files navigation reads of the run's scenes that changed since the dataset was
    /// built, as `scene/file changed|added|removed` ([`sage_dataset::folder::scene_changes`]):
    /// the episodes' goals and reference paths were planned on the files as they were.
    pub scene_changes: Vec<String>,
}

impl RunOutcome {
    /// Whether the run did what was asked: `Err` with the reason when every episode of the run
    /// faulted (none was scored) or, if `strict`, when any did.
    ///
    /// # Errors
    ///
    /// The verdict, naming the faulted count and the summary's failure kinds.
    pub fn verdict(&self, strict: bool) -> Result<()> {
        let failed = self.summary.failed.len();
        let episodes = self.summary.episodes;
        if failed == 0 || (!strict && failed < episodes) {
            return Ok(());
        }
        let what = if failed == episodes {
            format!("every episode of the run faulted ({failed})")
        } else {
            format!("{failed} of {episodes} episodes faulted (`strict`)")
        };
        Err(Error::invalid(format!(
            "{what}: {}; see the records' \"error\" fields",
            self.summary.failure_counts()
        )))
    }
}

/// The environment of an evaluation of `settings`: its preset with RGB only (at the preset's
/// size, rendered on its device) for agents that read images (remote models), without images
/// for the others, which do not read them (rendering does not change the motion); the action
/// space the agent needs (ground velocities for pose replays), else the preset's; and its
/// choice of bodies.
pub fn env_config(settings: &EvalSettings, agent: &AgentMaker) -> Result<EnvConfig> {
    let config = EnvConfig::preset(&settings.preset)?;
    Ok(EnvConfig {
        device: settings.device,
        splat_bodies: settings.splat_bodies,
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

/// The environment an evaluation of `settings` runs in: a built-in agent's (`maker`) without
/// `overrides` is the one `sage3d eval` runs it in ([`env_config`]); otherwise the preset with
/// `overrides` (a JSON object, as [`EnvConfig::with_overrides`] takes them; an agent of the
/// caller's sees the preset's images), rendered on the settings' device with its bodies. The
/// Python front end runs its evaluations in this, and merges their shards with it.
///
/// # Errors
///
/// An unknown preset; overrides that name no field or make an invalid environment.
pub fn evaluation_env(
    settings: &EvalSettings,
    maker: Option<&AgentMaker>,
    overrides: Option<&serde_json::Value>,
) -> Result<EnvConfig> {
    match (maker, overrides) {
        (Some(maker), None) => env_config(settings, maker).within("preset"),
        _ => Ok(EnvConfig {
            device: settings.device,
            splat_bodies: settings.splat_bodies,
            ..EnvConfig::with_overrides(
                &settings.preset,
                overrides.unwrap_or(&serde_json::json!({})),
            )?
        }),
    }
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
    /// Run the episodes one at a time (the agent's server holds one episode's state).
    pub serial: bool,
    /// Set by the caller to stop the run (Ctrl-C in Python): no episode starts once it is, the
    /// episodes in flight are recorded, and the run ends with an error; a rerun resumes.
    pub stop: Option<&'a AtomicBool>,
}

/// The record of episode `e` by agent `agent` before it runs: its tags, no outcome yet.
pub(crate) fn blank_record(agent: &str, e: &Episode) -> EvalRecord {
    EvalRecord {
        episode_id: e.episode_id.clone(),
        scene: e.scene.clone(),
        task: e.task,
        level: e.level,
        instruction_type: e.instruction_type,
        slices: e.slices.clone(),
        agent: agent.to_string(),
        termination: None,
        metrics: None,
        error: None,
        failure: None,
        faults: Vec::new(),
        notes: Vec::new(),
        record: None,
        bodies: Default::default(),
    }
}

/// Scores a finished episode's trace as every run does: its metric record in `scoring`'s mode
/// and the metrics of that record, written into `rec` with the trace's termination.
///
/// # Errors
///
/// A record the metrics refuse.
pub fn score_into(
    rec: &mut EvalRecord,
    ctx: &SceneContext,
    scoring: Scoring,
    trace: &EpisodeTrace,
) -> Result<()> {
    let record = sage_env::scoring::metric_record(ctx, trace, scoring.mode);
    rec.metrics = Some(sage_metrics::evaluate(&record, scoring)?);
    rec.termination = trace.termination;
    rec.record = Some(record);
    Ok(())
}

/// Runs one episode to its record; a failure is recorded, not returned.
fn run_one(
    ctx: &Arc<sage_env::SceneContext>,
    runner: &Runner,
    scoring: Scoring,
    e: &Episode,
) -> EvalRecord {
    let mut rec = blank_record(&runner.agent_name, e);
    rec.bodies = ctx.body_sources.clone();
    let mut agent = None;
    let result = (|| {
        let mut env = Env::new(ctx.clone(), runner.config.clone())?;
        let agent = agent.insert((runner.agent)()?);
        let trace = run_episode(&mut env, agent.as_mut(), &e.env_episode())?;
        score_into(&mut rec, ctx, scoring, &trace)
    })();
    if let Err(err) = result {
        rec.error = Some(err.to_string());
    }
    if let Some(mut agent) = agent {
        rec.faults = agent.take_faults();
        rec.notes = agent.take_notes();
    }
    if rec.error.is_some() {
        // A remote agent fails an episode only on a request whose every attempt faulted.
        let gave_up = rec.faults.last().is_some_and(|f| !f.recovered);
        rec.failure = Some(if gave_up {
            Failure::ModelServer
        } else {
            Failure::EpisodeError
        });
    }
    rec
}

/// Claims `out` for an evaluation and returns its lock, to hold while the run and its report
/// are written: `out` must be new, empty or an evaluation's (a rerun, which resumes when its
/// settings are the same); with `force`, a folder of other files is written into, provided
/// none of them would be replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// A folder that another command is writing, or one holding files an evaluation did not
/// write, naming it and one of them.
pub fn claim(out: &Path, force: bool) -> Result<FolderLock> {
    sage_io::run::claim_folder(out, &[COMMAND], &RUN_OUTPUTS, force)
}

/// [`claim`] for a rescoring (`sage3d report RUN --mode M --out NEW`, which writes an
/// evaluation's folder): the same folders are taken, and a refusal names the command that
/// was run, `sage3d report`.
///
/// # Errors
///
/// As [`claim`].
pub fn claim_rescoring(out: &Path, force: bool) -> Result<FolderLock> {
    sage_io::run::claim_folder(out, &[RESCORING_COMMAND, COMMAND], &RUN_OUTPUTS, force)
}

/// The command that rescores a run, as a refused folder names it.
const RESCORING_COMMAND: &str = "report";

/// The run record's fingerprint of the scenes `episodes` name: per scene, the hash of every
/// file loading it reads ([`sage_scene::scenes_input_hashes`]; a scene not among `dirs` has
/// none).
pub(crate) fn scene_inputs(
    episodes: &[Episode],
    dirs: &BTreeMap<String, std::path::PathBuf>,
) -> serde_json::Value {
    serde_json::json!(sage_scene::scenes_input_hashes(
        episodes.iter().map(|e| e.scene.as_str()),
        dirs
    ))
}

/// The first scene file whose hash differs between two run records' `scene_inputs`, as
/// `scene/file` (only files both record are compared: a record written before the hashes
/// existed has none).
fn changed_scene_file(old: &serde_json::Value, new: &serde_json::Value) -> Option<String> {
    let old = old.as_object()?;
    new.as_object()?.iter().find_map(|(scene, files)| {
        let before = old.get(scene)?.as_object()?;
        files.as_object()?.iter().find_map(|(file, hash)| {
            before
                .get(file)
                .filter(|h| *h != hash)
                .map(|_| format!("{scene}/{file}"))
        })
    })
}

/// The differences between the settings a run folder recorded (`old`) and those asked
/// (`new`), as `key: OLD recorded, NEW asked`, in key order. The dataset and scenes folders are
/// not compared (they may be named from another working directory; the hashes say which data),
/// and the defaults of fields recorded only since they existed are filled in (exact DTW, the
/// CPU).
fn changed_settings(old: Option<&serde_json::Value>, new: &serde_json::Value) -> Vec<String> {
    let run_of = |v: Option<&serde_json::Value>| {
        let mut fields = v
            .and_then(serde_json::Value::as_object)
            .cloned()
            .unwrap_or_default();
        fields.remove("dataset");
        fields.remove("scenes");
        fields
            .entry("dtw")
            .or_insert_with(|| Dtw::Exact.as_str().into());
        fields
            .entry("device")
            .or_insert_with(|| Device::Cpu.to_string().into());
        fields
            .entry("splat_bodies")
            .or_insert_with(|| SplatBodies::Auto.as_str().into());
        fields.into_iter().collect()
    };
    sage_io::run::differences(&run_of(old), &run_of(Some(new)))
}

/// The differences between the environment a run folder recorded (`old`, its `env`) and the
/// one asked (`new`), field by field as `env.sensors.width: OLD recorded, NEW asked` (as
/// [`changed_settings`] words them), in key order. A record without `env` (written before it
/// was recorded) has none to compare. The device and the bodies are left to
/// [`changed_settings`]: every front end takes them from the settings, which record them, so
/// a difference is named once.
fn changed_env(old: Option<&serde_json::Value>, new: &serde_json::Value) -> Vec<String> {
    let Some(old) = old else {
        return Vec::new();
    };
    let fields_of = |v: &serde_json::Value| {
        let mut fields = BTreeMap::new();
        leaves("env", v, &mut fields);
        fields.remove("env.device");
        fields.remove("env.splat_bodies");
        fields
    };
    sage_io::run::differences(&fields_of(old), &fields_of(new))
}

/// The leaves of `v` by their dotted path under `path` (`env.sensors.width`), into `out`: an
/// object's fields one by one, so a difference names the field; any other value whole.
fn leaves(path: &str, v: &serde_json::Value, out: &mut BTreeMap<String, serde_json::Value>) {
    match v.as_object() {
        Some(fields) => {
            for (k, field) in fields {
                leaves(&format!("{path}.{k}"), field, out);
            }
        }
        None => {
            out.insert(path.to_string(), v.clone());
        }
    }
}

/// Checks a run folder's earlier settings and environment against `settings` and `env` (a
/// folder resumes only the same run, in the same environment, on the same data and scenes;
/// `split_file` is the split's episodes file, whose hash is `dataset_hash`) and writes the run
/// record, marked unfinished until the run is written. `out_setting` is the setting that
/// named `out` (`out`; a human run's `play`), which the advice of a refusal names.
fn claim_run_folder(
    out: &Path,
    out_setting: &str,
    run: &RecordedRun,
    split_file: &Path,
) -> Result<()> {
    let RecordedRun {
        settings,
        env,
        dataset_hash,
        scenes,
        ..
    } = *run;
    let path = out.join(RUN_RECORD);
    // A rescoring's folder resumed as the evaluation it equals keeps the word of where its
    // numbers came from.
    let mut rescored_from = None;
    if path.is_file() {
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let old: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format("sage3d_run.json", e.to_string()).in_file(&path))?;
        let changed = changed_settings(old.get("settings"), settings);
        let other_env = env.map_or_else(Vec::new, |env| changed_env(old.get("env"), env));
        // Another split is another file: its hash differing says nothing more.
        let other_data = old.get("dataset_hash") != Some(dataset_hash)
            && !changed.iter().any(|c| c.starts_with("split:"));
        let mut why = Vec::new();
        if !changed.is_empty() {
            why.push(format!("other settings ({})", changed.join("; ")));
        }
        if !other_env.is_empty() {
            why.push(format!("another environment ({})", other_env.join("; ")));
        }
        if other_data {
            why.push(format!(
                "another dataset (its split file {} changed since the run)",
                split_file.display()
            ));
        }
        if let Some((last, first)) = why.split_last() {
            let why = if first.is_empty() {
                last.clone()
            } else {
                format!("{} and {last}", first.join(", "))
            };
            return Err(Error::invalid(format!(
                "this run folder holds a run with {why}; use a new run folder (`{out_setting}`)"
            ))
            .in_file(&path));
        }
        if let Some(file) = old
            .get("scene_inputs")
            .and_then(|o| changed_scene_file(o, scenes))
        {
            return Err(Error::invalid(format!(
                "this run folder holds a run on other scene files ({file} changed since); use a new run folder (`{out_setting}`)"
            ))
            .in_file(&path));
        }
        rescored_from = old.get("rescored_from").cloned();
    }
    mark_unfinished(out, run, rescored_from)
}

/// The settings as the run record stores them: `settings` with the agent's recorded name.
pub(crate) fn recorded_settings(settings: &EvalSettings, agent: &str) -> Result<serde_json::Value> {
    let mut recorded =
        serde_json::to_value(settings).map_err(|e| Error::invalid(format!("settings: {e}")))?;
    recorded["agent"] = agent.into();
    Ok(recorded)
}

/// The environment as the run record stores it (its `env`): `config` serialized, each float
/// written as the `f32` it is (`1.2`, where the `f64` it widens to would read
/// `1.2000000476837158`), so the record reads as the config was given and reads back as the
/// same config; objects' keys sorted, so the same config is the same bytes. Only a valid
/// config is recorded ([`EnvConfig::validate`]: a non-finite float would be written `null`,
/// which no reader of the record takes back).
///
/// # Errors
///
/// A config the validation refuses, naming the field.
pub(crate) fn env_record(config: &EnvConfig) -> Result<serde_json::Value> {
    config.validate().within("environment")?;
    let text =
        serde_json::to_string(config).map_err(|e| Error::invalid(format!("environment: {e}")))?;
    serde_json::from_str(&text).map_err(|e| Error::invalid(format!("environment: {e}")))
}

/// What an evaluation's run record says of its run besides its status: the recorded settings
/// ([`recorded_settings`]), the environment it ran in ([`env_record`]; `None` for a
/// rescoring of a run recorded before the environment was), the split file's hash and the
/// hashes of its scenes' files ([`scene_inputs`]).
#[derive(Clone, Copy)]
pub(crate) struct RecordedRun<'a> {
    /// `settings`.
    pub(crate) settings: &'a serde_json::Value,
    /// `env`, when known.
    pub(crate) env: Option<&'a serde_json::Value>,
    /// `dataset_hash`.
    pub(crate) dataset_hash: &'a serde_json::Value,
    /// `scene_inputs`.
    pub(crate) scenes: &'a serde_json::Value,
    /// The scenes folder, when it is known to exist (`None`: the record names none beside
    /// `settings.scenes`), recorded as `scenes_folder`: absolute and relative to the run
    /// folder ([`sage_dataset::folder::scenes_record`]), so that the run's report and viewer
    /// find it from any working directory ([`crate::folder::recorded_scenes`]).
    pub(crate) scenes_folder: Option<&'a Path>,
}

/// Writes an evaluation's run record marked unfinished (`"status": "unfinished"`, the first
/// write of a run: [`crate::folder::mark_finished`] is its last): what `run` holds and, for a
/// folder a rescoring wrote, the run it was rescored from.
pub(crate) fn mark_unfinished(
    out: &Path,
    run: &RecordedRun,
    rescored_from: Option<serde_json::Value>,
) -> Result<()> {
    let mut record = serde_json::json!({
        "settings": run.settings,
        "dataset_hash": run.dataset_hash,
        "scene_inputs": run.scenes,
        "status": UNFINISHED,
    });
    if let Some(env) = run.env {
        record["env"] = env.clone();
    }
    if let Some(folder) = run.scenes_folder {
        record["scenes_folder"] = sage_dataset::folder::scenes_record(out, folder);
    }
    if let Some(from) = rescored_from {
        record["rescored_from"] = from;
    }
    sage_io::run::write_run_record(
        out,
        COMMAND,
        run.settings.get("seed").and_then(serde_json::Value::as_u64),
        record,
    )
}

/// A run's split as [`open_split`] prepared it.
pub(crate) struct Split {
    /// The episodes of the run (the shard's, when there is one).
    pub(crate) episodes: Vec<Episode>,
    /// The scene folders by name; every episode's scene is among them.
    pub(crate) dirs: BTreeMap<String, std::path::PathBuf>,
    /// The ids already recorded in the run folder.
    pub(crate) done: BTreeSet<String>,
    /// [`RunOutcome::scene_changes`].
    pub(crate) scene_changes: Vec<String>,
}

/// Reads the split of `settings` (the episodes `shard` keeps), checks that every episode's
/// scene is present, and claims `out` for a run of `agent` with these settings in the
/// environment `env`: its run record written (or checked against an earlier one) and its
/// records file ready to resume. `out_setting` names the setting that named `out`
/// ([`claim_run_folder`]).
///
/// # Errors
///
/// An empty or unknown split, a scene missing, a run folder of another run (other settings or
/// another environment), a corrupt records file.
pub(crate) fn open_split(
    settings: &EvalSettings,
    agent: &str,
    env: &EnvConfig,
    shard: Option<&(dyn Fn(&Episode) -> bool + Sync)>,
    out: &Path,
    out_setting: &str,
) -> Result<Split> {
    let (file, mut episodes) = split_episodes(&settings.dataset, &settings.split)?;
    if episodes.is_empty() {
        let with_episodes = non_empty_splits(&settings.dataset)?;
        return Err(Error::invalid(format!(
            "split '{}' has no episodes (splits with episodes: {})",
            settings.split,
            if with_episodes.is_empty() {
                "none".to_string()
            } else {
                with_episodes.join(", ")
            }
        ))
        .in_file(&file));
    }
    let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
    let dataset_hash = sage_io::hash::fnv1a64_hex(&bytes);
    let dirs = sage_io::scenes::scene_dirs_by_name(&settings.scenes)?;
    if let Some(keep) = shard {
        episodes.retain(|e| keep(e));
    }
    // A shard hashes the scenes it runs (each node would otherwise read every scene's
    // Gaussians); the merge of the shards records the whole split's, as one run over it does.
    let scenes = scene_inputs(&episodes, &dirs);
    let scene_changes = sage_dataset::folder::scene_changes(
        &settings.dataset,
        episodes.iter().map(|e| e.scene.as_str()),
        &dirs,
    );
    if let Some(e) = episodes.iter().find(|e| !dirs.contains_key(&e.scene)) {
        return Err(Error::invalid(format!(
            "scene '{}' of episode {} is not among the scenes",
            e.scene, e.episode_id
        ))
        .in_file(&settings.scenes));
    }
    // Checked before the folder is made: a bad environment leaves no record to resume.
    let env = env_record(env)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let recorded = recorded_settings(settings, agent)?;
    let run = RecordedRun {
        settings: &recorded,
        env: Some(&env),
        dataset_hash: &dataset_hash.into(),
        scenes: &scenes,
        scenes_folder: Some(settings.scenes.as_path()).filter(|p| p.is_dir()),
    };
    claim_run_folder(out, out_setting, &run, &file)?;
    let ids: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    let done = records::resume(&out.join(RECORDS_FILE), &ids)?;
    Ok(Split {
        episodes,
        dirs,
        done,
        scene_changes,
    })
}

/// Runs (or resumes) an evaluation into `out`, calling `on_done(record, to_run)` after each
/// episode is recorded (`to_run`: the episodes this call runs), then writes `out/summary.json`
/// and marks the run finished. Callers [`claim`] `out` first and hold its lock until the run
/// and its report are written.
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
    with_runner(settings, |runner| run_with(settings, runner, out, on_done))
}

/// Calls `f` with the runner [`run`] runs the agent of `settings` with: the environment of its
/// preset, a fresh agent per episode, every episode of the split.
///
/// # Errors
///
/// The agent `human` (a person plays in the viewer), an agent that cannot be made, an unknown
/// preset; `f`'s own.
pub fn with_runner<T>(settings: &EvalSettings, f: impl FnOnce(&Runner) -> Result<T>) -> Result<T> {
    if settings.agent == sage_agents::AgentKind::Human {
        return Err(Error::invalid(
            "agent human: a person plays the split in `sage3d view DATASET --play RUN`; eval runs built agents",
        ));
    }
    let maker = settings.agent.maker()?;
    let runner = Runner {
        config: env_config(settings, &maker).within("preset")?,
        agent_name: settings.agent.to_string(),
        agent: &|| maker.build(settings.seed),
        shard: None,
        serial: maker.serial(),
        stop: None,
    };
    f(&runner)
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
    let outcome = run_unfinished(settings, runner, out, on_done)?;
    mark_finished(out)?;
    Ok(outcome)
}

/// [`run_with`] that also writes the run's report (`report`) before it marks the run finished,
/// as `sage3d eval` does: a run killed before its report is written is still unfinished, and
/// its rerun writes it.
///
/// # Errors
///
/// As [`run`] and [`crate::report::write_with_options`].
pub fn run_with_report(
    settings: &EvalSettings,
    runner: &Runner,
    out: &Path,
    on_done: &(dyn Fn(&EvalRecord, usize) + Sync),
    report: &ReportJob,
) -> Result<(RunOutcome, ReportOutcome)> {
    let outcome = run_unfinished(settings, runner, out, on_done)?;
    Ok((outcome, report.finish(out)?))
}

/// [`run_with`] up to its summary: the run record stays marked unfinished.
fn run_unfinished(
    settings: &EvalSettings,
    runner: &Runner,
    out: &Path,
    on_done: &(dyn Fn(&EvalRecord, usize) + Sync),
) -> Result<RunOutcome> {
    let Split {
        episodes,
        dirs,
        done,
        scene_changes,
    } = open_split(
        settings,
        &runner.agent_name,
        &runner.config,
        runner.shard,
        out,
        "out",
    )?;
    let records_path = out.join(RECORDS_FILE);
    let ids: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    let mut groups: BTreeMap<&str, Vec<&Episode>> = BTreeMap::new();
    for e in episodes
        .iter()
        .filter(|e| !done.contains(e.episode_id.as_str()))
    {
        groups.entry(e.scene.as_str()).or_default().push(e);
    }
    let ran: usize = groups.values().map(Vec::len).sum();
    let writer = Mutex::new(records::Appender::open(&records_path)?);
    let run_scene = |scene: &str, eps: &[&Episode]| {
        // A scene that cannot be loaded fails its episodes, with the reason; the run goes on.
        let ctx = SceneContext::load_with_bodies(
            &dirs[scene],
            None,
            &LoadOptions::default(),
            settings.splat_bodies,
        )
        .within(format!("scene {scene}"))
        .map(Arc::new);
        let record_episode = |e: &&Episode| {
            if runner.stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                return Err(Error::invalid(
                    "the run was stopped; run it again to resume where it stopped",
                ));
            }
            let rec = match &ctx {
                Ok(ctx) => run_one(ctx, runner, settings.scoring(), e),
                Err(err) => EvalRecord {
                    error: Some(err.to_string()),
                    failure: Some(Failure::SceneLoad),
                    ..blank_record(&runner.agent_name, e)
                },
            };
            writer
                .lock()
                .map_err(|_| Error::invalid("records writer poisoned"))?
                .append(&rec)?;
            on_done(&rec, ran);
            Ok::<_, Error>(())
        };
        if runner.serial {
            eps.iter().try_for_each(record_episode)
        } else {
            eps.par_iter().try_for_each(record_episode)
        }
    };
    if runner.serial {
        // Plain loops: a rayon worker waiting on a shared server must never pick up another
        // episode of the same server while it holds one.
        groups
            .iter()
            .try_for_each(|(scene, eps)| run_scene(scene, eps))?;
    } else {
        groups
            .par_iter()
            .try_for_each(|(scene, eps)| run_scene(scene, eps))?;
    }
    drop(writer);
    // Finishing order depends on the threads; sorted by id, the file is the same bytes for
    // any thread count, resume or shard merge (`merge_shards` writes this order).
    let all = records::sort(&records_path, &ids)?;
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
        scene_changes,
    })
}
