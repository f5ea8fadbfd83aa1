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

/// Generates the scene of `config` and writes it to `out` in the InteriorGS layout with
/// Gaussians in `layout`, then the run record (written last: its presence marks a complete
/// folder). `on_stage` is told each [`Stage`] as it starts.
///
/// # Errors
///
/// Bad settings, or a write error.
pub fn synthesize(
    config: &SynthConfig,
    out: &Path,
    layout: SplatLayout,
    on_stage: &dyn Fn(Stage),
) -> Result<Scene> {
    on_stage(Stage::Generating);
    let scene = sage_synth::generate(config)?;
    on_stage(Stage::Writing);
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
    sage_io::run::write_run_record(out, "scene synth", Some(config.seed), details)?;
    Ok(scene)
}
