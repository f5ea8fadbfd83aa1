//! Routes and their replay: episodes that share one walk are grouped into a route, and a
//! route is walked once through the environment (physics and camera), recording each action
//! with the pose it commanded and the pose it achieved.

use crate::follow::{Ending, PathFollower};
use crate::preset::ActionPreset;
use sage_core::{Result, wrap_angle};
use sage_dataset::Episode;
use sage_env::agents::Agent;
use sage_env::{Action, Env, Images, Observation, Pending, Termination};
use serde::{Deserialize, Serialize};

/// Episodes of one scene that share a start, a reference path and a goal, so one walk (one
/// set of frames) serves them all: the instructions written for one trajectory.
#[derive(Debug, Clone)]
pub struct Route {
    /// The scene.
    pub scene: String,
    /// The route's folder name: its first episode's id as a file-name stem
    /// ([`sage_io::names::stem`]: distinct ids, distinct folders).
    pub name: String,
    /// The episodes, in dataset order.
    pub episodes: Vec<Episode>,
}

/// Groups `episodes` into routes, in the order of each route's first episode.
pub fn routes(episodes: &[Episode]) -> Vec<Route> {
    let mut out: Vec<Route> = Vec::new();
    let mut index: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for e in episodes {
        let key = serde_json::json!([e.scene, e.start, e.reference_path, e.goal]).to_string();
        match index.get(&key) {
            Some(&i) => out[i].episodes.push(e.clone()),
            None => {
                index.insert(key, out.len());
                out.push(Route {
                    scene: e.scene.clone(),
                    name: sage_io::names::stem(&e.episode_id),
                    episodes: vec![e.clone()],
                });
            }
        }
    }
    out
}

/// One action of a walk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WalkStep {
    /// The action (`MOVE_FORWARD`, `TURN_LEFT`, `TURN_RIGHT`, `STOP`).
    pub action: String,
    /// The pose the frame of this step was taken at, before the action: `[x, y, yaw]` (W
    /// frame, metres, radians).
    pub pose: [f32; 3],
    /// Where the action was meant to take the agent: the pose plus one step or one turn.
    pub commanded: [f32; 3],
    /// Where physics put it.
    pub achieved: [f32; 3],
    /// The agent touched something during the action.
    pub contact: bool,
}

/// Why a route's walk is kept or dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Ended within the success distance (1 m) of the goal position without touching
    /// anything.
    Clean,
    /// Touched an obstacle on the way.
    Collided,
    /// Ended away from the goal: farther than the success distance from its position, a
    /// rotation in place short of its turn (cut by the motion cap), or out of the scene.
    FarFromGoal,
}

/// A finished walk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Walk {
    /// Every action, STOP last.
    pub steps: Vec<WalkStep>,
    /// `reached`, `capped` (the motion cap, or the environment's step limit), `blocked`
    /// (three blocked moves in a row) or `left_scene` (a move took the agent out of the scene,
    /// which ends the environment's episode).
    pub ending: String,
    /// Steps on which the agent touched something.
    pub contact_steps: usize,
    /// Straight-line distance from the final position to the goal position, metres.
    pub final_distance: Option<f32>,
    /// The verdict.
    pub verdict: Verdict,
}

/// The turns left of `episode`'s ground-truth actions less its turns right: how far a
/// rotation in place turns, in the dataset's turns.
pub fn net_turns(episode: &Episode) -> i32 {
    episode
        .actions
        .iter()
        .map(|a| match a {
            sage_lang::DiscreteAction::Left => 1,
            sage_lang::DiscreteAction::Right => -1,
            _ => 0,
        })
        .sum()
}

/// The turns of the preset that a rotation in place of `degrees` (positive: left) takes: as
/// many whole turns as fit, at least one (the published action generator's rule).
pub fn turns_in_place(degrees: f32, preset: &ActionPreset) -> i32 {
    if degrees == 0.0 {
        return 0;
    }
    let n = ((degrees.abs() / preset.turn_deg) + 1e-4).floor().max(1.0) as i32;
    n * degrees.signum() as i32
}

