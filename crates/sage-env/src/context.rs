//! What a scene contributes to every episode run in it, built once.

use sage_core::{Error, Polygon2, Result};
use sage_metrics::distance::LabelledBox;
use sage_nav::gnbench::GnBenchGrid;
use sage_nav::{CostParams, GridParams, PathFinder, PublishedMap, SemanticMap, TrajectoryParams};
use sage_physics::{
    Decomposer, HullCache, SceneBodies, SplatBodies, SplatBodyParams, World, WorldOptions,
    default_cache_dir, splat_bodies,
};
use sage_scene::{LoadOptions, Scene};
use sage_splat::{Backend, Device, RendererPool};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

/// A loaded scene with its semantic map, collision bodies and path finder.
///
/// Immutable once built (but for what it builds on first use and keeps: path finders for wide
/// agents, the scene's upload to the GPU or its pool of CPU renderers): share it (`Arc`)
/// between the environments of all worker threads. What changes during an episode (the
/// physics world with its movable bodies) lives in each [`crate::Env`], which copies its
/// world from the context's pristine one.
pub struct SceneContext {
    /// The scene.
    pub scene: Scene,
    /// The semantic map (item ids and footprints of goal objects).
    pub semantic: SemanticMap,
    /// The boxes of the published SAGE-3D builder's map of the scene, among which metric mode
    /// `sage-official` picks its goal box; `None` when the scene has no occupancy image to cut
    /// the map from.
    pub published_boxes: Option<Vec<LabelledBox>>,
    /// How many objects' bodies came from each source (`published`, `mesh`, `gaussians`,
    /// `box`): the provenance run records keep, so that numbers made with different physics
    /// are not compared unknowingly.
    pub body_sources: BTreeMap<String, usize>,
    /// The choice of bodies recovered from Gaussians the context was loaded with
    /// ([`SceneContext::load_with_bodies`]); `None` for one assembled from bodies its caller
    /// built ([`SceneContext::new`]). An environment whose configuration asks for another
    /// choice is refused ([`crate::Env::new`]) rather than run on bodies it did not ask for.
    pub splat_bodies: Option<SplatBodies>,
    /// The physics world at rest, built once; every episode starts from a copy.
    world: World,
    /// The navigable grid for geodesic distances (every agent profile is scored on it).
    pub pathfinder: Arc<PathFinder>,
    /// Path finders over the same grid for agents wider than its planning radius, built on
    /// first use, by radius in millimetres.
    planners: Mutex<BTreeMap<u32, Arc<PathFinder>>>,
    /// GN-Bench's inflated occupancy grids (metric mode `gnbench`), built on first use;
    /// `None` inside when the scene has no occupancy image.
    gnbench: OnceLock<Option<GnBenchGrid>>,
    /// The scene's renderers by the device they were asked for (`gpu` and `auto` may choose
    /// different adapters), opened by the first environment that renders there: the
    /// Gaussians resident on a GPU, or the CPU's pool of renderers.
    renderers: Mutex<Vec<(Device, Backend)>>,
}

impl SceneContext {
    /// Assembles a context from a scene and its bodies (built with the caller's decomposer and
    /// hull cache), planning on a grid of `grid` with `cost`.
    ///
    /// # Errors
    ///
    /// No navigable space in the scene, or bad grid or cost parameters.
    pub fn new(
        scene: Scene,
        bodies: SceneBodies,
        grid: &GridParams,
        cost: CostParams,
    ) -> Result<SceneContext> {
        let (pathfinder, _) = PathFinder::from_scene(&scene, grid, cost)?;
        let semantic = SemanticMap::build(&scene);
        let published_boxes = scene.occupancy.as_ref().map(|occ| {
            PublishedMap::build(&scene.objects, occ)
                .entries
                .into_iter()
                .map(|x| LabelledBox {
                    item_id: x.item_id,
                    label: x.label,
                    min: x.min,
                    max: x.max,
                })
                .collect()
        });
        let body_sources = bodies
            .object_sources(&scene)
            .into_iter()
            .map(|(k, n)| (k.as_str().to_string(), n))
            .collect();
        let world = World::new(&scene, bodies, &WorldOptions::default());
        Ok(SceneContext {
            body_sources,
            splat_bodies: None,
            scene,
            semantic,
            published_boxes,
            world,
            pathfinder: Arc::new(pathfinder),
            planners: Mutex::new(BTreeMap::new()),
            gnbench: OnceLock::new(),
            renderers: Mutex::new(Vec::new()),
        })
    }

    /// GN-Bench's grids of the scene's occupancy image (its distance to goal, metric mode
    /// `gnbench`), built on the first call and kept; `None` without an occupancy image.
    pub fn gnbench_grid(&self) -> Option<&GnBenchGrid> {
        self.gnbench
            .get_or_init(|| {
                self.scene
                    .occupancy
                    .as_ref()
                    .map(GnBenchGrid::from_occupancy)
            })
            .as_ref()
    }

