//! A training-data render end to end: the settings, the plan (episodes grouped into routes per
//! scene), rendering one scene (resumable per route), and the finish that writes the format's
//! files and the manifest last.

use crate::encode::{self, RgbCodec};
use crate::lerobot;
use crate::output::{self, Layout};
use crate::preset::ActionPreset;
use crate::replay::{self, Route, Verdict, Walk, Walker};
use crate::sample::{self, EpisodeSample, IMAGES_DIR, ROUTE_FILE, RouteRecord};
use rayon::prelude::*;
use sage_core::{Error, Result, ResultExt, Task};
use sage_env::{ActionSpace, Env, EnvConfig, Pending, SceneContext, SensorConfig};
use sage_io::files::{read_json, write_json};
use sage_io::hash::fnv1a64_hex;
use sage_io::lock::FolderLock;
use sage_physics::SplatBodies;
use sage_scene::LoadOptions;
use sage_splat::{Device, RenderOutput, Rendering};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The file a finished render writes last.
pub const MANIFEST: &str = "manifest.json";

/// The images a sample holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sensors {
    /// RGB frames.
    pub rgb: bool,
    /// Depth (16-bit PNG, millimetres).
    pub depth: bool,
    /// Category ids (16-bit PNG).
    pub semantic: bool,
    /// Instance ids (16-bit PNG).
    pub instance: bool,
}

impl Default for Sensors {
    /// RGB only.
    fn default() -> Self {
        Sensors {
            rgb: true,
            depth: false,
            semantic: false,
            instance: false,
        }
    }
}

impl std::fmt::Display for Sensors {
    /// `rgb[,depth][,semantic][,instance]`, as [`FromStr`](std::str::FromStr) reads it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("rgb")?;
        for (on, name) in [
            (self.depth, "depth"),
            (self.semantic, "semantic"),
            (self.instance, "instance"),
        ] {
            if on {
                write!(f, ",{name}")?;
            }
        }
        Ok(())
    }
}

impl std::str::FromStr for Sensors {
    type Err = Error;

    /// `rgb[,depth,semantic,instance]`: RGB is always produced (every format needs it).
    fn from_str(s: &str) -> Result<Sensors> {
        let mut out = Sensors::default();
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "rgb" => {}
                "depth" => out.depth = true,
                "semantic" => out.semantic = true,
                "instance" => out.instance = true,
                other => {
                    return Err(Error::invalid(format!(
                        "unknown sensor '{other}' (known: rgb, depth, semantic, instance)"
                    )));
                }
            }
        }
        Ok(out)
    }
}

/// Everything a render is set up with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// The dataset folder (`episodes/{split}.jsonl`).
    pub dataset: PathBuf,
    /// A scene folder or a folder of scene folders.
    pub scenes: PathBuf,
    /// The split to render.
    pub split: String,
    /// The action preset.
    pub preset: ActionPreset,
    /// The agent profile (`wheeled`, `go2`, `g1`, `h1`): radius for physics, camera height.
    pub agent: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// The images of each frame.
    pub sensors: Sensors,
    /// How RGB frames are stored.
    pub rgb_codec: RgbCodec,
    /// The output layout.
    pub format: Layout,
    /// Samples per NaVILA part, episodes per WebDataset shard.
    pub shard_size: usize,
    /// Render the first N goal-directed episodes of the split only.
    pub limit: Option<usize>,
    /// Seed of the NaVILA sample shuffle (the render itself has no random choice).
    pub seed: u64,
    /// Keep the episodes of walks that collided or ended far from the goal.
    pub keep_failed: bool,
    /// Episodes shown in `preview.gif` (0: no preview).
    pub preview: usize,
    /// Where the frames are rendered. Recorded only when not the CPU (so a CPU render's
    /// record is as it always was), and a render resumes only on the device it started on.
    #[serde(default, skip_serializing_if = "is_cpu")]
    pub device: Device,
    /// Which objects get bodies recovered from their Gaussians. Recorded only when not `auto`
    /// (so the record of the default is as it always was); a render resumes only with the
    /// bodies it started with.
    #[serde(default, skip_serializing_if = "is_auto")]
    pub splat_bodies: SplatBodies,
}

/// True for the default device (serde leaves it out of the settings).
fn is_cpu(device: &Device) -> bool {
    *device == Device::Cpu
}

/// True for the default choice of bodies (serde leaves it out of the settings).
fn is_auto(choice: &SplatBodies) -> bool {
    *choice == SplatBodies::Auto
}

impl Settings {
    /// Settings with the published defaults ([`Options::default`](crate::Options)) for
    /// `dataset` and `scenes`.
    ///
    /// # Errors
    ///
    /// None in practice (the defaults are in range).
    pub fn new(dataset: &Path, scenes: &Path) -> Result<Settings> {
        crate::Options::new(dataset.to_path_buf(), None).settings_with(scenes)
    }

    /// The environment the walks run in: the agent profile, the preset's discrete actions,
    /// the camera and the device it renders on.
    ///
    /// # Errors
    ///
    /// A bad profile, size, field of view, preset or motion cap (`max_actions`), naming the
    /// field; a step or turn the answers' wording cannot say; sensors the layout cannot hold.
    pub fn env_config(&self) -> Result<EnvConfig> {
        let mut config = EnvConfig {
            agent: self.agent.clone(),
            device: self.device,
            splat_bodies: self.splat_bodies,
            ..EnvConfig::default()
        };
        config.actions = ActionSpace::Discrete {
            forward: self.preset.step_m,
            turn_deg: self.preset.turn_deg,
            look_deg: 30.0,
            seconds: 1.0,
        };
        config.sensors = SensorConfig {
            width: self.width,
            height: self.height,
            hfov_deg: self.hfov_deg,
            camera_height: None,
            depth_size: None,
            rgb: true,
            depth: self.sensors.depth,
            semantic: self.sensors.semantic,
            instance: self.sensors.instance,
        };
        // Settings read from JSON (a distributed render's steps) have not been through the
        // options: the cap is checked before the step limit is made from it.
        self.preset.check_max_actions()?;
        config.task.max_steps = config.task.max_steps.max(self.preset.max_actions + 1);
        self.preset.check_answers()?;
        if self.shard_size == 0 {
            return Err(Error::invalid("`shard_size`: must be at least 1"));
        }
        if self.limit == Some(0) {
            return Err(Error::invalid(
                "`limit` 0 renders nothing: give at least 1, or leave it out for every episode",
            ));
        }
        if self.format == Layout::Lerobot && (self.sensors.semantic || self.sensors.instance) {
            return Err(Error::invalid(format!(
                "the LeRobot layout holds RGB and depth images only, not `sensors` {}; \
                 category and instance ids need the navila, webdataset or frames layout",
                self.sensors
            )));
        }
        config.validate()?;
        if config.profile()?.kind != sage_physics::Locomotion::Ground {
            return Err(Error::invalid(format!(
                "agent: '{}' is not a ground agent; a training-data walk needs one (wheeled, go2, g1, h1)",
                self.agent
            )));
        }
        Ok(config)
    }

