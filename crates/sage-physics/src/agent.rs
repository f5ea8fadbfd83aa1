//! Agents: ground robots as vertical capsules and a UAV as a sphere, moved kinematically through
//! the world by collide-and-slide shape casts, with a contact report per step (SPEC §6).
//!
//! The profiles are kinematic approximations of the named robots (a body shape, speed limits
//! and a camera height), not models of their legs, wheels or rotors.

use crate::world::World;
use glam::{Vec2, Vec3};
use rapier3d::parry::query::ShapeCastOptions;
use rapier3d::prelude::*;
use sage_core::{Error, InstanceId, MAX_COORDINATE, Pose, Result, within_bounds, wrap_angle};
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// The gap kept between an agent and what it touches (m): shape casts stop this short.
pub const SKIN: f32 = 0.002;
/// Distance within which a body counts as touched (m).
pub const TOUCH: f32 = 2.0 * SKIN + 1e-3;
/// Penetration deeper than this (m) is reported and recovered from.
pub const PENETRATION_EPSILON: f32 = 0.01;
/// Steps without progress while commanded to move before an agent counts as stuck.
pub const STUCK_STEPS: u32 = 5;
/// Progress below this fraction of the commanded translation counts as none.
const NO_PROGRESS: f32 = 0.05;
/// Slide iterations per step (each handles one more contact plane).
const SLIDE_ITERATIONS: usize = 4;
/// The largest turn a command or a heading may hold, radians (ten full turns): more is a
/// mistake, and f32 keeps no useful precision in an angle much larger.
pub const MAX_TURN: f32 = 20.0 * std::f32::consts::PI;
/// The longest a velocity command may be held, seconds: a command is one control step, and the
/// physics of the rigid bodies is stepped through all of it.
pub const MAX_COMMAND_SECONDS: f32 = 60.0;

/// How an agent moves: a ground robot or a UAV (named apart from `sage_agents::AgentKind`,
/// the agent an evaluation runs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Locomotion {
    /// A vertical capsule on the floor plane.
    Ground,
    /// A sphere with 6-DoF velocity commands.
    Uav,
}

/// The body and limits of an agent.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AgentProfile {
    /// Name (`wheeled`, `go2`, `g1`, `h1`, `uav`).
    pub name: &'static str,
    /// Ground robot or UAV.
    pub kind: Locomotion,
    /// Capsule or sphere radius (m).
    pub radius: f32,
    /// Top of the body above its pose (m); for the UAV, the sphere's diameter.
    pub height: f32,
    /// Free height under a ground robot's capsule (m): what it steps over.
    pub clearance: f32,
    /// Camera above the pose (m); the UAV's camera is at its centre.
    pub camera_height: f32,
    /// Top horizontal speed (m/s).
    pub max_speed: f32,
    /// Top vertical speed (m/s; UAV only).
    pub max_climb: f32,
    /// Top yaw rate (rad/s).
    pub max_yaw_rate: f32,
    /// Lowest and highest altitude of the UAV's centre (m).
    pub altitude: [f32; 2],
}

impl AgentProfile {
    /// All profiles, in a fixed order.
    pub fn all() -> [AgentProfile; 5] {
        let ground =
            |name, radius, height, clearance, camera_height, max_speed, yaw: f32| AgentProfile {
                name,
                kind: Locomotion::Ground,
                radius,
                height,
                clearance,
                camera_height,
                max_speed,
                max_climb: 0.0,
                max_yaw_rate: yaw.to_radians(),
                altitude: [0.0, 0.0],
            };
        [
            ground("wheeled", 0.20, 1.30, 0.03, 1.20, 1.0, 90.0),
            ground("go2", 0.28, 0.62, 0.05, 0.35, 2.5, 120.0),
            ground("g1", 0.25, 1.32, 0.08, 1.20, 1.5, 90.0),
            ground("h1", 0.30, 1.80, 0.10, 1.65, 2.0, 90.0),
            AgentProfile {
                name: "uav",
                kind: Locomotion::Uav,
                radius: 0.25,
                height: 0.5,
                clearance: 0.0,
                camera_height: 0.0,
                max_speed: 3.0,
                max_climb: 1.5,
                max_yaw_rate: 90f32.to_radians(),
                altitude: [0.3, 10.0],
            },
        ]
    }
}

