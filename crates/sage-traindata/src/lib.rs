//! `sage-traindata`: training data for VLN models — what SAGE-Bench's instruction–trajectory
//! pairs were made for.
//!
//! A dataset split's goal-directed episodes are grouped into routes (the instructions of one
//! trajectory share a walk, [`replay::routes`]); each route is walked once through the
//! environment's physics by a [`follow::PathFollower`] that cuts the reference path into a
//! preset's discrete actions ([`preset::ActionPreset`]: `vlnce`, `navila_small`,
//! `navila_large`, `custom_small`, answering in SAGE-3D's or NaVILA's words,
//! [`preset::Answers`]); the camera's frame before each action is rendered and
//! encoded ([`encode`]); and the samples are written as NaVILA's annotation parts, WebDataset
//! shards, a plain folder tree ([`output`]) or a LeRobot v3.0 dataset ([`lerobot`]), with a
//! manifest last ([`run`]). A route is
//! the unit of resumption: its `route.json` is written after its frames, so a rerun after a
//! crash redoes only unfinished routes. Nothing depends on thread count or order: the same
//! settings give the same bytes.

pub mod encode;
pub mod follow;
pub mod lerobot;
pub mod options;
pub mod output;
pub mod preset;
pub mod preview;
pub mod replay;
pub mod run;
pub mod sample;

pub use encode::ImageType;
pub use options::Options;
pub use output::Layout;
pub use preset::{ActionPreset, Answers, PresetName};
pub use run::{
    Manifest, Plan, Progress, RouteDone, SceneProgress, Sensors, Settings, claim, finish, lock,
    render, render_scene,
};
