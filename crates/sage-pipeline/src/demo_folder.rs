//! The demo's output folder: claimed, and its run record written marked unfinished, before any
//! step of [`crate::demo::run`] writes into it, so that a demo that stopped half-way is
//! recognised as the demo's when it is rerun to resume, and says it is not complete until then;
//! a folder of someone else's files is refused.

use crate::demo::DemoSettings;
use sage_core::Result;
use sage_io::lock::FolderLock;
use sage_io::run::{FINISHED, UNFINISHED};

/// The command, as the demo folder's run record names it.
pub const COMMAND: &str = "demo";

/// Everything the demo writes at the top of its folder.
const OUTPUTS: [&str; 6] = [
    "scenes",
    "dataset",
    "train_data",
    "runs",
    "overview.png",
    sage_io::RUN_RECORD,
];

/// Claims `s.out` for the demo and writes its run record, marked unfinished
/// ([`sage_io::run::UNFINISHED`]) until [`crate::demo::run`] has written everything
/// ([`finish`]): the folder must be new, empty or a demo's, finished or not (a rerun, which
/// resumes); with `force`, a folder of other files is written into, provided none of them
/// would be replaced ([`sage_io::run::claim_folder`]). Returns the folder's lock, to hold
/// while [`crate::demo::run`] writes there. Each step claims its own sub-folder in turn.
///
/// # Errors
///
/// A folder that another command is writing, one holding files the demo did not write, or a
/// write error.
pub fn claim(s: &DemoSettings, force: bool) -> Result<FolderLock> {
    let lock = sage_io::run::claim_folder(&s.out, &[COMMAND], &OUTPUTS, force)?;
    write_record(s, UNFINISHED)?;
    Ok(lock)
}

/// Marks the demo's run record finished ([`sage_io::run::FINISHED`]), once every step and the
/// overview are written: the record a rerun that resumed ends with is the same, byte for byte,
/// as that of a run never interrupted.
///
/// # Errors
///
/// The record cannot be written.
pub fn finish(s: &DemoSettings) -> Result<()> {
    write_record(s, FINISHED)
}

/// Writes the demo's run record in `s.out`: its settings and `status`.
fn write_record(s: &DemoSettings, status: &str) -> Result<()> {
    sage_io::run::write_run_record(
        &s.out,
        COMMAND,
        Some(s.seed),
        serde_json::json!({
            "status": status,
            "scenes": s.scenes,
            "per_scene": s.per_scene,
            "gaussians": s.gaussians,
            "agents": s.agents,
            "split": s.split,
            "from": s.from.as_ref().map(|p| p.to_string_lossy()),
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_record_is_unfinished_from_the_claim_until_finish_and_a_rerun_claims_it() {
        let dir = tempfile::tempdir().unwrap();
        let s = DemoSettings {
            out: dir.path().join("demo"),
            ..DemoSettings::default()
        };
        let lock = claim(&s, false).unwrap();
        assert_eq!(
            sage_io::run::unfinished_command(&s.out).as_deref(),
            Some(COMMAND)
        );
        // What a demo killed after its first step leaves: its record, unfinished, and a file.
        std::fs::write(s.out.join("overview.png"), "half").unwrap();
        drop(lock);
        let lock = claim(&s, false).unwrap();
        assert!(!sage_io::run::is_finished(&s.out));
        finish(&s).unwrap();
        drop(lock);
        let record = sage_io::run::read_record(&s.out).unwrap();
        assert_eq!(record["status"], FINISHED);
        assert_eq!(record["command"], COMMAND);
        assert_eq!(record["agents"], serde_json::json!(s.agents));
        // The resumed demo ends with the record of one never interrupted.
        let whole = DemoSettings {
            out: dir.path().join("whole"),
            ..s.clone()
        };
        let lock = claim(&whole, false).unwrap();
        finish(&whole).unwrap();
        drop(lock);
        let record = |d: &DemoSettings| std::fs::read(d.out.join(sage_io::RUN_RECORD)).unwrap();
        assert_eq!(record(&s), record(&whole));
        // A finished demo is a demo's folder too: rerunning it resumes.
        drop(claim(&s, false).unwrap());
        // Another command may not take it over.
        assert!(sage_io::run::claim_folder(&s.out, &["eval"], &[], false).is_err());
    }
}
