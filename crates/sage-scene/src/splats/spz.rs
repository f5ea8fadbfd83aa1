//! SPZ (Niantic): Gaussians quantised to a few bytes each, in per-attribute arrays, compressed.
//!
//! # Versions and containers
//!
//! Every version stores the same header fields — magic `0x5053474e` (`"NGSP"` on disk),
//! `version`, `numPoints`, `shDegree`, `fractionalBits`, `flags` (bit 0 antialiased, bit 1
//! extensions present) — and then six arrays, each over all Gaussians in file order:
//!
//! | array | bytes per Gaussian | encoding |
//! |---|---|---|
//! | positions | 9 (v1: 6) | x y z as 24-bit little-endian two's complement fixed point with `fractionalBits` fraction bits (v1: float16) |
//! | alphas | 1 | `round(sigmoid(opacity) · 255)` |
//! | colors | 3 | `round(f_dc · 0.15 · 255 + 127.5)` (0.15, not `SH_C0`, leaves room for colours out of range) |
//! | scales | 3 | `round((log_scale + 10) · 16)` |
//! | rotations | 4 (v1, v2: 3) | v3+: "smallest three": 2-bit index of the largest component, then for the other three in xyzw order a sign bit and a 9-bit magnitude of `|q_i| / √½`; the largest is rebuilt from the unit norm. v1/v2: x y z as `round(q_i · 127.5 + 127.5)` with the sign chosen so that `w ≥ 0`, `w` rebuilt |
//! | sh | 3 × (0, 3, 8, 15 or 24) | `(coeff · 128) + 128`, coefficient-major (for each coefficient R, G, B); degree-1 codes rounded to multiples of 8, higher degrees to multiples of 16 |
//!
//! Each code is clamped to 0–255. Versions 1–3 gzip the whole stream: a 16-byte header
//! (`magic u32, version u32, numPoints u32, shDegree u8, fractionalBits u8, flags u8,
//! reserved u8`) followed by the arrays. Version 4 (PlayCanvas `splat-transform` 2.7's default,
//! written through Niantic's library) is not gzipped: a plain 32-byte header (the same fields,
//! then `numStreams u8, tocByteOffset u32, reserved[12]`), optional extension records up to
//! `tocByteOffset`, a table of contents of `numStreams` × (`compressedSize u64,
//! uncompressedSize u64`), then each non-empty array as its own Zstandard frame, decoded and
//! written with the `ruzstd` crate.
//!
//! Sources: `nianticlabs/spz` `src/cc/load-spz.cc`, `splat-types.h` (read through the code
//! index, versions from 2024 to the version-4 one) and `playcanvas/splat-transform`
//! `src/lib/spz-module.ts`, `write-spz.ts`; the field encodings were checked byte for byte against
//! `testdata/splats/*.spz` and the tool's own decodings of them.
//!
//! # Coordinates
//!
//! SPZ stores RUB (x right, y up, z back); PLY — and sage3d's [`Gaussian`] — is RDF.
//! `splat-transform` converts on both sides (`from`/`to: RDF` in Niantic's library), so a
//! reader that matches it negates y and z of positions, negates the y and z components of the
//! rotation quaternion (x and w unchanged) and negates each higher-order SH coefficient whose
//! basis function changes sign when y and z do (`FLIP_SH` below). The writer applies the same
//! flips in reverse.
//!
//! # Reading
//!
//! [`SpzDecoder::open`] reads versions 1–3 gzipped (also ungzipped, as older `splat-transform`
//! readers accept) and version 4, validates every count against the bytes present before it
//! allocates, and keeps the byte codes; [`BlockDecoder::decode`] expands them as the reference
//! does, in `f32`, with two deliberate differences: alpha codes 0 and 255, whose logits are ∓∞
//! in the reference, become ∓[`MAX_LOGIT`] (as the PLY reader keeps them finite), and a damaged
//! smallest-three rotation whose three stored components exceed unit norm rebuilds its largest
//! component as 0 rather than NaN. SH degree 4 (24 coefficients, newer than sage3d's model) is
//! read with the fourth band dropped. Extension records (flag bit 1) are skipped in version 4;
//! a gzipped file that declares them is refused, because their position in the stream changed
//! between releases of the reference library.
//!
//! # Writing
//!
//! [`write()`] writes version 3: gzip, smallest-three rotations. Version 4 differs from it only in
//! the container (Zstandard per array), not in any code; version 3 is read by `splat-transform`
//! 2.7 and Niantic's library, and also by every reader that predates version 4 (gzip makes the
//! files about 1.15 times the size of the tool's). [`write_version`] writes version 2, 3 or 4
//! (Zstandard frames at `ruzstd`'s fastest level) on request. Codes are computed exactly as the reference packer does
//! (`f32`, round half away from zero, clamp to 0–255; SH buckets of 8 and 16), so what is lost
//! on writing is:
//!
//! | field | step | range |
//! |---|---|---|
//! | position | 2^−12 m ≈ 0.24 mm | ±2048 m |
//! | log-scale | 1/16 | −10 … 5.94 |
//! | opacity | 1/255 after the sigmoid | 0 … 1 |
//! | `f_dc` | 1/38.25 ≈ 0.026 | ±3.33 |
//! | rotation (v3, v4) | √½/511 ≈ 0.0014 per component | unit quaternion |
//! | rotation (v2) | 1/127.5 per component | unit quaternion |
//! | SH degree 1 | 0.0625 | −1 … 0.99 |
//! | SH degrees 2–3 | 0.125 | −1 … 0.99 |
//!
//! Scenes larger than ±2048 m get fewer fraction bits (one fewer per doubling; the reference
//! writer would wrap such positions around instead). Decoding a file the reference wrote and
//! writing it again reproduces its codes exactly: for that, a rotation that is exactly the
//! decoding of a smallest-three code is given that code back (the reference packer re-packs
//! about 1 in 1000 of them around another component, because the rebuilt largest component can
//! come out just below a stored one), and a stored −0 keeps its sign bit (the reference tests
//! `< 0`). Neither rule changes the code of any other input.

use crate::gaussians::Gaussian;
use crate::splats::{BLOCK, BlockDecoder, SplatSource, check_finite};
use glam::{Quat, Vec3};
use half::f16;
use rayon::prelude::*;
use sage_core::{Error, Result};
use std::fmt;
use std::io::{self, Read, Write};

/// `"NGSP"` read as a little-endian `u32`.
const NGSP_MAGIC: u32 = 0x5053_474e;
/// The first two bytes of a gzip member.
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];
/// The header of versions 1–3.
const LEGACY_HEADER: usize = 16;
/// The header of version 4.
const NGSP_HEADER: usize = 32;
/// The newest version read.
const LATEST_VERSION: u32 = 4;
/// The version [`write()`] writes (see the module docs for why not 4).
pub const WRITE_VERSION: u32 = 3;
/// Header flag: the scene was trained with antialiasing (mip-splatting).
const FLAG_ANTIALIASED: u8 = 0x1;
/// Header flag: extension records follow the header.
const FLAG_EXTENSIONS: u8 = 0x2;
/// Beyond this, `2^-fractionalBits` is not a meaningful step of a 24-bit coordinate.
const MAX_FRACTIONAL_BITS: u8 = 31;
/// The fraction bits the reference writer always uses (≈ 0.24 mm).
const FRACTIONAL_BITS: u8 = 12;
/// The DC colour scale of SPZ (the reference's `colorScale`).
const COLOR_SCALE: f32 = 0.15;
/// √½ as the reference spells it (`(float)0.7071067811865475`).
const SQRT1_2: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// The largest 9-bit magnitude of a smallest-three component.
const MAG_MASK: u32 = (1 << 9) - 1;
/// The SH bucket of degree-1 codes (5 significant bits, `sh1Bits = 5`).
const SH1_BUCKET: i32 = 1 << (8 - 5);
/// The SH bucket of degree-2 and higher codes (`shRestBits = 4`).
const SH_REST_BUCKET: i32 = 1 << (8 - 4);
/// The opacity logit stored for alpha codes 0 and 255 (the PLY reader's bound: sigmoid(±20) is
/// within 2e-9 of 0 or 1, and encodes back to the same code).
pub const MAX_LOGIT: f32 = 20.0;
/// Sign of each higher-order SH coefficient (coefficient-major order) between RDF and RUB: the
/// reference's `flipSh` for flips (x, y, z) = (+1, −1, −1).
const FLIP_SH: [f32; 15] = [
    -1.0, -1.0, 1.0, // degree 1: y, z, x
    -1.0, 1.0, 1.0, -1.0, 1.0, // degree 2: xy, yz, 1, xz, 1
    -1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0, // degree 3: y, xyz, y, z, x, z, x
];
/// A declared size is plausible when its attributes take at most this many bytes per byte of
/// the file: real SPZ arrays compress 2–4 : 1, so this only refuses bombs and lying headers.
const MAX_EXPANSION: usize = 64;
/// Below this, any declared size is allowed whatever the file size (small, highly compressible
/// scenes).
const MIN_BUDGET: usize = 64 << 20;

