//! One episode of the benchmark (SPEC §9), W frame.

use crate::slices::Slices;
use sage_core::{Error, Pose, Result, ResultExt, Vec3};
use sage_env::{EnvEpisode, EnvGoal};
use sage_lang::{DiscreteAction, InstructionType, Level, SingleGoalKind, Source};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

pub use sage_core::Task;

/// A start pose: position (W, floor z) and heading (radians, +x counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StartPose {
    /// `[x, y, z]`, metres.
    pub position: [f32; 3],
    /// Heading, radians.
    pub yaw: f32,
}

impl StartPose {
    /// As a [`Pose`].
    pub fn pose(&self) -> Pose {
        Pose::new(self.position.into(), self.yaw)
    }
}

/// The goal of a VLN episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Goal {
    /// What the goal is (`sofa_2`, `room_3`, `dining_area_1`; empty for Base-Action).
    #[serde(rename = "ref")]
    pub reference: String,
    /// `object`, `room`, `area` or `pose` (Base-Action: the pose the motion ends at).
    pub kind: String,
    /// Goal point `[x, y, z]` (the reference path's end), metres.
    pub position: [f32; 3],
    /// The heading a pose goal ends at (Base-Action), radians: its success in mode `sage` is
    /// the pose test of docs/metrics.md. Absent in other goals and older datasets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f32>,
}

/// One episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// Unique id: `{scene}-t{trajectory}-{k}`, `{scene}-b{i}` or `{scene}-n{i}`.
    pub episode_id: String,
    /// Scene name.
    pub scene: String,
    /// `vln` or `nogoal`.
    pub task: Task,
    /// Index of the trajectory in the scene (`None` for Base-Action and no-goal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trajectory_id: Option<usize>,
    /// Instruction text: what the agent is given.
    pub instruction: String,
    /// Every wording of the instruction the source file holds, by name, when it holds more
    /// than one (GN-Bench's `grounded` and `plain`; `instruction` is the one chosen at import).
    /// Empty for episodes with one wording, and in files written before the field existed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub instruction_texts: BTreeMap<String, String>,
    /// `high` or `low` (`None` for no-goal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<Level>,
    /// Instruction type.
    pub instruction_type: InstructionType,
    /// Single-Goal subtype.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subtype: Option<SingleGoalKind>,
    /// Who wrote the instruction.
    pub source: Source,
    /// Start reference (`chair_3`, `room_2`, …), if the start is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_ref: Option<String>,
    /// Start pose.
    pub start: StartPose,
    /// Goal (`None` for no-goal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Goal>,
    /// Dense reference path `[x, y, z]`, W frame (every 0.25 m; the replayed motion for
    /// Base-Action; the start alone for no-goal).
    pub reference_path: Vec<[f32; 3]>,
    /// Ground-truth actions (0 STOP, 1 FORWARD, 2 LEFT, 3 RIGHT), ending with STOP.
    pub actions: Vec<DiscreteAction>,
    /// Length of the reference path, metres.
    pub path_length: f32,
    /// Geodesic distance start → goal, metres (0 for no-goal).
    pub geodesic_distance: f32,
    /// Complexity slices.
    pub slices: Slices,
}

/// The largest coordinate magnitude an episode file may hold, metres: the bound every file
/// reader applies (following a path then takes a bounded number of steps).
pub use sage_core::MAX_COORDINATE;

/// Checks a point read from a file: finite, each coordinate within [`MAX_COORDINATE`].
///
/// # Errors
///
/// At `at`, naming the offending value.
pub fn check_point(p: [f32; 3], at: &str) -> Result<()> {
    if sage_core::within_bounds(glam::Vec3::from_array(p)) {
        Ok(())
    } else {
        Err(Error::format(
            at,
            format!("{p:?}: expected finite coordinates within ±{MAX_COORDINATE} m"),
        ))
    }
}

/// Checks that no episode id of a file is given twice (two episodes with one id would share
/// their records, frames and maps); `at(k)` names where episode `k` is in the file.
///
/// # Errors
///
/// At the second episode, naming the first.
pub fn check_unique_ids(episodes: &[Episode], at: impl Fn(usize) -> String) -> Result<()> {
    let mut first: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for (k, e) in episodes.iter().enumerate() {
        if let Some(&j) = first.get(e.episode_id.as_str()) {
            return Err(Error::format(
                at(k),
                format!(
                    "episode id '{}' is given twice (first at {})",
                    e.episode_id.escape_debug(),
                    at(j)
                ),
            ));
        }
        first.insert(&e.episode_id, k);
    }
    Ok(())
}

/// The kinds a goal may have: what `goal.kind` says the goal region is (an object's footprint,
/// a room's or an area's point, a pose; docs/dataset.md).
pub const GOAL_KINDS: [&str; 4] = ["object", "room", "area", "pose"];

