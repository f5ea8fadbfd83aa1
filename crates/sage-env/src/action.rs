//! The actions an agent can take: discrete (VLN-CE's six), ground velocity, UAV velocity.

use serde::{Deserialize, Serialize};

/// One action. STOP is valid in every action space; the others only in theirs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Action {
    /// End the episode.
    Stop,
    /// Discrete: move forward one step.
    MoveForward,
    /// Discrete: turn left (counter-clockwise) one step.
    TurnLeft,
    /// Discrete: turn right one step.
    TurnRight,
    /// Discrete: tilt the camera up one step.
    LookUp,
    /// Discrete: tilt the camera down one step.
    LookDown,
    /// Discrete space: move by `(dx, dy)` in the body frame and turn by `dyaw`, as one step
    /// (a GN0 `nav_delta` row). It runs through physics as the ground velocity
    /// `(dx, dy, dyaw) / seconds` held for the step's `seconds` (1 s when steps take no time), so the body slides along what
    /// it hits (never through it) and the profile's speed and yaw-rate limits apply.
    Displace {
        /// Metres forward.
        dx: f32,
        /// Metres to the left.
        dy: f32,
        /// Radians, counter-clockwise.
        dyaw: f32,
    },
    /// Ground velocity in the body frame (x forward, y left), yaw rate, held for `dt`.
    Velocity {
        /// m/s.
        vx: f32,
        /// m/s.
        vy: f32,
        /// rad/s.
        wz: f32,
        /// s.
        dt: f32,
    },
    /// UAV velocity: body-frame horizontal, world vertical, yaw rate, held for `dt`.
    Fly {
        /// m/s.
        vx: f32,
        /// m/s.
        vy: f32,
        /// m/s.
        vz: f32,
        /// rad/s.
        wz: f32,
        /// s.
        dt: f32,
    },
}

impl Action {
    /// The discrete action with VLN-CE's index: 0 STOP, 1 FORWARD, 2 LEFT, 3 RIGHT, 4 LOOK_UP,
    /// 5 LOOK_DOWN.
    pub fn from_index(i: u8) -> Option<Action> {
        [
            Action::Stop,
            Action::MoveForward,
            Action::TurnLeft,
            Action::TurnRight,
            Action::LookUp,
            Action::LookDown,
        ]
        .get(usize::from(i))
        .copied()
    }
}
