//! The environment loop: reset, step, observations and termination.

use crate::action::Action;
use crate::config::{ActionSpace, EnvConfig};
use crate::context::SceneContext;
use crate::episode::{EnvEpisode, EpisodeTrace, StepInfo, Termination, TraceGeodesics};
use glam::Vec2;
use sage_core::Task;
use sage_core::{Error, MAX_COORDINATE, Polygon2, Pose, Result};
use sage_metrics::distance::pose_reached;
use sage_nav::PathFinder;
use sage_physics::agent::MAX_TURN;
use sage_physics::{AgentBody, AgentProfile, Command, Touch, World};
use sage_splat::{Backend, Camera, Channels, RenderOptions, RenderOutput, Rendering};
use std::sync::Arc;

/// Largest camera tilt reachable with look actions (degrees).
const MAX_PITCH_DEG: f32 = 60.0;

/// The rendered images, row-major `height × width` (RGB × 3); absent when not configured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Images {
    /// Colour image width.
    pub width: usize,
    /// Colour image height.
    pub height: usize,
    /// RGB, 8-bit.
    pub rgb: Option<Vec<u8>>,
    /// Depth size `(width, height)` (the colour size unless configured otherwise).
    pub depth_size: (usize, usize),
    /// Median depth along the optical axis, metres (0 where nothing is hit).
    pub depth: Option<Vec<f32>>,
    /// Category ids.
    pub semantic: Option<Vec<u16>>,
    /// Instance ids.
    pub instance: Option<Vec<u32>>,
}

/// What the agent perceives after a reset or a step.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Images (`None` when no image is configured).
    pub images: Option<Images>,
    /// Agent pose.
    pub pose: Pose,
    /// Camera pitch, radians (up positive).
    pub pitch: f32,
    /// Bodies touched after the last step (none at reset).
    pub contacts: Vec<Touch>,
    /// The episode's instruction.
    pub instruction: Arc<str>,
    /// Simulated seconds since reset.
    pub time: f32,
    /// Steps taken.
    pub step: usize,
}

/// A running episode's state.
struct Running {
    body: AgentBody,
    world: World,
    pitch: f32,
    time: f32,
    instruction: Arc<str>,
    region: Option<Polygon2>,
    trace: EpisodeTrace,
}

impl Running {
    /// Euclidean distance from `at` to the goal region (0 inside the footprint); `None`
    /// without a goal.
    fn goal_distance(&self, at: Vec2) -> Option<f32> {
        let goal = self.trace.episode.goal.as_ref()?;
        Some(region_distance(
            self.region.as_ref(),
            goal.point.truncate(),
            at,
        ))
    }
}

/// Euclidean distance from `at` to a goal region: 0 inside the footprint `region`, else to
/// its boundary; to the goal `point` when there is no footprint.
pub(crate) fn region_distance(region: Option<&Polygon2>, point: Vec2, at: Vec2) -> f32 {
    match region {
        Some(r) if r.contains(at) => 0.0,
        Some(r) => r.distance_to_boundary(at),
        None => at.distance(point),
    }
}

/// A reset or step whose observation waits for its images: the cameras to render (none when
/// no image is configured) and the bodies touched. [`Env::reset`] and [`Env::step`] render
/// them at once; a vector environment, or a training-data render walking many routes in
/// lockstep, gathers the cameras of all its environments over a scene into one batch first
/// ([`Env::reset_unrendered`], [`Env::step_unrendered`], [`Env::render`],
/// [`Env::observation`]).
pub struct Pending {
    contacts: Vec<Touch>,
    cameras: Vec<Camera>,
}

impl Pending {
    /// The cameras to render, in order: the colour camera, then the depth camera when depth
    /// has a size of its own.
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }
}

/// The executable environment over one scene; one per worker thread.
pub struct Env {
    ctx: Arc<SceneContext>,
    config: EnvConfig,
    profile: AgentProfile,
    renderer: Option<Backend>,
    state: Option<Running>,
}

