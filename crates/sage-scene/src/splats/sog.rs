//! SOG (PlayCanvas "Spatially Ordered Gaussians"): a zip of WebP images plus `meta.json`, read
//! exactly as PlayCanvas `splat-transform` (the format's reference tool) decodes it.
//!
//! # Container
//!
//! A `.sog` file is a zip archive (`PK\x03\x04`) holding `meta.json` at its root and the images
//! that `meta.json` names: every property lists its `files`, whose names are arbitrary but whose
//! order is significant. Entries may be stored or deflated. (The unbundled variant, the same files
//! in a folder, is not read here.) Images are 8-bit RGBA, lossless WebP; a lossy WebP is refused
//! because it would corrupt the quantised codes. Every per-Gaussian image has the same size
//! `W × H ≥ count`; Gaussian `i` is pixel `i` in row-major order from the top-left
//! (`x = i % W`, `y = i / W`), and trailing pixels are ignored.
//!
//! | file (as the tool names it) | channels | holds |
//! |---|---|---|
//! | `means_l.webp`, `means_u.webp` | RGB | low / high byte of a 16-bit code per axis |
//! | `quats.webp` | RGBA | smallest-three rotation: three components in RGB, tag in A |
//! | `scales.webp` | RGB | one 8-bit code per axis |
//! | `sh0.webp` | RGBA | one 8-bit code per colour channel (DC) and the opacity in A |
//! | `shN_centroids.webp` | RGB | the palette of higher-order SH (optional) |
//! | `shN_labels.webp` | RG | each Gaussian's 16-bit palette index, low byte in R (optional) |
//!
//! # Decoding (all arithmetic in `f64`, rounded to `f32` at the end, as the tool does)
//!
//! - **Position**: `q = lo | hi << 8` per axis; `n = min + (max − min) · q / 65535` with
//!   `means.mins` / `means.maxs` (a zero range counts as 1); `p = sign(n) · (e^|n| − 1)`, the
//!   inverse of the writer's `sign(x) · ln(|x| + 1)`.
//! - **Rotation**: the tag `A − 252` (`252..=255`) is the index in `(w, x, y, z)` of the component
//!   of largest magnitude, which the writer made positive and dropped. The other three, in
//!   `(w, x, y, z)` order, are `(c / 255 · 2 − 1) / √2`; the dropped one is
//!   `√max(0, 1 − Σ others²)`. Any other tag is a damaged record.
//! - **Version 2** (`"version": 2`, what splat-transform writes, e.g. v1.8 and v2.7):
//!   `scales.codebook` and `sh0.codebook` are 256 floats (read as `f32`) that the three
//!   channels' codes index — natural-log scales and `f_dc`. The opacity byte is the opacity
//!   *after* the sigmoid: the logit is `ln(a / (1 − a))` with `a = A / 255` clamped to
//!   `[1e-6, 1 − 1e-6]` (so ±13.8 at the ends).
//!   `shN` = `{count, bands, codebook, files: [centroids, labels]}`: the centroids image is
//!   `64 · K` pixels wide (`K` = 3, 8, 15 coefficients for bands 1–3), palette entry `n`'s
//!   coefficient `k` at pixel `((n % 64) · K + k, n / 64)`, its RGB codes indexing the shared
//!   256-entry `shN.codebook`; R, G, B are the three colour channels.
//! - **Version 1** (no `version`; the original `playcanvas/sogs` compressor): the count is
//!   `means.shape[0]`; scales, `f_dc` and opacity are linear 8-bit codes,
//!   `min + (max − min) · c / 255` with per-channel `mins` / `maxs` (`sh0` has four: RGB and the
//!   opacity *logit*); `shN` has scalar `mins` / `maxs` for every code, its band count is given by
//!   the centroids width (192, 512, 960) and its palette by the height (64 entries a row).
//!
//! # What SOG keeps and loses
//!
//! Positions keep 16 bits per axis in the log domain (the step grows with the distance from the
//! origin); rotations about 8 bits per component, normalised, with the sign made canonical;
//! scales and `f_dc` one of 256 shared values per axis or channel; opacity 8 bits after the
//! sigmoid, so logits beyond about ±5.5 collapse onto the end codes; higher-order SH a palette of
//! at most 65 536 entries (k-means clusters) of 8-bit codes. The writer reorders Gaussians (Morton
//! order); the order read is the file's. Instance ids and anything else are not stored.
//!
//! # Coordinates
//!
//! The specification declares a right-handed frame (x right, y up, z back). The tool reads the
//! values into its PLY-convention table and writes a PLY with no axis change, so this reader
//! keeps values exactly as stored (checked against the tool's own decoding in the tests).
//!
//! # Hostile input
//!
//! Nothing is allocated from a declared size before it is checked: `count` may not exceed what
//! the file's bytes could hold ([`GAUSSIANS_PER_BYTE`] per byte of the file, plus an allowance for
//! tiny files), image dimensions are read from the WebP header and checked against `count` before
//! any pixel is decoded (at most `2 · count + 65536` pixels an image), and every zip entry is
//! inflated through a bounded reader (at most 8 bytes a pixel), so neither a zip bomb nor a WebP
//! bomb makes the reader allocate more than a bounded multiple of the file's size. The palette of
//! higher-order SH is dequantised at open into at most 65 536 × 15 RGB triples (12 MB).

use crate::gaussians::{Gaussian, sh_rest_count};
use crate::splats::BlockDecoder;
use glam::{Quat, Vec3};
use image_webp::WebPDecoder;
use rayon::prelude::*;
use sage_core::{Error, Result};
use serde_json::Value;
use std::f64::consts::SQRT_2;
use std::io::{Cursor, Read};
use zip::ZipArchive;
use zip::result::ZipError;

/// The local-file-header signature every zip archive starts with.
const ZIP_MAGIC: &[u8; 4] = b"PK\x03\x04";
/// The metadata entry, at the archive root.
const META: &str = "meta.json";
/// A `meta.json` is a few kilobytes (three 256-entry codebooks); anything beyond this is damage.
const META_MAX_BYTES: u64 = 16 << 20;
/// The most Gaussians a file may declare per byte of its own size. Real SOG files spend 3–20
/// bytes on a Gaussian; four per byte leaves room for very regular scenes while keeping what a
/// small hostile file can make us allocate proportional to its size.
pub const GAUSSIANS_PER_BYTE: u64 = 4;
/// Gaussians allowed on top of [`GAUSSIANS_PER_BYTE`], so that tiny files (tests, single objects)
/// are never refused.
const GAUSSIAN_ALLOWANCE: u64 = 1 << 16;
/// The largest image WebP can describe (16384 × 16384 pixels).
const WEBP_MAX_PIXELS: u64 = 1 << 28;
/// Spare pixels allowed past `count` (writers round the image to a multiple of 4, or use a fixed
/// width), on top of twice `count`.
const PIXEL_ALLOWANCE: u64 = 1 << 16;
/// Palette entries per row of the SH centroids image.
const PALETTE_ROW: u64 = 64;
/// The most palette entries a 16-bit label can address.
const PALETTE_MAX: u64 = 1 << 16;
/// The lowest quaternion tag: tags 252..=255 name the dropped component.
const QUAT_TAG_BASE: u8 = 252;

/// True when `bytes` look like a SOG file: a zip archive with a `meta.json` entry at its root.
pub fn sniff(bytes: &[u8]) -> bool {
    bytes.starts_with(ZIP_MAGIC)
        && ZipArchive::new(Cursor::new(bytes)).is_ok_and(|zip| zip.index_for_name(META).is_some())
}

/// The end-of-central-directory signature, in the last record of every zip archive.
const END_MAGIC: &[u8; 4] = b"PK\x05\x06";
/// The end record's fixed size; a comment of at most 65 535 bytes may follow it.
const END_RECORD: usize = 22;

/// True when the tail of `bytes`, where a zip's end record sits, holds a whole one: its
/// signature followed by its 22 bytes and the comment they announce. A zip cut short has lost
/// it (zips record nothing of their size at the start, so this is the sign of a cut).
fn has_end_record(bytes: &[u8]) -> bool {
    let from = bytes
        .len()
        .saturating_sub(END_RECORD + usize::from(u16::MAX));
    bytes[from..]
        .windows(END_MAGIC.len())
        .enumerate()
        .any(|(i, w)| {
            let at = from + i;
            w == END_MAGIC
                && bytes.get(at + 20..at + 22).is_some_and(|c| {
                    at + END_RECORD + usize::from(u16::from_le_bytes([c[0], c[1]])) <= bytes.len()
                })
        })
}

/// One channel's byte codes resolved to values at open time, so that decoding is a lookup.
#[derive(Debug, Clone)]
struct Table {
    values: [f32; 256],
    /// Codes at or above this index are damage (a codebook shorter than 256 entries).
    len: usize,
}

