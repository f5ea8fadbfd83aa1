//! Scenes as Python objects: a loaded [`SceneContext`] (from a folder, or synthesised and
//! cached) and its path finder with Habitat's query names.

use crate::convert::{PyResultExt, arg_extractors, array, to_py};
use glam::Vec2;
use numpy::ndarray::Ix1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Result, ResultExt};
use sage_dataset::build::{SceneParams, scene_episodes};
use sage_env::SceneContext;
use sage_physics::SplatBodies;
use sage_scene::{LoadOptions, SplatLayout};
use sage_synth::{SceneKind, SynthConfig};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A scene with everything its episodes share: Gaussians, semantic map, collision bodies and
/// path finder, loaded once (`Scene.load` or `Scene.synth`).
#[pyclass(name = "Scene", module = "sage3d._sage3d", frozen)]
pub struct PyScene {
    /// The loaded context, shared with every environment over the scene.
    pub ctx: Arc<SceneContext>,
    /// The scene folder.
    pub dir: PathBuf,
}

/// Writes the synthetic scene of `config` under `cache` unless it is already there; returns its
/// folder. The folder appears whole or not at all (written beside it, then renamed), so
/// processes that synthesise the same scene at once do not see each other's half.
fn synth_folder(config: &SynthConfig, cache: &Path) -> Result<PathBuf> {
    let dir = cache.join(format!(
        "{}-r{}-o{}-g{}",
        config.scene_name(),
        config.rooms,
        config.objects,
        config.gaussians
    ));
    if dir.join("structure.json").is_file() {
        return Ok(dir);
    }
    std::fs::create_dir_all(cache).map_err(|e| Error::io(cache, e))?;
    let tmp = cache.join(format!(
        ".{}.tmp{}",
        dir.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        std::process::id()
    ));
    sage_pipeline::scene::synthesize(config, &tmp, SplatLayout::Compressed, &|_| {})?;
    if std::fs::rename(&tmp, &dir).is_err() {
        // Another process renamed its copy first; both are the same bytes.
        let _ = std::fs::remove_dir_all(&tmp);
        if !dir.join("structure.json").is_file() {
            return Err(
                Error::invalid("could not move the synthesised scene into place").in_file(&dir),
            );
        }
    }
    Ok(dir)
}

arg_extractors! {
    load_path: PathBuf = "Scene.load: path";
    load_cache: Option<PathBuf> = "Scene.load: cache";
    load_collision: Option<PathBuf> = "Scene.load: collision";
    load_splat_bodies: String = "Scene.load: splat_bodies";
    synth_cache: PathBuf = "Scene.synth: cache";
    synth_seed: u64 = "Scene.synth: seed";
    synth_kind: String = "Scene.synth: kind";
    synth_rooms: usize = "Scene.synth: rooms";
    synth_objects: usize = "Scene.synth: objects";
    synth_gaussians: usize = "Scene.synth: gaussians";
    episodes_count: usize = "Scene.episodes: count";
    episodes_seed: u64 = "Scene.episodes: seed";
}

