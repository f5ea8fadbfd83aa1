//! Reading a file through a memory map. Its own module because both the PLY reader and the
//! any-format splat readers map their input, and neither should have to import the other for it.

use sage_core::{Error, Result, ResultExt};
use std::path::Path;

/// Runs `f` on the bytes of the 3DGS file `path`, memory-mapped; errors name the file (unless
/// they name another already). A directory (or another thing that is no file) is refused as
/// such, before it is mapped.
///
/// # Errors
///
/// `path` is missing, a directory or no regular file, cannot be read, or `f`'s error.
pub(crate) fn with_mapped_file<T>(path: &Path, f: impl FnOnce(&[u8]) -> Result<T>) -> Result<T> {
    refuse_non_file(path)?;
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    // SAFETY: the map is read-only and dropped before returning; a file truncated by another
    // process while mapped is outside what a reader can defend against.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
    f(&map).in_file(path)
}

/// Refuses a directory (or another thing that is no regular file) at `path` by what it is:
/// mapping one fails with an obscure OS error (`No such device`). A missing `path` passes, for
/// the reader to report.
///
/// # Errors
///
/// `path` is a directory, or exists and is no regular file, naming it.
pub(crate) fn refuse_non_file(path: &Path) -> Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            Err(Error::invalid("a directory, not a file: give the 3DGS file itself").in_file(path))
        }
        Ok(m) if !m.is_file() => Err(Error::invalid(
            "not a regular file (a device, pipe or socket): give a 3DGS file",
        )
        .in_file(path)),
        _ => Ok(()),
    }
}
