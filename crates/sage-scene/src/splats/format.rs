//! Which format a 3DGS file is in, told from its bytes, and the one door to reading and
//! writing any of them.

use super::{BlockDecoder, SplatSource, SplatTable, antimatter, gltf, sog, spz};
use crate::gaussians::Gaussians;
use crate::mapped::with_mapped_file;
use crate::ply::{self, SplatLayout};
use sage_core::{Error, Result};
use std::fmt;
use std::path::Path;

/// A 3DGS file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// PLY, standard (Inria) or compressed (SuperSplat) layout.
    Ply(SplatLayout),
    /// Niantic's SPZ.
    Spz,
    /// PlayCanvas's SOG (a zip of WebP images and `meta.json`).
    Sog,
    /// glTF 2.0 (GLB or JSON) with the `KHR_gaussian_splatting` extension.
    Gltf,
    /// antimatter15's `.splat` (32-byte records, no header).
    Splat,
}

/// Every format, in the order [`Format::detect`] tries them.
pub const ALL: [Format; 6] = [
    Format::Ply(SplatLayout::Standard),
    Format::Ply(SplatLayout::Compressed),
    Format::Spz,
    Format::Sog,
    Format::Gltf,
    Format::Splat,
];

impl Format {
    /// The format's name as commands take and print it: `ply`, `compressed-ply`, `spz`,
    /// `sog`, `gltf`, `splat`.
    pub fn as_str(self) -> &'static str {
        match self {
            Format::Ply(SplatLayout::Standard) => "ply",
            Format::Ply(SplatLayout::Compressed) => "compressed-ply",
            Format::Spz => "spz",
            Format::Sog => "sog",
            Format::Gltf => "gltf",
            Format::Splat => "splat",
        }
    }

    /// True when sage3d writes the format (standard and compressed PLY, SPZ).
    pub fn writable(self) -> bool {
        matches!(self, Format::Ply(_) | Format::Spz)
    }

    /// The format of `bytes`, from magic bytes and headers: PLY (`ply` and its header's
    /// layout), SPZ (gzip holding the `NGSP` header), SOG (a zip holding `meta.json`), glTF
    /// (`glTF` magic, or JSON naming the extension), and last `.splat`, which has no magic (a
    /// whole number of plausible 32-byte records).
    ///
    /// # Errors
    ///
    /// None of them fits, or a PLY header is damaged. When none fits, a zip or gzip signature
    /// says which format the file means to be (SOG, SPZ), and that format's reader says what is
    /// wrong (a truncated archive …); otherwise the message lists what was tried.
    pub fn detect(bytes: &[u8]) -> Result<Format> {
        Format::detect_named(bytes, None)
    }

    /// [`Format::detect`] of the bytes of the file `name`. The content decides, as there; the
    /// name only explains a failure: when no format fits and the content has no signature that
    /// names one, the format the name's extension names (`.ply`, `.spz`, `.sog`, `.glb`,
    /// `.gltf`, `.splat`) says what is wrong — for `.splat`, which has no magic, the length that
    /// is no whole number of records (truncated) or the record that is no Gaussian (a NaN).
    ///
    /// # Errors
    ///
    /// As [`Format::detect`], with the named format's reason.
    pub fn detect_named(bytes: &[u8], name: Option<&Path>) -> Result<Format> {
        if bytes.starts_with(b"ply") {
            let header = ply::header::parse_header(bytes)?;
            return Ok(Format::Ply(ply::detect_layout(&header)?));
        }
        if spz::sniff(bytes) {
            return Ok(Format::Spz);
        }
        if sog::sniff(bytes) {
            return Ok(Format::Sog);
        }
        if gltf::sniff(bytes) {
            return Ok(Format::Gltf);
        }
        if antimatter::sniff(bytes) {
            return Ok(Format::Splat);
        }
        Err(why_not(bytes, name))
    }

    /// The format a file's name says it holds, from its extension (`.ply`, `.spz`, `.sog`,
    /// `.glb` or `.gltf`, `.splat`; any case), if any. Reading never relies on it (see
    /// [`Format::detect_named`]).
    pub fn from_input_name(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        Some(match ext.as_str() {
            "ply" => Format::Ply(SplatLayout::Standard),
            "spz" => Format::Spz,
            "sog" => Format::Sog,
            "glb" | "gltf" => Format::Gltf,
            "splat" => Format::Splat,
            _ => return None,
        })
    }

    /// The format a file name asks for when writing, in any case: `*.compressed.ply` /
    /// `*_compressed.ply` compressed PLY ([`SplatLayout::from_file_name`]; `*.decompressed.ply`
    /// is not one), other `*.ply` standard PLY, `*.spz` SPZ.
    ///
    /// # Errors
    ///
    /// Another name, or a format sage3d only reads.
    pub fn from_output_name(path: &Path) -> Result<Format> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if name.ends_with(".spz") {
            Ok(Format::Spz)
        } else if name.ends_with(".ply") {
            Ok(Format::Ply(SplatLayout::from_file_name(path)?))
        } else {
            Err(Error::invalid(format!(
                "{}: cannot tell the output format from the name (write NAME.ply, \
                 NAME.compressed.ply or NAME.spz; SOG, glTF and .splat are read only)",
                path.display()
            )))
        }
    }
}