    /// The settings as the run record stores them: without the folders (they may be named
    /// from another working directory; the dataset's hash says which data).
    pub(crate) fn recorded(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        if let Some(o) = v.as_object_mut() {
            o.remove("dataset");
            o.remove("scenes");
        }
        v
    }
}

/// An episode left out, with the reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Skip {
    /// The episode.
    pub episode_id: String,
    /// Why (names the scene or the file).
    pub reason: String,
}

/// What a render will do: the routes of every scene, and the episodes left out before it.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The settings.
    pub settings: Settings,
    /// The environment of the walks.
    pub env: EnvConfig,
    /// The routes by scene, scenes sorted, routes in dataset order.
    pub routes: BTreeMap<String, Vec<Route>>,
    /// Each scene's folder.
    pub scene_dirs: BTreeMap<String, PathBuf>,
    /// Episodes whose scene is not among the scenes.
    pub skipped: Vec<Skip>,
    /// Episodes of the split with nothing to walk, by reason: `no_goal` (no-goal episodes)
    /// and `no_motion` (a reference path of one point and no net turn); with a `limit`, those
    /// before the last episode it takes.
    pub ignored: BTreeMap<String, usize>,
    /// Degrees of one turn of the dataset's ground-truth actions (its run record's action
    /// space; 15, VLN-CE's, for datasets without one): how far a rotation in place turns.
    pub dataset_turn_deg: f32,
    /// The split file's hash.
    pub dataset_hash: String,
}

impl Plan {
    /// The run record's fingerprint of the scenes walked: per scene, the hash of every file
    /// loading it reads ([`sage_scene::scenes_input_hashes`]).
    pub fn scene_inputs(&self) -> serde_json::Value {
        serde_json::json!(sage_scene::scenes_input_hashes(
            self.routes.keys().map(String::as_str),
            &self.scene_dirs
        ))
    }

    /// Reads the split and groups its goal-directed episodes (the first `limit`) into routes.
    ///
    /// # Errors
    ///
    /// Bad settings, an unknown or empty split, an unreadable dataset or scenes folder.
    pub fn new(settings: &Settings) -> Result<Plan> {
        let env = settings.env_config()?;
        let (file, episodes) =
            sage_dataset::folder::split_episodes(&settings.dataset, &settings.split)?;
        let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
        // Read in split order up to the `limit`-th goal-directed episode: the episodes past it
        // are neither rendered nor counted as ignored.
        let mut ignored: BTreeMap<String, usize> = BTreeMap::new();
        let mut goal = Vec::new();
        for e in episodes {
            if settings.limit.is_some_and(|n| goal.len() >= n) {
                break;
            }
            let why = if e.task != Task::Vln {
                "no_goal"
            } else if e.reference_path.len() < 2 && replay::net_turns(&e) == 0 {
                "no_motion"
            } else {
                goal.push(e);
                continue;
            };
            *ignored.entry(why.into()).or_default() += 1;
        }
        if goal.is_empty() {
            return Err(Error::invalid(format!(
                "split '{}' has no goal-directed episodes to render",
                settings.split
            ))
            .in_file(&file));
        }
        // Episode ids name route folders and WebDataset keys: two that would share one are
        // refused before any work, never mixed.
        sage_io::names::distinct_stems("episode", goal.iter().map(|e| e.episode_id.as_str()))
            .in_file(&file)?;
        let scene_dirs = sage_io::scenes::scene_dirs_by_name(&settings.scenes)?;
        let (present, missing): (Vec<_>, Vec<_>) = goal
            .into_iter()
            .partition(|e| scene_dirs.contains_key(&e.scene));
        let skipped = missing
            .iter()
            .map(|e| Skip {
                episode_id: e.episode_id.clone(),
                reason: format!(
                    "scene '{}' is not among the scenes in {}",
                    e.scene,
                    settings.scenes.display()
                ),
            })
            .collect();
        let mut routes: BTreeMap<String, Vec<Route>> = BTreeMap::new();
        for r in replay::routes(&present) {
            routes.entry(r.scene.clone()).or_default().push(r);
        }
        let dataset_turn_deg =
            read_json::<serde_json::Value>(&settings.dataset.join(sage_io::run::RUN_RECORD))
                .ok()
                .and_then(|r| r.pointer("/config/scene/space/turn_deg")?.as_f64())
                .map_or(sage_lang::StepSizes::default().turn_deg, |t| t as f32);
        Ok(Plan {
            settings: settings.clone(),
            dataset_turn_deg,
            env,
            routes,
            scene_dirs,
            skipped,
            ignored,
            dataset_hash: fnv1a64_hex(&bytes),
        })
    }

    /// The scenes with routes to walk, sorted.
    pub fn scenes(&self) -> Vec<String> {
        self.routes.keys().cloned().collect()
    }

    /// Routes in all scenes.
    pub fn route_count(&self) -> usize {
        self.routes.values().map(Vec::len).sum()
    }

    /// Per scene, its routes and those already done under `out`: what a render split over
    /// machines needs to know of a folder to hand out only the work left.
    pub fn scene_progress(&self, out: &Path) -> BTreeMap<String, SceneProgress> {
        self.routes
            .iter()
            .map(|(scene, routes)| {
                let done = routes
                    .iter()
                    .filter(|r| is_done(out, r))
                    .map(|r| format!("{IMAGES_DIR}/{}/{}/{ROUTE_FILE}", r.scene, r.name))
                    .collect();
                let progress = SceneProgress {
                    routes: routes.len(),
                    done,
                };
                (scene.clone(), progress)
            })
            .collect()
    }
}

