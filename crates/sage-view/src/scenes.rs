//! The scenes the viewer has opened: each loaded once per choice of bodies, on first use, as
//! the environment loads it (its context: Gaussians, physics, path finder, semantic map), with
//! its renderer and its top-down map.

use glam::Vec2;
use sage_core::{Error, Result, ResultExt};
use sage_env::SceneContext;
use sage_eval::report::maps::{base_map, map_zoom};
use sage_physics::SplatBodies;
use sage_scene::LoadOptions;
use sage_splat::Device;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

/// One opened scene.
pub struct LoadedScene {
    /// The scene as the environment runs it.
    pub ctx: Arc<SceneContext>,
    /// The viewer's device: frames render through the context's one renderer there
    /// ([`SceneContext::renderer`]), opened when the scene loads, so requests render at once
    /// (on the CPU each borrows a renderer from the scene's pool).
    pub device: Device,
    /// The top-down map, PNG.
    pub map_png: Vec<u8>,
    /// What the page needs to draw over the map and label it ([`map_json`]).
    pub map: Value,
}

/// A scene's load, done once: the scene, or why it could not be loaded.
type Load = Arc<OnceLock<Result<Arc<LoadedScene>, String>>>;

/// The scene folders by name and those loaded so far.
pub struct SceneCache {
    dirs: BTreeMap<String, PathBuf>,
    device: Device,
    /// By scene and choice of bodies ([`SplatBodies::as_str`]): the bodies are built when the
    /// scene loads, and an environment refuses a scene loaded with another choice than its own.
    loaded: Mutex<BTreeMap<(String, &'static str), Load>>,
}

impl SceneCache {
    /// A cache over `dirs`, rendering on `device`.
    pub fn new(dirs: BTreeMap<String, PathBuf>, device: Device) -> SceneCache {
        SceneCache {
            dirs,
            device,
            loaded: Mutex::new(BTreeMap::new()),
        }
    }

    /// The scene names, sorted.
    pub fn names(&self) -> Vec<String> {
        self.dirs.keys().cloned().collect()
    }

    /// The folder of scene `name`.
    pub fn dir(&self, name: &str) -> Option<&std::path::Path> {
        self.dirs.get(name).map(PathBuf::as_path)
    }

    /// True when `name` is one of the scenes.
    pub fn contains(&self, name: &str) -> bool {
        self.dirs.contains_key(name)
    }

    /// Scene `name` with the bodies `bodies` chooses (an environment's
    /// [`sage_env::EnvConfig::splat_bodies`]), loaded on first use (concurrent first uses wait
    /// for one load); each choice is a load of its own.
    ///
    /// # Errors
    ///
    /// An unknown scene, or the load's error (kept: a scene that failed is not retried).
    pub fn get(&self, name: &str, bodies: SplatBodies) -> Result<Arc<LoadedScene>> {
        let dir = self
            .dirs
            .get(name)
            .ok_or_else(|| Error::invalid(format!("no scene '{name}' here")))?;
        let cell = self
            .loaded
            .lock()
            .map_err(|_| Error::invalid("scene cache poisoned"))?
            .entry((name.to_string(), bodies.as_str()))
            .or_default()
            .clone();
        cell.get_or_init(|| {
            load(dir, self.device, bodies)
                .within(format!("scene {name}"))
                .map(Arc::new)
                .map_err(|e| e.to_string())
        })
        .clone()
        .map_err(Error::invalid)
    }
}

/// Loads the scene in `dir` with the bodies `bodies` chooses, its renderer and map.
fn load(dir: &std::path::Path, device: Device, bodies: SplatBodies) -> Result<LoadedScene> {
    let ctx = Arc::new(SceneContext::load_with_bodies(
        dir,
        None,
        &LoadOptions::default(),
        bodies,
    )?);
    // Opened now, so that a device that cannot render fails the scene's load, not each frame.
    ctx.renderer(device)?;
    let (map_png, map) = map_json(&ctx)?;
    Ok(LoadedScene {
        ctx,
        device,
        map_png,
        map,
    })
}

/// The scene's top-down map as the report draws it (rooms, objects by category, walls, doors
/// by state) in PNG, and the data the page draws over it: the pixel frame (`origin` is the
/// world point at the bottom-left pixel corner, `scale` metres per pixel, y up) and every
/// object, room and door with its outline in world metres.
///
/// # Errors
///
/// The PNG cannot be encoded.
pub fn map_json(ctx: &SceneContext) -> Result<(Vec<u8>, Value)> {
    let grid = &ctx.pathfinder.grid;
    let map = &ctx.semantic;
    let zoom = map_zoom(grid);
    let (w, h) = (grid.width * zoom, grid.height * zoom);
    let canvas = base_map(map, grid, w, h);
    let png = sage_io::image::encode_rgb_png(w, h, &canvas.rgb)?;
    let outline = |p: &[Vec2]| p.iter().map(|v| [v.x, v.y]).collect::<Vec<_>>();
    let items: Vec<Value> = map
        .items
        .iter()
        .map(|i| {
            json!({
                "id": i.item_id,
                "category": i.category,
                "instance": i.instance_id,
                "ins_id": i.ins_id,
                "room": i.room,
                "state": i.state,
                "polygon": outline(&i.polygon),
            })
        })
        .collect();
    let rooms: Vec<Value> = map
        .rooms
        .iter()
        .map(|r| json!({"index": r.index, "type": r.room_type, "area_m2": r.area_m2, "polygon": outline(&r.polygon)}))
        .collect();
    let doors: Vec<Value> = map
        .doors
        .iter()
        .map(|d| json!({"state": d.state, "polygon": outline(&d.polygon)}))
        .collect();
    let meta = json!({
        "scene": map.scene,
        "width": w,
        "height": h,
        "origin": [grid.origin.x, grid.origin.y],
        "scale": grid.cell / zoom as f32,
        "items": items,
        "rooms": rooms,
        "doors": doors,
    });
    Ok((png, meta))
}
