//! Episodes from elsewhere (the published SAGE-Bench GVLN files, R2R-VLNCE splits) as one split
//! of a dataset folder, so that `eval` and `data render` read them like a built dataset.

use crate::formats::{gvln, jsonl, r2r};
use crate::{Episode, folder};
use glam::Vec2;
use sage_core::{Error, Result, ResultExt};
use sage_lang::StepSizes;
use std::path::{Path, PathBuf};

/// Where the episodes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A GVLN file; files that do not state their frame are in the S frame with this offset.
    Gvln {
        /// The file.
        file: PathBuf,
        /// The S-frame offset (δx, δy) of files without a `frame` field.
        offset: Vec2,
    },
    /// The R2R-VLNCE split `split` in folder `dir` (`{split}/{split}.json.gz` and its `_gt`).
    R2r {
        /// The folder.
        dir: PathBuf,
        /// The split's name there.
        split: String,
    },
}

/// The command, as the run record of a dataset folder it made names it.
pub const COMMAND: &str = "data import";

/// Reads `source`, writes its episodes as `dataset/episodes/{split}.jsonl` and lists the split
/// in the dataset's `splits.json` ([`folder::add_split`]); returns the episodes. `dataset` must
/// be new, empty, or a dataset folder written by `data build` or `data import` (a folder
/// without a run record gets this command's); with `force`, a folder of other files is
/// written into, provided none of them would be replaced ([`sage_io::run::claim_folder`]), and
/// an existing split file is replaced.
///
/// # Errors
///
/// A split name that would name a file outside the dataset, an output folder holding files a
/// dataset command did not write, a bad source file (naming
/// the file and field), an existing split without `force`, a write error.
pub fn import(source: &Source, dataset: &Path, split: &str, force: bool) -> Result<Vec<Episode>> {
    sage_io::names::check_plain("split", split).within("`split`")?;
    let names = ["episodes", folder::SPLITS_FILE, sage_io::RUN_RECORD];
    let _lock = sage_io::run::claim_folder(dataset, &[COMMAND, "data build"], &names, force)?;
    let space = StepSizes::default();
    let episodes = match source {
        Source::Gvln { file, offset } => gvln::read(file, *offset, &space)?,
        Source::R2r { dir, split } => r2r::read(dir, split, &space)?,
    };
    let dir = dataset.join("episodes");
    let file = dir.join(format!("{split}.jsonl"));
    if file.exists() && !force {
        return Err(Error::invalid(
            "this split exists already; choose another `split`, or set `force` to replace it",
        )
        .in_file(&file));
    }
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    jsonl::write(&file, &episodes)?;
    folder::add_split(dataset, split, &episodes)?;
    // A built dataset keeps its build's record (it names the scenes folder `eval` reads).
    if sage_io::run::recorded_command(dataset).is_none() {
        sage_io::run::write_run_record(dataset, COMMAND, None, serde_json::json!({}))?;
    }
    Ok(episodes)
}
