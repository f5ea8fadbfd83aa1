//! The preview: an animated GIF of a few episodes, so a person can check the data by eye.

/// The preview's file name in the output folder.
pub const PREVIEW_FILE: &str = "preview.gif";

use crate::run::Plan;
use crate::sample::EpisodeSample;
use sage_core::Result;
use std::path::Path;

/// Writes `out/preview.gif` showing the first `n` of `samples`.
///
/// # Errors
///
/// A frame or scene that cannot be read, or a write error.
pub fn write(_plan: &Plan, _out: &Path, _samples: &[EpisodeSample], _n: usize) -> Result<()> {
    Err(sage_core::Error::invalid("preview: not written yet"))
}
