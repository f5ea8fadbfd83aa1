//! The sizes a binary USD file (USDC, "crate" format) declares, checked against what its bytes
//! can hold before the USD reader sees it.
//!
//! The reader allocates every table of the file's structural sections (tokens, strings,
//! fields, field sets, paths, specs) at the size the file declares, before reading it: a
//! damaged count asks for terabytes, and a failed allocation aborts the process, which no
//! `catch_unwind` stops. Each declared size is checked here against the bytes that must hold it:
//! compressed blocks (LZ4, which expands a byte to at most 255) lie inside the file, a table of
//! integers (USD's integer coding: at least two bits an integer) fits what its block can expand
//! to, and a table read raw fits the file. The arrays among the fields' values (read later, when
//! the stage is composed: points, indices, counts) are checked the same way, each at the place
//! its value names, and so is every USDC layer packed in a USDZ archive. A file USD itself wrote
//! always passes. Values nested in time samples, dictionaries and list edits are not checked.

use sage_core::{Error, Result};
use std::io::Read;

/// The first bytes of a USDC file.
pub const MAGIC: &[u8; 8] = b"PXR-USDC";

/// The first bytes of a ZIP archive, as a USDZ package is.
pub const ZIP_MAGIC: &[u8; 4] = b"PK\x03\x04";

/// The oldest crate version whose structural sections the reader reads (older ones it does not
/// implement, and stops on).
const OLDEST: (u8, u8) = (0, 4);

/// At most this many sections in the table of contents (the reader's own bound).
const MOST_SECTIONS: u64 = 64;

/// Checks the declared sizes of USDC `bytes` (which start with [`MAGIC`]).
///
/// # Errors
///
/// A version before 0.4, a table of contents or a section outside the file, or a section
/// declaring more than its bytes hold: the error names the section.
pub fn check(bytes: &[u8]) -> Result<()> {
    let mut header = Cursor::new(bytes, "bootstrap", 8);
    let v = header.take(8)?;
    let version = (v[0], v[1]);
    if version < OLDEST {
        return Err(Error::format(
            "bootstrap",
            format!(
                "USDC version {}.{}.{} is older than {}.{}, which the USD reader does not read",
                v[0], v[1], v[2], OLDEST.0, OLDEST.1
            ),
        ));
    }
    let toc = header.count()?;
    let mut contents = Cursor::at(bytes, "table of contents", toc)?;
    let sections = contents.count()?;
    if sections == 0 || sections >= MOST_SECTIONS {
        return Err(Error::format(
            "table of contents",
            format!("{sections} sections (expected 1 to {})", MOST_SECTIONS - 1),
        ));
    }
    let mut seen: Vec<&[u8]> = Vec::new();
    let mut values = Vec::new();
    for _ in 0..sections {
        let raw = contents.take(16)?;
        let name = &raw[..raw.iter().position(|&b| b == 0).unwrap_or(raw.len())];
        let start = contents.count()?;
        let _size = contents.count()?;
        // The reader takes the first section of a name.
        if seen.contains(&name) {
            continue;
        }
        seen.push(name);
        let label = String::from_utf8_lossy(name).into_owned();
        let mut s = Cursor::at(bytes, label, start)?;
        match name {
            b"TOKENS" => {
                let _count = s.count()?;
                let text = s.count()?;
                s.compressed(text)?;
            }
            b"STRINGS" => {
                let count = s.count()?;
                s.take(count.saturating_mul(4))?;
            }
            b"FIELDS" => {
                let count = s.count()?;
                s.encoded_ints(count)?;
                let block = s.compressed(count.saturating_mul(8))?;
                values = s.value_reps(block, count)?;
            }
            b"FIELDSETS" => {
                let count = s.count()?;
                s.encoded_ints(count)?;
            }
            b"PATHS" => {
                // The table of paths, then the tree that fills it: one entry a path.
                let paths = s.count()?;
                let count = s.count()?;
                s.holds(paths, s.peek_count()?, "paths")?;
                for _ in 0..3 {
                    s.encoded_ints(count)?;
                }
            }
            b"SPECS" => {
                let count = s.count()?;
                for _ in 0..3 {
                    s.encoded_ints(count)?;
                }
            }
            _ => {}
        }
    }
    for rep in values {
        check_array(bytes, version, rep)?;
    }
    Ok(())
}

