//! Environment settings: action space, sensors, task limits, and the named presets (SPEC §11,
//! §13).

use glam::Vec3;
use sage_core::{Error, Pose, Result, ResultExt};
use sage_physics::{AgentProfile, Command, Locomotion, SplatBodies};
use sage_splat::{Camera, Device, Intrinsics};
use serde::{Deserialize, Serialize};

/// What actions the agent may send (STOP is allowed in every space).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ActionSpace {
    /// `stop / move_forward / turn_left / turn_right / look_up / look_down`.
    Discrete {
        /// Forward step, metres.
        forward: f32,
        /// Turn step, degrees.
        turn_deg: f32,
        /// Camera tilt step, degrees.
        look_deg: f32,
        /// Simulated seconds one discrete action takes.
        seconds: f32,
    },
    /// Ground velocity `(vx, vy, ω, dt)` in the body frame.
    Ground {
        /// Longest accepted `dt`, seconds.
        max_dt: f32,
    },
    /// UAV velocity `(vx, vy, vz, ω, dt)`.
    Uav {
        /// Longest accepted `dt`, seconds.
        max_dt: f32,
    },
}

impl Default for ActionSpace {
    fn default() -> Self {
        ActionSpace::Discrete {
            forward: 0.25,
            turn_deg: 15.0,
            look_deg: 30.0,
            seconds: 1.0,
        }
    }
}

/// The camera and which images it produces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Camera above the agent's pose, metres; `None`: the agent profile's camera height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_height: Option<f32>,
    /// Depth image size `[width, height]` when it differs from the colour image (a second
    /// render at that size).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_size: Option<[u32; 2]>,
    /// Produce the RGB image.
    pub rgb: bool,
    /// Produce the depth image (median depth, metres).
    pub depth: bool,
    /// Produce the category-id image.
    pub semantic: bool,
    /// Produce the instance-id image.
    pub instance: bool,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            width: 224,
            height: 224,
            hfov_deg: 90.0,
            camera_height: None,
            depth_size: None,
            rgb: true,
            depth: true,
            semantic: false,
            instance: false,
        }
    }
}

impl SensorConfig {
    /// True when any image is requested (otherwise steps render nothing).
    pub fn renders(&self) -> bool {
        self.rgb || self.depth || self.semantic || self.instance
    }

    /// The same camera with no image requested: an environment of it steps physics alone.
    pub fn without_images(self) -> SensorConfig {
        SensorConfig {
            rgb: false,
            depth: false,
            semantic: false,
            instance: false,
            ..self
        }
    }
}

/// Task limits (SPEC §10).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskConfig {
    /// Steps after which an episode is cut (STOP included).
    pub max_steps: usize,
    /// VLN success radius around the goal region, metres (`≤`).
    pub success_distance: f32,
    /// NoGoal: simulated seconds after which the episode ends.
    pub nogoal_time_limit: f32,
}

impl Default for TaskConfig {
    fn default() -> Self {
        TaskConfig {
            max_steps: 500,
            success_distance: 1.0,
            nogoal_time_limit: sage_metrics::nogoal::NOGOAL_TIME_LIMIT as f32,
        }
    }
}

/// GN-Bench's image size `[width, height]` (research notes gn_bench.md §A2).
pub const GNBENCH_SIZE: [u32; 2] = [480, 360];
/// GN-Bench's `HFOV: 70`, which its simulator uses as the *vertical* field of view, degrees.
pub const GNBENCH_VFOV_DEG: f64 = 70.0;
/// GN-Bench's eye height, metres.
pub const GNBENCH_EYE_HEIGHT: f32 = 1.3;

/// The horizontal field of view of GN-Bench's camera, degrees: its 70° is vertical, so with
/// square pixels hfov = 2·atan(tan(35°) · 480/360) ≈ 86.067°.
pub fn gnbench_hfov_deg() -> f32 {
    let [w, h] = GNBENCH_SIZE.map(f64::from);
    let half = (GNBENCH_VFOV_DEG.to_radians() / 2.0).tan() * w / h;
    (2.0 * half.atan()).to_degrees() as f32
}

