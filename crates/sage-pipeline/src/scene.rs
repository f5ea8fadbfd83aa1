//! Synthetic scene folders: generate one from a seed and write it with its run record.

use sage_core::{Error, Result};
use sage_scene::{Scene, SplatLayout};
use sage_synth::SynthConfig;
use std::path::Path;

/// The stages of [`synthesize`], as they start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Generating the scene in memory.
    Generating,
    /// Writing its files.
    Writing,
}

/// The command that writes synthetic scene folders, as their run record names it.
pub const SYNTH_COMMAND: &str = sage_scene::scene::writers::SYNTH;

/// [`synthesize_into`] without `force`: `out` must be new, empty or a synthesised scene's.
///
/// # Errors
///
/// As [`synthesize_into`].
pub fn synthesize(
    config: &SynthConfig,
    out: &Path,
    layout: SplatLayout,
    on_stage: &dyn Fn(Stage),
) -> Result<Scene> {
    synthesize_into(config, out, layout, false, on_stage)
}

/// Generates the scene of `config` and writes it to `out` in the InteriorGS layout with
/// Gaussians in `layout`: the run record marked unfinished before the first file, the full one
/// after the last ([`sage_io::run::mark_unfinished`]), so a run killed half-way leaves a folder
/// that loads as no scene and that its rerun redoes. `out` must be new, empty or a synthesised
/// scene's, finished or not (a rerun replaces its files);
/// with `force`, a folder of other files is written into, provided none of them would be
/// replaced ([`sage_io::run::claim_folder`]). `on_stage` is told each [`Stage`] as it starts.
///
/// # Errors
///
/// Bad settings, an output folder holding files the command did not write, or a write error.
pub fn synthesize_into(
    config: &SynthConfig,
    out: &Path,
    layout: SplatLayout,
    force: bool,
    on_stage: &dyn Fn(Stage),
) -> Result<Scene> {
    let mut names = sage_scene::scene::files::WRITTEN.to_vec();
    names.push(sage_io::RUN_RECORD);
    let _lock = sage_io::run::claim_folder(out, &[SYNTH_COMMAND], &names, force)?;
    on_stage(Stage::Generating);
    let scene = sage_synth::generate(config)?;
    on_stage(Stage::Writing);
    sage_io::run::mark_unfinished(out, SYNTH_COMMAND, Some(config.seed))?;
    remove_earlier_scene(out)?;
    scene.save(out, layout)?;
    let details = serde_json::json!({
        "config": {
            "kind": config.kind.as_str(),
            "rooms": config.rooms,
            "objects": config.objects,
            "gaussians": config.gaussians,
            "wall_height": config.wall_height,
            "cell": config.cell,
            "layout": layout.as_str(),
        },
        "inputs": [],
    });
    sage_io::run::write_run_record(out, SYNTH_COMMAND, Some(config.seed), details)?;
    Ok(scene)
}

/// Removes the Gaussian files and meshes an earlier `scene synth` left in `out`. The folder is
/// new, empty or that command's own ([`sage_io::run::claim_folder`]), so they are its; a rerun
/// with other settings writes one layout's Gaussian file and its own objects' meshes, and left
/// beside them, the other layout's file (which the loader reads first) or the meshes of objects
/// the new scene does not have would make a folder of two scenes.
fn remove_earlier_scene(out: &Path) -> Result<()> {
    use sage_scene::scene::files;
    for name in [files::COMPRESSED_PLY, files::STANDARD_PLY, files::MESHES] {
        let path = out.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        let removed = if meta.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        removed.map_err(|e| Error::io(&path, e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_scene::scene::files;

    /// The files of folder `dir` and its sub-folders, relative, sorted.
    fn listing(dir: &Path) -> Vec<String> {
        sage_io::files::read_tree(dir)
            .unwrap()
            .into_keys()
            .collect()
    }

    #[test]
    fn a_rerun_with_other_settings_leaves_no_file_of_the_earlier_scene() {
        let tmp = tempfile::tempdir().unwrap();
        let big = SynthConfig {
            seed: 3,
            rooms: 5,
            objects: 30,
            gaussians: 4000,
            ..SynthConfig::default()
        };
        let small = SynthConfig {
            seed: 9,
            rooms: 2,
            objects: 6,
            gaussians: 1500,
            ..SynthConfig::default()
        };
        let (rerun, fresh) = (tmp.path().join("rerun"), tmp.path().join("fresh"));
        synthesize(&big, &rerun, SplatLayout::Compressed, &|_| {}).unwrap();
        synthesize(&small, &rerun, SplatLayout::Standard, &|_| {}).unwrap();
        synthesize(&small, &fresh, SplatLayout::Standard, &|_| {}).unwrap();
        assert!(!rerun.join(files::COMPRESSED_PLY).exists());
        assert_eq!(listing(&rerun), listing(&fresh));
        let count = |dir: &Path| Scene::load(dir).unwrap().0.gaussians.len();
        assert_eq!(count(&rerun), count(&fresh));
    }
}