impl FromStr for AgentProfile {
    type Err = Error;

    /// A profile by name (`wheeled`, `go2`, `g1`, `h1`, `uav`).
    fn from_str(s: &str) -> Result<AgentProfile> {
        AgentProfile::all()
            .into_iter()
            .find(|p| p.name.eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| {
                Error::invalid(format!(
                    "unknown agent profile '{s}' (expected wheeled, go2, g1, h1 or uav)"
                ))
            })
    }
}

impl Default for AgentProfile {
    /// The wheeled robot, the profile every setting starts from.
    fn default() -> Self {
        let [wheeled, ..] = AgentProfile::all();
        wheeled
    }
}

impl fmt::Display for AgentProfile {
    /// The profile's name, which [`FromStr`] reads back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

/// A profile in settings files by its name (`"go2"`), not its numbers: for
/// `#[serde(with = "sage_physics::agent::profile_name")]`.
pub mod profile_name {
    use super::AgentProfile;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes the profile's name.
    ///
    /// # Errors
    ///
    /// The serializer's.
    pub fn serialize<S: Serializer>(profile: &AgentProfile, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(profile.name)
    }

    /// Reads a profile by name.
    ///
    /// # Errors
    ///
    /// An unknown name, listing the known ones.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<AgentProfile, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// One command to an agent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Command {
    /// Move `distance` metres along the heading (negative: backwards); no speed limit applies.
    Forward {
        /// Metres.
        distance: f32,
    },
    /// Turn by `angle` radians (counter-clockwise positive).
    Turn {
        /// Radians.
        angle: f32,
    },
    /// Do nothing this step.
    Stop,
    /// Ground velocity in the body frame (x forward, y left) and yaw rate, held for `dt`.
    Ground {
        /// Forward speed (m/s).
        vx: f32,
        /// Leftward speed (m/s).
        vy: f32,
        /// Yaw rate (rad/s).
        wz: f32,
        /// Duration (s).
        dt: f32,
    },
    /// UAV velocity: body-frame horizontal, world vertical, yaw rate, held for `dt`.
    Uav {
        /// Forward speed (m/s).
        vx: f32,
        /// Leftward speed (m/s).
        vy: f32,
        /// Upward speed (m/s).
        vz: f32,
        /// Yaw rate (rad/s).
        wz: f32,
        /// Duration (s).
        dt: f32,
    },
}

impl Command {
    /// Checks the command's numbers: finite; a distance, speed and the distance a velocity
    /// asks for (speed × duration) within ±[`MAX_COORDINATE`] m (and m/s); turns and yaw rates
    /// within ±[`MAX_TURN`] (rad, rad/s); durations from 0 to [`MAX_COMMAND_SECONDS`]. Beyond
    /// those a shape cast cannot place the agent (at 1e20 m it passes through walls) and the
    /// physics would step for ages; the limits of the agent's profile then clamp what is left.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the command and the value at fault.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, value: f32, range: String| {
            Err(Error::invalid(format!(
                "command '{self}': {what} {value:?} is {}; expected {range}",
                if value.is_finite() {
                    "out of range"
                } else {
                    "not finite"
                }
            )))
        };
        let metres = |what: &str, v: f32| {
            if v.abs() <= MAX_COORDINATE {
                Ok(())
            } else {
                bad(what, v, format!("within ±{MAX_COORDINATE}"))
            }
        };
        let angle = |what: &str, a: f32| {
            if a.abs() <= MAX_TURN {
                Ok(())
            } else {
                bad(
                    what,
                    a.to_degrees(),
                    format!("within ±{}°", MAX_TURN.to_degrees().round()),
                )
            }
        };
        let seconds = |dt: f32| {
            if (0.0..=MAX_COMMAND_SECONDS).contains(&dt) {
                Ok(())
            } else {
                bad("dt", dt, format!("0 to {MAX_COMMAND_SECONDS} s"))
            }
        };
        match *self {
            Command::Forward { distance } => metres("distance (m)", distance),
            Command::Turn { angle: a } => angle("turn (deg)", a),
            Command::Stop => Ok(()),
            Command::Ground { vx, vy, wz, dt } => {
                metres("vx (m/s)", vx)?;
                metres("vy (m/s)", vy)?;
                angle("yaw rate (deg/s)", wz)?;
                seconds(dt)?;
                metres(
                    "distance asked for, speed × dt (m)",
                    Vec2::new(vx, vy).length() * dt,
                )
            }
            Command::Uav { vx, vy, vz, wz, dt } => {
                metres("vx (m/s)", vx)?;
                metres("vy (m/s)", vy)?;
                metres("vz (m/s)", vz)?;
                angle("yaw rate (deg/s)", wz)?;
                seconds(dt)?;
                metres(
                    "distance asked for, speed × dt (m)",
                    Vec3::new(vx, vy, vz).length() * dt,
                )
            }
        }
    }
}