/// The image size `[width, height]` the published SAGE-Bench harness sends a model
/// (`SimpleVLNEnv`'s default; research notes sage3d_interiorgs.md §5).
pub const HARNESS_SIZE: [u32; 2] = [640, 480];
/// The published harness's camera: focal length 8.0 over USD's default horizontal aperture
/// 20.955 (the same unit), so hfov = 2·atan(20.955 / 16) ≈ 105.3°.
pub const HARNESS_FOCAL_LENGTH: f64 = 8.0;
/// USD's default horizontal aperture, which the published harness's camera keeps.
pub const HARNESS_APERTURE: f64 = 20.955;
/// The most a command moves in the published harness, metres (a forward step of 0.20 m).
pub const HARNESS_STEP: f32 = 0.20;
/// A turn command of the published harness without an angle, degrees.
pub const HARNESS_TURN_DEG: f32 = 30.0;
/// The published harness's step limit (`run_benchmark.py --max-steps`).
pub const HARNESS_MAX_STEPS: usize = 200;

/// The horizontal field of view of the published harness's camera, degrees (≈ 105.3°).
pub fn harness_hfov_deg() -> f32 {
    (2.0 * (HARNESS_APERTURE / (2.0 * HARNESS_FOCAL_LENGTH)).atan()).to_degrees() as f32
}

/// The names [`EnvConfig::preset`] knows, in the order errors and help list them.
pub const PRESETS: [&str; 7] = [
    "sage",
    "vlnce",
    "gnbench",
    "sage-harness",
    "navila_small",
    "navila_large",
    "custom_small",
];

/// The steps of SAGE-3D's training-data presets (`generate_actions.py`): (name, forward
/// metres, turn degrees). The training-data render walks with them, and an evaluation of a
/// model trained on such data moves with them: the environment presets of those names, `vlnce`
/// (whose steps are the default ones) among them.
pub const TRAINING_STEPS: [(&str, f32, f32); 4] = [
    ("vlnce", 0.25, 15.0),
    ("navila_small", 0.35, 30.0),
    ("navila_large", 0.75, 15.0),
    ("custom_small", 0.50, 30.0),
];

/// The image widths and heights a sensor may have, pixels.
pub const IMAGE_SIDE: std::ops::RangeInclusive<u32> = 1..=8192;

/// A horizontal field of view in degrees as a flag gives it (`--hfov`), in (0, 180) as every
/// camera takes it; the error says why, for the command line to show beside the flag.
///
/// # Errors
///
/// Not a number, or not strictly between 0 and 180.
pub fn parse_hfov(s: &str) -> std::result::Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|e| format!("{e}"))?;
    if v > 0.0 && v < 180.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not in (0, 180) degrees"))
    }
}

/// Everything an [`crate::Env`] is set up with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvConfig {
    /// Agent profile name (`wheeled`, `go2`, `g1`, `h1`, `uav`).
    pub agent: String,
    /// The action space.
    pub actions: ActionSpace,
    /// The camera.
    pub sensors: SensorConfig,
    /// The task limits.
    pub task: TaskConfig,
    /// Where the sensors' images are rendered (`cpu`, `gpu`, `auto`; the CPU by default).
    #[serde(default, deserialize_with = "device_field")]
    pub device: Device,
    /// Which objects of the scenes the environment opens get collision bodies recovered from
    /// their Gaussians (`auto`, `always`, `never`: `sage3d physics build --splat-bodies`).
    /// Written only when not `auto`, so the configs and records of the default stay as they
    /// were.
    #[serde(default, skip_serializing_if = "is_auto")]
    pub splat_bodies: SplatBodies,
}

