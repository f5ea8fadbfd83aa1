//! Agents written in Python, driven by the Rust evaluator through the environment's
//! [`Agent`] trait.

use crate::convert::to_py;
use crate::sim::{obs_to_py, parse_action};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sage_core::{Error, Result};
use sage_env::agents::Agent;
use sage_env::{Action, ActionSpace, Env, EnvEpisode, Observation};

/// A Python object with `act(obs) -> action` and optionally `reset(episode)`: `obs` is the
/// dict of NumPy arrays the Gymnasium environment returns, `episode` the environment's episode
/// (id, task, instruction, start, goal, reference path), the action an integer (discrete) or a
/// vector (continuous), as `SageEnv.step` takes it.
pub struct PyAgent {
    obj: Py<PyAny>,
    name: String,
    space: ActionSpace,
}

impl PyAgent {
    /// Wraps `obj`, reported as `name`.
    pub fn new(obj: Py<PyAny>, name: String) -> PyAgent {
        PyAgent {
            obj,
            name,
            space: ActionSpace::default(),
        }
    }
}

/// A Python exception as a sage3d error naming the agent.
fn agent_error(name: &str, e: PyErr) -> Error {
    Error::invalid(format!("python agent {name}: {e}"))
}

impl Agent for PyAgent {
    fn name(&self) -> &str {
        &self.name
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        self.space = env.config().actions;
        Python::attach(|py| {
            let obj = self.obj.bind(py);
            if obj.hasattr("reset")? {
                obj.call_method1("reset", (to_py(py, episode)?,))?;
            }
            Ok(())
        })
        .map_err(|e| agent_error(&self.name, e))
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        Python::attach(|py| {
            let a = self
                .obj
                .bind(py)
                .call_method1("act", (obs_to_py(py, obs.clone())?,))?;
            match parse_action(&self.space, &a)? {
                // What `SageEnv` offers by default (`Discrete(4)`): a policy is scored with
                // the actions it was trained with, not with the camera tilts beyond them.
                Action::LookUp | Action::LookDown => Err(PyValueError::new_err(format!(
                    "action: {a} is a camera tilt (LOOK_UP / LOOK_DOWN), which an evaluated \
                     agent is not offered: it answers 0-3, as SageEnv.step takes them"
                ))),
                action => Ok(action),
            }
        })
        .map_err(|e| agent_error(&self.name, e))
    }
}