/// A walk under way, advanced one action at a time: its follower, its steps so far and the
/// observation the next action is chosen from. [`walk`] runs one to the end; a training-data
/// render on the GPU advances many in lockstep, so each step renders every walk's frame in one
/// batch.
pub struct Walker {
    follower: PathFollower,
    step_m: f32,
    turn: f32,
    steps: Vec<WalkStep>,
    obs: Option<Observation>,
    /// A rotation in place (a reference path of one point).
    rotation: bool,
    /// How the environment ended the episode on a motion (its step limit, the agent out of the
    /// scene): the walk ends there, with a STOP where the agent stands.
    ended: Option<Termination>,
}

impl Walker {
    /// Starts `route` in `env` (already set up with the preset's action space and the
    /// sensors) up to the rendering of its first frame. The walk is the route's first
    /// episode's: its start, reference path and goal, which the route's episodes share. A
    /// route whose path is a single point rotates in place by what its episode's ground-truth
    /// actions turn, at `dataset_turn_deg` degrees a turn (the dataset's action space).
    ///
    /// # Errors
    ///
    /// The episode cannot be started (its goal object is missing from the scene, …).
    pub fn start(
        env: &mut Env,
        route: &Route,
        preset: &ActionPreset,
        dataset_turn_deg: f32,
    ) -> Result<(Walker, Pending)> {
        let first = &route.episodes[0];
        let episode = first.env_episode();
        let mut follower = PathFollower::new(preset);
        let rotation = first.reference_path.len() == 1;
        if rotation {
            let net = net_turns(first);
            follower.rotate_in_place(turns_in_place(net as f32 * dataset_turn_deg, preset));
        }
        let pending = env.reset_unrendered(&episode)?;
        follower.reset(env, &episode)?;
        let walker = Walker {
            follower,
            step_m: preset.step_m,
            turn: preset.turn_deg.to_radians(),
            steps: Vec::new(),
            obs: None,
            rotation,
            ended: None,
        };
        Ok((walker, pending))
    }

    /// Takes the observation of the frame last pending; returns the frame's index (the
    /// action it is taken before).
    pub fn observe(&mut self, obs: Observation) -> usize {
        self.obs = Some(obs);
        self.steps.len()
    }

    /// The images of the frame last observed.
    pub fn images(&self) -> Option<&Images> {
        self.obs.as_ref().and_then(|o| o.images.as_ref())
    }

    /// Chooses the next action from the frame last observed and applies it (physics, no
    /// rendering): the next frame to render, or `None` once the walk called STOP (whose
    /// frame nobody sees). When a motion ends the environment's episode (its step limit, the
    /// agent out of the scene), the frame after it is still rendered and the walk then ends
    /// with a STOP where the agent stands, as at the motion cap; that STOP is recorded
    /// without a step (the episode is over), not moving and touching nothing.
    ///
    /// # Errors
    ///
    /// Nothing observed since the last action, or a step error.
    pub fn advance(&mut self, env: &mut Env) -> Result<Option<Pending>> {
        let Some(obs) = &self.obs else {
            return Err(sage_core::Error::invalid(
                "a walk advanced without a frame observed",
            ));
        };
        let p = obs.pose;
        let pose = [p.position.x, p.position.y, p.yaw];
        if self.ended.is_some() {
            self.steps.push(WalkStep {
                action: crate::preset::action_name(Action::Stop).into(),
                pose,
                commanded: pose,
                achieved: pose,
                contact: false,
            });
            return Ok(None);
        }
        let action = self.follower.act(obs)?;
        let commanded = match action {
            Action::MoveForward => [
                pose[0] + self.step_m * p.yaw.cos(),
                pose[1] + self.step_m * p.yaw.sin(),
                p.yaw,
            ],
            Action::TurnLeft => [pose[0], pose[1], wrap_angle(p.yaw + self.turn)],
            Action::TurnRight => [pose[0], pose[1], wrap_angle(p.yaw - self.turn)],
            _ => pose,
        };
        let (next, info) = env.step_unrendered(action)?;
        self.steps.push(WalkStep {
            action: crate::preset::action_name(action).into(),
            pose,
            commanded,
            achieved: [info.pose.position.x, info.pose.position.y, info.pose.yaw],
            // STOP does not move: what it reports touching was touched by the step before.
            contact: action != Action::Stop && !info.touched.is_empty(),
        });
        if action == Action::Stop {
            return Ok(None);
        }
        // The environment ended the episode on this motion: a further step would be refused.
        self.ended = info.termination;
        Ok(Some(next))
    }