/// Checks a pose an agent is placed at: a finite position within ±[`MAX_COORDINATE`] m and a
/// finite heading (any: it is wrapped as the agent turns).
///
/// # Errors
///
/// An `invalid` error giving the pose.
pub fn check_pose(pose: &Pose) -> Result<()> {
    if !within_bounds(pose.position) {
        return Err(Error::invalid(format!(
            "position {:?}: expected finite coordinates within ±{MAX_COORDINATE} m",
            pose.position.to_array()
        )));
    }
    if !pose.yaw.is_finite() {
        return Err(Error::invalid(format!(
            "yaw {:?}: expected a finite heading",
            pose.yaw
        )));
    }
    Ok(())
}

/// `angle` (radians) in degrees, in the fewest decimals that parse back to the same angle: the
/// `15` of `turn:15`, where the plain conversion writes `15.000001`.
fn degrees(angle: f32) -> String {
    let exact = angle.to_degrees();
    (0..9)
        .map(|decimals| format!("{exact:.decimals$}"))
        .find(|text| text.parse::<f32>().is_ok_and(|d| d.to_radians() == angle))
        .unwrap_or_else(|| exact.to_string())
}

impl fmt::Display for Command {
    /// The command's text, as [`Command::from_str`] reads it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Command::Forward { distance } => write!(f, "forward:{distance}"),
            Command::Turn { angle } => write!(f, "turn:{}", degrees(angle)),
            Command::Stop => f.write_str("stop"),
            Command::Ground { vx, vy, wz, dt } => {
                write!(f, "vel:{vx}:{vy}:{}:{dt}", degrees(wz))
            }
            Command::Uav { vx, vy, vz, wz, dt } => {
                write!(f, "uav:{vx}:{vy}:{vz}:{}:{dt}", degrees(wz))
            }
        }
    }
}

impl FromStr for Command {
    type Err = Error;

    /// Parses `forward:D`, `turn:DEG`, `stop`, `vel:VX:VY:WZDEG:DT` or `uav:VX:VY:VZ:WZDEG:DT`.
    fn from_str(s: &str) -> Result<Command> {
        let mut it = s.trim().split(':');
        let word = it.next().unwrap_or("").to_ascii_lowercase();
        let nums = it
            .map(|x| {
                x.trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        Error::invalid(format!(
                            "command '{s}': '{}' is not a finite number",
                            x.trim()
                        ))
                    })
            })
            .collect::<Result<Vec<f32>>>()?;
        let cmd = match (word.as_str(), nums.as_slice()) {
            ("forward", [d]) => Command::Forward { distance: *d },
            ("turn", [a]) => Command::Turn {
                angle: a.to_radians(),
            },
            ("stop", []) => Command::Stop,
            ("vel", [vx, vy, w, dt]) if *dt >= 0.0 => Command::Ground {
                vx: *vx,
                vy: *vy,
                wz: w.to_radians(),
                dt: *dt,
            },
            ("uav", [vx, vy, vz, w, dt]) if *dt >= 0.0 => Command::Uav {
                vx: *vx,
                vy: *vy,
                vz: *vz,
                wz: w.to_radians(),
                dt: *dt,
            },
            _ => {
                return Err(Error::invalid(format!(
                    "command '{s}': expected forward:D, turn:DEG, stop, vel:VX:VY:WZDEG:DT or \
                     uav:VX:VY:VZ:WZDEG:DT (dt >= 0)"
                )));
            }
        };
        cmd.validate()?;
        Ok(cmd)
    }
}

/// One body touched during a step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Touch {
    /// Instance id of the body (floor and ceiling: of the room below or above).
    pub instance: InstanceId,
    /// Signed distance at the end of the step (m; negative = penetration).
    pub distance: f32,
}

