//! The environment for Python: [`Sim`] wraps one [`sage_env::PooledEnv`], [`VecSim`] one
//! [`sage_env::VecEnv`] (several stepped in parallel in one call). Rewards, episode ends and the
//! info record come from sage-env; this module only translates: it releases the GIL while they
//! reset, step and render, and hands images out as NumPy arrays that own the rendered buffers.

use crate::convert::{PyResultExt, arg_extractors, array, drop_none, from_json, to_py};
use numpy::ndarray::{Ix1, Ix2, Ix3, Ix4};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sage_core::Error;
use sage_dataset::Episode;
use sage_env::pool::{Order, Transition};
use sage_env::{Action, ActionSpace, EnvConfig, Observation, Pool, PoolEpisode, PooledEnv, VecEnv};
use sage_metrics::Mode;
use serde::Serialize;
use std::sync::Arc;

/// What a single step hands Python: observation, reward, terminated, truncated, info.
type PyTransition<'py> = (Bound<'py, PyDict>, f32, bool, bool, Bound<'py, PyAny>);

/// What a vector step hands Python: observations (a dict of stacked arrays), rewards,
/// terminated and truncated flags, and infos.
type Batch<'py> = (
    Bound<'py, PyDict>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
);

/// An info record as a Python dict, undefined values dropped (see [`drop_none`]).
fn info_to_py<'py>(py: Python<'py>, info: &sage_env::pool::Info) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(info)
        .map_err(|e| Error::invalid(format!("info: {e}")))
        .py()?;
    let info = py.import("json")?.call_method1("loads", (text,))?;
    drop_none(&info)?;
    Ok(info)
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
/// episode's scene; the dataset episodes come back too, for Python to read.
fn pool(
    scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
    episodes: &str,
    scene_of: Vec<usize>,
) -> PyResult<(Arc<Pool>, Vec<Episode>)> {
    let episodes: Vec<Episode> = from_json(episodes, "episodes")?;
    if episodes.len() != scene_of.len() {
        return Err(PyValueError::new_err(
            "episodes and scene_of must have the same length",
        ));
    }
    if let Some(&k) = scene_of.iter().find(|&&k| k >= scenes.len()) {
        return Err(PyIndexError::new_err(format!(
            "scene index {k} out of range"
        )));
    }
    let entries = episodes
        .iter()
        .zip(scene_of)
        .map(|(e, scene)| PoolEpisode {
            scene,
            scene_name: e.scene.clone(),
            episode: e.env_episode(),
        })
        .collect();
    let scenes = scenes.iter().map(|s| s.ctx.clone()).collect();
    Ok((Arc::new(Pool::new(scenes, entries).py()?), episodes))
}

/// The agent profile's limits that bound the continuous action spaces.
#[derive(Serialize)]
struct Limits {
    name: &'static str,
    max_speed: f32,
    max_climb: f32,
    max_yaw_rate: f32,
    camera_height: f32,
}

arg_extractors! {
    env_config_preset: String = "env_config: preset";
    env_config_overrides: String = "env_config: overrides";
}

