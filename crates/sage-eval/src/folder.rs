//! The layout of a run folder: what an evaluation and its report write at its top, how a
//! folder is told to be one, and whether its writer finished it.
//!
//! Every command that writes a run folder (`sage3d eval`, a rescoring, a merge of shards, human
//! play) records itself in `sage3d_run.json` before its first output, marked unfinished
//! ([`UNFINISHED`](sage_io::run::UNFINISHED)), and marks the run [`FINISHED`] once its last
//! output is written (the summary, and the report when it writes one). A run whose record says
//! unfinished was killed or failed half-way: its rerun resumes or redoes it, and every reader
//! that needs the run's numbers refuses it ([`finished_run_record`]). Records written before
//! the status existed have none and read as finished.

use sage_core::{Error, Result, ResultExt};
use sage_io::run::{FINISHED, RUN_RECORD, unfinished_status};
use std::path::{Path, PathBuf};

/// The command, as the run record of a run folder names it.
pub const COMMAND: &str = "eval";

/// The per-episode records file of a run folder.
pub const RECORDS_FILE: &str = "episodes.jsonl";
/// The aggregate file of a run folder.
pub const SUMMARY_FILE: &str = "summary.json";

/// The report page of a run folder.
pub const REPORT_FILE: &str = "report.html";
/// The folder of the report's PNGs (charts; maps under `maps/`), in the run folder.
pub const REPORT_DIR: &str = "report";

/// Everything an evaluation and its report write at the top of a run folder.
pub const RUN_OUTPUTS: [&str; 5] = [
    RECORDS_FILE,
    SUMMARY_FILE,
    RUN_RECORD,
    REPORT_FILE,
    REPORT_DIR,
];

/// The run record of the evaluation run folder `dir`, read after checking that `dir` is one:
/// a folder whose `sage3d_run.json` names [`COMMAND`] (`sage3d eval`, a merge of its shards,
/// a rescoring and a person's play in the viewer all write such a record). Commands that read
/// a run (its report, its rescoring, the viewer) call this first, so that a dataset or another
/// command's folder is named for what it is rather than failing later on a file it lacks.
///
/// # Errors
///
/// An `invalid` error naming the folder when it does not exist, has no run record, or has one
/// from another command (naming that command: `its sage3d_run.json is from `data build``);
/// a run record that cannot be read or parsed, naming the file.
pub fn run_record(dir: &Path) -> Result<serde_json::Value> {
    if !dir.is_dir() {
        return Err(Error::invalid("no such run folder").in_file(dir));
    }
    let path = dir.join(RUN_RECORD);
    if !path.is_file() {
        return Err(Error::invalid(format!(
            "not an evaluation run (it has no {RUN_RECORD}; `sage3d eval --out` makes one)"
        ))
        .in_file(dir));
    }
    let record: serde_json::Value = sage_io::files::read_json(&path)?;
    match record.get("command").and_then(serde_json::Value::as_str) {
        Some(COMMAND) => Ok(record),
        Some(other) => Err(Error::invalid(format!(
            "not an evaluation run (its {RUN_RECORD} is from `{other}`; `sage3d eval --out` makes one)"
        ))
        .in_file(dir)),
        None => Err(Error::format("command", "missing: expected the command that made the folder").in_file(&path)),
    }
}

/// [`run_record`] of a run whose writer finished it: the run record of `dir`, which must not
/// be marked unfinished (see the module doc). Every reader of a run's numbers (its report, a
/// rescoring, the viewer) goes through this.
///
/// # Errors
///
/// As [`run_record`]; an `invalid` error naming the folder when the run was not finished:
/// naming the command still writing it, else saying which command to rerun to finish it.
pub fn finished_run_record(dir: &Path) -> Result<serde_json::Value> {
    let record = run_record(dir)?;
    let Some(status) = unfinished_status(&record) else {
        return Ok(record);
    };
    let settings = record.get("settings");
    let setting = |key: &str| {
        settings
            .and_then(|s| s.get(key))
            .and_then(serde_json::Value::as_str)
            .unwrap_or("?")
    };
    // What the run is, how to finish it, and how it stands while its writer still runs.
    const WRITING: (&str, &str) = ("is still being written by", "wait for it to finish");
    let (what, finish, busy) = if let Some(from) = record.get("rescored_from") {
        let run = from
            .get("run")
            .and_then(serde_json::Value::as_str)
            .unwrap_or("RUN");
        (
            "rescoring",
            format!(
                "rerun the same rescoring (`sage3d report {run} --mode {} --dtw {} --out {}`) to finish it",
                setting("mode"),
                setting("dtw"),
                dir.display()
            ),
            WRITING,
        )
    } else if setting("agent") == sage_agents::AgentKind::Human.to_string() {
        (
            "human run",
            format!(
                "play an episode of it (`sage3d view {} --play {}`) to finish it",
                setting("dataset"),
                dir.display()
            ),
            ("is open for play in", "play an episode there to finish it"),
        )
    } else {
        (
            "evaluation",
            format!("rerun the same `sage3d {COMMAND}` into it to finish it"),
            WRITING,
        )
    };
    if let Some(writer) = sage_io::lock::writer_of(dir) {
        let (stands, then) = busy;
        return Err(Error::invalid(format!(
            "the {what} in this folder {stands} {writer}: {then}"
        ))
        .in_file(dir));
    }
    Err(Error::invalid(format!(
        "the {what} in this folder was not finished (its {RUN_RECORD} has status '{status}'): {finish}"
    ))
    .in_file(dir))
}

/// Marks the run in `dir` finished: its run record written again with the `status`
/// [`FINISHED`], the last write of every command that writes a run folder. The record is
/// otherwise kept as its command wrote it, so a resumed run ends with the same bytes as an
/// uninterrupted one.
///
/// # Errors
///
/// Not an evaluation run ([`run_record`]), or a write error.
pub(crate) fn mark_finished(dir: &Path) -> Result<()> {
    let mut record = run_record(dir)?;
    record["status"] = FINISHED.into();
    sage_io::files::write_json(&dir.join(RUN_RECORD), &record)
}

/// The scenes folder the evaluation run in `dir` was evaluated with, as its run record names it:
/// what its report, rescoring and viewer draw maps with unless told otherwise. The record's
/// `scenes_folder` (absolute and relative to the run folder) is resolved relative to `dir`
/// first, then absolute ([`sage_dataset::folder::resolve_scenes_record`]); a record written
/// before it has only `settings.scenes`, as the command was given it (relative to where it
/// ran).
///
/// # Errors
///
/// Not an evaluation run ([`run_record`]), or a record naming no scenes folder that exists
/// (asking for the scenes folder).
pub fn recorded_scenes(dir: &Path) -> Result<PathBuf> {
    let record = run_record(dir)?;
    let path = dir.join(RUN_RECORD);
    if let Some(folder) = record.get("scenes_folder") {
        return sage_dataset::folder::resolve_scenes_record(dir, folder, "scenes_folder")
            .in_file(&path);
    }
    let given = record
        .get("settings")
        .and_then(|s| s.get("scenes"))
        .and_then(serde_json::Value::as_str)
        .map(PathBuf::from)
        .ok_or_else(|| {
            Error::invalid(
                "the run record names no scenes folder (settings.scenes); name it (`scenes`)",
            )
            .in_file(&path)
        })?;
    if given.is_dir() {
        return Ok(given);
    }
    Err(Error::invalid(format!(
        "the scenes folder the run record names (settings.scenes: {}, as the evaluation was given it) does not exist from here; name the scenes folder (`scenes`)",
        given.display()
    ))
    .in_file(&path))
}
