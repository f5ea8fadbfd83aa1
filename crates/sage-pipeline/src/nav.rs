//! A scene's navigation map step: the semantic top-down map and the occupancy grid of an
//! agent's height slab, written beside the scene, and the published SAGE-3D builder's map of
//! the scene's own occupancy image (the file the published harness reads); and the
//! trajectories of a scene or a folder of scenes.

use rayon::prelude::*;
use sage_core::Result;
use sage_io::runner::Status;
use sage_nav::trajectory::{self, SceneOutcome, TrajectoryParams};
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

/// The command that writes a scene's maps, as its run record names it.
pub const MAP_COMMAND: &str = "nav map";

/// The command that writes trajectories, as its run record names it.
pub const TRAJECTORIES_COMMAND: &str = "nav trajectories";

/// The commands whose outputs share a scene's `nav` folder (the default of both): each
/// accepts a folder the other wrote as its own.
const NAV_COMMANDS: [&str; 2] = [MAP_COMMAND, TRAJECTORIES_COMMAND];

/// [`map_into`] without `force`.
///
/// # Errors
///
/// As [`map_into`].
pub fn map(scene_dir: &Path, out: Option<&Path>, grid_params: &GridParams) -> Result<MapReport> {
    map_into(scene_dir, out, grid_params, false)
}