/// What happened in one step (SPEC §6).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepReport {
    /// Pose after the step.
    pub pose: Pose,
    /// Commanded translation this step (after speed and altitude limits), m.
    pub commanded: Vec3,
    /// Translation achieved by the slide (before any recovery), m.
    pub achieved: Vec3,
    /// Bodies touched during or at the end of the step, by instance id (sorted, unique).
    pub touched: Vec<Touch>,
    /// Deepest penetration at the end of the step, before recovery (m, ≥ 0).
    pub penetration: f32,
    /// Collision intensity c(t) ∈ [0, 1]: the fraction of the commanded translation that
    /// contact prevented (see [`collision_intensity`]).
    pub intensity: f32,
    /// Contact this step and none the step before.
    pub contact_onset: bool,
    /// Steps in a row without progress while commanded to move.
    pub no_progress_steps: u32,
    /// `no_progress_steps` ≥ [`STUCK_STEPS`].
    pub stuck: bool,
    /// Penetration exceeded [`PENETRATION_EPSILON`].
    pub interpenetrating: bool,
    /// The agent was pushed to the nearest free pose; by this offset (m).
    pub recovery: Option<Vec3>,
}

/// c(t) = clamp(1 − (a · d) / |d|², 0, 1) for commanded translation d and achieved a, when the
/// step touched something; 0 otherwise. A step with no commanded translation is 1 when contact
/// blocked its rotation; capsules and spheres turn freely about Z, so it is 0 for them.
pub fn collision_intensity(commanded: Vec3, achieved: Vec3, touched: bool) -> f32 {
    let d2 = commanded.length_squared();
    if !touched || d2 < 1e-12 {
        return 0.0;
    }
    (1.0 - achieved.dot(commanded) / d2).clamp(0.0, 1.0)
}

/// An agent's body in a world: its shape, pose and contact state. Named apart from
/// `sage_env::agents::Agent`, the policy that decides where the body goes.
#[derive(Debug, Clone)]
pub struct AgentBody {
    /// Its body and limits.
    pub profile: AgentProfile,
    /// Position (ground robots: on the floor; UAV: its centre) and heading.
    pub pose: Pose,
    shape: SharedShape,
    /// The shape's centre above the pose.
    lift: f32,
    no_progress: u32,
    was_touching: bool,
}

impl AgentBody {
    /// An agent of `profile` at `pose` (a UAV's altitude is clamped to its limits).
    pub fn new(profile: AgentProfile, pose: Pose) -> AgentBody {
        let (shape, lift) = match profile.kind {
            Locomotion::Ground => {
                let half = ((profile.height - profile.clearance) * 0.5 - profile.radius).max(0.0);
                (
                    SharedShape::capsule_z(half, profile.radius),
                    profile.clearance + profile.radius + half,
                )
            }
            Locomotion::Uav => (SharedShape::ball(profile.radius), 0.0),
        };
        let mut pose = pose;
        if profile.kind == Locomotion::Uav {
            pose.position.z = pose
                .position
                .z
                .clamp(profile.altitude[0], profile.altitude[1]);
        }
        AgentBody {
            profile,
            pose,
            shape,
            lift,
            no_progress: 0,
            was_touching: false,
        }
    }

    /// The collision shape's centre.
    pub fn centre(&self) -> Vec3 {
        self.pose.position + Vec3::Z * self.lift
    }

    /// The camera position.
    pub fn camera(&self) -> Vec3 {
        self.pose.position + Vec3::Z * self.profile.camera_height
    }