impl Table {
    /// A codebook of `meta.json`, rounded to `f32` as the tool's `Float32Array` does.
    fn codebook(values: &[f64], at: &str) -> Result<Table> {
        let mut table = Table {
            values: [0.0; 256],
            len: values.len(),
        };
        for (slot, &v) in table.values.iter_mut().zip(values) {
            *slot = finite_f32(v, at)?;
        }
        Ok(table)
    }

    /// Version 1's linear codes: `min + (max − min) · c / 255`.
    fn linear(min: f64, max: f64, at: &str) -> Result<Table> {
        let mut values = [0.0; 256];
        for (c, slot) in values.iter_mut().enumerate() {
            *slot = finite_f32(min + (max - min) * (c as f64 / 255.0), at)?;
        }
        Ok(Table { values, len: 256 })
    }

    /// Version 2's opacity byte: a sigmoid value, turned back into a clamped logit.
    fn logit() -> Table {
        let mut values = [0.0; 256];
        for (c, slot) in values.iter_mut().enumerate() {
            let a = (c as f64 / 255.0).clamp(1e-6, 1.0 - 1e-6);
            *slot = (a / (1.0 - a)).ln() as f32;
        }
        Table { values, len: 256 }
    }

    /// The value of a code; `None` past a short codebook.
    fn get(&self, code: u8) -> Option<f32> {
        let i = usize::from(code);
        if i < self.len {
            self.values.get(i).copied()
        } else {
            None
        }
    }
}

/// `v` rounded to `f32` (as the tool's `Float32Array` rounds), refusing what overflows it.
fn finite_f32(v: f64, at: &str) -> Result<f32> {
    let f = v as f32;
    if f.is_finite() {
        Ok(f)
    } else {
        Err(Error::format(
            meta_at(at),
            format!("{v} is not a finite 32-bit value"),
        ))
    }
}

/// The error location of a `meta.json` field.
fn meta_at(path: &str) -> String {
    format!("{META}:{path}")
}

/// The `meta.json` value at a dotted path.
fn field<'a>(meta: &'a Value, path: &str) -> Result<&'a Value> {
    path.split('.')
        .try_fold(meta, |v, key| v.get(key))
        .ok_or_else(|| Error::format(meta_at(path), "missing field"))
}

/// A finite JSON number.
fn number(v: &Value, at: &str) -> Result<f64> {
    v.as_f64()
        .filter(|x| x.is_finite())
        .ok_or_else(|| Error::format(meta_at(at), format!("expected a finite number, found {v}")))
}

/// A non-negative integer (written as `3000` or `3000.0`).
fn integer(v: &Value, at: &str) -> Result<u64> {
    if let Some(n) = v.as_u64() {
        return Ok(n);
    }
    match v.as_f64() {
        Some(x) if x >= 0.0 && x.fract() == 0.0 && x < 2f64.powi(53) => Ok(x as u64),
        _ => Err(Error::format(
            meta_at(at),
            format!("expected a non-negative integer, found {v}"),
        )),
    }
}

/// An array of finite numbers whose length lies in `lengths`.
fn numbers(v: &Value, at: &str, lengths: std::ops::RangeInclusive<usize>) -> Result<Vec<f64>> {
    let array = v
        .as_array()
        .filter(|a| lengths.contains(&a.len()))
        .ok_or_else(|| {
            let (lo, hi) = (lengths.start(), lengths.end());
            let want = if lo == hi {
                format!("{lo}")
            } else {
                format!("{lo} to {hi}")
            };
            Error::format(meta_at(at), format!("expected an array of {want} numbers"))
        })?;
    array
        .iter()
        .enumerate()
        .map(|(i, x)| number(x, &format!("{at}[{i}]")))
        .collect()
}

/// The first `n` names of a `files` array.
fn files(v: &Value, at: &str, n: usize) -> Result<Vec<String>> {
    let array = v
        .as_array()
        .filter(|a| a.len() >= n)
        .ok_or_else(|| Error::format(meta_at(at), format!("expected {n} file names")))?;
    array
        .iter()
        .take(n)
        .enumerate()
        .map(|(i, name)| {
            name.as_str()
                .map(str::to_owned)
                .ok_or_else(|| Error::format(meta_at(&format!("{at}[{i}]")), "not a string"))
        })
        .collect()
}

/// How the higher-order SH are laid out, as far as `meta.json` says.
struct ShPlan {
    /// Version 2's band count; version 1 infers it from the centroids width.
    bands: Option<u8>,
    /// Version 2's palette size; version 1 infers it from the centroids height.
    palette: Option<usize>,
    table: Table,
    centroids: String,
    labels: String,
}

/// Everything `meta.json` says: what to read and how to dequantise it.
struct Plan {
    count: u64,
    means_min: [f64; 3],
    means_range: [f64; 3],
    /// means_l, means_u, quats, scales, sh0.
    images: [String; 5],
    scales: [Table; 3],
    colors: [Table; 3],
    opacity: Table,
    sh: Option<ShPlan>,
}

impl Plan {
    /// Reads a version 1 or 2 `meta.json`, checking every field it uses.
    fn parse(meta: &Value) -> Result<Plan> {
        if !meta.is_object() {
            return Err(Error::format(META, "expected a JSON object"));
        }
        let version = match meta.get("version") {
            None => 1,
            Some(v) if v.as_f64() == Some(2.0) => 2,
            Some(v) => {
                return Err(Error::format(
                    meta_at("version"),
                    format!("unsupported SOG version {v} (expected 2, or none for version 1)"),
                ));
            }
        };
        let count = if version == 2 {
            integer(field(meta, "count")?, "count")?
        } else {
            let shape = field(meta, "means.shape")?;
            let first = shape
                .get(0)
                .ok_or_else(|| Error::format(meta_at("means.shape"), "expected [count, 3]"))?;
            integer(first, "means.shape[0]")?
        };
        let mins = numbers(field(meta, "means.mins")?, "means.mins", 3..=3)?;
        let maxs = numbers(field(meta, "means.maxs")?, "means.maxs", 3..=3)?;
        let mut means_min = [0.0; 3];
        let mut means_range = [0.0; 3];
        for (k, (lo, hi)) in mins.iter().zip(&maxs).enumerate() {
            let range = hi - lo;
            if !range.is_finite() {
                return Err(Error::format(meta_at("means.maxs"), "range is not finite"));
            }
            if let (Some(m), Some(r)) = (means_min.get_mut(k), means_range.get_mut(k)) {
                *m = *lo;
                // The tool's `(max - min) || 1`: a flat axis decodes with a unit range.
                *r = if range == 0.0 { 1.0 } else { range };
            }
        }
        let one = |path: &str| -> Result<String> {
            files(field(meta, path)?, path, 1)?
                .into_iter()
                .next()
                .ok_or_else(|| Error::format(meta_at(path), "expected 1 file name"))
        };
        let mut means = files(field(meta, "means.files")?, "means.files", 2)?.into_iter();
        let (Some(means_l), Some(means_u)) = (means.next(), means.next()) else {
            return Err(Error::format(
                meta_at("means.files"),
                "expected 2 file names",
            ));
        };
        let images = [
            means_l,
            means_u,
            one("quats.files")?,
            one("scales.files")?,
            one("sh0.files")?,
        ];
        let (scales, colors, opacity) = if version == 2 {
            let s = numbers(field(meta, "scales.codebook")?, "scales.codebook", 1..=256)?;
            let s = Table::codebook(&s, "scales.codebook")?;
            let c = numbers(field(meta, "sh0.codebook")?, "sh0.codebook", 1..=256)?;
            let c = Table::codebook(&c, "sh0.codebook")?;
            (
                [s.clone(), s.clone(), s],
                [c.clone(), c.clone(), c],
                Table::logit(),
            )
        } else {
            let smin = numbers(field(meta, "scales.mins")?, "scales.mins", 3..=3)?;
            let smax = numbers(field(meta, "scales.maxs")?, "scales.maxs", 3..=3)?;
            let cmin = numbers(field(meta, "sh0.mins")?, "sh0.mins", 4..=4)?;
            let cmax = numbers(field(meta, "sh0.maxs")?, "sh0.maxs", 4..=4)?;
            let table = |lo: &[f64], hi: &[f64], k: usize, at: &str| -> Result<Table> {
                match (lo.get(k), hi.get(k)) {
                    (Some(&a), Some(&b)) => Table::linear(a, b, at),
                    _ => Err(Error::format(meta_at(at), "missing channel")),
                }
            };
            (
                [
                    table(&smin, &smax, 0, "scales.maxs")?,
                    table(&smin, &smax, 1, "scales.maxs")?,
                    table(&smin, &smax, 2, "scales.maxs")?,
                ],
                [
                    table(&cmin, &cmax, 0, "sh0.maxs")?,
                    table(&cmin, &cmax, 1, "sh0.maxs")?,
                    table(&cmin, &cmax, 2, "sh0.maxs")?,
                ],
                table(&cmin, &cmax, 3, "sh0.maxs")?,
            )
        };
        let sh = match meta.get("shN") {
            None | Some(Value::Null) => None,
            Some(_) if version == 2 => {
                let bands = integer(field(meta, "shN.bands")?, "shN.bands")?;
                if bands > 3 {
                    return Err(Error::format(
                        meta_at("shN.bands"),
                        format!("{bands} bands; expected 0 to 3"),
                    ));
                }
                if bands == 0 {
                    // The tool skips a zero-band palette without reading its files.
                    None
                } else {
                    let palette = integer(field(meta, "shN.count")?, "shN.count")?;
                    if !(1..=PALETTE_MAX).contains(&palette) {
                        return Err(Error::format(
                            meta_at("shN.count"),
                            format!("palette of {palette} entries; expected 1 to {PALETTE_MAX}"),
                        ));
                    }
                    let code = numbers(field(meta, "shN.codebook")?, "shN.codebook", 1..=256)?;
                    let mut names = files(field(meta, "shN.files")?, "shN.files", 2)?.into_iter();
                    let (Some(centroids), Some(labels)) = (names.next(), names.next()) else {
                        return Err(Error::format(meta_at("shN.files"), "expected 2 file names"));
                    };
                    Some(ShPlan {
                        bands: Some(bands as u8),
                        palette: Some(palette as usize),
                        table: Table::codebook(&code, "shN.codebook")?,
                        centroids,
                        labels,
                    })
                }
            }
            Some(_) => {
                let lo = number(field(meta, "shN.mins")?, "shN.mins")?;
                let hi = number(field(meta, "shN.maxs")?, "shN.maxs")?;
                let mut names = files(field(meta, "shN.files")?, "shN.files", 2)?.into_iter();
                let (Some(centroids), Some(labels)) = (names.next(), names.next()) else {
                    return Err(Error::format(meta_at("shN.files"), "expected 2 file names"));
                };
                Some(ShPlan {
                    bands: None,
                    palette: None,
                    table: Table::linear(lo, hi, "shN.maxs")?,
                    centroids,
                    labels,
                })
            }
        };
        Ok(Plan {
            count,
            means_min,
            means_range,
            images,
            scales,
            colors,
            opacity,
            sh,
        })
    }
}

