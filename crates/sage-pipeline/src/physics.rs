//! A scene's collision bodies step: decompose the object meshes not yet in the hull cache and
//! assemble the bodies.

use sage_core::Result;
use sage_physics::{BuildReport, Decomposer, HullCache, SceneBodies};
use sage_scene::Scene;
use std::path::Path;

/// Loads the scene in `scene_dir` and builds its collision bodies with `decomposer`, hulls from
/// and into `cache`; `on_object(objects)` is called as each of the scene's `objects` is done.
///
/// # Errors
///
/// The scene cannot be loaded, or a decomposition or cache write fails.
pub fn bodies(
    scene_dir: &Path,
    decomposer: &Decomposer,
    cache: &HullCache,
    on_object: &(dyn Fn(usize) + Sync),
) -> Result<(Scene, SceneBodies, BuildReport)> {
    let (scene, _) = Scene::load(scene_dir)?;
    let objects = scene.objects.len();
    let (bodies, report) =
        SceneBodies::build_with_progress(&scene, decomposer, cache, &|| on_object(objects))?;
    Ok((scene, bodies, report))
}
