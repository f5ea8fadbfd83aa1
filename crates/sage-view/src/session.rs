//! Sessions: an agent stepped through the environment by a person, one keypress a step.
//!
//! A session owns an [`Env`] over a loaded scene and steps it with the action the page sends,
//! so a move in the viewer goes through the same physics, contact and termination rules as a
//! step of `sage3d eval`. An *explore* session walks a scene (or an episode from its start)
//! with no end but leaving the scene or STOP, and can be placed anywhere navigable; a *play*
//! session is one episode of a human run, ended by STOP or the step limit and then scored.
//! The environment renders nothing itself: the page asks for frames at the session's pose
//! ([`crate::frame`]), at its own size.

use crate::player::num;
use crate::scenes::LoadedScene;
use glam::{Vec2, Vec3};
use sage_core::{Error, Pose, Result, Task};
use sage_env::{Action, Env, EnvConfig, EnvEpisode, EnvGoal, StepInfo};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::sync::Arc;

/// At most this many sessions are kept; opening another drops the oldest.
pub const MAX_SESSIONS: usize = 32;
/// Steps an explore session may take before it ends (it has no step limit of its own).
const EXPLORE_STEPS: usize = 100_000;
/// How far a click on the map may be from navigable floor to place the agent there, metres.
const PLACE_SNAP_M: f32 = 0.5;

/// What a session is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// Walking a scene freely.
    Explore,
    /// One episode of a human run; `map_shown` when the person chose to see the map.
    Play {
        /// The person had the top-down map open at some point of the episode.
        map_shown: bool,
    },
}

/// One person's agent in one scene.
pub struct Session {
    /// The scene's name.
    pub scene: String,
    /// The episode played or explored from, if any.
    pub episode: Option<String>,
    /// Explore or play.
    pub purpose: Purpose,
    loaded: Arc<LoadedScene>,
    env: Env,
    started: EnvEpisode,
    last: Option<StepInfo>,
}

impl Session {
    /// A session in `loaded` (scene `scene`) running `episode` with `config` (its sensors are
    /// switched off: frames are rendered on request). An explore session has no step limit.
    ///
    /// # Errors
    ///
    /// The environment's errors on `config` or the episode (a start off the map).
    pub fn start(
        scene: &str,
        loaded: Arc<LoadedScene>,
        config: &EnvConfig,
        episode: EnvEpisode,
        purpose: Purpose,
    ) -> Result<Session> {
        let mut config = EnvConfig {
            sensors: config.sensors.without_images(),
            ..config.clone()
        };
        if purpose == Purpose::Explore {
            config.task.max_steps = EXPLORE_STEPS;
        }
        let mut env = Env::new(loaded.ctx.clone(), config)?;
        env.reset(&episode)?;
        Ok(Session {
            scene: scene.to_string(),
            episode: (!episode.id.is_empty()).then(|| episode.id.clone()),
            purpose,
            loaded,
            env,
            started: episode,
            last: None,
        })
    }

    /// The environment (its trace, pose and configuration).
    pub fn env(&self) -> &Env {
        &self.env
    }

    /// The scene the session runs in.
    pub fn loaded(&self) -> &Arc<LoadedScene> {
        &self.loaded
    }

    /// Takes `action`.
    ///
    /// # Errors
    ///
    /// An episode that has ended, or an action outside the action space.
    pub fn step(&mut self, action: Action) -> Result<&StepInfo> {
        let (_, info) = self.env.step(action)?;
        Ok(self.last.insert(info))
    }