    /// The commanded translation and rotation of `cmd` from the current pose, after limits.
    fn resolve(&self, cmd: &Command) -> Result<(Vec3, f32, f32)> {
        let p = &self.profile;
        let fwd = self.pose.forward();
        let left = -self.pose.right();
        let planar = |vx: f32, vy: f32, dt: f32| {
            let v = Vec2::new(vx, vy);
            let v = if v.length() > p.max_speed {
                v * (p.max_speed / v.length())
            } else {
                v
            };
            (fwd * v.x + left * v.y) * dt
        };
        let yaw = |wz: f32, dt: f32| wz.clamp(-p.max_yaw_rate, p.max_yaw_rate) * dt;
        Ok(match (*cmd, p.kind) {
            (Command::Forward { distance }, _) => ((fwd * distance).extend(0.0), 0.0, 0.0),
            (Command::Turn { angle }, _) => (Vec3::ZERO, angle, 0.0),
            (Command::Stop, _) => (Vec3::ZERO, 0.0, 0.0),
            (Command::Ground { vx, vy, wz, dt }, Locomotion::Ground) => {
                (planar(vx, vy, dt).extend(0.0), yaw(wz, dt), dt)
            }
            (Command::Uav { vx, vy, vz, wz, dt }, Locomotion::Uav) => {
                let z = self.pose.position.z;
                let target = (z + vz.clamp(-p.max_climb, p.max_climb) * dt)
                    .clamp(p.altitude[0], p.altitude[1]);
                (planar(vx, vy, dt).extend(target - z), yaw(wz, dt), dt)
            }
            (c, k) => {
                return Err(Error::invalid(format!(
                    "command {c} does not apply to a {k:?} agent ({})",
                    p.name
                )));
            }
        })
    }

    /// Executes one command: wakes the rigid bodies for its duration when any is awake, slides
    /// the body along what it hits, then reports contacts, c(t), stuck and penetration, and
    /// pushes the agent out of any deep penetration.
    ///
    /// # Errors
    ///
    /// A command out of range ([`Command::validate`]), an agent at a pose out of range
    /// ([`check_pose`]: [`AgentBody::new`] takes any), a ground command to a UAV or a UAV
    /// command to a ground robot.
    pub fn step(&mut self, world: &mut World, cmd: &Command) -> Result<StepReport> {
        // Commands are built by hand, from text, from Python and by environments: each is
        // checked where it is carried out.
        cmd.validate()?;
        check_pose(&self.pose).map_err(|e| e.within("the agent's pose"))?;
        let (commanded, turn, dt) = self.resolve(cmd)?;
        world.advance(dt);
        let planar = self.profile.kind == Locomotion::Ground;
        let qp = world.physics.query_pipeline();
        let mut hits: Vec<ColliderHandle> = Vec::new();
        let start = self.centre();
        let end = slide(&qp, &*self.shape, start, commanded, planar, &mut hits);
        let achieved = end - start;
        self.pose.position += achieved;
        self.pose.yaw = wrap_angle(self.pose.yaw + turn);
        let contacts = contacts_at(&qp, &*self.shape, end);
        let penetration = contacts
            .iter()
            .map(|c| -c.1)
            .fold(0.0f32, f32::max)
            .max(0.0);
        let at = self.pose.position.truncate();
        let mut touched: Vec<Touch> = contacts
            .iter()
            .map(|&(h, d)| Touch {
                instance: world.instance_at(h, at),
                distance: d,
            })
            .chain(hits.iter().map(|&h| Touch {
                instance: world.instance_at(h, at),
                distance: SKIN,
            }))
            .collect();
        touched.sort_by(|a, b| {
            a.instance
                .cmp(&b.instance)
                .then(a.distance.total_cmp(&b.distance))
        });
        touched.dedup_by_key(|t| t.instance);
        let touching = !touched.is_empty();
        let intensity = collision_intensity(commanded, achieved, touching);
        let moving = commanded.length() > 1e-6;
        // Steps without commanded translation (turns, stops) neither count nor reset.
        if moving {
            if achieved.dot(commanded) < NO_PROGRESS * commanded.length_squared() {
                self.no_progress += 1;
            } else {
                self.no_progress = 0;
            }
        }
        let interpenetrating = penetration > PENETRATION_EPSILON;
        let recovery = if interpenetrating {
            let free = nearest_free(&qp, &*self.shape, end, planar, self.profile.radius);
            free.map(|p| {
                self.pose.position += p - end;
                p - end
            })
        } else {
            None
        };
        let report = StepReport {
            pose: self.pose,
            commanded,
            achieved,
            touched,
            penetration,
            intensity,
            contact_onset: touching && !self.was_touching,
            no_progress_steps: self.no_progress,
            stuck: self.no_progress >= STUCK_STEPS,
            interpenetrating,
            recovery,
        };
        self.was_touching = touching;
        Ok(report)
    }
}

