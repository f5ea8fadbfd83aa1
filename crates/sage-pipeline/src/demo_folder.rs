//! The demo's output folder: claimed, and its run record written, before any step of
//! [`crate::demo::run`] writes into it, so that a demo that stopped half-way is recognised as
//! the demo's when it is rerun to resume, and a folder of someone else's files is refused.

use crate::demo::DemoSettings;
use sage_core::Result;
use sage_io::lock::FolderLock;
use std::path::Path;

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

/// Claims `s.out` for the demo and writes its run record: the folder must be new, empty or a
/// demo's (a rerun, which resumes); with `force`, a folder of other files is written into,
/// provided none of them would be replaced ([`sage_io::run::claim_folder`]). Returns the
/// folder's lock, to hold while [`crate::demo::run`] writes there. Each step claims its own
/// sub-folder in turn.
///
/// # Errors
///
/// A folder that another command is writing, one holding files the demo did not write, or a
/// write error.
pub fn claim(s: &DemoSettings, force: bool) -> Result<FolderLock> {
    let out: &Path = &s.out;
    let lock = sage_io::run::claim_folder(out, &[COMMAND], &OUTPUTS, force)?;
    sage_io::run::write_run_record(
        out,
        COMMAND,
        Some(s.seed),
        serde_json::json!({
            "scenes": s.scenes,
            "per_scene": s.per_scene,
            "gaussians": s.gaussians,
            "agents": s.agents,
            "split": s.split,
            "from": s.from.as_ref().map(|p| p.to_string_lossy()),
        }),
    )?;
    Ok(lock)
}