    /// Starts the explore session again at `(x, y)` (snapped to navigable floor within
    /// 0.5 m) facing `yaw`, keeping its goal.
    ///
    /// # Errors
    ///
    /// A play session (its start is the episode's), or no navigable floor near the point.
    pub fn place(&mut self, x: f32, y: f32, yaw: f32) -> Result<()> {
        if self.purpose != Purpose::Explore {
            return Err(Error::invalid(
                "a played episode starts where the episode does",
            ));
        }
        // As a frame's pose: a yaw past ±MAX_COORDINATE would reach the recorded pose as a
        // number no command takes back.
        if !sage_core::within_bounds(Vec3::new(x, y, yaw)) {
            return Err(Error::invalid(format!(
                "place: x, y and yaw must be numbers within ±{}",
                sage_core::MAX_COORDINATE
            )));
        }
        let at = self
            .loaded
            .ctx
            .pathfinder
            .snap_point(Vec2::new(x, y), PLACE_SNAP_M)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "no navigable floor within {PLACE_SNAP_M} m of ({x:.2}, {y:.2})"
                ))
            })?;
        let z = self.started.start.position.z;
        self.started.start = Pose::new(at.extend(z), yaw);
        self.env.reset(&self.started)?;
        self.last = None;
        Ok(())
    }

    /// The session as the page shows it: the pose and camera pitch, the step, the last step's
    /// contact (its intensity c(t) and the bodies touched) and, in an episode, distance to the
    /// goal, whether the episode ended and why, the path walked so far, and an episode's
    /// reference path and goal point; and the choice of bodies recovered from Gaussians the
    /// scene moves on (`splat_bodies`: the environment's, which a scene loaded otherwise refuses).
    pub fn state(&self, id: u64) -> Value {
        let trace = self.env.trace();
        let pose = self.env.pose().unwrap_or(self.started.start);
        let path: Vec<[f64; 2]> = std::iter::once(self.started.start.position)
            .chain(
                trace
                    .iter()
                    .flat_map(|t| t.steps.iter().map(|s| s.pose.position)),
            )
            .map(|p| [num(p.x), num(p.y)])
            .collect();
        let last = self.last.as_ref();
        // A person playing sees what an agent sees: no goal, no way, no distance.
        let explore = self.purpose == Purpose::Explore;
        // A walk through a scene without an episode has no goal (its episode's goal point is
        // the start, which the environment needs): no distance to one either.
        let goal = self
            .episode
            .as_ref()
            .filter(|_| explore)
            .and(self.started.goal.as_ref());
        json!({
            "session": id.to_string(),
            "scene": self.scene,
            "episode": self.episode,
            "purpose": match self.purpose { Purpose::Explore => "explore", Purpose::Play { .. } => "play" },
            "pose": {
                "x": num(pose.position.x),
                "y": num(pose.position.y),
                "z": num(pose.position.z),
                "yaw": num(pose.yaw),
            },
            "pitch": num(last.map_or(0.0, |s| s.pitch)),
            "step": trace.map_or(0, |t| t.steps.len()),
            "time": last.map_or(0.0, |s| s.time),
            "action": last.map(|s| action_name(&s.action)),
            "contact": last.is_some_and(|s| s.collision || !s.touched.is_empty()),
            "collision": last.is_some_and(|s| s.collision),
            "intensity": num(last.map_or(0.0, |s| s.intensity)),
            "touched": last.map(|s| s.touched.clone()).unwrap_or_default(),
            "distance_to_goal": last.and_then(|s| s.distance_to_goal).filter(|_| goal.is_some()).map(num),
            "done": self.env.done(),
            "termination": trace.and_then(|t| t.termination),
            "path": path,
            "reference_path": self
                .started
                .reference_path
                .iter()
                .filter(|_| explore)
                .map(|p| [num(p.x), num(p.y)])
                .collect::<Vec<_>>(),
            "goal": goal.map(|g| [num(g.point.x), num(g.point.y)]),
            "splat_bodies": self.loaded.ctx.splat_bodies,
        })
    }
}

/// The action a key names: `forward`, `left`, `right`, `stop`, `look_up`, `look_down`.
///
/// # Errors
///
/// Any other name, listing these.
pub fn parse_action(name: &str) -> Result<Action> {
    Ok(match name {
        "forward" => Action::MoveForward,
        "left" => Action::TurnLeft,
        "right" => Action::TurnRight,
        "stop" => Action::Stop,
        "look_up" => Action::LookUp,
        "look_down" => Action::LookDown,
        other => {
            return Err(Error::invalid(format!(
                "unknown action '{other}' (expected forward, left, right, stop, look_up or look_down)"
            )));
        }
    })
}

/// The page's name of `action` ([`parse_action`]'s, `move` for velocity actions).
pub fn action_name(action: &Action) -> &'static str {
    match action {
        Action::MoveForward => "forward",
        Action::TurnLeft => "left",
        Action::TurnRight => "right",
        Action::Stop => "stop",
        Action::LookUp => "look_up",
        Action::LookDown => "look_down",
        Action::Displace { .. } | Action::Velocity { .. } | Action::Fly { .. } => "move",
    }
}

/// An episode to explore a scene from `start` facing `yaw`: a point goal at the start
/// itself (walking has no target), no step limit of its own.
pub fn explore_episode(start: Vec3, yaw: f32) -> EnvEpisode {
    EnvEpisode {
        id: String::new(),
        task: Task::Vln,
        instruction: String::new(),
        start: Pose::new(start, yaw),
        goal: Some(EnvGoal {
            point: start,
            object: None,
            heading: None,
        }),
        reference_path: Vec::new(),
    }
}

/// Where an explore session of `loaded` starts: the agent's navigable floor nearest the middle
/// of the largest room ([`sage_splat::camera::default_eye`], which `sage3d render` also moves to
/// free floor), else the first navigable cell.
///
/// # Errors
///
/// A scene with no navigable floor.
pub fn default_start(loaded: &LoadedScene) -> Result<Vec3> {
    let pf = &loaded.ctx.pathfinder;
    let eye = sage_splat::camera::default_eye(&loaded.ctx.scene);
    pf.snap_point(eye.truncate(), pf.grid.size().max_element())
        .or_else(|| {
            pf.navigable_cells()
                .first()
                .map(|&k| pf.grid.center_of(k as usize))
        })
        .map(|p| p.extend(0.0))
        .ok_or_else(|| Error::invalid("the scene has no navigable floor"))
}

/// The open sessions by id.
#[derive(Default)]
pub struct Sessions {
    next: u64,
    open: BTreeMap<u64, Session>,
}

impl Sessions {
    /// Keeps `session` (dropping the oldest past [`MAX_SESSIONS`]) and returns its id.
    pub fn insert(&mut self, session: Session) -> u64 {
        self.next += 1;
        self.open.insert(self.next, session);
        while self.open.len() > MAX_SESSIONS {
            self.open.pop_first();
        }
        self.next
    }

    /// Session `id`.
    ///
    /// # Errors
    ///
    /// No such session (never opened, or dropped as the oldest).
    pub fn get_mut(&mut self, id: u64) -> Result<&mut Session> {
        self.open
            .get_mut(&id)
            .ok_or_else(|| Error::invalid(format!("no session {id} (open a new one)")))
    }
}