/// Resolves a preset plus JSON overrides for Python callers (the Gymnasium wrappers read
/// spaces from it), with the agent profile's limits under `profile`.
#[pyfunction]
#[pyo3(
    signature = (preset="sage".to_string(), overrides="{}".to_string()),
    // PyO3 shows a default it cannot print as a Python literal (`"sage".to_string()`) as `...`:
    // the signature `help()` and `inspect.signature` read is written out here.
    text_signature = "(preset='sage', overrides='{}')"
)]
pub fn env_config<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = env_config_preset)] preset: String,
    #[pyo3(from_py_with = env_config_overrides)] overrides: String,
) -> PyResult<Bound<'py, PyAny>> {
    let overrides = from_json(&overrides, "env_config: overrides")?;
    let config = EnvConfig::with_overrides(&preset, &overrides).py()?;
    let profile = config.profile().py()?;
    let out = to_py(py, &config)?;
    out.set_item(
        "profile",
        to_py(
            py,
            &Limits {
                name: profile.name,
                max_speed: profile.max_speed,
                max_climb: profile.max_climb,
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
    env: PooledEnv,
    episodes: Vec<Episode>,
    render_device: Option<String>,
}

#[pymethods]
impl Sim {
    /// An environment over `episodes` (JSON list of dataset episodes), episode `i` running in
    /// `scenes[scene_of[i]]`, with `preset` plus the JSON `overrides`; episode metrics in `mode`.
    /// The renderer of the first episode's scene opens here, so a `device` that cannot render
    /// fails at once.
    #[new]
    #[pyo3(signature = (scenes, episodes, scene_of, preset="sage", overrides="{}", mode="sage"))]
    fn new(
        py: Python<'_>,
        scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
        episodes: &str,
        scene_of: Vec<usize>,
        preset: &str,
        overrides: &str,
        mode: &str,
    ) -> PyResult<Sim> {
        let config = EnvConfig::with_overrides(preset, &from_json(overrides, "overrides")?).py()?;
        let (pool, episodes) = pool(scenes, episodes, scene_of)?;
        let first = pool.episodes[0].scene;
        let mut env = PooledEnv::new(pool, config, mode_of(mode)?);
        let render_device = py
            .detach(|| {
                env.open(first)
                    .map(|e| e.render_device().map(str::to_owned))
            })
            .py()?;
        Ok(Sim {
            env,
            episodes,
            render_device,
        })
    }

    /// Which renderer forms the images, in words (`cpu (8 threads)`, `gpu: …`, or the CPU
    /// with the reason `auto` took no GPU); `None` when no image is configured.
    #[getter]
    fn render_device(&self) -> Option<String> {
        self.render_device.clone()
    }

    /// Number of episodes in the pool.
    fn __len__(&self) -> usize {
        self.env.pool().episodes.len()
    }

    /// The pool's episodes as dicts (dataset schema).
    fn episodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.episodes)
    }

    /// Starts episode `index`; returns `(obs, info)`.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        index: usize,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
        let env = &mut self.env;
        let out = py.detach(|| env.reset(index)).py()?;
        Ok((obs_to_py(py, out.obs)?, info_to_py(py, &out.info)?))
    }

    /// Applies one action; returns `(obs, reward, terminated, truncated, info)`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: &Bound<'py, PyAny>,
    ) -> PyResult<PyTransition<'py>> {
        let action = parse_action(&self.env.config().actions, action)?;
        let env = &mut self.env;
        let out = py.detach(|| env.step(action)).py()?;
        let info = info_to_py(py, &out.info)?;
        Ok((
            obs_to_py(py, out.obs)?,
            out.reward,
            out.terminated,
            out.truncated,
            info,
        ))
    }
}

/// Several environments over one pool, stepped in parallel in one call (the engine under
/// `sage3d.SageVectorEnv`): observations come back stacked along a leading axis.
#[pyclass(module = "sage3d._sage3d")]
pub struct VecSim {
    envs: VecEnv,
    render_device: Option<String>,
}

impl VecSim {
    /// Runs `orders` in parallel and returns the batch as Python objects.
    fn run<'py>(&mut self, py: Python<'py>, orders: Vec<Order>) -> PyResult<Batch<'py>> {
        let envs = &mut self.envs;
        let outs: Vec<Transition> = py.detach(|| envs.run(orders)).py()?;
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

    fn check_len(&self, n: usize) -> PyResult<()> {
        let want = self.envs.envs().len();
        if n == want {
            Ok(())
        } else {
            Err(PyValueError::new_err(format!(
                "expected {want} entries (one per sub-environment), got {n}"
            )))
        }
    }
}

#[pymethods]
impl VecSim {
    /// `num_envs` environments over one pool (as [`Sim`]).
    #[new]
    #[pyo3(signature = (num_envs, scenes, episodes, scene_of, preset="sage", overrides="{}", mode="sage"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        num_envs: usize,
        scenes: Vec<PyRef<'_, crate::scene::PyScene>>,
        episodes: &str,
        scene_of: Vec<usize>,
        preset: &str,
        overrides: &str,
        mode: &str,
    ) -> PyResult<VecSim> {
        let config = EnvConfig::with_overrides(preset, &from_json(overrides, "overrides")?).py()?;
        let (pool, _) = pool(scenes, episodes, scene_of)?;
        let first = pool.episodes[0].scene;
        let mut envs = VecEnv::new(num_envs, pool, config, mode_of(mode)?).py()?;
        let render_device = py
            .detach(|| {
                envs.open(first)
                    .map(|e| e.render_device().map(str::to_owned))
            })
            .py()?;
        Ok(VecSim {
            envs,
            render_device,
        })
    }

    /// Which renderer forms the images (as [`Sim`]'s); the sub-environments over a scene on
    /// the GPU render from one upload of it, their cameras in one batch per step.
    #[getter]
    fn render_device(&self) -> Option<String> {
        self.render_device.clone()
    }

    /// Number of sub-environments.
    fn __len__(&self) -> usize {
        self.envs.envs().len()
    }

    /// Number of episodes in the pool.
    fn num_episodes(&self) -> usize {
        self.envs
            .envs()
            .first()
            .map_or(0, |e| e.pool().episodes.len())
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
            .zip(self.envs.envs())
            .map(|((a, r), env)| match r {
                Some(k) => Ok(Order::Reset(k)),
                None => parse_action(&env.config().actions, a).map(Order::Step),
            })
            .collect::<PyResult<Vec<_>>>()?;
        self.run(py, orders)
    }
}