    /// The walk so far, judged: the straight-line distance from where it ended to the
    /// route's goal position, within the success distance of `env`'s task and without
    /// contact for a clean verdict. A rotation in place that the motion cap cut short, and a
    /// walk that left the scene, did not end at their goal: `far_from_goal` unless they
    /// touched something.
    pub fn finish(&self, env: &Env, route: &Route) -> Walk {
        let steps = self.steps.clone();
        let contact_steps = steps.iter().filter(|s| s.contact).count();
        let end = steps.last().map_or(glam::Vec2::ZERO, |s| {
            glam::Vec2::new(s.achieved[0], s.achieved[1])
        });
        let final_distance = route.episodes[0]
            .goal
            .as_ref()
            .map(|g| end.distance(glam::Vec2::new(g.position[0], g.position[1])));
        let ending = match (self.ended, self.follower.ending()) {
            (Some(Termination::LeftScene), _) => "left_scene",
            (Some(_), _) | (None, Some(Ending::Capped)) => "capped",
            (None, Some(Ending::Blocked)) => "blocked",
            (None, _) => "reached",
        };
        // A rotation's goal is its heading, which a capped one falls short of; a walk out of
        // the scene fails in the environment whatever its distance.
        let short = ending == "left_scene" || (self.rotation && ending == "capped");
        let verdict = if contact_steps > 0 {
            Verdict::Collided
        } else if !short && final_distance.is_some_and(|d| d <= env.config().task.success_distance)
        {
            Verdict::Clean
        } else {
            Verdict::FarFromGoal
        };
        Walk {
            steps,
            ending: ending.into(),
            contact_steps,
            final_distance,
            verdict,
        }
    }
}

/// Walks `route` in `env` to the end ([`Walker`] alone): `on_frame(k, images)` gets the
/// observation taken before action `k` (the frame a model sees when it chooses that action).
///
/// # Errors
///
/// The episode cannot be started, a step or render error, or an error of `on_frame`.
pub fn walk(
    env: &mut Env,
    route: &Route,
    preset: &ActionPreset,
    dataset_turn_deg: f32,
    mut on_frame: impl FnMut(usize, &Images) -> Result<()>,
) -> Result<Walk> {
    let (mut walker, mut pending) = Walker::start(env, route, preset, dataset_turn_deg)?;
    loop {
        let outputs = env.render(pending.cameras())?;
        let k = walker.observe(env.observation(pending, outputs)?);
        if let Some(images) = walker.images() {
            on_frame(k, images)?;
        }
        match walker.advance(env)? {
            Some(next) => pending = next,
            None => return Ok(walker.finish(env, route)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_take_whole_turns_of_the_preset_at_least_one() {
        let p = ActionPreset::named("navila_small").unwrap();
        assert_eq!(turns_in_place(180.0, &p), 6);
        assert_eq!(turns_in_place(-90.0, &p), -3);
        assert_eq!(turns_in_place(45.0, &p), 1);
        assert_eq!(turns_in_place(15.0, &p), 1);
        assert_eq!(turns_in_place(0.0, &p), 0);
        let v = ActionPreset::named("vlnce").unwrap();
        assert_eq!(turns_in_place(-45.0, &v), -3);
    }
}