/// Element bytes of an array of USD value type `ty` as the reader reads it raw (1, the least,
/// for types it does not read as arrays).
fn element_bytes(ty: u64) -> u64 {
    match ty {
        // Half.
        7 => 2,
        // Int, Uint, Float, Token (an index), Vec2h.
        3 | 4 | 8 | 11 | 21 => 4,
        // Vec3h.
        25 => 6,
        // Int64, Uint64, Double, Quath, Vec2f, Vec2i, Vec4h, TimeCode.
        5 | 6 | 9 | 18 | 20 | 22 | 29 | 56 => 8,
        // Vec3f, Vec3i.
        24 | 26 => 12,
        // Quatf, Vec2d, Vec4f, Vec4i.
        17 | 19 | 28 | 30 => 16,
        // Vec3d.
        23 => 24,
        // Matrix2d, Quatd, Vec4d.
        13 | 16 | 27 => 32,
        // Matrix3d.
        14 => 72,
        // Matrix4d.
        15 => 128,
        _ => 1,
    }
}

/// Checks the array a field's value `rep` (USD's `ValueRep`: array, inlined and compressed
/// flags, the type in bits 48–55, a file offset below) names, as the reader reads it.
fn check_array(bytes: &[u8], version: (u8, u8), rep: u64) -> Result<()> {
    const PAYLOAD: u64 = (1 << 48) - 1;
    let (array, inlined, compressed) = (rep >> 63 == 1, rep >> 62 & 1 == 1, rep >> 61 & 1 == 1);
    let (ty, payload) = (rep >> 48 & 0xff, rep & PAYLOAD);
    // Strings, asset paths, and vectors of paths, tokens and strings: a count, then a 4-byte
    // index each.
    let indices = matches!(ty, 40 | 41 | 50) || (array && matches!(ty, 10 | 12));
    let double_vector = ty == 48;
    if !(array || indices || double_vector) || inlined || payload == 0 {
        return Ok(());
    }
    let mut c = Cursor::at(bytes, format!("the array value at byte {payload}"), payload)?;
    if indices {
        let count = c.count()?;
        c.take(count.saturating_mul(4))?;
        return Ok(());
    }
    if version < (0, 5) {
        c.take(4)?;
    }
    let count = if version < (0, 7) {
        u64::from(c.word()?)
    } else {
        c.count()?
    };
    let ints = matches!(ty, 3..=6) && version >= (0, 5);
    let floats = (matches!(ty, 7..=9) || double_vector) && version >= (0, 6);
    if !(compressed && count >= 4 && (ints || floats)) {
        let element = if double_vector { 8 } else { element_bytes(ty) };
        c.take(count.saturating_mul(element))?;
    } else if ints {
        c.encoded_ints(count)?;
    } else {
        match c.take(1)?[0] {
            b'i' => c.encoded_ints(count)?,
            b't' => {
                let table = u64::from(c.word()?);
                c.take(table.saturating_mul(element_bytes(ty)))?;
                c.encoded_ints(count)?;
            }
            // The reader refuses another code itself.
            _ => {}
        }
    }
    Ok(())
}

/// Checks, as [`check`] does, every USDC layer of the USDZ package `bytes`, each read up to
/// `most` bytes. Faults of the archive itself are left to the reader, which refuses them.
///
/// # Errors
///
/// A packed layer that [`check`] refuses: the error names the layer.
pub fn check_package(bytes: &[u8], most: u64) -> Result<()> {
    let Ok(mut archive) = zip::ZipArchive::new(std::io::Cursor::new(bytes)) else {
        return Ok(());
    };
    for i in 0..archive.len() {
        let Ok(entry) = archive.by_index(i) else {
            continue;
        };
        let name = entry.name().map(String::from).unwrap_or_default();
        let mut layer = Vec::new();
        if entry.take(most).read_to_end(&mut layer).is_err() {
            continue;
        }
        if layer.starts_with(MAGIC) {
            check(&layer).map_err(|e| Error::format(name, e.to_string()))?;
        }
    }
    Ok(())
}

