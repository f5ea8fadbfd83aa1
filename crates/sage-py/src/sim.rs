//! The environment for Python: [`Sim`] runs one environment over a pool of episodes, [`VecSim`]
//! runs several in parallel (rayon) in one call. Both release the GIL while they reset, step and
//! render, and hand images out as NumPy arrays that own the rendered buffers.
//!
//! Rewards follow Habitat's navigation reward: VLN pays the decrease of the distance to the goal
//! region each step, minus a slack of 0.01, plus 2.5 when the agent calls STOP within the
//! success distance; NoGoal pays the metres achieved along the command, minus the slack.
//! `terminated` is STOP or a NoGoal collision, `truncated` the step or time limit.

use crate::convert::{PyResultExt, array, drop_none, from_json, to_py};
use numpy::ndarray::{Ix1, Ix2, Ix3, Ix4};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::prelude::*;
use sage_bench::dataset::Episode;
use sage_bench::eval::convert::{env_episode, metric_record};
use sage_core::{Error, Result};
use sage_env::{
    Action, ActionSpace, Env, EnvConfig, EnvEpisode, Observation, SceneContext, StepInfo,
    Termination,
};
use sage_metrics::{EpisodeMetrics, Mode};
use serde::Serialize;
use serde_json::Value;
use std::sync::Arc;

/// What a single step hands Python: observation, reward, terminated, truncated, info.
type Transition<'py> = (Bound<'py, PyDict>, f32, bool, bool, Bound<'py, PyAny>);

/// What a vector step hands Python: observations (a dict of stacked arrays), rewards,
/// terminated and truncated flags, and infos.
type Batch<'py> = (
    Bound<'py, PyDict>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
);

/// Reward per step for existing (Habitat's slack reward).
const SLACK: f32 = 0.01;
/// Reward for a successful STOP (Habitat's success reward).
const SUCCESS_REWARD: f32 = 2.5;

/// The episodes an environment draws from, each with the scene it runs in.
struct Pool {
    scenes: Vec<Arc<SceneContext>>,
    episodes: Vec<(usize, Episode, EnvEpisode)>,
}

/// The resolved configuration: `preset` with the JSON object `overrides` merged over it (nested
/// objects merge key by key), validated.
pub(crate) fn resolve_config(preset: &str, overrides: &Value) -> Result<EnvConfig> {
    fn merge(base: &mut Value, over: &Value) {
        match (base, over) {
            (Value::Object(b), Value::Object(o)) => {
                for (k, v) in o {
                    match b.get_mut(k) {
                        Some(slot) if v.is_object() && slot.is_object() => merge(slot, v),
                        _ => {
                            b.insert(k.clone(), v.clone());
                        }
                    }
                }
            }
            (b, o) => *b = o.clone(),
        }
    }
    let mut v = serde_json::to_value(EnvConfig::preset(preset)?)
        .map_err(|e| Error::invalid(e.to_string()))?;
    merge(&mut v, overrides);
    let config: EnvConfig = serde_json::from_value(v)
        .map_err(|e| Error::invalid(format!("environment config: {e}")))?;
    config.validate()?;
    Ok(config)
}

/// What one reset or step produced, before conversion to Python objects.
struct Outcome {
    obs: Observation,
    reward: f32,
    terminated: bool,
    truncated: bool,
    /// The info dict as JSON text.
    info: String,
}

/// One environment over a [`Pool`]: the environments of the scenes it has visited (built on
/// first use) and the running episode.
struct Core {
    pool: Arc<Pool>,
    config: EnvConfig,
    mode: Mode,
    envs: Vec<Option<Env>>,
    running: Option<usize>,
    last_distance: Option<f32>,
}

impl Core {
    fn new(pool: Arc<Pool>, config: EnvConfig, mode: Mode) -> Core {
        let envs = pool.scenes.iter().map(|_| None).collect();
        Core {
            pool,
            config,
            mode,
            envs,
            running: None,
            last_distance: None,
        }
    }

