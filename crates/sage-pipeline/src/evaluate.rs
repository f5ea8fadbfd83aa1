//! An evaluation with its report: run (or resume) an agent over a dataset split, then write the
//! run's `report.html` and maps — for the command line, Python and the demo alike.

use sage_agents::AgentKind;
use sage_core::Result;
use sage_dataset::folder::scenes_folder;
use sage_env::EnvConfig;
use sage_eval::folder::COMMAND;
use sage_eval::report::{self, ReportJob, ReportOptions, ReportOutcome};
use sage_eval::{EvalRecord, EvalSettings, RunOutcome, Runner, Summary};
use sage_io::lock::FolderLock;
use sage_metrics::{Dtw, Mode};
use sage_physics::SplatBodies;
use sage_splat::Device;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The settings of an evaluation besides its dataset and agent, as `sage3d eval`'s flags and
/// the keyword arguments of `sage3d.evaluate` name them; [`EvalOptions::default`] gives every
/// default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct EvalOptions {
    /// One scene folder or a folder of scene folders, named as the episodes' scenes (default:
    /// the scenes folder the dataset was built from, as its sage3d_run.json records it).
    #[cfg_attr(feature = "clap", arg(long))]
    pub scenes: Option<PathBuf>,
    /// Dataset split, one of those DATASET/splits.json lists (`DATASET/episodes/{split}.jsonl`).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = EvalOptions::default().split))]
    pub split: String,
    /// Metric mode: sage, vlnce, sage-official or gnbench.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = EvalOptions::default().mode))]
    pub mode: Mode,
    /// nDTW alignment: exact or fast (FastDTW, radius 1, as VLN-CE computes it).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = EvalOptions::default().dtw))]
    pub dtw: Dtw,
    /// Seed of the agent (each episode mixes in its id).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = EvalOptions::default().seed))]
    pub seed: u64,
    /// Environment preset: sage, vlnce, gnbench, sage-harness (the published SAGE-Bench
    /// harness's camera, steps and step limit), or navila_small, navila_large or custom_small
    /// (sage moving with that training-data preset's steps).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = EvalOptions::default().preset))]
    pub preset: String,
    /// Where images are rendered for agents that read them: cpu; gpu (any GPU adapter, a
    /// software one such as Mesa's lavapipe included; an error when there is none); or auto (a
    /// hardware GPU when there is one, else the CPU).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "cpu|gpu|auto", default_value_t = EvalOptions::default().device)
    )]
    pub device: Device,
    /// Which objects get collision bodies recovered from their Gaussians, as `physics build
    /// --splat-bodies`: auto, always or never (recorded in the run when not auto).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "auto|always|never", default_value_t = SplatBodies::default())
    )]
    pub splat_bodies: SplatBodies,
}

impl Default for EvalOptions {
    /// The balanced test split, the `sage` metrics with exact nDTW, seed 0, the `sage`
    /// environment, on the CPU, in the scenes folder the dataset records.
    fn default() -> Self {
        EvalOptions {
            scenes: None,
            split: sage_dataset::split::TEST_BALANCED.into(),
            mode: Mode::default(),
            dtw: Dtw::default(),
            seed: 0,
            preset: "sage".into(),
            device: Device::default(),
            splat_bodies: SplatBodies::default(),
        }
    }
}

impl EvalOptions {
    /// The settings of an evaluation of `agent` over `dataset` with these options.
    ///
    /// # Errors
    ///
    /// No scenes folder given nor recorded by the dataset.
    pub fn settings(&self, dataset: &Path, agent: AgentKind) -> Result<EvalSettings> {
        Ok(EvalSettings {
            dataset: dataset.to_path_buf(),
            scenes: scenes_folder(dataset, self.scenes.as_deref())?,
            split: self.split.clone(),
            agent,
            mode: self.mode,
            dtw: self.dtw,
            seed: self.seed,
            preset: self.preset.clone(),
            device: self.device,
            splat_bodies: self.splat_bodies,
        })
    }
}

/// What an evaluation reports as it goes.
#[derive(Clone, Copy)]
pub struct Callbacks<'a> {
    /// After each episode: its record and the episodes this run has to run.
    pub on_episode: &'a (dyn Fn(&EvalRecord, usize) + Sync),
    /// After each map of the report: its episode id and the maps in all.
    pub on_map: &'a (dyn Fn(&str, usize) + Sync),
}

impl Callbacks<'_> {
    /// Callbacks that do nothing.
    pub fn silent() -> Callbacks<'static> {
        Callbacks {
            on_episode: &|_, _| {},
            on_map: &|_, _| {},
        }
    }
}

