//! `sage3d bench physics`: one agent stepping through a scene, physics only (no rendering).

use crate::machine;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Pose, Result};
use sage_physics::{
    AgentBody, AgentProfile, Command, Decomposer, HullCache, Locomotion, SceneBodies, World,
    WorldOptions, default_cache_dir,
};
use sage_scene::Scene;
use sage_synth::{SceneKind, SynthConfig};
use serde::Serialize;
use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

/// What `bench physics` steps, and where.
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicsSettings {
    /// Scene folder (`None`: generate a home with `objects` objects).
    pub scene: Option<PathBuf>,
    /// Objects in the generated scene (doors and windows included).
    pub objects: usize,
    /// Hull cache (`None`: SCENE/.sage3d/collision, or a folder in the system temp dir for a
    /// generated scene, so repeated runs reuse it).
    pub cache: Option<PathBuf>,
    /// Agent profile name (`wheeled`, `go2`, `g1`, `h1`, `uav`).
    pub agent: String,
    /// Agent steps per timed run.
    pub steps: usize,
    /// Timed runs (the median is reported).
    pub repeat: usize,
    /// Seed of the generated scene and of the command sequence.
    pub seed: u64,
}

impl Default for PhysicsSettings {
    fn default() -> Self {
        Self {
            scene: None,
            objects: 200,
            cache: None,
            agent: "wheeled".into(),
            steps: 100_000,
            repeat: 5,
            seed: 0,
        }
    }
}

/// What `bench physics` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PhysicsReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Scene name.
    pub scene: String,
    /// Objects in the scene.
    pub objects: usize,
    /// Walls in the scene.
    pub walls: usize,
    /// Convex collision parts.
    pub parts: usize,
    /// Seconds to build the collision bodies.
    pub bodies_s: f64,
    /// Objects decomposed for this run.
    pub decomposed: usize,
    /// Objects whose hulls came from the cache.
    pub cached: usize,
    /// The hull cache folder.
    pub cache_dir: String,
    /// Agent profile name.
    pub agent: String,
    /// Steps per timed run.
    pub steps: usize,
    /// Steps per second of each run, slowest first.
    pub steps_per_s: Vec<f64>,
    /// Steps of the first run touching something.
    pub touching: usize,
    /// Steps of the first run that left the agent stuck.
    pub stuck: usize,
    /// Recoveries in the first run.
    pub recovered: usize,
}

impl PhysicsReport {
    /// Median steps per second.
    pub fn median_steps_per_s(&self) -> f64 {
        crate::median(&self.steps_per_s)
    }
}

impl fmt::Display for PhysicsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.steps as f64;
        let median = self.median_steps_per_s();
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            {} ({} objects, {} walls, {} collision parts)",
            self.scene, self.objects, self.walls, self.parts
        )?;
        writeln!(
            f,
            "bodies           built in {:.2} s ({} decomposed, {} from cache {})",
            self.bodies_s, self.decomposed, self.cached, self.cache_dir
        )?;
        writeln!(
            f,
            "agent            {} ({} steps per run, {} runs; seeded wander: forward, turn, velocity; turn away when blocked)",
            self.agent,
            self.steps,
            self.steps_per_s.len()
        )?;
        writeln!(
            f,
            "steps/s          median {:.0}, best {:.0} ({:.2} µs per step)",
            median,
            self.steps_per_s.last().copied().unwrap_or(f64::NAN),
            1e6 / median
        )?;
        writeln!(
            f,
            "contacts         {:.1} % of steps touching, {:.1} % stuck, {} recoveries",
            100.0 * self.touching as f64 / n,
            100.0 * self.stuck as f64 / n,
            self.recovered
        )
    }
}