    fn env(&mut self) -> Result<&mut Env> {
        let k = self
            .running
            .ok_or_else(|| Error::invalid("reset before step"))?;
        let scene = self.pool.episodes[k].0;
        self.envs[scene]
            .as_mut()
            .ok_or_else(|| Error::invalid("reset before step"))
    }

    fn reset(&mut self, k: usize) -> Result<Outcome> {
        let pool = self.pool.clone();
        let (scene, _, episode) = pool
            .episodes
            .get(k)
            .ok_or_else(|| Error::invalid(format!("episode index {k} out of range")))?;
        let slot = &mut self.envs[*scene];
        if slot.is_none() {
            *slot = Some(Env::new(pool.scenes[*scene].clone(), self.config.clone())?);
        }
        // A failed reset leaves no running episode (not the previous one, half replaced).
        self.running = None;
        let obs = slot
            .as_mut()
            .ok_or_else(|| Error::invalid("no environment for the scene"))?
            .reset(episode)?;
        self.running = Some(k);
        self.last_distance = start_distance(&pool.scenes[*scene], episode);
        let info = self.info(None, &obs)?;
        Ok(Outcome {
            obs,
            reward: 0.0,
            terminated: false,
            truncated: false,
            info,
        })
    }

    fn step(&mut self, action: Action) -> Result<Outcome> {
        let env = self.env()?;
        let (obs, step) = env.step(action)?;
        let within = env.within_success_distance();
        let task = env.trace().map(|t| t.episode.task);
        let reward = match task {
            Some(sage_core::Task::Nogoal) => step.achieved - SLACK,
            _ => {
                let progress = match (self.last_distance, step.distance_to_goal) {
                    (Some(a), Some(b)) => a - b,
                    _ => 0.0,
                };
                let success = step.termination == Some(Termination::Stop) && within;
                progress - SLACK + if success { SUCCESS_REWARD } else { 0.0 }
            }
        };
        self.last_distance = step.distance_to_goal;
        let (terminated, truncated) = match step.termination {
            Some(Termination::Stop | Termination::Collision) => (true, false),
            Some(Termination::MaxSteps | Termination::TimeLimit) => (false, true),
            None => (false, false),
        };
        let info = self.info(Some(&step), &obs)?;
        Ok(Outcome {
            obs,
            reward,
            terminated,
            truncated,
            info,
        })
    }

    /// The info dict: episode, pose, contacts, this step's record, the metrics so far, and the
    /// episode's metrics (in the configured mode) once it has ended.
    fn info(&mut self, step: Option<&StepInfo>, obs: &Observation) -> Result<String> {
        let (mode, last_distance) = (self.mode, self.last_distance);
        let k = self.running.unwrap_or_default();
        let pool = self.pool.clone();
        let (scene, episode, _) = &pool.episodes[k];
        let ctx = &pool.scenes[*scene];
        let env = self.env()?;
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
            Some(_) => Some(sage_metrics::evaluate(&metric_record(ctx, trace), mode)?),
            None => None,
        };
        let p = obs.pose;
        serde_json::to_string(&Info {
            episode_id: &episode.episode_id,
            scene: &episode.scene,
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
            step_info: step,
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
        .map_err(|e| Error::invalid(format!("info: {e}")))
    }
}

/// The info dict of a reset or step (documented in `docs/python.md`).
#[derive(Serialize)]
struct Info<'a> {
    episode_id: &'a str,
    scene: &'a str,
    episode_index: usize,
    step: usize,
    time: f32,
    pose: [f32; 4],
    pitch: f32,
    contacts: Vec<Contact>,
    step_info: Option<&'a StepInfo>,
    within_success_distance: bool,
    metrics_so_far: SoFar,
    termination: Option<Termination>,
    metrics: Option<EpisodeMetrics>,
}