    /// A renderer of the scene's Gaussians on `device`: every call hands out a handle on the
    /// first call's ([`Backend::shared_clone`]). On a GPU that is one upload of the scene
    /// however many environments render it; on the CPU one pool of renderers over one index,
    /// holding as many frame buffers as renders ran at once, not a set per environment.
    /// `auto` without a usable hardware GPU gives a CPU renderer that says why in
    /// [`Backend::describe`].
    ///
    /// # Errors
    ///
    /// A scene without Gaussians, `gpu` without a usable adapter (or in a build without the
    /// GPU renderer), or a scene too large for the adapter.
    pub fn renderer(&self, device: Device) -> Result<Backend> {
        // Held while opening, so that environments created at once upload the scene once.
        let mut opened = self.opened();
        if let Some((_, backend)) = opened.iter().find(|(d, _)| *d == device) {
            return Ok(backend.shared_clone());
        }
        // A scene loads without its Gaussian file (physics and paths need none), but its
        // views would be black: an observation of nothing is an error, not an image.
        if self.scene.gaussians.is_empty() {
            return Err(Error::invalid(format!(
                "scene {} has no Gaussians to render: its folder has no {} (nor {}), or the \
                 file holds none",
                self.scene.name,
                sage_scene::scene::files::COMPRESSED_PLY,
                sage_scene::scene::files::GAUSSIANS[1..].join(", ")
            )));
        }
        let backend = Backend::open(device, &self.scene.gaussians)
            .map_err(|e| e.within(format!("device {device}")))?;
        opened.push((device, backend.shared_clone()));
        Ok(backend)
    }

    /// The path finder an agent of `radius` metres plans its own way with: the scene's where
    /// `radius` is within its planning radius, else one over the same grid whose navigable
    /// cells keep `radius` from obstacles (so a wider robot is not routed through gaps it
    /// touches), built once per radius and kept.
    ///
    /// # Errors
    ///
    /// No cell of the scene is navigable for an agent that wide.
    pub fn planner(&self, radius: f32) -> Result<Arc<PathFinder>> {
        if radius <= self.pathfinder.params.robot_radius {
            return Ok(self.pathfinder.clone());
        }
        let key = (radius * 1000.0).round() as u32;
        let mut planners = self.planners.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(pf) = planners.get(&key) {
            return Ok(pf.clone());
        }
        let params = CostParams {
            robot_radius: key as f32 / 1000.0,
            ..self.pathfinder.params.clone()
        };
        let pf = Arc::new(
            PathFinder::new(self.pathfinder.grid.clone(), &self.scene.floorplan, params)
                .map_err(|e| e.within(format!("planning for a {radius} m agent")))?,
        );
        planners.insert(key, pf.clone());
        Ok(pf)
    }

    /// Loads a scene folder with its collision bodies (hulls cached in `cache`, by default
    /// beside the scene) and the path finder of the default trajectory settings: the context
    /// every front end (evaluator, `env run`, Python) opens a scene with.
    ///
    /// # Errors
    ///
    /// The scene, its bodies or its navigation grid cannot be built.
    ///
    /// Objects with neither a published body nor a mesh get bodies recovered from their
    /// Gaussians ([`SplatBodies::Auto`]).
    pub fn load(dir: &Path, cache: Option<PathBuf>) -> Result<SceneContext> {
        Self::load_with(dir, cache, &LoadOptions::default())
    }

    /// [`SceneContext::load`] with the scene loaded with `options` (a published collision file
    /// given by path: [`LoadOptions::collision`]).
    ///
    /// # Errors
    ///
    /// The scene, its collision file, its bodies or its navigation grid cannot be built.
    pub fn load_with(
        dir: &Path,
        cache: Option<PathBuf>,
        options: &LoadOptions,
    ) -> Result<SceneContext> {
        Self::load_with_bodies(dir, cache, options, SplatBodies::Auto)
    }

    /// [`SceneContext::load_with`] with `splat_bodies` choosing which objects get bodies
    /// recovered from their Gaussians, as `sage3d physics build --splat-bodies` does (an
    /// environment's [`crate::EnvConfig::splat_bodies`]).
    ///
    /// # Errors
    ///
    /// The scene, its collision file, its bodies or its navigation grid cannot be built.
    pub fn load_with_bodies(
        dir: &Path,
        cache: Option<PathBuf>,
        options: &LoadOptions,
        splat_bodies: SplatBodies,
    ) -> Result<SceneContext> {
        let (mut scene, _) = Scene::load_with(dir, options)?;
        splat_bodies::attach(&mut scene, splat_bodies, &SplatBodyParams::default())?;
        let cache = HullCache::new(cache.unwrap_or_else(|| default_cache_dir(dir)));
        let (bodies, _) = SceneBodies::build(&scene, &Decomposer::default(), &cache)?;
        let params = TrajectoryParams::default();
        let mut ctx = SceneContext::new(scene, bodies, &params.grid, params.cost)?;
        ctx.splat_bodies = Some(splat_bodies);
        Ok(ctx)
    }

    /// How many uploads of the scene are resident on GPUs: one per device asked for (`gpu`,
    /// `auto` where it took a GPU), however many environments render from it.
    pub fn uploads(&self) -> usize {
        self.opened().iter().filter(|(_, b)| b.is_gpu()).count()
    }

    /// How many CPU renderers (sets of frame buffers) the scene's environments hold between
    /// them: the most that rendered at once, however many environments there are.
    pub fn cpu_renderers(&self) -> usize {
        self.opened()
            .iter()
            .filter_map(|(_, b)| b.as_cpu())
            .map(RendererPool::renderers)
            .sum()
    }

    fn opened(&self) -> std::sync::MutexGuard<'_, Vec<(Device, Backend)>> {
        self.renderers.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A fresh physics world (movable bodies at their scene poses): a copy of the one built
    /// with the context.
    pub fn world(&self) -> World {
        self.world.clone()
    }

    /// The footprint of the object with item id `item`.
    ///
    /// # Errors
    ///
    /// An `invalid` error when the scene has no such object.
    pub fn footprint(&self, item: &str) -> Result<Polygon2> {
        self.semantic
            .item(item)
            .map(|i| i.footprint_polygon())
            .ok_or_else(|| {
                Error::invalid(format!(
                    "goal object '{item}' is not an object of scene {}",
                    self.scene.name
                ))
            })
    }
}
