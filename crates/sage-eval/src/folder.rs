//! The layout of a run folder: what an evaluation and its report write at its top.

use sage_io::run::RUN_RECORD;

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
