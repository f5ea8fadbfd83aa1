//! `sage3d report RUN [--scenes SCENES] [--videos N]`: (re)writes an evaluation run's
//! `report.html`, its PNGs and N episode videos under progress bars (`docs/evaluation.md`,
//! "Report"), holding the run folder's lock
//! (`sage_pipeline::evaluate::report`); `sage3d eval` calls the same writer at the end of a run.

use sage_core::{Error, Result};
use sage_eval::report::{ReportOptions, ReportOutcome};
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
    /// Write episode videos (report/videos/*.gif, shown by the page) of the first N episodes
    /// in the gallery's order: unsuccessful first, then by id.
    #[arg(long, default_value_t = 0, value_name = "N")]
    videos: usize,
}

/// Writes the report of `run` with the scenes of `scenes` and `videos` episode videos under
/// progress bars over the episodes' maps and videos.
fn write_with_bar(run: &Path, scenes: &Path, videos: usize) -> Result<ReportOutcome> {
    let maps = crate::progress::bar("{bar:30} {pos}/{len} maps {elapsed} (eta {eta}) {msg}");
    let clips = crate::progress::bar("{bar:30} {pos}/{len} videos {elapsed} (eta {eta}) {msg}");
    let tick = |bar: &indicatif::ProgressBar, id: &str, total: usize| {
        bar.set_length(total as u64);
        bar.set_message(id.to_string());
        bar.inc(1);
    };
    let options = ReportOptions {
        videos,
        ..ReportOptions::default()
    };
    let outcome = sage_pipeline::evaluate::report_with_options(
        run,
        scenes,
        &options,
        &|id, total| tick(&maps, id, total),
        &|id, total| {
            maps.finish_and_clear();
            tick(&clips, id, total)
        },
    );
    maps.finish_and_clear();
    clips.finish_and_clear();
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
    let outcome = write_with_bar(&a.run, &scenes, a.videos)?;
    println!("{}", describe(&outcome));
    if a.videos > 0 {
        let mut line = format!("videos: {} in report/videos/", outcome.videos);
        if outcome.videos < a.videos {
            line.push_str(&format!(
                " (asked for {}; the run has {} episodes with a trajectory)",
                a.videos, outcome.maps
            ));
        }
        println!("{line}");
    }
    Ok(())
}