/// A body touched after the step.
#[derive(Serialize)]
struct Contact {
    instance: u32,
    distance: f32,
}

/// Running totals of the episode.
#[derive(Serialize)]
struct SoFar {
    steps: usize,
    path_length: f32,
    collisions: usize,
    contact_steps: usize,
    distance_to_goal: Option<f32>,
}

/// An info dict from its JSON text, undefined values dropped (see [`drop_none`]).
fn info_to_py<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    let info = py.import("json")?.call_method1("loads", (text,))?;
    drop_none(&info)?;
    Ok(info)
}

/// The Euclidean distance from the episode's start to its goal region (the footprint of its
/// goal object, else its goal point), which the first step's progress reward is measured from.
fn start_distance(ctx: &SceneContext, episode: &EnvEpisode) -> Option<f32> {
    let goal = episode.goal.as_ref()?;
    let at = episode.start.position.truncate();
    match &goal.object {
        Some(item) => {
            let region = ctx.footprint(item).ok()?;
            Some(if region.contains(at) {
                0.0
            } else {
                region.distance_to_boundary(at)
            })
        }
        None => Some(at.distance(goal.point.truncate())),
    }
}

/// Reads an action from Python for `space`: an integer (VLN-CE's index) in the discrete
/// space; `[stop, vx, vy, wz, dt]` on the ground and `[stop, vx, vy, vz, wz, dt]` for the UAV,
/// where `stop >= 0.5` calls STOP.
pub(crate) fn parse_action(space: &ActionSpace, a: &Bound<'_, PyAny>) -> PyResult<Action> {
    let bad = |what: String| PyValueError::new_err(format!("action: {what}"));
    match space {
        ActionSpace::Discrete { .. } => {
            let i: i64 = a
                .extract()
                .map_err(|_| bad(format!("expected an integer 0-5, got {a}")))?;
            u8::try_from(i)
                .ok()
                .and_then(Action::from_index)
                .ok_or_else(|| bad(format!("index {i} is not 0-5")))
        }
        ActionSpace::Ground { .. } | ActionSpace::Uav { .. } => {
            let uav = matches!(space, ActionSpace::Uav { .. });
            let v: Vec<f32> = a
                .extract()
                .map_err(|_| bad(format!("expected a sequence of numbers, got {a}")))?;
            match (uav, v.as_slice()) {
                (_, [stop, ..]) if *stop >= 0.5 => Ok(Action::Stop),
                (false, &[_, vx, vy, wz, dt]) => Ok(Action::Velocity { vx, vy, wz, dt }),
                (true, &[_, vx, vy, vz, wz, dt]) => Ok(Action::Fly { vx, vy, vz, wz, dt }),
                _ => Err(bad(format!(
                    "expected {} numbers, got {}",
                    if uav { 6 } else { 5 },
                    v.len()
                ))),
            }
        }
    }
}

/// The observation as a dict of NumPy arrays owning the rendered buffers (no copy), the pose
/// `[x, y, z, yaw]` and the instruction.
pub(crate) fn obs_to_py<'py>(py: Python<'py>, obs: Observation) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    if let Some(im) = obs.images {
        let (w, h) = (im.width, im.height);
        let (dw, dh) = im.depth_size;
        if let Some(v) = im.rgb {
            d.set_item("rgb", array(py, Ix3(h, w, 3), v)?)?;
        }
        if let Some(v) = im.depth {
            d.set_item("depth", array(py, Ix2(dh, dw), v)?)?;
        }
        if let Some(v) = im.semantic {
            d.set_item("semantic", array(py, Ix2(h, w), v)?)?;
        }
        if let Some(v) = im.instance {
            d.set_item("instance", array(py, Ix2(h, w), v)?)?;
        }
    }
    let p = obs.pose;
    d.set_item(
        "pose",
        array(
            py,
            Ix1(4),
            vec![p.position.x, p.position.y, p.position.z, p.yaw],
        )?,
    )?;
    d.set_item("instruction", &*obs.instruction)?;
    Ok(d)
}