/// Writes `semantic_map.json`, `semantic_map.png`, `occupancy.png` + `occupancy.json`, the
/// published map `2D_Semantic_Map_{scene}_Complete.json` (when the scene has an occupancy
/// image) and the run record of the scene in `scene_dir` into `out` (default `scene_dir/nav`),
/// all computed before the first is written; the run record is marked unfinished before the
/// first map and written in full after the last ([`sage_io::run::mark_unfinished`]), and a
/// write that fails removes the maps written before it. `out` must be new, empty or a `nav`
/// folder, finished or not (a rerun replaces its maps); with `force`, a folder of other files
/// is written into, provided none of them would be replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// The scene cannot be loaded, an output folder holding files the command did not write, its
/// grid cannot be built, or a write error.
pub fn map_into(
    scene_dir: &Path,
    out: Option<&Path>,
    grid_params: &GridParams,
    force: bool,
) -> Result<MapReport> {
    let (scene, _) = Scene::load(scene_dir)?;
    let out = out.map_or_else(|| scene_dir.join("nav"), Path::to_path_buf);
    let published_name = published_map::file_name(&scene.name);
    let names = [
        "semantic_map.json",
        "semantic_map.png",
        "occupancy.png",
        "occupancy.json",
        published_name.as_str(),
        sage_io::RUN_RECORD,
    ];
    let _lock = sage_io::run::claim_folder(&out, &NAV_COMMANDS, &names, force)?;
    // Everything is computed before the first file is written, so that a run that fails or
    // is interrupted while it works leaves no map behind, and the writing that follows takes
    // moments; one killed while it writes leaves the record marked unfinished, which its rerun
    // takes as its own.
    let (grid, source) = NavGrid::from_scene(&scene, grid_params)?;
    let map = SemanticMap::build(&scene);
    let picture = map.draw(&grid, &[]).0;
    let occupancy = grid.to_occupancy((grid_params.slab_bottom, grid_params.agent_height))?;
    let published = scene
        .occupancy
        .as_ref()
        .map(|occ| PublishedMap::build(&scene.objects, occ));
    sage_io::run::mark_unfinished(&out, MAP_COMMAND, None)?;
    let written = (|| {
        map.save_json(&out.join("semantic_map.json"))?;
        picture.save_png(&out.join("semantic_map.png"))?;
        occupancy.save(&out)?;
        if let Some(p) = &published {
            sage_io::files::write_json(&out.join(&published_name), &p.to_json())?;
        }
        Ok::<(), sage_core::Error>(())
    })();
    if let Err(e) = written {
        // A failed write leaves no part of a map beside the others (the claim made sure that
        // these names are this command's to replace).
        for name in names.iter().filter(|n| **n != sage_io::RUN_RECORD) {
            let _ = std::fs::remove_file(out.join(name));
        }
        return Err(e);
    }
    let (free, occupied, unknown) = grid.counts();
    sage_io::run::write_run_record(
        &out,
        MAP_COMMAND,
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

/// What [`trajectories`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrajectoriesReport {
    /// The output folder.
    pub out: PathBuf,
    /// Per scene: made, resumed or skipped.
    pub outcomes: Vec<SceneOutcome>,
}

/// Generates (or resumes) the trajectories of the scene folder, or of every scene folder
/// inside the folder, `scenes` into `out` (default: `scenes/nav` for a scene,
/// `scenes/../nav_trajectories` for a folder of scenes: one sub-folder per scene there),
/// parallel over scenes, then the run record; `on_scene(outcome, scenes)` is called as each
/// of the `scenes` folders is done. `out` must be new, empty or a `nav` folder; with `force`, a
/// folder of other files is written into, provided none of them would be replaced
/// ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// No scenes, a scene folder whose name is not a plain name
/// ([`trajectory::check_scene_names`]), an output folder holding files the command did not
/// write, or a write error. A scene that fails is skipped with its reason (in the outcomes).
pub fn trajectories(
    scenes: &Path,
    out: Option<&Path>,
    params: &TrajectoryParams,
    force: bool,
    on_scene: &(dyn Fn(&SceneOutcome, usize) + Sync),
) -> Result<TrajectoriesReport> {
    let dirs = sage_io::scenes::scene_dirs(scenes)?;
    // Before the folder is claimed: a refused run leaves nothing behind.
    trajectory::check_scene_names(&dirs)?;
    let single = dirs.len() == 1 && dirs[0] == scenes;
    let out = out.map_or_else(
        || {
            if single {
                scenes.join("nav")
            } else {
                scenes.with_file_name("nav_trajectories")
            }
        },
        Path::to_path_buf,
    );
    let target_name = |dir: &Path| {
        dir.file_name()
            .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned())
    };
    let mut names: Vec<String> = if single {
        vec![
            trajectory::TRAJECTORIES_FILE.into(),
            trajectory::TRAJECTORIES_PNG.into(),
        ]
    } else {
        dirs.iter().map(|d| target_name(d)).collect()
    };
    names.push(sage_io::RUN_RECORD.into());
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let _lock =
        sage_io::run::claim_folder(&out, &[TRAJECTORIES_COMMAND, MAP_COMMAND], &names, force)?;
    let record = |outcomes: &[SceneOutcome]| {
        sage_io::run::write_run_record(
            &out,
            TRAJECTORIES_COMMAND,
            Some(params.seed),
            serde_json::json!({ "config": params, "scenes": outcomes }),
        )
    };
    // Recorded before the scenes too, so that an interrupted run is recognised as this
    // command's when it is rerun to resume.
    record(&[])?;
    let outcomes: Vec<SceneOutcome> = dirs
        .par_iter()
        .map(|dir| {
            let target = if single {
                out.clone()
            } else {
                out.join(target_name(dir))
            };
            let outcome = trajectory::run_scene(dir, &target, params);
            on_scene(&outcome, dirs.len());
            outcome
        })
        .collect();
    // The record says what the folder holds, not what this run did: a scene another run
    // completed is `done` there, so a resumed or repeated run records the same bytes as one
    // that ran through (the outcomes returned still tell the resumed ones apart). A scene
    // resumes only while its input files hash as its file records, so the hashes listed are
    // those its trajectories were made from.
    let held: Vec<SceneOutcome> = outcomes
        .iter()
        .cloned()
        .map(|mut o| {
            if o.status == Status::Resumed {
                o.status = Status::Done;
            }
            o
        })
        .collect();
    record(&held)?;
    Ok(TrajectoriesReport { out, outcomes })
}