/// Runs or resumes the evaluation of `settings` into `out` with the agent the settings name,
/// then writes its report. `out` must be new, empty or an evaluation's run folder; with
/// `force`, a folder of other files is written into, provided none of them would be replaced
/// ([`sage_eval::claim`]).
///
/// # Errors
///
/// As [`sage_eval::claim`], [`sage_eval::run`] and [`sage_eval::run_with_report`].
pub fn evaluate(
    settings: &EvalSettings,
    out: &Path,
    force: bool,
    callbacks: Callbacks<'_>,
) -> Result<(RunOutcome, ReportOutcome)> {
    let _lock = sage_eval::claim(out, force)?;
    sage_eval::with_runner(settings, |runner| {
        sage_eval::run_with_report(
            settings,
            runner,
            out,
            callbacks.on_episode,
            &report_job(settings, callbacks),
        )
    })
}

/// The report an evaluation of `settings` writes at its end: with the run's scenes, no videos.
fn report_job<'a>(settings: &'a EvalSettings, callbacks: Callbacks<'a>) -> ReportJob<'a> {
    ReportJob {
        on_map: callbacks.on_map,
        ..ReportJob::new(&settings.scenes)
    }
}

/// [`evaluate`] with a caller's runner (an agent written in Python, other environment
/// settings, or the episodes of some scenes only); without `report`, no report is written (a
/// shard of a larger run, whose report is written once its shards are merged). `force` as
/// [`evaluate`]'s.
///
/// # Errors
///
/// As [`sage_eval::claim`], [`sage_eval::run_with`] and [`sage_eval::run_with_report`].
pub fn evaluate_with(
    settings: &EvalSettings,
    runner: &Runner,
    out: &Path,
    report: bool,
    force: bool,
    callbacks: Callbacks<'_>,
) -> Result<(RunOutcome, Option<ReportOutcome>)> {
    let _lock = sage_eval::claim(out, force)?;
    if report {
        let job = report_job(settings, callbacks);
        let (outcome, report) =
            sage_eval::run_with_report(settings, runner, out, callbacks.on_episode, &job)?;
        Ok((outcome, Some(report)))
    } else {
        let outcome = sage_eval::run_with(settings, runner, out, callbacks.on_episode)?;
        Ok((outcome, None))
    }
}

/// Merges the records of evaluation shards (the text of each shard's `episodes.jsonl`), run in
/// `env` (`None`: the environment `sage3d eval` runs `agent_name` in, see
/// [`sage_eval::merge_shards`]), into the run folder `out`, as one evaluation over their union
/// writes it, then writes its report,
/// holding the lock on `out` ([`FolderLock`]) meanwhile; temporary files that an interrupted
/// earlier merge left there are removed first.
///
/// # Errors
///
/// A folder that another command is writing, or as [`sage_eval::merge_shards_with_report`].
pub fn merge(
    settings: &EvalSettings,
    agent_name: &str,
    env: Option<&EnvConfig>,
    shards: &[String],
    out: &Path,
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<(Summary, ReportOutcome)> {
    let lock = FolderLock::acquire(out, COMMAND)?;
    lock.remove_temporary();
    let job = ReportJob {
        on_map,
        ..ReportJob::new(&settings.scenes)
    };
    sage_eval::merge_shards_with_report(settings, agent_name, env, shards, out, &job)
}

/// Writes (again) the report of the evaluation run in `run` with the scenes of `scenes`
/// ([`report::write_with`], `on_map` called after each map), holding the lock on `run`
/// ([`FolderLock`]) meanwhile; in a run folder (its run record names `eval`), temporary files
/// that an interrupted earlier report or run left are removed first.
///
/// # Errors
///
/// A folder that another command is writing, or as [`report::write_with`].
pub fn report(
    run: &Path,
    scenes: &Path,
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<ReportOutcome> {
    report_with_options(run, scenes, &ReportOptions::default(), on_map, &|_, _| {})
}

/// [`report()`] with `options` (episode videos: [`report::write_with_options`], `on_video`
/// called after each video).
///
/// # Errors
///
/// A folder that another command is writing, or as [`report::write_with_options`].
pub fn report_with_options(
    run: &Path,
    scenes: &Path,
    options: &ReportOptions,
    on_map: &(dyn Fn(&str, usize) + Sync),
    on_video: &(dyn Fn(&str, usize) + Sync),
) -> Result<ReportOutcome> {
    let lock = FolderLock::acquire(run, "report")?;
    if sage_io::run::recorded_command(run).as_deref() == Some(COMMAND) {
        lock.remove_temporary();
    }
    report::write_with_options(run, scenes, options, on_map, on_video)
}