impl Env {
    /// An environment over `ctx` with `config` (validated). When the sensors produce images,
    /// the renderer on `config.device` is opened here ([`SceneContext::renderer`]: the scene's
    /// one pool of CPU renderers, or its one GPU upload, shared).
    ///
    /// # Errors
    ///
    /// A bad configuration, naming the field, a device that cannot render (`gpu` without
    /// a usable adapter), or a [`EnvConfig::splat_bodies`] other than the one `ctx` was loaded
    /// with.
    pub fn new(ctx: Arc<SceneContext>, config: EnvConfig) -> Result<Env> {
        config.validate()?;
        // The bodies were built when the scene was loaded: a configuration asking for other
        // ones would run on physics it did not choose, and its numbers be compared unknowingly.
        if let Some(loaded) = ctx.splat_bodies
            && loaded != config.splat_bodies
        {
            return Err(Error::invalid(format!(
                "splat_bodies: the environment asks for '{}' but scene {} was loaded with '{}'; \
                 load it with the same choice",
                config.splat_bodies, ctx.scene.name, loaded
            )));
        }
        let profile = config.profile()?;
        let renderer = if config.sensors.renders() {
            Some(ctx.renderer(config.device)?)
        } else {
            None
        };
        Ok(Env {
            ctx,
            config,
            profile,
            renderer,
            state: None,
        })
    }

    /// The configuration in force.
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// The agent's profile (its body's size, camera height, speeds).
    pub fn profile(&self) -> &AgentProfile {
        &self.profile
    }

    /// The scene context.
    pub fn context(&self) -> &Arc<SceneContext> {
        &self.ctx
    }

    /// Which renderer forms the images, in words ([`Backend::describe`]: `cpu (2 threads)`,
    /// `gpu: …`, or the CPU with the reason `auto` took no GPU); `None` when no image is
    /// configured (nothing is rendered).
    pub fn render_device(&self) -> Option<&str> {
        self.renderer.as_ref().map(Backend::describe)
    }

    /// True when the renderer is a handle on the scene's GPU upload, so the cameras of every
    /// environment over the scene can go to it in one batch (a CPU renderer renders a camera
    /// at a time; environments over a scene borrow from its pool in parallel instead).
    pub fn renders_in_scene_batches(&self) -> bool {
        self.renderer.as_ref().is_some_and(Backend::is_gpu)
    }

    /// Starts `episode`: a fresh physics world, the agent at the start pose, time 0.
    ///
    /// # Errors
    ///
    /// A VLN episode without a goal, a goal object missing from the scene, or a render error.
    pub fn reset(&mut self, episode: &EnvEpisode) -> Result<Observation> {
        let pending = self.reset_unrendered(episode)?;
        self.finish(pending)
    }

    /// [`Env::reset`] up to the rendering: the cameras of the first observation.
    ///
    /// # Errors
    ///
    /// As [`Env::reset`], rendering aside.
    pub fn reset_unrendered(&mut self, episode: &EnvEpisode) -> Result<Pending> {
        let region = match (&episode.task, &episode.goal) {
            (Task::Vln, None) => {
                return Err(Error::invalid(format!(
                    "episode {}: a vln episode needs a goal",
                    episode.id
                )));
            }
            (_, Some(g)) => match &g.object {
                Some(item) => Some(
                    self.ctx
                        .footprint(item)
                        .map_err(|e| e.within(format!("episode {}", episode.id)))?,
                ),
                None => None,
            },
            (Task::Nogoal, None) => None,
        };
        // A start off the scene's map (a damaged or foreign dataset) has no distances to score
        // by: the episode fails with the reason instead of being scored as a miss.
        if self
            .ctx
            .pathfinder
            .grid
            .cell_at(episode.start.position.truncate())
            .is_none()
        {
            let p = episode.start.position;
            return Err(Error::invalid(format!(
                "episode {}: the start ({:.2}, {:.2}) lies outside the scene's map",
                episode.id, p.x, p.y
            )));
        }
        let body = AgentBody::new(self.profile.clone(), episode.start);
        let trace = EpisodeTrace {
            episode: episode.clone(),
            goal_footprint: region
                .as_ref()
                .map(|r| r.points.iter().map(|p| [p.x, p.y]).collect()),
            steps: Vec::new(),
            termination: None,
            geodesics: TraceGeodesics::default(),
        };
        self.state = Some(Running {
            body,
            world: self.ctx.world(),
            pitch: 0.0,
            time: 0.0,
            instruction: Arc::from(episode.instruction.as_str()),
            region,
            trace,
        });
        self.pending(Vec::new())
    }

