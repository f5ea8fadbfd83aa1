//! `sage-pipeline`: the pipelines of sage3d as library functions, shared by the command line
//! and the Python package (as brush's `brush-process` is by its CLI and app).
//!
//! - [`recon`]: mesh scene → planned cameras → ground-truth views → nerfstudio export → a fitted
//!   Gaussian scene.
//!
//! Every function takes plain settings, reports progress through a callback, writes its
//! outputs atomically with a run record, and returns a plain report; printing is the front
//! end's.

pub mod recon;
