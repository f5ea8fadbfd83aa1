//! The path follower: an agent that walks an episode's reference path with a preset's
//! discrete actions, deciding each action from where physics actually put it.

use crate::preset::ActionPreset;
use glam::Vec2;
use sage_core::{Error, Result, wrap_angle};
use sage_env::agents::Agent;
use sage_env::{Action, Env, EnvEpisode, Observation};

/// Forward moves in a row that make almost no progress before the follower gives up.
const MAX_BLOCKED: usize = 3;

/// How a follower's walk ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// It reached the end of the reference path (within half a step) and called STOP.
    Reached,
    /// The preset's cap on motions was hit (a rotation in place counts each turn); it called
    /// STOP where it stood.
    Capped,
    /// Three forward moves in a row were blocked; it called STOP where it stood.
    Blocked,
}

/// Walks the reference path: skips waypoints closer than one step, turns towards the next one
/// until it lies within half a turn of the heading, else moves forward; STOP within half a
/// step of the path's end — or earlier, once within the success distance of the goal, when the
/// next step would leave the navigable grid (a path's end often lies beside its object with
/// no room to spare) — as the published pipeline ends a trajectory where its path ends
/// (an object goal is not approached further: the straight line to its footprint may cross a
/// wall). Because every decision is taken from the achieved pose, a step that
/// physics shortened is made up by the following ones, as a robot replaying the path would.
/// A reference path of a single point is a rotation in place ([`PathFollower::rotate_in_place`]),
/// whose turns count against the cap as every other motion does.
#[derive(Clone)]
pub struct PathFollower {
    step: f32,
    turn: f32,
    max_actions: usize,
    waypoints: Vec<Vec2>,
    next: usize,
    motions: usize,
    last_forward_from: Option<Vec2>,
    blocked: usize,
    ending: Option<Ending>,
    /// Turns left to take in place (negative: right), for an episode that only rotates.
    spin: i32,
    /// The scene (its navigable grid) and the goal with its success distance.
    scene: Option<std::sync::Arc<sage_env::SceneContext>>,
    goal: Option<Vec2>,
    success: f32,
}

/// How far inside the success distance the follower must be to stop short of an obstacle.
const STOP_MARGIN: f32 = 0.05;

impl PathFollower {
    /// A follower with `preset`'s step, turn and cap.
    pub fn new(preset: &ActionPreset) -> PathFollower {
        PathFollower {
            step: preset.step_m,
            turn: preset.turn_deg.to_radians(),
            max_actions: preset.max_actions,
            waypoints: Vec::new(),
            next: 0,
            motions: 0,
            last_forward_from: None,
            blocked: 0,
            ending: None,
            spin: 0,
            scene: None,
            goal: None,
            success: 0.0,
        }
    }

    /// Makes the next walk a rotation in place of `turns` turns (negative: to the right)
    /// instead of a walk along the reference path: what a Base-Action rotation asks for.
    pub fn rotate_in_place(&mut self, turns: i32) {
        self.spin = turns;
    }

    /// How the last walk ended (`None` before STOP).
    pub fn ending(&self) -> Option<Ending> {
        self.ending
    }

    fn stop(&mut self, why: Ending) -> Action {
        self.ending = Some(why);
        Action::Stop
    }
}

impl PathFollower {
    /// True when a forward step from `at` along `yaw` would cross a cell the agent does not
    /// fit in (sampled every 5 cm).
    fn leaves_free_space(&self, at: Vec2, yaw: f32) -> bool {
        self.scene.as_ref().is_some_and(|ctx| {
            sage_env::agents::step_leaves_navigable(&ctx.pathfinder, at, yaw, self.step)
        })
    }

    /// True when `at` is well inside the success distance of the goal position.
    fn near_goal(&self, at: Vec2) -> bool {
        self.goal
            .is_some_and(|g| at.distance(g) <= self.success - STOP_MARGIN)
    }
}

impl Agent for PathFollower {
    fn name(&self) -> &str {
        "path-follower"
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        if episode.reference_path.is_empty() {
            return Err(Error::invalid(format!(
                "episode {}: no reference path to follow",
                episode.id
            )));
        }
        self.waypoints = episode
            .reference_path
            .iter()
            .map(|p| p.truncate())
            .collect();
        self.next = 1.min(self.waypoints.len() - 1);
        self.motions = 0;
        self.last_forward_from = None;
        self.blocked = 0;
        self.ending = None;
        self.scene = Some(env.context().clone());
        self.goal = episode.goal.as_ref().map(|g| g.point.truncate());
        self.success = env.config().task.success_distance;
        Ok(())
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        if self.waypoints.len() == 1 {
            let turn = match self.spin.signum() {
                1 => Action::TurnLeft,
                -1 => Action::TurnRight,
                _ => return Ok(self.stop(Ending::Reached)),
            };
            // Each turn in place is a motion: the cap bounds a rotation as it bounds a walk.
            if self.motions >= self.max_actions {
                return Ok(self.stop(Ending::Capped));
            }
            self.motions += 1;
            self.spin -= self.spin.signum();
            return Ok(turn);
        }
        let at = obs.pose.position.truncate();
        if let Some(from) = self.last_forward_from.take() {
            if at.distance(from) < 0.1 * self.step {
                self.blocked += 1;
            } else {
                self.blocked = 0;
            }
        }
        if self.blocked >= MAX_BLOCKED {
            return Ok(self.stop(Ending::Blocked));
        }
        let last = self.waypoints.len() - 1;
        while self.next < last && at.distance(self.waypoints[self.next]) < self.step {
            self.next += 1;
        }
        if self.next == last && at.distance(self.waypoints[last]) < 0.5 * self.step {
            return Ok(self.stop(Ending::Reached));
        }
        if self.motions >= self.max_actions {
            return Ok(self.stop(Ending::Capped));
        }
        self.motions += 1;
        let d = self.waypoints[self.next] - at;
        let error = wrap_angle(d.y.atan2(d.x) - obs.pose.yaw);
        Ok(if error > 0.5 * self.turn {
            Action::TurnLeft
        } else if error < -0.5 * self.turn {
            Action::TurnRight
        } else if self.leaves_free_space(at, obs.pose.yaw) && self.near_goal(at) {
            // The last stretch of a path often ends beside its object with no room to spare:
            // stop within the success distance rather than step into it.
            self.stop(Ending::Reached)
        } else {
            self.last_forward_from = Some(at);
            Action::MoveForward
        })
    }
}
