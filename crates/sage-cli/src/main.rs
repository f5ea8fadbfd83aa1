//! `sage3d`: the command-line tool of sage3d.
//!
//! Each subcommand is a thin edge over the library crates: it parses flags, calls one library
//! function, prints or writes the result. See `sage3d --help`.

mod bench;
mod config;
mod data_cmd;
mod demo_cmd;
mod env_cmd;
mod eval_cmd;
mod flags;
mod nav_cmd;
mod physics_cmd;
mod progress;
mod recon_cmd;
mod render_cmd;
mod report_cmd;
mod scene_cmd;
mod splat_cmd;
mod view_cmd;

use clap::{Parser, Subcommand};
use std::ffi::OsString;
use std::process::ExitCode;

/// sage3d: executable 3D Gaussian Splatting scenes for vision-and-language navigation.
#[derive(Parser)]
#[command(name = "sage3d", version)]
struct Cli {
    /// Worker threads, 1-1024 (default: all cores).
    #[arg(long, global = true, value_parser = flags::count_in(1..=1024))]
    threads: Option<usize>,
    /// Settings from a TOML file: a table per subcommand (`[data.build]`, `[eval]`) of
    /// `flag = value`; flags given on the command line win.
    #[arg(long, global = true, value_name = "FILE.toml")]
    config: Option<std::path::PathBuf>,
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job on synthetic scenes, end to end: scenes, maps, physics, dataset, evaluation
    /// of the baseline agents, reports (each step printed as the subcommand it runs).
    Demo(demo_cmd::DemoArgs),
    /// Scene folders: synthesise one, describe one, draw its plan, import your own capture.
    #[command(subcommand)]
    Scene(scene_cmd::SceneCommand),
    /// Render RGB, depth, instance and semantic images of a scene from a camera.
    Render(render_cmd::RenderArgs),
    /// 3DGS files: convert between formats (reads PLY, compressed PLY, SPZ, SOG, glTF/GLB and
    /// .splat; writes PLY, compressed PLY and SPZ).
    #[command(subcommand)]
    Splat(splat_cmd::SplatCommand),
    /// Physics: collision bodies and their quality, the CoACD work list, driving an agent.
    #[command(subcommand)]
    Physics(physics_cmd::PhysicsCommand),
    /// Export a scene to another format (USDA for Isaac Sim / Omniverse).
    #[command(subcommand)]
    Export(physics_cmd::ExportCommand),
    /// Reconstruction: plan cameras over a mesh scene, render its views, export them for 3DGS
    /// training.
    #[command(subcommand)]
    Recon(recon_cmd::ReconCommand),
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
    /// Write an evaluation run's report: report.html (tables, charts, trajectory maps), PNGs and,
    /// with --videos N, episode GIFs; with --mode/--dtw and --out NEW, rescore the run in
    /// another metric mode into a new run folder.
    Report(report_cmd::ReportArgs),
    /// The browser viewer: a scene's map and first-person view, driving with the keyboard, an
    /// evaluation run's episodes step by step, human play of a dataset split scored like any
    /// agent (`--play RUN`).
    View(view_cmd::ViewArgs),
    /// Benchmarks (SPEC §12): report figures beside the machine they ran on.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

/// The command line, with the flags of `--config FILE.toml` added when it is given, and where
/// each added flag came from.
fn command_line() -> sage_core::Result<(Vec<OsString>, config::Origins)> {
    let raw: Vec<OsString> = std::env::args_os().collect();
    let text: Vec<String> = raw
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let Some(file) = config::config_path(&text) else {
        return Ok((raw, Vec::new()));
    };
    // Help and the version never run a command, so they need no config file: a missing or
    // broken one must not hide how to write it.
    if config::asks_for_help::<Cli>(&text) {
        return Ok((raw, Vec::new()));
    }
    let file = std::path::PathBuf::from(file);
    let toml = std::fs::read_to_string(&file).map_err(|e| sage_core::Error::io(&file, e))?;
    let path = config::subcommand_path::<Cli>(&text);
    let applied = config::apply::<Cli>(&toml, &file, &path, &text)?;
    for left_out in &applied.left_out {
        eprintln!("note: {left_out}");
    }
    Ok((applied.argv(&raw), applied.origins))
}

/// The parsed command line; clap's refusal of a flag the config file gave says where it came
/// from.
fn parse(argv: Vec<OsString>, origins: &[(String, String)]) -> Cli {
    Cli::try_parse_from(argv).unwrap_or_else(|e| {
        if let Some(clap::error::ContextValue::String(arg)) =
            e.get(clap::error::ContextKind::InvalidArg)
            && let Some(origin) = config::origin_of(origins, arg)
        {
            let _ = e.print();
            eprintln!("note: that value is {origin}");
            std::process::exit(e.exit_code());
        }
        e.exit()
    })
}

fn main() -> ExitCode {
    quiet_on_closed_pipe();
    let (cli, origins) = match command_line() {
        Ok((argv, origins)) => (parse(argv, &origins), origins),
        // A config file is part of the command line: what is wrong with it is a usage error,
        // as clap's are (exit status 2).
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
    {
        eprintln!("error: cannot set up {n} threads: {e}");
        return ExitCode::FAILURE;
    }
    match dispatch(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A file's content names the file's own fields, which are no flags.
            let message = match e.kind() {
                sage_core::ErrorKind::Format => e.to_string(),
                _ => flags::in_flags(&e.to_string()),
            };
            eprintln!("error: {message}");
            // The message names flags; one the config file gave was never typed.
            for (flag, origin) in config::named_in(&origins, &message) {
                eprintln!("note: {flag} is {origin}");
            }
            ExitCode::FAILURE
        }
    }
}

/// Restores SIGPIPE's default action, which Rust programs start with ignored: then a reader
/// that stops early (`sage3d … | head`) ends the command quietly, as it ends `cat`, instead of
/// a panic on the next print. Files are written before anything is printed about them, so the
/// command's outputs are complete.
fn quiet_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: called first in `main`, before any thread exists; setting a signal's action to
    // its default has no other precondition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn dispatch(command: Command) -> sage_core::Result<()> {
    match command {
        Command::Demo(a) => demo_cmd::run(a),
        Command::Scene(c) => scene_cmd::run(c),
        Command::Render(a) => render_cmd::run(a),
        Command::Splat(c) => splat_cmd::run(c),
        Command::Physics(c) => physics_cmd::run(c),
        Command::Export(c) => physics_cmd::run_export(c),
        Command::Recon(c) => recon_cmd::run(c),
        Command::Nav(c) => nav_cmd::run(c),
        Command::Data(c) => data_cmd::run(c),
        Command::Env(c) => env_cmd::run(c),
        Command::Eval(a) => eval_cmd::run(a),
        Command::Report(a) => report_cmd::run(a),
        Command::View(a) => view_cmd::run(a),
        Command::Bench(c) => bench::run(c),
    }
}