/// True for the default choice of bodies (serde leaves it out).
fn is_auto(choice: &SplatBodies) -> bool {
    *choice == SplatBodies::Auto
}

/// Reads [`EnvConfig::device`], naming the field and the accepted names when the value is
/// not one of them (serde's own message names neither the field nor the key path).
fn device_field<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Device, D::Error> {
    let name = String::deserialize(d)?;
    name.parse()
        .map_err(|e: Error| serde::de::Error::custom(format!("device: {}", e.message())))
}

impl Default for EnvConfig {
    /// The SAGE-Bench set-up: wheeled robot, camera at 1.2 m, RGB and depth, HFOV 90°,
    /// 0.25 m / 15°, 500 steps.
    fn default() -> Self {
        EnvConfig {
            agent: "wheeled".into(),
            actions: ActionSpace::default(),
            sensors: SensorConfig::default(),
            task: TaskConfig::default(),
            device: Device::default(),
            splat_bodies: SplatBodies::default(),
        }
    }
}

impl EnvConfig {
    /// The preset `preset` with the JSON object `overrides` merged over it (nested objects
    /// merge key by key, any other value replaces), validated: how the Python environments and
    /// configuration files adjust a preset.
    ///
    /// # Errors
    ///
    /// An unknown preset, an override of the wrong type (`environment config: …`) or a value
    /// the validation refuses (naming the field).
    pub fn with_overrides(preset: &str, overrides: &serde_json::Value) -> Result<EnvConfig> {
        fn merge(base: &mut serde_json::Value, over: &serde_json::Value) {
            use serde_json::Value;
            match (base, over) {
                (Value::Object(b), Value::Object(o)) => {
                    for (k, v) in o {
                        // An object of another kind (`actions` turned `ground`) replaces the
                        // preset's whole: the preset's fields are not that kind's.
                        let same_kind = |slot: &Value| {
                            v.get("kind")
                                .is_none_or(|kind| slot.get("kind") == Some(kind))
                        };
                        match b.get_mut(k) {
                            Some(slot) if v.is_object() && slot.is_object() && same_kind(slot) => {
                                merge(slot, v)
                            }
                            _ => {
                                b.insert(k.clone(), v.clone());
                            }
                        }
                    }
                }
                (b, o) => *b = o.clone(),
            }
        }
        let mut v = serde_json::to_value(EnvConfig::preset(preset)?)
            .map_err(|e| Error::invalid(e.to_string()))?;
        merge(&mut v, overrides);
        // The path names the field at fault (`sensors.widht`), which serde's message lacks.
        let config: EnvConfig = serde_path_to_error::deserialize(v).map_err(|e| {
            Error::invalid(format!("environment config: {}: {}", e.path(), e.inner()))
        })?;
        config.validate()?;
        Ok(config)
    }

