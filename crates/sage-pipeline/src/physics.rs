//! A scene's collision bodies step: decompose the object meshes not yet in the hull cache and
//! assemble the bodies; the hull cache's work list; the hybrid USDA scene built on them.

use sage_core::{Error, Result};
use sage_io::files::write_json;
use sage_physics::usd::{SplatAsset, write_usda};
use sage_physics::{
    BuildReport, Decomposer, HullCache, SceneBodies, SplatBodies, SplatBodyParams, WorkList,
    splat_bodies,
};
use sage_scene::scene::files;
use sage_scene::{LoadOptions, LoadReport, Scene};
use std::path::{Component, Path, PathBuf};

/// How a scene is loaded for its bodies: the published collision file given, if any, and which
/// objects get bodies recovered from their Gaussians.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BodyOptions {
    /// How the scene folder is loaded ([`LoadOptions::collision`]).
    pub load: LoadOptions,
    /// Which objects get bodies recovered from their Gaussians.
    pub splat_bodies: SplatBodies,
}

impl BodyOptions {
    /// Loads the scene in `scene_dir` with these options and gives the objects they select
    /// bodies recovered from their Gaussians.
    ///
    /// # Errors
    ///
    /// The scene or its collision file cannot be loaded.
    pub fn load(&self, scene_dir: &Path) -> Result<(Scene, LoadReport)> {
        let (mut scene, loaded) = Scene::load_with(scene_dir, &self.load)?;
        splat_bodies::attach(&mut scene, self.splat_bodies, &SplatBodyParams::default())?;
        Ok((scene, loaded))
    }

    /// The files loading the scene in `scene_dir` with these options reads: what an output of
    /// a command on the scene may never replace.
    pub fn inputs(&self, scene_dir: &Path) -> Vec<PathBuf> {
        let mut inputs = sage_scene::scene_files(scene_dir);
        inputs.extend(self.load.collision.clone());
        inputs
    }

    /// Checks that the output file `out` of a command reading the scene in `scene_dir` may be
    /// written: never one of the scene's files ([`BodyOptions::inputs`]), and an existing file
    /// only with `force` ([`sage_io::run::claim_output_file`]).
    fn claim_output(&self, scene_dir: &Path, out: &Path, force: bool) -> Result<()> {
        let inputs = self.inputs(scene_dir);
        sage_io::run::claim_output_file(out, &inputs, "a file of the input scene", force)
    }
}

/// Loads the scene in `scene_dir` with `options` and builds its collision bodies with
/// `decomposer`, hulls from and into `cache`; `on_object(objects)` is called as each of the
/// scene's `objects` is done.
///
/// # Errors
///
/// The scene or its collision file cannot be loaded, or a decomposition or cache write fails.
pub fn bodies(
    scene_dir: &Path,
    options: &BodyOptions,
    decomposer: &Decomposer,
    cache: &HullCache,
    on_object: &(dyn Fn(usize) + Sync),
) -> Result<(Scene, SceneBodies, BuildReport)> {
    let (scene, loaded) = options.load(scene_dir)?;
    let objects = scene.objects.len();
    let (bodies, mut report) =
        SceneBodies::build_with_progress(&scene, decomposer, cache, &|| on_object(objects))?;
    report.collision = loaded.collision;
    Ok((scene, bodies, report))
}

/// Writes to `out` the work list of the scene in `scene_dir` (loaded with `options`): its
/// object meshes that `decomposer` has not yet decomposed into `cache`, or whose entry there is
/// damaged (what an offline
/// decomposer such as `python/tools/coacd_cache.py` is to do). An existing `out` is replaced only with `force`,
/// and never when it is one of the scene's files.
///
/// # Errors
///
/// An existing `out` without `force`, `out` being a file of the scene, a scene that cannot be loaded, or a write error.
pub fn work_list(
    scene_dir: &Path,
    options: &BodyOptions,
    out: &Path,
    decomposer: &Decomposer,
    cache: &HullCache,
    force: bool,
) -> Result<WorkList> {
    options.claim_output(scene_dir, out, force)?;
    let (scene, _) = options.load(scene_dir)?;
    let list = WorkList::of(&scene, decomposer, cache)?;
    write_json(out, &list)?;
    Ok(list)
}

/// What [`export_usd`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdReport {
    /// The scene's name.
    pub scene: String,
    /// Rigid bodies written (objects, wall pieces and slabs).
    pub bodies: usize,
    /// How the bodies were built: collision parts, meshes decomposed and taken from the cache.
    pub build: BuildReport,
    /// The Gaussians as the USDA references them, when the scene folder holds a PLY of them.
    pub splats: Option<SplatAsset>,
}

