//! `sage3d bench env`: environment steps per second with a seeded random agent, without
//! rendering and with RGB + depth at each resolution.

use crate::machine;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Result};
use sage_env::agents::{Agent, RandomAgent};
use sage_env::pool::Order;
use sage_env::{
    Action, Env, EnvConfig, EnvEpisode, Pool, PoolEpisode, SceneContext, SensorConfig, VecEnv,
};
use sage_metrics::Mode;
use sage_nav::{GridParams, TrajectoryParams};
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_splat::Device;
use serde::Serialize;
use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What `bench env` steps.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvSettings {
    /// Objects in the generated home.
    pub objects: usize,
    /// Gaussians in the generated home.
    pub gaussians: usize,
    /// Seed of the scene, the episodes and the random agent.
    pub seed: u64,
    /// Steps without rendering.
    pub steps: usize,
    /// Steps per rendered resolution.
    pub render_steps: usize,
    /// Resolutions, (width, height) (RGB + depth each).
    pub sizes: Vec<(u32, u32)>,
    /// Hull cache folder (`None`: a folder in the system temp dir, so repeated runs reuse it).
    pub cache: Option<PathBuf>,
    /// Where the images are rendered.
    pub device: Device,
    /// Sub-environments of the vector environment (0: not measured), stepped in lockstep
    /// with RGB + depth at the first size: on the GPU one batch per step.
    pub envs: usize,
}

impl Default for EnvSettings {
    fn default() -> Self {
        Self {
            objects: 200,
            gaussians: 1_000_000,
            seed: 1,
            steps: 20_000,
            render_steps: 200,
            sizes: vec![(224, 224), (640, 480)],
            cache: None,
            device: Device::Cpu,
            envs: 16,
        }
    }
}

/// What `bench env` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnvReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Scene name.
    pub scene: String,
    /// Objects in the scene.
    pub objects: usize,
    /// Gaussians in the scene.
    pub gaussians: usize,
    /// Convex collision parts.
    pub parts: usize,
    /// Seconds to build the collision bodies.
    pub bodies_s: f64,
    /// Planned trajectories run as episodes, cycled.
    pub episodes: usize,
    /// Steps without rendering.
    pub steps: usize,
    /// Their rate.
    pub blind: Rate,
    /// Steps per rendered resolution.
    pub render_steps: usize,
    /// One entry per resolution, in the order asked.
    pub rendered: Vec<SizedRate>,
    /// The renderer ([`sage_splat::Backend::describe`]).
    pub renderer: String,
    /// The vector environment's rate, when measured.
    pub vector: Option<VectorRate>,
}

/// A vector environment stepped in lockstep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VectorRate {
    /// Sub-environments.
    pub envs: usize,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Lockstep steps timed (each steps every sub-environment).
    pub batches: usize,
    /// Sub-environment steps per second (physics, rendering, observations; resets of ended
    /// episodes included).
    pub steps_per_s: f64,
    /// CPU renderers (sets of frame buffers) the scene's environments built between them: the
    /// most renders under way at once (0 when a GPU renders).
    pub cpu_renderers: usize,
    /// The process's resident memory after the vector environment's steps, bytes (where the
    /// OS tells it).
    pub resident_bytes: Option<u64>,
}

/// Steps and resets of one configuration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Rate {
    /// Steps per second of `act` + `step` (physics, trace, observation, rendering when set).
    pub steps_per_s: f64,
    /// Episode resets done.
    pub resets: usize,
    /// Mean milliseconds per reset (fresh physics world, first observation).
    pub reset_ms: f64,
}

/// The rate with RGB + depth at one resolution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SizedRate {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Steps and resets.
    pub rate: Rate,
}

impl fmt::Display for EnvReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            {} ({} objects, {} Gaussians; {} collision parts, bodies in {:.2} s)",
            self.scene, self.objects, self.gaussians, self.parts, self.bodies_s
        )?;
        writeln!(
            f,
            "episodes         {} planned trajectories, cycled; seeded random agent (forward / left / right), 500-step limit",
            self.episodes
        )?;
        let r = &self.blind;
        writeln!(
            f,
            "no rendering     {:.0} steps/s ({:.2} µs per step; {} steps); reset {:.2} ms ({} resets)",
            r.steps_per_s,
            1e6 / r.steps_per_s,
            self.steps,
            r.reset_ms,
            r.resets
        )?;
        writeln!(f, "renderer         {}", self.renderer)?;
        for s in &self.rendered {
            writeln!(
                f,
                "{:<16} {:.1} steps/s ({:.1} ms per step; RGB + depth, HFOV 90, {} steps); reset {:.1} ms",
                format!("{}x{}", s.width, s.height),
                s.rate.steps_per_s,
                1e3 / s.rate.steps_per_s,
                self.render_steps,
                s.rate.reset_ms
            )?;
        }
        if let Some(v) = &self.vector {
            writeln!(
                f,
                "vector env       {} envs at {}x{} RGB + depth: {:.1} steps/s ({} lockstep steps)",
                v.envs, v.width, v.height, v.steps_per_s, v.batches
            )?;
            if v.cpu_renderers > 0 {
                writeln!(
                    f,
                    "                 {} CPU renderers between the scene's environments (the most renders at once)",
                    v.cpu_renderers
                )?;
            }
            if let Some(bytes) = v.resident_bytes {
                writeln!(
                    f,
                    "resident         {:.0} MB: the whole process after the vector environment",
                    bytes as f64 / 1e6
                )?;
            }
        }
        Ok(())
    }
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

