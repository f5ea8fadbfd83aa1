//! `sage-env`: the executable environment E_exec of sage3d (SPEC §1, §10, §11).
//!
//! A [`SceneContext`] loads what a scene needs once (Gaussians, semantic map, collision bodies,
//! path finder) and is shared by reference count; an [`Env`] over it serves any number of
//! episodes: [`Env::reset`] puts the agent at an episode's start, [`Env::step`] applies one
//! [`Action`] through the physics agent, advances simulated time, renders the configured
//! sensors and applies the task's termination rules (`vln`, `nogoal`). [`agents`] holds the
//! [`agents::Agent`] trait (observation → action) and the local baselines. Conventions are
//! documented in `docs/environment.md`.
//!
//! It is the one door to an environment for every front end: [`SceneContext::load`] opens a
//! scene folder, [`reward`] holds the tasks' rewards, [`scoring`] turns a finished
//! [`EpisodeTrace`] into the metrics of `sage-metrics`, and [`pool`] runs environments over a
//! pool of episodes in many scenes, one at a time or several in parallel (what the Python
//! environments and vector environments wrap). Episodes come in as [`EnvEpisode`] (the part of
//! a dataset episode the environment uses), so this crate never depends on the benchmark crate.
//!
//! Images are rendered on the configuration's device ([`EnvConfig::device`], through
//! `sage_splat::Backend`): every environment over a scene renders through the scene's one
//! renderer ([`SceneContext::renderer`]): on the CPU a pool lending a renderer per render, on a
//! GPU one upload of the Gaussians, to which a [`VecEnv`] sends the cameras of its
//! environments over the scene in one batch per step.

pub mod action;
pub mod agents;
pub mod config;
pub mod context;
pub mod env;
pub mod episode;
pub mod pool;
pub mod reward;
pub mod scoring;

pub use action::Action;
pub use config::{ActionSpace, EnvConfig, SensorConfig, TaskConfig};
pub use context::SceneContext;
pub use env::{Env, Images, Observation, Pending};
pub use episode::{EnvEpisode, EnvGoal, EpisodeTrace, StepInfo, Termination};
pub use pool::{Pool, PoolEpisode, PooledEnv, Transition, VecEnv};
