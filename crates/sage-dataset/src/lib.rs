//! `sage-dataset`: sage3d's VLN datasets (SPEC §9, `docs/dataset.md`) — from scenes to
//! episodes, splits and files, and back.
//!
//! [`episode`] is the record of one episode, [`slices`] its complexity tags, [`split`] the
//! train / val / test assignment with the three unseen test sets, [`selector`] the balanced test
//! selection, [`formats`] the files (JSONL, SAGE-Bench GVLN, R2R-VLNCE,
//! GN-Bench Parquet), [`build`] the steps of
//! the build over a folder of scenes (the pipeline itself is `sage_pipeline::dataset`),
//! [`import`] a split from other files, [`export`] one to another tool's file, and [`folder`] what a dataset folder records about
//! itself and how a split is read from it ([`folder::split_episodes`]) — what the evaluator,
//! the training-data render and Python all read datasets through.

pub mod build;
pub mod episode;
pub mod export;
pub mod folder;
pub mod formats;
pub mod import;
pub mod selector;
pub mod slices;
pub mod split;

pub use episode::{Episode, Goal, StartPose, Task};
