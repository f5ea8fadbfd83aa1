//! Agents: the [`Agent`] trait (observation → action) and the local baselines of SPEC §11 —
//! random, forward-only and the shortest-path oracle — plus [`run_episode`], the loop that
//! drives one episode.
//!
//! The baselines act in the discrete action space. Remote agents (model servers) implement the
//! same trait.

use crate::action::Action;
use crate::config::ActionSpace;
use crate::env::{Env, Observation};
use crate::episode::{EnvEpisode, EpisodeTrace};
use glam::Vec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Polygon2, Result, wrap_angle};
use sage_metrics::distance::POSE_SUCCESS_DISTANCE;
use sage_nav::PathFinder;
use serde::{Deserialize, Serialize};

/// Something that chooses actions from observations.
pub trait Agent {
    /// A short name for reports (`random`, `forward`, `oracle`, …).
    fn name(&self) -> &str;

    /// Prepares for `episode` in `env` (which has just been reset to it). Privileged agents
    /// (the oracle) may read the scene through `env`; others only their own state.
    ///
    /// # Errors
    ///
    /// The agent cannot act in this environment (wrong action space, no path, …).
    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()>;

    /// The next action after `obs`.
    ///
    /// # Errors
    ///
    /// The agent failed to decide (for remote agents: after its retries).
    fn act(&mut self, obs: &Observation) -> Result<Action>;

    /// The faults since the last call (for remote agents: every failed attempt, whether a
    /// retry made it good or not), taken so the evaluator can record them on the episode.
    /// Local agents have none.
    fn take_faults(&mut self) -> Vec<Fault> {
        Vec::new()
    }

    /// Remarks on what the agent did with its decisions since the last call that a reader of
    /// the record should know (for remote agents: a reply cut to the `repeat` cap). Local
    /// agents have none.
    fn take_notes(&mut self) -> Vec<String> {
        Vec::new()
    }
}

/// What went wrong with one attempt of a remote agent's request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// No reply came through: refused, timed out, disconnected, bad framing, a reply that is
    /// not JSON, an HTTP status other than 200.
    Transport,
    /// The server replied that it failed: an error status, `parsed_from: "error"`, an
    /// "Error processing request" text.
    ServerError,
    /// The server replaced the model's output by an action of its own (NaVid picks one at
    /// random when it cannot read the model's text).
    Substituted,
    /// The reply holds nothing readable as an action.
    Unparseable,
}

impl FaultKind {
    /// Every kind, in report order.
    pub const ALL: [FaultKind; 4] = [
        FaultKind::Transport,
        FaultKind::ServerError,
        FaultKind::Substituted,
        FaultKind::Unparseable,
    ];

    /// The kind's name as records store it.
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::Transport => "transport",
            FaultKind::ServerError => "server_error",
            FaultKind::Substituted => "substituted",
            FaultKind::Unparseable => "unparseable",
        }
    }
}

impl std::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One failed attempt of a remote agent's request, as the episode's record keeps it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Fault {
    /// The step the request was for.
    pub step: usize,
    /// The attempt, from 1.
    pub attempt: u32,
    /// What went wrong.
    pub kind: FaultKind,
    /// The details.
    pub message: String,
    /// A later attempt of the same request succeeded.
    pub recovered: bool,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "step {}, attempt {}: {}: {}",
            self.step, self.attempt, self.kind, self.message
        )
    }
}

