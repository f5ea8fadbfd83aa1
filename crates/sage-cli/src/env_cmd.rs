//! `sage3d env run`: drive one episode with a baseline agent, one JSON line per step, then its
//! metrics.
//!
//! Dataset episodes become environment episodes (`Episode::env_episode`) and traces are scored
//! by `sage_env::scoring`, as in the evaluator.

use clap::{Args, Subcommand};
use sage_agents::AgentKind;
use sage_core::{Error, Result};
use sage_env::agents::run_episode;
use sage_env::{Env, EnvConfig, SceneContext};
use sage_metrics::{Dtw, Mode, Scoring};
use sage_physics::SplatBodies;
use sage_scene::LoadOptions;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Subcommand)]
pub enum EnvCommand {
    /// Run one episode of a dataset in its scene with a baseline agent; print each step as a
    /// JSON line, then the episode's metrics.
    Run(RunArgs),
}

#[derive(Args)]
pub struct RunArgs {
    /// Scene folder.
    scene: PathBuf,
    /// Dataset episodes (JSONL, as `sage3d data build` writes them).
    #[arg(long)]
    episodes: PathBuf,
    /// Episode id (default: the first episode of this scene).
    #[arg(long)]
    episode: Option<String>,
    /// Agent: any of `sage3d eval --agent` (oracle, forward, random, replay:FILE,
    /// socket:HOST:PORT, …).
    #[arg(long, default_value = "oracle")]
    agent: String,
    /// Seed of the random agent.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Environment preset: sage, vlnce, gnbench, sage-harness (the published SAGE-Bench
    /// harness's camera, steps and step limit), or navila_small, navila_large or custom_small
    /// (sage moving with that training-data preset's steps).
    #[arg(long, default_value = "sage")]
    preset: String,
    /// Metric mode: sage, vlnce, sage-official or gnbench.
    #[arg(long, default_value_t = Mode::default())]
    mode: Mode,
    /// nDTW alignment: exact or fast (FastDTW, radius 1, as VLN-CE computes it).
    #[arg(long, default_value_t = Dtw::default())]
    dtw: Dtw,
    /// Render the preset's images at every step, as an agent receiving them would (they are
    /// not written; without this flag the run is blind, which the baselines do not need).
    #[arg(long)]
    render: bool,
    /// Hull cache folder (default: beside the scene).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Which objects get bodies recovered from their Gaussians, as `physics build
    /// --splat-bodies`: auto, always or never.
    #[arg(long, value_name = "auto|always|never", default_value_t = SplatBodies::default())]
    splat_bodies: SplatBodies,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
}

pub fn run(cmd: EnvCommand) -> Result<()> {
    match cmd {
        EnvCommand::Run(a) => run_one(a),
    }
}

fn run_one(a: RunArgs) -> Result<()> {
    let scoring = Scoring {
        mode: a.mode,
        dtw: a.dtw,
    };
    let mut config = EnvConfig::preset(&a.preset).map_err(|e| e.within("--preset"))?;
    config.device = a.device.device;
    config.splat_bodies = a.splat_bodies;
    if !a.render {
        config.sensors = config.sensors.without_images();
    }
    let mut agent = a
        .agent
        .parse::<AgentKind>()
        .map_err(|e| e.within(format!("--agent '{}'", a.agent)))?
        .build(a.seed)?;
    let renderer = a.device.probe()?;
    if a.render {
        eprintln!("renderer: {renderer}");
    } else {
        eprintln!("renderer: {renderer} (not used: without --render no images are rendered)");
    }
    let ctx = Arc::new(SceneContext::load_with_bodies(
        &a.scene,
        a.cache,
        &LoadOptions::default(),
        config.splat_bodies,
    )?);
    let episodes = sage_dataset::formats::jsonl::read(&a.episodes)?;
    let episode = episodes
        .iter()
        .find(|e| match &a.episode {
            Some(id) => &e.episode_id == id,
            None => e.scene == ctx.scene.name,
        })
        .ok_or_else(|| {
            Error::invalid(match &a.episode {
                Some(id) => format!("no episode '{id}'"),
                None => format!("no episode of scene {}", ctx.scene.name),
            })
            .in_file(&a.episodes)
        })?;
    if episode.scene != ctx.scene.name {
        return Err(Error::invalid(format!(
            "episode {} is in scene {}, not {}",
            episode.episode_id, episode.scene, ctx.scene.name
        )));
    }
    let mut env = Env::new(ctx.clone(), config)?;
    let trace = run_episode(&mut env, agent.as_mut(), &episode.env_episode())?;
    for s in &trace.steps {
        println!("{}", json(s)?);
    }
    let m = sage_metrics::evaluate(
        &sage_env::scoring::metric_record(&ctx, &trace, scoring.mode),
        scoring,
    )?;
    println!(
        "{}",
        json(&serde_json::json!({
            "episode": trace.episode.id,
            "agent": agent.name(),
            "termination": trace.termination,
            "mode": scoring.mode,
            "dtw": scoring.dtw,
            "metrics": m,
        }))?
    );
    Ok(())
}

fn json(v: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string(v).map_err(|e| Error::invalid(e.to_string()))
}
