//! `replay:FILE`: trajectories produced elsewhere, replayed through the environment so their
//! metrics (collisions included) are computed here exactly as for a live agent.
//!
//! The file is JSONL, one episode per line: `{"episode_id": …, "actions": […]}` with action
//! names (`move_forward`, `MOVE_FORWARD`, …), VLN-CE indices 0–5 or sage3d `Action` objects;
//! or `{"episode_id": …, "poses": [[x, y, yaw] | [x, y, z, yaw], …]}` in the W frame (metres,
//! radians). Poses are driven through physics with ground-velocity actions, one per pose with
//! dt = 1 s: each is the body-frame displacement and heading change from where the agent
//! stands to the pose, so contacts are measured and a blocked step is made up later within
//! the profile's speed limits. A first pose within 1 cm and 1° of the start is the start
//! itself and is skipped. After the sequence the agent calls STOP.

use sage_core::{Error, MAX_COORDINATE, Result, ResultExt, within_bounds, wrap_angle};
use sage_env::agents::Agent;
use sage_env::{Action, ActionSpace, Env, EnvEpisode, Observation};
use serde_json::Value;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How close a first pose must be to the start to be taken for it.
const START_TOLERANCE_M: f32 = 0.01;
/// Heading tolerance of the same test, radians (1°).
const START_TOLERANCE_RAD: f32 = 0.017_453_3;

/// One episode's recorded sequence.
#[derive(Debug, Clone, PartialEq)]
pub enum Sequence {
    /// Actions, replayed as they are.
    Actions(Vec<Action>),
    /// Poses `(x, y, yaw)` in the W frame, reached with ground-velocity actions.
    Poses(Vec<[f32; 3]>),
}

impl Sequence {
    /// True when the sequence needs the ground-velocity action space.
    fn needs_ground(&self) -> bool {
        match self {
            Sequence::Poses(_) => true,
            Sequence::Actions(a) => a.iter().any(|a| matches!(a, Action::Velocity { .. })),
        }
    }

    /// True when the sequence holds discrete motions (STOP fits every space).
    fn needs_discrete(&self) -> bool {
        matches!(self, Sequence::Actions(a) if a.iter().any(|a| !matches!(a, Action::Stop | Action::Velocity { .. })))
    }
}

/// A replay file: the sequence of every episode it names.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayFile {
    path: PathBuf,
    episodes: HashMap<String, Sequence>,
    ground_dt: Option<f32>,
}

impl ReplayFile {
    /// Reads and checks a replay file.
    ///
    /// # Errors
    ///
    /// An unreadable file, or a bad line (naming the file, the line and the field): not JSON,
    /// no `episode_id`, neither `actions` nor `poses`, an unknown action, a pose that is not 3
    /// or 4 finite numbers (x and y within ±[`MAX_COORDINATE`] m), an episode given twice,
    /// or discrete motions mixed with poses or velocities (one action space per run; STOP fits
    /// either).
    pub fn read(path: &Path) -> Result<ReplayFile> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut episodes = HashMap::new();
        let (mut ground, mut discrete) = (None::<usize>, None::<usize>);
        let mut max_dt = 1.0f32;
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let at = format!("line {}", i + 1);
            let (id, seq) = parse_line(line).within(&at).in_file(path)?;
            if seq.needs_ground() {
                ground.get_or_insert(i + 1);
            }
            if seq.needs_discrete() {
                discrete.get_or_insert(i + 1);
            }
            if let Sequence::Actions(a) = &seq {
                for a in a {
                    if let Action::Velocity { dt, .. } = a {
                        max_dt = max_dt.max(*dt);
                    }
                }
            }
            if episodes.insert(id.clone(), seq).is_some() {
                return Err(
                    Error::format(at, format!("episode '{id}' is given twice")).in_file(path)
                );
            }
        }
        if let (Some(g), Some(d)) = (ground, discrete) {
            return Err(Error::format(
                format!("line {}", g.max(d)),
                format!(
                    "discrete actions (line {d}) and poses or velocities (line {g}) in one file; \
                     a run has one action space"
                ),
            )
            .in_file(path));
        }
        Ok(ReplayFile {
            path: path.to_path_buf(),
            episodes,
            ground_dt: ground.map(|_| max_dt),
        })
    }

    /// The ground-velocity action space when the file holds poses or velocities (`max_dt`
    /// covering its longest velocity), else `None` (the preset's space).
    pub fn action_space(&self) -> Option<ActionSpace> {
        self.ground_dt.map(|max_dt| ActionSpace::Ground { max_dt })
    }

    /// The sequence of episode `id`.
    pub fn get(&self, id: &str) -> Option<&Sequence> {
        self.episodes.get(id)
    }
}

/// One line: the episode id and its sequence.
fn parse_line(line: &str) -> Result<(String, Sequence)> {
    let v: Value = serde_json::from_str(line)
        .map_err(|e| Error::format("json", format!("not a JSON object: {e}")))?;
    let id = v
        .get("episode_id")
        .and_then(Value::as_str)
        .ok_or_else(|| Error::format("episode_id", "expected a string"))?
        .to_string();
    let list = |key: &str| {
        v.get(key).map(|l| {
            l.as_array()
                .ok_or_else(|| Error::format(key.to_string(), "expected an array"))
        })
    };
    let seq = match (list("actions"), list("poses")) {
        (Some(a), None) => Sequence::Actions(
            a?.iter()
                .enumerate()
                .map(|(k, a)| action(a).map_err(|m| Error::format(format!("actions[{k}]"), m)))
                .collect::<Result<_>>()?,
        ),
        (None, Some(p)) => Sequence::Poses(
            p?.iter()
                .enumerate()
                .map(|(k, p)| pose(p).map_err(|m| Error::format(format!("poses[{k}]"), m)))
                .collect::<Result<_>>()?,
        ),
        _ => {
            return Err(Error::format(
                "actions/poses",
                "expected exactly one of \"actions\" and \"poses\"",
            ));
        }
    };
    Ok((id, seq))
}

