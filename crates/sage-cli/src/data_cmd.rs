//! `sage3d data …`: benchmark datasets (instructions, episodes, splits, files).

use clap::{Args, Subcommand, ValueEnum};
use sage_core::Result;
use sage_io::runner::{Status, Tally};
use sage_pipeline::dataset::{BuildSettings, DatasetReport};
use sage_pipeline::traindata::TrainDataReport;
use sage_traindata::Progress;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum DataCommand {
    /// Build a dataset over a folder of scenes: trajectories, instructions (grammar or LLM),
    /// episodes, splits, JSONL / GVLN / R2R-VLNCE files and a summary (parallel, resumable).
    Build(BuildArgs),
    /// Render a training set from a dataset split: each trajectory cut into a preset's
    /// discrete actions, walked through physics, a frame rendered before every action, written
    /// as NaVILA annotations, WebDataset shards, a LeRobot dataset or a folder tree (parallel,
    /// resumable).
    Render(RenderArgs),
    /// Read episodes from a SAGE-Bench GVLN file, an R2R-VLNCE split or a GN-Bench Parquet
    /// split into a dataset folder's split (DATASET/episodes/SPLIT.jsonl, listed in
    /// DATASET/splits.json), for `eval` and `data render`.
    Import(ImportArgs),
    /// Write a split of a dataset as another tool's file: a GN-Bench Parquet split, so that
    /// sage3d's episodes run in GN-Bench.
    Export(ExportArgs),
}

/// The instruction text a GN-Bench import gives the agent.
#[derive(Clone, Copy, ValueEnum)]
enum GnInstruction {
    /// `grounded_instruction`, what GN-Bench's instruction sensor gives (the default).
    Grounded,
    /// `instruction`.
    Plain,
}

/// The formats `data export` writes.
#[derive(Clone, Copy, ValueEnum)]
enum ExportFormat {
    /// A GN-Bench split: Parquet, one row per episode, every column GN-Bench reads.
    GnBench,
}

