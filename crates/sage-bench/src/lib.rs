//! `sage-bench`: the benchmark of sage3d — its data and its scores (SPEC §9 and §10).
//!
//! [`dataset`] holds episodes, slices, splits, the balanced test selector, the file formats
//! (our JSONL, SAGE-Bench GVLN JSON, R2R-VLNCE) and the `build` pipeline that turns a folder of
//! scenes into a dataset (`docs/dataset.md`). [`eval`] runs an agent over
//! a dataset split in the environment, resumably, and summarises the scores per slice with
//! `sage-metrics` (`docs/evaluation.md`); [`agents`] adds the replay and remote (model server) agents it can
//! run. [`report`] turns a run folder into a self-contained HTML page with the metric tables,
//! per-slice charts and per-episode trajectory maps.

pub mod agents;
pub mod dataset;
pub mod eval;
pub mod report;
