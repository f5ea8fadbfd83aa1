//! `sage3d data …`: benchmark datasets (instructions, episodes, splits, files).

use clap::{Args, Subcommand};
use sage_core::Result;
use sage_dataset::build::{AssembleParams, SceneParams};
use sage_io::runner::{Status, Tally};
use sage_lang::llm::LlmConfig;
use sage_pipeline::dataset::DatasetReport;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum DataCommand {
    /// Build a dataset over a folder of scenes: trajectories, instructions (grammar or LLM),
    /// episodes, splits, JSONL / GVLN / R2R-VLNCE files and a summary (parallel, resumable).
    Build(BuildArgs),
    /// Render a training set from a dataset split: each trajectory cut into a preset's
    /// discrete actions, walked through physics, a frame rendered before every action, written
    /// as NaVILA annotations, WebDataset shards or a folder tree (parallel, resumable).
    Render(RenderArgs),
    /// Read episodes from a SAGE-Bench GVLN file or an R2R-VLNCE split into a dataset folder's
    /// split (DATASET/episodes/SPLIT.jsonl, listed in DATASET/splits.json), for `eval` and
    /// `data render`.
    Import(ImportArgs),
}

#[derive(Args)]
pub struct ImportArgs {
    /// A GVLN JSON file, or an R2R-VLNCE folder (with --r2r-split).
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
    /// The dataset folder (made by `sage3d data build`: episodes/{split}.jsonl).
    dataset: PathBuf,
    /// A scene folder, or a folder of scene folders, holding the dataset's scenes (default: the
    /// scenes folder the dataset was built from, as its sage3d_run.json records it).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// Output folder (new or empty; rerun with the same settings to resume).
    #[arg(long)]
    out: PathBuf,
    /// The split to render (one of those DATASET/splits.json lists).
    #[arg(long, default_value = "train")]
    split: String,
    /// Action preset: vlnce (0.25 m, 15°), navila_small (0.35 m, 30°), navila_large
    /// (0.75 m, 15°), custom_small (0.50 m, 30°).
    #[arg(long, default_value = "navila_small")]
    preset: String,
    /// MOVE_FORWARD distance in metres (overrides the preset's).
    #[arg(long)]
    step: Option<f32>,
    /// Turn angle in degrees (overrides the preset's).
    #[arg(long)]
    turn: Option<f32>,
    /// Motions per trajectory at most; past it the walk calls STOP where it stands.
    #[arg(long, default_value_t = sage_traindata::preset::DEFAULT_MAX_ACTIONS)]
    max_actions: usize,
    /// Image width in pixels (the published pipeline rendered 1024×768).
    #[arg(long, default_value_t = 224)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 224)]
    height: u32,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 90.0)]
    hfov: f32,
    /// Images per frame: rgb[,depth,semantic,instance] (depth: 16-bit PNG millimetres).
    #[arg(long, default_value = "rgb")]
    sensors: String,
    /// Output layout: navila, webdataset or frames.
    #[arg(long, default_value = "navila")]
    format: String,
    /// Samples per NaVILA part (default 10000), episodes per WebDataset shard (default 100).
    #[arg(long)]
    shard_size: Option<usize>,
    /// Render only the first N goal-directed episodes of the split.
    #[arg(long)]
    limit: Option<usize>,
    /// Seed of the NaVILA sample shuffle.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Agent profile (camera height, body radius): wheeled, go2, g1 or h1.
    #[arg(long, default_value = "wheeled")]
    agent: String,
    /// RGB file type: jpg or png.
    #[arg(long, default_value = "jpg")]
    image: String,
    /// JPEG quality (1–100).
    #[arg(long, default_value_t = 90)]
    jpeg_quality: u8,
    /// Keep episodes whose walk collided or ended farther than 1 m from the goal (dropped by
    /// default; counted either way).
    #[arg(long)]
    keep_failed: bool,
    /// Write preview.gif of the first N kept episodes (frames with instruction and action,
    /// beside the top-down map with the pose).
    #[arg(long, default_value_t = 0)]
    preview: usize,
    /// Replace another render's output in --out (files a render did not write are never
    /// touched).
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
}

