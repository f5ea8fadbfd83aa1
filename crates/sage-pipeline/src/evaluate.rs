//! An evaluation with its report: run (or resume) an agent over a dataset split, then write the
//! run's `report.html` and maps — for the command line, Python and the demo alike.

use sage_core::Result;
use sage_eval::report::{self, ReportOutcome};
use sage_eval::{EvalRecord, EvalSettings, RunOutcome, Runner, Summary};
use std::path::Path;

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
/// As [`sage_eval::claim`], [`sage_eval::run`] and [`report::write_with`].
pub fn evaluate(
    settings: &EvalSettings,
    out: &Path,
    force: bool,
    callbacks: Callbacks<'_>,
) -> Result<(RunOutcome, ReportOutcome)> {
    sage_eval::claim(out, force)?;
    let outcome = sage_eval::run(settings, out, callbacks.on_episode)?;
    let report = report::write_with(out, &settings.scenes, callbacks.on_map)?;
    Ok((outcome, report))
}

/// [`evaluate`] with a caller's runner (an agent written in Python, other environment
/// settings, or the episodes of some scenes only); without `report`, no report is written (a
/// shard of a larger run, whose report is written once its shards are merged).
///
/// # Errors
///
/// As [`sage_eval::claim`], [`sage_eval::run_with`] and [`report::write_with`].
pub fn evaluate_with(
    settings: &EvalSettings,
    runner: &Runner,
    out: &Path,
    report: bool,
    callbacks: Callbacks<'_>,
) -> Result<(RunOutcome, Option<ReportOutcome>)> {
    sage_eval::claim(out, false)?;
    let outcome = sage_eval::run_with(settings, runner, out, callbacks.on_episode)?;
    let report = report
        .then(|| report::write_with(out, &settings.scenes, callbacks.on_map))
        .transpose()?;
    Ok((outcome, report))
}

/// Merges the records of evaluation shards (the text of each shard's `episodes.jsonl`) into
/// the run folder `out`, as one evaluation over their union writes it, then writes its report.
///
/// # Errors
///
/// As [`sage_eval::merge_shards`] and [`report::write_with`].
pub fn merge(
    settings: &EvalSettings,
    agent_name: &str,
    shards: &[String],
    out: &Path,
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<(Summary, ReportOutcome)> {
    let summary = sage_eval::merge_shards(settings, agent_name, shards, out)?;
    let report = report::write_with(out, &settings.scenes, on_map)?;
    Ok((summary, report))
}