/// A scene's routes and those of them done in an output folder ([`Plan::scene_progress`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneProgress {
    /// Routes of the scene.
    pub routes: usize,
    /// The records (`images/{scene}/{route}/route.json`, relative to the output folder, `/`
    /// between names) of the routes done: a record with a walk.
    pub done: Vec<String>,
}

/// A route finished by [`render_scene`] (for progress displays).
#[derive(Debug, Clone)]
pub struct RouteDone {
    /// The scene.
    pub scene: String,
    /// The route.
    pub route: String,
    /// Frames rendered and kept: 0 for a walk whose episodes are not written, which physics
    /// alone tells before any frame is rendered.
    pub frames: usize,
    /// Routes in the whole render (all scenes).
    pub of: usize,
    /// Why it could not be walked.
    pub error: Option<String>,
}

impl RouteDone {
    /// The files of this route under `out`, relative to `out` with `/` between names, its
    /// record (`route.json`) last: the order to copy a finished route in elsewhere, so that a
    /// copy cut short is never taken for a finished route.
    ///
    /// # Errors
    ///
    /// The route's folder cannot be listed.
    pub fn files(&self, out: &Path) -> Result<Vec<String>> {
        let dir = out.join(IMAGES_DIR).join(&self.scene).join(&self.route);
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .map_err(|e| Error::io(&dir, e))?
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_file())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort_by_key(|n| (n == ROUTE_FILE, n.clone()));
        Ok(names
            .into_iter()
            .map(|n| format!("{IMAGES_DIR}/{}/{}/{n}", self.scene, self.route))
            .collect())
    }
}

/// The folder of a route's frames under `out`.
pub fn route_dir(out: &Path, route: &Route) -> PathBuf {
    out.join(IMAGES_DIR).join(&route.scene).join(&route.name)
}

/// True when the episodes of a route with `walk` are written: it was walked, and its walk
/// ended clean or failed walks are kept.
fn writes_episodes(settings: &Settings, walk: Option<&Walk>) -> bool {
    walk.is_some_and(|w| w.verdict == Verdict::Clean || settings.keep_failed)
}

/// Removes every file of a route folder but its record: the frames of a route whose episodes
/// are not written (a dropped walk, or one that could not be walked), which no annotation,
/// shard or manifest would name. Its record stays and says why its episodes are left out; a
/// dropped walk's record also makes the route done (a resume does not walk it again), while a
/// record holding only an error does not ([`is_done`]: the next run tries the route again).
fn drop_frames(dir: &Path) -> Result<()> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(dir, e)),
    };
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.is_file() && path.file_name().is_none_or(|n| n != ROUTE_FILE) {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}

/// True when `route` has a complete record under `out` (a walk, not an error).
fn is_done(out: &Path, route: &Route) -> bool {
    read_json::<RouteRecord>(&route_dir(out, route).join(ROUTE_FILE))
        .is_ok_and(|r| r.walk.is_some())
}

/// Renders the routes of `scene` that are not done under `out` (in parallel): per route its
/// frames, then its `route.json`. Unless failed walks are kept, every route is first walked
/// through physics alone (`triage`): a walk whose episodes will not be written (not clean)
/// leaves only its record, without a frame rendered. A route that cannot be walked gets a
/// record with the reason (retried by the next run); a scene that cannot be loaded gives every
/// route that record. Returns the routes done.
///
/// # Errors
///
/// A write error (a full disk, an unwritable folder), naming the file: the run cannot go on.
pub fn render_scene(
    plan: &Plan,
    scene: &str,
    out: &Path,
    on_route: &(dyn Fn(&RouteDone) + Sync),
) -> Result<usize> {
    let pending: Vec<&Route> = plan
        .routes
        .get(scene)
        .map(|r| r.iter().filter(|r| !is_done(out, r)).collect())
        .unwrap_or_default();
    if pending.is_empty() {
        return Ok(0);
    }
    let s = &plan.settings;
    let suffixes: Vec<String> = {
        let probe = sage_env::Images {
            rgb: Some(Vec::new()),
            depth: s.sensors.depth.then(Vec::new),
            semantic: s.sensors.semantic.then(Vec::new),
            instance: s.sensors.instance.then(Vec::new),
            ..Default::default()
        };
        encode::suffixes(&probe, s.rgb_codec)
            .into_iter()
            .map(String::from)
            .collect()
    };
    let record = |route: &Route, walk, error| RouteRecord {
        scene: route.scene.clone(),
        route: route.name.clone(),
        episodes: route
            .episodes
            .iter()
            .map(|e| e.episode_id.clone())
            .collect(),
        suffixes: suffixes.clone(),
        walk,
        error,
    };
    let ctx = SceneContext::load_with_bodies(
        &plan.scene_dirs[scene],
        None,
        &LoadOptions::default(),
        plan.env.splat_bodies,
    )
    .within(format!("scene {scene}"))
    .map(Arc::new);
    let ctx = match ctx {
        Ok(ctx) => ctx,
        Err(err) => {
            for route in &pending {
                let dir = route_dir(out, route);
                std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
                let rec = record(route, None, Some(err.to_string()));
                write_json(&dir.join(ROUTE_FILE), &rec)?;
                on_route(&RouteDone {
                    scene: scene.into(),
                    route: route.name.clone(),
                    frames: 0,
                    of: plan.route_count(),
                    error: rec.error,
                });
            }
            return Ok(pending.len());
        }
    };
    // A fresh folder per route: a route rendered before is rendered again whole.
    let begin = |route: &Route| -> Result<PathBuf> {
        let dir = route_dir(out, route);
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        }
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        Ok(dir)
    };
    // The route's record (its walk, or why it has none) and its progress.
    let end = |route: &Route, dir: &Path, walked: Result<Walk>| -> Result<()> {
        let (frames, rec) = match walked {
            Ok(walk) => {
                let kept = writes_episodes(s, Some(&walk));
                (
                    if kept { walk.steps.len() } else { 0 },
                    record(route, Some(walk), None),
                )
            }
            Err(err) => (
                0,
                record(
                    route,
                    None,
                    Some(
                        err.within(format!("episode {}", route.episodes[0].episode_id))
                            .to_string(),
                    ),
                ),
            ),
        };
        // Before the record: a crash in between leaves a route without one, walked again.
        if !writes_episodes(s, rec.walk.as_ref()) {
            drop_frames(dir)?;
        }
        write_json(&dir.join(ROUTE_FILE), &rec)?;
        on_route(&RouteDone {
            scene: scene.into(),
            route: route.name.clone(),
            frames,
            of: plan.route_count(),
            error: rec.error,
        });
        Ok(())
    };
    let done = pending.len();
    // With failed walks kept every walk is rendered: the physics pass would only repeat it.
    let pending = if s.keep_failed {
        pending
    } else {
        triage(plan, &ctx, pending, &begin, &end)?
    };
    if pending.is_empty() {
        return Ok(done);
    }
    let first = Env::new(ctx.clone(), plan.env.clone())?;
    if first.renders_in_scene_batches() {
        return lockstep(plan, &ctx, &pending, first, &begin, &end).map(|()| done);
    }
    // One worker walks with the environment opened above; the others open their own.
    let spare = Mutex::new(Some(first));
    pending
        .par_iter()
        .map_init(
            || {
                let env = spare.lock().ok().and_then(|mut e| e.take());
                env.map_or_else(|| Env::new(ctx.clone(), plan.env.clone()), Ok)
            },
            |env, route| {
                let env = env.as_mut().map_err(|e| Error::invalid(e.to_string()))?;
                let dir = begin(route)?;
                // A write error stops the run; an error of the walk itself is the route's.
                let mut write_error = None;
                let walked =
                    replay::walk(env, route, &s.preset, plan.dataset_turn_deg, |k, images| {
                        match write_frame(&dir, k, images, s.rgb_codec)? {
                            Ok(()) => Ok(()),
                            Err(e) => {
                                write_error = Some(e);
                                Err(Error::invalid("a frame could not be written"))
                            }
                        }
                    });
                if let Some(err) = write_error {
                    return Err(err);
                }
                end(route, &dir, walked)
            },
        )
        .collect::<Result<Vec<()>>>()?;
    Ok(done)
}