    /// True when the current episode has ended (or none was started).
    pub fn done(&self) -> bool {
        self.state
            .as_ref()
            .is_none_or(|s| s.trace.termination.is_some())
    }

    /// The current episode's trace so far.
    pub fn trace(&self) -> Option<&EpisodeTrace> {
        self.state.as_ref().map(|s| &s.trace)
    }

    /// The agent's current pose.
    pub fn pose(&self) -> Option<Pose> {
        self.state.as_ref().map(|s| s.body.pose)
    }

    /// Applies `action`, advances simulated time, checks termination and observes.
    ///
    /// # Errors
    ///
    /// No running episode, an episode that has ended, an action outside the action space, a
    /// non-finite or out-of-range velocity, or a render error.
    pub fn step(&mut self, action: Action) -> Result<(Observation, StepInfo)> {
        let (pending, info) = self.step_unrendered(action)?;
        Ok((self.finish(pending)?, info))
    }

    /// [`Env::step`] up to the rendering: the step's record and the cameras of its
    /// observation.
    ///
    /// # Errors
    ///
    /// As [`Env::step`], rendering aside.
    pub fn step_unrendered(&mut self, action: Action) -> Result<(Pending, StepInfo)> {
        self.check_running()?;
        let (command, seconds, tilt) = self.command(action)?;
        let task = self.config.task;
        let s = self.state.as_mut().expect("checked by done()");
        let report = s.body.step(&mut s.world, &command)?;
        s.time += seconds;
        s.pitch = (s.pitch + tilt).clamp(-MAX_PITCH_DEG.to_radians(), MAX_PITCH_DEG.to_radians());
        let commanded = report.commanded.length();
        let achieved = if commanded > 0.0 {
            report.achieved.dot(report.commanded) / commanded
        } else {
            0.0
        };
        let distance_to_goal = s.goal_distance(s.body.pose.position.truncate());
        let steps = s.trace.steps.len() + 1;
        let termination = if action == Action::Stop {
            Some(Termination::Stop)
        } else if s.trace.episode.task == Task::Nogoal && report.contact_onset {
            Some(Termination::Collision)
        } else if s.trace.episode.task == Task::Nogoal && s.time >= task.nogoal_time_limit {
            Some(Termination::TimeLimit)
        } else if left_scene(&self.ctx, s.body.pose.position.truncate()) {
            Some(Termination::LeftScene)
        } else if steps >= task.max_steps {
            Some(Termination::MaxSteps)
        } else {
            None
        };
        let info = StepInfo {
            action,
            pose: s.body.pose,
            pitch: s.pitch,
            time: s.time,
            commanded,
            achieved,
            touched: report.touched.iter().map(|t| t.instance.0).collect(),
            intensity: report.intensity,
            collision: report.contact_onset,
            stuck: report.stuck,
            distance_to_goal,
            termination,
        };
        s.trace.steps.push(info.clone());
        if termination.is_some() {
            s.trace.termination = termination;
            s.trace.geodesics = geodesics(&self.ctx, &s.trace, s.region.as_ref());
        }
        Ok((self.pending(report.touched)?, info))
    }

    /// True when the task's success test passes now: within the success distance of the goal
    /// region, or for a pose goal (Base-Action) at its pose
    /// ([`sage_metrics::distance::pose_reached`]); the agent must still call STOP for the
    /// episode to succeed.
    pub fn within_success_distance(&self) -> bool {
        let Some(s) = &self.state else {
            return false;
        };
        let pose = s.body.pose;
        match s
            .trace
            .episode
            .goal
            .as_ref()
            .and_then(|g| Some((g, g.heading?)))
        {
            Some((goal, heading)) => pose_reached(
                f64::from(pose.position.truncate().distance(goal.point.truncate())),
                f64::from(pose.yaw - heading),
            ),
            None => s
                .goal_distance(pose.position.truncate())
                .is_some_and(|d| d <= self.config.task.success_distance),
        }
    }

