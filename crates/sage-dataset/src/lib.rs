//! Datasets: from scenes to episodes, splits and files.
//!
//! [`episode`] is the record of one episode (SPEC §9), [`slices`] its complexity tags,
//! [`split`] the train / val / test assignment with the three unseen test sets, [`selector`] the
//! balanced test selection, [`formats`] the files (JSONL, GVLN, R2R-VLNCE), [`build`] the
//! whole pipeline over a folder of scenes, [`import`] a split from other files and [`folder`]
//! what a dataset folder records about itself (its splits, its scenes folder).

pub mod build;
pub mod episode;
pub mod folder;
pub mod formats;
pub mod import;
pub mod selector;
pub mod slices;
pub mod split;

pub use episode::{Episode, Goal, StartPose, Task};
