//! What an evaluation runs: the dataset split, the scenes, the agent, the metric mode and the
//! seed. A run folder records them and resumes only a run with the same settings.

use sage_agents::AgentKind;
use sage_metrics::{Dtw, Mode, Scoring};
use sage_physics::SplatBodies;
use sage_splat::Device;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What an evaluation runs; a run folder only resumes a run with the same settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalSettings {
    /// Dataset folder (holds `episodes/{split}.jsonl`).
    pub dataset: PathBuf,
    /// One scene folder or a folder of scene folders, named as the episodes' `scene`.
    pub scenes: PathBuf,
    /// Dataset split.
    pub split: String,
    /// The agent.
    pub agent: AgentKind,
    /// Metric mode.
    pub mode: Mode,
    /// The alignment of nDTW (exact unless asked).
    #[serde(default)]
    pub dtw: Dtw,
    /// Seed of the agent (each episode mixes in its id).
    pub seed: u64,
    /// Environment preset (`sage_env::config::PRESETS`).
    pub preset: String,
    /// Where the images of agents that read them are rendered; recorded only when not the
    /// CPU, so the records of CPU runs are as they always were.
    #[serde(default, skip_serializing_if = "is_cpu")]
    pub device: Device,
    /// Which objects of the scenes get collision bodies recovered from their Gaussians
    /// (`sage3d physics build --splat-bodies`); recorded only when not `auto`, so the records
    /// of default runs are as they always were.
    #[serde(default, skip_serializing_if = "is_auto")]
    pub splat_bodies: SplatBodies,
}

/// True for the default bodies (serde leaves them out of the run record).
fn is_auto(choice: &SplatBodies) -> bool {
    *choice == SplatBodies::Auto
}

/// True for the default device (serde leaves it out of the run record).
fn is_cpu(device: &Device) -> bool {
    *device == Device::Cpu
}

impl EvalSettings {
    /// How the run's records are scored.
    pub fn scoring(&self) -> Scoring {
        Scoring {
            mode: self.mode,
            dtw: self.dtw,
        }
    }
}