#[derive(Args)]
pub struct BuildArgs {
    /// A scene folder, or a folder of scene folders.
    scenes: PathBuf,
    /// Output dataset folder.
    #[arg(long)]
    out: PathBuf,
    /// Trajectories per scene (each gives a Single-Goal and up to five high-level episodes).
    #[arg(long, default_value_t = 20)]
    per_scene: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Ground agent profile the reference paths are planned for (wheeled, go2, g1, h1): its
    /// radius is the planner's inflation, so the paths leave that robot room to pass.
    #[arg(long, default_value = "wheeled")]
    agent: String,
    /// Shares of short / medium / long reference paths (SPEC §9 bins), e.g. 0.4,0.4,0.2
    /// (default: free). A scene without room for a bin's share yields fewer trajectories.
    #[arg(long, value_delimiter = ',')]
    length_mix: Option<Vec<f32>>,
    /// Base-Action episodes per scene (default: a quarter of --per-scene).
    #[arg(long)]
    base_actions: Option<usize>,
    /// No-goal episodes per scene.
    #[arg(long, default_value_t = 1)]
    nogoal: usize,
    /// High-level instructions kept per type and trajectory.
    #[arg(long, default_value_t = 1)]
    high_per_type: usize,
    /// Size of the balanced test selection (0: none).
    #[arg(long, default_value_t = 1000)]
    balanced: usize,
    /// Share of scenes held out for the scene-unseen test set.
    #[arg(long, default_value_t = 0.15)]
    scene_unseen: f32,
    /// Share of scenes for validation.
    #[arg(long, default_value_t = 0.1)]
    val: f32,
    /// OpenAI-compatible base URL for high-level instructions (default: the offline grammar).
    #[arg(long)]
    llm_url: Option<String>,
    /// LLM model name.
    #[arg(long, default_value = "gpt-4o-mini")]
    llm_model: String,
    /// Environment variable holding the LLM API key.
    #[arg(long, default_value = "OPENAI_API_KEY")]
    llm_key_env: String,
    /// LLM requests in flight at most.
    #[arg(long, default_value_t = 4)]
    llm_concurrency: usize,
    /// LLM answer cache (default: OUT/llm_cache).
    #[arg(long)]
    llm_cache: Option<PathBuf>,
    /// Write into an output folder that holds other files (never replacing one of them).
    #[arg(long)]
    force: bool,
}

pub fn run(cmd: DataCommand) -> Result<()> {
    match cmd {
        DataCommand::Build(a) => data_build(a),
        DataCommand::Render(a) => data_render(a),
        DataCommand::Import(a) => data_import(a),
    }
}

fn data_build(a: BuildArgs) -> Result<()> {
    let mut params = SceneParams::new(a.per_scene, a.seed)
        .for_agent(&a.agent)
        .map_err(|e| e.within("--agent"))?;
    if let Some(b) = a.base_actions {
        params.base_actions = b;
    }
    params.trajectories.sampling.length_mix = a.length_mix.clone();
    params.nogoal = a.nogoal;
    params.high_per_type = a.high_per_type;
    params.llm = a.llm_url.as_ref().map(|url| LlmConfig {
        base_url: url.clone(),
        model: a.llm_model.clone(),
        api_key_env: a.llm_key_env.clone(),
        concurrency: a.llm_concurrency,
        cache_dir: Some(
            a.llm_cache
                .clone()
                .unwrap_or_else(|| a.out.join("llm_cache")),
        ),
        ..LlmConfig::default()
    });
    let assemble = AssembleParams::new(a.seed, a.balanced, a.scene_unseen, a.val);
    let bar = crate::progress::bar("{bar:30} {pos}/{len} scenes {elapsed} (eta {eta}) {msg}");
    let start = Instant::now();
    let report =
        sage_pipeline::dataset::build(&a.scenes, &a.out, &params, &assemble, a.force, &|o, n| {
            bar.set_length(n as u64);
            bar.set_message(o.scene.clone());
            bar.inc(1);
        });
    bar.finish_and_clear();
    print_dataset(&report?, &a.out, start.elapsed().as_secs_f64());
    Ok(())
}

