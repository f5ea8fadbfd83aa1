//! What the integration tests of the evaluator share: one small generated home with its
//! dataset.

use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::split::SplitParams;
use sage_synth::{SynthConfig, generate};
use std::path::{Path, PathBuf};

/// A 3-room, 30-object home saved as `dir/scenes/home1` and its dataset in `dir/data`
/// (3 trajectories, seed 2, `balanced` episodes in the balanced test split); returns
/// (scenes folder, scene folder, dataset folder).
pub fn small_dataset(dir: &Path, balanced: usize) -> (PathBuf, PathBuf, PathBuf) {
    let scenes = dir.join("scenes");
    let home = scenes.join("home1");
    generate(&SynthConfig {
        seed: 1,
        rooms: 3,
        objects: 30,
        gaussians: 1000,
        ..SynthConfig::default()
    })
    .unwrap()
    .save(&home, sage_scene::SplatLayout::Compressed)
    .unwrap();
    let data = dir.join("data");
    let assemble = AssembleParams {
        seed: 2,
        split: SplitParams::default(),
        balanced,
    };
    build::build(
        std::slice::from_ref(&home),
        &data,
        &SceneParams::new(3, 2),
        &assemble,
        &|_| {},
    )
    .unwrap();
    (scenes, home, data)
}