/// Walks `routes` through physics alone (an environment without sensors, in parallel) and
/// ends there, with its record, each route that cannot be walked or whose episodes will not be
/// written; returns the others, in order, to be walked again with their frames. The second
/// walk is the same: the walk takes its actions from the poses physics gives, never from the
/// images, and physics runs the same steps from the same start (tested). A dropped walk so
/// costs its physics, about a thousandth of its frames' rendering.
fn triage<'r>(
    plan: &Plan,
    ctx: &Arc<SceneContext>,
    routes: Vec<&'r Route>,
    begin: &(dyn Fn(&Route) -> Result<PathBuf> + Sync),
    end: &EndRoute<'_>,
) -> Result<Vec<&'r Route>> {
    let s = &plan.settings;
    let mut config = plan.env.clone();
    config.sensors = config.sensors.without_images();
    let kept = routes
        .into_par_iter()
        .map_init(
            || Env::new(ctx.clone(), config.clone()),
            |env, route| {
                let env = env.as_mut().map_err(|e| Error::invalid(e.to_string()))?;
                let walked =
                    replay::walk(env, route, &s.preset, plan.dataset_turn_deg, |_, _| Ok(()));
                if walked
                    .as_ref()
                    .is_ok_and(|walk| writes_episodes(s, Some(walk)))
                {
                    return Ok(Some(route));
                }
                let dir = begin(route)?;
                end(route, &dir, walked)?;
                Ok(None)
            },
        )
        .collect::<Result<Vec<Option<&Route>>>>()?;
    Ok(kept.into_iter().flatten().collect())
}

/// Walks at once in a lockstep render, over all cohorts.
const LOCKSTEP_WALKS: usize = 128;

/// Cohorts of a lockstep render, each with a batch of its own in flight: while the GPU renders
/// one cohort's frames, the host steps the other's walks through physics and encodes and
/// writes their frames of the step before.
const COHORTS: usize = 2;

/// Encodes frame `k` of a walk into `dir`: the encoding's error is the walk's (outer `Ok`), a
/// file that cannot be written stops the run (inner `Err`).
fn write_frame(
    dir: &Path,
    k: usize,
    images: &sage_env::Images,
    codec: RgbCodec,
) -> Result<Result<()>> {
    for (suffix, bytes) in encode::encode(images, codec)? {
        let path = dir.join(format!("{k:04}.{suffix}"));
        if let Err(e) = std::fs::write(&path, bytes) {
            return Ok(Err(Error::io(&path, e)));
        }
    }
    Ok(Ok(()))
}

/// Writes a route's record (its walk, or why it has none) into its folder and reports it.
type EndRoute<'a> = dyn Fn(&Route, &Path, Result<Walk>) -> Result<()> + Sync + 'a;

/// A walk of a lockstep render.
struct Stepping<'r> {
    route: &'r Route,
    dir: PathBuf,
    env: Env,
    walker: Walker,
    /// The frame to render in the next batch.
    pending: Option<Pending>,
    /// Its frame observed in the last batch is to be written.
    observed: Option<usize>,
    /// Why it stopped early.
    failed: Option<Error>,
}

/// The walks of one cohort of a lockstep render and its batch in flight.
#[derive(Default)]
struct Cohort<'r> {
    active: Vec<Stepping<'r>>,
    in_flight: Option<Rendering>,
}

/// What every cohort of a lockstep render shares: the routes not yet started, the
/// environments of walks that ended, and what begins and ends a route.
struct Lockstep<'a, 'r> {
    plan: &'a Plan,
    ctx: &'a Arc<SceneContext>,
    queue: std::slice::Iter<'r, &'r Route>,
    spare: Vec<Env>,
    begin: &'a (dyn Fn(&Route) -> Result<PathBuf> + Sync),
    end: &'a EndRoute<'a>,
}