/// Builds the pool from loaded scenes and dataset episodes (JSON list) with the index of each
/// episode's scene.
fn pool(
    scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
    episodes: &str,
    scene_of: Vec<usize>,
) -> PyResult<Arc<Pool>> {
    let episodes: Vec<Episode> = from_json(episodes, "episodes")?;
    if episodes.len() != scene_of.len() {
        return Err(PyValueError::new_err(
            "episodes and scene_of must have the same length",
        ));
    }
    if episodes.is_empty() {
        return Err(PyValueError::new_err("no episodes to run"));
    }
    if let Some(&k) = scene_of.iter().find(|&&k| k >= scenes.len()) {
        return Err(PyIndexError::new_err(format!(
            "scene index {k} out of range"
        )));
    }
    Ok(Arc::new(Pool {
        scenes: scenes.iter().map(|s| s.ctx.clone()).collect(),
        episodes: episodes
            .into_iter()
            .zip(scene_of)
            .map(|(e, s)| {
                let env = env_episode(&e);
                (s, e, env)
            })
            .collect(),
    }))
}

/// The agent profile's limits that bound the continuous action spaces.
#[derive(Serialize)]
struct Limits {
    name: &'static str,
    max_speed: f32,
    max_yaw_rate: f32,
    camera_height: f32,
}

/// Resolves a preset plus JSON overrides for Python callers (the Gymnasium wrappers read
/// spaces from it), with the agent profile's limits under `profile`.
#[pyfunction]
#[pyo3(signature = (preset="sage", overrides="{}"))]
pub fn env_config<'py>(
    py: Python<'py>,
    preset: &str,
    overrides: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let config = resolve_config(preset, &from_json(overrides, "overrides")?).py()?;
    let profile = config.profile().py()?;
    let out = to_py(py, &config)?;
    out.set_item(
        "profile",
        to_py(
            py,
            &Limits {
                name: profile.name,
                max_speed: profile.max_speed,
                max_yaw_rate: profile.max_yaw_rate,
                camera_height: profile.camera_height,
            },
        )?,
    )?;
    Ok(out)
}

fn mode_of(mode: &str) -> PyResult<Mode> {
    mode.parse::<Mode>().py()
}

/// One environment over a pool of episodes (the engine under `sage3d.SageEnv`).
#[pyclass(module = "sage3d._sage3d")]
pub struct Sim {
    core: Core,
}

#[pymethods]
impl Sim {
    /// An environment over `episodes` (JSON list of dataset episodes), episode `i` running in
    /// `scenes[scene_of[i]]`, with `preset` plus the JSON `overrides`; episode metrics in `mode`.
    #[new]
    #[pyo3(signature = (scenes, episodes, scene_of, preset="sage", overrides="{}", mode="sage"))]
    fn new(
        scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
        episodes: &str,
        scene_of: Vec<usize>,
        preset: &str,
        overrides: &str,
        mode: &str,
    ) -> PyResult<Sim> {
        let config = resolve_config(preset, &from_json(overrides, "overrides")?).py()?;
        Ok(Sim {
            core: Core::new(pool(scenes, episodes, scene_of)?, config, mode_of(mode)?),
        })
    }

    /// Number of episodes in the pool.
    fn __len__(&self) -> usize {
        self.core.pool.episodes.len()
    }