/// A decoded image: RGB or RGBA bytes, row-major.
#[derive(Debug)]
struct Image {
    name: String,
    width: u32,
    height: u32,
    /// 3 (no alpha: read as 255) or 4.
    channels: usize,
    data: Vec<u8>,
}

impl Image {
    /// `W · H`.
    fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Pixel `i` as RGBA.
    fn texel(&self, i: usize) -> Option<[u8; 4]> {
        let start = i.checked_mul(self.channels)?;
        match *self.data.get(start..start.checked_add(self.channels)?)? {
            [r, g, b] => Some([r, g, b, 255]),
            [r, g, b, a] => Some([r, g, b, a]),
            _ => None,
        }
    }

    /// Pixel `i` as RGBA, or an error naming the image and the Gaussian.
    fn at(&self, i: usize) -> Result<[u8; 4]> {
        self.texel(i)
            .ok_or_else(|| Error::format(format!("{}[{i}]", self.name), "pixel outside the image"))
    }

    /// `W×H`, for messages.
    fn size(&self) -> String {
        format!("{}×{}", self.width, self.height)
    }
}

/// Decodes one lossless WebP image of at most `max_pixels` pixels, checking the dimensions in its
/// header before allocating.
fn decode_webp(name: &str, bytes: &[u8], max_pixels: u64) -> Result<Image> {
    let bad = |e: image_webp::DecodingError| {
        Error::format(name.to_owned(), format!("unreadable WebP image: {e}"))
    };
    let mut decoder = WebPDecoder::new(Cursor::new(bytes)).map_err(bad)?;
    if decoder.is_animated() {
        return Err(Error::format(
            name.to_owned(),
            "animated WebP; SOG images are single frames",
        ));
    }
    if decoder.is_lossy() {
        return Err(Error::format(
            name.to_owned(),
            "lossy WebP; SOG images must be lossless (lossy coding corrupts the quantised codes)",
        ));
    }
    let (width, height) = decoder.dimensions();
    let pixels = u64::from(width) * u64::from(height);
    if pixels > max_pixels {
        return Err(Error::format(
            name.to_owned(),
            format!(
                "{width}×{height} image is far larger than the Gaussian count needs \
                 (at most {max_pixels} pixels)"
            ),
        ));
    }
    let channels = if decoder.has_alpha() { 4 } else { 3 };
    let size = decoder
        .output_buffer_size()
        .filter(|&s| s as u64 == pixels * channels as u64)
        .ok_or_else(|| Error::format(name.to_owned(), "inconsistent image size"))?;
    let mut data = vec![0u8; size];
    decoder.read_image(&mut data).map_err(bad)?;
    Ok(Image {
        name: name.to_owned(),
        width,
        height,
        channels,
        data,
    })
}

/// Reads one archive entry, inflating at most `cap` bytes.
fn read_entry(zip: &mut ZipArchive<Cursor<&[u8]>>, name: &str, cap: u64) -> Result<Vec<u8>> {
    let file = match zip.by_name(name) {
        Ok(file) => file,
        Err(ZipError::FileNotFound) => {
            return Err(Error::format(
                name.to_owned(),
                "missing from the archive (named in meta.json)",
            ));
        }
        Err(e) => {
            return Err(Error::format(
                name.to_owned(),
                format!("unreadable entry: {e}"),
            ));
        }
    };
    let declared = file.size();
    if declared > cap {
        return Err(Error::format(
            name.to_owned(),
            format!("entry declares {declared} bytes; at most {cap} are plausible here"),
        ));
    }
    // `declared <= cap`, which the caller bounded by the file's own size.
    let mut data = Vec::with_capacity(usize::try_from(declared).unwrap_or(0));
    file.take(cap.saturating_add(1))
        .read_to_end(&mut data)
        .map_err(|e| Error::format(name.to_owned(), format!("unreadable entry: {e}")))?;
    if data.len() as u64 > cap {
        return Err(Error::format(
            name.to_owned(),
            format!("entry inflates past {cap} bytes"),
        ));
    }
    Ok(data)
}

/// Why a palette entry cannot be decoded (kept per entry, reported by the Gaussians using it).
#[derive(Debug, Clone, Copy, PartialEq)]
enum EntryState {
    Ok,
    /// Its row lies below the centroids image.
    Outside,
    /// One of its codes is past the codebook.
    BadCode(u8),
}

/// The higher-order SH palette, dequantised once at open: a Gaussian's SH is then one copy.
#[derive(Debug)]
struct Palette {
    bands: u8,
    /// Coefficients per channel: 3, 8 or 15.
    coeffs: usize,
    /// `entries × coeffs` RGB triples.
    values: Vec<[f32; 3]>,
    states: Vec<EntryState>,
    codebook_len: usize,
    centroids: String,
    centroid_rows: u32,
    labels: Image,
}

impl Palette {
    /// Entry `n`'s coefficient `k` is at pixel `((n % 64) · coeffs + k, n / 64)`.
    fn build(
        bands: u8,
        entries: usize,
        table: &Table,
        centroids: &Image,
        labels: Image,
    ) -> Palette {
        let coeffs = sh_rest_count(bands);
        let mut values = vec![[0.0f32; 3]; entries * coeffs];
        let mut states = vec![EntryState::Ok; entries];
        let row = PALETTE_ROW as usize;
        for (n, (out, state)) in values.chunks_exact_mut(coeffs).zip(&mut states).enumerate() {
            let first = (n / row) * centroids.width as usize + (n % row) * coeffs;
            for (k, v) in out.iter_mut().enumerate() {
                let Some(rgb) = centroids.texel(first + k) else {
                    *state = EntryState::Outside;
                    break;
                };
                for (x, &c) in v.iter_mut().zip(&rgb) {
                    match table.get(c) {
                        Some(value) => *x = value,
                        None => *state = EntryState::BadCode(c),
                    }
                }
            }
        }
        Palette {
            bands,
            coeffs,
            values,
            states,
            codebook_len: table.len,
            centroids: centroids.name.clone(),
            centroid_rows: centroids.height,
            labels,
        }
    }

    /// Gaussian `i`'s higher-order SH from its palette entry.
    fn fill(&self, i: usize, out: &mut [[f32; 3]; 15]) -> Result<()> {
        let l = self.labels.at(i)?;
        let label = usize::from(l[0]) | usize::from(l[1]) << 8;
        let at = || format!("{}[{i}]", self.labels.name);
        let state = self.states.get(label).ok_or_else(|| {
            Error::format(
                at(),
                format!(
                    "palette index {label} is past the {} entries",
                    self.states.len()
                ),
            )
        })?;
        match *state {
            EntryState::Ok => {}
            EntryState::Outside => {
                return Err(Error::format(
                    at(),
                    format!(
                        "palette index {label} is past the {} rows of {}",
                        self.centroid_rows, self.centroids
                    ),
                ));
            }
            EntryState::BadCode(c) => {
                return Err(Error::format(
                    format!("{}[{label}]", self.centroids),
                    format!(
                        "code {c} is past the codebook's {} entries",
                        self.codebook_len
                    ),
                ));
            }
        }
        let first = label * self.coeffs;
        if let Some(values) = self.values.get(first..first + self.coeffs) {
            for (o, v) in out.iter_mut().zip(values) {
                *o = *v;
            }
        }
        Ok(())
    }
}

