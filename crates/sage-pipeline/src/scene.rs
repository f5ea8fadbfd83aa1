//! Synthetic scene folders: generate one from a seed and write it with its run record.

use sage_core::Result;
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