    /// The pool's episodes as dicts (dataset schema).
    fn episodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let e: Vec<&Episode> = self.core.pool.episodes.iter().map(|(_, e, _)| e).collect();
        to_py(py, &e)
    }

    /// Starts episode `index`; returns `(obs, info)`.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        index: usize,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
        let core = &mut self.core;
        let out = py.detach(|| core.reset(index)).py()?;
        Ok((obs_to_py(py, out.obs)?, info_to_py(py, &out.info)?))
    }

    /// Applies one action; returns `(obs, reward, terminated, truncated, info)`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: &Bound<'py, PyAny>,
    ) -> PyResult<Transition<'py>> {
        let action = parse_action(&self.core.config.actions, action)?;
        let core = &mut self.core;
        let out = py.detach(|| core.step(action)).py()?;
        Ok((
            obs_to_py(py, out.obs)?,
            out.reward,
            out.terminated,
            out.truncated,
            info_to_py(py, &out.info)?,
        ))
    }
}

/// Several environments over one pool, stepped in parallel in one call (the engine under
/// `sage3d.SageVectorEnv`): observations come back stacked along a leading axis.
#[pyclass(module = "sage3d._sage3d")]
pub struct VecSim {
    cores: Vec<Core>,
}

/// A reset (episode index) or an action for one sub-environment.
enum Order {
    Reset(usize),
    Step(Action),
}

impl VecSim {
    /// Runs `orders` in parallel and returns the batch as Python objects.
    fn run<'py>(&mut self, py: Python<'py>, orders: Vec<Order>) -> PyResult<Batch<'py>> {
        let cores = &mut self.cores;
        let outs: Vec<Outcome> = py
            .detach(|| {
                cores
                    .par_iter_mut()
                    .zip(orders)
                    .enumerate()
                    .map(|(i, (core, order))| {
                        match order {
                            Order::Reset(k) => core.reset(k),
                            Order::Step(a) => core.step(a),
                        }
                        .map_err(|e| e.within(format!("sub-environment {i}")))
                    })
                    .collect::<Result<Vec<_>>>()
            })
            .py()?;
        let n = outs.len();
        let rewards: Vec<f32> = outs.iter().map(|o| o.reward).collect();
        let terminated: Vec<bool> = outs.iter().map(|o| o.terminated).collect();
        let truncated: Vec<bool> = outs.iter().map(|o| o.truncated).collect();
        let infos = PyList::empty(py);
        for o in &outs {
            infos.append(info_to_py(py, &o.info)?)?;
        }
        let obs = PyDict::new(py);
        let first = &outs[0].obs;
        if let Some(im) = &first.images {
            let (w, h) = (im.width, im.height);
            let (dw, dh) = im.depth_size;
            macro_rules! stack {
                ($key:literal, $field:ident, $dim:expr) => {
                    if im.$field.is_some() {
                        let mut all = Vec::new();
                        for o in &outs {
                            if let Some(v) = o.obs.images.as_ref().and_then(|i| i.$field.as_ref()) {
                                all.extend_from_slice(v);
                            }
                        }
                        obs.set_item($key, array(py, $dim, all)?)?;
                    }
                };
            }
            stack!("rgb", rgb, Ix4(n, h, w, 3));
            stack!("depth", depth, Ix3(n, dh, dw));
            stack!("semantic", semantic, Ix3(n, h, w));
            stack!("instance", instance, Ix3(n, h, w));
        }
        let poses: Vec<f32> = outs
            .iter()
            .flat_map(|o| {
                let p = o.obs.pose;
                [p.position.x, p.position.y, p.position.z, p.yaw]
            })
            .collect();
        obs.set_item("pose", array(py, Ix2(n, 4), poses)?)?;
        let instructions: Vec<String> =
            outs.iter().map(|o| o.obs.instruction.to_string()).collect();
        obs.set_item("instruction", instructions)?;
        Ok((
            obs,
            array(py, Ix1(n), rewards)?,
            array(py, Ix1(n), terminated)?,
            array(py, Ix1(n), truncated)?,
            infos.into_any(),
        ))
    }
}

