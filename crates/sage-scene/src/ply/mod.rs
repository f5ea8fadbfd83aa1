//! 3DGS PLY files in both layouts. The [`header`] parser serves any PLY file: PLY meshes are read
//! on top of it by [`crate::mesh::read_ply`], next to the mesh type they fill.
//!
//! - [`standard`]: the Inria layout (`x y z … f_dc_* f_rest_* opacity scale_* rot_*`), matched by
//!   property name in any order and any scalar type, ASCII or binary; SH degree inferred from the
//!   number of `f_rest_*` properties.
//! - [`compressed`]: the SuperSplat/PlayCanvas chunked layout (`chunk` + packed `vertex` +
//!   optional `sh` elements), 12- or 18-float chunk records.
//!
//! The layout is detected from the header, never from the file name.

pub mod compressed;
pub mod header;
pub mod standard;

use crate::gaussians::Gaussians;
use crate::mapped::with_mapped_file;
use crate::splats::SplatSource;
use sage_core::{Error, Result};
use std::path::Path;

/// The two 3DGS PLY layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SplatLayout {
    /// The standard (Inria) float layout.
    Standard,
    /// The SuperSplat chunked, quantised layout.
    Compressed,
}

impl SplatLayout {
    /// The layout a file name asks for when writing, in any case as the other format names:
    /// `*.compressed.ply` (what `splat-transform` tests) or `*_compressed.ply` (the scene
    /// folders' `3dgs_compressed.ply`) is compressed, any other `.ply` standard. The suffix must
    /// follow a `.` or `_`: `x.decompressed.ply`, the name `splat-transform` gives its decoded
    /// output, and `x_uncompressed.ply` are standard, never silently quantised.
    pub fn from_file_name(path: &Path) -> Result<SplatLayout> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if name.ends_with(".compressed.ply") || name.ends_with("_compressed.ply") {
            Ok(SplatLayout::Compressed)
        } else if name.ends_with(".ply") {
            Ok(SplatLayout::Standard)
        } else {
            Err(Error::invalid(format!(
                "{}: cannot tell the layout from the name (use NAME.ply or NAME.compressed.ply)",
                path.display()
            )))
        }
    }

    /// A short name for reports.
    pub fn as_str(self) -> &'static str {
        match self {
            SplatLayout::Standard => "standard",
            SplatLayout::Compressed => "compressed",
        }
    }
}

/// Detects the layout of a parsed header.
pub fn detect_layout(header: &header::Header) -> Result<SplatLayout> {
    let has_chunk = header.element("chunk").is_some();
    let packed = header
        .element("vertex")
        .is_some_and(|(_, v)| v.property_index("packed_position").is_some());
    match (has_chunk, packed) {
        (true, true) => Ok(SplatLayout::Compressed),
        (false, false) if header.element("vertex").is_some() => Ok(SplatLayout::Standard),
        (true, false) => Err(Error::format(
            "vertex",
            "has a 'chunk' element but no 'packed_position' property",
        )),
        (false, true) => Err(Error::format(
            "chunk",
            "packed vertices need a 'chunk' element",
        )),
        (false, false) => Err(Error::format(
            "vertex",
            "no 'vertex' element: not a Gaussian splat file",
        )),
    }
}

/// Reads Gaussians from PLY bytes in either layout into the compact store.
pub fn read_splats(bytes: &[u8]) -> Result<(Gaussians, SplatLayout)> {
    let header = header::parse_header(bytes)?;
    let layout = detect_layout(&header)?;
    let g = match layout {
        SplatLayout::Standard => standard::read(&header, bytes)?,
        SplatLayout::Compressed => compressed::read(&header, bytes)?,
    };
    Ok((g, layout))
}

/// Reads a Gaussian file (memory-mapped); errors name the file, and a directory is refused as
/// one.
pub fn read_splats_file(path: &Path) -> Result<(Gaussians, SplatLayout)> {
    with_mapped_file(path, read_splats)
}

/// Writes Gaussians in `layout`, atomically (temporary file, then rename).
pub fn write_splats_file(
    path: &Path,
    gaussians: &impl SplatSource,
    layout: SplatLayout,
) -> Result<()> {
    sage_io::files::write_atomic(path, |w| match layout {
        SplatLayout::Standard => standard::write(w, gaussians),
        SplatLayout::Compressed => compressed::write(w, gaussians),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_separated_compressed_suffix_asks_for_the_compressed_layout() {
        let layout = |name: &str| SplatLayout::from_file_name(Path::new(name)).unwrap();
        for name in [
            "x.compressed.ply",
            "x_compressed.ply",
            "dir/3dgs_compressed.ply",
            "X.COMPRESSED.PLY",
            "x_Compressed.Ply",
        ] {
            assert_eq!(layout(name), SplatLayout::Compressed, "{name}");
        }
        // `compressed.ply` ending a longer word is not the suffix: these are standard PLYs.
        for name in [
            "x.decompressed.ply",
            "random_3k_sh0.decompressed.ply",
            "x_uncompressed.ply",
            "xcompressed.ply",
            "compressed.ply",
            "x.ply",
            "X.PLY",
        ] {
            assert_eq!(layout(name), SplatLayout::Standard, "{name}");
        }
        let e = SplatLayout::from_file_name(Path::new("x.compressed"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.compressed: cannot tell the layout"), "{e}");
    }
}