impl Episode {
    /// Checks an episode read from a file: an id, a scene that is a plain name (it names a
    /// folder: [`sage_io::names::check_plain`]), finite points within [`MAX_COORDINATE`],
    /// finite headings and finite, non-negative lengths, and what its task needs to be scored
    /// ([`Episode::check_task`]).
    ///
    /// # Errors
    ///
    /// The first bad field, named.
    pub fn check(&self) -> Result<()> {
        if self.episode_id.is_empty() {
            return Err(Error::format("episode_id", "expected a non-empty id"));
        }
        sage_io::names::check_plain("scene", &self.scene).within("scene")?;
        check_point(self.start.position, "start.position")?;
        if !self.start.yaw.is_finite() {
            return Err(Error::format("start.yaw", "expected a finite number"));
        }
        if let Some(g) = &self.goal {
            check_point(g.position, "goal.position")?;
            if g.yaw.is_some_and(|y| !y.is_finite()) {
                return Err(Error::format("goal.yaw", "expected a finite number"));
            }
        }
        for (i, p) in self.reference_path.iter().enumerate() {
            check_point(*p, &format!("reference_path[{i}]"))?;
        }
        for (key, v) in [
            ("path_length", self.path_length),
            ("geodesic_distance", self.geodesic_distance),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::format(
                    key,
                    format!("{v}: expected a finite length >= 0"),
                ));
            }
        }
        self.check_task()
    }

    /// Checks what the episode's task needs to be run and scored, so that an episode a reader
    /// lets through never faults for its own content once an evaluation has started:
    ///
    /// - a `vln` episode has a goal (success is reaching it) and a reference path of at least
    ///   one point (nDTW and CSR measure the walk against it; with none, every walk would score
    ///   0 there whatever it did);
    /// - a `nogoal` episode has no goal (its metrics are exploration's; a goal there would be
    ///   read by no metric, yet the oracle would walk to it);
    /// - the type `Goal-less` goes with the task `nogoal` and no other (the GVLN files tell the
    ///   task by the type);
    /// - a goal's `kind` is one of [`GOAL_KINDS`]; an `object` goal names its object (`ref`,
    ///   whose footprint is the goal region); only a `pose` goal has a heading (`yaw`: the
    ///   environment reads it on pose goals alone, so elsewhere it would be silently ignored).
    ///
    /// Whether an object goal's `ref` names an object of its scene needs the scene: the
    /// environment checks it when the episode starts.
    ///
    /// # Errors
    ///
    /// The first unmet need, naming its field.
    pub fn check_task(&self) -> Result<()> {
        match (self.task, &self.goal) {
            (Task::Vln, None) => {
                return Err(Error::format(
                    "goal",
                    "missing: a vln episode needs a goal (its success is reaching it)",
                ));
            }
            (Task::Nogoal, Some(_)) => {
                return Err(Error::format(
                    "goal",
                    "a nogoal episode has no goal (drop the goal, or make the task vln)",
                ));
            }
            _ => {}
        }
        let goal_less = self.instruction_type == InstructionType::GoalLess;
        if goal_less != (self.task == Task::Nogoal) {
            return Err(Error::format(
                "instruction_type",
                format!(
                    "'{}' with task '{}': the type Goal-less goes with the task nogoal, and only with it",
                    self.instruction_type.as_str(),
                    match self.task {
                        Task::Vln => "vln",
                        Task::Nogoal => "nogoal",
                    }
                ),
            ));
        }
        if let Some(g) = &self.goal {
            if !GOAL_KINDS.contains(&g.kind.as_str()) {
                return Err(Error::format(
                    "goal.kind",
                    format!(
                        "'{}': expected one of {}",
                        g.kind.escape_debug(),
                        GOAL_KINDS.join(", ")
                    ),
                ));
            }
            if g.kind == "object" && g.reference.is_empty() {
                return Err(Error::format(
                    "goal.ref",
                    "empty: an object goal names its object's item id (`sofa_2`), whose footprint is the goal region",
                ));
            }
            if g.yaw.is_some() && g.kind != "pose" {
                return Err(Error::format(
                    "goal.yaw",
                    format!(
                        "only a pose goal has a heading (this goal's kind is '{}')",
                        g.kind
                    ),
                ));
            }
        }
        if self.task == Task::Vln && self.reference_path.is_empty() {
            return Err(Error::format(
                "reference_path",
                "empty: a vln episode's reference path holds at least its start (nDTW and CSR are measured against it)",
            ));
        }
        Ok(())
    }

    /// This episode with every negative zero of its numbers made a plain zero: an empty sum of
    /// floats is −0.0 (a turn in place has no path length), which files would otherwise show
    /// as `-0.0`. Adding +0.0 turns −0.0 into +0.0 and leaves every other value as it is.
    pub fn without_negative_zeros(&self) -> Episode {
        let z = |v: f32| v + 0.0;
        let point = |p: [f32; 3]| p.map(z);
        let mut e = self.clone();
        e.start.position = point(e.start.position);
        e.start.yaw = z(e.start.yaw);
        if let Some(g) = &mut e.goal {
            g.position = point(g.position);
            g.yaw = g.yaw.map(z);
        }
        for p in &mut e.reference_path {
            *p = point(*p);
        }
        e.path_length = z(e.path_length);
        e.geodesic_distance = z(e.geodesic_distance);
        e
    }

    /// The environment's view of this episode: an object goal names its item id, so the
    /// object's footprint becomes the goal region.
    pub fn env_episode(&self) -> EnvEpisode {
        EnvEpisode {
            id: self.episode_id.clone(),
            task: self.task,
            instruction: self.instruction.clone(),
            start: self.start.pose(),
            goal: self.goal.as_ref().map(|g| EnvGoal {
                point: Vec3::from(g.position),
                object: (g.kind == "object").then(|| g.reference.clone()),
                heading: g.yaw.filter(|_| g.kind == "pose"),
            }),
            reference_path: self.reference_path.iter().map(|&p| Vec3::from(p)).collect(),
        }
    }
}
