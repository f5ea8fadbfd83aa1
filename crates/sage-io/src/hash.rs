//! The one stable hash of sage3d: FNV-1a, in 32, 64 and 128 bits.
//!
//! Std's hasher is randomly seeded and may change between releases; what is hashed here ends
//! up in files (input fingerprints, cache keys) and in seeds (a scene's or an episode's), so it
//! must give the same value on every platform and in every release. Not for security.

/// FNV-1a, 32 bits.
pub fn fnv1a32(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811c_9dc5, |h, &b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// FNV-1a, 64 bits: fingerprints of files and seeds derived from names.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    fnv1a64_on(FNV64_OFFSET, bytes)
}

/// FNV-1a 64's start: the hash of nothing.
const FNV64_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a 64 of what gave `h`, followed by `bytes`.
fn fnv1a64_on(h: u64, bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// [`fnv1a64`] as 16 lower-case hex digits, as run records and scene files store it.
pub fn fnv1a64_hex(bytes: &[u8]) -> String {
    format!("{:016x}", fnv1a64(bytes))
}

/// [`fnv1a64_hex`] of the file at `path`, read in pieces (a scene's Gaussians may be hundreds
/// of megabytes).
///
/// # Errors
///
/// The file cannot be read, naming it.
pub fn fnv1a64_file_hex(path: &std::path::Path) -> sage_core::Result<String> {
    use std::io::Read;
    let fail = |e| sage_core::Error::io(path, e);
    let mut file = std::fs::File::open(path).map_err(fail)?;
    let mut buf = vec![0u8; 1 << 20];
    let mut h = FNV64_OFFSET;
    loop {
        let n = file.read(&mut buf).map_err(fail)?;
        if n == 0 {
            return Ok(format!("{h:016x}"));
        }
        h = fnv1a64_on(h, &buf[..n]);
    }
}

/// FNV-1a, 128 bits, fed piece by piece: cache keys over many values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a128(u128);

impl Fnv1a128 {
    const OFFSET: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013B;

    /// The hash of nothing.
    pub fn new() -> Self {
        Fnv1a128(Self::OFFSET)
    }

    /// Feeds `bytes`.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u128::from(b)).wrapping_mul(Self::PRIME);
        }
    }

    /// The hash of everything fed so far.
    pub fn finish(&self) -> u128 {
        self.0
    }
}

impl Default for Fnv1a128 {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published FNV test vectors (Fowler, Noll, Vo; draft-eastlake-fnv).
    #[test]
    fn matches_the_published_test_vectors() {
        assert_eq!(fnv1a32(b""), 0x811c_9dc5);
        assert_eq!(fnv1a32(b"a"), 0xe40c_292c);
        assert_eq!(fnv1a32(b"foobar"), 0xbf9c_f968);
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
        assert_eq!(fnv1a64_hex(b"a"), "af63dc4c8601ec8c");
        let mut h = Fnv1a128::new();
        assert_eq!(h.finish(), 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d);
        h.write(b"a");
        assert_eq!(h.finish(), 0xd228_cb69_6f1a_8caf_7891_2b70_4e4a_8964);
    }

    #[test]
    fn a_file_hashes_as_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        // Past one read's piece, so the pieces are chained.
        let bytes: Vec<u8> = (0..(3 << 20) + 17)
            .map(|i: u32| (i * 7 % 251) as u8)
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(fnv1a64_file_hex(&path).unwrap(), fnv1a64_hex(&bytes));
        let e = fnv1a64_file_hex(&dir.path().join("missing")).unwrap_err();
        assert!(e.to_string().contains("missing"), "{e}");
    }

    #[test]
    fn feeding_in_pieces_equals_feeding_at_once() {
        let (mut a, mut b) = (Fnv1a128::new(), Fnv1a128::new());
        a.write(b"foo");
        a.write(b"bar");
        b.write(b"foobar");
        assert_eq!(a, b);
    }
}
