//! An evaluation with its report: run (or resume) an agent over a dataset split, then write the
//! run's `report.html` and maps.

use sage_core::Result;
use sage_eval::report::{self, ReportOutcome};
use sage_eval::{EvalRecord, EvalSettings, RunOutcome};
use std::path::Path;

/// [`evaluate_into`] without `force`.
///
/// # Errors
///
/// As [`evaluate_into`].
pub fn evaluate(
    settings: &EvalSettings,
    out: &Path,
    on_episode: &(dyn Fn(&EvalRecord, usize) + Sync),
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<(RunOutcome, ReportOutcome)> {
    evaluate_into(settings, out, false, on_episode, on_map)
}

/// Runs or resumes the evaluation of `settings` into `out` (`on_episode(record, to_run)` after
/// each episode), then writes its report (`on_map(episode_id, maps)` after each map). `out`
/// must be new, empty or an evaluation's run folder; with `force`, a folder of other files is
/// written into, provided none of them would be replaced ([`sage_eval::claim`]).
///
/// # Errors
///
/// As [`sage_eval::claim`], [`sage_eval::run`] and [`report::write_with`].
pub fn evaluate_into(
    settings: &EvalSettings,
    out: &Path,
    force: bool,
    on_episode: &(dyn Fn(&EvalRecord, usize) + Sync),
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<(RunOutcome, ReportOutcome)> {
    sage_eval::claim(out, force)?;
    let outcome = sage_eval::run(settings, out, on_episode)?;
    let report = report::write_with(out, &settings.scenes, on_map)?;
    Ok((outcome, report))
}