/// Why `bytes`, which no format's test fits, are not a 3DGS file: the reason of the format
/// their signature (a zip is SOG, a gzip SPZ) or else `name`'s extension names, when that
/// format's reader finds one; otherwise what was tried.
fn why_not(bytes: &[u8], name: Option<&Path>) -> Error {
    if bytes.is_empty() {
        return Error::format("file", "empty (0 bytes)");
    }
    let meant = if bytes.starts_with(b"PK\x03\x04") {
        Some(Format::Sog)
    } else if bytes.starts_with(&[0x1f, 0x8b]) {
        Some(Format::Spz)
    } else {
        name.and_then(Format::from_input_name)
    };
    let reason = match meant {
        Some(Format::Sog) => sog::SogDecoder::open(bytes).err(),
        Some(Format::Spz) => spz::SpzDecoder::open(bytes).err(),
        Some(Format::Gltf) => gltf::GltfDecoder::open(bytes).err(),
        Some(Format::Splat) => antimatter::check(bytes).err(),
        Some(Format::Ply(_)) => Some(Error::format(
            "header",
            "does not start with 'ply': not a PLY file",
        )),
        None => None,
    };
    reason.unwrap_or_else(|| {
        Error::format(
            "file",
            "not a 3DGS file sage3d reads (tried PLY, SPZ, SOG, glTF/GLB and .splat)",
        )
    })
}

impl std::str::FromStr for Format {
    type Err = Error;

    /// A format by the name [`Format::as_str`] gives (`glb` also names glTF).
    fn from_str(s: &str) -> Result<Format> {
        let name = s.trim().to_ascii_lowercase();
        ALL.into_iter()
            .find(|f| f.as_str() == name)
            .or((name == "glb").then_some(Format::Gltf))
            .ok_or_else(|| {
                let names: Vec<&str> = ALL.iter().map(|f| f.as_str()).collect();
                Error::invalid(format!(
                    "unknown format '{s}' (expected one of: {})",
                    names.join(", ")
                ))
            })
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Opens `bytes` for decoding in the format they are in.
///
/// # Errors
///
/// As [`Format::detect`], and the format's own checks.
pub fn open(bytes: &[u8]) -> Result<(Box<dyn BlockDecoder + '_>, Format)> {
    open_named(bytes, None)
}

/// [`open`] of the bytes of the file `name`, whose extension explains a failure to detect a
/// format ([`Format::detect_named`]).
///
/// # Errors
///
/// As [`Format::detect_named`], and the format's own checks.
pub fn open_named<'a>(
    bytes: &'a [u8],
    name: Option<&Path>,
) -> Result<(Box<dyn BlockDecoder + 'a>, Format)> {
    let format = Format::detect_named(bytes, name)?;
    let decoder: Box<dyn BlockDecoder + '_> = match format {
        Format::Ply(layout) => {
            let header = ply::header::parse_header(bytes)?;
            match layout {
                SplatLayout::Standard => {
                    Box::new(ply::standard::StandardDecoder::open(&header, bytes)?)
                }
                SplatLayout::Compressed => {
                    Box::new(ply::compressed::CompressedDecoder::open(&header, bytes)?)
                }
            }
        }
        Format::Spz => Box::new(spz::SpzDecoder::open(bytes)?),
        Format::Sog => Box::new(sog::SogDecoder::open(bytes)?),
        Format::Gltf => Box::new(gltf::GltfDecoder::open(bytes)?),
        Format::Splat => Box::new(antimatter::SplatDecoder::open(bytes)?),
    };
    Ok((decoder, format))
}

/// Reads a 3DGS file of any format into the compact scene store.
///
/// # Errors
///
/// `path` is missing, a directory or no regular file, or cannot be read; otherwise as
/// [`open_named`] and [`BlockDecoder::to_gaussians`], naming the file.
pub fn read_gaussians_file(path: &Path) -> Result<(Gaussians, Format)> {
    with_mapped_file(path, |bytes| {
        let (decoder, format) = open_named(bytes, Some(path))?;
        Ok((decoder.to_gaussians()?, format))
    })
}

/// Reads a 3DGS file of any format at full precision.
///
/// # Errors
///
/// `path` is missing, a directory or no regular file, or cannot be read; otherwise as
/// [`open_named`] and [`BlockDecoder::to_table`], naming the file.
pub fn read_table_file(path: &Path) -> Result<(SplatTable, Format)> {
    with_mapped_file(path, |bytes| {
        let (decoder, format) = open_named(bytes, Some(path))?;
        Ok((decoder.to_table()?, format))
    })
}

/// Writes `src` to `path` in `format`, atomically (temporary file, then rename).
///
/// # Errors
///
/// A format sage3d only reads, or the write error.
pub fn write_file(path: &Path, src: &impl SplatSource, format: Format) -> Result<()> {
    if !format.writable() {
        return Err(Error::invalid(format!(
            "{}: sage3d reads {format} but does not write it (write ply, compressed-ply or spz)",
            path.display()
        )));
    }
    sage_io::files::write_atomic(path, |w| match format {
        Format::Ply(SplatLayout::Standard) => ply::standard::write(w, src),
        Format::Ply(SplatLayout::Compressed) => ply::compressed::write(w, src),
        _ => spz::write(w, src),
    })
}
