//! Rewards for learning in the environment, as Habitat's navigation reward defines them.
//!
//! VLN pays the decrease of the distance to the goal region each step, minus a slack of 0.01,
//! plus 2.5 when the agent calls STOP within the success distance; NoGoal pays the metres
//! achieved along the command, minus the slack. Episode ends map to Gymnasium's flags through
//! [`crate::Termination::is_terminal`] and [`crate::Termination::is_truncation`].

use crate::context::SceneContext;
use crate::episode::EnvEpisode;
use crate::episode::{StepInfo, Termination};
use sage_core::Task;

/// Reward per step for existing (Habitat's slack reward).
pub const SLACK: f32 = 0.01;
/// Reward for a successful STOP (Habitat's success reward).
pub const SUCCESS_REWARD: f32 = 2.5;

/// The reward of one running episode: remembers the last distance to the goal region that the
/// next step's progress is measured from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reward {
    task: Task,
    last_distance: Option<f32>,
}

impl Reward {
    /// The reward of `episode` at its start in `ctx`.
    pub fn start(ctx: &SceneContext, episode: &EnvEpisode) -> Reward {
        Reward {
            task: episode.task,
            last_distance: start_distance(ctx, episode),
        }
    }

    /// The reward of one step; `within` tells whether the agent ends it within the success
    /// distance of the goal.
    pub fn step(&mut self, step: &StepInfo, within: bool) -> f32 {
        let reward = match self.task {
            Task::Nogoal => step.achieved - SLACK,
            Task::Vln => {
                let progress = match (self.last_distance, step.distance_to_goal) {
                    (Some(a), Some(b)) => a - b,
                    _ => 0.0,
                };
                let success = step.termination == Some(Termination::Stop) && within;
                progress - SLACK + if success { SUCCESS_REWARD } else { 0.0 }
            }
        };
        self.last_distance = step.distance_to_goal;
        reward
    }

    /// The distance to the goal region the last reward was measured to (`None` without a goal).
    pub fn last_distance(&self) -> Option<f32> {
        self.last_distance
    }
}

/// The Euclidean distance from the episode's start to its goal region (the footprint of its
/// goal object, else its goal point), which the first step's progress is measured from.
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