    /// A named preset ([`PRESETS`]): `sage` (the default), `vlnce` (224×224 RGB, 256×256
    /// depth, HFOV 90, 0.25 m / 15°, 500 steps, camera at 1.25 m as in VLN-CE's agent),
    /// `gnbench` (GN-Bench's camera: 480×360 RGB only, vertical field of view 70° (see
    /// [`gnbench_hfov_deg`]), eye at 1.3 m; 0.25 m / 15°, 500 steps) or `sage-harness` (the
    /// published SAGE-Bench harness's setting: 640×480 RGB and depth at HFOV ≈ 105.3° (see
    /// [`harness_hfov_deg`]), 0.20 m / 30° steps, 200 steps; camera at 1.2 m as in `sage`), or
    /// one of [`TRAINING_STEPS`] (`sage` moving with that training-data preset's steps).
    ///
    /// # Errors
    ///
    /// An `invalid` error for an unknown name.
    pub fn preset(name: &str) -> Result<EnvConfig> {
        match name.trim().to_ascii_lowercase().as_str() {
            "sage" => Ok(EnvConfig::default()),
            "vlnce" => Ok(EnvConfig {
                sensors: SensorConfig {
                    camera_height: Some(1.25),
                    depth_size: Some([256, 256]),
                    ..SensorConfig::default()
                },
                ..EnvConfig::default()
            }),
            "gnbench" => Ok(EnvConfig {
                sensors: SensorConfig {
                    width: GNBENCH_SIZE[0],
                    height: GNBENCH_SIZE[1],
                    hfov_deg: gnbench_hfov_deg(),
                    camera_height: Some(GNBENCH_EYE_HEIGHT),
                    depth: false,
                    ..SensorConfig::default()
                },
                ..EnvConfig::default()
            }),
            "sage-harness" => Ok(EnvConfig {
                actions: ActionSpace::Discrete {
                    forward: HARNESS_STEP,
                    turn_deg: HARNESS_TURN_DEG,
                    look_deg: 30.0,
                    seconds: 1.0,
                },
                sensors: SensorConfig {
                    width: HARNESS_SIZE[0],
                    height: HARNESS_SIZE[1],
                    hfov_deg: harness_hfov_deg(),
                    ..SensorConfig::default()
                },
                task: TaskConfig {
                    max_steps: HARNESS_MAX_STEPS,
                    ..TaskConfig::default()
                },
                ..EnvConfig::default()
            }),
            other => match TRAINING_STEPS.iter().find(|(n, _, _)| *n == other) {
                Some(&(_, forward, turn_deg)) => Ok(EnvConfig {
                    actions: ActionSpace::Discrete {
                        forward,
                        turn_deg,
                        look_deg: 30.0,
                        seconds: 1.0,
                    },
                    ..EnvConfig::default()
                }),
                None => Err(Error::invalid(format!(
                    "unknown environment preset '{name}' (expected {})",
                    PRESETS.join(", ")
                ))),
            },
        }
    }