#[derive(Args)]
pub struct ExportArgs {
    /// The dataset folder.
    dataset: PathBuf,
    /// The split to write.
    #[arg(long)]
    split: String,
    /// The file to write, named with the format's extension (`.parquet`); never a file of the
    /// dataset or of its scenes.
    #[arg(long)]
    out: PathBuf,
    /// The format.
    #[arg(long, value_enum, default_value = "gn-bench")]
    format: ExportFormat,
    /// The scenes folder, whose occupancy maps give the pixel columns (default: the one the
    /// dataset records).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// Replace --out when it exists.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
pub struct ImportArgs {
    /// A GVLN JSON file, an R2R-VLNCE folder (with --r2r-split) or a GN-Bench Parquet file
    /// (with --gn-bench).
    source: PathBuf,
    /// The dataset folder to write into: new, empty, or one `data build` or `data import` wrote.
    #[arg(long)]
    out: PathBuf,
    /// The split to write.
    #[arg(long, default_value = "train")]
    split: String,
    /// Read SOURCE as an R2R-VLNCE folder and take this split of it.
    #[arg(long)]
    r2r_split: Option<String>,
    /// Read SOURCE as a GN-Bench split (Parquet): every episode is checked against its
    /// scene's occupancy map in --scenes; rows that fail are listed and not imported.
    #[arg(long, conflicts_with = "r2r_split")]
    gn_bench: bool,
    /// The folder of the episodes' scenes (or one scene folder): every episode's scene must be
    /// there, and a dataset that records no scenes folder records this one for `eval` and
    /// `data render`. Episodes of a file without sage3d's asset slices (the published GVLN and
    /// R2R-VLNCE files) take their scene's from it (else `medium`). A GN-Bench import checks
    /// its rows against it (default: the one the dataset records).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// Which text of a GN-Bench row the agent gets (the other is kept in the episode).
    #[arg(long, value_enum, default_value = "grounded", requires = "gn_bench")]
    instruction: GnInstruction,
    /// S-frame offset DX,DY of a GVLN file that does not state its frame (the published ones).
    #[arg(long, default_value = "0,0", allow_hyphen_values = true)]
    offset: String,
    /// Replace the split when it exists, and write into a folder holding other files (never
    /// replacing one of them).
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub(crate) options: sage_traindata::Options,
    /// Output folder (new or empty; rerun with the same settings to resume).
    #[arg(long)]
    out: PathBuf,
    /// Replace another render's output in --out (files a render did not write are never
    /// touched).
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
pub struct BuildArgs {
    /// A scene folder, or a folder of scene folders.
    scenes: PathBuf,
    /// Output dataset folder.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    pub(crate) settings: BuildSettings,
    /// Write into an output folder that holds other files (never replacing one of them).
    #[arg(long)]
    force: bool,
}

pub fn run(cmd: DataCommand) -> Result<()> {
    match cmd {
        DataCommand::Build(a) => data_build(a),
        DataCommand::Render(a) => data_render(a),
        DataCommand::Import(a) => data_import(a),
        DataCommand::Export(a) => data_export(a),
    }
}

fn data_build(a: BuildArgs) -> Result<()> {
    let bar = crate::progress::bar("{bar:30} {pos}/{len} scenes {elapsed} (eta {eta}) {msg}");
    let start = Instant::now();
    let report = sage_pipeline::dataset::build(&a.scenes, &a.out, &a.settings, a.force, &|o, n| {
        bar.set_length(n as u64);
        bar.set_message(o.scene.clone());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let report = report?;
    print_dataset(&report, &a.out, start.elapsed().as_secs_f64());
    let skipped = report.skipped();
    if skipped > 0 {
        return Err(sage_core::Error::invalid(format!(
            "{skipped} of {} scenes were skipped (listed above); the dataset lacks their episodes, and a rerun retries them",
            report.outcomes.len()
        )));
    }
    let failed = report.summary.llm_failures;
    if failed > 0 {
        return Err(sage_core::Error::invalid(format!(
            "{failed} LLM requests failed after their retries: the dataset lacks their high-level instructions, and a rerun asks again"
        )));
    }
    Ok(())
}

fn data_import(a: ImportArgs) -> Result<()> {
    use sage_dataset::formats::gnbench::InstructionChoice;
    use sage_dataset::import::Source;
    let source = if a.gn_bench {
        Source::GnBench {
            file: a.source.clone(),
            instruction: match a.instruction {
                GnInstruction::Grounded => InstructionChoice::Grounded,
                GnInstruction::Plain => InstructionChoice::Plain,
            },
        }
    } else if let Some(split) = &a.r2r_split {
        Source::R2r {
            dir: a.source.clone(),
            split: split.clone(),
        }
    } else {
        let bad = || sage_core::Error::invalid(format!("--offset '{}' is not DX,DY", a.offset));
        let (x, y) = a.offset.split_once(',').ok_or_else(bad)?;
        let num = |v: &str| v.trim().parse::<f32>().map_err(|_| bad());
        Source::Gvln {
            file: a.source.clone(),
            offset: glam::Vec2::new(num(x)?, num(y)?),
        }
    };
    let r =
        sage_pipeline::dataset::import(&source, &a.out, &a.split, a.scenes.as_deref(), a.force)?;
    for x in &r.rejected {
        eprintln!(
            "rejected row {} ({}, {}): {}",
            x.row, x.episode_id, x.column, x.reason
        );
    }
    if let Some(report) = &r.report {
        eprintln!(
            "{} rows imported, {} rejected (listed in {})",
            r.episodes,
            r.rejected.len(),
            report.display()
        );
    }
    if r.assets_unknown > 0 {
        eprintln!(
            "asset slice `medium` for {} episodes: the file holds no asset slices and no --scenes was given to count their scenes' objects",
            r.assets_unknown
        );
    }
    println!(
        "{} episodes of {} scenes -> {}",
        r.episodes,
        r.scenes,
        r.file.display()
    );
    Ok(())
}

fn data_export(a: ExportArgs) -> Result<()> {
    use sage_dataset::export::Format;
    let format = match a.format {
        ExportFormat::GnBench => Format::GnBench,
    };
    let r = sage_pipeline::dataset::export(
        &a.dataset,
        &a.split,
        a.scenes.as_deref(),
        format,
        &a.out,
        a.force,
    )?;
    for l in &r.left_out {
        eprintln!("left out {}: {}", l.episode_id, l.reason);
    }
    println!(
        "{} episodes ({} left out) -> {}",
        r.rows,
        r.left_out.len(),
        a.out.display()
    );
    Ok(())
}

fn data_render(a: RenderArgs) -> Result<()> {
    eprintln!("renderer: {}", crate::flags::probe(a.options.device)?);
    let bar = crate::progress::bar("{bar:30} {pos}/{len} walks {elapsed} (eta {eta}) {msg}");
    let start = Instant::now();
    let frames = std::sync::atomic::AtomicUsize::new(0);
    let report = sage_pipeline::traindata::render(&a.options, &a.out, a.force, &|p| match p {
        Progress::Planned {
            routes,
            scene_changes,
        } => {
            bar.set_length(routes as u64);
            if !scene_changes.is_empty() {
                bar.suspend(|| {
                    eprintln!(
                        "note: scene files changed since the dataset was built ({}): its reference paths were planned on the files as they were; build the dataset again (`sage3d data build`) to walk the scenes as they are",
                        scene_changes.join(", ")
                    )
                });
            }
        }
        Progress::AlreadyComplete => {}
        Progress::Scene(scene) => bar.set_message(format!("loading {scene}")),
        Progress::Route(r) => {
            let n = frames.fetch_add(r.frames, std::sync::atomic::Ordering::Relaxed) + r.frames;
            if let Some(e) = &r.error {
                bar.suspend(|| eprintln!("skipped walk {}: {e}", r.route));
            }
            bar.set_message(format!(
                "{n} frames, {:.1} frames/s",
                n as f64 / start.elapsed().as_secs_f64().max(1e-9)
            ));
            bar.inc(1);
        }
    });
    bar.finish_and_clear();
    let report = report?;
    print_render(&report, &a.out, start.elapsed().as_secs_f64());
    let manifest = &report.manifest;
    if a.options.preview > 0 {
        println!(
            "preview: {}",
            a.out.join(sage_traindata::preview::PREVIEW_FILE).display()
        );
    }
    if manifest.skipped_any() {
        return Err(sage_core::Error::invalid(format!(
            "{} episodes were skipped (listed above and in {}/manifest.json)",
            manifest.counts.skipped,
            a.out.display()
        )));
    }
    Ok(())
}

/// Prints what a training-data render did: whether it had finished before, skipped episodes
/// with their reasons, the counts and the rate of the frames this run rendered.
pub fn print_render(report: &TrainDataReport, out: &Path, secs: f64) {
    if report.already_complete {
        println!("already complete: {}", out.display());
    }
    let (m, rendered) = (&report.manifest, report.rendered_frames);
    for s in &m.skipped {
        eprintln!("skipped {}: {}", s.episode_id, s.reason);
    }
    let c = &m.counts;
    let listed = |m: &std::collections::BTreeMap<String, usize>| {
        let parts: Vec<String> = m.iter().map(|(k, v)| format!("{v} {k}")).collect();
        if parts.is_empty() {
            String::new()
        } else {
            format!(" ({})", parts.join(", "))
        }
    };
    println!(
        "{} episodes ({} walks): {} kept{}, {} dropped{}, {} skipped; {} ignored{}",
        c.episodes,
        c.routes,
        c.kept,
        listed(&c.kept_failed).replacen(" (", " (not clean: ", 1),
        c.dropped.values().sum::<usize>(),
        listed(&c.dropped),
        c.skipped,
        c.ignored.values().sum::<usize>(),
        listed(&c.ignored)
    );
    // Samples are NaVILA's (one per step); LeRobot's rows are the same count (its info.json's
    // `total_frames`: episodes of one walk repeat its frames); the other layouts hold episodes
    // of the walks' frames.
    let samples = match m.settings.get("format").and_then(|f| f.as_str()) {
        Some("navila") => format!("{} NaVILA samples, ", c.samples),
        Some("lerobot") => format!("{} LeRobot rows (total_frames) from ", c.samples),
        _ => String::new(),
    };
    println!(
        "{samples}{} frames; rendered {rendered} frames in {secs:.1} s ({:.1} frames/s on {} threads) -> {}",
        c.frames,
        rendered as f64 / secs.max(1e-9),
        rayon::current_num_threads(),
        out.display()
    );
}

/// Prints what a dataset build did: skipped scenes with their reasons, the summary table and a
/// line of counts (`secs`: how long it took).
pub fn print_dataset(r: &DatasetReport, out: &Path, secs: f64) {
    for o in r.outcomes.iter().filter(|o| o.status == Status::Skipped) {
        eprintln!("skipped {}: {}", o.scene, o.reason.as_deref().unwrap_or(""));
    }
    print!("{}", r.summary.table());
    let tally = Tally::of(r.outcomes.iter().map(|o| o.status));
    let made: usize = r
        .outcomes
        .iter()
        .filter(|o| o.status == Status::Done)
        .map(|o| o.episodes)
        .sum();
    println!(
        "{} scenes: {tally}; {made} new episodes in {secs:.1} s ({:.1} episodes/s on {} threads) -> {}",
        r.outcomes.len(),
        made as f64 / secs.max(1e-9),
        rayon::current_num_threads(),
        out.display()
    );
}