#[pymethods]
impl VecSim {
    /// `num_envs` environments over one pool (as [`Sim`]).
    #[new]
    #[pyo3(signature = (num_envs, scenes, episodes, scene_of, preset="sage", overrides="{}", mode="sage"))]
    fn new(
        num_envs: usize,
        scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
        episodes: &str,
        scene_of: Vec<usize>,
        preset: &str,
        overrides: &str,
        mode: &str,
    ) -> PyResult<VecSim> {
        if num_envs == 0 {
            return Err(PyValueError::new_err("num_envs must be at least 1"));
        }
        let config = resolve_config(preset, &from_json(overrides, "overrides")?).py()?;
        let pool = pool(scenes, episodes, scene_of)?;
        let mode = mode_of(mode)?;
        Ok(VecSim {
            cores: (0..num_envs)
                .map(|_| Core::new(pool.clone(), config.clone(), mode))
                .collect(),
        })
    }

    /// Number of sub-environments.
    fn __len__(&self) -> usize {
        self.cores.len()
    }

    /// Number of episodes in the pool.
    fn num_episodes(&self) -> usize {
        self.cores.first().map_or(0, |c| c.pool.episodes.len())
    }

    /// Resets every sub-environment, `indices[i]` the episode of sub-environment `i`; returns
    /// `(obs, infos)` with stacked observations and a list of info dicts.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        indices: Vec<usize>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
        self.check_len(indices.len())?;
        let (obs, _, _, _, infos) =
            self.run(py, indices.into_iter().map(Order::Reset).collect())?;
        Ok((obs, infos))
    }

    /// One step of every sub-environment: `actions[i]`, or a reset to episode `resets[i]` where
    /// that is not `None` (the autoreset of a finished one; its reward is 0 and it is neither
    /// terminated nor truncated). Returns `(obs, rewards, terminated, truncated, infos)`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: Vec<Bound<'py, PyAny>>,
        resets: Vec<Option<usize>>,
    ) -> PyResult<Batch<'py>> {
        self.check_len(actions.len())?;
        self.check_len(resets.len())?;
        let orders = actions
            .iter()
            .zip(resets)
            .zip(&self.cores)
            .map(|((a, r), core)| match r {
                Some(k) => Ok(Order::Reset(k)),
                None => parse_action(&core.config.actions, a).map(Order::Step),
            })
            .collect::<PyResult<Vec<_>>>()?;
        self.run(py, orders)
    }
}

impl VecSim {
    fn check_len(&self, n: usize) -> PyResult<()> {
        if n == self.cores.len() {
            Ok(())
        } else {
            Err(PyValueError::new_err(format!(
                "expected {} entries (one per sub-environment), got {n}",
                self.cores.len()
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn overrides_merge_key_by_key_over_the_preset_and_are_validated() {
        let c = resolve_config(
            "vlnce",
            &json!({"sensors": {"width": 32, "semantic": true}, "task": {"max_steps": 7}}),
        )
        .unwrap();
        let base = EnvConfig::preset("vlnce").unwrap();
        assert_eq!(
            (c.sensors.width, c.sensors.height),
            (32, base.sensors.height)
        );
        assert!(c.sensors.semantic && c.sensors.rgb);
        assert_eq!(c.sensors.depth_size, base.sensors.depth_size);
        assert_eq!(c.task.max_steps, 7);
        assert_eq!(c.task.success_distance, base.task.success_distance);
        let ground = resolve_config(
            "sage",
            &json!({"actions": {"kind": "ground", "max_dt": 0.5}}),
        );
        assert_eq!(ground.unwrap().actions, ActionSpace::Ground { max_dt: 0.5 });
        let e = resolve_config("sage", &json!({"sensors": {"hfov_deg": 200.0}})).unwrap_err();
        assert!(e.to_string().contains("hfov_deg"), "{e}");
        let e = resolve_config("sage", &json!({"sensors": {"width": "wide"}})).unwrap_err();
        assert!(e.to_string().contains("environment config"), "{e}");
        assert!(resolve_config("habitat", &json!({})).is_err());
    }
}
