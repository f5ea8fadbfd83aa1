//! The run record: how an output folder was made (SPEC §13).

use crate::files::write_json;
use sage_core::Result;
use std::path::Path;

/// The file in which a command records how its output folder was made (SPEC §13).
pub const RUN_RECORD: &str = "sage3d_run.json";

/// Writes `dir/sage3d_run.json` (atomically): the tool, its version, the command and its seed,
/// plus the command's own `details` (an object: resolved settings, input hashes, outcomes).
pub fn write_run_record(
    dir: &Path,
    command: &str,
    seed: Option<u64>,
    details: serde_json::Value,
) -> Result<()> {
    let mut record = serde_json::json!({
        "tool": "sage3d",
        "version": env!("CARGO_PKG_VERSION"),
        "command": command,
        "seed": seed,
    });
    if let (Some(fields), serde_json::Value::Object(extra)) = (record.as_object_mut(), details) {
        fields.extend(extra);
    }
    write_json(&dir.join(RUN_RECORD), &record)
}
