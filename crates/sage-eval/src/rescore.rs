//! Rescoring a finished evaluation run in another metric mode or DTW alignment, from the
//! per-episode records it stored (`docs/evaluation.md`, "Rescoring").
//!
//! Every metric is a pure function of an episode's stored `record` (`sage_metrics::evaluate`),
//! and what the agent did does not depend on the mode (the environment, the agents and their
//! seeds never read it), so scoring the stored records in mode M gives the numbers an
//! evaluation of the same agent in mode M gives. The rescored run is written as a new run
//! folder — records, summary, run record — that is exactly such an evaluation's: its run
//! record holds the run's settings with the new mode and alignment, so its report, the viewer
//! and a resumed `eval` in that mode read it as one; the run rescored is only read.
//!
//! The new folder's run record is written first, marked unfinished, and marked finished last
//! (after the report, when one is written): a rescoring killed half-way leaves a folder that
//! its rerun — the same run, mode and alignment into the same folder — takes as its own and
//! writes again, where any other run, finished or not, is refused.
//!
//! One exception: GN-Bench's distances to goal (`record.gnbench`) are only computed in a run
//! scored in mode `gnbench`, so only such a run's records rescore in that mode; a record of
//! another run says so ([`sage_metrics::evaluate`]'s error), before anything is written.

use crate::evaluator::{RecordedRun, mark_unfinished};
use crate::folder::{COMMAND, RECORDS_FILE, SUMMARY_FILE, finished_run_record, mark_finished};
use crate::records::EvalRecord;
use crate::report::{ReportJob, ReportOutcome, read_run};
use crate::summary::Summary;
use sage_core::{Error, Result, ResultExt};
use sage_io::lock::FolderLock;
use sage_io::run::{RUN_RECORD, read_record, unfinished_status};
use sage_metrics::{Dtw, Mode, Scoring};
use std::io::Write;
use std::path::Path;

/// What [`rescore`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Rescored {
    /// How the run was scored before.
    pub from: Scoring,
    /// How it is scored now.
    pub to: Scoring,
    /// Episodes scored again.
    pub rescored: usize,
    /// Faulted episodes (never scored; copied as they are).
    pub faulted: usize,
    /// The summary written to the new run folder's `summary.json`.
    pub summary: Summary,
}

/// How the run record `record` says its run was scored (`settings.mode`, `settings.dtw`;
/// runs recorded before the DTW choice used exact DTW).
fn recorded_scoring(record: &serde_json::Value) -> Result<Scoring> {
    let settings = record
        .get("settings")
        .ok_or_else(|| Error::format("settings", "missing"))?;
    let field = |key: &str| settings.get(key).cloned();
    let mode: Mode = serde_json::from_value(field("mode").unwrap_or_default())
        .map_err(|e| Error::format("settings.mode", e.to_string()))?;
    let dtw = match field("dtw") {
        None => Default::default(),
        Some(v) => {
            serde_json::from_value(v).map_err(|e| Error::format("settings.dtw", e.to_string()))?
        }
    };
    Ok(Scoring { mode, dtw })
}

/// `rec` scored under `scoring` from its stored `record`, as an evaluation in that mode would
/// have written it: a faulted record as it is; GN-Bench's distances kept only in mode
/// `gnbench` (the only mode that computes them).
///
/// # Errors
///
/// A scored record without its stored `record`, or one the metrics refuse in that mode.
fn rescore_record(rec: &EvalRecord, scoring: Scoring) -> Result<EvalRecord> {
    let mut out = rec.clone();
    if rec.metrics.is_none() {
        return Ok(out);
    }
    let Some(record) = out.record.as_mut() else {
        return Err(Error::invalid(format!(
            "episode {} has metrics but no stored record to rescore (evaluate it again in mode {})",
            rec.episode_id, scoring.mode
        )));
    };
    if scoring.mode != Mode::GnBench {
        record.gnbench = None;
    }
    out.metrics = Some(sage_metrics::evaluate(record, scoring)?);
    Ok(out)
}

/// Whether `out` holds a rescoring of the run at `from_run` (its canonical path) in `scoring`
/// that was stopped before it finished: that rescoring's own folder, which its rerun writes
/// again.
fn unfinished_rescoring(out: &Path, from_run: &Path, scoring: Scoring) -> bool {
    read_record(out).is_some_and(|record| {
        record.get("command").and_then(serde_json::Value::as_str) == Some(COMMAND)
            && unfinished_status(&record).is_some()
            && record
                .pointer("/rescored_from/run")
                .and_then(serde_json::Value::as_str)
                == from_run.to_str()
            && recorded_scoring(&record).is_ok_and(|s| s == scoring)
    })
}

/// Rescores the finished evaluation run in `run` in metric mode `mode` with nDTW alignment
/// `dtw` (`None`: as the run was scored) into the new run folder `out`:
/// `episodes.jsonl` with every scored episode's metrics computed again from its stored record
/// (faulted episodes copied), `summary.json` in the new mode, and `sage3d_run.json` holding the
/// run's settings with the new mode and alignment, its environment (`env`, when the run records
/// one), its dataset and scene hashes, and `rescored_from` (the run's folder and how it was
/// scored). `run` is only read, under its lock
/// so no evaluation writes it meanwhile. Callers claim `out` first ([`crate::claim`]) and hold
/// its lock while this and the new folder's report are written. Every record is scored before
/// anything is written, so a refused rescoring leaves `out` as it was.
///
/// # Errors
///
/// `run` not a finished evaluation run ([`read_run`]), `out` the same folder as `run` or one
/// that already holds a run (a rescoring writes a new one; the unfinished folder of this same
/// rescoring is written again), a record that cannot be rescored in the new mode (naming its
/// episode: a run not scored in `gnbench` cannot be rescored in `gnbench`), or a write error.
pub fn rescore(run: &Path, mode: Option<Mode>, dtw: Option<Dtw>, out: &Path) -> Result<Rescored> {
    let rescored = rescore_unfinished(run, mode, dtw, out)?;
    mark_finished(out)?;
    Ok(rescored)
}