/// The default environment with RGB + depth of `width` × `height` rendered on `device`.
fn rgbd(width: u32, height: u32, device: Device) -> EnvConfig {
    EnvConfig {
        sensors: SensorConfig {
            width,
            height,
            ..SensorConfig::default()
        },
        device,
        ..EnvConfig::default()
    }
}

/// Steps `envs` sub-environments of a [`VecEnv`] over `episodes` in lockstep for `batches`
/// timed steps after a reset, each with a seeded random action (forward / left / right); a
/// sub-environment whose episode ended starts the next episode in its place.
fn measure_vector(
    ctx: &Arc<SceneContext>,
    config: EnvConfig,
    episodes: &[EnvEpisode],
    envs: usize,
    batches: usize,
    seed: u64,
) -> Result<f64> {
    let pool = Pool::new(
        vec![ctx.clone()],
        episodes
            .iter()
            .map(|e| PoolEpisode {
                scene: 0,
                scene_name: ctx.scene.name.clone(),
                episode: e.clone(),
            })
            .collect(),
    )?;
    let mut vector = VecEnv::new(envs, Arc::new(pool), config, Mode::default())?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut next = 0;
    let mut reset = || {
        next += 1;
        Order::Reset((next - 1) % episodes.len())
    };
    let mut transitions = vector.run((0..envs).map(|_| reset()).collect())?;
    let actions = [Action::MoveForward, Action::TurnLeft, Action::TurnRight];
    let start = Instant::now();
    for _ in 0..batches {
        let orders = transitions
            .iter()
            .map(|t| {
                if t.terminated || t.truncated {
                    reset()
                } else {
                    Order::Step(actions[rng.random_range(0..actions.len())])
                }
            })
            .collect();
        transitions = vector.run(orders)?;
    }
    Ok((envs * batches) as f64 / start.elapsed().as_secs_f64())
}

/// Runs `bench env`: a generated home with its collision bodies and 16 planned trajectories
/// as episodes, stepped blind, then with RGB + depth at each size.
///
/// # Errors
///
/// The scene, its bodies or its trajectories cannot be made, or the environment fails.
pub fn run(settings: &EnvSettings) -> Result<EnvReport> {
    let scene = crate::generated_home(settings.seed, settings.objects, settings.gaussians)?;
    let cache = HullCache::new(
        settings
            .cache
            .clone()
            .unwrap_or_else(|| std::env::temp_dir().join("sage3d-bench-env-hulls")),
    );
    let (bodies, report) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
    let params = TrajectoryParams {
        count: 16,
        seed: settings.seed,
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
        return Err(Error::invalid(format!(
            "the generated home of {} objects has no trajectory to run (its endpoints are \
             objects, rooms and areas: more `objects` or another `seed` gives some)",
            scene.objects.len()
        )));
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
        sensors: SensorConfig::default().without_images(),
        ..EnvConfig::default()
    };
    let machine = machine::describe();
    let blind = measure(&ctx, blind, &episodes, settings.steps, settings.seed)?;
    let mut rendered = Vec::with_capacity(settings.sizes.len());
    for &(width, height) in &settings.sizes {
        let rate = measure(
            &ctx,
            rgbd(width, height, settings.device),
            &episodes,
            settings.render_steps,
            settings.seed,
        )?;
        rendered.push(SizedRate {
            width,
            height,
            rate,
        });
    }
    let renderer = Env::new(
        ctx.clone(),
        EnvConfig {
            device: settings.device,
            ..EnvConfig::default()
        },
    )?
    .render_device()
    .unwrap_or("none")
    .to_string();
    let vector = match (settings.envs, settings.sizes.first()) {
        (0, _) | (_, None) => None,
        (envs, Some(&(width, height))) => {
            let batches = settings.render_steps.div_ceil(envs).max(3);
            let config = rgbd(width, height, settings.device);
            let steps_per_s =
                measure_vector(&ctx, config, &episodes, envs, batches, settings.seed)?;
            Some(VectorRate {
                envs,
                width,
                height,
                batches,
                steps_per_s,
                cpu_renderers: ctx.cpu_renderers(),
                resident_bytes: machine::resident_bytes(),
            })
        }
    };
    Ok(EnvReport {
        renderer,
        vector,
        machine,
        scene: name,
        objects,
        gaussians,
        parts: report.parts,
        bodies_s: report.seconds,
        episodes: episodes.len(),
        steps: settings.steps,
        blind,
        render_steps: settings.render_steps,
        rendered,
    })
}
