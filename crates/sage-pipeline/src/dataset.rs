//! The dataset build over a folder of scenes: per-scene trajectories, instructions and episodes
//! (parallel, resumable), then splits, files and summary, and the run record.

use sage_core::{Error, Result};
use sage_dataset::build::{self, AssembleParams, DatasetSummary, SceneOutcome, SceneParams};
use std::path::{Path, PathBuf};

/// What [`build`] did.
#[derive(Debug, Clone)]
pub struct DatasetReport {
    /// The scene folders.
    pub dirs: Vec<PathBuf>,
    /// Per scene: made, resumed or skipped.
    pub outcomes: Vec<SceneOutcome>,
    /// The dataset's summary.
    pub summary: DatasetSummary,
}

/// Builds (or resumes) the dataset of the scenes under `scenes` into `out`; `on_scene(outcome,
/// scenes)` is called as each of the `scenes` folders is done. `out` must be new, empty or a
/// dataset build's folder; with `force`, a folder of other files is written into, provided
/// none of them would be replaced ([`sage_io::run::claim_folder`]).
///
/// # Errors
///
/// Bad settings (shares outside 0..1, naming the flags), no scenes, an output folder holding
/// files the build did not write, or a write error. A scene that fails is skipped with its
/// reason (in the outcomes) and the build goes on.
pub fn build(
    scenes: &Path,
    out: &Path,
    params: &SceneParams,
    assemble: &AssembleParams,
    force: bool,
    on_scene: &(dyn Fn(&SceneOutcome, usize) + Sync),
) -> Result<DatasetReport> {
    params.validate()?;
    let shares = [assemble.split.scene_unseen, assemble.split.val];
    if !shares.iter().all(|s| (0.0..=1.0).contains(s)) {
        return Err(Error::invalid(
            "--scene-unseen and --val must be shares between 0 and 1",
        ));
    }
    let dirs = sage_io::scenes::scene_dirs(scenes)?;
    sage_io::run::claim_folder(out, &["data build"], &build::OUTPUTS, force)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    // Recorded before the work too, so a build that crashes halfway is this command's folder
    // and its rerun resumes instead of being refused.
    build::write_run_record(out, scenes, &dirs, params, assemble)?;
    let (outcomes, summary) =
        build::build(&dirs, out, params, assemble, &|o| on_scene(o, dirs.len()))?;
    build::write_run_record(out, scenes, &dirs, params, assemble)?;
    Ok(DatasetReport {
        dirs,
        outcomes,
        summary,
    })
}