/// Collide and slide: sweeps `shape` from `start` along `desired`, stopping [`SKIN`] short of
/// each obstacle and continuing with the part of the motion tangent to it; returns the end
/// centre. `planar` keeps the motion horizontal.
fn slide(
    qp: &QueryPipeline,
    shape: &dyn Shape,
    start: Vec3,
    desired: Vec3,
    planar: bool,
    hits: &mut Vec<ColliderHandle>,
) -> Vec3 {
    let mut pos = start;
    let mut remaining = desired;
    let mut planes: Vec<Vec3> = Vec::new();
    let options = |max| ShapeCastOptions {
        max_time_of_impact: max,
        target_distance: SKIN,
        stop_at_penetration: false,
        compute_impact_geometry_on_penetration: true,
    };
    for _ in 0..SLIDE_ITERATIONS {
        let len = remaining.length();
        if len < 1e-6 {
            break;
        }
        let dir = remaining / len;
        let Some((handle, hit)) =
            qp.cast_shape(&Pose3::from_translation(pos), dir, shape, options(len))
        else {
            pos += remaining;
            break;
        };
        let toi = hit.time_of_impact.clamp(0.0, len);
        pos += dir * toi;
        hits.push(handle);
        let mut n = hit.normal1;
        if planar {
            n.z = 0.0;
        }
        let Some(n) = n.try_normalize() else { break };
        planes.push(n);
        remaining -= dir * toi;
        // Remove the motion into every plane met so far (two planes: move along their crease).
        for _ in 0..2 {
            for &p in &planes {
                let into = remaining.dot(p);
                if into < 0.0 {
                    remaining -= p * into;
                }
            }
        }
        if planes.iter().any(|p| remaining.dot(*p) < -1e-6) {
            break;
        }
    }
    pos
}

/// Colliders within [`TOUCH`] of `shape` at `centre`, with their signed distances.
fn contacts_at(qp: &QueryPipeline, shape: &dyn Shape, centre: Vec3) -> Vec<(ColliderHandle, f32)> {
    let pose = Pose3::from_translation(centre);
    let aabb = shape.compute_aabb(&pose).loosened(TOUCH);
    qp.intersect_aabb_conservative(aabb)
        .filter_map(|(h, c)| {
            let pos12 = pose.inv_mul(c.position());
            let contact = qp
                .dispatcher
                .contact(&pos12, shape, c.shape(), TOUCH)
                .ok()
                .flatten()?;
            Some((h, contact.dist))
        })
        .collect()
}

