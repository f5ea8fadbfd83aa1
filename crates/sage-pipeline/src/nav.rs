//! A scene's navigation map step: the semantic top-down map and the occupancy grid of an
//! agent's height slab, written beside the scene, and the published SAGE-3D builder's map of
//! the scene's own occupancy image (the file the published harness reads).

use sage_core::{Error, Result};
use sage_nav::{GridParams, NavGrid, PublishedMap, SemanticMap, published_map};
use sage_scene::Scene;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What [`map`] wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapReport {
    /// Scene name.
    pub scene: String,
    /// Objects on the map.
    pub items: usize,
    /// Walls.
    pub walls: usize,
    /// Doors.
    pub doors: usize,
    /// Rooms.
    pub rooms: usize,
    /// Grid width, cells.
    pub width: usize,
    /// Grid height, cells.
    pub height: usize,
    /// Cell size, metres.
    pub cell: f32,
    /// What the grid was made from (`meshes`, `occupancy`, …).
    pub source: String,
    /// Free cells.
    pub free: usize,
    /// Occupied cells.
    pub occupied: usize,
    /// Unknown cells.
    pub unknown: usize,
    /// Entries of the published map (`2D_Semantic_Map_{scene}_Complete.json`); `None` when the
    /// scene has no occupancy image to cut it from.
    pub published_entries: Option<usize>,
    /// The output folder.
    pub out: PathBuf,
}

/// Writes `semantic_map.json`, `semantic_map.png`, `occupancy.png` + `occupancy.json`, the
/// published map `2D_Semantic_Map_{scene}_Complete.json` (when the scene has an occupancy
/// image) and the run record of the scene in `scene_dir` into `out` (default `scene_dir/nav`).
///
/// # Errors
///
/// The scene cannot be loaded, its grid cannot be built, or a write error.
pub fn map(scene_dir: &Path, out: Option<&Path>, grid_params: &GridParams) -> Result<MapReport> {
    let (scene, _) = Scene::load(scene_dir)?;
    let out = out.map_or_else(|| scene_dir.join("nav"), Path::to_path_buf);
    let (grid, source) = NavGrid::from_scene(&scene, grid_params)?;
    let map = SemanticMap::build(&scene);
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    map.save_json(&out.join("semantic_map.json"))?;
    map.draw(&grid, &[])
        .0
        .save_png(&out.join("semantic_map.png"))?;
    grid.to_occupancy((grid_params.slab_bottom, grid_params.agent_height))?
        .save(&out)?;
    let published = scene
        .occupancy
        .as_ref()
        .map(|occ| PublishedMap::build(&scene.objects, occ));
    if let Some(p) = &published {
        sage_io::files::write_json(
            &out.join(published_map::file_name(&scene.name)),
            &p.to_json(),
        )?;
    }
    let (free, occupied, unknown) = grid.counts();
    sage_io::run::write_run_record(
        &out,
        "nav map",
        None,
        serde_json::json!({
            "config": {
                "cell": grid_params.cell,
                "agent_height": grid_params.agent_height,
                "slab_bottom": grid_params.slab_bottom,
                "margin": grid_params.margin,
                "grid_source": source.as_str(),
            },
            "inputs": sage_io::scenes::input_hashes(scene_dir),
        }),
    )?;
    Ok(MapReport {
        scene: scene.name,
        items: map.items.len(),
        walls: map.walls.len(),
        doors: map.doors.len(),
        rooms: map.rooms.len(),
        width: grid.width,
        height: grid.height,
        cell: grid.cell,
        source: source.as_str().to_string(),
        free,
        occupied,
        unknown,
        published_entries: published.map(|p| p.entries.len()),
        out,
    })
}
