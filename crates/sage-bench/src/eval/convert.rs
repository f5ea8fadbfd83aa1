//! The bridge between the benchmark and the environment: a dataset episode becomes an
//! environment episode, a finished trace becomes the metrics' record, an agent name becomes an
//! agent, and a scene folder becomes a loaded [`SceneContext`]. The environment crate does not
//! know the benchmark crate, so these live here.

use crate::dataset::{Episode, Task};
use crate::metrics::distance::{GoalRegion, LabelledBox, OfficialGoal, official_goal_box};
use crate::metrics::{EpisodeRecord, Geodesics, StepRecord};
use glam::{Vec2, Vec3};
use sage_core::{Error, Result};
use sage_env::agents::{Agent, ForwardAgent, OracleAgent, RandomAgent};
use sage_env::{EnvEpisode, EnvGoal, EnvTask, EpisodeTrace, SceneContext};
use sage_nav::TrajectoryParams;
use sage_physics::{Decomposer, HullCache, SceneBodies, default_cache_dir};
use sage_scene::Scene;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The agents an evaluation can name on the command line; new kinds (remote model servers,
/// replay) slot in as variants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AgentKind {
    /// Uniform FORWARD / LEFT / RIGHT with a small STOP probability, seeded per episode.
    Random,
    /// FORWARD until the step limit.
    Forward,
    /// The shortest-path follower (privileged: reads the scene's path finder).
    Oracle,
}

impl AgentKind {
    /// Every kind, in the order error messages list them.
    pub const ALL: [AgentKind; 3] = [AgentKind::Random, AgentKind::Forward, AgentKind::Oracle];

    /// The kind's name as written in flags and files.
    pub fn as_str(self) -> &'static str {
        match self {
            AgentKind::Random => "random",
            AgentKind::Forward => "forward",
            AgentKind::Oracle => "oracle",
        }
    }

    /// A fresh agent of this kind (`seed` drives the random agent).
    ///
    /// # Errors
    ///
    /// The agent's own parameter checks.
    pub fn build(self, seed: u64) -> Result<Box<dyn Agent>> {
        Ok(match self {
            AgentKind::Random => Box::new(RandomAgent::new(seed, 0.02)?),
            AgentKind::Forward => Box::new(ForwardAgent::new(None)),
            AgentKind::Oracle => Box::new(OracleAgent::new(0.25)),
        })
    }
}

impl fmt::Display for AgentKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for AgentKind {
    type Err = Error;

    fn from_str(s: &str) -> Result<AgentKind> {
        let name = s.trim().to_ascii_lowercase();
        AgentKind::ALL
            .into_iter()
            .find(|k| k.as_str() == name)
            .ok_or_else(|| {
                let valid: Vec<&str> = AgentKind::ALL.iter().map(|k| k.as_str()).collect();
                Error::invalid(format!(
                    "unknown agent '{s}' (expected one of: {})",
                    valid.join(", ")
                ))
            })
    }
}

/// The environment's view of a dataset episode: an object goal names its item id, so the
/// object's footprint becomes the goal region.
pub fn env_episode(e: &Episode) -> EnvEpisode {
    EnvEpisode {
        id: e.episode_id.clone(),
        task: match e.task {
            Task::Vln => EnvTask::Vln,
            Task::Nogoal => EnvTask::Nogoal,
        },
        instruction: e.instruction.clone(),
        start: e.start.pose(),
        goal: e.goal.as_ref().map(|g| EnvGoal {
            point: Vec3::from(g.position),
            object: (g.kind == "object").then(|| g.reference.clone()),
        }),
        reference_path: e.reference_path.iter().map(|&p| Vec3::from(p)).collect(),
    }
}

/// The metrics' record of a finished trace; the published code's goal box is chosen among
/// the scene's semantic-map objects and walls.
pub fn metric_record(ctx: &SceneContext, t: &EpisodeTrace) -> EpisodeRecord {
    let f = |v: Vec2| [f64::from(v.x), f64::from(v.y)];
    let boxes: Vec<LabelledBox> = ctx
        .semantic
        .items
        .iter()
        .map(|i| (i.category.clone(), &i.polygon))
        .chain(
            ctx.semantic
                .walls
                .iter()
                .map(|w| ("wall".to_string(), &w.polygon)),
        )
        .map(|(label, poly)| {
            let lo = poly.iter().fold(Vec2::INFINITY, |m, p| m.min(*p));
            let hi = poly.iter().fold(Vec2::NEG_INFINITY, |m, p| m.max(*p));
            LabelledBox {
                label,
                min: f(lo),
                max: f(hi),
            }
        })
        .collect();
    let e = &t.episode;
    let goal = e.goal.as_ref().map(|g| GoalRegion {
        point: f(g.point.truncate()),
        footprint: t.goal_footprint.as_ref().map(|p| {
            p.iter()
                .map(|q| [f64::from(q[0]), f64::from(q[1])])
                .collect()
        }),
    });
    let official_goal = OfficialGoal::Map {
        chosen: e
            .reference_path
            .last()
            .or(e.goal.as_ref().map(|g| &g.point))
            .and_then(|p| official_goal_box(&boxes, f(p.truncate()))),
    };
    EpisodeRecord {
        episode_id: e.id.clone(),
        task: match e.task {
            EnvTask::Vln => Task::Vln,
            EnvTask::Nogoal => Task::Nogoal,
        },
        start: e.start.position.to_array(),
        start_yaw: e.start.yaw,
        steps: t
            .steps
            .iter()
            .enumerate()
            .map(|(k, s)| StepRecord {
                position: s.pose.position.to_array(),
                yaw: s.pose.yaw,
                time: s.time,
                commanded: s.commanded,
                achieved: s.achieved,
                contact: !s.touched.is_empty(),
                intensity: s.intensity,
                geodesic_to_goal_point: t.geodesics.steps_to_point.get(k).copied().flatten(),
            })
            .collect(),
        stop_called: t.stop_called(),
        reference_path: e.reference_path.iter().map(|p| p.to_array()).collect(),
        goal,
        geodesics: Geodesics {
            start_to_region: t.geodesics.start_to_region,
            final_to_region: t.geodesics.final_to_region,
            start_to_point: t.geodesics.start_to_point,
        },
        official_goal,
    }
}

/// Loads a scene folder with its collision bodies (hulls cached in `cache`, by default beside
/// the scene) and the path finder of the default trajectory settings.
///
/// # Errors
///
/// The scene, its bodies or its navigation grid cannot be built.
pub fn load_context(dir: &Path, cache: Option<PathBuf>) -> Result<SceneContext> {
    let (scene, _) = Scene::load(dir)?;
    let cache = HullCache::new(cache.unwrap_or_else(|| default_cache_dir(dir)));
    let (bodies, _) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
    let params = TrajectoryParams::default();
    SceneContext::new(scene, bodies, &params.grid, params.cost)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agent_names_round_trip_and_unknown_names_list_the_valid_ones() {
        for k in AgentKind::ALL {
            assert_eq!(k.as_str().parse::<AgentKind>().unwrap(), k);
        }
        assert_eq!(" Oracle ".parse::<AgentKind>().unwrap(), AgentKind::Oracle);
        let e = "genius".parse::<AgentKind>().unwrap_err().to_string();
        assert!(
            e.contains("'genius'") && e.contains("random, forward, oracle"),
            "{e}"
        );
    }
}