fn data_import(a: ImportArgs) -> Result<()> {
    use sage_dataset::import::{Source, import};
    let source = match &a.r2r_split {
        Some(split) => Source::R2r {
            dir: a.source.clone(),
            split: split.clone(),
        },
        None => {
            let bad = || sage_core::Error::invalid(format!("--offset '{}' is not DX,DY", a.offset));
            let (x, y) = a.offset.split_once(',').ok_or_else(bad)?;
            let num = |v: &str| v.trim().parse::<f32>().map_err(|_| bad());
            Source::Gvln {
                file: a.source.clone(),
                offset: glam::Vec2::new(num(x)?, num(y)?),
            }
        }
    };
    let episodes = import(&source, &a.out, &a.split, a.force)?;
    let scenes: std::collections::BTreeSet<&str> =
        episodes.iter().map(|e| e.scene.as_str()).collect();
    println!(
        "{} episodes of {} scenes -> {}",
        episodes.len(),
        scenes.len(),
        a.out
            .join("episodes")
            .join(format!("{}.jsonl", a.split))
            .display()
    );
    Ok(())
}

fn render_settings(a: &RenderArgs) -> Result<sage_traindata::Settings> {
    sage_traindata::Options {
        split: a.split.clone(),
        preset: a.preset.clone(),
        step: a.step,
        turn: a.turn,
        max_actions: a.max_actions,
        width: a.width,
        height: a.height,
        hfov: a.hfov,
        sensors: a.sensors.clone(),
        format: a.format.clone(),
        shard_size: a.shard_size,
        limit: a.limit,
        seed: a.seed,
        agent: a.agent.clone(),
        image: a.image.clone(),
        jpeg_quality: a.jpeg_quality,
        keep_failed: a.keep_failed,
        preview: a.preview,
        device: a.device.device.to_string(),
        ..sage_traindata::Options::new(a.dataset.clone(), a.scenes.clone())
    }
    .settings()
}

fn data_render(a: RenderArgs) -> Result<()> {
    let settings = render_settings(&a)?;
    eprintln!("renderer: {}", a.device.probe()?);
    let bar = crate::progress::bar("{bar:30} {pos}/{len} walks {elapsed} (eta {eta}) {msg}");
    let start = Instant::now();
    let frames = std::sync::atomic::AtomicUsize::new(0);
    let plan = sage_traindata::Plan::new(&settings)?;
    bar.set_length(plan.route_count() as u64);
    let manifest = match sage_traindata::claim(&plan, &a.out, a.force)? {
        Some(done) => {
            println!("already complete: {}", a.out.display());
            done
        }
        None => {
            let on_route = |r: &sage_traindata::RouteDone| {
                let n = frames.fetch_add(r.frames, std::sync::atomic::Ordering::Relaxed) + r.frames;
                if let Some(e) = &r.error {
                    bar.suspend(|| eprintln!("skipped walk {}: {e}", r.route));
                }
                bar.set_message(format!(
                    "{n} frames, {:.1} frames/s",
                    n as f64 / start.elapsed().as_secs_f64().max(1e-9)
                ));
                bar.inc(1);
            };
            for scene in plan.scenes() {
                bar.set_message(format!("loading {scene}"));
                sage_traindata::render_scene(&plan, &scene, &a.out, &on_route)?;
            }
            bar.finish_and_clear();
            sage_traindata::finish(&plan, &a.out)?
        }
    };
    let rendered = frames.into_inner();
    let secs = start.elapsed().as_secs_f64();
    print_render(&manifest, &a.out, rendered, secs);
    if a.preview > 0 {
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

/// Prints what a training-data render did: skipped episodes with their reasons, the counts
/// and the rate.
pub fn print_render(m: &sage_traindata::Manifest, out: &Path, rendered: usize, secs: f64) {
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
        "{} episodes ({} walks): {} kept, {} dropped{}, {} skipped; {} ignored{}",
        c.episodes,
        c.routes,
        c.kept,
        c.dropped.values().sum::<usize>(),
        listed(&c.dropped),
        c.skipped,
        c.ignored.values().sum::<usize>(),
        listed(&c.ignored)
    );
    println!(
        "{} samples, {} frames; rendered {rendered} frames in {secs:.1} s ({:.1} frames/s on {} threads) -> {}",
        c.samples,
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
