//! What the environment needs of an episode, and what it hands back when the episode ends.
//!
//! [`EnvEpisode`] is the part of a dataset episode (SPEC §9) that drives the environment: the
//! benchmark converts its own episode records into it, so this crate never depends on the
//! benchmark crate. Each step leaves a [`StepInfo`]; the last one says why the episode ended
//! ([`Termination`]); the [`EpisodeTrace`] holds them all.

use crate::action::Action;
use glam::Vec3;
use sage_core::{Pose, Task};
use sage_nav::{EndpointKind, Trajectory};
use serde::{Deserialize, Serialize};

/// The goal of a VLN episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvGoal {
    /// The goal point (the reference path's end), W frame.
    pub point: Vec3,
    /// The end object's item id (`sofa_2`) when the goal is an object: its footprint is then
    /// the goal region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    /// The heading a pose goal asks for (a Base-Action motion's end), radians: success then
    /// needs the pose, not only the place (`sage_metrics::distance::GoalRegion::reached`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading: Option<f32>,
}

/// One episode as the environment runs it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvEpisode {
    /// Episode id.
    pub id: String,
    /// The task.
    pub task: Task,
    /// The instruction shown to the agent.
    pub instruction: String,
    /// Start pose (floor position, heading).
    pub start: Pose,
    /// The goal (VLN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<EnvGoal>,
    /// The dense reference path, W frame.
    #[serde(default)]
    pub reference_path: Vec<Vec3>,
}

/// Why an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The agent called STOP.
    Stop,
    /// The step limit was reached.
    MaxSteps,
    /// NoGoal: a collision event.
    Collision,
    /// NoGoal: the simulated time limit was reached.
    TimeLimit,
    /// The agent left the scene: outside every room and farther than
    /// [`crate::env::LEAVE_DISTANCE`] from the navigable area (through an exterior opening,
    /// say). Ends the episode unsuccessfully, whatever the task.
    LeftScene,
}

impl Termination {
    /// True when the task itself ended the episode (STOP, a NoGoal collision, leaving the
    /// scene): Gymnasium's `terminated`. The other endings are limits:
    /// [`Termination::is_truncation`].
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            Termination::Stop | Termination::Collision | Termination::LeftScene
        )
    }

    /// True when a step or time limit cut the episode: Gymnasium's `truncated`.
    pub fn is_truncation(self) -> bool {
        matches!(self, Termination::MaxSteps | Termination::TimeLimit)
    }
}

/// What one step did (the per-step record of an episode).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// The action.
    pub action: Action,
    /// Pose after the step.
    pub pose: Pose,
    /// Camera pitch after the step, radians.
    pub pitch: f32,
    /// Simulated seconds since reset, after the step.
    pub time: f32,
    /// Commanded translation length, metres.
    pub commanded: f32,
    /// Achieved translation along the command, metres.
    pub achieved: f32,
    /// Instance ids of the bodies touched.
    pub touched: Vec<u32>,
    /// Collision intensity c(t) (SPEC §6).
    pub intensity: f32,
    /// Contact began this step after a step without.
    pub collision: bool,
    /// No progress for several commanded moves.
    pub stuck: bool,
    /// Euclidean distance from the agent to the goal region (VLN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance_to_goal: Option<f32>,
    /// Set on the step that ended the episode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub termination: Option<Termination>,
}

/// Geodesic distances of a finished VLN episode (metres; `None` when unreachable).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TraceGeodesics {
    /// Start to the goal region (L*).
    pub start_to_region: Option<f32>,
    /// Final position to the goal region (NE).
    pub final_to_region: Option<f32>,
    /// Start to the goal point (VLN-CE's d0).
    pub start_to_point: Option<f32>,
    /// Each step's position to the goal point (VLN-CE's distance_to_goal).
    pub steps_to_point: Vec<Option<f32>>,
}

/// A finished (or running) episode: everything the metrics need.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeTrace {
    /// The episode.
    pub episode: EnvEpisode,
    /// The goal region's footprint when the goal is an object of the scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal_footprint: Option<Vec<[f32; 2]>>,
    /// The steps taken.
    pub steps: Vec<StepInfo>,
    /// Why the episode ended (`None` while it runs).
    pub termination: Option<Termination>,
    /// Geodesic distances from the scene's path finder.
    pub geodesics: TraceGeodesics,
}

impl EnvEpisode {
    /// A VLN episode along a planned trajectory of `sage_nav` (its start pose, goal object or
    /// point and reference path), with `instruction`: what tests and benchmarks run when no
    /// dataset is at hand.
    pub fn from_trajectory(id: impl Into<String>, t: &Trajectory, instruction: &str) -> EnvEpisode {
        let object = (t.goal.kind == EndpointKind::Object).then(|| t.goal.reference.clone());
        EnvEpisode {
            id: id.into(),
            task: Task::Vln,
            instruction: instruction.to_string(),
            start: Pose::new(
                Vec3::from(t.start.point),
                t.headings.first().copied().unwrap_or(0.0),
            ),
            goal: Some(EnvGoal {
                point: Vec3::from(t.goal.point),
                object,
                heading: None,
            }),
            reference_path: t.points.iter().map(|&p| Vec3::from(p)).collect(),
        }
    }
}

impl EpisodeTrace {
    /// True when the agent called STOP.
    pub fn stop_called(&self) -> bool {
        self.termination == Some(Termination::Stop)
    }
}