#[pymethods]
impl PyScene {
    /// Loads a scene folder (InteriorGS layout) with its collision bodies (hulls cached in
    /// `cache`, by default beside the scene) and path finder. `collision` names a published
    /// collision file (SAGE-Bench `{scene}_collision.usd`) to use as the physics layer; by
    /// default one in the folder by that name is used when present. `splat_bodies` chooses
    /// which objects get bodies recovered from their Gaussians, as `sage3d physics build
    /// --splat-bodies`: `auto`, `always` or `never`.
    #[staticmethod]
    #[pyo3(
        signature = (path, cache=None, collision=None, splat_bodies="auto".to_string()),
        text_signature = "(path, cache=None, collision=None, splat_bodies='auto')"
    )]
    fn load(
        py: Python<'_>,
        #[pyo3(from_py_with = load_path)] path: PathBuf,
        #[pyo3(from_py_with = load_cache)] cache: Option<PathBuf>,
        #[pyo3(from_py_with = load_collision)] collision: Option<PathBuf>,
        #[pyo3(from_py_with = load_splat_bodies)] splat_bodies: String,
    ) -> PyResult<PyScene> {
        let options = LoadOptions { collision };
        let splat_bodies: SplatBodies = splat_bodies
            .parse()
            .map_err(|e: String| Error::invalid(format!("splat_bodies: {e}")))
            .py()?;
        let ctx = py
            .detach(|| SceneContext::load_with_bodies(&path, cache, &options, splat_bodies))
            .py()?;
        Ok(PyScene {
            ctx: Arc::new(ctx),
            dir: path,
        })
    }

    /// A synthetic scene (`sage_synth`) written once under `cache` (keyed by kind, seed
    /// and sizes) and loaded from there, so later calls and other processes reuse the folder and
    /// its collision hulls.
    #[staticmethod]
    #[pyo3(
        signature = (cache, seed=0, kind="home".to_string(), rooms=4, objects=40, gaussians=60_000),
        // PyO3 shows a default it cannot print as a Python literal (`"home".to_string()`) as
        // `...`: the signature `help()` and `inspect.signature` read is written out here.
        text_signature = "(cache, seed=0, kind='home', rooms=4, objects=40, gaussians=60000)"
    )]
    fn synth(
        py: Python<'_>,
        #[pyo3(from_py_with = synth_cache)] cache: PathBuf,
        #[pyo3(from_py_with = synth_seed)] seed: u64,
        #[pyo3(from_py_with = synth_kind)] kind: String,
        #[pyo3(from_py_with = synth_rooms)] rooms: usize,
        #[pyo3(from_py_with = synth_objects)] objects: usize,
        #[pyo3(from_py_with = synth_gaussians)] gaussians: usize,
    ) -> PyResult<PyScene> {
        let config = SynthConfig {
            seed,
            kind: kind.parse::<SceneKind>().within("kind").py()?,
            rooms,
            objects,
            gaussians,
            ..SynthConfig::default()
        };
        let (dir, ctx) = py
            .detach(|| {
                let dir = synth_folder(&config, &cache)?;
                let ctx = SceneContext::load(&dir, None)?;
                Ok::<_, Error>((dir, ctx))
            })
            .py()?;
        Ok(PyScene {
            ctx: Arc::new(ctx),
            dir,
        })
    }

    /// The choice of bodies recovered from Gaussians the scene was loaded with (`auto`,
    /// `always`, `never`).
    #[getter]
    fn splat_bodies(&self) -> String {
        self.ctx
            .splat_bodies
            .unwrap_or_default()
            .as_str()
            .to_string()
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> String {
        self.ctx.scene.name.clone()
    }

    /// The scene folder.
    #[getter]
    fn path(&self) -> PathBuf {
        self.dir.clone()
    }

    /// Number of objects (the asset count of the slices).
    #[getter]
    fn num_objects(&self) -> usize {
        self.ctx.scene.objects.len()
    }

    /// Number of Gaussians.
    #[getter]
    fn num_gaussians(&self) -> usize {
        self.ctx.scene.gaussians.len()
    }

    /// The scene's path finder (a fresh sampler seeded with 0).
    #[getter]
    fn pathfinder(&self) -> PyPathFinder {
        PyPathFinder {
            ctx: self.ctx.clone(),
            rng: Mutex::new(ChaCha8Rng::seed_from_u64(0)),
        }
    }

    /// Benchmark episodes of this scene made as `sage3d data build` makes them (planned
    /// trajectories, grammar instructions, Base-Action and no-goal episodes): `count`
    /// trajectories from `seed`. A list of episode dicts (the dataset's JSONL schema).
    #[pyo3(signature = (count=8, seed=0))]
    fn episodes<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = episodes_count)] count: usize,
        #[pyo3(from_py_with = episodes_seed)] seed: u64,
    ) -> PyResult<Bound<'py, PyAny>> {
        // Named here: the dataset's check speaks of its own setting (`per_scene`).
        let most = sage_nav::trajectory::MAX_TRAJECTORIES;
        if count > most {
            return Err(PyValueError::new_err(format!(
                "count: must be at most {most} trajectories, got {count}"
            )));
        }
        let params = SceneParams::new(count, seed);
        let (_, episodes) = py
            .detach(|| scene_episodes(&self.ctx.scene, &params, None))
            .py()?;
        to_py(py, &episodes)
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(name={:?}, objects={}, gaussians={}, path={:?})",
            self.ctx.scene.name,
            self.ctx.scene.objects.len(),
            self.ctx.scene.gaussians.len(),
            self.dir
        )
    }
}

/// The path finder of a scene (Habitat's names): shortest paths, geodesic distances,
/// navigability, snapping and seeded sampling on the clearance-aware navigable grid. Points are
/// `[x, y]` or `[x, y, z]` in the W frame (z ignored).
#[pyclass(name = "PathFinder", module = "sage3d._sage3d", frozen)]
pub struct PyPathFinder {
    ctx: Arc<SceneContext>,
    rng: Mutex<ChaCha8Rng>,
}

impl PyPathFinder {
    fn xy<'py>(py: Python<'py>, p: Vec2) -> PyResult<Bound<'py, PyAny>> {
        array(py, Ix1(2), vec![p.x, p.y])
    }
}

