//! The report of an evaluation run (`docs/evaluation.md`, "Report"): `RUN/report.html`, one
//! self-contained page that opens offline, and the PNGs it shows under `RUN/report/`.
//!
//! The page states the run (mode, agent, split, dataset hash, version, episode counts, faulted
//! episodes — never scored — with their errors, under a banner), holds the metric tables overall
//! and per slice ([`html`]), one chart per slice axis with a panel per metric on one scale per
//! metric for the whole report, as inline SVG ([`charts`], also written as PNG), a gallery of
//! per-episode top-down maps — the semantic map with the reference path, the agent's path and
//! its collision points, the paper's figure of ground truth against agent trajectories
//! ([`maps`]) — a table of the episodes with their instructions, and, when asked
//! ([`ReportOptions::videos`]), episode videos: animated GIFs of the agent's view beside the
//! map, step by step ([`video`]). Everything is read back
//! from the run folder (`summary.json`, `episodes.jsonl`, `sage3d_run.json`) plus the scenes
//! and the instructions of the run's dataset, so a report can be regenerated at any time; the
//! same inputs give the same bytes.

pub mod charts;
pub mod escape;
pub mod html;
pub mod maps;
pub mod video;

use crate::folder::{RECORDS_FILE, REPORT_DIR, REPORT_FILE, SUMMARY_FILE};
use crate::records::EvalRecord;
use crate::summary::AXES;
use crate::summary::Summary;
use rayon::prelude::*;
use sage_core::{Error, Result, ResultExt};
use sage_env::{EnvConfig, SceneContext};
use sage_io::run::RUN_RECORD;
use sage_nav::{NavGrid, SemanticMap, TrajectoryParams};
use sage_scene::Scene;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// At most this many maps are embedded in the page; the others are linked by path.
pub const EMBEDDED_MAPS: usize = 60;

/// What a run folder holds, as the report reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFiles {
    /// `sage3d_run.json` (kept as JSON: the report shows it, it does not interpret it).
    pub run: serde_json::Value,
    /// `summary.json`.
    pub summary: Summary,
    /// `episodes.jsonl`, sorted by episode id.
    pub records: Vec<EvalRecord>,
}

/// What [`write()`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportOutcome {
    /// `RUN/report.html`.
    pub html: PathBuf,
    /// Chart PNGs written (one per slice axis).
    pub charts: usize,
    /// Map PNGs written (one per episode with a record).
    pub maps: usize,
    /// Maps embedded in the page (the others are linked).
    pub embedded: usize,
    /// Episode videos written (GIFs under `report/videos/`, shown by the page).
    pub videos: usize,
}

/// What a report makes besides its page, charts and maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReportOptions {
    /// Episode videos to write ([`video`]): one for each of this many first episodes of the
    /// gallery order ([`gallery_order`]; episodes with a record), all of them when the run
    /// has fewer; 0 writes none.
    pub videos: usize,
    /// The first-person view's size in the videos.
    pub video_size: video::VideoSize,
}

/// One image of an episode (its map PNG, or its video GIF): the record it shows and the
/// file's path relative to the run folder.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFile<'a> {
    /// The episode.
    pub record: &'a EvalRecord,
    /// `report/maps/{name}.png` (or `report/videos/{name}.gif`), with `/` separators (it is
    /// also the page's link).
    pub rel_path: String,
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| Error::io(path, e))
}

/// Reads a finished run folder: its run record, summary and episode records.
///
/// # Errors
///
/// A folder that is not an evaluation run ([`crate::folder::run_record`]: none, a dataset,
/// another command's) or whose writer did not finish it
/// ([`crate::folder::finished_run_record`]), a missing or unreadable file, a bad line of
/// `episodes.jsonl` (named by its line and field: [`EvalRecord::from_line`]), an episode
/// recorded twice, or a summary that does not count the records (an unfinished run): each
/// names the folder or file.
pub fn read_run(run_dir: &Path) -> Result<RunFiles> {
    read_files(run_dir, crate::folder::finished_run_record(run_dir)?)
}