/// [`rescore`] that also writes the new folder's report (`report`) before it marks the new
/// run finished, as `sage3d report RUN --mode M --out NEW` does: a rescoring killed before its
/// report is written is still unfinished, and its rerun writes it all again.
///
/// # Errors
///
/// As [`rescore`] and [`crate::report::write_with_options`].
pub fn rescore_with_report(
    run: &Path,
    mode: Option<Mode>,
    dtw: Option<Dtw>,
    out: &Path,
    report: &ReportJob,
) -> Result<(Rescored, ReportOutcome)> {
    let rescored = rescore_unfinished(run, mode, dtw, out)?;
    Ok((rescored, report.finish(out)?))
}

/// [`rescore`] up to the new folder's summary: its run record, written first, stays marked
/// unfinished.
fn rescore_unfinished(
    run: &Path,
    mode: Option<Mode>,
    dtw: Option<Dtw>,
    out: &Path,
) -> Result<Rescored> {
    finished_run_record(run)?;
    let same = |a: &Path, b: &Path| {
        let abs = |p: &Path| std::fs::canonicalize(p).or_else(|_| std::path::absolute(p));
        matches!((abs(a), abs(b)), (Ok(x), Ok(y)) if x == y)
    };
    if same(run, out) {
        return Err(Error::invalid(
            "a rescoring writes a new run folder and leaves the run as it is: choose another folder (`out`)",
        )
        .in_file(out));
    }
    let _reading = FolderLock::acquire(run, "report")?;
    let files = read_run(run)?;
    let from = recorded_scoring(&files.run).in_file(run.join(RUN_RECORD))?;
    let scoring = Scoring {
        mode: mode.unwrap_or(from.mode),
        dtw: dtw.unwrap_or(from.dtw),
    };
    let from_run = std::fs::canonicalize(run).unwrap_or_else(|_| run.to_path_buf());
    if !unfinished_rescoring(out, &from_run, scoring)
        && let Some(held) = [RECORDS_FILE, SUMMARY_FILE, RUN_RECORD]
            .into_iter()
            .find(|f| out.join(f).exists())
    {
        return Err(Error::invalid(format!(
            "the folder holds a run already ({held}); a rescoring writes a new one: choose a new or empty folder (`out`)"
        ))
        .in_file(out));
    }
    let rescored: Vec<EvalRecord> = files
        .records
        .iter()
        .map(|r| rescore_record(r, scoring))
        .collect::<Result<_>>()
        .map_err(|e| e.in_file(run.join(RECORDS_FILE)))?;
    // The lines as an evaluation writes them; the summary is computed from the lines read
    // back, as an evaluation computes it from its records file (reading a number back can
    // move its last bit, so the means are those of what the file holds).
    let mut lines = Vec::with_capacity(rescored.len());
    for r in &rescored {
        lines.push(serde_json::to_string(r).map_err(|e| Error::invalid(e.to_string()))?);
    }
    let records: Vec<EvalRecord> = lines
        .iter()
        .map(|l| serde_json::from_str(l).map_err(|e| Error::invalid(e.to_string())))
        .collect::<Result<_>>()?;
    let summary = Summary::of_records(
        &files.summary.agent,
        &files.summary.split,
        scoring,
        &records,
    );
    let mut settings = files.run.get("settings").cloned().unwrap_or_default();
    settings["mode"] = scoring.mode.as_str().into();
    settings["dtw"] = scoring.dtw.as_str().into();
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    // The record first: a rescoring killed from here on leaves a folder its rerun takes.
    let recorded = |key: &str| files.run.get(key).unwrap_or(&serde_json::Value::Null);
    mark_unfinished(
        out,
        &RecordedRun {
            settings: &settings,
            // The run's episodes ran in its environment; a run recorded before the environment
            // was has none to copy, and its rescoring none to claim.
            env: files.run.get("env"),
            dataset_hash: recorded("dataset_hash"),
            scenes: recorded("scene_inputs"),
            scenes_folder: crate::folder::recorded_scenes(run).ok().as_deref(),
        },
        Some(serde_json::json!({
            "run": from_run,
            "mode": from.mode.as_str(),
            "dtw": from.dtw.as_str(),
        })),
    )?;
    sage_io::files::write_atomic(&out.join(RECORDS_FILE), |w| {
        lines.iter().try_for_each(|l| {
            w.write_all(l.as_bytes())?;
            w.write_all(b"\n")
        })
    })?;
    sage_io::files::write_json(&out.join(SUMMARY_FILE), &summary)?;
    let faulted = records.iter().filter(|r| r.metrics.is_none()).count();
    Ok(Rescored {
        from,
        to: scoring,
        rescored: records.len() - faulted,
        faulted,
        summary,
    })
}