/// Renders `routes` on a GPU that every environment over the scene shares, up to
/// [`LOCKSTEP_WALKS`] walks at once in [`COHORTS`] cohorts taking turns: each turn of a cohort
/// renders the next frame of every walk of it in one batch, and while the GPU renders it, the
/// host steps the other cohort's walks through physics and encodes and writes the frames of
/// the step before. Walks start as others end, in `routes` order; each walk's frames and
/// record are those [`replay::walk`] gives it alone.
fn lockstep(
    plan: &Plan,
    ctx: &Arc<SceneContext>,
    routes: &[&Route],
    first: Env,
    begin: &(dyn Fn(&Route) -> Result<PathBuf> + Sync),
    end: &EndRoute<'_>,
) -> Result<()> {
    let mut shared = Lockstep {
        plan,
        ctx,
        queue: routes.iter(),
        spare: vec![first],
        begin,
        end,
    };
    let mut cohorts: Vec<Cohort> = (0..COHORTS).map(|_| Cohort::default()).collect();
    loop {
        for c in 0..COHORTS {
            // Routes are shared out evenly while fewer remain than the cohorts hold, so that
            // each cohort's batch renders while the other's walks are stepped.
            let busy: usize = cohorts.iter().map(|other| walking(&other.active)).sum();
            let places =
                (LOCKSTEP_WALKS / COHORTS).min((busy + shared.queue.len()).div_ceil(COHORTS));
            shared.turn(&mut cohorts[c], places)?;
        }
        let idle = |c: &Cohort| c.active.is_empty() && c.in_flight.is_none();
        if cohorts.iter().all(idle) && shared.queue.len() == 0 {
            return Ok(());
        }
    }
}

/// The walks of `active` with a frame to render.
fn walking(active: &[Stepping]) -> usize {
    active.iter().filter(|w| w.pending.is_some()).count()
}

impl<'r> Lockstep<'_, 'r> {
    /// One turn of `cohort`: its last batch's frames observed and its walks' next actions
    /// stepped, new walks in the places of those that ended (up to `places` walking), its next
    /// batch submitted, the frames observed written, and the records of walks that ended.
    fn turn(&mut self, cohort: &mut Cohort<'r>, places: usize) -> Result<()> {
        let s = &self.plan.settings;
        let active = &mut cohort.active;
        // The last batch's frames: observed, then the next actions (physics, in parallel).
        if let Some(rendering) = cohort.in_flight.take() {
            let mut outputs = rendering.wait()?.into_iter();
            let per_walk: Vec<Vec<RenderOutput>> = active
                .iter()
                .map(|w| {
                    let n = w.pending.as_ref().map_or(0, |p| p.cameras().len());
                    outputs.by_ref().take(n).collect()
                })
                .collect();
            active.par_iter_mut().zip(per_walk).for_each(|(w, images)| {
                let Some(pending) = w.pending.take() else {
                    return;
                };
                if w.failed.is_some() {
                    // Its frame could not be encoded: its images are not wanted.
                    return;
                }
                let stepped = w
                    .env
                    .observation(pending, images)
                    .map(|obs| w.walker.observe(obs))
                    .and_then(|k| {
                        w.observed = Some(k);
                        w.walker.advance(&mut w.env)
                    });
                match stepped {
                    Ok(next) => w.pending = next,
                    Err(e) => w.failed = Some(e),
                }
            });
        }
        // New walks take the places of those that ended.
        while walking(active) < places {
            let Some(route) = self.queue.next() else {
                break;
            };
            let dir = (self.begin)(route)?;
            let mut env = match self.spare.pop() {
                Some(env) => env,
                None => Env::new(self.ctx.clone(), self.plan.env.clone())?,
            };
            match Walker::start(&mut env, route, &s.preset, self.plan.dataset_turn_deg) {
                Ok((walker, pending)) => active.push(Stepping {
                    route,
                    dir,
                    env,
                    walker,
                    pending: Some(pending),
                    observed: None,
                    failed: None,
                }),
                Err(e) => {
                    (self.end)(route, &dir, Err(e))?;
                    self.spare.push(env);
                }
            }
        }
        // The next batch renders while this step's frames are written (and the other cohort
        // takes its turn).
        let cameras: Vec<_> = active
            .iter()
            .filter_map(|w| w.pending.as_ref())
            .flat_map(|p| p.cameras().iter().copied())
            .collect();
        if let Some(lead) = active.iter_mut().find(|w| w.pending.is_some()) {
            cohort.in_flight = Some(lead.env.submit(&cameras)?);
        }
        let failures: Vec<Result<()>> = active
            .par_iter_mut()
            .map(|w| {
                let (Some(k), None) = (w.observed.take(), &w.failed) else {
                    return Ok(());
                };
                let Some(images) = w.walker.images() else {
                    return Ok(());
                };
                match write_frame(&w.dir, k, images, s.rgb_codec) {
                    Ok(written) => written,
                    Err(e) => {
                        w.failed = Some(e);
                        Ok(())
                    }
                }
            })
            .collect();
        failures.into_iter().collect::<Result<Vec<()>>>()?;
        // Walks that ended (STOP, or an error) get their records once no frame of theirs is
        // in flight.
        let mut k = 0;
        while k < active.len() {
            if active[k].pending.is_some() {
                k += 1;
                continue;
            }
            let w = active.remove(k);
            let walked = match w.failed {
                Some(e) => Err(e),
                None => Ok(w.walker.finish(&w.env, w.route)),
            };
            (self.end)(w.route, &w.dir, walked)?;
            self.spare.push(w.env);
        }
        Ok(())
    }
}

/// Counts of a finished render.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    /// Goal-directed episodes selected from the split.
    pub episodes: usize,
    /// Routes (walks) they share.
    pub routes: usize,
    /// Episodes written.
    pub kept: usize,
    /// Episodes dropped, by their walk's verdict.
    pub dropped: BTreeMap<String, usize>,
    /// Episodes written although their walk did not end clean (`keep_failed`), by its verdict:
    /// what `dropped` would have counted. Absent when there are none.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub kept_failed: BTreeMap<String, usize>,
    /// Episodes skipped for an error (listed in `skipped`).
    pub skipped: usize,
    /// Episodes of the split with nothing to walk, by reason (`no_goal`, `no_motion`).
    pub ignored: BTreeMap<String, usize>,
    /// NaVILA samples (one per step of each kept episode).
    pub samples: usize,
    /// Frames rendered for the kept routes.
    pub frames: usize,
}

/// A written file: its path relative to the output, size and FNV-1a 64 hash.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileEntry {
    /// Relative path.
    pub path: String,
    /// Bytes.
    pub bytes: u64,
    /// FNV-1a 64 of the bytes, hex.
    pub fnv1a64: String,
}