/// The nearest pose to `centre` where `shape` penetrates nothing by more than
/// [`PENETRATION_EPSILON`]: first by pushing out along contact normals, then by searching rings
/// of candidates (16 directions, steps of a quarter radius, up to 2 m). `None` when no free pose
/// is found.
fn nearest_free(
    qp: &QueryPipeline,
    shape: &dyn Shape,
    centre: Vec3,
    planar: bool,
    radius: f32,
) -> Option<Vec3> {
    let deepest = |p: Vec3| -> Option<(f32, Vec3)> {
        let pose = Pose3::from_translation(p);
        let aabb = shape.compute_aabb(&pose);
        qp.intersect_aabb_conservative(aabb)
            .filter_map(|(_, c)| {
                let pos12 = pose.inv_mul(c.position());
                let k = qp
                    .dispatcher
                    .contact(&pos12, shape, c.shape(), 0.0)
                    .ok()??;
                (k.dist < -PENETRATION_EPSILON).then_some((-k.dist, k.normal1))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
    };
    let mut p = centre;
    for _ in 0..8 {
        let Some((depth, normal)) = deepest(p) else {
            return Some(p);
        };
        let mut n = normal;
        if planar {
            n.z = 0.0;
        }
        let n = n.try_normalize()?;
        p -= n * (depth + SKIN);
    }
    let step = (radius * 0.25).max(0.02);
    let rings = (2.0 / step).ceil() as usize;
    for ring in 1..=rings {
        let r = step * ring as f32;
        for k in 0..16 {
            let a = std::f32::consts::TAU * k as f32 / 16.0;
            let candidate = centre + Vec3::new(a.cos() * r, a.sin() * r, 0.0);
            if deepest(candidate).is_none() {
                return Some(candidate);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip_through_text() {
        for s in [
            "forward:0.25",
            "turn:15",
            "stop",
            "vel:0.5:0:30:1",
            "uav:1:0:0.5:0:0.5",
        ] {
            let c: Command = s.parse().unwrap();
            assert_eq!(c.to_string(), s, "written as read");
            let back: Command = c.to_string().parse().unwrap();
            assert_eq!(c, back, "{s}");
        }
        // Any angle read from text comes back exactly, in as few decimals as that takes.
        for k in 0..2000 {
            let c: Command = format!("turn:{}", k as f32 * 0.1373 - 137.0)
                .parse()
                .unwrap();
            assert_eq!(c.to_string().parse::<Command>().unwrap(), c);
        }
        let e = "turn:abc".parse::<Command>().unwrap_err().to_string();
        assert!(e.contains("'abc' is not a finite number"), "{e}");
        assert!("forward".parse::<Command>().is_err());
        assert!("vel:1:0:0:-1".parse::<Command>().is_err());
        assert!("turn:NaN".parse::<Command>().is_err());
    }

    #[test]
    fn commands_out_of_range_are_refused_from_text_and_by_hand() {
        for (text, said) in [
            (
                "forward:1e20",
                "distance (m) 1e20 is out of range; expected within ±10000",
            ),
            ("forward:-10001", "distance (m) -10001.0 is out of range"),
            ("turn:1e9", "turn (deg)"),
            ("vel:1e5:0:0:1", "vx (m/s) 100000.0 is out of range"),
            (
                "vel:1:0:0:61",
                "dt 61.0 is out of range; expected 0 to 60 s",
            ),
            ("uav:0:0:1e30:0:1", "vz (m/s)"),
            // Each number in range, the distance they ask for not: 5000 m/s for 50 s.
            (
                "vel:5000:0:0:50",
                "distance asked for, speed × dt (m) 250000.0",
            ),
            ("forward:1e40", "'1e40' is not a finite number"),
        ] {
            let e = text.parse::<Command>().unwrap_err().to_string();
            assert!(e.contains(said), "{text}: {e}");
        }
        for fine in [
            "forward:10000",
            "turn:3599",
            "vel:1:0:90:60",
            "uav:3:0:1.5:0:60",
        ] {
            fine.parse::<Command>().unwrap();
        }
        let by_hand = [
            Command::Forward { distance: f32::NAN },
            Command::Turn {
                angle: f32::INFINITY,
            },
            Command::Ground {
                vx: 1.0,
                vy: 0.0,
                wz: 0.0,
                dt: -1.0,
            },
            Command::Uav {
                vx: 0.0,
                vy: 0.0,
                vz: 0.0,
                wz: f32::NAN,
                dt: 1.0,
            },
        ];
        for c in by_hand {
            assert!(c.validate().is_err(), "{c}");
        }
        let e = Command::Forward { distance: f32::NAN }
            .validate()
            .unwrap_err()
            .to_string();
        assert!(e.contains("NaN is not finite"), "{e}");
    }

    #[test]
    fn poses_must_be_finite_and_within_the_bound() {
        check_pose(&Pose::new(Vec3::new(1e4, -1e4, 0.0), 100.0)).unwrap();
        for (p, yaw) in [
            (Vec3::new(f32::NAN, 0.0, 0.0), 0.0),
            (Vec3::new(0.0, 2e4, 0.0), 0.0),
            (Vec3::new(0.0, 0.0, f32::INFINITY), 0.0),
            (Vec3::ZERO, f32::NAN),
        ] {
            assert!(check_pose(&Pose::new(p, yaw)).is_err(), "{p} {yaw}");
        }
    }

    #[test]
    fn profiles_parse_and_fit_their_bodies() {
        for p in AgentProfile::all() {
            assert_eq!(p.name.parse::<AgentProfile>().unwrap(), p);
            assert!(
                p.height >= p.clearance + 2.0 * p.radius - 1e-6,
                "{}",
                p.name
            );
            assert!(p.camera_height <= p.height);
        }
        assert!("tank".parse::<AgentProfile>().is_err());
    }

    #[test]
    fn intensity_follows_its_formula() {
        let d = Vec3::X;
        assert_eq!(collision_intensity(d, d, false), 0.0);
        assert_eq!(collision_intensity(d, Vec3::ZERO, true), 1.0);
        assert!((collision_intensity(d, Vec3::new(0.75, 0.4, 0.0), true) - 0.25).abs() < 1e-6);
        assert_eq!(collision_intensity(Vec3::ZERO, Vec3::ZERO, true), 0.0);
    }
}