/// [`read_run`] of the run folder its caller writes and has not marked finished yet (it
/// writes the report before it does).
///
/// # Errors
///
/// As [`read_run`], whatever the run record's status.
fn read_own_run(run_dir: &Path) -> Result<RunFiles> {
    read_files(run_dir, crate::folder::run_record(run_dir)?)
}

/// The summary and records of the run folder `run_dir`, whose run record is `run`.
fn read_files(run_dir: &Path, run: serde_json::Value) -> Result<RunFiles> {
    let summary_path = run_dir.join(SUMMARY_FILE);
    if !summary_path.is_file() {
        return Err(Error::invalid(
            "no summary.json: not a finished evaluation run (run `sage3d eval` into it first)",
        )
        .in_file(&summary_path));
    }
    let summary: Summary = serde_json::from_str(&read_text(&summary_path)?)
        .map_err(|e| Error::format(SUMMARY_FILE, e.to_string()).in_file(&summary_path))?;
    let records_path = run_dir.join(RECORDS_FILE);
    let mut records = Vec::new();
    let mut seen = BTreeSet::new();
    for (k, line) in read_text(&records_path)?.lines().enumerate() {
        let where_ = format!("line {}", k + 1);
        let rec = EvalRecord::from_line(line, &where_).in_file(&records_path)?;
        if !seen.insert(rec.episode_id.clone()) {
            return Err(Error::format(
                where_,
                format!("episode {} is recorded twice", rec.episode_id),
            )
            .in_file(&records_path));
        }
        records.push(rec);
    }
    if records.len() != summary.episodes {
        return Err(Error::invalid(format!(
            "summary.json counts {} episodes but {} holds {}: the run is unfinished (rerun the evaluation into the same run folder, `out`)",
            summary.episodes,
            RECORDS_FILE,
            records.len()
        ))
        .in_file(&summary_path));
    }
    records.sort_by(|a, b| a.episode_id.cmp(&b.episode_id));
    Ok(RunFiles {
        run,
        summary,
        records,
    })
}

/// True when the episode reached what it was asked: SR = 1 for a VLN episode, no collision
/// ending (and not leaving the scene) for a no-goal one.
pub fn succeeded(rec: &EvalRecord) -> bool {
    match &rec.metrics {
        Some(m) => match m.sr {
            Some(sr) => sr >= 1.0,
            None => !matches!(
                rec.termination,
                Some(sage_env::Termination::Collision | sage_env::Termination::LeftScene)
            ),
        },
        None => false,
    }
}

/// The file name of an episode's map: the episode id's file-name stem
/// ([`sage_io::names::stem`]: inside the maps folder, bounded in length, distinct per id).
pub fn map_file_name(episode_id: &str) -> String {
    format!("{}.png", sage_io::names::stem(episode_id))
}

/// The file name of an episode's video: the stem of its map's ([`map_file_name`]), `.gif`.
pub fn video_file_name(episode_id: &str) -> String {
    format!("{}.gif", sage_io::names::stem(episode_id))
}

/// The order of the gallery: unsuccessful episodes first, then by id.
pub fn gallery_order<'a>(maps: &[MapFile<'a>]) -> Vec<MapFile<'a>> {
    let mut order = maps.to_vec();
    order.sort_by(|a, b| {
        succeeded(a.record)
            .cmp(&succeeded(b.record))
            .then_with(|| a.record.episode_id.cmp(&b.record.episode_id))
    });
    order
}

/// The instruction of each episode of `split`, by id, from the split's episodes file in the
/// dataset the run record (`sage3d_run.json`) names.
///
/// # Errors
///
/// The record names no dataset, the split's file cannot be read, or it is not the file the run
/// was made from (its hash differs from the record's `dataset_hash`), so its texts may not be
/// the ones the agent was given.
pub fn read_instructions(run: &serde_json::Value, split: &str) -> Result<BTreeMap<String, String>> {
    let dataset = run
        .get("settings")
        .and_then(|s| s.get("dataset"))
        .and_then(|d| d.as_str())
        .ok_or_else(|| Error::invalid(format!("{RUN_RECORD} names no dataset")))?;
    let (file, episodes) = sage_dataset::folder::split_episodes(Path::new(dataset), split)?;
    if let Some(hash) = run.get("dataset_hash").and_then(|h| h.as_str()) {
        let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
        if sage_io::hash::fnv1a64_hex(&bytes) != hash {
            return Err(Error::invalid(
                "the episodes file changed since the run (its hash is not the run's dataset_hash)",
            )
            .in_file(&file));
        }
    }
    Ok(episodes
        .into_iter()
        .map(|e| (e.episode_id, e.instruction))
        .collect())
}