/// A SOG file unpacked and its images decoded, ready to decode Gaussians in any order.
#[derive(Debug)]
pub struct SogDecoder {
    count: usize,
    means_min: [f64; 3],
    means_range: [f64; 3],
    means_l: Image,
    means_u: Image,
    quats: Image,
    scales_image: Image,
    sh0: Image,
    scales: [Table; 3],
    colors: [Table; 3],
    opacity: Table,
    palette: Option<Palette>,
}

impl SogDecoder {
    /// Unzips a `.sog` file, reads `meta.json` and decodes every image (in parallel).
    ///
    /// # Errors
    ///
    /// Not a zip, a missing entry, a bad `meta.json` field, an unreadable or lossy image, an image
    /// smaller than `count` or of another size than `means_l`, or a count or image far larger
    /// than the file could hold — each naming the entry or field.
    pub fn open(bytes: &[u8]) -> Result<SogDecoder> {
        if !bytes.starts_with(ZIP_MAGIC) {
            return Err(Error::format(
                "zip",
                "not a SOG file: no zip signature (PK\\x03\\x04)",
            ));
        }
        let mut zip = ZipArchive::new(Cursor::new(bytes)).map_err(|e| {
            if has_end_record(bytes) {
                Error::format("zip", format!("unreadable archive: {e}"))
            } else {
                Error::format(
                    "zip",
                    format!(
                        "truncated: the archive's end record (end of central directory, which \
                         every whole zip ends with) is missing from its {} bytes",
                        bytes.len()
                    ),
                )
            }
        })?;
        let meta_bytes = read_entry(&mut zip, META, META_MAX_BYTES)?;
        let meta: Value = serde_json::from_slice(&meta_bytes)
            .map_err(|e| Error::format(META, format!("not valid JSON: {e}")))?;
        let plan = Plan::parse(&meta)?;

        let file_bytes = bytes.len() as u64;
        let most = file_bytes
            .saturating_mul(GAUSSIANS_PER_BYTE)
            .saturating_add(GAUSSIAN_ALLOWANCE)
            .min(WEBP_MAX_PIXELS);
        if plan.count > most {
            return Err(Error::format(
                meta_at("count"),
                format!(
                    "{} Gaussians declared; a {file_bytes}-byte file holds at most {most}",
                    plan.count
                ),
            ));
        }
        let count = plan.count as usize;
        let max_pixels = plan
            .count
            .saturating_mul(2)
            .saturating_add(PIXEL_ALLOWANCE)
            .min(WEBP_MAX_PIXELS);
        let centroid_pixels = PALETTE_ROW * 15 * (PALETTE_MAX / PALETTE_ROW);
        // A lossless WebP never needs much more than its raw pixels (15-bit codes at worst).
        let entry_cap = |pixels: u64| pixels * 8 + (1 << 20);

        let mut jobs: Vec<(String, u64)> = plan
            .images
            .iter()
            .map(|name| (name.clone(), max_pixels))
            .collect();
        if let Some(sh) = &plan.sh {
            jobs.push((sh.centroids.clone(), centroid_pixels));
            jobs.push((sh.labels.clone(), max_pixels));
        }
        let entries = jobs
            .into_iter()
            .map(|(name, pixels)| {
                let data = read_entry(&mut zip, &name, entry_cap(pixels))?;
                Ok((name, data, pixels))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut images = entries
            .par_iter()
            .map(|(name, data, pixels)| decode_webp(name, data, *pixels))
            .collect::<Result<Vec<_>>>()?
            .into_iter();
        let mut next = || {
            images
                .next()
                .ok_or_else(|| Error::format("zip", "image missing after decoding"))
        };
        let means_l = next()?;
        let per_gaussian = [next()?, next()?, next()?, next()?];
        check_size(&means_l, &means_l, plan.count)?;
        for image in &per_gaussian {
            check_size(image, &means_l, plan.count)?;
        }
        let [means_u, quats, scales_image, sh0] = per_gaussian;
        let palette = match plan.sh {
            None => None,
            Some(sh) => {
                let centroids = next()?;
                let labels = next()?;
                check_size(&labels, &means_l, plan.count)?;
                let bands = match sh.bands {
                    Some(b) => b,
                    None => match centroids.width {
                        192 => 1,
                        512 => 2,
                        960 => 3,
                        w => {
                            return Err(Error::format(
                                centroids.name.clone(),
                                format!("{w} pixels wide; a version 1 palette is 192, 512 or 960"),
                            ));
                        }
                    },
                };
                let coeffs = sh_rest_count(bands);
                let width = PALETTE_ROW * coeffs as u64;
                if u64::from(centroids.width) != width {
                    return Err(Error::format(
                        centroids.name.clone(),
                        format!(
                            "{} pixels wide; {bands} bands need 64 × {coeffs} = {width}",
                            centroids.width
                        ),
                    ));
                }
                // Version 1 has no palette size: every row of the image, as far as a 16-bit
                // label reaches.
                let entries = sh.palette.unwrap_or(
                    (PALETTE_ROW * u64::from(centroids.height)).min(PALETTE_MAX) as usize,
                );
                Some(Palette::build(
                    bands, entries, &sh.table, &centroids, labels,
                ))
            }
        };
        Ok(SogDecoder {
            count,
            means_min: plan.means_min,
            means_range: plan.means_range,
            means_l,
            means_u,
            quats,
            scales_image,
            sh0,
            scales: plan.scales,
            colors: plan.colors,
            opacity: plan.opacity,
            palette,
        })
    }

    /// Gaussian `i` (`i < count`).
    fn gaussian(&self, i: usize) -> Result<Gaussian> {
        let lo = self.means_l.at(i)?;
        let hi = self.means_u.at(i)?;
        let mut position = [0.0f32; 3];
        for (k, p) in position.iter_mut().enumerate() {
            let (Some(&l), Some(&h), Some(&min), Some(&range)) = (
                lo.get(k),
                hi.get(k),
                self.means_min.get(k),
                self.means_range.get(k),
            ) else {
                continue;
            };
            let q = u16::from(l) | u16::from(h) << 8;
            *p = unlog(min + range * (f64::from(q) / 65535.0)) as f32;
            if !p.is_finite() {
                return Err(Error::format(
                    format!("{}[{i}]", self.means_l.name),
                    "position overflows a 32-bit float",
                ));
            }
        }

        let q = self.quats.at(i)?;
        let rotation = quaternion(q).ok_or_else(|| {
            Error::format(
                format!("{}[{i}]", self.quats.name),
                format!(
                    "quaternion tag {} is not one of {QUAT_TAG_BASE}..=255",
                    q[3]
                ),
            )
        })?;

        let code = |image: &Image, table: &Table, c: u8| {
            table.get(c).ok_or_else(|| {
                Error::format(
                    format!("{}[{i}]", image.name),
                    format!("code {c} is past the codebook's {} entries", table.len),
                )
            })
        };
        let s = self.scales_image.at(i)?;
        let [s0, s1, s2] = &self.scales;
        let log_scale = Vec3::new(
            code(&self.scales_image, s0, s[0])?,
            code(&self.scales_image, s1, s[1])?,
            code(&self.scales_image, s2, s[2])?,
        );
        let c = self.sh0.at(i)?;
        let [c0, c1, c2] = &self.colors;
        let sh_dc = [
            code(&self.sh0, c0, c[0])?,
            code(&self.sh0, c1, c[1])?,
            code(&self.sh0, c2, c[2])?,
        ];
        let opacity_logit = code(&self.sh0, &self.opacity, c[3])?;

        let mut sh_rest = [[0.0f32; 3]; 15];
        if let Some(p) = &self.palette {
            p.fill(i, &mut sh_rest)?;
        }
        Ok(Gaussian {
            position: Vec3::from_array(position),
            rotation,
            log_scale,
            opacity_logit,
            sh_dc,
            sh_rest,
            instance: 0,
        })
    }
}

/// Checks that a per-Gaussian image covers `count` pixels and matches `means_l`'s size.
fn check_size(image: &Image, reference: &Image, count: u64) -> Result<()> {
    if image.pixels() < count {
        return Err(Error::format(
            image.name.clone(),
            format!(
                "{} image holds {} pixels, fewer than the {count} Gaussians",
                image.size(),
                image.pixels()
            ),
        ));
    }
    if (image.width, image.height) != (reference.width, reference.height) {
        return Err(Error::format(
            image.name.clone(),
            format!(
                "{} image; {} is {} and every per-Gaussian image must match",
                image.size(),
                reference.name,
                reference.size()
            ),
        ));
    }
    Ok(())
}

/// The inverse of the writer's `sign(x) · ln(|x| + 1)`, written as the tool writes it.
fn unlog(n: f64) -> f64 {
    let e = n.abs().exp() - 1.0;
    if n < 0.0 { -e } else { e }
}

/// A smallest-three quaternion (`tag` in alpha); `None` for a tag outside 252..=255.
fn quaternion(texel: [u8; 4]) -> Option<Quat> {
    let [r, g, b, tag] = texel;
    let largest = usize::from(tag.checked_sub(QUAT_TAG_BASE)?);
    // `(w, x, y, z)`, the order of PLY's rot_0..rot_3.
    let mut q = [0.0f64; 4];
    let mut stored = [r, g, b].into_iter();
    for (k, c) in q.iter_mut().enumerate() {
        if k != largest {
            let code = stored.next()?;
            *c = (f64::from(code) / 255.0 * 2.0 - 1.0) / SQRT_2;
        }
    }
    let [w, x, y, z] = q;
    let rest = 1.0 - (w * w + x * x + y * y + z * z);
    *q.get_mut(largest)? = rest.max(0.0).sqrt();
    let [w, x, y, z] = q.map(|v| v as f32);
    Some(Quat::from_xyzw(x, y, z, w))
}

impl BlockDecoder for SogDecoder {
    fn len(&self) -> usize {
        self.count
    }

    fn sh_degree(&self) -> u8 {
        self.palette.as_ref().map_or(0, |p| p.bands)
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        let end = start
            .checked_add(out.len())
            .filter(|&end| end <= self.count)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "Gaussians {start}..{} requested from a SOG file of {}",
                    start.saturating_add(out.len()),
                    self.count
                ))
            })?;
        for (i, g) in (start..end).zip(out.iter_mut()) {
            *g = self.gaussian(i)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image_webp::{ColorType, WebPEncoder};
    use proptest::prelude::*;
    use sage_core::ErrorKind;
    use serde_json::json;
    use std::io::Write;
    use std::time::{Duration, Instant};
    use zip::write::SimpleFileOptions;
    use zip::{CompressionMethod, ZipWriter};

    const SOG_FILE: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/splats/random_3k_sh0.sog"
    );
    const SOG_DECODED: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/splats/random_3k_sh0.sog.decoded.ply"
    );

    fn real_file() -> Vec<u8> {
        std::fs::read(SOG_FILE).expect("test file")
    }

    #[test]
    fn matches_the_reference_decoding() {
        let sog = real_file();
        assert!(sniff(&sog));
        let decoder = SogDecoder::open(&sog).expect("open");
        let table = decoder.to_table().expect("decode");
        let reference = crate::splats::test_files::standard_table(
            &std::fs::read(SOG_DECODED).expect("reference"),
        );
        assert_eq!(table.sh_degree, 0);
        assert_eq!(table.gaussians.len(), reference.gaussians.len());
        type Get = fn(&Gaussian) -> f32;
        let fields: [(&str, Get); 14] = [
            ("x", |g| g.position.x),
            ("y", |g| g.position.y),
            ("z", |g| g.position.z),
            ("scale_0", |g| g.log_scale.x),
            ("scale_1", |g| g.log_scale.y),
            ("scale_2", |g| g.log_scale.z),
            ("f_dc_0", |g| g.sh_dc[0]),
            ("f_dc_1", |g| g.sh_dc[1]),
            ("f_dc_2", |g| g.sh_dc[2]),
            ("opacity", |g| g.opacity_logit),
            ("rot_0", |g| g.rotation.w),
            ("rot_1", |g| g.rotation.x),
            ("rot_2", |g| g.rotation.y),
            ("rot_3", |g| g.rotation.z),
        ];
        for (name, get) in fields {
            let (mut max_err, mut exact) = (0f32, 0);
            for (i, (g, r)) in table.gaussians.iter().zip(&reference.gaussians).enumerate() {
                let (ours, theirs) = (get(g), get(r));
                let err = (ours - theirs).abs() / theirs.abs().max(1.0);
                exact += usize::from(ours.to_bits() == theirs.to_bits());
                max_err = max_err.max(err);
                assert!(err <= 1e-6, "Gaussian {i} {name}: {ours} vs {theirs}");
            }
            eprintln!(
                "{name}: max relative error {max_err:e}, {exact}/{} bit-exact",
                reference.gaussians.len()
            );
        }
        // Every Gaussian is the same whichever way it is decoded.
        let mut one = [Gaussian::default(); 7];
        decoder.decode(1234, &mut one).expect("decode a run");
        assert_eq!(&one[..], &table.gaussians[1234..1241]);
        let store = decoder.to_gaussians().expect("compact store");
        assert_eq!(store.len(), 3000);
    }

    // ---- building SOG files -------------------------------------------------------------------

    fn webp(width: u32, height: u32, rgba: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        WebPEncoder::new(&mut out)
            .encode(rgba, width, height, ColorType::Rgba8)
            .expect("encode");
        out
    }

    fn zip_of(entries: &[(String, Vec<u8>)]) -> Vec<u8> {
        let mut zip = ZipWriter::new(Cursor::new(Vec::new()));
        for (name, data) in entries {
            let method = if name.ends_with(".json") {
                CompressionMethod::Deflated
            } else {
                CompressionMethod::Stored
            };
            zip.start_file(
                name.as_str(),
                SimpleFileOptions::default().compression_method(method),
            )
            .expect("start entry");
            zip.write_all(data).expect("write entry");
        }
        zip.finish().expect("finish").into_inner()
    }

    /// A SOG's meta.json and raw images, to edit before zipping.
    struct Synth {
        meta: Value,
        /// (name, width, height, RGBA)
        images: Vec<(String, u32, u32, Vec<u8>)>,
    }

    impl Synth {
        fn entries(&self) -> Vec<(String, Vec<u8>)> {
            let mut out = vec![(
                META.to_owned(),
                serde_json::to_vec(&self.meta).expect("json"),
            )];
            for (name, w, h, rgba) in &self.images {
                out.push((name.clone(), webp(*w, *h, rgba)));
            }
            out
        }

        fn bytes(&self) -> Vec<u8> {
            zip_of(&self.entries())
        }

        fn image(&mut self, name: &str) -> &mut Vec<u8> {
            &mut self
                .images
                .iter_mut()
                .find(|(n, ..)| n == name)
                .expect("image")
                .3
        }
    }

    /// A small deterministic byte stream.
    fn noise(seed: u32, n: usize) -> Vec<u8> {
        let mut x = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                (x >> 24) as u8
            })
            .collect()
    }

    const W: u32 = 4;
    const H: u32 = 3;
    const COUNT: usize = 10;
    const PALETTE: usize = 70;

    fn codebook(offset: f64, step: f64) -> Vec<f64> {
        (0..256).map(|i| offset + step * i as f64).collect()
    }

    /// Centroid codes of palette entry `n`, coefficient `k`, channel `c`: all distinct enough.
    fn centroid_code(n: usize, k: usize, c: usize) -> u8 {
        ((n * 7 + k * 31 + c * 101) % 256) as u8
    }

    /// A version 2 SOG of `COUNT` Gaussians in a `W × H` image, with `bands` of SH.
    fn synth_v2(bands: usize) -> Synth {
        let px = (W * H) as usize;
        let mut quats = noise(3, px * 4);
        for (i, p) in quats.chunks_exact_mut(4).enumerate() {
            p[3] = QUAT_TAG_BASE + (i % 4) as u8;
        }
        let mut images = vec![
            ("means_l.webp".to_owned(), W, H, noise(1, px * 4)),
            ("means_u.webp".to_owned(), W, H, noise(2, px * 4)),
            ("quats.webp".to_owned(), W, H, quats),
            ("scales.webp".to_owned(), W, H, noise(4, px * 4)),
            ("sh0.webp".to_owned(), W, H, noise(5, px * 4)),
        ];
        let mut meta = json!({
            "version": 2,
            "asset": {"generator": "test"},
            "count": COUNT,
            "means": {"mins": [-1.5, 0.0, 2.0], "maxs": [1.5, 0.5, 2.0],
                      "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"codebook": codebook(-8.0, 0.03), "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"codebook": codebook(-2.0, 0.015), "files": ["sh0.webp"]},
        });
        if bands > 0 {
            let coeffs = sh_rest_count(bands as u8);
            let (cw, ch) = (64 * coeffs, PALETTE.div_ceil(64));
            let mut centroids = vec![0u8; cw * ch * 4];
            for n in 0..PALETTE {
                for k in 0..coeffs {
                    let p = ((n / 64) * cw + (n % 64) * coeffs + k) * 4;
                    for c in 0..3 {
                        centroids[p + c] = centroid_code(n, k, c);
                    }
                    centroids[p + 3] = 255;
                }
            }
            let mut labels = vec![0u8; px * 4];
            for (i, p) in labels.chunks_exact_mut(4).enumerate() {
                let label = (i * 23 + 5) % PALETTE;
                p.copy_from_slice(&[label as u8, (label >> 8) as u8, 0, 255]);
            }
            images.push((
                "shN_centroids.webp".to_owned(),
                cw as u32,
                ch as u32,
                centroids,
            ));
            images.push(("shN_labels.webp".to_owned(), W, H, labels));
            meta["shN"] = json!({
                "count": PALETTE, "bands": bands, "codebook": codebook(-1.28, 0.01),
                "files": ["shN_centroids.webp", "shN_labels.webp"],
            });
        }
        Synth { meta, images }
    }

    /// The spec's formulas, written independently of the decoder.
    fn expect_position(meta: &Value, lo: &[u8], hi: &[u8]) -> [f32; 3] {
        std::array::from_fn(|k| {
            let min = meta["means"]["mins"][k].as_f64().unwrap();
            let max = meta["means"]["maxs"][k].as_f64().unwrap();
            let range = if max == min { 1.0 } else { max - min };
            let q = f64::from(lo[k]) + 256.0 * f64::from(hi[k]);
            let n = min + range * q / 65535.0;
            (n.signum() * (n.abs().exp() - 1.0)) as f32
        })
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-6 * b.abs().max(1.0)
    }

    #[test]
    fn version_2_with_sh_follows_the_spec() {
        for bands in [1usize, 2, 3] {
            let synth = synth_v2(bands);
            let sog = synth.bytes();
            assert!(sniff(&sog));
            let decoder = SogDecoder::open(&sog).expect("open");
            assert_eq!(decoder.len(), COUNT);
            assert_eq!(decoder.sh_degree() as usize, bands);
            let table = decoder.to_table().expect("decode");
            let img = |name: &str| &synth.images.iter().find(|i| i.0 == name).unwrap().3;
            let scales_cb = codebook(-8.0, 0.03);
            let sh0_cb = codebook(-2.0, 0.015);
            let shn_cb = codebook(-1.28, 0.01);
            let coeffs = sh_rest_count(bands as u8);
            for (i, g) in table.gaussians.iter().enumerate() {
                let p = |name: &str| &img(name)[i * 4..i * 4 + 4];
                let pos = expect_position(&synth.meta, p("means_l.webp"), p("means_u.webp"));
                for (a, b) in g.position.to_array().iter().zip(pos) {
                    assert!(close(*a, b), "Gaussian {i}: position {a} vs {b}");
                }
                let s = p("scales.webp");
                for (k, v) in g.log_scale.to_array().iter().enumerate() {
                    assert_eq!(*v, scales_cb[s[k] as usize] as f32);
                }
                let c = p("sh0.webp");
                for k in 0..3 {
                    assert_eq!(g.sh_dc[k], sh0_cb[c[k] as usize] as f32);
                }
                let a = (f64::from(c[3]) / 255.0).clamp(1e-6, 1.0 - 1e-6);
                assert!(close(g.opacity_logit, (a / (1.0 - a)).ln() as f32));
                // The quaternion: unit length, tag component non-negative and in its slot.
                let q = p("quats.webp");
                let wxyz = [g.rotation.w, g.rotation.x, g.rotation.y, g.rotation.z];
                let largest = usize::from(q[3] - QUAT_TAG_BASE);
                assert!(wxyz[largest] >= 0.0);
                let stored: Vec<f32> = (0..4).filter(|&k| k != largest).map(|k| wxyz[k]).collect();
                for (v, code) in stored.iter().zip(&q[..3]) {
                    let want = ((f64::from(*code) / 255.0 - 0.5) * 2.0 / SQRT_2) as f32;
                    assert!(close(*v, want), "Gaussian {i}: {v} vs {want}");
                }
                if wxyz[largest] > 0.0 {
                    assert!((g.rotation.length() - 1.0).abs() < 1e-6);
                }
                // Higher-order SH through the palette, channel R/G/B = colour 0/1/2.
                let label = (i * 23 + 5) % PALETTE;
                for k in 0..15 {
                    for ch in 0..3 {
                        let want = if k < coeffs {
                            shn_cb[centroid_code(label, k, ch) as usize] as f32
                        } else {
                            0.0
                        };
                        assert_eq!(g.sh_rest[k][ch], want, "Gaussian {i} coeff {k} ch {ch}");
                    }
                }
                assert_eq!(g.instance, 0);
            }
        }
    }

    #[test]
    fn version_1_uses_linear_ranges() {
        let mut synth = synth_v2(1);
        let smin = [-9.0, -8.0, -7.0];
        let smax = [1.0, 0.5, 0.25];
        let cmin = [-1.0, -2.0, -3.0, -5.0];
        let cmax = [2.0, 3.0, 4.0, 9.0];
        // The original compressor writes square images with exactly `count` pixels.
        synth.meta = json!({
            "means": {"shape": [W * H, 3], "dtype": "float32",
                      "mins": [-1.5, 0.0, 2.0], "maxs": [1.5, 0.5, 2.5],
                      "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"shape": [W * H, 3], "mins": smin, "maxs": smax, "files": ["scales.webp"]},
            "quats": {"shape": [W * H, 4], "encoding": "quaternion_packed",
                      "files": ["quats.webp"]},
            "sh0": {"shape": [W * H, 1, 4], "mins": cmin, "maxs": cmax, "files": ["sh0.webp"]},
            "shN": {"shape": [W * H, 9], "mins": -0.5, "maxs": 0.75, "quantization": 8,
                    "files": ["shN_centroids.webp", "shN_labels.webp"]},
        });
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        assert_eq!(decoder.len(), (W * H) as usize);
        assert_eq!(decoder.sh_degree(), 1);
        let table = decoder.to_table().expect("decode");
        let img = |name: &str| &synth.images.iter().find(|i| i.0 == name).unwrap().3;
        let lerp = |lo: f64, hi: f64, c: u8| (lo + (hi - lo) * (f64::from(c) / 255.0)) as f32;
        for (i, g) in table.gaussians.iter().enumerate() {
            let p = |name: &str| &img(name)[i * 4..i * 4 + 4];
            let pos = expect_position(&synth.meta, p("means_l.webp"), p("means_u.webp"));
            assert_eq!(g.position.to_array(), pos);
            let s = p("scales.webp");
            for k in 0..3 {
                assert_eq!(g.log_scale.to_array()[k], lerp(smin[k], smax[k], s[k]));
            }
            let c = p("sh0.webp");
            for k in 0..3 {
                assert_eq!(g.sh_dc[k], lerp(cmin[k], cmax[k], c[k]));
            }
            // Version 1 stores the opacity logit itself.
            assert_eq!(g.opacity_logit, lerp(cmin[3], cmax[3], c[3]));
            let label = (i * 23 + 5) % PALETTE;
            for k in 0..3 {
                for ch in 0..3 {
                    let want = lerp(-0.5, 0.75, centroid_code(label, k, ch));
                    assert_eq!(g.sh_rest[k][ch], want);
                }
            }
        }
    }

    #[test]
    fn quaternion_components_land_in_their_slots() {
        // Tag 252 drops w, 255 drops z; the stored three keep (w, x, y, z) order.
        let mid = |v: f64| ((v * SQRT_2 * 0.5 + 0.5) * 255.0).round() as u8;
        let q = quaternion([mid(0.1), mid(-0.2), mid(0.3), 252]).unwrap();
        assert!((q.x - 0.1).abs() < 3e-3 && (q.y + 0.2).abs() < 3e-3 && (q.z - 0.3).abs() < 3e-3);
        assert!((q.w - (1.0f32 - 0.01 - 0.04 - 0.09).sqrt()).abs() < 3e-3);
        let q = quaternion([mid(0.1), mid(-0.2), mid(0.3), 255]).unwrap();
        assert!((q.w - 0.1).abs() < 3e-3 && (q.x + 0.2).abs() < 3e-3 && (q.y - 0.3).abs() < 3e-3);
        assert!(q.z > 0.9);
        assert!(quaternion([0, 0, 0, 251]).is_none());
        // All-extreme codes would overflow the unit sphere: the dropped component clamps to 0.
        let q = quaternion([255, 255, 255, 253]).unwrap();
        assert_eq!(q.x, 0.0);
    }

    // ---- errors -------------------------------------------------------------------------------

    fn open_err(bytes: &[u8]) -> Error {
        match SogDecoder::open(bytes) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e,
        }
    }

    fn assert_err(bytes: &[u8], location: &str, message: &str) {
        let e = open_err(bytes);
        assert_eq!(e.kind(), ErrorKind::Format, "{e}");
        assert!(e.location().contains(location), "{e}");
        assert!(e.message().contains(message), "{e}");
    }

    fn with_meta(edit: impl FnOnce(&mut Value)) -> Vec<u8> {
        let mut synth = synth_v2(3);
        edit(&mut synth.meta);
        synth.bytes()
    }

    #[test]
    fn damaged_containers_are_named() {
        assert_err(b"not a zip at all", "zip", "zip signature");
        assert!(!sniff(b"PK\x03\x04 but not really"));
        assert_err(b"PK\x03\x04 but not really", "zip", "truncated");
        // A whole end record whose central directory is not there: damaged, not cut short.
        let mut bogus_end = b"PK\x03\x04 but not reallyPK\x05\x06\0\0\0\0\x01\0\x01\0".to_vec();
        bogus_end.extend_from_slice(&100u32.to_le_bytes());
        bogus_end.extend_from_slice(&1000u32.to_le_bytes());
        bogus_end.extend_from_slice(&[0, 0]);
        assert_err(&bogus_end, "zip", "unreadable archive");
        assert_err(&bogus_end[..bogus_end.len() - 1], "zip", "truncated");
        let no_meta = zip_of(&[("other.json".to_owned(), b"{}".to_vec())]);
        assert!(!sniff(&no_meta));
        assert_err(&no_meta, "meta.json", "missing from the archive");
        let bad_json = zip_of(&[(META.to_owned(), b"{\"version\": 2,".to_vec())]);
        assert_err(&bad_json, "meta.json", "not valid JSON");
        let not_object = zip_of(&[(META.to_owned(), b"[1, 2]".to_vec())]);
        assert_err(&not_object, "meta.json", "JSON object");

        let mut synth = synth_v2(3);
        let mut entries = synth.entries();
        entries.retain(|(n, _)| n != "quats.webp");
        assert_err(&zip_of(&entries), "quats.webp", "missing from the archive");
        entries = synth.entries();
        entries.retain(|(n, _)| n != "shN_labels.webp");
        assert_err(&zip_of(&entries), "shN_labels.webp", "missing");
        entries = synth.entries();
        for e in &mut entries {
            if e.0 == "scales.webp" {
                e.1 = b"RIFF\x10\0\0\0WEBPjunkjunk".to_vec();
            }
        }
        assert_err(&zip_of(&entries), "scales.webp", "unreadable WebP");

        // A mismatched size and a too-small image.
        synth.images[3] = ("scales.webp".to_owned(), 8, 3, noise(9, 8 * 3 * 4));
        assert_err(&synth.bytes(), "scales.webp", "must match");
        let mut small = synth_v2(0);
        for img in &mut small.images {
            *img = (img.0.clone(), 3, 3, noise(1, 36));
        }
        assert_err(
            &small.bytes(),
            "means_l.webp",
            "fewer than the 10 Gaussians",
        );
    }

    type Edit = Box<dyn FnOnce(&mut Value)>;

    fn case(edit: impl FnOnce(&mut Value) + 'static) -> Edit {
        Box::new(edit)
    }

    #[test]
    fn bad_meta_fields_are_named() {
        let cases: Vec<(Edit, &str, &str)> = vec![
            (case(|m| m["version"] = json!(3)), "version", "unsupported"),
            (
                case(|m| m["count"] = json!(-1)),
                "count",
                "non-negative integer",
            ),
            (
                case(|m| m["count"] = json!(2.5)),
                "count",
                "non-negative integer",
            ),
            (
                case(|m| m["count"] = json!("ten")),
                "count",
                "non-negative integer",
            ),
            (
                case(|m| m["count"] = json!(1u64 << 40)),
                "count",
                "holds at most",
            ),
            (
                case(|m| {
                    m.as_object_mut()
                        .unwrap()
                        .remove("count")
                        .map(drop)
                        .unwrap()
                }),
                "count",
                "missing field",
            ),
            (
                case(|m| m["means"]["mins"] = json!([0, 1])),
                "means.mins",
                "3 numbers",
            ),
            (
                case(|m| m["means"]["maxs"] = json!([0, "a", 1])),
                "means.maxs[1]",
                "finite number",
            ),
            (
                case(|m| {
                    m["means"]["mins"] = json!([-1.7e308, 0, 0]);
                    m["means"]["maxs"] = json!([1.7e308, 1, 1]);
                }),
                "means.maxs",
                "range is not finite",
            ),
            (
                case(|m| m["means"]["files"] = json!(["means_l.webp"])),
                "means.files",
                "2 file",
            ),
            (
                case(|m| m["quats"]["files"] = json!([7])),
                "quats.files[0]",
                "not a string",
            ),
            (
                case(|m| m["scales"]["codebook"] = json!([])),
                "scales.codebook",
                "1 to 256",
            ),
            (
                case(|m| m["scales"]["codebook"] = json!(vec![0.5; 257])),
                "scales.codebook",
                "1 to 256",
            ),
            (
                case(|m| m["sh0"]["codebook"][7] = json!(1e300)),
                "sh0.codebook",
                "32-bit",
            ),
            (
                case(|m| m["shN"]["bands"] = json!(4)),
                "shN.bands",
                "expected 0 to 3",
            ),
            (
                case(|m| m["shN"]["count"] = json!(0)),
                "shN.count",
                "palette of 0",
            ),
            (
                case(|m| m["shN"]["count"] = json!(70_000)),
                "shN.count",
                "palette of 70000",
            ),
            (
                case(|m| m["shN"]["bands"] = json!(2)),
                "shN_centroids.webp",
                "2 bands need 64 × 8 = 512",
            ),
            (
                case(|m| m["quats"]["files"] = json!(["nowhere.webp"])),
                "nowhere.webp",
                "missing from the archive",
            ),
        ];
        for (edit, location, message) in cases {
            assert_err(&with_meta(edit), location, message);
        }
        // Zero bands: the palette is ignored, as the tool does.
        let sog = with_meta(|m| m["shN"]["bands"] = json!(0));
        assert_eq!(SogDecoder::open(&sog).expect("open").sh_degree(), 0);
    }

    #[test]
    fn damaged_records_are_named_at_decode() {
        let mut synth = synth_v2(3);
        synth.image("quats.webp")[7 * 4 + 3] = 17;
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("bad tag");
        assert_eq!(e.location(), "quats.webp[7]");
        assert!(e.message().contains("tag 17"), "{e}");

        let mut synth = synth_v2(3);
        synth.image("shN_labels.webp")[4 * 4..4 * 4 + 2].copy_from_slice(&[100, 0]);
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("bad label");
        assert_eq!(e.location(), "shN_labels.webp[4]");
        assert!(e.message().contains("palette index 100"), "{e}");

        // A palette entry below the centroids image (the palette says 70, the image has 64).
        let mut synth = synth_v2(1);
        let c = synth
            .images
            .iter()
            .position(|i| i.0 == "shN_centroids.webp")
            .unwrap();
        synth.images[c].2 = 1;
        synth.images[c].3.truncate(192 * 4);
        synth.image("shN_labels.webp")[2 * 4..2 * 4 + 2].copy_from_slice(&[66, 0]);
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("outside");
        assert_eq!(e.location(), "shN_labels.webp[2]");
        assert!(e.message().contains("past the 1 rows"), "{e}");
        // A centroid code past a short SH codebook, reported with the palette entry.
        let mut synth = synth_v2(1);
        synth.meta["shN"]["codebook"] = json!([0.5, 0.5, 0.5]);
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("bad centroid code");
        assert!(e.location().starts_with("shN_centroids.webp["), "{e}");
        assert!(e.message().contains("codebook's 3 entries"), "{e}");

        // A codebook shorter than the codes that index it.
        let mut synth = synth_v2(0);
        synth.meta["sh0"]["codebook"] = json!([0.5, 0.25]);
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("short codebook");
        assert!(e.location().starts_with("sh0.webp["), "{e}");
        assert!(e.message().contains("codebook's 2 entries"), "{e}");

        // A position that overflows f32.
        let mut synth = synth_v2(0);
        synth.meta["means"]["maxs"] = json!([200.0, 0.5, 2.0]);
        let decoder = SogDecoder::open(&synth.bytes()).expect("open");
        let e = decoder.to_table().expect_err("overflow");
        assert!(e.message().contains("overflows"), "{e}");

        // A run past the end is the caller's error.
        let decoder = SogDecoder::open(&synth_v2(0).bytes()).expect("open");
        let mut out = [Gaussian::default(); 3];
        let e = decoder
            .decode(COUNT - 2, &mut out)
            .expect_err("past the end");
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        assert!(decoder.decode(usize::MAX, &mut out).is_err());
        decoder.decode(COUNT - 3, &mut out).expect("last three");
    }

    /// A WebP header claiming a `width × height` lossless image, with no pixel data.
    fn webp_header(width: u32, height: u32) -> Vec<u8> {
        let bits = (width - 1) | (height - 1) << 14 | 1 << 28;
        let mut chunk = vec![0x2f];
        chunk.extend_from_slice(&bits.to_le_bytes());
        chunk.extend_from_slice(&[0; 7]);
        let mut out = b"RIFF".to_vec();
        out.extend_from_slice(&(4 + 8 + chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(b"WEBPVP8L");
        out.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(&chunk);
        out
    }

    #[test]
    fn bombs_are_refused_before_allocating() {
        let started = Instant::now();
        let synth = synth_v2(0);
        // A WebP that claims 16383 × 16383 pixels (1 GiB decoded) for 10 Gaussians.
        let mut entries = synth.entries();
        entries[3].1 = webp_header(16383, 16383);
        assert_err(&zip_of(&entries), "quats.webp", "far larger");
        // The same for the centroids image.
        let mut entries = synth_v2(3).entries();
        let c = entries
            .iter()
            .position(|e| e.0 == "shN_centroids.webp")
            .unwrap();
        entries[c].1 = webp_header(960, 16383);
        assert_err(&zip_of(&entries), "shN_centroids.webp", "far larger");
        // A lossy WebP header.
        let mut lossy = b"RIFF\x1a\0\0\0WEBPVP8 \x0e\0\0\0".to_vec();
        lossy.extend_from_slice(&[0x10, 0, 0, 0x9d, 0x01, 0x2a, 4, 0, 3, 0, 0, 0, 0, 0]);
        entries = synth.entries();
        entries[4].1 = lossy;
        assert_err(&zip_of(&entries), "scales.webp", "lossy");
        // A zip bomb: 32 MiB of spaces deflate to a few kilobytes.
        let mut big = synth.meta.to_string().into_bytes();
        big.resize(32 << 20, b' ');
        entries = synth.entries();
        entries[0].1 = big;
        let bomb = zip_of(&entries);
        assert!(bomb.len() < 1 << 20);
        assert_err(&bomb, "meta.json", "entry declares");
        // An image entry far larger than its pixels could need.
        entries = synth.entries();
        entries[1].1.resize(8 << 20, 0);
        let mut zip = ZipWriter::new(Cursor::new(Vec::new()));
        for (name, data) in &entries {
            let options =
                SimpleFileOptions::default().compression_method(CompressionMethod::Deflated);
            zip.start_file(name.as_str(), options).unwrap();
            zip.write_all(data).unwrap();
        }
        let bomb = zip.finish().unwrap().into_inner();
        assert_err(&bomb, "means_l.webp", "entry declares");
        assert!(started.elapsed() < Duration::from_secs(20));
    }

    // ---- fuzzing ------------------------------------------------------------------------------

    /// Opens and decodes `bytes`; anything but a panic is fine.
    fn exercise(bytes: &[u8]) {
        if let Ok(decoder) = SogDecoder::open(bytes) {
            let _ = decoder.to_table();
        }
        let _ = sniff(bytes);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        #[test]
        fn truncated_files_fail_cleanly(cut in 0usize..57_600) {
            let sog = real_file();
            let cut = cut.min(sog.len().saturating_sub(1));
            prop_assert!(SogDecoder::open(&sog[..cut]).is_err());
            let _ = sniff(&sog[..cut]);
        }

        #[test]
        fn mutated_files_never_panic(
            edits in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8),
        ) {
            let mut sog = real_file();
            let n = sog.len();
            for (at, v) in edits {
                sog[at % n] ^= v | 1;
            }
            exercise(&sog);
        }

        #[test]
        fn mutated_entries_never_panic(
            entry in 0usize..6,
            edits in prop::collection::vec((any::<usize>(), any::<u8>()), 1..6),
            cut in prop::option::of(any::<usize>()),
        ) {
            // Damage one entry's content under a valid CRC, so the WebP and JSON readers see it.
            let mut zip = ZipArchive::new(Cursor::new(real_file())).unwrap();
            let mut entries = Vec::new();
            for i in 0..zip.len() {
                let mut f = zip.by_index(i).unwrap();
                let mut data = Vec::new();
                f.read_to_end(&mut data).unwrap();
                entries.push((f.name().unwrap().into_owned(), data));
            }
            let target = &mut entries[entry % 6].1;
            let n = target.len();
            for (at, v) in edits {
                target[at % n] ^= v | 1;
            }
            if let Some(cut) = cut {
                target.truncate(cut % n);
            }
            exercise(&zip_of(&entries));
        }

        #[test]
        fn hostile_meta_values_fail_fast(
            count in prop_oneof![Just(json!(u64::MAX)), (0u64..1 << 34).prop_map(|v| json!(v)),
                                 any::<f64>().prop_map(|v| json!(v))],
            bands in prop_oneof![
                (0u64..6).prop_map(|v| json!(v)), Just(json!(null)), Just(json!(-1)),
            ],
            palette in prop_oneof![(0u64..200_000).prop_map(|v| json!(v)), Just(json!("x"))],
        ) {
            let started = Instant::now();
            let sog = with_meta(|m| {
                m["count"] = count;
                m["shN"]["bands"] = bands;
                m["shN"]["count"] = palette;
            });
            exercise(&sog);
            prop_assert!(started.elapsed() < Duration::from_secs(5));
        }
    }

    /// Decode speed on a million random Gaussians with SH degree 3 and 0
    /// (`cargo test --release -- --ignored`).
    #[test]
    #[ignore = "timing; run by hand in release mode"]
    fn decode_speed_one_million() {
        let (w, h) = (1000u32, 1000u32);
        let px = (w * h) as usize;
        let mut synth = synth_v2(3);
        synth.meta["count"] = json!(px);
        synth.meta["shN"]["count"] = json!(65536);
        let (cw, ch) = (960u32, 1024u32);
        let mut quats = noise(3, px * 4);
        for (i, p) in quats.chunks_exact_mut(4).enumerate() {
            p[3] = QUAT_TAG_BASE + (i % 4) as u8;
        }
        synth.images = vec![
            ("means_l.webp".to_owned(), w, h, noise(1, px * 4)),
            ("means_u.webp".to_owned(), w, h, noise(2, px * 4)),
            ("quats.webp".to_owned(), w, h, quats),
            ("scales.webp".to_owned(), w, h, noise(4, px * 4)),
            ("sh0.webp".to_owned(), w, h, noise(5, px * 4)),
            (
                "shN_centroids.webp".to_owned(),
                cw,
                ch,
                noise(6, (cw * ch * 4) as usize),
            ),
            ("shN_labels.webp".to_owned(), w, h, noise(7, px * 4)),
        ];
        let sog = synth.bytes();
        for _ in 0..3 {
            let t = Instant::now();
            let decoder = SogDecoder::open(&sog).expect("open");
            let opened = t.elapsed();
            let table = decoder.to_table().expect("decode");
            eprintln!(
                "{} Gaussians ({} MB file): open {opened:?}, open + decode {:?}",
                table.gaussians.len(),
                sog.len() >> 20,
                t.elapsed()
            );
        }
        let mut synth0 = synth;
        synth0.meta.as_object_mut().unwrap().remove("shN");
        synth0.images.truncate(5);
        let sog = synth0.bytes();
        for _ in 0..3 {
            let t = Instant::now();
            let decoder = SogDecoder::open(&sog).expect("open");
            let opened = t.elapsed();
            let table = decoder.to_table().expect("decode");
            eprintln!(
                "SH0: {} Gaussians: open {opened:?}, open + decode {:?}",
                table.gaussians.len(),
                t.elapsed()
            );
        }
    }

    /// Decode speed on real files: `SOG_BENCH=a.sog:b.sog cargo test --release -- --ignored`.
    #[test]
    #[ignore = "timing; run by hand in release mode with SOG_BENCH set"]
    fn decode_speed_of_files() {
        use crate::splats::BLOCK;
        let paths = std::env::var("SOG_BENCH").unwrap_or_default();
        for path in paths.split(':').filter(|p| !p.is_empty()) {
            let sog = std::fs::read(path).expect("bench file");
            for _ in 0..3 {
                let t = Instant::now();
                let decoder = SogDecoder::open(&sog).expect("open");
                let opened = t.elapsed();
                // Decoding alone, into one reused block per task (no full-table allocation).
                let t = Instant::now();
                let n = decoder.len();
                (0..n.div_ceil(BLOCK)).into_par_iter().for_each(|b| {
                    let mut block = vec![Gaussian::default(); BLOCK.min(n - b * BLOCK)];
                    decoder.decode(b * BLOCK, &mut block).expect("decode");
                });
                let decoded = t.elapsed();
                let t = Instant::now();
                let table = decoder.to_table().expect("decode");
                eprintln!(
                    "{path}: {n} Gaussians, SH {}: open {opened:?}, decode {decoded:?}, \
                     to_table {:?}",
                    table.sh_degree,
                    t.elapsed()
                );
            }
        }
    }
}
