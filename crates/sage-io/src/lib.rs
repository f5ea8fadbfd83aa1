//! `sage-io`: the plumbing of files and runs that every sage3d pipeline shares.
//!
//! - [`files`]: atomic writes (a file is whole or absent, never half-written; an interrupted
//!   one leaves a temporary file that [`files::is_temporary`] recognises), JSON, PNG and
//!   NumPy `.npy`, readers whose errors name the file, line and column;
//! - [`names`]: the one rule by which names from data (splits, scenes, episode ids) become
//!   file names, inside their folder and distinct;
//! - [`limits`]: the caps on what an input file may hold or declare (file sizes, label counts,
//!   image pixels, decoded meshes), each raised by an environment variable `SAGE3D_MAX_…`;
//! - [`hash`]: the one stable hash (FNV-1a) for fingerprints, cache keys and derived seeds;
//! - [`image`]: PNG and JPEG encoded in memory (frames, responses, training data);
//! - [`run`]: the run record `sage3d_run.json` that says how an output folder was made (or that
//!   its command has not finished writing it), and the claim of an output folder;
//! - [`lock`]: one writer per output folder (an OS advisory lock held while a command writes
//!   it), and the removal of the temporary files an interrupted run left there;
//! - [`scenes`]: finding scene folders, their names, and fingerprints of their input files;
//! - [`runner`]: the resumable per-scene runner and its typed outcome;
//! - [`canvas`]: the small RGB canvas that draws maps, plans and charts to PNG,
//!   [`palette`]: distinct, stable colours for ids, and [`marks`]: the paths and markers drawn
//!   over top-down maps;
//! - [`gif`]: the one writer of animated GIFs.
//!
//! It knows nothing of scenes beyond their folder layout, so every other crate can use it.

pub mod canvas;
pub mod files;
pub mod gif;
pub mod hash;
pub mod image;
pub mod limits;
pub mod lock;
pub mod marks;
pub mod names;
pub mod palette;
pub mod run;
pub mod runner;
pub mod scenes;

pub use canvas::Canvas;
pub use files::{read_json, write_atomic, write_json};
pub use run::{RUN_RECORD, write_run_record};