/// The names of the six arrays, in file order (also the stream order of version 4).
const ARRAYS: [&str; 6] = ["positions", "alphas", "colors", "scales", "rotations", "sh"];
const POSITIONS: usize = 0;
const ALPHAS: usize = 1;
const COLORS: usize = 2;
const SCALES: usize = 3;
const ROTATIONS: usize = 4;
const SH: usize = 5;

/// The number of higher-order SH coefficients per channel of a stored degree (0–4).
fn stored_sh_count(degree: u8) -> usize {
    match degree {
        0 => 0,
        1 => 3,
        2 => 8,
        3 => 15,
        _ => 24,
    }
}

/// The header fields every version shares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Header {
    version: u32,
    count: usize,
    degree: u8,
    fractional_bits: u8,
    flags: u8,
}

impl Header {
    /// Bytes per Gaussian of each array, in file order.
    fn strides(&self) -> [usize; 6] {
        [
            if self.version == 1 { 6 } else { 9 },
            1,
            3,
            3,
            if self.version >= 3 { 4 } else { 3 },
            stored_sh_count(self.degree) * 3,
        ]
    }

    /// Checks the fields that bound what follows; the count is checked against the bytes by
    /// [`Header::sizes`].
    fn validate(&self) -> Result<()> {
        if self.version == 0 || self.version > LATEST_VERSION {
            return Err(Error::format(
                "spz.header.version",
                format!(
                    "version {} is not one this reader knows (1–{LATEST_VERSION})",
                    self.version
                ),
            ));
        }
        if self.degree > 4 {
            return Err(Error::format(
                "spz.header.shDegree",
                format!("SH degree {} is not one SPZ defines (0–4)", self.degree),
            ));
        }
        if self.fractional_bits > MAX_FRACTIONAL_BITS {
            return Err(Error::format(
                "spz.header.fractionalBits",
                format!(
                    "{} fraction bits in a 24-bit coordinate (at most {MAX_FRACTIONAL_BITS})",
                    self.fractional_bits
                ),
            ));
        }
        Ok(())
    }

    /// The byte size of each array, after checking that the declared count is plausible for a
    /// file of `input_len` bytes (so that nothing is allocated from a lying header).
    fn sizes(&self, input_len: usize) -> Result<[usize; 6]> {
        let overflow = || {
            Error::format(
                "spz.header.numPoints",
                format!("{} Gaussians overflow the address space", self.count),
            )
        };
        let mut sizes = [0usize; 6];
        let mut total = 0usize;
        for (size, stride) in sizes.iter_mut().zip(self.strides()) {
            *size = self.count.checked_mul(stride).ok_or_else(overflow)?;
            total = total.checked_add(*size).ok_or_else(overflow)?;
        }
        let budget = input_len.saturating_mul(MAX_EXPANSION).max(MIN_BUDGET);
        if total > budget {
            return Err(Error::format(
                "spz.header.numPoints",
                format!(
                    "{} Gaussians of SH degree {} need {total} bytes of attributes, more than a \
                     {input_len}-byte file can hold (at most {MAX_EXPANSION}:1 expansion)",
                    self.count, self.degree
                ),
            ));
        }
        Ok(sizes)
    }
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let bytes = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(bytes.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    let bytes = b.get(at..at.checked_add(8)?)?;
    Some(u64::from_le_bytes(bytes.try_into().ok()?))
}

/// Parses the 16 bytes every version begins its (decompressed) stream with.
fn legacy_header(b: &[u8; LEGACY_HEADER]) -> Result<Header> {
    let magic = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    if magic != NGSP_MAGIC {
        return Err(Error::format(
            "spz.header.magic",
            format!("found {magic:#010x}, expected {NGSP_MAGIC:#010x} (\"NGSP\")"),
        ));
    }
    let header = Header {
        version: u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
        count: u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize,
        degree: b[12],
        fractional_bits: b[13],
        flags: b[14],
    };
    header.validate()?;
    if header.flags & FLAG_EXTENSIONS != 0 {
        // Releases of the reference library put extension records before the arrays, later ones
        // after them; without knowing which wrote the file the arrays cannot be located.
        return Err(Error::format(
            "spz.header.flags",
            "gzipped SPZ with extension records (flag 0x2) is not supported",
        ));
    }
    Ok(header)
}

/// An SPZ file opened for decoding: the header and the six arrays of byte codes.
pub struct SpzDecoder {
    header: Header,
    /// Bytes per Gaussian of each array ([`Header::strides`]).
    strides: [usize; 6],
    /// The arrays in file order, each exactly `count × stride` bytes.
    arrays: [Vec<u8>; 6],
}

impl fmt::Debug for SpzDecoder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SpzDecoder")
            .field("version", &self.header.version)
            .field("count", &self.header.count)
            .field("sh_degree", &self.header.degree)
            .field("fractional_bits", &self.header.fractional_bits)
            .field("flags", &self.header.flags)
            .finish_non_exhaustive()
    }
}

impl SpzDecoder {
    /// Opens an SPZ file held in memory: unpacks the container and checks every count.
    ///
    /// # Errors
    ///
    /// Not SPZ, an unknown version, a count or SH degree the data does not hold, a damaged gzip
    /// or Zstandard stream, or a declared size no file of this length can plausibly hold.
    pub fn open(bytes: &[u8]) -> Result<SpzDecoder> {
        if bytes.starts_with(&GZIP_MAGIC) {
            Self::open_gzip(bytes)
        } else if u32_at(bytes, 0) == Some(NGSP_MAGIC) {
            match u32_at(bytes, 4) {
                Some(v) if v >= 4 => Self::open_ngsp(bytes),
                // An ungzipped legacy stream: not what the reference writes, but older
                // `splat-transform` readers accept it.
                _ => {
                    let head = bytes.get(..LEGACY_HEADER).ok_or_else(|| {
                        Error::format(
                            "spz.header",
                            format!("{} bytes, the header needs {LEGACY_HEADER}", bytes.len()),
                        )
                    })?;
                    let mut h = [0u8; LEGACY_HEADER];
                    h.copy_from_slice(head);
                    let header = legacy_header(&h)?;
                    Self::split_legacy(header, &bytes[LEGACY_HEADER..], bytes.len())
                }
            }
        } else {
            Err(Error::format(
                "spz.header.magic",
                "not an SPZ file (neither gzip nor \"NGSP\")",
            ))
        }
    }

    /// Versions 1–3: a gzip member holding the header and the arrays.
    fn open_gzip(bytes: &[u8]) -> Result<SpzDecoder> {
        let gzip = |e: io::Error| Error::format("spz.gzip", format!("damaged gzip stream: {e}"));
        let mut inflate = flate2::bufread::GzDecoder::new(bytes);
        let mut h = [0u8; LEGACY_HEADER];
        inflate.read_exact(&mut h).map_err(gzip)?;
        let header = legacy_header(&h)?;
        let expected: usize = header.sizes(bytes.len())?.iter().sum();
        // Inflate one byte more than the arrays need: more data means a wrong count, and
        // stopping there bounds what a gzip bomb can make us allocate. The buffer grows as data
        // arrives, so a lying header in a small file reserves little.
        let mut payload = Vec::with_capacity(expected.min(bytes.len().saturating_mul(16)));
        inflate
            .take(expected as u64 + 1)
            .read_to_end(&mut payload)
            .map_err(gzip)?;
        Self::split_legacy(header, &payload, bytes.len())
    }

