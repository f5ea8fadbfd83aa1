//! `sage3d data …`: benchmark datasets (instructions, episodes, splits, files).

use clap::{Args, Subcommand};
use sage_bench::dataset::build::{AssembleParams, SceneParams};
use sage_core::Result;
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
}

pub fn run(cmd: DataCommand) -> Result<()> {
    match cmd {
        DataCommand::Build(a) => data_build(a),
    }
}

fn data_build(a: BuildArgs) -> Result<()> {
    let mut params = SceneParams::new(a.per_scene, a.seed);
    if let Some(b) = a.base_actions {
        params.base_actions = b;
    }
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
    let report = sage_pipeline::dataset::build(&a.scenes, &a.out, &params, &assemble, &|o, n| {
        bar.set_length(n as u64);
        bar.set_message(o.scene.clone());
        bar.inc(1);
    });
    bar.finish_and_clear();
    print_dataset(&report?, &a.out, start.elapsed().as_secs_f64());
    Ok(())
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
