//! An evaluation with its report: run (or resume) an agent over a dataset split, then write the
//! run's `report.html` and maps.

use sage_bench::eval::{self, EvalRecord, EvalSettings, RunOutcome};
use sage_bench::report::{self, ReportOutcome};
use sage_core::Result;
use std::path::Path;

/// Runs or resumes the evaluation of `settings` into `out` (`on_episode(record, to_run)` after
/// each episode), then writes its report (`on_map(episode_id, maps)` after each map).
///
/// # Errors
///
/// As [`eval::run`] and [`report::write_with`].
pub fn evaluate(
    settings: &EvalSettings,
    out: &Path,
    on_episode: &(dyn Fn(&EvalRecord, usize) + Sync),
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<(RunOutcome, ReportOutcome)> {
    let outcome = eval::run(settings, out, on_episode)?;
    let report = report::write_with(out, &settings.scenes, on_map)?;
    Ok((outcome, report))
}