    /// Splits the arrays of versions 1–3, which must fill `payload` exactly.
    fn split_legacy(header: Header, payload: &[u8], input_len: usize) -> Result<SpzDecoder> {
        let sizes = header.sizes(input_len)?;
        let expected: usize = sizes.iter().sum();
        if payload.len() != expected {
            // Name the first array the data does not hold (or the surplus).
            let mut at = 0usize;
            for (name, size) in ARRAYS.iter().zip(sizes) {
                if payload.len() < at + size {
                    return Err(Error::format(
                        format!("spz.{name}"),
                        format!(
                            "numPoints {} (SH degree {}) needs {expected} bytes after the header; \
                             the stream holds {} ({name} is cut short)",
                            header.count,
                            header.degree,
                            payload.len()
                        ),
                    ));
                }
                at += size;
            }
            return Err(Error::format(
                "spz.header.numPoints",
                format!(
                    "numPoints {} (SH degree {}) needs {expected} bytes after the header; the \
                     stream holds more",
                    header.count, header.degree
                ),
            ));
        }
        let mut arrays: [Vec<u8>; 6] = Default::default();
        let mut at = 0usize;
        for (array, size) in arrays.iter_mut().zip(sizes) {
            *array = payload[at..at + size].to_vec();
            at += size;
        }
        Ok(SpzDecoder {
            header,
            strides: header.strides(),
            arrays,
        })
    }

