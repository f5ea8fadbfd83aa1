//! `sage3d report RUN [--scenes SCENES] [--videos N] [--mode M] [--dtw D] [--out NEW]`:
//! (re)writes an evaluation run's `report.html`, its PNGs and N episode videos under progress
//! bars (`docs/evaluation.md`, "Report"), holding the run folder's lock
//! (`sage_pipeline::evaluate::report`); `sage3d eval` calls the same writer at the end of a run.
//! With `--mode` or `--dtw` it rescores the run from its stored records into the new run
//! folder `--out` instead (`sage_eval::rescore_with_report`, "Rescoring"), with that folder's
//! report.

use sage_core::{Error, Result};
use sage_eval::report::{ReportJob, ReportOptions, ReportOutcome};
use sage_metrics::{Dtw, Mode};
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
    /// Rescore the run in this metric mode (sage, vlnce, sage-official, gnbench) from its stored
    /// records, into the new run folder --out (the run is left as it is); gnbench only from a
    /// run scored in gnbench.
    #[arg(long, requires = "out")]
    mode: Option<Mode>,
    /// Rescore the run with this nDTW alignment (exact or fast) into --out; with --mode, or
    /// alone to keep the run's mode.
    #[arg(long, requires = "out")]
    dtw: Option<Dtw>,
    /// The new run folder a rescoring (--mode, --dtw) writes: records, summary, run record and
    /// report, as an evaluation in that mode writes them; new or empty.
    #[arg(long, value_name = "NEW")]
    out: Option<PathBuf>,
    /// Write the rescored run into a folder holding other files (never replacing one of them).
    #[arg(long, requires = "out")]
    force: bool,
}

/// Calls `write` with the report of the scenes of `scenes` and `videos` episode videos, under
/// progress bars over the episodes' maps and videos.
fn with_bars<T>(
    scenes: &Path,
    videos: usize,
    write: impl FnOnce(&ReportJob) -> Result<T>,
) -> Result<T> {
    let maps = crate::progress::bar("{bar:30} {pos}/{len} maps {elapsed} (eta {eta}) {msg}");
    let clips = crate::progress::bar("{bar:30} {pos}/{len} videos {elapsed} (eta {eta}) {msg}");
    let tick = |bar: &indicatif::ProgressBar, id: &str, total: usize| {
        bar.set_length(total as u64);
        bar.set_message(id.to_string());
        bar.inc(1);
    };
    let on_map = |id: &str, total: usize| tick(&maps, id, total);
    let on_video = |id: &str, total: usize| {
        maps.finish_and_clear();
        tick(&clips, id, total)
    };
    let job = ReportJob {
        scenes,
        options: ReportOptions {
            videos,
            ..ReportOptions::default()
        },
        on_map: &on_map,
        on_video: &on_video,
    };
    let outcome = write(&job);
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

/// Regenerates the report (or rescores the run into a new folder) and prints what it wrote.
pub fn run(a: ReportArgs) -> Result<()> {
    // A folder that is not a run, or a run not finished, is named for what it is before
    // anything else is read.
    sage_eval::folder::finished_run_record(&a.run)?;
    let scenes = match &a.scenes {
        Some(s) => s.clone(),
        None => sage_eval::folder::recorded_scenes(&a.run)?,
    };
    let outcome = match &a.out {
        Some(out) => {
            if a.mode.is_none() && a.dtw.is_none() {
                return Err(Error::invalid(
                    "--out names the folder of a rescoring: give the mode (--mode) or the alignment (--dtw) to rescore in",
                ));
            }
            let _lock = sage_eval::claim_rescoring(out, a.force)?;
            let (done, report) = with_bars(&scenes, a.videos, |job| {
                sage_eval::rescore_with_report(&a.run, a.mode, a.dtw, out, job)
            })?;
            print!("{}", done.summary.table());
            println!(
                "rescored {} episodes ({} faulted, copied) from mode {} ({} DTW) to mode {} ({} DTW) -> {}",
                done.rescored,
                done.faulted,
                done.from.mode,
                done.from.dtw,
                done.to.mode,
                done.to.dtw,
                out.display()
            );
            report
        }
        None => with_bars(&scenes, a.videos, |job| {
            sage_pipeline::evaluate::report_with_options(
                &a.run,
                job.scenes,
                &job.options,
                job.on_map,
                job.on_video,
            )
        })?,
    };
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
