//! The layout of a run folder: what an evaluation and its report write at its top, and how a
//! folder is told to be one.

use sage_core::{Error, Result};
use sage_io::run::RUN_RECORD;
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

/// The scenes folder the evaluation run in `dir` was evaluated with, as its run record names it
/// (`settings.scenes`): what its report and rescoring draw maps with unless told otherwise.
///
/// # Errors
///
/// Not an evaluation run ([`run_record`]), or a record without `settings.scenes` (asking for
/// the scenes folder).
pub fn recorded_scenes(dir: &Path) -> Result<PathBuf> {
    let record = run_record(dir)?;
    record
        .get("settings")
        .and_then(|s| s.get("scenes"))
        .and_then(serde_json::Value::as_str)
        .map(PathBuf::from)
        .ok_or_else(|| {
            Error::invalid(
                "the run record names no scenes folder (settings.scenes); name it (`scenes`)",
            )
            .in_file(dir.join(RUN_RECORD))
        })
}
