//! What the training-data tests share: a small generated home and its dataset.

use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::split::SplitParams;
use std::path::{Path, PathBuf};

/// A 3-room, 30-object home of 3000 Gaussians saved as `dir/scenes/home1`, and its dataset in
/// `dir/data` with `trajectories` trajectories and every episode in `train`: (scenes,
/// dataset).
pub fn home_dataset(dir: &Path, trajectories: usize) -> (PathBuf, PathBuf) {
    let scenes = dir.join("scenes");
    let home = scenes.join("home1");
    sage_synth::generate(&sage_synth::SynthConfig {
        seed: 1,
        rooms: 3,
        objects: 30,
        gaussians: 3000,
        ..sage_synth::SynthConfig::default()
    })
    .unwrap()
    .save(&home, sage_scene::SplatLayout::Compressed)
    .unwrap();
    let dataset = dir.join("data");
    let assemble = AssembleParams {
        seed: 2,
        split: SplitParams {
            scene_unseen: 0.0,
            val: 0.0,
            donor_share: 0.0,
        },
        balanced: 0,
    };
    build::build(
        std::slice::from_ref(&home),
        &dataset,
        &SceneParams::new(trajectories, 2),
        &assemble,
        &|_| {},
    )
    .unwrap();
    (scenes, dataset)
}
