//! `sage-pipeline`: the pipelines of sage3d as library functions, shared by the command line
//! and the Python package (as brush's `brush-process` is by its CLI and app).
//!
//! - [`demo`]: the whole job end to end on synthetic (or real) scenes, as a plan of steps, with
//!   the claim of its output folder;
//! - its steps: [`scene`] (synthesise a scene folder), [`nav`] (semantic map and occupancy),
//!   [`physics`] (collision bodies, the hull cache's work list, the USDA export), [`dataset`]
//!   (the dataset build and imports, with [`dataset::BuildSettings`]), [`traindata`]
//!   (training data rendered from a split), [`evaluate`] (an agent's evaluation with its
//!   report, with [`evaluate::EvalOptions`]), [`overview`] (the demo's picture);
//! - [`capture`]: a capture of one's own (any 3DGS file) as a scene folder in W, with its
//!   occupancy map and provenance;
//! - [`render`]: a scene's images from one camera (every channel, a legend, a turntable);
//! - [`recon`]: mesh scene → planned cameras → ground-truth views → nerfstudio export → a fitted
//!   Gaussian scene.
//!
//! Every pipeline is one function that takes one typed settings struct (its defaults in one
//! `Default`; with the feature `clap`, the command line's flags; with serde, Python's keyword
//! arguments), reports progress through a callback, writes its outputs atomically with a run
//! record, and returns a plain report; printing is the front end's. Errors name settings, not
//! flags.

pub mod capture;
pub mod dataset;
pub mod demo;
pub mod evaluate;
pub mod nav;
pub mod overview;
pub mod physics;
pub mod recon;
pub mod render;
pub mod scene;
pub mod traindata;