/// The next command of a seeded wandering agent: mostly 0.25 m forward steps, 15° turns and
/// velocity commands; after a step that contact mostly blocked (c > 0.5), a turn of 90–180°, so
/// the walk explores the scene instead of pressing into a corner.
fn wander(rng: &mut ChaCha8Rng, blocked: bool, uav: bool) -> Command {
    let sign = if rng.random() { 1.0f32 } else { -1.0 };
    if blocked {
        return Command::Turn {
            angle: sign * rng.random_range(90f32..180.0).to_radians(),
        };
    }
    match rng.random_range(0..10) {
        0..=5 => Command::Forward { distance: 0.25 },
        6 => Command::Turn {
            angle: sign * 15f32.to_radians(),
        },
        _ if uav => Command::Uav {
            vx: rng.random_range(0.0..1.0),
            vy: rng.random_range(-0.3..0.3),
            vz: rng.random_range(-0.5..0.5),
            wz: rng.random_range(-0.5..0.5),
            dt: 0.2,
        },
        _ => Command::Ground {
            vx: rng.random_range(0.0..1.0),
            vy: 0.0,
            wz: rng.random_range(-0.8..0.8),
            dt: 0.25,
        },
    }
}

/// Runs `bench physics`: the scene's collision bodies (hulls from the cache where there), then
/// `repeat` runs of the same seeded walk of `steps` steps from the middle of the largest room;
/// contacts are counted over the first run.
///
/// # Errors
///
/// An unknown agent profile, a scene that cannot be loaded or generated or has no rooms, or a
/// failing step.
pub fn run(settings: &PhysicsSettings) -> Result<PhysicsReport> {
    let profile: AgentProfile = settings.agent.parse()?;
    let (scene, cache) = match &settings.scene {
        Some(dir) => (
            Scene::load(dir)?.0,
            HullCache::new(
                settings
                    .cache
                    .clone()
                    .unwrap_or_else(|| default_cache_dir(dir)),
            ),
        ),
        None => {
            let config = SynthConfig {
                seed: settings.seed,
                kind: SceneKind::Home,
                rooms: (settings.objects / 14).clamp(1, 64),
                objects: settings.objects,
                gaussians: 20_000,
                ..SynthConfig::default()
            };
            eprintln!("generating a {}-object home …", settings.objects);
            let scene = sage_synth::generate(&config)?;
            let dir = settings
                .cache
                .clone()
                .unwrap_or_else(|| std::env::temp_dir().join("sage3d-bench-physics-hulls"));
            (scene, HullCache::new(dir))
        }
    };
    let (bodies, report) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
    let mut world = World::new(&scene, bodies, &WorldOptions::default());
    let room = scene
        .floorplan
        .rooms
        .iter()
        .max_by(|x, y| x.profile.area().total_cmp(&y.profile.area()))
        .ok_or_else(|| Error::invalid("the scene has no rooms to start the agent in"))?;
    let uav = profile.kind == Locomotion::Uav;
    let z = if uav { 1.2 } else { 0.0 };
    let start = Pose::new(room.profile.centroid().extend(z), 0.0);
    let steps = settings.steps.max(1);
    let mut rates = Vec::new();
    let (mut touching, mut stuck, mut recovered) = (0usize, 0usize, 0usize);
    for run in 0..settings.repeat.max(1) {
        let mut agent = AgentBody::new(profile.clone(), start);
        agent.step(&mut world, &Command::Stop)?;
        // Every run replays the same seeded walk.
        let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
        let mut blocked = false;
        let t0 = Instant::now();
        for _ in 0..steps {
            let r = agent.step(&mut world, &wander(&mut rng, blocked, uav))?;
            blocked = r.intensity > 0.5;
            if run == 0 {
                touching += usize::from(!r.touched.is_empty());
                stuck += usize::from(r.stuck);
                recovered += usize::from(r.recovery.is_some());
            }
        }
        rates.push(steps as f64 / t0.elapsed().as_secs_f64());
    }
    rates.sort_by(f64::total_cmp);
    Ok(PhysicsReport {
        machine: machine::describe(),
        scene: scene.name.clone(),
        objects: scene.objects.len(),
        walls: scene.floorplan.walls.len(),
        parts: report.parts,
        bodies_s: report.seconds,
        decomposed: report.decomposed,
        cached: report.cached,
        cache_dir: report.cache_dir,
        agent: profile.name.to_string(),
        steps,
        steps_per_s: rates,
        touching,
        stuck,
        recovered,
    })
}
