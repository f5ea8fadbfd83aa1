//! `sage3d eval DATASET [--scenes SCENES] --agent A --out RUN`: run an agent over a dataset split
//! under a progress bar, resumably, print the summary tables and write the run's report
//! (`docs/evaluation.md`).

use crate::progress::bar;
use sage_core::{Error, Result};
use sage_eval::RunOutcome;
use sage_eval::report::ReportOutcome;
use sage_pipeline::evaluate::{Callbacks, EvalOptions};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags of `sage3d eval`.
#[derive(clap::Args)]
pub struct EvalArgs {
    /// Dataset folder (as `sage3d data build` writes it).
    dataset: PathBuf,
    /// Agent: random, forward, oracle; replay:FILE (JSONL of recorded actions or poses per
    /// episode); socket:HOST:PORT (SAGE socket protocol), http:URL (POST /vln_step) or
    /// chat:MODEL@BASE_URL (OpenAI-compatible; key from OPENAI_API_KEY), with options
    /// ?history=8&timeout=60&retries=3&quality=90&repeat=3 (chat also temperature=0.1,
    /// max_tokens=64; socket also server=navila|navid|mllm for the published SAGE-3D servers);
    /// ws:HOST:PORT (GN0 / openpi WebSocket policy server, ws:// only) with
    /// ?actions=8&state=0&format=auto&rotate=chunk_start&history_cap=auto&metadata=2&timeout=120&retries=3.
    /// A server's URL names the same agent (http://HOST:PORT is http:HOST:PORT, ws://HOST:PORT
    /// is ws:HOST:PORT). See docs/evaluation.md.
    #[arg(long)]
    agent: String,
    #[command(flatten)]
    options: EvalOptions,
    /// Run folder: episodes.jsonl, summary.json, sage3d_run.json, report.html; new, empty, or
    /// an evaluation's. Rerunning into it resumes.
    #[arg(long)]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Exit non-zero when any episode failed (without it: only when every episode failed).
    #[arg(long)]
    strict: bool,
}

/// Runs or resumes the evaluation and prints its tables.
pub fn run(a: EvalArgs) -> Result<()> {
    let agent = a
        .agent
        .parse()
        .map_err(|e: Error| e.within(format!("--agent '{}'", a.agent)))?;
    let settings = a.options.settings(&a.dataset, agent)?;
    // Agents that read no images run blind, yet a GPU that cannot be had is refused for them
    // too: a command line that works with one agent works with any.
    eprintln!("renderer: {}", crate::flags::probe(settings.device)?);
    let episodes = bar("{bar:30} {pos}/{len} episodes {elapsed} (eta {eta}) {msg}");
    let maps = bar("{bar:30} {pos}/{len} maps {elapsed} (eta {eta}) {msg}");
    let start = Instant::now();
    let result = sage_pipeline::evaluate::evaluate(
        &settings,
        &a.out,
        a.force,
        Callbacks {
            on_episode: &|rec, to_run| {
                episodes.set_length(to_run as u64);
                episodes.set_message(rec.episode_id.clone());
                episodes.inc(1);
            },
            on_map: &|id, total| {
                episodes.finish_and_clear();
                maps.set_length(total as u64);
                maps.set_message(id.to_string());
                maps.inc(1);
            },
        },
    );
    episodes.finish_and_clear();
    maps.finish_and_clear();
    let (outcome, report) = result?;
    print_eval(&outcome, &report, &a.out, start.elapsed().as_secs_f64());
    outcome.verdict(a.strict)
}

/// Prints an evaluation: the summary tables, a line of counts (`secs`: how long it took) and
/// where its report is.
pub fn print_eval(outcome: &RunOutcome, report: &ReportOutcome, out: &Path, secs: f64) {
    print!("{}", outcome.summary.table());
    println!(
        "{} episodes: {} already recorded, {} run now in {secs:.1} s on {} threads -> {}",
        outcome.total,
        outcome.resumed,
        outcome.ran,
        rayon::current_num_threads(),
        out.display()
    );
    println!("{}", crate::report_cmd::describe(report));
    if !outcome.scene_changes.is_empty() {
        eprintln!(
            "note: scene files changed since the dataset was built ({}): its goals and reference paths were planned on the files as they were; build the dataset again (`sage3d data build`) to score against the scenes as they are",
            outcome.scene_changes.join(", ")
        );
    }
}
