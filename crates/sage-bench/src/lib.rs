//! `sage-bench`: the benchmark data of sage3d (SPEC §9).
//!
//! [`dataset`] holds episodes, slices, splits, the balanced test selector, the file formats
//! (our JSONL, SAGE-Bench GVLN JSON, R2R-VLNCE) and the `build` pipeline that turns a folder of
//! scenes into a dataset. Conventions are documented in `docs/dataset.md`.

pub mod dataset;
pub mod metrics;
