//! One split of a dataset folder written in another tool's format (GN-Bench's Parquet), so
//! that episodes sage3d made run there; the inverse of [`crate::import`].

use crate::folder;
use crate::formats::gnbench::{self, LeftOut};
use sage_core::{Error, Result};
use std::path::Path;

/// The formats a split can be exported to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A GN-Bench split ([`gnbench`]).
    GnBench,
}

impl Format {
    /// The file extension of the format: readers (GN-Bench's loader, `pandas`, `datasets`)
    /// tell a file's format by it.
    pub fn extension(self) -> &'static str {
        match self {
            Format::GnBench => "parquet",
        }
    }
}

/// What [`export`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// Rows written (episodes, in the split's order).
    pub rows: usize,
    /// Episodes the format cannot hold, with the reasons.
    pub left_out: Vec<LeftOut>,
}

/// Writes split `split` of `dataset` to the file `out` in `format`, in the split's order (so
/// GN-Bench's `episode_id`, the row number, is the episode's place in the split). `scenes` is
/// the scenes folder (GN-Bench's pixels are those of each scene's occupancy map); `None`: the
/// one the dataset records ([`folder::scenes_folder`]). An existing `out` is replaced only
/// with `force`; the file is written whole or not at all.
///
/// # Errors
///
/// An `out` not named with the format's extension ([`Format::extension`]), an existing `out`
/// without `force`, a split the dataset does not list, no scenes folder, a
/// split none of whose episodes the format can hold (naming the first and why), a write error.
pub fn export(
    dataset: &Path,
    split: &str,
    scenes: Option<&Path>,
    format: Format,
    out: &Path,
    force: bool,
) -> Result<Exported> {
    let extension = format.extension();
    if !out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(extension))
    {
        return Err(Error::invalid(format!(
            "the output must end in .{extension}: its format is told by its name"
        ))
        .in_file(out));
    }
    sage_io::run::claim_file(out, force)?;
    let scenes = folder::scenes_folder(dataset, scenes)?;
    let (_, episodes) = folder::split_episodes(dataset, split)?;
    match format {
        Format::GnBench => {
            let (rows, left_out) = gnbench::rows(&episodes, &scenes)?;
            if rows.is_empty() {
                let why = left_out.first().map_or_else(
                    || "the split is empty".to_string(),
                    |l| format!("{}: {}", l.episode_id, l.reason),
                );
                return Err(Error::invalid(format!(
                    "no episode of split '{split}' can be written as GN-Bench ({why})"
                )));
            }
            gnbench::write_rows(out, &rows)?;
            Ok(Exported {
                rows: rows.len(),
                left_out,
            })
        }
    }
}