    /// Checks that `action` may be stepped now, as [`Env::step`] checks it, without stepping:
    /// a vector environment checks every sub-environment's action before it steps any.
    ///
    /// # Errors
    ///
    /// No running episode, an episode that has ended, an action outside the action space, a
    /// non-finite or out-of-range velocity.
    pub fn check_step(&self, action: Action) -> Result<()> {
        self.check_running()?;
        self.command(action).map(|_| ())
    }

    /// An error unless an episode is running.
    fn check_running(&self) -> Result<()> {
        if self.done() {
            return Err(Error::invalid(
                "step called with no running episode (reset first, and not after the end)",
            ));
        }
        Ok(())
    }

    /// The physics command, simulated seconds and camera tilt of `action`.
    fn command(&self, action: Action) -> Result<(Command, f32, f32)> {
        let outside = || {
            Err(Error::invalid(format!(
                "action {action:?} is not in the {} action space",
                match self.config.actions {
                    ActionSpace::Discrete { .. } => "discrete",
                    ActionSpace::Ground { .. } => "ground",
                    ActionSpace::Uav { .. } => "uav",
                }
            )))
        };
        let check_dt = |dt: f32, max_dt: f32, values: &[f32]| {
            if values.iter().all(|v| v.is_finite()) && dt >= 0.0 && dt <= max_dt {
                Ok(())
            } else {
                Err(Error::invalid(format!(
                    "action {action:?}: velocities must be finite and 0 <= dt <= {max_dt}"
                )))
            }
        };
        match (self.config.actions, action) {
            (ActionSpace::Discrete { seconds, .. }, Action::Stop) => {
                Ok((Command::Stop, seconds, 0.0))
            }
            (_, Action::Stop) => Ok((Command::Stop, 0.0, 0.0)),
            (ActionSpace::Discrete { seconds, .. }, Action::Displace { dx, dy, dyaw }) => {
                if !([dx, dy, dyaw].iter().all(|v| v.is_finite())) {
                    return Err(Error::invalid(format!(
                        "action {action:?}: the displacement must be finite"
                    )));
                }
                // A preset whose steps take no simulated time still moves over 1 s of physics.
                let dt = if seconds > 0.0 { seconds } else { 1.0 };
                // A row beyond what a command may ask (a server's 20 km row) moves as far as
                // the profile's limits allow, as any long row does: the limits clamp far below.
                let v = Vec2::new(dx, dy) / dt;
                let most = MAX_COORDINATE.min(MAX_COORDINATE / dt);
                // Its direction from the vector over its largest component, whose square
                // cannot overflow as a 10³⁰ m row's would.
                let largest = v.abs().max_element();
                let direction = v / largest;
                let v = if largest * direction.length() > most {
                    direction.normalize() * most
                } else {
                    v
                };
                let (vx, vy) = (v.x, v.y);
                let wz = (dyaw / dt).clamp(-MAX_TURN, MAX_TURN);
                Ok((Command::Ground { vx, vy, wz, dt }, seconds, 0.0))
            }
            (
                ActionSpace::Discrete {
                    forward,
                    turn_deg,
                    look_deg,
                    seconds,
                },
                a,
            ) => {
                let turn = turn_deg.to_radians();
                let look = look_deg.to_radians();
                match a {
                    Action::MoveForward => {
                        Ok((Command::Forward { distance: forward }, seconds, 0.0))
                    }
                    Action::TurnLeft => Ok((Command::Turn { angle: turn }, seconds, 0.0)),
                    Action::TurnRight => Ok((Command::Turn { angle: -turn }, seconds, 0.0)),
                    Action::LookUp => Ok((Command::Stop, seconds, look)),
                    Action::LookDown => Ok((Command::Stop, seconds, -look)),
                    _ => outside(),
                }
            }
            (ActionSpace::Ground { max_dt }, Action::Velocity { vx, vy, wz, dt }) => {
                check_dt(dt, max_dt, &[vx, vy, wz])?;
                Ok((Command::Ground { vx, vy, wz, dt }, dt, 0.0))
            }
            (ActionSpace::Uav { max_dt }, Action::Fly { vx, vy, vz, wz, dt }) => {
                check_dt(dt, max_dt, &[vx, vy, vz, wz])?;
                Ok((Command::Uav { vx, vy, vz, wz, dt }, dt, 0.0))
            }
            _ => outside(),
        }
    }

