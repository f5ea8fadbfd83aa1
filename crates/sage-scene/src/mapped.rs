//! Reading a file through a memory map. Its own module because both the PLY reader and the
//! any-format splat readers map their input, and neither should have to import the other for it.

use sage_core::{Error, Result, ResultExt};
use std::path::Path;

/// Runs `f` on the bytes of `path`, memory-mapped; errors name the file (unless they name
/// another already).
pub(crate) fn with_mapped_file<T>(path: &Path, f: impl FnOnce(&[u8]) -> Result<T>) -> Result<T> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    // SAFETY: the map is read-only and dropped before returning; a file truncated by another
    // process while mapped is outside what a reader can defend against.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
    f(&map).in_file(path)
}