/// The manifest of a finished render, written last.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// `sage3d`.
    pub tool: String,
    /// Its version.
    pub version: String,
    /// The settings (without the folders).
    pub settings: serde_json::Value,
    /// The split file's hash.
    pub dataset_hash: String,
    /// The counts.
    pub counts: Counts,
    /// Episodes left out for an error, with the reason.
    pub skipped: Vec<Skip>,
    /// The format's files (parts, shards, index).
    pub files: Vec<FileEntry>,
    /// The frames under `images/` (none for WebDataset and LeRobot, whose shards and Parquet
    /// files hold them): count, total bytes and one FNV-1a 64 over every frame in path order,
    /// each as its relative path, a 0 byte, its length (u64, little-endian) and its bytes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<FileEntry>,
}

impl Manifest {
    /// True when something asked for was not done: an episode skipped for an error.
    pub fn skipped_any(&self) -> bool {
        self.counts.skipped > 0
    }
}

/// Writes the format's files from the rendered routes, the preview when asked for, then the
/// manifest, then (WebDataset, LeRobot) removes the frames folder the shards or Parquet files
/// now hold. Frames of routes whose episodes are not written (left by a render made before
/// [`render_scene`] removed them) are removed first.
///
/// # Errors
///
/// A route not rendered yet, an unreadable route record or frame, no episode kept, a write
/// error.
///
/// Callers hold the lock on `out` ([`claim`], [`lock`]).
pub fn finish(plan: &Plan, out: &Path) -> Result<Manifest> {
    let s = &plan.settings;
    let mut counts = Counts {
        episodes: plan
            .routes
            .values()
            .flatten()
            .map(|r| r.episodes.len())
            .sum::<usize>()
            + plan.skipped.len(),
        routes: plan.route_count(),
        ignored: plan.ignored.clone(),
        ..Counts::default()
    };
    let mut skipped = plan.skipped.clone();
    let mut samples: Vec<EpisodeSample> = Vec::new();
    for route in plan.routes.values().flatten() {
        let path = route_dir(out, route).join(ROUTE_FILE);
        if !path.is_file() {
            return Err(Error::invalid(format!(
                "route {} of scene {} has not been rendered (run the render again)",
                route.name, route.scene
            )));
        }
        let rec: RouteRecord = read_json(&path)?;
        // Rendered before dropped walks left no frames (or copied in from such a render).
        if !writes_episodes(s, rec.walk.as_ref()) {
            drop_frames(&route_dir(out, route))?;
        }
        match &rec.walk {
            None => skipped.extend(route.episodes.iter().map(|e| Skip {
                episode_id: e.episode_id.clone(),
                reason: rec.error.clone().unwrap_or_default(),
            })),
            Some(walk) => {
                let failed = (walk.verdict != Verdict::Clean).then(|| {
                    serde_json::to_value(walk.verdict)
                        .ok()
                        .and_then(|v| v.as_str().map(String::from))
                        .unwrap_or_default()
                });
                match failed {
                    Some(why) if !s.keep_failed => {
                        *counts.dropped.entry(why).or_default() += route.episodes.len();
                        continue;
                    }
                    Some(why) => {
                        *counts.kept_failed.entry(why).or_default() += route.episodes.len()
                    }
                    None => {}
                }
                counts.frames += walk.steps.len();
                samples.extend(sample::samples(route, &rec, &s.preset));
            }
        }
    }
    counts.kept = samples.len();
    counts.skipped = skipped.len();
    counts.samples = samples.iter().map(|e| e.actions.len()).sum();
    if samples.is_empty() {
        // Training data without an episode is no training data (and LeRobot cannot open it):
        // refused before any file of the layout, so the folder is never taken for a finished one.
        let dropped: Vec<String> = counts
            .dropped
            .iter()
            .map(|(why, n)| format!("{n} {why}"))
            .collect();
        return Err(Error::invalid(format!(
            "no episode was kept: {} dropped ({}), {} skipped; nothing to write (`keep_failed` \
             keeps the walks that did not end clean)",
            counts.dropped.values().sum::<usize>(),
            if dropped.is_empty() {
                "none".to_string()
            } else {
                dropped.join(", ")
            },
            counts.skipped
        ))
        .in_file(out));
    }
    let written = match s.format {
        Layout::Navila => output::write_navila(
            out,
            &samples,
            &s.preset,
            s.shard_size,
            s.seed,
            &format!("sage3d_{}_{}", s.split, s.preset.name),
        )?,
        Layout::Webdataset => output::write_webdataset(out, &samples, s.shard_size, &s.split)?,
        Layout::Frames => output::write_frames_index(out, &samples)?,
        Layout::Lerobot => crate::lerobot::write(out, &samples, &lerobot_spec(plan)?)?,
    };
    let files = written
        .iter()
        .map(|p| {
            let bytes = std::fs::read(out.join(p)).map_err(|e| Error::io(out.join(p), e))?;
            Ok(FileEntry {
                path: p.clone(),
                bytes: bytes.len() as u64,
                fnv1a64: fnv1a64_hex(&bytes),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let images = (!s.format.packs_frames())
        .then(|| images_entry(out, &samples))
        .transpose()?;
    let manifest = Manifest {
        tool: "sage3d".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        settings: s.recorded(),
        dataset_hash: plan.dataset_hash.clone(),
        counts,
        skipped,
        files,
        images,
    };
    if s.preview > 0 {
        let from = crate::preview::Sources {
            routes: &plan.routes,
            scene_dirs: &plan.scene_dirs,
            frame_size: (s.width as usize, s.height as usize),
        };
        crate::preview::write(&from, out, &samples, s.preview)?;
    }
    write_json(&out.join(MANIFEST), &manifest)?;
    remove_packed_frames(out, s.format)?;
    Ok(manifest)
}

/// Removes the route folders of frames once a layout that packs them (shards, LeRobot videos)
/// has written its manifest: on a finished render, and again on a rerun that finds the render
/// finished, for a run stopped between the manifest and this.
fn remove_packed_frames(out: &Path, format: Layout) -> Result<()> {
    let frames = out.join(IMAGES_DIR);
    if format.packs_frames() && frames.exists() {
        std::fs::remove_dir_all(&frames).map_err(|e| Error::io(&frames, e))?;
    }
    Ok(())
}

/// What the LeRobot files are made from besides the samples: the render's frame size and
/// camera, and each episode's floor height (its start's z: a ground agent stays on it).
fn lerobot_spec(plan: &Plan) -> Result<crate::lerobot::Spec> {
    let s = &plan.settings;
    let sensors = &plan.env.sensors;
    Ok(crate::lerobot::Spec {
        split: s.split.clone(),
        robot_type: s.agent.clone(),
        width: s.width,
        height: s.height,
        hfov_deg: s.hfov_deg,
        depth: s.sensors.depth,
        eye_height: sensors
            .camera_height
            .map_or_else(|| plan.env.profile().map(|p| p.camera_height), Ok)?,
        floor: plan
            .routes
            .values()
            .flatten()
            .flat_map(|r| &r.episodes)
            .map(|e| (e.episode_id.clone(), e.start.position[2]))
            .collect(),
    })
}

/// The frames of the kept samples as one entry: count, bytes and the hash of
/// [`frames_hash`].
fn images_entry(out: &Path, samples: &[EpisodeSample]) -> Result<FileEntry> {
    let mut files: Vec<&str> = samples
        .iter()
        .flat_map(|e| e.files.iter().flatten())
        .map(String::as_str)
        .collect();
    files.sort_unstable();
    files.dedup();
    let (bytes, hash) = frames_hash(&out.join(IMAGES_DIR), &files)?;
    Ok(FileEntry {
        path: format!("{IMAGES_DIR}/ ({} files)", files.len()),
        bytes,
        fnv1a64: hash,
    })
}

/// The bytes of `files` (relative to `root`, `/` between names, in the order given: sorted)
/// and the FNV-1a 64 ([`sage_io::hash::fnv1a64`]) of one stream holding, per file, its path
/// (UTF-8), a 0 byte, its length in bytes as a little-endian u64, then its bytes: the length
/// and the 0 byte (which no path holds) delimit each file, so moving bytes from one file to
/// the next, or from a path into a file, changes the hash. As 16 lower-case hex digits.
fn frames_hash(root: &Path, files: &[&str]) -> Result<(u64, String)> {
    let mut hash = Fnv1a64::new();
    let mut bytes = 0u64;
    for f in files {
        let path = root.join(f);
        let data = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        bytes += data.len() as u64;
        hash.write(f.as_bytes());
        hash.write(&[0]);
        hash.write(&(data.len() as u64).to_le_bytes());
        hash.write(&data);
    }
    Ok((bytes, format!("{:016x}", hash.0)))
}

/// FNV-1a 64 fed piece by piece: [`sage_io::hash::fnv1a64`] of everything fed (tested), without
/// holding it all in memory (a render's frames may take gigabytes). sage-io offers the one-shot
/// form only.
struct Fnv1a64(u64);

impl Fnv1a64 {
    /// The hash of nothing.
    fn new() -> Fnv1a64 {
        Fnv1a64(0xcbf2_9ce4_8422_2325)
    }

    /// Feeds `bytes`.
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// The command a render's run record names.
const COMMAND: &str = "data render";

/// The files a render may have written in an output folder (nothing else is ever touched).
const OWN: [&str; 9] = [
    IMAGES_DIR,
    lerobot::META_DIR,
    lerobot::DATA_DIR,
    output::SHARDS_DIR,
    output::EPISODES_FILE,
    "dataset_info.json",
    MANIFEST,
    sage_io::run::RUN_RECORD,
    crate::preview::PREVIEW_FILE,
];

fn is_own(name: &str) -> bool {
    OWN.contains(&name) || (name.starts_with("annotations_part_") && name.ends_with(".json"))
}

/// True when a render may have written the file at `path` (relative to the output folder, by
/// components, inside one of the folders of [`OWN`]): a frame or route record at
/// `images/{scene}/{route}/`, a WebDataset shard, a LeRobot data, episodes or meta file, or
/// a temporary file of any of them.
fn render_writes(path: &[&str]) -> bool {
    let numbered = |name: &str, prefix: &str, suffix: &str| {
        name.strip_prefix(prefix)
            .and_then(|n| n.strip_suffix(suffix))
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
    };
    let chunk_file = |chunk: &str, file: &str| {
        numbered(chunk, "chunk-", "") && numbered(file, "file-", ".parquet")
    };
    match path {
        [.., name] if sage_io::files::is_temporary(name) => true,
        [IMAGES_DIR, _, _, name] => *name == ROUTE_FILE || encode::is_frame_file(name),
        [output::SHARDS_DIR, name] => name.ends_with(".tar"),
        [lerobot::DATA_DIR, chunk, file] | [lerobot::META_DIR, "episodes", chunk, file] => {
            chunk_file(chunk, file)
        }
        [lerobot::META_DIR, _] => [lerobot::INFO_FILE, lerobot::STATS_FILE, lerobot::TASKS_FILE]
            .contains(&path.join("/").as_str()),
        _ => false,
    }
}

/// The first file under the folder `out/name` (one of [`OWN`]) that a render would not have
/// written ([`render_writes`]), relative to `out`: [`claim`] refuses the output folder then,
/// so that neither `force` nor a render's own clean-up of its folders removes a user's file.
fn foreign_within(out: &Path, name: &str) -> Result<Option<String>> {
    let mut stack = vec![vec![name.to_string()]];
    while let Some(parts) = stack.pop() {
        let dir = parts.iter().fold(out.to_path_buf(), |p, c| p.join(c));
        for entry in std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, e))? {
            let entry = entry.map_err(|e| Error::io(&dir, e))?;
            let mut path = parts.clone();
            path.push(entry.file_name().to_string_lossy().into_owned());
            // A link is judged by its own name, as removing the folder removes only the link.
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(path);
            } else if !render_writes(&path.iter().map(String::as_str).collect::<Vec<_>>()) {
                return Ok(Some(path.join("/")));
            }
        }
    }
    Ok(None)
}

/// Locks `out` for a render ([`FolderLock`]): no other command writes it while the guard is
/// held. [`claim`] takes this lock; a caller that writes into a claimed folder again later
/// (the finish of a distributed render) takes it around that write.
///
/// # Errors
///
/// A folder that another command is writing, naming it; a folder that cannot be made.
pub fn lock(out: &Path) -> Result<FolderLock> {
    FolderLock::acquire(out, COMMAND)
}

/// Claims `out` for a render with `plan`'s settings: a new or empty folder, or the folder of
/// the same render (which resumes). With `force`, a folder of another render has that
/// render's files removed first. Returns the folder's [`lock`], to hold while the render
/// writes there, and the manifest when the same render already finished. Temporary files that
/// an interrupted earlier render left are removed from a claimed folder.
///
/// # Errors
///
/// A folder that another command is writing, a folder holding files a render did not write,
/// or another render's output without `force`; a write error.
pub fn claim(plan: &Plan, out: &Path, force: bool) -> Result<(FolderLock, Option<Manifest>)> {
    let record_path = out.join(sage_io::run::RUN_RECORD);
    let settings = plan.settings.recorded();
    let lock = lock(out)?;
    let names = sage_io::run::entries(out)?;
    let foreign = match names.iter().find(|n| !is_own(n)) {
        Some(name) => Some(name.clone()),
        None => names
            .iter()
            .filter(|n| out.join(n).is_dir())
            .find_map(|n| foreign_within(out, n).transpose())
            .transpose()?,
    };
    if let Some(foreign) = foreign {
        return Err(Error::invalid(format!(
            "the output folder holds '{foreign}', which a training-data render did not write; choose an empty or new folder"
        ))
        .in_file(out));
    }
    let rendered = sage_io::run::recorded_command(out).as_deref() == Some(COMMAND);
    if !names.is_empty() && !rendered {
        return Err(Error::invalid(
            "the output folder is not a training-data render's (its run record is missing or names another command); choose an empty or new folder",
        )
        .in_file(out));
    }
    let scenes = plan.scene_inputs();
    // Records written before the scenes' hashes existed resume on their settings alone.
    let same = read_json::<serde_json::Value>(&record_path).is_ok_and(|old| {
        old.get("settings") == Some(&settings)
            && old.get("dataset_hash").and_then(|h| h.as_str()) == Some(plan.dataset_hash.as_str())
            && old.get("scene_inputs").is_none_or(|o| *o == scenes)
    });
    if !same && !names.is_empty() {
        if !force {
            return Err(Error::invalid(
                "the output folder holds a render with other settings, another dataset or other scene files; use a new output folder (`out`), or set `force` to replace it",
            )
            .in_file(out));
        }
        for name in names.iter().filter(|n| is_own(n)) {
            let p = out.join(name);
            let removed = if p.is_dir() {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            };
            removed.map_err(|e| Error::io(&p, e))?;
        }
    }
    lock.remove_temporary();
    if same && let Ok(m) = read_json::<Manifest>(&out.join(MANIFEST)) {
        remove_packed_frames(out, plan.settings.format)?;
        return Ok((lock, Some(m)));
    }
    sage_io::run::write_run_record(
        out,
        COMMAND,
        Some(plan.settings.seed),
        serde_json::json!({
            "settings": settings,
            "dataset_hash": plan.dataset_hash,
            "scene_inputs": scenes,
        }),
    )?;
    Ok((lock, None))
}

/// What a whole [`render`] tells its caller as it goes.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// The plan is made: this many routes in all (done ones included).
    Planned {
        /// Routes of every scene.
        routes: usize,
        /// The files navigation reads of the scenes walked that changed since the dataset was
        /// built ([`sage_dataset::folder::scene_changes`]): the walks follow reference paths
        /// planned on the files as they were.
        scene_changes: &'a [String],
    },
    /// The same render already finished in the output folder: nothing is rendered.
    AlreadyComplete,
    /// A scene starts (its scene is being loaded).
    Scene(&'a str),
    /// A route is done (walked, or given up with its reason).
    Route(&'a RouteDone),
}

/// A whole render: claim `out`, render every scene (resuming routes already done), finish.
/// A render that already finished returns its manifest.
///
/// # Errors
///
/// As [`Plan::new`], [`claim`], [`render_scene`] and [`finish`].
pub fn render(
    settings: &Settings,
    out: &Path,
    force: bool,
    on_progress: &(dyn Fn(Progress<'_>) + Sync),
) -> Result<Manifest> {
    let plan = Plan::new(settings)?;
    let scene_changes = sage_dataset::folder::scene_changes(
        &settings.dataset,
        plan.routes.keys().map(String::as_str),
        &plan.scene_dirs,
    );
    on_progress(Progress::Planned {
        routes: plan.route_count(),
        scene_changes: &scene_changes,
    });
    let (_lock, done) = claim(&plan, out, force)?;
    if let Some(done) = done {
        on_progress(Progress::AlreadyComplete);
        return Ok(done);
    }
    for scene in plan.scenes() {
        on_progress(Progress::Scene(&scene));
        render_scene(&plan, &scene, out, &|r| on_progress(Progress::Route(r)))?;
    }
    finish(&plan, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frames_hash_is_fnv1a64_of_delimited_paths_and_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir_all(root.join("home/r")).unwrap();
        std::fs::write(root.join("home/r/0000.jpg"), b"ab").unwrap();
        std::fs::write(root.join("home/r/0001.jpg"), b"").unwrap();
        let files = ["home/r/0000.jpg", "home/r/0001.jpg"];
        let (bytes, hash) = frames_hash(root, &files).unwrap();
        let mut stream = Vec::new();
        for (path, data) in [(files[0], &b"ab"[..]), (files[1], &b""[..])] {
            stream.extend_from_slice(path.as_bytes());
            stream.push(0);
            stream.extend_from_slice(&(data.len() as u64).to_le_bytes());
            stream.extend_from_slice(data);
        }
        assert_eq!(bytes, 2);
        assert_eq!(hash, sage_io::hash::fnv1a64_hex(&stream));
        // A byte moved from one frame to the next is another stream, hence another hash.
        std::fs::write(root.join("home/r/0000.jpg"), b"a").unwrap();
        std::fs::write(root.join("home/r/0001.jpg"), b"b").unwrap();
        let (moved_bytes, moved) = frames_hash(root, &files).unwrap();
        assert_eq!(moved_bytes, 2);
        assert_ne!(moved, hash);
        let e = frames_hash(root, &["home/r/missing.jpg"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.jpg"), "{e}");
    }
}