    /// The cameras of the observation after a reset or step that touched `contacts`.
    fn pending(&self, contacts: Vec<Touch>) -> Result<Pending> {
        let s = self.state.as_ref().expect("an episode is running");
        let sensors = self.config.sensors;
        let mut cameras = Vec::new();
        if self.renderer.is_some() {
            let camera = |w: u32, h: u32| {
                self.config
                    .camera(&self.profile, s.body.pose, s.pitch, w, h)
            };
            cameras.push(camera(sensors.width, sensors.height)?);
            if let Some([w, h]) = sensors.depth_size
                && sensors.depth
                && (w, h) != (sensors.width, sensors.height)
            {
                cameras.push(camera(w, h)?);
            }
        }
        Ok(Pending { contacts, cameras })
    }

    /// The images a render of this environment's cameras asks for: its sensors' (the GPU
    /// reads back only those).
    fn render_options(&self) -> RenderOptions {
        let sensors = &self.config.sensors;
        RenderOptions {
            channels: Channels {
                rgb: sensors.rgb,
                depth_median: sensors.depth,
                semantic: sensors.semantic,
                instance: sensors.instance,
                ..Channels::NONE
            },
            ..RenderOptions::default()
        }
    }

    /// Renders `cameras` (of this environment's or another's [`Pending`] over the same scene)
    /// with this environment's renderer, in one batch.
    ///
    /// # Errors
    ///
    /// A render error.
    pub fn render(&mut self, cameras: &[Camera]) -> Result<Vec<RenderOutput>> {
        let options = self.render_options();
        match self.renderer.as_mut() {
            Some(renderer) if !cameras.is_empty() => {
                let scene = &self.ctx.scene;
                renderer.render_batch(
                    &scene.gaussians,
                    &scene.instances.category_ids,
                    cameras,
                    &options,
                )
            }
            _ => Ok(Vec::new()),
        }
    }

    /// Starts rendering `cameras` as [`Env::render`] does and returns at once: on the GPU the
    /// caller steps physics or encodes images while the batch renders, then waits. (Renders
    /// submitted from several threads at once are not gathered into one batch as
    /// [`Env::render`]'s are.)
    ///
    /// # Errors
    ///
    /// A render error.
    pub fn submit(&mut self, cameras: &[Camera]) -> Result<Rendering> {
        let options = self.render_options();
        match self.renderer.as_mut() {
            Some(renderer) if !cameras.is_empty() => {
                let scene = &self.ctx.scene;
                renderer.submit_batch(
                    &scene.gaussians,
                    &scene.instances.category_ids,
                    cameras,
                    &options,
                )
            }
            _ => Ok(Rendering::Done(Vec::new())),
        }
    }

    /// Renders `pending`'s cameras and assembles the observation.
    fn finish(&mut self, pending: Pending) -> Result<Observation> {
        let outputs = self.render(pending.cameras())?;
        self.observation(pending, outputs)
    }