/// The most bytes an LZ4 block of `compressed` bytes expands to (255 a byte, and a margin).
fn expanded(compressed: u64) -> u64 {
    compressed.saturating_mul(256).saturating_add(64)
}

/// The most integers USD's integer coding fits in `bytes` bytes (two bits each).
fn ints_within(bytes: u64) -> u64 {
    bytes.saturating_mul(4)
}

/// Reads a section's little-endian fields in order, each inside the file.
struct Cursor<'a> {
    bytes: &'a [u8],
    what: String,
    at: u64,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], what: impl Into<String>, at: u64) -> Self {
        Cursor {
            bytes,
            what: what.into(),
            at,
        }
    }

    /// A cursor at `at`, which must lie inside the file.
    fn at(bytes: &'a [u8], what: impl Into<String>, at: u64) -> Result<Self> {
        let what = what.into();
        if at >= bytes.len() as u64 {
            return Err(Error::format(
                what,
                format!("starts at byte {at}, past the file's {} bytes", bytes.len()),
            ));
        }
        Ok(Cursor::new(bytes, what, at))
    }

    /// The next `n` bytes.
    fn take(&mut self, n: u64) -> Result<&'a [u8]> {
        let len = self.bytes.len() as u64;
        let end = self.at.saturating_add(n);
        if end > len {
            return Err(Error::format(
                self.what.clone(),
                format!(
                    "declares {n} bytes at byte {}, past the file's {len} bytes",
                    self.at
                ),
            ));
        }
        let taken = &self.bytes[self.at as usize..end as usize];
        self.at = end;
        Ok(taken)
    }

    /// The next little-endian u64.
    fn count(&mut self) -> Result<u64> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(b.try_into().expect("eight bytes")))
    }

    /// The next little-endian u32.
    fn word(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes(b.try_into().expect("four bytes")))
    }

    /// The next u64, left to be read again.
    fn peek_count(&self) -> Result<u64> {
        let mut ahead = Cursor::new(self.bytes, self.what.clone(), self.at);
        ahead.count()
    }

    /// Fails when `count` `things` could not come from a block of `compressed` bytes.
    fn holds(&self, count: u64, compressed: u64, things: &str) -> Result<()> {
        let most = ints_within(expanded(compressed));
        if count > most {
            return Err(Error::format(
                self.what.clone(),
                format!(
                    "declares {count} {things}, more than its block of {compressed} compressed bytes holds (at most {most})"
                ),
            ));
        }
        Ok(())
    }

    /// A compressed block (its size, then its bytes) that the reader expands into `expected`
    /// bytes; its bytes.
    fn compressed(&mut self, expected: u64) -> Result<&'a [u8]> {
        let size = self.count()?;
        let block = self.take(size)?;
        self.single_block(block)?;
        if expected > expanded(size) {
            return Err(Error::format(
                self.what.clone(),
                format!(
                    "declares {expected} bytes in a block of {size} compressed bytes (at most {})",
                    expanded(size)
                ),
            ));
        }
        Ok(block)
    }

    /// Fails on a block in chunks (USD's form for data over 2 GB), which the reader does not
    /// read (it stops the process).
    fn single_block(&self, block: &[u8]) -> Result<()> {
        match block.first() {
            Some(&chunks) if chunks != 0 => Err(Error::format(
                self.what.clone(),
                format!(
                    "a compressed block in {chunks} chunks, which the USD reader does not read"
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The fields' `count` value representations from their compressed `block`.
    fn value_reps(&self, block: &[u8], count: u64) -> Result<Vec<u64>> {
        let mut out = vec![0u8; (count as usize).saturating_mul(8)];
        let input = block.get(1..).unwrap_or_default();
        let n = lz4_flex::block::decompress_into(input, &mut out)
            .map_err(|e| Error::format(self.what.clone(), format!("the values' block: {e}")))?;
        Ok(out[..n - n % 8]
            .chunks_exact(8)
            .map(|w| u64::from_le_bytes(w.try_into().expect("eight bytes")))
            .collect())
    }

    /// A compressed block of `count` integers in USD's integer coding.
    fn encoded_ints(&mut self, count: u64) -> Result<()> {
        let size = self.peek_count()?;
        self.holds(count, size, "integers")?;
        self.count()?;
        let block = self.take(size)?;
        self.single_block(block)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A crate file of one section `name` whose body is `body`.
    fn crate_file(name: &str, body: &[u8]) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend_from_slice(&[0, 8, 0, 0, 0, 0, 0, 0]);
        let toc = 32 + body.len() as u64;
        b.extend_from_slice(&toc.to_le_bytes());
        b.extend_from_slice(&[0; 8]);
        b.extend_from_slice(body);
        b.extend_from_slice(&1u64.to_le_bytes());
        let mut raw = [0u8; 16];
        raw[..name.len()].copy_from_slice(name.as_bytes());
        b.extend_from_slice(&raw);
        b.extend_from_slice(&32u64.to_le_bytes());
        b.extend_from_slice(&(body.len() as u64).to_le_bytes());
        b
    }

    fn words(w: &[u64]) -> Vec<u8> {
        w.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    #[test]
    fn sizes_the_bytes_hold_pass() {
        // Three specs in blocks of 10 compressed bytes each.
        let mut body = words(&[3]);
        for _ in 0..3 {
            body.extend(words(&[10]));
            body.extend([0; 10]);
        }
        check(&crate_file("SPECS", &body)).unwrap();
        let mut strings = words(&[2]);
        strings.extend([0; 8]);
        check(&crate_file("STRINGS", &strings)).unwrap();
    }

    #[test]
    fn a_count_past_its_block_is_refused_before_any_allocation() {
        let mut body = words(&[1 << 40, 10]);
        body.extend([0; 10]);
        let e = check(&crate_file("SPECS", &body)).unwrap_err().to_string();
        assert!(
            e.contains("SPECS") && e.contains("1099511627776 integers"),
            "{e}"
        );
        let e = check(&crate_file("STRINGS", &words(&[1 << 26])))
            .unwrap_err()
            .to_string();
        assert!(e.contains("STRINGS") && e.contains("past the file"), "{e}");
        let mut tokens = words(&[2, 1 << 45, 4]);
        tokens.extend([0; 4]);
        let e = check(&crate_file("TOKENS", &tokens))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("TOKENS") && e.contains("compressed bytes"),
            "{e}"
        );
        let e = check(&crate_file("FIELDS", &words(&[1, u64::MAX])))
            .unwrap_err()
            .to_string();
        assert!(e.contains("FIELDS"), "{e}");
    }

    #[test]
    fn element_sizes_are_those_of_the_readers_types() {
        use openusd::gf;
        use std::mem::size_of;
        let sizes = [
            (7, size_of::<gf::f16>()),
            (21, size_of::<gf::Vec2h>()),
            (25, size_of::<gf::Vec3h>()),
            (29, size_of::<gf::Vec4h>()),
            (20, size_of::<gf::Vec2f>()),
            (24, size_of::<gf::Vec3f>()),
            (28, size_of::<gf::Vec4f>()),
            (19, size_of::<gf::Vec2d>()),
            (23, size_of::<gf::Vec3d>()),
            (27, size_of::<gf::Vec4d>()),
            (22, size_of::<gf::Vec2i>()),
            (26, size_of::<gf::Vec3i>()),
            (30, size_of::<gf::Vec4i>()),
            (18, size_of::<gf::Quath>()),
            (17, size_of::<gf::Quatf>()),
            (16, size_of::<gf::Quatd>()),
            (13, size_of::<gf::Mat2d>()),
            (14, size_of::<gf::Mat3d>()),
            (15, size_of::<gf::Matrix4d>()),
        ];
        for (ty, bytes) in sizes {
            assert_eq!(element_bytes(ty), bytes as u64, "type {ty}");
        }
    }

    #[test]
    fn old_versions_and_contents_outside_the_file_are_refused() {
        let mut old = crate_file("SPECS", &words(&[0]));
        old[9] = 3;
        let e = check(&old).unwrap_err().to_string();
        assert!(e.contains("0.3.0"), "{e}");
        let mut far = crate_file("SPECS", &words(&[0]));
        far[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = check(&far).unwrap_err().to_string();
        assert!(e.contains("table of contents"), "{e}");
    }
}