    /// The environment in a line, as a report shows it: `wheeled; 224x224 rgb, depth at HFOV
    /// 90° (camera at the profile's height); 0.25 m / 15° steps; 500 steps, success within
    /// 1 m`.
    pub fn summary(&self) -> String {
        let s = &self.sensors;
        let images: Vec<&str> = [
            (s.rgb, "rgb"),
            (s.depth, "depth"),
            (s.semantic, "semantic"),
            (s.instance, "instance"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|&(_, name)| name)
        .collect();
        let images = if images.is_empty() {
            "no images".to_string()
        } else {
            images.join(", ")
        };
        let camera = match s.camera_height {
            Some(h) => format!("camera at {h} m"),
            None => "camera at the profile's height".to_string(),
        };
        let actions = match self.actions {
            ActionSpace::Discrete {
                forward, turn_deg, ..
            } => format!("{forward} m / {turn_deg}° steps"),
            ActionSpace::Ground { max_dt } => format!("ground velocities, up to {max_dt} s each"),
            ActionSpace::Uav { max_dt } => format!("UAV velocities, up to {max_dt} s each"),
        };
        format!(
            "{}; {}x{} {images} at HFOV {}° ({camera}); {actions}; {} steps, success within {} m",
            self.agent,
            s.width,
            s.height,
            s.hfov_deg,
            self.task.max_steps,
            self.task.success_distance
        )
    }

    /// The agent profile named by [`EnvConfig::agent`].
    ///
    /// # Errors
    ///
    /// An unknown profile name.
    pub fn profile(&self) -> Result<AgentProfile> {
        self.agent.parse().map_err(|e: Error| e.within("agent"))
    }

    /// The camera of an agent of `profile` standing at `pose` with its camera tilted by
    /// `pitch` (radians, up positive), `width` × `height` pixels with the sensors' field of
    /// view: the eye at the sensors' camera height (else the profile's) above the pose, or at
    /// the pose itself for a drone. Every image of an agent — observations, the viewer's
    /// frames, episode videos — comes from this camera.
    ///
    /// # Errors
    ///
    /// A size or field of view that makes no camera.
    pub fn camera(
        &self,
        profile: &AgentProfile,
        pose: Pose,
        pitch: f32,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        let eye = if profile.kind == Locomotion::Uav {
            pose.position
        } else {
            pose.position + Vec3::Z * self.sensors.camera_height.unwrap_or(profile.camera_height)
        };
        Ok(Camera::from_yaw_pitch(
            Intrinsics::from_hfov(width, height, self.sensors.hfov_deg)?,
            eye,
            pose.yaw,
            pitch,
        ))
    }

    /// Checks every range, naming the field at fault.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the field.
    pub fn validate(&self) -> Result<()> {
        let profile = self.profile()?;
        let bad = |field: &str, why: &str| Err(Error::invalid(format!("{field}: {why}")));
        let s = &self.sensors;
        if !IMAGE_SIDE.contains(&s.width) || !IMAGE_SIDE.contains(&s.height) {
            return bad("sensors.width/height", "expected 1–8192 pixels");
        }
        if let Some([w, h]) = s.depth_size
            && (!IMAGE_SIDE.contains(&w) || !IMAGE_SIDE.contains(&h))
        {
            return bad("sensors.depth_size", "expected 1–8192 pixels");
        }
        if !(s.hfov_deg > 0.0 && s.hfov_deg < 180.0) {
            return bad("sensors.hfov_deg", "expected 0 < hfov < 180 degrees");
        }
        if s.camera_height
            .is_some_and(|h| !(h.is_finite() && h >= 0.0))
        {
            return bad("sensors.camera_height", "expected a finite height >= 0 m");
        }
        let t = &self.task;
        if t.max_steps == 0 {
            return bad("task.max_steps", "expected at least 1");
        }
        if !(t.success_distance.is_finite() && t.success_distance >= 0.0) {
            return bad("task.success_distance", "expected a finite distance >= 0 m");
        }
        if !(t.nogoal_time_limit.is_finite() && t.nogoal_time_limit > 0.0) {
            return bad("task.nogoal_time_limit", "expected a finite time > 0 s");
        }
        let uav = profile.kind == sage_physics::Locomotion::Uav;
        match self.actions {
            ActionSpace::Discrete {
                forward,
                turn_deg,
                look_deg,
                seconds,
            } => {
                let ok = [forward, turn_deg, look_deg]
                    .iter()
                    .all(|v| v.is_finite() && *v >= 0.0)
                    && seconds.is_finite()
                    && seconds >= 0.0;
                if !ok {
                    return bad(
                        "actions",
                        "discrete steps and seconds must be finite and >= 0",
                    );
                }
                // The commands the steps become, checked as they will be when carried out
                // (`Command::validate`, whose limits these are): refused here, a bad preset
                // fails before an episode.
                let longest = Command::Ground {
                    vx: 0.0,
                    vy: 0.0,
                    wz: 0.0,
                    dt: seconds,
                };
                for command in [
                    Command::Forward { distance: forward },
                    Command::Turn {
                        angle: turn_deg.to_radians(),
                    },
                    longest,
                ] {
                    command.validate().within("actions")?;
                }
            }
            ActionSpace::Ground { max_dt } | ActionSpace::Uav { max_dt } => {
                if max_dt <= 0.0 {
                    return bad("actions.max_dt", "expected a time > 0 s");
                }
                let longest = Command::Ground {
                    vx: 0.0,
                    vy: 0.0,
                    wz: 0.0,
                    dt: max_dt,
                };
                longest.validate().within("actions.max_dt")?;
                let wants_uav = matches!(self.actions, ActionSpace::Uav { .. });
                if wants_uav != uav {
                    return bad(
                        "actions",
                        "the UAV action space needs the uav profile and the ground space a ground robot",
                    );
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn presets_and_validation() {
        let d = EnvConfig::preset("sage").unwrap();
        assert_eq!(d, EnvConfig::default());
        d.validate().unwrap();
        let v = EnvConfig::preset("VLNCE").unwrap();
        assert_eq!(v.sensors.depth_size, Some([256, 256]));
        v.validate().unwrap();
        assert!(EnvConfig::preset("habitat").is_err());
        let g = EnvConfig::preset("gnbench").unwrap();
        g.validate().unwrap();
        assert_eq!((g.sensors.width, g.sensors.height), (480, 360));
        assert_eq!(g.sensors.camera_height, Some(1.3));
        assert!(g.sensors.rgb && !g.sensors.depth);
        assert_eq!(g.task.max_steps, 500);
        assert_eq!(g.actions, ActionSpace::default());
        // 70° vertical at 4:3 is 86.067° horizontal; back through the intrinsics the vertical
        // field of view is 70° again.
        assert!(
            (g.sensors.hfov_deg - 86.0671).abs() < 1e-3,
            "{}",
            g.sensors.hfov_deg
        );
        let fy = 240.0 / (f64::from(g.sensors.hfov_deg).to_radians() / 2.0).tan();
        let vfov = 2.0 * (180.0 / fy).atan().to_degrees();
        assert!((vfov - 70.0).abs() < 1e-4, "{vfov}");
        let h = EnvConfig::preset("sage-harness").unwrap();
        h.validate().unwrap();
        assert_eq!((h.sensors.width, h.sensors.height), (640, 480));
        // Focal length 8.0 over an aperture of 20.955: fx = 640 · 8.0 / 20.955 px.
        let fx = 320.0 / (f64::from(h.sensors.hfov_deg).to_radians() / 2.0).tan();
        assert!((fx - 640.0 * 8.0 / 20.955).abs() < 1e-3, "{fx}");
        assert_eq!(h.task.max_steps, 200);
        assert!(matches!(
            h.actions,
            ActionSpace::Discrete { forward, turn_deg, .. } if forward == 0.2 && turn_deg == 30.0
        ));
        assert_eq!(h.sensors.camera_height, d.sensors.camera_height);
        for name in PRESETS {
            EnvConfig::preset(name).unwrap().validate().unwrap();
        }
        let err = EnvConfig::preset("habitat").unwrap_err().to_string();
        assert!(
            err.contains("sage, vlnce, gnbench, sage-harness, navila_small"),
            "{err}"
        );
        assert_eq!(
            EnvConfig::default().summary(),
            "wheeled; 224x224 rgb, depth at HFOV 90° (camera at the profile's height); \
             0.25 m / 15° steps; 500 steps, success within 1 m"
        );
        // Every training-data preset's steps are those of the environment preset of its name.
        for (name, step, turn) in TRAINING_STEPS {
            let c = EnvConfig::preset(name).unwrap();
            assert!(
                matches!(
                    c.actions,
                    ActionSpace::Discrete { forward, turn_deg, .. } if forward == step && turn_deg == turn
                ),
                "{name}"
            );
        }
        let n = EnvConfig::preset("navila_small").unwrap();
        n.validate().unwrap();
        assert_eq!(
            (n.sensors, n.task),
            (EnvConfig::default().sensors, EnvConfig::default().task)
        );
        assert!(matches!(
            n.actions,
            ActionSpace::Discrete { forward, turn_deg, .. } if forward == 0.35 && turn_deg == 30.0
        ));
        let mut c = EnvConfig::default();
        c.sensors.hfov_deg = 180.0;
        assert!(c.validate().unwrap_err().message().contains("hfov_deg"));
        let mut c = EnvConfig {
            actions: ActionSpace::Uav { max_dt: 1.0 },
            ..EnvConfig::default()
        };
        assert!(c.validate().unwrap_err().message().contains("uav"));
        c.agent = "uav".into();
        c.validate().unwrap();
        c.agent = "robot".into();
        assert!(c.validate().is_err());
        // Steps that the agent's commands would refuse are refused here first.
        c.agent = "uav".into();
        c.actions = ActionSpace::Uav { max_dt: 1e6 };
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("actions.max_dt") && e.contains("dt 1000000.0"),
            "{e}"
        );
        let mut c = EnvConfig::default();
        if let ActionSpace::Discrete { forward, .. } = &mut c.actions {
            *forward = 1e20;
        }
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("actions") && e.contains("out of range"), "{e}");
        let mut c = EnvConfig::default();
        if let ActionSpace::Discrete { seconds, .. } = &mut c.actions {
            *seconds = 1e9;
        }
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("actions") && e.contains("dt 1000000000.0"),
            "{e}"
        );
    }

    #[test]
    fn overrides_merge_key_by_key_over_the_preset_and_are_validated() {
        let c = EnvConfig::with_overrides(
            "vlnce",
            &json!({"sensors": {"width": 32, "semantic": true}, "task": {"max_steps": 7}}),
        )
        .unwrap();
        let base = EnvConfig::preset("vlnce").unwrap();
        assert_eq!(
            (c.sensors.width, c.sensors.height),
            (32, base.sensors.height)
        );
        assert!(c.sensors.semantic && c.sensors.rgb);
        assert_eq!(c.sensors.depth_size, base.sensors.depth_size);
        assert_eq!(c.task.max_steps, 7);
        assert_eq!(c.task.success_distance, base.task.success_distance);
        let ground = EnvConfig::with_overrides(
            "sage",
            &json!({"actions": {"kind": "ground", "max_dt": 0.5}}),
        );
        assert_eq!(ground.unwrap().actions, ActionSpace::Ground { max_dt: 0.5 });
        let e = EnvConfig::with_overrides("sage", &json!({"sensors": {"hfov_deg": 200.0}}))
            .unwrap_err();
        assert!(e.to_string().contains("hfov_deg"), "{e}");
        let e =
            EnvConfig::with_overrides("sage", &json!({"sensors": {"width": "wide"}})).unwrap_err();
        assert!(
            e.to_string()
                .contains("environment config: sensors.width: invalid type"),
            "{e}"
        );
        // A misspelt field is an error naming it, at any depth.
        for (over, path) in [
            (
                json!({"sensors": {"widht": 3}}),
                "sensors.widht: unknown field `widht`",
            ),
            (json!({"sensorz": {}}), "sensorz: unknown field `sensorz`"),
            (
                json!({"task": {"max_step": 3}}),
                "task.max_step: unknown field",
            ),
            (
                json!({"actions": {"forwrd": 0.3}}),
                "actions: unknown field `forwrd`",
            ),
        ] {
            let e = EnvConfig::with_overrides("sage", &over)
                .unwrap_err()
                .to_string();
            assert!(e.contains(path), "{over}: {e}");
        }
        assert!(EnvConfig::with_overrides("habitat", &json!({})).is_err());
    }

    #[test]
    fn device_defaults_to_the_cpu_and_a_bad_name_is_an_error_naming_the_field() {
        assert_eq!(EnvConfig::default().device, Device::Cpu);
        let mut without: serde_json::Value = serde_json::to_value(EnvConfig::default()).unwrap();
        without.as_object_mut().unwrap().remove("device");
        let read: EnvConfig = serde_json::from_value(without).unwrap();
        assert_eq!(read.device, Device::Cpu);
        for name in Device::NAMES {
            let c = EnvConfig::with_overrides("vlnce", &json!({ "device": name })).unwrap();
            assert_eq!(c.device.to_string(), name);
        }
        let e = EnvConfig::with_overrides("sage", &json!({"device": "tpu"})).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("device") && text.contains("tpu"), "{text}");
        assert!(text.contains("cpu, gpu, auto"), "{text}");
        let e = EnvConfig::with_overrides("sage", &json!({"device": 1})).unwrap_err();
        assert!(e.to_string().contains("environment config"), "{e}");
    }
}
