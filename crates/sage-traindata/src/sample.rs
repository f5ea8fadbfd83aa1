//! What a render leaves per route (`route.json` beside its frames) and the per-episode
//! samples the output formats are written from.

use crate::preset::ActionPreset;
use crate::replay::{Route, Verdict, Walk, WalkStep};
use serde::{Deserialize, Serialize};

/// The folder of an output holding the frames: `images/{scene}/{route}/{k:04}.{suffix}`.
pub const IMAGES_DIR: &str = "images";

/// The record a route's folder gets once all of its frames are written: its presence marks
/// the route as done.
pub const ROUTE_FILE: &str = "route.json";

/// A rendered route: its walk, or why it could not be walked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RouteRecord {
    /// The scene.
    pub scene: String,
    /// The route's folder name.
    pub route: String,
    /// Its episodes' ids.
    pub episodes: Vec<String>,
    /// The file suffixes of each frame (`jpg`, `depth.png`, …), RGB first.
    pub suffixes: Vec<String>,
    /// The walk, when it could be made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub walk: Option<Walk>,
    /// Why the route could not be walked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// One episode as a training sample: its instruction and its walk's actions, frames and poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSample {
    /// The episode's id.
    pub episode_id: String,
    /// The scene.
    pub scene: String,
    /// The instruction.
    pub instruction: String,
    /// The route folder the frames are in (shared by the episodes of one walk).
    pub route: String,
    /// The walk's verdict (`clean` unless failed walks are kept).
    pub verdict: Verdict,
    /// How the walk ended: `reached`, `capped` or `blocked`.
    pub ending: String,
    /// The actions, STOP last.
    pub actions: Vec<String>,
    /// Each action in words (`move forward 0.35 meter`, …).
    pub words: Vec<String>,
    /// Each frame's files, relative to the images folder, RGB first:
    /// `files[k] = ["home_0/home_0-t0-0/0003.jpg", "home_0/home_0-t0-0/0003.depth.png"]`.
    pub files: Vec<Vec<String>>,
    /// Per action: the frame's pose, the commanded and the achieved pose.
    pub steps: Vec<WalkStep>,
}

/// The samples of `route`'s episodes from its `record` (which must hold a walk).
pub fn samples(route: &Route, record: &RouteRecord, preset: &ActionPreset) -> Vec<EpisodeSample> {
    let Some(walk) = &record.walk else {
        return Vec::new();
    };
    let files: Vec<Vec<String>> = (0..walk.steps.len())
        .map(|k| {
            record
                .suffixes
                .iter()
                .map(|s| format!("{}/{}/{k:04}.{s}", route.scene, route.name))
                .collect()
        })
        .collect();
    let actions: Vec<String> = walk.steps.iter().map(|s| s.action.clone()).collect();
    let words: Vec<String> = actions
        .iter()
        .map(|a| preset.words(crate::preset::action_from_name(a)))
        .collect();
    route
        .episodes
        .iter()
        .map(|e| EpisodeSample {
            episode_id: e.episode_id.clone(),
            scene: e.scene.clone(),
            instruction: e.instruction.clone(),
            route: route.name.clone(),
            verdict: walk.verdict,
            ending: walk.ending.clone(),
            actions: actions.clone(),
            words: words.clone(),
            files: files.clone(),
            steps: walk.steps.clone(),
        })
        .collect()
}