/// The grid and semantic map of a scene, as the evaluator's path finder sees it (the default
/// trajectory grid settings).
///
/// # Errors
///
/// The scene cannot be loaded or gridded.
pub fn scene_map(dir: &Path) -> Result<(NavGrid, SemanticMap)> {
    let (scene, _) = Scene::load(dir)?;
    let (grid, _) = NavGrid::from_scene(&scene, &TrajectoryParams::default().grid)?;
    Ok((grid, SemanticMap::build(&scene)))
}

/// Writes the report of the run in `run_dir` (see the module docs); the scenes are read from
/// `scenes_dir` (one scene folder or a folder of them, as for `sage3d eval`). When the run's
/// dataset cannot be read ([`read_instructions`]) the page says why instead of showing the
/// instructions.
///
/// # Errors
///
/// As [`write_with`].
pub fn write(run_dir: &Path, scenes_dir: &Path) -> Result<ReportOutcome> {
    write_with(run_dir, scenes_dir, &|_, _| {})
}

/// [`write()`], calling `on_map(episode_id, total)` after each episode map is drawn.
///
/// # Errors
///
/// As [`write_with_options`].
pub fn write_with(
    run_dir: &Path,
    scenes_dir: &Path,
    on_map: &(dyn Fn(&str, usize) + Sync),
) -> Result<ReportOutcome> {
    write_with_options(
        run_dir,
        scenes_dir,
        &ReportOptions::default(),
        on_map,
        &|_, _| {},
    )
}

/// [`write_with`] with `options`: the episode videos it asks for are written too, calling
/// `on_video(episode_id, total)` after each.
///
/// Every file is written atomically, the images first and the page last, so a page on disk
/// always shows complete images. Once the page is written, the videos an earlier report wrote
/// that this one does not show are removed: the GIFs under `report/videos/` named for an
/// episode of the run ([`video_file_name`]); any other file there is left as it is.
///
/// # Errors
///
/// A bad run folder ([`read_run`]), a scene of a record that is not among the scenes or cannot
/// be loaded, a run record without the environment (or, recorded before it was, the preset)
/// the videos are rendered with, a video that cannot be made, or a write error.
pub fn write_with_options(
    run_dir: &Path,
    scenes_dir: &Path,
    options: &ReportOptions,
    on_map: &(dyn Fn(&str, usize) + Sync),
    on_video: &(dyn Fn(&str, usize) + Sync),
) -> Result<ReportOutcome> {
    write_files(
        run_dir,
        read_run(run_dir)?,
        scenes_dir,
        options,
        on_map,
        on_video,
    )
}

/// The report a command writes of the run folder it writes (an evaluation, a rescoring, a
/// merge of shards) as its last output, before it marks the run finished: the run's
/// [`ReportOptions`] and where its scenes are, with the callbacks of [`write_with_options`].
#[derive(Clone, Copy)]
pub struct ReportJob<'a> {
    /// One scene folder or a folder of them, as for [`write_with_options`].
    pub scenes: &'a Path,
    /// The videos to write.
    pub options: ReportOptions,
    /// Called after each map: its episode id and the maps in all.
    pub on_map: &'a (dyn Fn(&str, usize) + Sync),
    /// Called after each video: its episode id and the videos in all.
    pub on_video: &'a (dyn Fn(&str, usize) + Sync),
}

