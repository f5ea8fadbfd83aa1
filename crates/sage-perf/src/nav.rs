//! `sage3d bench nav`: grid and EDT once, then many trajectories planned in parallel.

use crate::machine;
use sage_core::Result;
use sage_nav::sampling::Endpoints;
use sage_nav::trajectory::{self, Prepared, TrajectoryParams};
use sage_nav::{NavGrid, PathFinder, SemanticMap};
use sage_scene::Scene;
use sage_synth::{SceneKind, SynthConfig};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// What `bench nav` plans.
#[derive(Clone, Debug, PartialEq)]
pub struct NavSettings {
    /// Trajectories to plan.
    pub count: usize,
    /// Seed of the scene and of the sampling.
    pub seed: u64,
    /// Rooms of the generated home (about 15 m² each; 27 make about 20 × 20 m).
    pub rooms: usize,
    /// Scene folder to use instead of a generated home.
    pub scene: Option<PathBuf>,
}

impl Default for NavSettings {
    fn default() -> Self {
        Self {
            count: 4000,
            seed: 1,
            rooms: 27,
            scene: None,
        }
    }
}

/// What `bench nav` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NavReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Scene name.
    pub scene: String,
    /// Rooms in the scene.
    pub rooms: usize,
    /// Objects in the scene.
    pub objects: usize,
    /// Grid extent, metres (x, y).
    pub grid_extent: [f32; 2],
    /// Grid width, cells.
    pub grid_width: usize,
    /// Grid height, cells.
    pub grid_height: usize,
    /// Cell size, metres.
    pub cell: f32,
    /// Free, occupied and unknown cells.
    pub cells: (usize, usize, usize),
    /// Cells the robot can stand on.
    pub navigable: usize,
    /// Milliseconds to rasterise the grid (meshes, walls).
    pub grid_ms: f64,
    /// Milliseconds for the distance transform, costs and islands.
    pub edt_ms: f64,
    /// Milliseconds for the semantic map and the endpoints.
    pub endpoints_ms: f64,
    /// Endpoints in all.
    pub endpoints: usize,
    /// Room, object and area endpoints.
    pub endpoint_kinds: [usize; 3],
    /// Trajectories kept.
    pub trajectories: usize,
    /// Wall-clock seconds to plan them.
    pub wall_s: f64,
    /// Worker threads.
    pub threads: usize,
    /// Candidates drawn.
    pub candidates: usize,
    /// Mean trajectory length, metres.
    pub mean_length: f32,
    /// Trajectories per length bin.
    pub by_length: BTreeMap<String, usize>,
    /// CPU milliseconds per kept trajectory and stage, summed over threads.
    pub per_trajectory_ms: StageMs,
    /// Candidates planned (A* run).
    pub planned: usize,
}

/// CPU milliseconds per kept trajectory of each planning stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageMs {
    /// Drawing pairs.
    pub sampling: f64,
    /// A* with the cost function.
    pub astar: f64,
    /// Line-of-sight shortcutting.
    pub shortcut: f64,
    /// Resampling and headings.
    pub resample: f64,
    /// The geodesic distance.
    pub geodesic: f64,
}

impl fmt::Display for NavReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (free, occupied, unknown) = self.cells;
        let per = &self.per_trajectory_ms;
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            {} ({} rooms, {} objects), grid {:.1} x {:.1} m = {} x {} cells at {} m ({free} free, {occupied} occupied, {unknown} unknown; {} navigable)",
            self.scene,
            self.rooms,
            self.objects,
            self.grid_extent[0],
            self.grid_extent[1],
            self.grid_width,
            self.grid_height,
            self.cell,
            self.navigable
        )?;
        writeln!(
            f,
            "once per scene   grid {:.0} ms (rasterise meshes, walls) + EDT/costs/islands {:.0} ms + map/endpoints {:.0} ms ({} endpoints: {:?} rooms/objects/areas)",
            self.grid_ms, self.edt_ms, self.endpoints_ms, self.endpoints, self.endpoint_kinds
        )?;
        writeln!(
            f,
            "trajectories     {} in {:.2} s = {:.0} trajectories/s on {} threads ({} candidates, mean length {:.1} m, {:?})",
            self.trajectories,
            self.wall_s,
            self.trajectories as f64 / self.wall_s,
            self.threads,
            self.candidates,
            self.mean_length,
            self.by_length
        )?;
        writeln!(
            f,
            "per trajectory   CPU ms: sampling {:.3} + A* {:.3} + shortcut {:.3} + resample {:.3} + geodesic {:.3} (summed over threads; {} planned for {} kept)",
            per.sampling,
            per.astar,
            per.shortcut,
            per.resample,
            per.geodesic,
            self.planned,
            self.trajectories
        )
    }
}

/// Runs `bench nav` (SPEC §12): the grid, path finder and endpoints of the scene once, a short
/// warm-up run that sizes every thread's search buffers, then `count` trajectories.
///
/// # Errors
///
/// The scene cannot be loaded or generated, or has nowhere to plan.
pub fn run(settings: &NavSettings) -> Result<NavReport> {
    let scene = match &settings.scene {
        Some(dir) => Scene::load(dir)?.0,
        None => {
            eprintln!("generating a {}-room home …", settings.rooms);
            sage_synth::generate(&SynthConfig {
                seed: settings.seed,
                kind: SceneKind::Home,
                rooms: settings.rooms,
                objects: settings.rooms * 12,
                gaussians: 1000,
                ..SynthConfig::default()
            })?
        }
    };
    let params = TrajectoryParams {
        count: settings.count,
        seed: settings.seed,
        ..TrajectoryParams::default()
    };
    let t = Instant::now();
    let (grid, source) = NavGrid::from_scene(&scene, &params.grid)?;
    let grid_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let finder = PathFinder::new(grid, &scene.floorplan, params.cost.clone())?;
    let edt_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let map = SemanticMap::build(&scene);
    let endpoints = Endpoints::collect(&map, &finder, &params.sampling);
    let endpoints_ms = t.elapsed().as_secs_f64() * 1e3;
    let prep = Prepared {
        finder,
        source,
        map,
        endpoints,
    };
    let warm = TrajectoryParams {
        count: 64,
        ..params.clone()
    };
    trajectory::generate(&scene.name, &prep, &warm)?;
    let t = Instant::now();
    let (set, times) = trajectory::generate(&scene.name, &prep, &params)?;
    let wall_s = t.elapsed().as_secs_f64();
    let g = &prep.finder.grid;
    let size = g.size();
    let n = set.trajectories.len().max(1) as f64;
    let per = |d: Duration| d.as_secs_f64() * 1e3 / n;
    Ok(NavReport {
        machine: machine::describe(),
        scene: scene.name.clone(),
        rooms: scene.floorplan.rooms.len(),
        objects: scene.objects.len(),
        grid_extent: [size.x, size.y],
        grid_width: g.width,
        grid_height: g.height,
        cell: g.cell,
        cells: g.counts(),
        navigable: prep.finder.navigable_cells().len(),
        grid_ms,
        edt_ms,
        endpoints_ms,
        endpoints: prep.endpoints.list.len(),
        endpoint_kinds: prep.endpoints.counts(),
        trajectories: set.trajectories.len(),
        wall_s,
        threads: rayon::current_num_threads(),
        candidates: set.report.candidates,
        mean_length: set.report.mean_length,
        by_length: set.report.by_length,
        per_trajectory_ms: StageMs {
            sampling: per(times.sampling),
            astar: per(times.astar),
            shortcut: per(times.shortcut),
            resample: per(times.resample),
            geodesic: per(times.geodesic),
        },
        planned: times.planned,
    })
}