/// An action: a name (any case), a VLN-CE index 0–5 or a sage3d action object.
fn action(v: &Value) -> std::result::Result<Action, String> {
    let expected = "expected stop, move_forward, turn_left, turn_right, look_up, look_down, an \
                    index 0–5 or an action object";
    let a = match v {
        Value::Number(n) => n
            .as_u64()
            .and_then(|i| u8::try_from(i).ok())
            .and_then(Action::from_index),
        Value::String(s) => {
            serde_json::from_value(serde_json::json!({"type": s.trim().to_ascii_lowercase()})).ok()
        }
        Value::Object(_) => serde_json::from_value(v.clone()).ok(),
        _ => None,
    };
    match a {
        Some(Action::Fly { .. }) => {
            Err("fly actions cannot be replayed (the evaluator's robots are ground robots)".into())
        }
        // A number too large for f32 reads as infinity; it would only fail later, mid-episode.
        Some(Action::Velocity { vx, vy, wz, dt })
            if ![vx, vy, wz, dt].iter().all(|n| n.is_finite()) =>
        {
            Err(format!("{v}: velocity values must be finite numbers"))
        }
        Some(Action::Displace { dx, dy, dyaw })
            if ![dx, dy, dyaw].iter().all(|n| n.is_finite()) =>
        {
            Err(format!("{v}: displacement values must be finite numbers"))
        }
        Some(a) => Ok(a),
        None => Err(format!("{v}: {expected}")),
    }
}

/// A pose `[x, y, yaw]` or `[x, y, z, yaw]` (z is ignored: ground robots stay on the floor),
/// its x and y within the world's bounds ([`sage_core::within_bounds`]): a pose further out
/// would only fail mid-episode, as a velocity the robot cannot have.
fn pose(v: &Value) -> std::result::Result<[f32; 3], String> {
    let nums: Option<Vec<f32>> = v
        .as_array()
        .and_then(|a| a.iter().map(|n| n.as_f64().map(|n| n as f32)).collect());
    match nums.as_deref() {
        Some(&[x, y, yaw] | &[x, y, _, yaw])
            if yaw.is_finite() && within_bounds(glam::Vec3::new(x, y, 0.0)) =>
        {
            Ok([x, y, yaw])
        }
        _ => Err(format!(
            "{v}: expected [x, y, yaw] or [x, y, z, yaw], finite numbers, x and y within \
             ±{MAX_COORDINATE} m"
        )),
    }
}

/// Replays one file's sequences (see the module doc).
#[derive(Debug, Clone)]
pub struct ReplayAgent {
    file: Arc<ReplayFile>,
    sequence: Option<Sequence>,
    next: usize,
}

impl ReplayAgent {
    /// An agent replaying `file`.
    pub fn new(file: Arc<ReplayFile>) -> ReplayAgent {
        ReplayAgent {
            file,
            sequence: None,
            next: 0,
        }
    }
}

impl Agent for ReplayAgent {
    fn name(&self) -> &str {
        "replay"
    }

    fn reset(&mut self, env: &Env, episode: &EnvEpisode) -> Result<()> {
        let seq = self.file.get(&episode.id).ok_or_else(|| {
            Error::invalid(format!("the replay file has no episode '{}'", episode.id))
                .in_file(&self.file.path)
        })?;
        let ground = matches!(env.config().actions, ActionSpace::Ground { .. });
        if seq.needs_ground() && !ground {
            return Err(Error::invalid(
                "replaying poses or velocities needs the ground action space",
            ));
        }
        self.next = match seq {
            Sequence::Poses(p) => {
                let s = &episode.start;
                usize::from(p.first().is_some_and(|q| {
                    (q[0] - s.position.x).hypot(q[1] - s.position.y) <= START_TOLERANCE_M
                        && wrap_angle(q[2] - s.yaw).abs() <= START_TOLERANCE_RAD
                }))
            }
            Sequence::Actions(_) => 0,
        };
        self.sequence = Some(seq.clone());
        Ok(())
    }

    fn act(&mut self, obs: &Observation) -> Result<Action> {
        let k = self.next;
        self.next += 1;
        Ok(match &self.sequence {
            Some(Sequence::Actions(a)) => a.get(k).copied().unwrap_or(Action::Stop),
            Some(Sequence::Poses(p)) => match p.get(k) {
                Some(&[x, y, yaw]) => {
                    let d = glam::Vec2::new(x, y) - obs.pose.position.truncate();
                    let (sin, cos) = obs.pose.yaw.sin_cos();
                    Action::Velocity {
                        vx: d.x * cos + d.y * sin,
                        vy: -d.x * sin + d.y * cos,
                        wz: wrap_angle(yaw - obs.pose.yaw),
                        dt: 1.0,
                    }
                }
                None => Action::Stop,
            },
            None => return Err(Error::invalid("replay: act before reset")),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displacements_replay_as_recorded_and_must_be_finite() {
        let ok = serde_json::json!({"type": "displace", "dx": 0.1, "dy": 0.0, "dyaw": 0.2});
        assert_eq!(
            action(&ok).unwrap(),
            Action::Displace {
                dx: 0.1,
                dy: 0.0,
                dyaw: 0.2
            }
        );
        let huge = serde_json::json!({"type": "displace", "dx": 1e39, "dy": 0.0, "dyaw": 0.0});
        assert!(action(&huge).unwrap_err().contains("finite"));
    }
}
