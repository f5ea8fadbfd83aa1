//! Synthetic scene folders: generate one from a seed and write it with its run record.

use sage_core::Result;
use sage_scene::{Scene, SplatLayout};
use sage_synth::SynthConfig;
use std::path::Path;

/// Generates the scene of `config` and writes it to `out` in the InteriorGS layout with
/// Gaussians in `layout`, then the run record (written last: its presence marks a complete
/// folder). `on_stage` names each stage as it starts (`generating`, `writing`).
///
/// # Errors
///
/// Bad settings, or a write error.
pub fn synthesize(
    config: &SynthConfig,
    out: &Path,
    layout: SplatLayout,
    on_stage: &dyn Fn(&str),
) -> Result<Scene> {
    on_stage("generating");
    let scene = sage_synth::generate(config)?;
    on_stage("writing");
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