    /// Version 4: a plain header, a table of contents and one Zstandard frame per array.
    fn open_ngsp(bytes: &[u8]) -> Result<SpzDecoder> {
        let head = bytes.get(..NGSP_HEADER).ok_or_else(|| {
            Error::format(
                "spz.header",
                format!(
                    "{} bytes, the version-4 header needs {NGSP_HEADER}",
                    bytes.len()
                ),
            )
        })?;
        let header = Header {
            version: u32_at(head, 4).unwrap_or(0),
            count: u32_at(head, 8).unwrap_or(0) as usize,
            degree: head[12],
            fractional_bits: head[13],
            flags: head[14],
        };
        header.validate()?;
        let streams = usize::from(head[15]);
        let toc = u32_at(head, 16).unwrap_or(0) as usize;
        let sizes = header.sizes(bytes.len())?;
        // The writer skips empty arrays (SH at degree 0, everything when there is no Gaussian).
        let present: Vec<usize> = (0..6).filter(|&a| sizes[a] > 0).collect();
        if streams != present.len() {
            return Err(Error::format(
                "spz.header.numStreams",
                format!(
                    "{streams} streams, but {} Gaussians of SH degree {} have {} non-empty arrays",
                    header.count,
                    header.degree,
                    present.len()
                ),
            ));
        }
        let toc_end = toc
            .checked_add(streams * 16)
            .filter(|&end| toc >= NGSP_HEADER && end <= bytes.len())
            .ok_or_else(|| {
                Error::format(
                    "spz.header.tocByteOffset",
                    format!(
                        "table of contents at {toc} ({streams} entries) does not lie between \
                         the header and the end of the {}-byte file",
                        bytes.len()
                    ),
                )
            })?;
        let mut frames = Vec::with_capacity(streams);
        let mut at = toc_end;
        for (entry, &a) in present.iter().enumerate() {
            let e = toc + entry * 16;
            let compressed = u64_at(bytes, e).unwrap_or(u64::MAX);
            let uncompressed = u64_at(bytes, e + 8).unwrap_or(u64::MAX);
            let name = ARRAYS[a];
            if uncompressed != sizes[a] as u64 {
                return Err(Error::format(
                    format!("spz.{name}"),
                    format!(
                        "stream holds {uncompressed} bytes, numPoints {} needs {}",
                        header.count, sizes[a]
                    ),
                ));
            }
            let end = usize::try_from(compressed)
                .ok()
                .and_then(|c| at.checked_add(c))
                .filter(|&end| end <= bytes.len())
                .ok_or_else(|| {
                    Error::format(
                        format!("spz.{name}"),
                        format!(
                            "{compressed} compressed bytes at {at} run past the end of the \
                             {}-byte file",
                            bytes.len()
                        ),
                    )
                })?;
            frames.push((a, &bytes[at..end]));
            at = end;
        }
        if at != bytes.len() {
            return Err(Error::format(
                "spz.streams",
                format!("{} bytes after the last stream", bytes.len() - at),
            ));
        }
        let decoded = frames
            .par_iter()
            .map(|&(a, frame)| {
                zstd::decompress(frame, sizes[a]).map_err(|why| {
                    Error::format(
                        format!("spz.{}", ARRAYS[a]),
                        format!("damaged Zstandard stream: {why}"),
                    )
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut arrays: [Vec<u8>; 6] = Default::default();
        for ((a, _), data) in frames.iter().zip(decoded) {
            arrays[*a] = data;
        }
        Ok(SpzDecoder {
            header,
            strides: header.strides(),
            arrays,
        })
    }

    /// The format version of the file (1–4).
    pub fn version(&self) -> u32 {
        self.header.version
    }

    /// Whether the header marks the scene as trained with antialiasing (mip-splatting).
    pub fn antialiased(&self) -> bool {
        self.header.flags & FLAG_ANTIALIASED != 0
    }

    /// The fraction bits of the 24-bit fixed-point positions.
    pub fn fractional_bits(&self) -> u8 {
        self.header.fractional_bits
    }

    /// The SH degree as stored (0–4; [`BlockDecoder::sh_degree`] reports at most 3).
    pub fn stored_sh_degree(&self) -> u8 {
        self.header.degree
    }

    /// The bytes of array `a` that belong to Gaussian `i` (`i < count`, checked by callers).
    fn codes(&self, a: usize, i: usize) -> &[u8] {
        let stride = self.strides[a];
        &self.arrays[a][i * stride..(i + 1) * stride]
    }

    /// Gaussian `i`, expanded as the reference reader expands it, in PLY (RDF) axes.
    fn gaussian(&self, i: usize) -> Gaussian {
        let p = self.codes(POSITIONS, i);
        let raw: [f32; 3] = if self.header.version == 1 {
            std::array::from_fn(|k| {
                f16::from_bits(u16::from_le_bytes([p[2 * k], p[2 * k + 1]])).to_f32()
            })
        } else {
            let scale = 1.0 / (1u32 << self.header.fractional_bits) as f32;
            std::array::from_fn(|k| fixed24([p[3 * k], p[3 * k + 1], p[3 * k + 2]]) as f32 * scale)
        };
        let s = self.codes(SCALES, i);
        let c = self.codes(COLORS, i);
        let r = self.codes(ROTATIONS, i);
        let [x, y, z, w] = match *r {
            [a, b, c, d] => unpack_smallest_three([a, b, c, d]),
            [a, b, c] => unpack_first_three([a, b, c]),
            _ => [0.0, 0.0, 0.0, 1.0],
        };
        let alpha = f32::from(self.codes(ALPHAS, i)[0]) / 255.0;
        let mut sh_rest = [[0.0f32; 3]; 15];
        for (k, rgb) in self.codes(SH, i).chunks_exact(3).take(15).enumerate() {
            for (out, &code) in sh_rest[k].iter_mut().zip(rgb) {
                *out = (f32::from(code) - 128.0) / 128.0 * FLIP_SH[k];
            }
        }
        Gaussian {
            position: Vec3::new(raw[0], -raw[1], -raw[2]),
            rotation: Quat::from_xyzw(x, -y, -z, w),
            log_scale: Vec3::from_array(std::array::from_fn(|k| f32::from(s[k]) / 16.0 - 10.0)),
            opacity_logit: (alpha / (1.0 - alpha)).ln().clamp(-MAX_LOGIT, MAX_LOGIT),
            sh_dc: std::array::from_fn(|k| ((f32::from(c[k]) / 255.0) - 0.5) / COLOR_SCALE),
            sh_rest,
            instance: 0,
        }
    }
}

impl BlockDecoder for SpzDecoder {
    fn len(&self) -> usize {
        self.header.count
    }

    fn sh_degree(&self) -> u8 {
        self.header.degree.min(3)
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        match start.checked_add(out.len()) {
            Some(end) if end <= self.header.count => {}
            _ => {
                return Err(Error::invalid(format!(
                    "SPZ Gaussians {start}..{} requested of {}",
                    start.saturating_add(out.len()),
                    self.header.count
                )));
            }
        }
        for (j, g) in out.iter_mut().enumerate() {
            *g = self.gaussian(start + j);
        }
        Ok(())
    }
}

/// A 24-bit little-endian two's complement value.
fn fixed24(b: [u8; 3]) -> i32 {
    (i32::from(b[0]) | i32::from(b[1]) << 8 | i32::from(b[2]) << 16) << 8 >> 8
}

/// Versions 3+: the largest component's index, then three 10-bit (sign, 9-bit magnitude)
/// fields for the others in xyzw order, the last one lowest. Returns x, y, z, w.
fn unpack_smallest_three(r: [u8; 4]) -> [f32; 4] {
    let mut comp = u32::from_le_bytes(r);
    let largest = (comp >> 30) as usize;
    let mut q = [0.0f32; 4];
    let mut sum_squares = 0.0f32;
    for i in (0..4).rev() {
        if i != largest {
            let magnitude = comp & MAG_MASK;
            let negative = (comp >> 9) & 1 == 1;
            comp >>= 10;
            let v = SQRT1_2 * magnitude as f32 / MAG_MASK as f32;
            q[i] = if negative { -v } else { v };
            sum_squares += q[i] * q[i];
        }
    }
    // A valid encoder keeps the three below unit norm; damaged data must not make NaN.
    q[largest] = (1.0 - sum_squares).max(0.0).sqrt();
    q
}

/// Versions 1–2: x, y, z in steps of 1/127.5, w ≥ 0 rebuilt. Returns x, y, z, w.
fn unpack_first_three(r: [u8; 3]) -> [f32; 4] {
    let [x, y, z] = r.map(|b| f32::from(b) * (1.0 / 127.5) - 1.0);
    [x, y, z, (1.0 - (x * x + y * y + z * z)).max(0.0).sqrt()]
}

/// True when `bytes` is an SPZ file: a gzip member whose content begins with `"NGSP"`, or a
/// plain `"NGSP"` header (version 4, or an ungzipped legacy stream).
pub fn sniff(bytes: &[u8]) -> bool {
    if u32_at(bytes, 0) == Some(NGSP_MAGIC) {
        return true;
    }
    if !bytes.starts_with(&GZIP_MAGIC) {
        return false;
    }
    let mut magic = [0u8; 4];
    flate2::bufread::GzDecoder::new(bytes)
        .read_exact(&mut magic)
        .is_ok()
        && u32::from_le_bytes(magic) == NGSP_MAGIC
}

/// Writes `src` as SPZ version [`WRITE_VERSION`] (3, gzip; see the module docs).
///
/// # Errors
///
/// More Gaussians than SPZ counts (2³² − 1), a position that is not finite or beyond ±8·10⁶ m,
/// a rotation that is zero or not finite, another value the scene store refuses
/// ([`check_finite`]), or the write error.
pub fn write(w: &mut impl Write, src: &impl SplatSource) -> io::Result<()> {
    write_version(w, src, WRITE_VERSION)
}

/// Writes `src` as SPZ `version` 2 (gzip, 3-byte rotations), 3 (gzip) or 4 (plain header,
/// Zstandard frames).
///
/// # Errors
///
/// Another version, or as [`write()`].
pub fn write_version(w: &mut impl Write, src: &impl SplatSource, version: u32) -> io::Result<()> {
    if !(2..=LATEST_VERSION).contains(&version) {
        return Err(invalid(format!(
            "SPZ version {version} cannot be written (2, 3 or 4)"
        )));
    }
    let (header, arrays) = pack(src, version)?;
    if version >= 4 {
        return write_ngsp(w, &header, &arrays);
    }
    let size = LEGACY_HEADER + arrays.iter().map(Vec::len).sum::<usize>();
    let mut stream = Vec::with_capacity(size);
    stream.extend_from_slice(&NGSP_MAGIC.to_le_bytes());
    stream.extend_from_slice(&header.version.to_le_bytes());
    stream.extend_from_slice(&(header.count as u32).to_le_bytes());
    stream.extend_from_slice(&[header.degree, header.fractional_bits, header.flags, 0]);
    for array in &arrays {
        stream.extend_from_slice(array);
    }
    w.write_all(&gzip(&stream)?)
}

/// The gzip member of `data`, deflated in parallel pieces as `pigz` does: each 1 MiB piece is
/// compressed on its own (at zlib's default level, as the reference) and ends in a sync flush,
/// which byte-aligns it so that the pieces join into one deflate stream. One member, because
/// the SPZ readers inflate only the first. (Level-6 deflate in pure Rust runs at about
/// 10 MB/s on one core: 7 s per million Gaussians of SH degree 3.)
fn gzip(data: &[u8]) -> io::Result<Vec<u8>> {
    const PIECE: usize = 1 << 20;
    let pieces: Vec<&[u8]> = if data.is_empty() {
        vec![data]
    } else {
        data.chunks(PIECE).collect()
    };
    let last = pieces.len() - 1;
    let deflated = pieces
        .par_iter()
        .enumerate()
        .map(|(i, piece)| deflate_piece(piece, i == last))
        .collect::<io::Result<Vec<_>>>()?;
    let mut out = Vec::with_capacity(18 + deflated.iter().map(Vec::len).sum::<usize>());
    // ID1 ID2, CM = deflate, no flags, no modification time, no extra flags, OS unknown.
    out.extend_from_slice(&[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff]);
    for piece in &deflated {
        out.extend_from_slice(piece);
    }
    let mut crc = flate2::Crc::new();
    crc.update(data);
    out.extend_from_slice(&crc.sum().to_le_bytes());
    // ISIZE: the length modulo 2^32.
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    Ok(out)
}

/// Raw deflate of one piece: ended by a sync flush, or by the final block when `last`.
fn deflate_piece(piece: &[u8], last: bool) -> io::Result<Vec<u8>> {
    use flate2::{Compress, Compression, FlushCompress, Status};
    let mut deflate = Compress::new(Compression::default(), false);
    let flush = if last {
        FlushCompress::Finish
    } else {
        FlushCompress::Sync
    };
    let mut out = Vec::with_capacity(piece.len() / 2 + 1024);
    loop {
        if out.capacity() - out.len() < 1024 {
            out.reserve(out.capacity().max(4096));
        }
        let (read, written) = (deflate.total_in(), deflate.total_out());
        let status = deflate
            .compress_vec(&piece[read as usize..], &mut out, flush)
            .map_err(io::Error::other)?;
        let all_read = deflate.total_in() as usize == piece.len();
        // A flush is complete when it leaves output space unused.
        if (last && status == Status::StreamEnd)
            || (!last && all_read && out.len() < out.capacity())
        {
            return Ok(out);
        }
        if (deflate.total_in(), deflate.total_out()) == (read, written) && status != Status::Ok {
            return Err(io::Error::other("deflate made no progress"));
        }
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Version 4: the plain header, the table of contents, one Zstandard frame per
/// non-empty array.
fn write_ngsp(w: &mut impl Write, header: &Header, arrays: &[Vec<u8>; 6]) -> io::Result<()> {
    let present: Vec<&Vec<u8>> = arrays.iter().filter(|a| !a.is_empty()).collect();
    let frames: Vec<Vec<u8>> = present.par_iter().map(|a| zstd::compress(a)).collect();
    let mut head = Vec::with_capacity(NGSP_HEADER + 16 * frames.len());
    head.extend_from_slice(&NGSP_MAGIC.to_le_bytes());
    head.extend_from_slice(&header.version.to_le_bytes());
    head.extend_from_slice(&(header.count as u32).to_le_bytes());
    head.extend_from_slice(&[
        header.degree,
        header.fractional_bits,
        header.flags,
        frames.len() as u8,
    ]);
    head.extend_from_slice(&(NGSP_HEADER as u32).to_le_bytes());
    head.extend_from_slice(&[0u8; 12]);
    for (frame, array) in frames.iter().zip(&present) {
        head.extend_from_slice(&(frame.len() as u64).to_le_bytes());
        head.extend_from_slice(&(array.len() as u64).to_le_bytes());
    }
    w.write_all(&head)?;
    for frame in &frames {
        w.write_all(frame)?;
    }
    Ok(())
}

/// The codes of every Gaussian of `src`, as the reference packer computes them.
fn pack(src: &impl SplatSource, version: u32) -> io::Result<(Header, [Vec<u8>; 6])> {
    let n = src.len();
    let degree = src.sh_degree();
    if degree > 3 {
        return Err(invalid(format!("SH degree {degree} (sage3d holds 0–3)")));
    }
    if u32::try_from(n).is_err() {
        return Err(invalid(format!(
            "{n} Gaussians; SPZ counts at most {}",
            u32::MAX
        )));
    }
    let header = Header {
        version,
        count: n,
        degree,
        fractional_bits: fractional_bits(src)?,
        flags: 0,
    };
    let strides = header.strides();
    let blocks: Vec<io::Result<[Vec<u8>; 6]>> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let range = b * BLOCK..((b + 1) * BLOCK).min(n);
            let rows: Vec<Gaussian> = range.clone().map(|i| src.get(i)).collect();
            // What the scene store refuses is refused here too, not quantised to some byte.
            check_finite(range.start, &rows).map_err(|e| invalid(e.to_string()))?;
            let mut arrays: [Vec<u8>; 6] =
                std::array::from_fn(|a| Vec::with_capacity(range.len() * strides[a]));
            for (i, g) in range.zip(&rows) {
                encode(g, i, &header, &mut arrays)?;
            }
            Ok(arrays)
        })
        .collect();
    // The first failing block, whatever the threads' order.
    let blocks = blocks.into_iter().collect::<io::Result<Vec<_>>>()?;
    let mut arrays: [Vec<u8>; 6] = std::array::from_fn(|a| Vec::with_capacity(n * strides[a]));
    for block in blocks {
        for (all, part) in arrays.iter_mut().zip(block) {
            all.extend_from_slice(&part);
        }
    }
    Ok((header, arrays))
}

/// The fraction bits of the positions [`write()`] gives `src`: the reference's 12 (steps of
/// 1/4096 m) for a scene within ±2048 m, one fewer per doubling beyond.
///
/// # Errors
///
/// A coordinate beyond what 24 bits hold even without fraction bits (±8388607 m).
pub fn position_fraction_bits(src: &impl SplatSource) -> Result<u8> {
    fractional_bits(src).map_err(|e| Error::invalid(e.to_string()))
}

/// The fraction bits the writer uses when every position is within ±2048 m (steps of 1/4096 m).
pub const DEFAULT_FRACTION_BITS: u8 = FRACTIONAL_BITS;

/// The most fraction bits (at most the reference's 12) that keep every coordinate inside 24
/// bits; the reference always uses 12 and wraps coordinates beyond ±2048 m around.
fn fractional_bits(src: &impl SplatSource) -> io::Result<u8> {
    let (lo, hi) = (0..src.len())
        .into_par_iter()
        .map(|i| {
            let p = src.get(i).position;
            // The stored (RUB) coordinates. A non-finite one is left out of the span: `pack`
            // refuses it, with the scene store's message.
            [p.x, -p.y, -p.z]
                .into_iter()
                .filter(|c| c.is_finite())
                .fold((0.0f32, 0.0f32), |(a, b), c| (a.min(c), b.max(c)))
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    (0..=FRACTIONAL_BITS)
        .rev()
        .find(|&bits| {
            let scale = (1u32 << bits) as f32;
            (lo * scale).round() >= -8_388_608.0 && (hi * scale).round() <= 8_388_607.0
        })
        .ok_or_else(|| {
            invalid(format!(
                "a Gaussian lies {} m from the origin along an axis; SPZ's 24-bit coordinates reach ±8388607 m",
                lo.abs().max(hi)
            ))
        })
}

/// `round(x)` clamped to a byte, as the reference's `toUint8`.
fn to_u8(x: f32) -> u8 {
    x.round().clamp(0.0, 255.0) as u8
}

/// An SH coefficient as the reference quantises it: `round(x · 128) + 128`, rounded to the
/// nearest multiple of `bucket` (integer division towards zero), clamped to a byte.
fn quantize_sh(x: f32, bucket: i32) -> u8 {
    // Clamping first keeps the integer arithmetic in range and changes no result: every value
    // outside 0–255 clamps to 0 or 255 either way.
    let q = ((x * 128.0).round() + 128.0).clamp(-1024.0, 1024.0) as i32;
    ((q + bucket / 2) / bucket * bucket).clamp(0, 255) as u8
}

/// Appends the codes of Gaussian `g` (number `i`, for messages) to `arrays`.
fn encode(g: &Gaussian, i: usize, header: &Header, arrays: &mut [Vec<u8>; 6]) -> io::Result<()> {
    let scale = (1u32 << header.fractional_bits) as f32;
    let flips = [1.0f32, -1.0, -1.0];
    for (v, flip) in g.position.to_array().into_iter().zip(flips) {
        let fixed = ((v * scale) * flip).round() as i32;
        arrays[POSITIONS].extend_from_slice(&fixed.to_le_bytes()[..3]);
    }
    let alpha = 1.0 / (1.0 + (-g.opacity_logit).exp());
    arrays[ALPHAS].push(to_u8(alpha * 255.0));
    for c in g.sh_dc {
        arrays[COLORS].push(to_u8(c * (COLOR_SCALE * 255.0) + 0.5 * 255.0));
    }
    for s in g.log_scale.to_array() {
        arrays[SCALES].push(to_u8((s + 10.0) * 16.0));
    }
    // One of tiny or huge components, whose squared length underflows or overflows, is
    // normalised first.
    let rotation = if g.rotation.length_squared().is_normal() {
        g.rotation
    } else {
        crate::gaussians::unit_rotation(g.rotation).ok_or_else(|| {
            invalid(format!(
                "Gaussian {i}: rotation {} is zero or not finite",
                g.rotation
            ))
        })?
    };
    let [x, y, z, w] = rotation.to_array();
    let norm = (x * x + y * y + z * z + w * w).sqrt();
    // Normalised, then into RUB: y and z change sign, x and w do not.
    let q = [x / norm, -(y / norm), -(z / norm), w / norm];
    if header.version >= 3 {
        let code = pack_smallest_three(q, None);
        // A rotation that is exactly the decoding of a code gets that code back, even where
        // the reference packer would pick another largest component: after quantisation the
        // rebuilt largest one can come out just below another (about 1 in 1000 rotations), and
        // decoding and writing again must not change the file. No other input is affected.
        let stored = [x, -y, -z, w].map(f32::to_bits);
        let decodes_to_input = |c: [u8; 4]| unpack_smallest_three(c).map(f32::to_bits) == stored;
        let code = if decodes_to_input(code) {
            code
        } else {
            (0..4)
                .map(|largest| pack_smallest_three(q, Some(largest)))
                .find(|&c| decodes_to_input(c))
                .unwrap_or(code)
        };
        arrays[ROTATIONS].extend_from_slice(&code);
    } else {
        let s = if q[3] < 0.0 { -127.5 } else { 127.5 };
        for c in &q[..3] {
            arrays[ROTATIONS].push(to_u8(c * s + 127.5));
        }
    }
    for (k, rgb) in g
        .sh_rest
        .iter()
        .take(stored_sh_count(header.degree))
        .enumerate()
    {
        let bucket = if k < 3 { SH1_BUCKET } else { SH_REST_BUCKET };
        for &v in rgb {
            arrays[SH].push(quantize_sh(FLIP_SH[k] * v, bucket));
        }
    }
    Ok(())
}

/// The smallest-three code of a unit quaternion (x, y, z, w), as the reference packs it: the
/// first component of largest magnitude (or the `forced` one) is dropped, its sign folded into
/// the others.
fn pack_smallest_three(q: [f32; 4], forced: Option<usize>) -> [u8; 4] {
    let mut largest = 0;
    for (i, v) in q.iter().enumerate().skip(1) {
        if v.abs() > q[largest].abs() {
            largest = i;
        }
    }
    let largest = forced.unwrap_or(largest);
    let negate = q[largest] < 0.0;
    let mut comp = largest as u32;
    for (i, v) in q.iter().enumerate() {
        if i != largest {
            // The sign bit of −0 is kept (the reference tests `< 0`): a stored negative zero
            // decodes to −0 and must encode back to the same code.
            let negative = u32::from(v.is_sign_negative() ^ negate);
            // Truncation after adding ½, as the reference; a non-largest component of a unit
            // quaternion is at most √½, so the clamp only guards rounding.
            let magnitude = ((MAG_MASK as f32 * (v.abs() / SQRT1_2) + 0.5) as u32).min(MAG_MASK);
            comp = (comp << 10) | (negative << 9) | magnitude;
        }
    }
    comp.to_le_bytes()
}

/// The Zstandard frames of SPZ version 4, through the `ruzstd` crate (pure Rust): decoded into
/// exactly the size the table of contents declares, written at its fastest level.
mod zstd {
    use std::io::Read;

    /// The content of one frame, which must be `size` bytes (already checked against the file).
    pub fn decompress(frame: &[u8], size: usize) -> Result<Vec<u8>, String> {
        let mut source = frame;
        let decoder = ruzstd::decoding::StreamingDecoder::new(&mut source)
            .map_err(|e| format!("not a Zstandard frame: {e}"))?;
        let mut out = Vec::with_capacity(size);
        // One byte more than declared is read, so a frame that holds more is seen, not cut.
        decoder
            .take(size as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| format!("damaged Zstandard frame: {e}"))?;
        if out.len() != size {
            return Err(format!(
                "the frame holds {}{} bytes where the table of contents says {size}",
                out.len().min(size),
                if out.len() > size { "+" } else { "" }
            ));
        }
        Ok(out)
    }

    /// `data` as one frame.
    pub fn compress(data: &[u8]) -> Vec<u8> {
        ruzstd::encoding::compress_to_vec(data, ruzstd::encoding::CompressionLevel::Fastest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splats::SplatTable;
    use glam::Vec4;
    use proptest::prelude::*;
    use std::sync::LazyLock;
    use std::time::{Duration, Instant};

    fn testdata(name: &str) -> Vec<u8> {
        let path = format!(
            "{}/../../testdata/splats/{name}",
            env!("CARGO_MANIFEST_DIR")
        );
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    static SH3: LazyLock<Vec<u8>> = LazyLock::new(|| testdata("random_4k_sh3.spz"));
    static SH0: LazyLock<Vec<u8>> = LazyLock::new(|| testdata("random_3k_sh0.spz"));
    /// The SH-3 scene rewritten as version 3 (gzip).
    static SH3_V3: LazyLock<Vec<u8>> = LazyLock::new(|| {
        let table = SpzDecoder::open(&SH3).unwrap().to_table().unwrap();
        let mut out = Vec::new();
        write_version(&mut out, &table, 3).unwrap();
        out
    });
    /// The decompressed stream of [`SH3_V3`].
    static SH3_V3_RAW: LazyLock<Vec<u8>> = LazyLock::new(|| inflate(&SH3_V3));

    fn inflate(gz: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(gz)
            .read_to_end(&mut out)
            .unwrap();
        out
    }

    fn deflate(raw: &[u8]) -> Vec<u8> {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(raw).unwrap();
        gz.finish().unwrap()
    }

    /// The Gaussians of a standard PLY at full precision, and the SH degree.
    fn ply_gaussians(bytes: &[u8]) -> (Vec<Gaussian>, u8) {
        let table = crate::splats::test_files::standard_table(bytes);
        (table.gaussians, table.sh_degree)
    }

    /// Opens `bytes` and decodes every Gaussian if it opens (the fuzz tests fail only on a
    /// panic); true when both succeed.
    fn exercise(bytes: &[u8]) -> bool {
        match SpzDecoder::open(bytes) {
            Ok(d) => {
                let _ = sniff(bytes);
                d.to_table().is_ok()
            }
            Err(_) => false,
        }
    }

    fn check_against_reference(name: &str) {
        let decoder = SpzDecoder::open(&testdata(name)).unwrap();
        assert_eq!(decoder.version(), 4);
        assert!(!decoder.antialiased());
        let table = decoder.to_table().unwrap();
        let (reference, degree) = ply_gaussians(&testdata(&format!("{name}.decoded.ply")));
        assert_eq!(table.sh_degree, degree);
        assert_eq!(table.gaussians.len(), reference.len());
        let k = crate::gaussians::sh_rest_count(degree);
        // Largest differences: position, rotation, log-scale, opacity logit (relative), f_dc, f_rest.
        let mut worst = [0.0f32; 6];
        let mut saturated = 0;
        for (g, r) in table.gaussians.iter().zip(&reference) {
            let d = |a: f32, b: f32| (a - b).abs();
            worst[0] = worst[0].max((g.position - r.position).abs().max_element());
            worst[1] = worst[1].max(
                (Vec4::from(g.rotation) - Vec4::from(r.rotation))
                    .abs()
                    .max_element(),
            );
            worst[2] = worst[2].max((g.log_scale - r.log_scale).abs().max_element());
            if r.opacity_logit.is_infinite() {
                // The reference keeps alpha codes 0 and 255 as ∓∞; sage3d as ∓MAX_LOGIT.
                assert_eq!(g.opacity_logit, MAX_LOGIT.copysign(r.opacity_logit));
                saturated += 1;
            } else {
                let rel = d(g.opacity_logit, r.opacity_logit) / r.opacity_logit.abs().max(1.0);
                worst[3] = worst[3].max(rel);
            }
            for c in 0..3 {
                worst[4] = worst[4].max(d(g.sh_dc[c], r.sh_dc[c]));
            }
            for (j, (a, b)) in g.sh_rest.iter().zip(&r.sh_rest).enumerate() {
                for c in 0..3 {
                    worst[5] = worst[5].max(d(a[c], b[c]));
                    if j >= k {
                        assert_eq!(a[c], 0.0);
                    }
                }
            }
        }
        println!(
            "{name}: max |error| position {:e}, rotation {:e}, log-scale {:e}, opacity logit \
             (relative) {:e}, f_dc {:e}, f_rest {:e}; {saturated} saturated alphas",
            worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
        );
        for w in worst {
            assert!(w <= 1e-5, "{name}: {worst:?}");
        }
    }

    #[test]
    fn decodes_as_the_reference_tool_sh3() {
        check_against_reference("random_4k_sh3.spz");
    }

    #[test]
    fn decodes_as_the_reference_tool_sh0() {
        check_against_reference("random_3k_sh0.spz");
    }

    #[test]
    fn writer_reproduces_the_reference_codes() {
        // The reference files were written from these PLYs, in the same order.
        for (ply, spz) in [
            ("random_4k_sh3.ply", "random_4k_sh3.spz"),
            ("random_3k_sh0.ply", "random_3k_sh0.spz"),
        ] {
            let (gaussians, sh_degree) = ply_gaussians(&testdata(ply));
            let table = SplatTable {
                gaussians,
                sh_degree,
            };
            let (header, arrays) = pack(&table, 4).unwrap();
            let reference = SpzDecoder::open(&testdata(spz)).unwrap();
            assert_eq!(header, reference.header);
            for (a, name) in ARRAYS.iter().enumerate() {
                let differing = arrays[a]
                    .iter()
                    .zip(&reference.arrays[a])
                    .filter(|(x, y)| x != y)
                    .count();
                println!(
                    "{spz}: {name}: {differing} of {} codes differ",
                    arrays[a].len()
                );
                assert_eq!(arrays[a].len(), reference.arrays[a].len());
                assert_eq!(differing, 0, "{spz}: {name}");
            }
        }
    }

    #[test]
    fn decode_write_decode_keeps_every_code() {
        for bytes in [&*SH3, &*SH0] {
            let decoder = SpzDecoder::open(bytes).unwrap();
            let table = decoder.to_table().unwrap();
            for version in [3, 4] {
                let mut out = Vec::new();
                write_version(&mut out, &table, version).unwrap();
                let again = SpzDecoder::open(&out).unwrap();
                assert_eq!(again.version(), version);
                assert_eq!(again.header.count, decoder.header.count);
                assert_eq!(again.header.degree, decoder.header.degree);
                assert_eq!(again.header.fractional_bits, decoder.header.fractional_bits);
                for (a, name) in ARRAYS.iter().enumerate() {
                    assert!(
                        again.arrays[a] == decoder.arrays[a],
                        "version {version}: {name}"
                    );
                }
                assert_eq!(again.to_table().unwrap(), table);
                assert!(sniff(&out));
            }
            // The default is version 3, gzipped.
            let mut out = Vec::new();
            write(&mut out, &table).unwrap();
            assert!(out.starts_with(&GZIP_MAGIC));
            assert_eq!(SpzDecoder::open(&out).unwrap().version(), WRITE_VERSION);
            // Version 2 changes only the rotation encoding.
            let mut out = Vec::new();
            write_version(&mut out, &table, 2).unwrap();
            let v2 = SpzDecoder::open(&out).unwrap();
            assert_eq!(v2.version(), 2);
            for a in [POSITIONS, ALPHAS, COLORS, SCALES, SH] {
                assert!(v2.arrays[a] == decoder.arrays[a], "{}", ARRAYS[a]);
            }
            for (g, h) in v2
                .to_table()
                .unwrap()
                .gaussians
                .iter()
                .zip(&table.gaussians)
            {
                assert!(
                    rotation_distance(g.rotation, h.rotation) <= V2_ROTATION_STEP,
                    "{} vs {}",
                    g.rotation,
                    h.rotation
                );
            }
        }
    }

    /// The distance between two rotations as quaternions (q and −q alike).
    fn rotation_distance(a: Quat, b: Quat) -> f32 {
        let (a, b) = (Vec4::from(a.normalize()), Vec4::from(b.normalize()));
        (a - b).length().min((a + b).length())
    }

    /// Versions 1–2 keep x, y, z in steps of 1/127.5 and rebuild w = √(1 − x² − y² − z²), which
    /// is ill-conditioned near w = 0: half a step on each of x, y, z moves x² + y² + z² by up to
    /// 2·√3·(0.5/127.5) ≈ 0.0136, so w by up to √0.0136 ≈ 0.117. A bound, not a step.
    const V2_ROTATION_STEP: f32 = 0.15;

    fn arb_gaussian() -> impl Strategy<Value = Gaussian> {
        (
            prop::array::uniform3(-100.0f32..100.0),
            prop::array::uniform4(-1.0f32..1.0),
            prop::array::uniform3(-9.9f32..5.9),
            -8.0f32..8.0,
            prop::array::uniform3(-3.3f32..3.3),
            prop::collection::vec(-0.99f32..0.99, 45),
        )
            .prop_filter("a rotation", |(_, q, ..)| {
                q.iter().map(|v| v * v).sum::<f32>() > 0.01
            })
            .prop_map(|(p, q, s, o, dc, rest)| Gaussian {
                position: Vec3::from_array(p),
                rotation: Quat::from_xyzw(q[0], q[1], q[2], q[3]),
                log_scale: Vec3::from_array(s),
                opacity_logit: o,
                sh_dc: dc,
                sh_rest: std::array::from_fn(|k| [rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]]),
                instance: 0,
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn write_then_read_is_within_one_step(
            gaussians in prop::collection::vec(arb_gaussian(), 0..40),
            sh_degree in 0u8..=3,
            version in 2u32..=4,
        ) {
            let k = crate::gaussians::sh_rest_count(sh_degree);
            let table = SplatTable { gaussians, sh_degree };
            let mut out = Vec::new();
            write_version(&mut out, &table, version).unwrap();
            prop_assert!(sniff(&out));
            let decoder = SpzDecoder::open(&out).unwrap();
            prop_assert_eq!(decoder.sh_degree(), sh_degree);
            let back = decoder.to_table().unwrap();
            prop_assert_eq!(back.gaussians.len(), table.gaussians.len());
            let sigmoid = |x: f32| 1.0 / (1.0 + (-x).exp());
            for (g, h) in back.gaussians.iter().zip(&table.gaussians) {
                prop_assert!((g.position - h.position).abs().max_element() <= 0.5 / 4096.0 + 2e-5);
                prop_assert!((g.log_scale - h.log_scale).abs().max_element() <= 0.5 / 16.0 + 1e-5);
                prop_assert!((sigmoid(g.opacity_logit) - sigmoid(h.opacity_logit)).abs() <= 0.5 / 255.0 + 1e-6);
                for c in 0..3 {
                    prop_assert!((g.sh_dc[c] - h.sh_dc[c]).abs() <= 0.5 / (255.0 * COLOR_SCALE) + 1e-5);
                }
                for (j, (a, b)) in g.sh_rest.iter().zip(&h.sh_rest).enumerate() {
                    let step = if j < 3 { 8.0 / 128.0 } else { 16.0 / 128.0 };
                    for c in 0..3 {
                        if j < k {
                            // Rounded to a code, then to a bucket.
                            prop_assert!((a[c] - b[c]).abs() <= (step + 1.0 / 128.0) / 2.0 + 1e-6);
                        } else {
                            prop_assert_eq!(a[c], 0.0);
                        }
                    }
                }
                let bound = if version >= 3 { 0.004 } else { V2_ROTATION_STEP };
                prop_assert!(rotation_distance(g.rotation, h.rotation) <= bound);
            }
            // Writing what was read reproduces the file's codes.
            let mut again = Vec::new();
            write_version(&mut again, &back, version).unwrap();
            let again = SpzDecoder::open(&again).unwrap();
            for a in [POSITIONS, ALPHAS, COLORS, SCALES, SH] {
                prop_assert!(again.arrays[a] == decoder.arrays[a]);
            }
            if version >= 3 {
                prop_assert!(again.arrays[ROTATIONS] == decoder.arrays[ROTATIONS]);
            }
        }

        #[test]
        fn truncated_files_are_errors(frac in 0.0f64..1.0, which in 0usize..3) {
            let file: &[u8] = [&*SH3, &*SH0, &*SH3_V3][which];
            let cut = (file.len() as f64 * frac) as usize;
            prop_assert!(SpzDecoder::open(&file[..cut]).is_err());
        }

        #[test]
        fn mutated_files_do_not_panic(
            mutations in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
            which in 0usize..3,
        ) {
            let mut file = [&*SH3, &*SH0, &*SH3_V3][which].clone();
            for (at, byte) in mutations {
                let i = at.index(file.len());
                file[i] = byte;
            }
            exercise(&file);
        }

        #[test]
        fn mutated_headers_do_not_panic(
            mutations in prop::collection::vec((0usize..NGSP_HEADER + 6 * 16, any::<u8>()), 1..4),
        ) {
            let mut file = SH3.clone();
            for (at, byte) in mutations {
                file[at] = byte;
            }
            let start = Instant::now();
            exercise(&file);
            prop_assert!(start.elapsed() < Duration::from_secs(5));
        }

        #[test]
        fn mutated_gzip_payloads_do_not_panic(
            mutations in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        ) {
            // Mutate inside the gzip member, so that the CRC is right and the damage reaches
            // the header and arrays.
            let mut raw = SH3_V3_RAW.clone();
            for (at, byte) in mutations {
                let i = at.index(raw.len());
                raw[i] = byte;
            }
            let file = deflate(&raw);
            let start = Instant::now();
            exercise(&file);
            prop_assert!(start.elapsed() < Duration::from_secs(5));
        }

        #[test]
        fn mutated_arrays_decode(
            mutations in prop::collection::vec((0usize..6, any::<prop::sample::Index>(), any::<u8>()), 1..16),
        ) {
            // Mutate the decompressed arrays of the version-4 file and store them again: any
            // byte is a valid code, so the file must open and decode.
            let decoder = SpzDecoder::open(&SH3).unwrap();
            let mut arrays = decoder.arrays.clone();
            for (a, at, byte) in mutations {
                let i = at.index(arrays[a].len());
                arrays[a][i] = byte;
            }
            let mut file = Vec::new();
            write_ngsp(&mut file, &decoder.header, &arrays).unwrap();
            prop_assert!(exercise(&file));
            // And as an ungzipped and a gzipped legacy stream.
            let mut raw = Vec::new();
            raw.extend_from_slice(&NGSP_MAGIC.to_le_bytes());
            raw.extend_from_slice(&3u32.to_le_bytes());
            raw.extend_from_slice(&(decoder.header.count as u32).to_le_bytes());
            raw.extend_from_slice(&[decoder.header.degree, 12, 0, 0]);
            for a in &arrays {
                raw.extend_from_slice(a);
            }
            prop_assert!(exercise(&raw));
            prop_assert!(exercise(&deflate(&raw)));
        }

        #[test]
        fn random_bytes_do_not_panic(bytes in prop::collection::vec(any::<u8>(), 0..256), prefix in 0usize..3) {
            // Behind each magic, so that the parsers (and the Zstandard decoder) see them.
            let mut file = match prefix {
                0 => NGSP_MAGIC.to_le_bytes().to_vec(),
                1 => [NGSP_MAGIC.to_le_bytes(), 4u32.to_le_bytes()].concat(),
                _ => Vec::new(),
            };
            file.extend_from_slice(&bytes);
            exercise(&file);
            exercise(&deflate(&file));
        }
    }

    /// Replaces `numPoints` in the header of a version-4 file, or of the stream inside a gzip.
    fn with_count(file: &[u8], count: u32) -> Vec<u8> {
        if file.starts_with(&GZIP_MAGIC) {
            let mut raw = inflate(file);
            raw[8..12].copy_from_slice(&count.to_le_bytes());
            deflate(&raw)
        } else {
            let mut out = file.to_vec();
            out[8..12].copy_from_slice(&count.to_le_bytes());
            out
        }
    }

    #[test]
    fn wrong_and_huge_counts_are_clear_errors() {
        for file in [&*SH3, &*SH3_V3] {
            for count in [0, 1, 4095, 4097, 1 << 20, 1 << 28, u32::MAX] {
                let start = Instant::now();
                let err = SpzDecoder::open(&with_count(file, count)).unwrap_err();
                assert!(start.elapsed() < Duration::from_secs(1), "{count}: slow");
                let location = err.location();
                assert!(
                    location.starts_with("spz.header.num")
                        || ARRAYS.iter().any(|a| location == format!("spz.{a}")),
                    "{count}: {err}"
                );
                println!("numPoints {count}: {err}");
            }
        }
    }

    #[test]
    fn bad_header_fields_are_named() {
        let cases: [(usize, &[u8], &str); 6] = [
            (4, &5u32.to_le_bytes(), "spz.header.version"),
            (12, &[5], "spz.header.shDegree"),
            (12, &[0], "spz.header.numStreams"),
            (13, &[40], "spz.header.fractionalBits"),
            (15, &[7], "spz.header.numStreams"),
            (16, &1_000_000u32.to_le_bytes(), "spz.header.tocByteOffset"),
        ];
        for (at, bytes, location) in cases {
            let mut file = SH3.clone();
            file[at..at + bytes.len()].copy_from_slice(bytes);
            let err = SpzDecoder::open(&file).unwrap_err();
            assert_eq!(err.location(), location, "{err}");
        }
        // The same fields inside a gzip.
        for (at, byte, location) in [
            (4, 9, "spz.header.version"),
            (12, 7, "spz.header.shDegree"),
            (14, FLAG_EXTENSIONS, "spz.header.flags"),
        ] {
            let mut raw = SH3_V3_RAW.clone();
            raw[at] = byte;
            let err = SpzDecoder::open(&deflate(&raw)).unwrap_err();
            assert_eq!(err.location(), location, "{err}");
        }
        // A compressed size past the end, and trailing bytes.
        let mut file = SH3.clone();
        file[NGSP_HEADER..NGSP_HEADER + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(
            SpzDecoder::open(&file).unwrap_err().location(),
            "spz.positions"
        );
        let mut file = SH3.clone();
        file.push(0);
        assert_eq!(
            SpzDecoder::open(&file).unwrap_err().location(),
            "spz.streams"
        );
        assert_eq!(
            SpzDecoder::open(b"").unwrap_err().location(),
            "spz.header.magic"
        );
    }

    #[test]
    fn a_gzip_bomb_is_refused_before_it_inflates() {
        // A header declaring 2^28 Gaussians, then 64 MiB of zeros: 64 KiB of gzip.
        let mut raw = Vec::with_capacity(64 << 20);
        raw.extend_from_slice(&NGSP_MAGIC.to_le_bytes());
        raw.extend_from_slice(&3u32.to_le_bytes());
        raw.extend_from_slice(&(1u32 << 28).to_le_bytes());
        raw.extend_from_slice(&[3, 12, 0, 0]);
        raw.resize(64 << 20, 0);
        let file = deflate(&raw);
        let start = Instant::now();
        let err = SpzDecoder::open(&file).unwrap_err();
        assert_eq!(err.location(), "spz.header.numPoints", "{err}");
        assert!(start.elapsed() < Duration::from_secs(1));
    }

    #[test]
    fn sniffs_spz_and_nothing_else() {
        assert!(sniff(&SH3));
        assert!(sniff(&SH0));
        assert!(sniff(&SH3_V3));
        assert!(!sniff(b""));
        assert!(!sniff(&testdata("random_3k_sh0.ply")));
        assert!(!sniff(&deflate(b"ply\nformat binary_little_endian 1.0\n")));
        assert!(!sniff(&[0x1f, 0x8b, 0, 0]));
    }

    #[test]
    fn empty_scenes_round_trip() {
        let table = SplatTable {
            gaussians: Vec::new(),
            sh_degree: 2,
        };
        for version in 2..=4 {
            let mut out = Vec::new();
            write_version(&mut out, &table, version).unwrap();
            let decoder = SpzDecoder::open(&out).unwrap();
            assert_eq!(decoder.len(), 0);
            assert_eq!(decoder.sh_degree(), 2);
        }
    }

    #[test]
    fn unwritable_input_is_an_error() {
        let mut g = Gaussian::default();
        let table = |g: Gaussian| SplatTable {
            gaussians: vec![g],
            sh_degree: 0,
        };
        assert!(write_version(&mut Vec::new(), &table(g), 5).is_err());
        g.rotation = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        assert!(write(&mut Vec::new(), &table(g)).is_err());
        g.rotation = Quat::IDENTITY;
        g.position = Vec3::new(f32::NAN, 0.0, 0.0);
        assert!(write(&mut Vec::new(), &table(g)).is_err());
        g.position = Vec3::new(1e8, 0.0, 0.0);
        assert!(write(&mut Vec::new(), &table(g)).is_err());
        // Far scenes keep fewer fraction bits instead of wrapping around.
        g.position = Vec3::new(5000.0, -3000.0, 10.0);
        let mut out = Vec::new();
        write(&mut out, &table(g)).unwrap();
        let decoder = SpzDecoder::open(&out).unwrap();
        assert_eq!(decoder.fractional_bits(), 10);
        let back = decoder.to_table().unwrap().gaussians[0].position;
        assert!((back - g.position).abs().max_element() <= 0.5 / 1024.0);
    }

    #[test]
    fn version_1_float16_positions_decode() {
        // Version 1 (never released by Niantic, still read): float16 positions, 3-byte
        // rotations.
        let mut raw = Vec::new();
        raw.extend_from_slice(&NGSP_MAGIC.to_le_bytes());
        raw.extend_from_slice(&1u32.to_le_bytes());
        raw.extend_from_slice(&1u32.to_le_bytes());
        raw.extend_from_slice(&[0, 0, 0, 0]);
        for v in [1.5f32, 2.0, -0.25] {
            raw.extend_from_slice(&f16::from_f32(v).to_bits().to_le_bytes());
        }
        raw.extend_from_slice(&[128, 166, 128, 128, 160, 176, 192, 128, 128, 128]);
        let g = SpzDecoder::open(&deflate(&raw))
            .unwrap()
            .to_table()
            .unwrap()
            .gaussians[0];
        assert_eq!(g.position, Vec3::new(1.5, -2.0, 0.25));
        assert_eq!(g.log_scale, Vec3::new(0.0, 1.0, 2.0));
        assert!((g.rotation.w - 1.0).abs() < 1e-4);
    }

    #[test]
    fn parallel_gzip_is_one_member() {
        // 3.5 pieces of compressible but varied bytes.
        let data: Vec<u8> = (0..(7usize << 19))
            .map(|i| (i * i / 977 % 61) as u8)
            .collect();
        let gz = gzip(&data).unwrap();
        let mut decoder = flate2::bufread::GzDecoder::new(&gz[..]);
        let mut out = Vec::new();
        decoder.read_to_end(&mut out).unwrap();
        assert!(out == data);
        assert!(
            decoder.into_inner().is_empty(),
            "bytes after the first member"
        );
        for empty in [&[][..], b"x"] {
            assert_eq!(inflate(&gzip(empty).unwrap()), empty);
        }
    }
}