impl<'a> ReportJob<'a> {
    /// The report of the run with its scenes in `scenes`: no videos, no callbacks.
    pub fn new(scenes: &'a Path) -> ReportJob<'a> {
        ReportJob {
            scenes,
            options: ReportOptions::default(),
            on_map: &|_, _| {},
            on_video: &|_, _| {},
        }
    }

    /// Writes the report of the run its caller has written into `run_dir` (its run record
    /// still marked unfinished), then marks the run finished
    /// ([`crate::folder::mark_finished`]).
    pub(crate) fn finish(&self, run_dir: &Path) -> Result<ReportOutcome> {
        let outcome = write_files(
            run_dir,
            read_own_run(run_dir)?,
            self.scenes,
            &self.options,
            self.on_map,
            self.on_video,
        )?;
        crate::folder::mark_finished(run_dir)?;
        Ok(outcome)
    }
}

/// [`write_with_options`] of the run `files` read from `run_dir`.
fn write_files(
    run_dir: &Path,
    files: RunFiles,
    scenes_dir: &Path,
    options: &ReportOptions,
    on_map: &(dyn Fn(&str, usize) + Sync),
    on_video: &(dyn Fn(&str, usize) + Sync),
) -> Result<ReportOutcome> {
    let drawn: Vec<&EvalRecord> = files
        .records
        .iter()
        .filter(|r| r.record.is_some())
        .collect();
    let mut by_scene: BTreeMap<&str, Vec<&EvalRecord>> = BTreeMap::new();
    for r in &drawn {
        by_scene.entry(r.scene.as_str()).or_default().push(r);
    }
    let dirs: BTreeMap<String, PathBuf> = if by_scene.is_empty() {
        BTreeMap::new()
    } else {
        sage_io::scenes::scene_dirs_by_name(scenes_dir)?
    };
    if let Some(scene) = by_scene.keys().find(|s| !dirs.contains_key(**s)) {
        return Err(Error::invalid(format!(
            "scene '{scene}' of the run's episodes is not among the scenes"
        ))
        .in_file(scenes_dir));
    }
    sage_io::names::distinct_stems("episode", drawn.iter().map(|r| r.episode_id.as_str()))?;
    let report_dir = run_dir.join(REPORT_DIR);
    let maps_dir = report_dir.join(maps::MAPS_DIR);
    std::fs::create_dir_all(&maps_dir).map_err(|e| Error::io(&maps_dir, e))?;

    let total = drawn.len();
    let scene_maps: Vec<Vec<MapFile>> = by_scene
        .par_iter()
        .map(|(scene, recs)| {
            let (grid, map) = scene_map(&dirs[*scene]).within(format!("scene {scene}"))?;
            recs.par_iter()
                .map(|r| {
                    let name = map_file_name(&r.episode_id);
                    maps::episode_map(&map, &grid, r).save_png(&maps_dir.join(&name))?;
                    on_map(&r.episode_id, total);
                    Ok(MapFile {
                        record: r,
                        rel_path: format!("{REPORT_DIR}/{}/{name}", maps::MAPS_DIR),
                    })
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    let mut map_files: Vec<MapFile> = scene_maps.into_iter().flatten().collect();
    map_files.sort_by(|a, b| a.record.episode_id.cmp(&b.record.episode_id));

    let scale_ends = charts::scale_ends(&files.summary);
    let mut chart_list = Vec::new();
    for axis in AXES {
        let Some(slices) = files.summary.slices.get(axis).filter(|s| !s.is_empty()) else {
            continue;
        };
        let chart = charts::slice_chart(axis, slices, &scale_ends);
        let rel = format!("{REPORT_DIR}/chart_{axis}.png");
        chart.to_canvas().save_png(&run_dir.join(&rel))?;
        chart_list.push((axis, chart, rel));
    }

    let gallery = gallery_order(&map_files);
    let embedded = gallery.len().min(EMBEDDED_MAPS);
    let instructions = read_instructions(&files.run, &files.summary.split);
    let chosen: Vec<&EvalRecord> = gallery
        .iter()
        .take(options.videos)
        .map(|m| m.record)
        .collect();
    let videos = write_videos(
        run_dir,
        &files.run,
        &dirs,
        &chosen,
        &instructions,
        options.video_size,
        on_video,
    )?;
    let page = html::page(&html::PageInput {
        run_dir,
        files: &files,
        charts: &chart_list,
        gallery: &gallery,
        embed: embedded,
        scale_ends: &scale_ends,
        instructions: &instructions,
        videos: &videos,
    })?;
    let html_path = run_dir.join(REPORT_FILE);
    sage_io::files::write_atomic(&html_path, |w| {
        std::io::Write::write_all(w, page.as_bytes())
    })?;
    remove_stale_videos(run_dir, &files.records, &chosen)?;
    Ok(ReportOutcome {
        html: html_path,
        charts: chart_list.len(),
        maps: map_files.len(),
        embedded,
        videos: videos.len(),
    })
}

/// Removes from `RUN/report/videos/` the videos an earlier report wrote that this one, which
/// shows those of `shown`, does not: the GIFs named for an episode of `records`
/// ([`video_file_name`]) other than those shown. Nothing else in the folder is touched (a
/// file of the user's, another name); the folder goes once it is empty. Called after the page
/// is written, so a page on disk never links a video that is gone.
///
/// # Errors
///
/// A video that cannot be removed, naming it.
fn remove_stale_videos(
    run_dir: &Path,
    records: &[EvalRecord],
    shown: &[&EvalRecord],
) -> Result<()> {
    let videos_dir = run_dir.join(REPORT_DIR).join(video::VIDEOS_DIR);
    if !videos_dir.is_dir() {
        return Ok(());
    }
    let kept: BTreeSet<String> = shown
        .iter()
        .map(|r| video_file_name(&r.episode_id))
        .collect();
    for name in records.iter().map(|r| video_file_name(&r.episode_id)) {
        let path = videos_dir.join(&name);
        if !kept.contains(&name) && path.is_file() {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    // Only an empty folder is removed; one holding other files stays as it is.
    let _ = std::fs::remove_dir(&videos_dir);
    Ok(())
}

/// The environment of the run record `run` (its parsed `sage3d_run.json`), whose agent camera
/// and profile the videos and the viewer show:
/// its `env`, the environment the run's episodes ran in (overrides of a Python run included);
/// for a run recorded before the environment was, the preset its settings name
/// (`settings.preset`, the only field read then, so runs of agents this build cannot name get
/// videos too). Rendered on the CPU whatever the run used.
///
/// # Errors
///
/// An `env` that is not an environment config or one the validation refuses, or (without
/// `env`) no preset or an unknown one, naming the run record's field.
pub fn run_env(run: &serde_json::Value) -> Result<EnvConfig> {
    let config = match run.get("env") {
        Some(env) => {
            let config: EnvConfig = serde_json::from_value(env.clone())
                .map_err(|e| Error::format(format!("{RUN_RECORD}: env"), e.to_string()))?;
            config.validate().within(format!("{RUN_RECORD}: env"))?;
            config
        }
        None => {
            let preset = run
                .get("settings")
                .and_then(|s| s.get("preset"))
                .and_then(|p| p.as_str())
                .ok_or_else(|| Error::invalid(format!("{RUN_RECORD} has no settings.preset")))?;
            EnvConfig::preset(preset).within(format!("{RUN_RECORD}: settings.preset"))?
        }
    };
    // The CPU renderer: its frames do not depend on the machine or the thread count, so a
    // report's videos are the same bytes wherever it is written.
    Ok(EnvConfig {
        device: sage_splat::Device::Cpu,
        ..config
    })
}

/// Writes the videos of `chosen` under `RUN/report/videos/` ([`video::episode_gif`]), loading
/// each scene once, and returns them in `chosen`'s order.
fn write_videos<'a>(
    run_dir: &Path,
    run: &serde_json::Value,
    dirs: &BTreeMap<String, PathBuf>,
    chosen: &[&'a EvalRecord],
    instructions: &Result<BTreeMap<String, String>>,
    size: video::VideoSize,
    on_video: &(dyn Fn(&str, usize) + Sync),
) -> Result<Vec<MapFile<'a>>> {
    if chosen.is_empty() {
        return Ok(Vec::new());
    }
    let config = run_env(run)?;
    let videos_dir = run_dir.join(REPORT_DIR).join(video::VIDEOS_DIR);
    std::fs::create_dir_all(&videos_dir).map_err(|e| Error::io(&videos_dir, e))?;
    let instruction = |id: &str| match instructions {
        Ok(texts) => texts.get(id).map_or("", String::as_str),
        Err(_) => "(instruction unavailable: see the report's episode table)",
    };
    let mut by_scene: BTreeMap<&str, Vec<&EvalRecord>> = BTreeMap::new();
    for r in chosen {
        by_scene.entry(r.scene.as_str()).or_default().push(r);
    }
    let total = chosen.len();
    // One scene in memory at a time (a scene context holds its Gaussians and physics); its
    // episodes in parallel, each in an environment of its own.
    for (scene, recs) in &by_scene {
        let ctx = SceneContext::load(&dirs[*scene], None).within(format!("scene {scene}"))?;
        recs.par_iter()
            .map(|r| {
                let bytes = video::episode_gif(
                    &ctx,
                    &config,
                    &ctx.semantic,
                    &ctx.pathfinder.grid,
                    r,
                    instruction(&r.episode_id),
                    size,
                )
                .within(format!("episode {}", r.episode_id))?;
                let path = videos_dir.join(video_file_name(&r.episode_id));
                sage_io::files::write_atomic(&path, |w| std::io::Write::write_all(w, &bytes))?;
                on_video(&r.episode_id, total);
                Ok(())
            })
            .collect::<Result<Vec<()>>>()?;
    }
    Ok(chosen
        .iter()
        .map(|r| MapFile {
            record: r,
            rel_path: format!(
                "{REPORT_DIR}/{}/{}",
                video::VIDEOS_DIR,
                video_file_name(&r.episode_id)
            ),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_dataset::Task;
    use sage_dataset::slices::Slices;
    use sage_lang::InstructionType;
    use sage_metrics::EpisodeMetrics;

    fn rec(id: &str, sr: Option<f64>, termination: sage_env::Termination) -> EvalRecord {
        EvalRecord {
            episode_id: id.into(),
            scene: "home1".into(),
            task: if sr.is_some() {
                Task::Vln
            } else {
                Task::Nogoal
            },
            level: None,
            instruction_type: InstructionType::SingleGoal,
            slices: Slices {
                assets: "few".into(),
                path: "short".into(),
            },
            agent: "random".into(),
            termination: Some(termination),
            metrics: Some(EpisodeMetrics {
                sr,
                ..EpisodeMetrics::default()
            }),
            error: None,
            failure: None,
            faults: Vec::new(),
            notes: Vec::new(),
            record: None,
            bodies: Default::default(),
        }
    }

    #[test]
    fn gallery_puts_unsuccessful_episodes_first_then_orders_by_id() {
        use sage_env::Termination::{Collision, MaxSteps, Stop, TimeLimit};
        let recs = [
            rec("a", Some(1.0), Stop),
            rec("b", Some(0.0), Stop),
            rec("c", None, Collision),
            rec("d", None, TimeLimit),
            rec("e", Some(0.0), MaxSteps),
        ];
        let maps: Vec<MapFile> = recs
            .iter()
            .map(|r| MapFile {
                record: r,
                rel_path: r.episode_id.clone(),
            })
            .collect();
        let order: Vec<&str> = gallery_order(&maps)
            .iter()
            .map(|m| m.record.episode_id.as_str())
            .collect();
        assert_eq!(order, ["b", "c", "e", "a", "d"]);
    }

    #[test]
    fn map_file_names_are_safe_and_distinct() {
        assert_eq!(map_file_name("home1-t3-2"), "home1-t3-2.png");
        let long = "e".repeat(300);
        let odd = ["a/b", "a?b", "a_b", ".hidden", "../x", "r.1", "r_1", &long];
        let names: BTreeSet<String> = odd.iter().map(|id| map_file_name(id)).collect();
        assert_eq!(names.len(), odd.len());
        for n in &names {
            assert!(
                !n.starts_with('.') && !n.contains('/') && n.len() < 160,
                "{n}"
            );
        }
    }
}
