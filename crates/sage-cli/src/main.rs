//! `sage3d`: the command-line tool of sage3d.
//!
//! Each subcommand is a thin edge over the library crates: it parses flags, calls one library
//! function, prints or writes the result. See `sage3d --help`.

mod bench;
mod data_cmd;
mod env_cmd;
mod eval_cmd;
mod machine;
mod nav_cmd;
mod physics_cmd;
mod render_cmd;
mod report_cmd;
mod scene_cmd;
mod splat_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// sage3d: executable 3D Gaussian Splatting scenes for vision-and-language navigation.
#[derive(Parser)]
#[command(name = "sage3d", version)]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the main job on the embedded default: synthesise a scene, render it, describe it.
    Demo(scene_cmd::DemoArgs),
    /// Scene folders: synthesise one, describe one.
    #[command(subcommand)]
    Scene(scene_cmd::SceneCommand),
    /// Render RGB, depth, instance and semantic images of a scene from a camera.
    Render(render_cmd::RenderArgs),
    /// 3DGS PLY files: convert between the standard and compressed layouts.
    #[command(subcommand)]
    Splat(splat_cmd::SplatCommand),
    /// Physics: collision bodies and their quality, the CoACD work list, driving an agent.
    #[command(subcommand)]
    Physics(physics_cmd::PhysicsCommand),
    /// Export a scene to another format (USDA for Isaac Sim / Omniverse).
    #[command(subcommand)]
    Export(physics_cmd::ExportCommand),
    /// Navigation: semantic top-down maps, occupancy grids, trajectories.
    #[command(subcommand)]
    Nav(nav_cmd::NavCommand),
    /// Benchmark datasets: instructions, episodes, splits and their files.
    #[command(subcommand)]
    Data(data_cmd::DataCommand),
    /// The executable environment: drive an episode with a baseline agent.
    #[command(subcommand)]
    Env(env_cmd::EnvCommand),
    /// Evaluate an agent on a dataset split: per-episode records, resumable, summary per slice.
    Eval(eval_cmd::EvalArgs),
    /// Write an evaluation run's report: report.html (tables, charts, trajectory maps) and PNGs.
    Report(report_cmd::ReportArgs),
    /// Benchmarks (SPEC §12): report figures beside the machine they ran on.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
    {
        eprintln!("error: cannot set up {n} threads: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Demo(a) => scene_cmd::demo(a),
        Command::Scene(c) => scene_cmd::run(c),
        Command::Render(a) => render_cmd::run(a),
        Command::Splat(c) => splat_cmd::run(c),
        Command::Physics(c) => physics_cmd::run(c),
        Command::Export(c) => physics_cmd::run_export(c),
        Command::Nav(c) => nav_cmd::run(c),
        Command::Data(c) => data_cmd::run(c),
        Command::Env(c) => env_cmd::run(c),
        Command::Eval(a) => eval_cmd::run(a),
        Command::Report(a) => report_cmd::run(a),
        Command::Bench(c) => bench::run(c),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
