//! `sage3d env run` (drive one episode with a baseline agent, one JSON line per step, then its
//! metrics) and `sage3d bench env` (environment steps per second with and without rendering).
//!
//! Dataset episodes become environment episodes, and traces metric records, through
//! `sage_bench::eval::convert`, as in the evaluator.

use crate::machine;
use clap::{Args, Subcommand};
use sage_bench::agents::AgentKind;
use sage_core::{Error, Result};
use sage_env::agents::{Agent, RandomAgent, run_episode};
use sage_env::{Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig};
use sage_metrics::Mode;
use sage_nav::{GridParams, TrajectoryParams};
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_synth::{SceneKind, SynthConfig};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    /// Agent: oracle, forward or random.
    #[arg(long, default_value = "oracle")]
    agent: String,
    /// Seed of the random agent.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Environment preset: sage or vlnce.
    #[arg(long, default_value = "sage")]
    preset: String,
    /// Metric mode: sage, vlnce or sage-official.
    #[arg(long, default_value = "sage")]
    mode: String,
    /// Render the preset's images at every step, as an agent receiving them would (they are
    /// not written; without this flag the run is blind, which the baselines do not need).
    #[arg(long)]
    render: bool,
    /// Hull cache folder (default: beside the scene).
    #[arg(long)]
    cache: Option<PathBuf>,
}

pub fn run(cmd: EnvCommand) -> Result<()> {
    match cmd {
        EnvCommand::Run(a) => run_one(a),
    }
}

fn run_one(a: RunArgs) -> Result<()> {
    let mode: Mode = a.mode.parse().map_err(|e: Error| e.within("--mode"))?;
    let mut config = EnvConfig::preset(&a.preset).map_err(|e| e.within("--preset"))?;
    if !a.render {
        config.sensors = SensorConfig {
            rgb: false,
            depth: false,
            semantic: false,
            instance: false,
            ..config.sensors
        };
    }
    let mut agent = a
        .agent
        .parse::<AgentKind>()
        .map_err(|e| e.within(format!("--agent '{}'", a.agent)))?
        .build(a.seed)?;
    let ctx = Arc::new(SceneContext::load(&a.scene, a.cache)?);
    let episodes = sage_bench::dataset::formats::jsonl::read(&a.episodes)?;
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
    let m = sage_metrics::evaluate(&sage_env::scoring::metric_record(&ctx, &trace), mode)?;
    println!(
        "{}",
        json(&serde_json::json!({
            "episode": trace.episode.id,
            "agent": agent.name(),
            "termination": trace.termination,
            "mode": mode,
            "metrics": m,
        }))?
    );
    Ok(())
}

fn json(v: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string(v).map_err(|e| Error::invalid(e.to_string()))
}

#[derive(Args)]
pub struct EnvBenchArgs {
    /// Objects in the generated home.
    #[arg(long, default_value_t = 200)]
    objects: usize,
    /// Gaussians in the generated home.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Seed of the scene, the episodes and the random agent.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Steps without rendering.
    #[arg(long, default_value_t = 20_000)]
    steps: usize,
    /// Steps per rendered resolution.
    #[arg(long, default_value_t = 200)]
    render_steps: usize,
    /// Resolutions as WxH (RGB + depth each).
    #[arg(long, value_delimiter = ',', default_value = "224x224,640x480")]
    sizes: Vec<String>,
    /// Hull cache folder.
    #[arg(long)]
    cache: Option<PathBuf>,
}

/// What [`measure`] found.
struct Rate {
    /// Steps per second of `act` + `step` (physics, trace, observation, rendering when set).
    steps_per_s: f64,
    /// Episode resets done.
    resets: usize,
    /// Mean milliseconds per reset (fresh physics world, first observation).
    reset_ms: f64,
}

