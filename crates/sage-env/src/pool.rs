//! Environments over a pool of episodes in many scenes, one at a time ([`PooledEnv`]) or several
//! stepped in parallel ([`VecEnv`]), with rewards, Gymnasium's `terminated`/`truncated` and an
//! info record per step: what the Python environments and vector environments run.

use crate::action::Action;
use crate::config::EnvConfig;
use crate::context::SceneContext;
use crate::env::{Env, Observation, Pending};
use crate::episode::EnvEpisode;
use crate::episode::{StepInfo, Termination};
use crate::reward::Reward;
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_metrics::{EpisodeMetrics, Mode};
use sage_splat::{Camera, RenderOutput};
use serde::Serialize;
use std::collections::BTreeMap;
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

    /// Episode `k` of the pool.
    ///
    /// # Errors
    ///
    /// `k` out of range.
    pub fn episode(&self, k: usize) -> Result<&PoolEpisode> {
        self.episodes
            .get(k)
            .ok_or_else(|| Error::invalid(format!("episode index {k} out of range")))
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

    /// The environment of the pool's scene `scene`, built now if this one has not run an
    /// episode there yet (otherwise the first reset into the scene builds it): a renderer that
    /// cannot open (`device: gpu` without an adapter) fails here.
    ///
    /// # Errors
    ///
    /// `scene` out of range, or [`Env::new`] fails.
    pub fn open(&mut self, scene: usize) -> Result<&Env> {
        Ok(self.open_mut(scene)?)
    }

    fn open_mut(&mut self, scene: usize) -> Result<&mut Env> {
        let ctx = self
            .pool
            .scenes
            .get(scene)
            .ok_or_else(|| Error::invalid(format!("scene index {scene} out of range")))?;
        let slot = &mut self.envs[scene];
        if slot.is_none() {
            *slot = Some(Env::new(ctx.clone(), self.config.clone())?);
        }
        slot.as_mut()
            .ok_or_else(|| Error::invalid("no environment for the scene"))
    }

    /// Starts episode `k` of the pool.
    ///
    /// # Errors
    ///
    /// `k` out of range, or the environment's reset fails (no episode is running then).
    pub fn reset(&mut self, k: usize) -> Result<Transition> {
        self.run(Order::Reset(k))
    }

    /// Applies one action to the running episode.
    ///
    /// # Errors
    ///
    /// No running episode, or the environment refuses the action.
    pub fn step(&mut self, action: Action) -> Result<Transition> {
        self.run(Order::Step(action))
    }

    /// Runs `order` with its observation rendered by this environment's handle on the scene's
    /// renderer, the camera alone.
    fn run(&mut self, order: Order) -> Result<Transition> {
        let begun = self.begin(order)?;
        let outputs = self
            .env()
            .and_then(|(env, ..)| env.render(begun.pending.cameras()));
        self.complete(begun, outputs)
    }

    /// Checks that `order` can begin, as [`PooledEnv::begin`] checks it, without running it.
    fn check(&self, order: &Order) -> Result<()> {
        match *order {
            Order::Reset(k) => self.pool.episode(k).map(|_| ()),
            Order::Step(action) => {
                let env = self
                    .running
                    .as_ref()
                    .and_then(|(k, _)| self.envs[self.pool.episodes[*k].scene].as_ref())
                    .ok_or_else(|| Error::invalid("reset before step"))?;
                env.check_step(action)
            }
        }
    }

    /// Runs `order` up to the rendering of its observation.
    fn begin(&mut self, order: Order) -> Result<Begun> {
        match order {
            Order::Reset(k) => {
                let pool = self.pool.clone();
                let entry = pool.episode(k)?;
                // A failed reset leaves no running episode (not the previous one, half
                // replaced).
                self.running = None;
                let pending = self
                    .open_mut(entry.scene)?
                    .reset_unrendered(&entry.episode)?;
                let reward = Reward::start(&pool.scenes[entry.scene], &entry.episode);
                self.running = Some((k, reward));
                Ok(Begun {
                    pending,
                    step: None,
                    reward: 0.0,
                })
            }
            Order::Step(action) => {
                let (env, reward, _) = self.env()?;
                let (pending, step) = env.step_unrendered(action)?;
                let reward = reward.step(&step, env.within_success_distance());
                Ok(Begun {
                    pending,
                    step: Some(step),
                    reward,
                })
            }
        }
    }

    /// The transition of `begun` with `outputs`, the renders of its cameras. A reset whose
    /// images failed leaves no running episode.
    fn complete(&mut self, begun: Begun, outputs: Result<Vec<RenderOutput>>) -> Result<Transition> {
        let Begun {
            pending,
            step,
            reward,
        } = begun;
        let obs = outputs.and_then(|outputs| {
            let (env, ..) = self.env()?;
            env.observation(pending, outputs)
        });
        let obs = match obs {
            Ok(obs) => obs,
            Err(e) => {
                if step.is_none() {
                    self.running = None;
                }
                return Err(e);
            }
        };
        let info = self.info(step.as_ref(), &obs)?;
        let termination = step.and_then(|s| s.termination);
        Ok(Transition {
            obs,
            reward,
            terminated: termination.is_some_and(Termination::is_terminal),
            truncated: termination.is_some_and(Termination::is_truncation),
            info,
        })
    }

    /// The pool's scene of the running episode, when its images can be rendered in one batch
    /// with those of other environments over the scene (the renderer is the scene's shared
    /// GPU upload).
    fn batch_scene(&self) -> Option<usize> {
        let (k, _) = self.running.as_ref()?;
        let scene = self.pool.episodes[*k].scene;
        self.envs[scene]
            .as_ref()?
            .renders_in_scene_batches()
            .then_some(scene)
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
        // A fold from +0: `sum` of no steps is −0, which Python prints as `-0.0`.
        let path_length = trace
            .steps
            .iter()
            .scan(trace.episode.start.position, |at, s| {
                let d = at.distance(s.pose.position);
                *at = s.pose.position;
                Some(d)
            })
            .fold(0.0_f32, |total, d| total + d);
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

/// A reset or step of a [`PooledEnv`] waiting for its images.
struct Begun {
    pending: Pending,
    /// The step's record; `None` for a reset.
    step: Option<StepInfo>,
    reward: f32,
}

/// What one sub-environment of a [`VecEnv`] does in a batch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Order {
    /// Start the pool's episode with this index.
    Reset(usize),
    /// Apply the action.
    Step(Action),
}

/// The most sub-environments a [`VecEnv`] holds: each keeps a physics world (and its images)
/// per scene it runs, so a count far past what a machine holds would only fail in an
/// allocation.
pub const MAX_ENVS: usize = 16_384;

/// Several [`PooledEnv`]s over one pool, run in parallel one batch at a time.
pub struct VecEnv {
    envs: Vec<PooledEnv>,
}

impl VecEnv {
    /// `n` environments over `pool`.
    ///
    /// # Errors
    ///
    /// `n` is 0 or over [`MAX_ENVS`].
    pub fn new(n: usize, pool: Arc<Pool>, config: EnvConfig, mode: Mode) -> Result<VecEnv> {
        if !(1..=MAX_ENVS).contains(&n) {
            return Err(Error::invalid(format!(
                "`num_envs` must be 1 to {MAX_ENVS}, got {n}"
            )));
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

    /// The environment of the pool's scene `scene` in the first sub-environment, built now
    /// ([`PooledEnv::open`]): every sub-environment has the same configuration, so a renderer
    /// that cannot open fails here rather than at the first reset.
    ///
    /// # Errors
    ///
    /// As [`PooledEnv::open`].
    pub fn open(&mut self, scene: usize) -> Result<&Env> {
        self.envs[0].open(scene)
    }

    /// Runs `orders[i]` in sub-environment `i`; the transitions come back in order. The
    /// physics of all sub-environments runs in parallel; then the cameras of the
    /// sub-environments whose scene is on the GPU are rendered in one batch per scene, each
    /// other sub-environment renders its own (all in parallel); then the observations and
    /// info records are assembled in parallel.
    ///
    /// # Errors
    ///
    /// Not one order per sub-environment, or the first failing order's error, naming its
    /// sub-environment. An order that cannot begin (an episode index out of range, a step
    /// before a reset, an action outside the space) is found before any order runs.
    pub fn run(&mut self, orders: Vec<Order>) -> Result<Vec<Transition>> {
        if orders.len() != self.envs.len() {
            return Err(Error::invalid(format!(
                "expected {} entries (one per sub-environment), got {}",
                self.envs.len(),
                orders.len()
            )));
        }
        let within = |i: usize| move |e: Error| e.within(format!("sub-environment {i}"));
        // Every order is checked before any runs: a refused batch leaves every
        // sub-environment as it was, not some stepped.
        for (i, (env, order)) in self.envs.iter().zip(&orders).enumerate() {
            env.check(order).map_err(within(i))?;
        }
        let begun: Vec<Begun> = first_error(
            self.envs
                .par_iter_mut()
                .zip(orders)
                .enumerate()
                .map(|(i, (env, order))| env.begin(order).map_err(within(i)))
                .collect(),
        )?;
        let batches = self.batches(&begun);
        // Each batch is rendered by its first sub-environment's renderer.
        let mut leads: Vec<Option<Vec<Camera>>> = self.envs.iter().map(|_| None).collect();
        for batch in &batches {
            let cameras = batch
                .iter()
                .flat_map(|&i| begun[i].pending.cameras().iter().copied())
                .collect();
            leads[batch[0]] = Some(cameras);
        }
        let mut rendered: Vec<Option<Result<Vec<RenderOutput>>>> = self
            .envs
            .par_iter_mut()
            .zip(leads)
            .map(|(env, cameras)| cameras.map(|c| env.env().and_then(|(env, ..)| env.render(&c))))
            .collect();
        let mut outputs: Vec<Option<Result<Vec<RenderOutput>>>> =
            self.envs.iter().map(|_| None).collect();
        for batch in &batches {
            let lead = batch[0];
            match rendered[lead].take().expect("every batch was rendered") {
                Ok(all) => {
                    let mut all = all.into_iter();
                    for &i in batch {
                        let n = begun[i].pending.cameras().len();
                        outputs[i] = Some(Ok(all.by_ref().take(n).collect()));
                    }
                }
                Err(e) => {
                    for &i in &batch[1..] {
                        outputs[i] = Some(Err(Error::invalid(format!(
                            "not rendered: the batch of sub-environment {lead} failed"
                        ))));
                    }
                    outputs[lead] = Some(Err(e));
                }
            }
        }
        first_error(
            self.envs
                .par_iter_mut()
                .zip(begun)
                .zip(outputs)
                .enumerate()
                .map(|(i, ((env, begun), outputs))| {
                    env.complete(begun, outputs.unwrap_or_else(|| Ok(Vec::new())))
                        .map_err(within(i))
                })
                .collect(),
        )
    }

    /// The render batches of `begun`, sub-environment indices in order, each batch's first
    /// the one that renders it: one per scene for the sub-environments on the scene's GPU
    /// upload, one per sub-environment for the others (CPU renders each borrow a renderer from
    /// the scene's pool and run in parallel). Sub-environments without cameras are in none.
    fn batches(&self, begun: &[Begun]) -> Vec<Vec<usize>> {
        let mut batches: Vec<Vec<usize>> = Vec::new();
        let mut by_scene: BTreeMap<usize, usize> = BTreeMap::new();
        for (i, env) in self.envs.iter().enumerate() {
            if begun[i].pending.cameras().is_empty() {
                continue;
            }
            match env.batch_scene() {
                Some(scene) => match by_scene.get(&scene) {
                    Some(&b) => batches[b].push(i),
                    None => {
                        by_scene.insert(scene, batches.len());
                        batches.push(vec![i]);
                    }
                },
                None => batches.push(vec![i]),
            }
        }
        batches
    }
}

/// The values of `results`, or the error of the first that failed.
fn first_error<T>(results: Vec<Result<T>>) -> Result<Vec<T>> {
    results.into_iter().collect()
}