impl<'de> Deserialize<'de> for Fault {
    /// A fault object, or the text `step S, attempt A: MESSAGE` that records written before
    /// faults had kinds hold (its kind read from the message).
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Fault, D::Error> {
        #[derive(Deserialize)]
        struct Object {
            step: usize,
            attempt: u32,
            kind: FaultKind,
            message: String,
            #[serde(default)]
            recovered: bool,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Stored {
            Object(Object),
            Text(String),
        }
        Ok(match Stored::deserialize(d)? {
            Stored::Object(o) => Fault {
                step: o.step,
                attempt: o.attempt,
                kind: o.kind,
                message: o.message,
                recovered: o.recovered,
            },
            Stored::Text(text) => Fault::from_legacy_text(&text),
        })
    }
}

impl Fault {
    /// A fault from the text of an older record (`step 3, attempt 1: connect: …`); whether it
    /// was recovered is not known there, so it counts as not.
    fn from_legacy_text(text: &str) -> Fault {
        let (head, message) = text.split_once(": ").unwrap_or(("", text));
        let number = |key: &str| {
            head.split(", ")
                .find_map(|part| part.strip_prefix(key))
                .and_then(|n| n.trim().parse().ok())
        };
        let kind = if message.starts_with("unparseable reply") {
            FaultKind::Unparseable
        } else if message.starts_with("the server answered status") {
            FaultKind::ServerError
        } else {
            FaultKind::Transport
        };
        Fault {
            step: number("step ").unwrap_or(0),
            attempt: number("attempt ").unwrap_or(1) as u32,
            kind,
            message: message.to_string(),
            recovered: false,
        }
    }
}

/// Runs `episode` in `env` with `agent` to its end and returns the trace.
///
/// # Errors
///
/// A reset, agent or step error.
pub fn run_episode(
    env: &mut Env,
    agent: &mut dyn Agent,
    episode: &EnvEpisode,
) -> Result<EpisodeTrace> {
    let mut obs = env.reset(episode)?;
    agent
        .reset(env, episode)
        .map_err(|e| e.within(format!("agent {} on episode {}", agent.name(), episode.id)))?;
    while !env.done() {
        let action = agent.act(&obs)?;
        obs = env.step(action)?.0;
    }
    Ok(env.trace().expect("an episode ran").clone())
}

/// The discrete steps of `env`, or an error naming the agent.
fn discrete(env: &Env, agent: &str) -> Result<(f32, f32)> {
    match env.config().actions {
        ActionSpace::Discrete {
            forward, turn_deg, ..
        } => Ok((forward, turn_deg.to_radians())),
        _ => Err(Error::invalid(format!(
            "the {agent} agent needs the discrete action space"
        ))),
    }
}

/// Uniform FORWARD / LEFT / RIGHT, and STOP with a fixed probability per step; seeded per
/// episode from its seed and the episode id, so results do not depend on episode order or
/// thread count.
#[derive(Debug, Clone)]
pub struct RandomAgent {
    seed: u64,
    stop_probability: f64,
    rng: ChaCha8Rng,
}

impl RandomAgent {
    /// A random agent; `stop_probability` ∈ [0, 1] per step.
    ///
    /// # Errors
    ///
    /// A probability outside [0, 1].
    pub fn new(seed: u64, stop_probability: f64) -> Result<RandomAgent> {
        if !(0.0..=1.0).contains(&stop_probability) {
            return Err(Error::invalid(format!(
                "random agent: stop probability {stop_probability} is not in [0, 1]"
            )));
        }
        Ok(RandomAgent {
            seed,
            stop_probability,
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }
}

impl Agent for RandomAgent {
    fn name(&self) -> &str {
        "random"
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        discrete(env, "random")?;
        self.rng =
            ChaCha8Rng::seed_from_u64(self.seed ^ sage_io::hash::fnv1a64(episode.id.as_bytes()));
        Ok(())
    }

    fn act(&mut self, _obs: &Observation) -> Result<Action> {
        if self.rng.random_bool(self.stop_probability) {
            return Ok(Action::Stop);
        }
        Ok([Action::MoveForward, Action::TurnLeft, Action::TurnRight][self.rng.random_range(0..3)])
    }
}

/// Moves forward every step; calls STOP after `stop_after` steps when given (otherwise the
/// episode ends by the task's rules).
#[derive(Debug, Clone, Default)]
pub struct ForwardAgent {
    stop_after: Option<usize>,
    taken: usize,
}

impl ForwardAgent {
    /// A forward-only agent.
    pub fn new(stop_after: Option<usize>) -> ForwardAgent {
        ForwardAgent {
            stop_after,
            taken: 0,
        }
    }
}

impl Agent for ForwardAgent {
    fn name(&self) -> &str {
        "forward"
    }

    fn reset(&mut self, env: &Env, _episode: &EnvEpisode) -> Result<()> {
        discrete(env, "forward")?;
        self.taken = 0;
        Ok(())
    }

    fn act(&mut self, _obs: &Observation) -> Result<Action> {
        self.taken += 1;
        Ok(match self.stop_after {
            Some(n) if self.taken > n => Action::Stop,
            _ => Action::MoveForward,
        })
    }
}

/// Follows the shortest path to the goal point with discrete actions: turn toward the next
/// waypoint until it is within half a turn step, else move forward; STOP within `stop_radius`
/// of the goal point, or nearer than any one step could bring it (with steps longer than twice
/// `stop_radius` no step may land within it). When a forward move makes no progress it replans from where it stands;
/// with no path to the goal (at reset or after replanning) it calls STOP.
#[derive(Clone, Default)]
pub struct OracleAgent {
    waypoints: Vec<Vec2>,
    next: usize,
    goal: Vec2,
    forward: f32,
    turn: f32,
    last: Option<(Action, Vec2, f32)>,
    replans: usize,
    stop_radius: f32,
    /// The goal object's footprint, when the episode names one.
    region: Option<Polygon2>,
    /// The task's success distance to the goal region.
    success: f32,
    /// Past the end point, closing in on an object goal's footprint or turning to a pose
    /// goal's heading.
    approaching: bool,
    /// A pose goal's heading (Base-Action): the oracle stops at the point facing it.
    heading: Option<f32>,
    scene: Option<std::sync::Arc<crate::SceneContext>>,
    /// The path finder for the agent's profile (its radius).
    planner: Option<std::sync::Arc<PathFinder>>,
}

/// How far inside the success distance of an object goal the oracle stops, metres: its end
/// point may be sampled at the very edge of that distance.
const SUCCESS_MARGIN: f32 = 0.05;

/// Replans allowed per episode before the oracle gives up and calls STOP.
const MAX_REPLANS: usize = 20;

impl OracleAgent {
    /// An oracle that stops within `stop_radius` metres of the goal point.
    pub fn new(stop_radius: f32) -> OracleAgent {
        OracleAgent {
            stop_radius,
            ..OracleAgent::default()
        }
    }

    /// Plans from `from` to the goal on the agent's own path finder (its profile's radius), or
    /// where that finds no way, on the scene's.
    fn plan(&mut self, from: Vec2) -> Result<()> {
        let ctx = self.scene.as_ref().expect("set at reset");
        let own = self.planner.as_ref().expect("set at reset");
        let path =
            path_on(own, from, self.goal).or_else(|_| path_on(&ctx.pathfinder, from, self.goal))?;
        // A point every step along the path, as the reference paths are resampled: the oracle
        // heads for one between one and two steps ahead, so a heading that is up to half a turn
        // off strays a few centimetres from the line before it is corrected, where aiming at a
        // corner metres away would stray decimetres (and touch what the line passes closely).
        self.waypoints = sage_core::geometry::resample_polyline(&path, self.forward);
        self.next = 1.min(self.waypoints.len() - 1);
        Ok(())
    }
}

/// The waypoints of a path on `pf` from `from` to `goal`, each snapped to its navigable grid
/// within 1 m (an agent pressed against an obstacle, a goal point closer to furniture than a
/// wide agent may come); the goal itself ends the path.
fn path_on(pf: &PathFinder, from: Vec2, goal: Vec2) -> Result<Vec<Vec2>> {
    let snap = |p: Vec2| {
        pf.snap_point(p, 1.0).ok_or_else(|| {
            Error::invalid(format!(
                "oracle: no navigable cell within 1 m of ({:.2}, {:.2})",
                p.x, p.y
            ))
        })
    };
    let (start, end) = (snap(from)?, snap(goal)?);
    let mut waypoints = pf.find_path(start, end)?.waypoints;
    if end != goal {
        waypoints.push(goal);
    }
    Ok(waypoints)
}

impl Agent for OracleAgent {
    fn name(&self) -> &str {
        "oracle"
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        let (forward, turn) = discrete(env, "oracle")?;
        let goal = episode
            .goal
            .as_ref()
            .ok_or_else(|| Error::invalid("oracle: the episode has no goal"))?;
        self.goal = goal.point.truncate();
        self.region = goal
            .object
            .as_ref()
            .and_then(|id| env.context().footprint(id).ok());
        self.success = env.config().task.success_distance;
        self.heading = goal.heading;
        self.approaching = false;
        self.forward = forward;
        self.turn = turn;
        self.last = None;
        self.replans = 0;
        self.scene = Some(env.context().clone());
        // A scene with no room at all for an agent that wide: it plans on the scene's grid.
        let ctx = env.context();
        self.planner = Some(
            ctx.planner(env.profile().radius)
                .unwrap_or_else(|_| ctx.pathfinder.clone()),
        );
        // An unreachable goal is the episode's property, not a fault: the oracle then stops.
        if self.plan(episode.start.position.truncate()).is_err() {
            self.waypoints.clear();
        }
        Ok(())
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        let at = obs.pose.position.truncate();
        // Blocked: the last forward step made little headway along its heading (sliding along
        // a wall beside an opening it missed moves the agent, but not where it was going).
        let blocked = matches!(self.last, Some((Action::MoveForward, before, yaw))
            if (at - before).dot(Vec2::from_angle(yaw)) < 0.5 * self.forward);
        if self.waypoints.is_empty() {
            return Ok(Action::Stop);
        }
        // A pose goal is reached only at its point (the success test's distance), facing its
        // heading.
        let arrival = match self.heading {
            Some(_) => self.stop_radius.min(POSE_SUCCESS_DISTANCE as f32),
            None => self.stop_radius,
        };
        if self.approaching
            || at.distance(self.goal) <= arrival
            || self.no_step_closer(at, obs.pose.yaw)
        {
            self.approaching = true;
            if let Some(heading) = self.heading {
                return Ok(self.steer(wrap_angle(heading - obs.pose.yaw), Action::Stop));
            }
            // At the end point: done, unless an object goal is still not well inside the
            // success distance; then a step towards its footprint — straight, or the heading
            // nearest to straight whose step stays on the navigable area and ends inside the
            // success distance — unless that step would leave the navigable area (touch what
            // stands there) where the episode already succeeds.
            let target = match &self.region {
                Some(r) if !blocked && !r.contains(at) => r
                    .nearest_boundary_point(at)
                    .filter(|q| at.distance(*q) > self.success - SUCCESS_MARGIN),
                _ => None,
            };
            return Ok(match target {
                Some(q) => match self.approach(q, at, obs.pose.yaw) {
                    Action::MoveForward
                        if at.distance(q) <= self.success
                            && self.step_leaves_navigable(at, obs.pose.yaw) =>
                    {
                        Action::Stop
                    }
                    action => action,
                },
                None => Action::Stop,
            });
        }
        if blocked {
            self.replans += 1;
            if self.replans > MAX_REPLANS || self.plan(at).is_err() {
                return Ok(Action::Stop);
            }
        }
        // Skip waypoints within a step: a path followed cell by cell through a narrow place has
        // waypoints closer than a step, which a step would overshoot and then turn back to.
        while self.next + 1 < self.waypoints.len()
            && at.distance(self.waypoints[self.next]) < self.forward
        {
            self.next += 1;
        }
        let action = self.head_for(self.waypoints[self.next], at, obs.pose.yaw);
        // Near the goal a last step that would leave the navigable area (a goal point beside
        // furniture, approached a few degrees off) would touch it: where the episode already
        // succeeds, the oracle stops instead.
        if action == Action::MoveForward
            && self.heading.is_none()
            && self.goal_distance(at) <= self.success - SUCCESS_MARGIN
            && self.step_leaves_navigable(at, obs.pose.yaw)
        {
            return Ok(Action::Stop);
        }
        Ok(action)
    }
}

impl OracleAgent {
    /// Euclidean distance from `at` to the goal region (0 inside an object's footprint).
    fn goal_distance(&self, at: Vec2) -> f32 {
        crate::env::region_distance(self.region.as_ref(), self.goal, at)
    }

    /// True when a forward step from `at` facing `yaw` crosses a cell the agent's path finder
    /// does not count navigable.
    fn step_leaves_navigable(&self, at: Vec2, yaw: f32) -> bool {
        let pf = self.planner.as_ref().expect("set at reset");
        step_leaves_navigable(pf, at, yaw, self.forward)
    }
}

/// True when a straight step of `length` metres from `at` along `yaw` crosses a cell `pf` does
/// not count navigable (sampled every 5 cm): a step the agent would take touching something.
pub fn step_leaves_navigable(pf: &PathFinder, at: Vec2, yaw: f32, length: f32) -> bool {
    let dir = Vec2::from_angle(yaw);
    let n = (length / 0.05).ceil().max(1.0) as usize;
    (1..=n).any(|k| !pf.is_navigable(at + dir * (length * k as f32 / n as f32)))
}

impl OracleAgent {
    /// True when no forward step, on any heading the agent can turn to (its yaw plus whole
    /// turn steps), would end nearer the goal point than `at`: there the oracle has arrived.
    /// Steps of twice the stop radius or more would otherwise step back and forth across the
    /// goal until the step limit (0.75 m steps around a 0.25 m stop radius).
    fn no_step_closer(&self, at: Vec2, yaw: f32) -> bool {
        let d = at.distance(self.goal);
        if d > self.forward {
            return false;
        }
        let steps = (std::f32::consts::PI / self.turn).round() as i32;
        (-steps..steps).all(|k| {
            let heading = yaw + k as f32 * self.turn;
            (at + Vec2::from_angle(heading) * self.forward).distance(self.goal) >= d
        })
    }

    /// Turns towards `target` until it is within half a turn step, else moves forward.
    fn head_for(&mut self, target: Vec2, at: Vec2, yaw: f32) -> Action {
        let d = target - at;
        self.head_along(d.y.atan2(d.x), at, yaw)
    }

    /// Turns towards `heading` until it is within half a turn step, else moves forward.
    fn head_along(&mut self, heading: f32, at: Vec2, yaw: f32) -> Action {
        let action = self.steer(wrap_angle(heading - yaw), Action::MoveForward);
        self.last = Some((action, at, yaw));
        action
    }

    /// The last steps onto an object goal's footprint point `q`: the heading the agent can
    /// take (its yaw plus whole turn steps) nearest to straight at `q`, within a quarter turn
    /// of it, whose step stays on the navigable area and ends well inside the success
    /// distance; straight at `q` when there is none. An end point at the edge of the success
    /// distance in a cluttered corner otherwise has the oracle step into what stands beside
    /// the object.
    fn approach(&mut self, q: Vec2, at: Vec2, yaw: f32) -> Action {
        let d = q - at;
        let straight = d.y.atan2(d.x);
        let steps = (std::f32::consts::PI / self.turn).round() as i32;
        let off = |h: f32| wrap_angle(h - straight).abs();
        let clear = (-steps..steps)
            .map(|k| yaw + k as f32 * self.turn)
            .filter(|&h| off(h) <= std::f32::consts::FRAC_PI_2)
            .filter(|&h| {
                let end = at + Vec2::from_angle(h) * self.forward;
                !self.step_leaves_navigable(at, h)
                    && self.goal_distance(end) <= self.success - SUCCESS_MARGIN
            })
            .min_by(|&a, &b| off(a).total_cmp(&off(b)));
        self.head_along(clear.unwrap_or(straight), at, yaw)
    }

    /// A turn towards a heading `error` radians away, or `aligned` once it is within half a
    /// turn step.
    fn steer(&self, error: f32, aligned: Action) -> Action {
        if error > 0.5 * self.turn {
            Action::TurnLeft
        } else if error < -0.5 * self.turn {
            Action::TurnRight
        } else {
            aligned
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_round_trip_and_older_records_text_faults_still_read() {
        let f = Fault {
            step: 3,
            attempt: 2,
            kind: FaultKind::ServerError,
            message: "the server answered status 'error'".into(),
            recovered: true,
        };
        let json = serde_json::to_string(&f).unwrap();
        assert_eq!(serde_json::from_str::<Fault>(&json).unwrap(), f);
        for (text, kind) in [
            (
                "step 3, attempt 1: connect: Connection refused",
                FaultKind::Transport,
            ),
            (
                "step 0, attempt 2: unparseable reply: \"hm\"",
                FaultKind::Unparseable,
            ),
            (
                "step 7, attempt 4: the server answered status 'error'",
                FaultKind::ServerError,
            ),
        ] {
            let f: Fault = serde_json::from_value(serde_json::json!(text)).unwrap();
            assert_eq!(f.kind, kind, "{text}");
            assert!(!f.recovered);
            assert_eq!(
                f.to_string(),
                text.replacen(": ", &format!(": {kind}: "), 1)
            );
        }
        let f: Fault =
            serde_json::from_value(serde_json::json!("step 3, attempt 1: connect: x")).unwrap();
        assert_eq!(
            (f.step, f.attempt, f.message.as_str()),
            (3, 1, "connect: x")
        );
    }
}
