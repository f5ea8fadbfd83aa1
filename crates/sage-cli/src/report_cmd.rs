//! `sage3d report RUN [--scenes SCENES]`: (re)writes an evaluation run's `report.html` and its
//! PNGs under a progress bar (`docs/evaluation.md`, "Report"), holding the run folder's lock
//! (`sage_pipeline::evaluate::report`); `sage3d eval` calls the same writer at the end of a run.

use sage_core::{Error, Result};
use sage_eval::report::ReportOutcome;
use sage_io::run::RUN_RECORD;
use std::path::{Path, PathBuf};

/// Flags of `sage3d report`.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// Run folder written by `sage3d eval` (summary.json, episodes.jsonl, sage3d_run.json).
    run: PathBuf,
    /// One scene folder or a folder of scene folders (default: the run's own `--scenes`).
    #[arg(long)]
    scenes: Option<PathBuf>,
}

/// Writes the report of `run` with the scenes of `scenes` under a progress bar over the
/// episodes' maps.
fn write_with_bar(run: &Path, scenes: &Path) -> Result<ReportOutcome> {
    let bar = crate::progress::bar("{bar:30} {pos}/{len} maps {elapsed} (eta {eta}) {msg}");
    let outcome = sage_pipeline::evaluate::report(run, scenes, &|id, total| {
        bar.set_length(total as u64);
        bar.set_message(id.to_string());
        bar.inc(1);
    });
    bar.finish_and_clear();
    outcome
}

/// One line saying what was written.
pub fn describe(o: &ReportOutcome) -> String {
    format!(
        "report: {} ({} charts, {} maps, {} embedded)",
        o.html.display(),
        o.charts,
        o.maps,
        o.embedded
    )
}

/// The scenes folder the run was evaluated with, from its run record.
fn recorded_scenes(run: &Path) -> Result<PathBuf> {
    let path = run.join(RUN_RECORD);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| Error::format(RUN_RECORD, e.to_string()).in_file(&path))?;
    v.get("settings")
        .and_then(|s| s.get("scenes"))
        .and_then(|s| s.as_str())
        .map(PathBuf::from)
        .ok_or_else(|| Error::invalid("no settings.scenes in it; pass --scenes").in_file(&path))
}

/// Regenerates the report and prints its path.
pub fn run(a: ReportArgs) -> Result<()> {
    let scenes = match a.scenes {
        Some(s) => s,
        None => recorded_scenes(&a.run)?,
    };
    let outcome = write_with_bar(&a.run, &scenes)?;
    println!("{}", describe(&outcome));
    Ok(())
}
