//! Environments over a pool of episodes in many scenes, one at a time ([`PooledEnv`]) or several
//! stepped in parallel ([`VecEnv`]), with rewards, Gymnasium's `terminated`/`truncated` and an
//! info record per step: what the Python environments and vector environments run.

use crate::action::Action;
use crate::config::EnvConfig;
use crate::context::SceneContext;
use crate::env::{Env, Observation};
use crate::episode::EnvEpisode;
use crate::episode::{StepInfo, Termination};
use crate::reward::Reward;
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_metrics::{EpisodeMetrics, Mode};
use serde::Serialize;
use std::sync::Arc;

/// One episode of a pool: the index of its scene among the pool's contexts, the scene's name as
/// the dataset gives it, and the episode.
#[derive(Debug, Clone, PartialEq)]
pub struct PoolEpisode {
    /// Index into [`Pool::scenes`].
    pub scene: usize,
    /// The scene's name (the dataset's `scene` field).
    pub scene_name: String,
    /// The episode.
    pub episode: EnvEpisode,
}

/// The scenes and episodes environments draw from.
pub struct Pool {
    /// Loaded scenes.
    pub scenes: Vec<Arc<SceneContext>>,
    /// Episodes, each naming its scene.
    pub episodes: Vec<PoolEpisode>,
}

impl Pool {
    /// A pool of `episodes` over `scenes`.
    ///
    /// # Errors
    ///
    /// No episodes, or an episode whose scene index is out of range.
    pub fn new(scenes: Vec<Arc<SceneContext>>, episodes: Vec<PoolEpisode>) -> Result<Pool> {
        if episodes.is_empty() {
            return Err(Error::invalid("no episodes to run"));
        }
        if let Some(e) = episodes.iter().find(|e| e.scene >= scenes.len()) {
            return Err(Error::invalid(format!(
                "scene index {} out of range",
                e.scene
            )));
        }
        Ok(Pool { scenes, episodes })
    }
}

/// What one reset or step produced.
#[derive(Debug, Clone)]
pub struct Transition {
    /// The observation.
    pub obs: Observation,
    /// The reward ([`crate::reward`]); 0 on reset.
    pub reward: f32,
    /// The task ended the episode (STOP, a NoGoal collision).
    pub terminated: bool,
    /// A step or time limit cut the episode.
    pub truncated: bool,
    /// The info record.
    pub info: Info,
}

/// The info record of a reset or step (documented in `docs/python.md`).
#[derive(Debug, Clone, Serialize)]
pub struct Info {
    /// Episode id.
    pub episode_id: String,
    /// Scene name.
    pub scene: String,
    /// Index of the episode in the pool.
    pub episode_index: usize,
    /// Steps taken.
    pub step: usize,
    /// Simulated time, seconds.
    pub time: f32,
    /// `[x, y, z, yaw]`, W frame.
    pub pose: [f32; 4],
    /// Camera tilt, radians.
    pub pitch: f32,
    /// Bodies touched after the step.
    pub contacts: Vec<Contact>,
    /// This step's record (absent on reset).
    pub step_info: Option<StepInfo>,
    /// Whether the agent is within the success distance of the goal.
    pub within_success_distance: bool,
    /// Running totals of the episode.
    pub metrics_so_far: SoFar,
    /// Why the episode ended, once it has.
    pub termination: Option<Termination>,
    /// The episode's metrics in the pool's mode, once it has ended.
    pub metrics: Option<EpisodeMetrics>,
}

/// A body touched after the step.
#[derive(Debug, Clone, Serialize)]
pub struct Contact {
    /// Its instance id.
    pub instance: u32,
    /// Distance to it, metres.
    pub distance: f32,
}

/// Running totals of an episode.
#[derive(Debug, Clone, Serialize)]
pub struct SoFar {
    /// Steps taken.
    pub steps: usize,
    /// Path length, metres.
    pub path_length: f32,
    /// Steps with a collision.
    pub collisions: usize,
    /// Steps touching a body.
    pub contact_steps: usize,
    /// Distance to the goal region after the last step.
    pub distance_to_goal: Option<f32>,
}

/// One environment over a [`Pool`]: the environments of the scenes it has visited (built on
/// first use) and the running episode with its reward.
pub struct PooledEnv {
    pool: Arc<Pool>,
    config: EnvConfig,
    mode: Mode,
    envs: Vec<Option<Env>>,
    running: Option<(usize, Reward)>,
}

impl PooledEnv {
    /// An environment over `pool` with `config`; episode metrics in `mode`.
    pub fn new(pool: Arc<Pool>, config: EnvConfig, mode: Mode) -> PooledEnv {
        let envs = pool.scenes.iter().map(|_| None).collect();
        PooledEnv {
            pool,
            config,
            mode,
            envs,
            running: None,
        }
    }

    /// The pool.
    pub fn pool(&self) -> &Arc<Pool> {
        &self.pool
    }

    /// The configuration.
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    fn env(&mut self) -> Result<(&mut Env, &mut Reward, usize)> {
        let (k, reward) = self
            .running
            .as_mut()
            .ok_or_else(|| Error::invalid("reset before step"))?;
        let scene = self.pool.episodes[*k].scene;
        let env = self.envs[scene]
            .as_mut()
            .ok_or_else(|| Error::invalid("reset before step"))?;
        Ok((env, reward, *k))
    }