arg_extractors! {
    find_path_start: Vec2 = "PathFinder.find_path: start";
    find_path_goal: Vec2 = "PathFinder.find_path: goal";
    geodesic_a: Vec2 = "PathFinder.geodesic_distance: a";
    geodesic_b: Vec2 = "PathFinder.geodesic_distance: b";
    is_navigable_p: Vec2 = "PathFinder.is_navigable: p";
    snap_point_p: Vec2 = "PathFinder.snap_point: p";
    snap_point_max_distance: f32 = "PathFinder.snap_point: max_distance";
    seed_seed: u64 = "PathFinder.seed: seed";
    sample_island: Option<u32> = "PathFinder.sample_navigable_point: island";
    island_p: Vec2 = "PathFinder.island: p";
}

#[pymethods]
impl PyPathFinder {
    /// The cheapest path from `start` to `goal` (clearance-aware costs, line-of-sight
    /// shortcut) as an `(N, 2)` float32 array of waypoints, first the start, last the goal.
    /// Raises `ValueError` when an end is not navigable or the two are not connected.
    fn find_path<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = find_path_start)] start: Vec2,
        #[pyo3(from_py_with = find_path_goal)] goal: Vec2,
    ) -> PyResult<Bound<'py, PyAny>> {
        let path = py
            .detach(|| self.ctx.pathfinder.find_path(start, goal))
            .py()?;
        let n = path.waypoints.len();
        let flat = path.waypoints.iter().flat_map(|p| [p.x, p.y]).collect();
        array(py, numpy::ndarray::Ix2(n, 2), flat)
    }

    /// The geodesic distance between two points in metres; `inf` when either is not
    /// navigable or they are not connected (as Habitat).
    fn geodesic_distance(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = geodesic_a)] a: Vec2,
        #[pyo3(from_py_with = geodesic_b)] b: Vec2,
    ) -> f32 {
        py.detach(|| self.ctx.pathfinder.geodesic_distance(a, b))
            .unwrap_or(f32::INFINITY)
    }

    /// True when the point lies on the navigable grid.
    fn is_navigable(&self, #[pyo3(from_py_with = is_navigable_p)] p: Vec2) -> bool {
        self.ctx.pathfinder.is_navigable(p)
    }

    /// The navigable cell centre nearest to `p` within `max_distance` metres (`p` itself's
    /// cell when navigable), or `None`.
    #[pyo3(signature = (p, max_distance=0.5))]
    fn snap_point<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = snap_point_p)] p: Vec2,
        #[pyo3(from_py_with = snap_point_max_distance)] max_distance: f32,
    ) -> PyResult<Option<Bound<'py, PyAny>>> {
        if max_distance.is_nan() || max_distance < 0.0 {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "PathFinder.snap_point: max_distance: {max_distance} is not a distance (0 or \
                 more; inf for any)"
            )));
        }
        let q = self.ctx.pathfinder.snap_point(p, max_distance);
        q.map(|q| Self::xy(py, q)).transpose()
    }

    /// Reseeds the sampler of [`Self::sample_navigable_point`].
    fn seed(&self, #[pyo3(from_py_with = seed_seed)] seed: u64) -> PyResult<()> {
        *self.rng.lock().map_err(|_| poisoned())? = ChaCha8Rng::seed_from_u64(seed);
        Ok(())
    }

    /// A navigable cell centre drawn uniformly with the path finder's seeded sampler
    /// (`seed()`), from one island when given.
    #[pyo3(signature = (island=None))]
    fn sample_navigable_point<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = sample_island)] island: Option<u32>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mut rng = self.rng.lock().map_err(|_| poisoned())?;
        let p = self
            .ctx
            .pathfinder
            .sample_navigable_point(&mut *rng, island)
            .ok_or_else(|| {
                let islands = self.ctx.pathfinder.island_areas().len();
                pyo3::exceptions::PyValueError::new_err(match island {
                    Some(i) => format!(
                        "PathFinder.sample_navigable_point: island: {i} is not an island (this scene has {islands}: 0-{})",
                        islands.saturating_sub(1)
                    ),
                    None => "the scene has no navigable cell".to_string(),
                })
            })?;
        Self::xy(py, p)
    }

    /// The island (connected component) of a navigable point, or `None`.
    fn island(&self, #[pyo3(from_py_with = island_p)] p: Vec2) -> Option<u32> {
        self.ctx.pathfinder.island(p)
    }

    /// Area of each island in m², indexed by island id.
    fn island_areas(&self) -> Vec<f32> {
        self.ctx.pathfinder.island_areas()
    }

    /// Grid cell size in metres.
    #[getter]
    fn cell_size(&self) -> f32 {
        self.ctx.pathfinder.grid.cell
    }
}

fn poisoned() -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err("path finder sampler poisoned by an earlier panic")
}
