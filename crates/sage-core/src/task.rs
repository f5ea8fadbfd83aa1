//! The task of an episode, shared by datasets, the environment and the metrics.

use serde::{Deserialize, Serialize};

/// Task of an episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Task {
    /// Vision-and-language navigation to a goal: reach it and STOP there.
    Vln,
    /// Explore without a goal: move as long as possible without a collision.
    Nogoal,
}
