//! `sage3d eval DATASET --scenes SCENES --agent A --out RUN`: run an agent over a dataset split
//! under a progress bar, resumably, print the summary tables and write the run's report
//! (`docs/evaluation.md`).

use indicatif::{ProgressBar, ProgressStyle};
use sage_bench::eval::{self, EvalSettings};
use sage_core::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

/// Flags of `sage3d eval`.
#[derive(clap::Args)]
pub struct EvalArgs {
    /// Dataset folder (as `sage3d data build` writes it).
    dataset: PathBuf,
    /// One scene folder or a folder of scene folders, named as the episodes' scenes.
    #[arg(long)]
    scenes: PathBuf,
    /// Agent: random, forward, oracle; replay:FILE (JSONL of recorded actions or poses per
    /// episode); socket:HOST:PORT (SAGE socket protocol), http:URL (POST /vln_step) or
    /// chat:MODEL@BASE_URL (OpenAI-compatible; key from OPENAI_API_KEY), with options
    /// ?history=8&timeout=60&retries=3&quality=90&repeat=3 (chat also temperature=0.1,
    /// max_tokens=64). See docs/evaluation.md.
    #[arg(long)]
    agent: String,
    /// Dataset split (`DATASET/episodes/{split}.jsonl`).
    #[arg(long, default_value = "test_balanced")]
    split: String,
    /// Metric mode: sage, vlnce or sage-official.
    #[arg(long, default_value = "sage")]
    mode: String,
    /// Seed of the agent (each episode mixes in its id).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Environment preset: sage or vlnce.
    #[arg(long, default_value = "sage")]
    preset: String,
    /// Run folder: episodes.jsonl, summary.json, sage3d_run.json. Rerunning into it resumes.
    #[arg(long)]
    out: PathBuf,
}

/// Runs or resumes the evaluation and prints its tables.
pub fn run(a: EvalArgs) -> Result<()> {
    let settings = EvalSettings {
        dataset: a.dataset,
        scenes: a.scenes,
        split: a.split,
        agent: a
            .agent
            .parse()
            .map_err(|e: Error| e.within(format!("--agent '{}'", a.agent)))?,
        mode: a.mode.parse().map_err(|e: Error| e.within("--mode"))?,
        seed: a.seed,
        preset: a.preset,
    };
    let bar = ProgressBar::new(0).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} episodes {elapsed} (eta {eta}) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let outcome = eval::run(&settings, &a.out, &|rec, to_run| {
        bar.set_length(to_run as u64);
        bar.set_message(rec.episode_id.clone());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let outcome = outcome?;
    print!("{}", outcome.summary.table());
    println!(
        "{} episodes: {} already recorded, {} run now in {:.1} s on {} threads -> {}",
        outcome.total,
        outcome.resumed,
        outcome.ran,
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        a.out.display()
    );
    let report = crate::report_cmd::write_with_bar(&a.out, &settings.scenes)?;
    println!("{}", crate::report_cmd::describe(&report));
    Ok(())
}
