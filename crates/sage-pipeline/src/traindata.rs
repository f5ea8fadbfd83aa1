//! Training data from a dataset split (`sage3d data render`, `sage3d.render_training_data`):
//! the options resolved, the render run or resumed with progress, and what it did.

use sage_core::Result;
use sage_traindata::{Manifest, Options, Progress};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// What [`render`] did.
#[derive(Debug, Clone)]
pub struct TrainDataReport {
    /// The manifest of the finished render (`manifest.json`).
    pub manifest: Manifest,
    /// The same render had already finished in the output folder: nothing was rendered.
    pub already_complete: bool,
    /// Frames rendered by this run (not those of routes resumed from an earlier run).
    pub rendered_frames: usize,
}

/// Renders (or resumes) the training set of `options` into `out`: `out` must be new, empty or
/// the same render's folder; with `force`, another render's output there is replaced (files a
/// render did not write are never touched). `on_progress` hears every [`Progress`] event.
///
/// # Errors
///
/// Bad options, no scenes folder given nor recorded, an output folder that may not be
/// written, or as [`sage_traindata::render`].
pub fn render(
    options: &Options,
    out: &Path,
    force: bool,
    on_progress: &(dyn Fn(Progress<'_>) + Sync),
) -> Result<TrainDataReport> {
    let settings = options.settings()?;
    let frames = AtomicUsize::new(0);
    let complete = AtomicBool::new(false);
    let manifest = sage_traindata::render(&settings, out, force, &|p| {
        match p {
            Progress::Route(r) => {
                frames.fetch_add(r.frames, Ordering::Relaxed);
            }
            Progress::AlreadyComplete => complete.store(true, Ordering::Relaxed),
            Progress::Planned { .. } | Progress::Scene(_) => {}
        }
        on_progress(p);
    })?;
    Ok(TrainDataReport {
        manifest,
        already_complete: complete.into_inner(),
        rendered_frames: frames.into_inner(),
    })
}