/// Writes the hybrid scene of `scene_dir` (loaded with `options`) as USDA to `out`: its
/// collision bodies (built as [`bodies`] does) with UsdPhysics schemas, and its Gaussians
/// referenced as a PLY asset by a path relative to `out`'s folder, so that the two can move together. An existing `out` is
/// replaced only with `force`, never when it is one of the scene's files (its `labels.json`
/// written over breaks the scene), and that is checked before the bodies are built.
///
/// # Errors
///
/// An existing `out` without `force`, `out` being a file of the scene, a scene that cannot be loaded, a decomposition that
/// fails, or a write error.
pub fn export_usd(
    scene_dir: &Path,
    options: &BodyOptions,
    out: &Path,
    decomposer: &Decomposer,
    cache: &HullCache,
    force: bool,
    on_object: &(dyn Fn(usize) + Sync),
) -> Result<UsdReport> {
    options.claim_output(scene_dir, out, force)?;
    let (scene, bodies, build) = bodies(scene_dir, options, decomposer, cache, on_object)?;
    let out_dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let splats = [files::COMPRESSED_PLY, files::STANDARD_PLY]
        .iter()
        .map(|f| scene_dir.join(f))
        .find(|p| p.is_file())
        .map(|p| SplatAsset {
            path: relative_path(&p, &out_dir),
            count: scene.gaussians.len(),
            sh_degree: scene.gaussians.sh_degree(),
        });
    write_usda(out, &scene.name, &bodies, splats.as_ref())?;
    Ok(UsdReport {
        scene: scene.name,
        bodies: bodies.bodies.len(),
        build,
        splats,
    })
}

/// `target` relative to the folder `base` (both made absolute), or `target` as given when no
/// relative path exists (another drive).
fn relative_path(target: &Path, base: &Path) -> String {
    let (Ok(t), Ok(b)) = (target.canonicalize(), base.canonicalize()) else {
        return target.display().to_string();
    };
    let tc: Vec<Component> = t.components().collect();
    let bc: Vec<Component> = b.components().collect();
    let common = tc.iter().zip(&bc).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return t.display().to_string();
    }
    let mut rel = PathBuf::new();
    for _ in common..bc.len() {
        rel.push("..");
    }
    for c in &tc[common..] {
        rel.push(c);
    }
    let s = rel.display().to_string();
    if s.starts_with("..") {
        s
    } else {
        format!("./{s}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_usda_references_the_scene_gaussians_and_is_replaced_only_with_force() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        let config = sage_synth::SynthConfig {
            seed: 2,
            rooms: 2,
            objects: 4,
            gaussians: 1000,
            ..sage_synth::SynthConfig::default()
        };
        crate::scene::synthesize(
            &config,
            &scene,
            sage_scene::SplatLayout::Compressed,
            &|_| {},
        )
        .unwrap();
        let decomposer = Decomposer::Vhacd {
            resolution: 16,
            concavity: 0.05,
            max_hulls: 4,
        };
        let cache = HullCache::new(dir.path().join("cache"));
        let out = dir.path().join("usd/scene.usda");
        let report = export_usd(
            &scene,
            &BodyOptions::default(),
            &out,
            &decomposer,
            &cache,
            false,
            &|_| {},
        )
        .unwrap();
        let splats = report.splats.expect("the scene has a PLY");
        assert_eq!(
            Path::new(&splats.path),
            Path::new("../scene/3dgs_compressed.ply")
        );
        assert_eq!(splats.count, 1000);
        assert!(report.bodies > 0 && report.build.parts > 0);
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(text.contains(&splats.path));
        let refused = export_usd(
            &scene,
            &BodyOptions::default(),
            &out,
            &decomposer,
            &cache,
            false,
            &|_| {},
        );
        assert!(refused.unwrap_err().to_string().contains("`force`"));
        let again = export_usd(
            &scene,
            &BodyOptions::default(),
            &out,
            &decomposer,
            &cache,
            true,
            &|_| {},
        )
        .unwrap();
        assert_eq!(again.build.decomposed, 0, "the hulls come from the cache");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), text);
        // The scene's own files are never outputs, force or not, however they are named; a new
        // file in the scene folder is.
        let mesh = std::fs::read_dir(scene.join("meshes"))
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        let dotted = scene.join("meshes/../structure.json");
        for file in [scene.join("labels.json"), dotted, mesh] {
            let before = std::fs::read(&file).unwrap();
            let refused = export_usd(
                &scene,
                &BodyOptions::default(),
                &file,
                &decomposer,
                &cache,
                true,
                &|_| {},
            )
            .unwrap_err()
            .to_string();
            assert!(
                refused.contains("the output is a file of the input scene"),
                "{refused}"
            );
            let refused = work_list(
                &scene,
                &BodyOptions::default(),
                &file,
                &decomposer,
                &cache,
                true,
            )
            .unwrap_err()
            .to_string();
            assert!(
                refused.contains("the output is a file of the input scene"),
                "{refused}"
            );
            assert_eq!(std::fs::read(&file).unwrap(), before, "{}", file.display());
        }
        let inside = scene.join("scene.usda");
        export_usd(
            &scene,
            &BodyOptions::default(),
            &inside,
            &decomposer,
            &cache,
            false,
            &|_| {},
        )
        .unwrap();
        assert!(inside.is_file());
    }

    #[test]
    fn asset_paths_are_relative_to_the_usda_folder() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        let usd = dir.path().join("out/usd");
        std::fs::create_dir_all(&scene).unwrap();
        std::fs::create_dir_all(&usd).unwrap();
        let ply = scene.join("3dgs_compressed.ply");
        std::fs::write(&ply, b"ply").unwrap();
        assert_eq!(
            relative_path(&ply, &usd),
            format!(
                "..{0}..{0}scene{0}3dgs_compressed.ply",
                std::path::MAIN_SEPARATOR
            )
        );
        assert_eq!(relative_path(&ply, &scene), "./3dgs_compressed.ply");
        // A file that does not exist cannot be made absolute: it is kept as given.
        let missing = scene.join("missing.ply");
        assert_eq!(relative_path(&missing, &usd), missing.display().to_string());
    }
}