/// Runs `steps` steps of a seeded random agent over the episodes, cycling them; steps and
/// resets are timed apart.
fn measure(
    ctx: &Arc<SceneContext>,
    config: EnvConfig,
    episodes: &[EnvEpisode],
    steps: usize,
    seed: u64,
) -> Result<Rate> {
    let mut env = Env::new(ctx.clone(), config)?;
    let mut agent = RandomAgent::new(seed, 0.0)?;
    let (mut done, mut resets) = (0, 0);
    let (mut stepping, mut resetting) = (Duration::ZERO, Duration::ZERO);
    'outer: for e in episodes.iter().cycle() {
        let t0 = Instant::now();
        let mut obs = env.reset(e)?;
        agent.reset(&env, e)?;
        resetting += t0.elapsed();
        resets += 1;
        while !env.done() {
            let t0 = Instant::now();
            obs = env.step(agent.act(&obs)?)?.0;
            stepping += t0.elapsed();
            done += 1;
            if done == steps {
                break 'outer;
            }
        }
    }
    Ok(Rate {
        steps_per_s: done as f64 / stepping.as_secs_f64(),
        resets,
        reset_ms: resetting.as_secs_f64() * 1e3 / resets as f64,
    })
}

pub fn bench(a: EnvBenchArgs) -> Result<()> {
    let sizes = a
        .sizes
        .iter()
        .map(|s| crate::bench::parse_size(s))
        .collect::<Result<Vec<_>>>()?;
    let config = SynthConfig {
        seed: a.seed,
        kind: SceneKind::Home,
        rooms: (a.objects / 14).clamp(1, 64),
        objects: a.objects,
        gaussians: a.gaussians,
        ..SynthConfig::default()
    };
    eprintln!(
        "generating a {}-object home of {} Gaussians …",
        a.objects, a.gaussians
    );
    let scene = sage_synth::generate(&config)?;
    let cache = HullCache::new(
        a.cache
            .unwrap_or_else(|| std::env::temp_dir().join("sage3d-bench-env-hulls")),
    );
    let (bodies, report) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
    let params = TrajectoryParams {
        count: 16,
        seed: a.seed,
        ..TrajectoryParams::default()
    };
    let prep = sage_nav::trajectory::prepare(&scene, &params)?;
    let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params)?;
    let episodes: Vec<EnvEpisode> = set
        .trajectories
        .iter()
        .map(|t| EnvEpisode::from_trajectory(format!("t{}", t.id), t, "go to the goal"))
        .collect();
    if episodes.is_empty() {
        return Err(Error::invalid(
            "the generated home has no trajectory to run",
        ));
    }
    let (name, objects, gaussians) = (
        scene.name.clone(),
        scene.objects.len(),
        scene.gaussians.len(),
    );
    let ctx = Arc::new(SceneContext::new(
        scene,
        bodies,
        &GridParams::default(),
        params.cost.clone(),
    )?);
    let blind = EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    };
    println!("machine          {}", machine::describe());
    println!(
        "scene            {name} ({objects} objects, {gaussians} Gaussians; {} collision parts, bodies in {:.2} s)",
        report.parts, report.seconds
    );
    println!(
        "episodes         {} planned trajectories, cycled; seeded random agent (forward / left / right), 500-step limit",
        episodes.len()
    );
    let r = measure(&ctx, blind, &episodes, a.steps, a.seed)?;
    println!(
        "no rendering     {:.0} steps/s ({:.2} µs per step; {} steps); reset {:.2} ms ({} resets)",
        r.steps_per_s,
        1e6 / r.steps_per_s,
        a.steps,
        r.reset_ms,
        r.resets
    );
    for (w, h) in sizes {
        let cfg = EnvConfig {
            sensors: SensorConfig {
                width: w,
                height: h,
                ..SensorConfig::default()
            },
            ..EnvConfig::default()
        };
        let r = measure(&ctx, cfg, &episodes, a.render_steps, a.seed)?;
        println!(
            "{:<16} {:.1} steps/s ({:.1} ms per step; RGB + depth, HFOV 90, {} steps); reset {:.1} ms",
            format!("{w}x{h}"),
            r.steps_per_s,
            1e3 / r.steps_per_s,
            a.render_steps,
            r.reset_ms
        );
    }
    Ok(())
}