    /// The observation of `pending` with `outputs`, the renders of its cameras in order.
    ///
    /// # Errors
    ///
    /// Not one render per camera.
    pub fn observation(&self, pending: Pending, outputs: Vec<RenderOutput>) -> Result<Observation> {
        if outputs.len() != pending.cameras.len() {
            return Err(Error::invalid(format!(
                "{} images rendered for {} cameras",
                outputs.len(),
                pending.cameras.len()
            )));
        }
        let s = self.state.as_ref().expect("an episode is running");
        let sensors = self.config.sensors;
        let mut outputs = outputs.into_iter();
        let images = outputs.next().map(|main| {
            let (depth_size, depth) = match outputs.next() {
                Some(d) => ((d.width, d.height), Some(d.depth_median)),
                None => (
                    (main.width, main.height),
                    sensors.depth.then_some(main.depth_median),
                ),
            };
            Images {
                width: main.width,
                height: main.height,
                depth_size,
                depth,
                rgb: sensors.rgb.then_some(main.rgb),
                semantic: sensors.semantic.then_some(main.semantic),
                instance: sensors.instance.then_some(main.instance),
            }
        });
        Ok(Observation {
            images,
            pose: s.body.pose,
            pitch: s.pitch,
            contacts: pending.contacts,
            instruction: s.instruction.clone(),
            time: s.time,
            step: s.trace.steps.len(),
        })
    }
}

/// How far a position off the navigable grid (an agent pressed against an obstacle, inside the
/// grid's safety inflation, or one step past [`LEAVE_DISTANCE`] where it left the scene) is
/// snapped to the nearest navigable cell for geodesic distances, metres.
pub const SNAP_DISTANCE: f32 = 2.0;

/// How far from the navigable area an agent outside every room may go before the episode ends
/// with [`Termination::LeftScene`], metres: beyond a wall's thickness and the planning radius,
/// so no position inside the building ends an episode.
pub const LEAVE_DISTANCE: f32 = 1.0;

/// True when `p` (floor plane) is outside every room of the scene and farther than
/// [`LEAVE_DISTANCE`] from its navigable area. A scene without rooms is bounded by the
/// navigable area alone.
fn left_scene(ctx: &SceneContext, p: Vec2) -> bool {
    let pf = &ctx.pathfinder;
    !pf.is_navigable(p)
        && !ctx
            .scene
            .floorplan
            .rooms
            .iter()
            .any(|r| r.profile.contains(p))
        && pf.snap_cell(p, LEAVE_DISTANCE).is_none()
}

/// `p` on the navigable grid: itself when navigable, else the nearest navigable cell centre
/// within [`SNAP_DISTANCE`]; with the gap between the two.
fn snapped(pf: &PathFinder, p: Vec2) -> Option<(Vec2, f32)> {
    if pf.is_navigable(p) {
        return Some((p, 0.0));
    }
    pf.snap_point(p, SNAP_DISTANCE).map(|q| (q, p.distance(q)))
}

/// The geodesic distances of a finished VLN episode (SPEC §10): to the goal region within
/// 1.0 m of its footprint (or to the goal point), and to the goal point per step. A position
/// off the navigable grid is snapped to it and the gap added.
fn geodesics(
    ctx: &SceneContext,
    trace: &EpisodeTrace,
    region: Option<&Polygon2>,
) -> TraceGeodesics {
    let Some(goal) = &trace.episode.goal else {
        return TraceGeodesics::default();
    };
    let pf = &ctx.pathfinder;
    let point = goal.point.truncate();
    let start = trace.episode.start.position.truncate();
    let last = trace
        .steps
        .last()
        .map_or(start, |s| s.pose.position.truncate());
    let to_region = |p: Vec2| {
        let (q, gap) = snapped(pf, p)?;
        let d = match region {
            Some(r) => pf.geodesic_distance_to_region(q, r, 1.0),
            None => pf.geodesic_distance(q, point),
        };
        d.map(|d| d + gap)
    };
    let field = snapped(pf, point).and_then(|(q, _)| pf.geodesic_field(q).ok());
    let to_point = |p: Vec2| {
        let (q, gap) = snapped(pf, p)?;
        field.as_ref()?.distance_to(q).map(|d| d + gap)
    };
    TraceGeodesics {
        start_to_region: to_region(start),
        final_to_region: to_region(last),
        start_to_point: to_point(start),
        steps_to_point: trace
            .steps
            .iter()
            .map(|s| to_point(s.pose.position.truncate()))
            .collect(),
    }
}