    /// Starts episode `k` of the pool.
    ///
    /// # Errors
    ///
    /// `k` out of range, or the environment's reset fails (no episode is running then).
    pub fn reset(&mut self, k: usize) -> Result<Transition> {
        let pool = self.pool.clone();
        let entry = pool
            .episodes
            .get(k)
            .ok_or_else(|| Error::invalid(format!("episode index {k} out of range")))?;
        let slot = &mut self.envs[entry.scene];
        if slot.is_none() {
            *slot = Some(Env::new(
                pool.scenes[entry.scene].clone(),
                self.config.clone(),
            )?);
        }
        // A failed reset leaves no running episode (not the previous one, half replaced).
        self.running = None;
        let obs = slot
            .as_mut()
            .ok_or_else(|| Error::invalid("no environment for the scene"))?
            .reset(&entry.episode)?;
        let reward = Reward::start(&pool.scenes[entry.scene], &entry.episode);
        self.running = Some((k, reward));
        let info = self.info(None, &obs)?;
        Ok(Transition {
            obs,
            reward: 0.0,
            terminated: false,
            truncated: false,
            info,
        })
    }

    /// Applies one action to the running episode.
    ///
    /// # Errors
    ///
    /// No running episode, or the environment refuses the action.
    pub fn step(&mut self, action: Action) -> Result<Transition> {
        let (env, reward, _) = self.env()?;
        let (obs, step) = env.step(action)?;
        let reward = reward.step(&step, env.within_success_distance());
        let info = self.info(Some(&step), &obs)?;
        Ok(Transition {
            obs,
            reward,
            terminated: step.termination.is_some_and(Termination::is_terminal),
            truncated: step.termination.is_some_and(Termination::is_truncation),
            info,
        })
    }

    fn info(&mut self, step: Option<&StepInfo>, obs: &Observation) -> Result<Info> {
        let (pool, mode) = (self.pool.clone(), self.mode);
        let (env, reward, k) = self.env()?;
        let last_distance = reward.last_distance();
        let entry = &pool.episodes[k];
        let ctx = &pool.scenes[entry.scene];
        let within = env.within_success_distance();
        let trace = env
            .trace()
            .ok_or_else(|| Error::invalid("no running episode"))?;
        let path_length: f32 = trace
            .steps
            .iter()
            .scan(trace.episode.start.position, |at, s| {
                let d = at.distance(s.pose.position);
                *at = s.pose.position;
                Some(d)
            })
            .sum();
        let metrics = match trace.termination {
            Some(_) => Some(crate::scoring::score(ctx, trace, mode)?),
            None => None,
        };
        let p = obs.pose;
        Ok(Info {
            episode_id: entry.episode.id.clone(),
            scene: entry.scene_name.clone(),
            episode_index: k,
            step: obs.step,
            time: obs.time,
            pose: [p.position.x, p.position.y, p.position.z, p.yaw],
            pitch: obs.pitch,
            contacts: obs
                .contacts
                .iter()
                .map(|c| Contact {
                    instance: c.instance.0,
                    distance: c.distance,
                })
                .collect(),
            step_info: step.cloned(),
            within_success_distance: within,
            metrics_so_far: SoFar {
                steps: trace.steps.len(),
                path_length,
                collisions: trace.steps.iter().filter(|s| s.collision).count(),
                contact_steps: trace.steps.iter().filter(|s| !s.touched.is_empty()).count(),
                distance_to_goal: trace
                    .steps
                    .last()
                    .map_or(last_distance, |s| s.distance_to_goal),
            },
            termination: trace.termination,
            metrics,
        })
    }
}

/// What one sub-environment of a [`VecEnv`] does in a batch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Order {
    /// Start the pool's episode with this index.
    Reset(usize),
    /// Apply the action.
    Step(Action),
}

/// Several [`PooledEnv`]s over one pool, run in parallel one batch at a time.
pub struct VecEnv {
    envs: Vec<PooledEnv>,
}

impl VecEnv {
    /// `n` environments over `pool`.
    ///
    /// # Errors
    ///
    /// `n` is 0.
    pub fn new(n: usize, pool: Arc<Pool>, config: EnvConfig, mode: Mode) -> Result<VecEnv> {
        if n == 0 {
            return Err(Error::invalid("num_envs must be at least 1"));
        }
        Ok(VecEnv {
            envs: (0..n)
                .map(|_| PooledEnv::new(pool.clone(), config.clone(), mode))
                .collect(),
        })
    }

    /// The sub-environments.
    pub fn envs(&self) -> &[PooledEnv] {
        &self.envs
    }

    /// Runs `orders[i]` in sub-environment `i`, all in parallel; the transitions come back in
    /// order.
    ///
    /// # Errors
    ///
    /// Not one order per sub-environment, or the first failing order's error, naming its
    /// sub-environment.
    pub fn run(&mut self, orders: Vec<Order>) -> Result<Vec<Transition>> {
        if orders.len() != self.envs.len() {
            return Err(Error::invalid(format!(
                "expected {} entries (one per sub-environment), got {}",
                self.envs.len(),
                orders.len()
            )));
        }
        self.envs
            .par_iter_mut()
            .zip(orders)
            .enumerate()
            .map(|(i, (env, order))| {
                match order {
                    Order::Reset(k) => env.reset(k),
                    Order::Step(a) => env.step(a),
                }
                .map_err(|e| e.within(format!("sub-environment {i}")))
            })
            .collect()
    }
}
