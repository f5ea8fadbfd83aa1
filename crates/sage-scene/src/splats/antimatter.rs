//! antimatter15's `.splat` (the format of the `antimatter15/splat` WebGL viewer and its
//! `convert.py`): no header, no magic, 32 bytes per Gaussian, little-endian:
//!
//! | bytes | field | encoding (writer → this reader) |
//! |---|---|---|
//! | 0–11 | position x, y, z | `f32` |
//! | 12–23 | scale x, y, z | `f32`, **linear** (`exp(scale_i)`) → `ln` |
//! | 24–26 | colour r, g, b | `u8`: `(0.5 + SH_C0 · f_dc) · 255` clipped → `f_dc = (u/255 − 0.5) / SH_C0` |
//! | 27 | opacity | `u8`: `sigmoid(opacity) · 255` → logit of `u/255`, clamped to ±[`MAX_LOGIT`] |
//! | 28–31 | rotation w, x, y, z | `u8`: `q/‖q‖ · 128 + 128` clipped → `(u − 128) / 128` |
//!
//! `convert.py` truncates the colour, opacity and rotation bytes and the viewer's own PLY import
//! rounds them; both viewers decode them as above, as does this reader. Positions are in the
//! PLY's frame (no axis change). The writers sort by size × opacity, so the order is not the
//! source PLY's.
//!
//! What is lost: every SH coefficient above degree 0; colour and opacity to 8 bits (1/255 in
//! colour, so `f_dc` within 1/(255 · SH_C0) ≈ 0.014 and alpha within 1/255 — the logit far
//! less precisely near 0 and 1); the rotation to 8 bits per component (≈ 1/128, and
//! normalised, so its length and sign are the writer's); colours outside \[0, 1\] are clipped.
//! A rotation of four 128s (zero) reads as the identity, as both viewers draw it.

use crate::gaussians::{Gaussian, SH_C0};
use crate::ply::standard::MAX_LOGIT;
use crate::splats::BlockDecoder;
use glam::{Quat, Vec3};
use sage_core::{Error, Result};

/// Bytes per Gaussian.
pub const RECORD: usize = 32;
/// The log-scale of a zero linear scale: the log of the smallest normal `f32`, finite.
const MIN_LOG_SCALE: f32 = -87.336_55;
/// How many leading records [`sniff`] checks.
const SNIFF_RECORDS: usize = 16;

/// A `.splat` file opened for decoding: the bytes, borrowed.
#[derive(Debug, Clone, Copy)]
pub struct SplatDecoder<'a> {
    bytes: &'a [u8],
}

impl<'a> SplatDecoder<'a> {
    /// Opens `.splat` bytes (nothing is decoded until [`BlockDecoder::decode`]).
    ///
    /// # Errors
    ///
    /// As [`check_length`].
    pub fn open(bytes: &'a [u8]) -> Result<SplatDecoder<'a>> {
        check_length(bytes)?;
        Ok(SplatDecoder { bytes })
    }
}

/// Checks that `bytes` are a whole, non-zero number of records.
///
/// # Errors
///
/// An empty file, or one that ends inside a record (`truncated: expected N bytes …, got M`).
pub fn check_length(bytes: &[u8]) -> Result<()> {
    let len = bytes.len();
    if len == 0 {
        return Err(Error::format(
            "file length",
            format!("empty: a .splat holds {RECORD}-byte records"),
        ));
    }
    if !len.is_multiple_of(RECORD) {
        let records = len.div_ceil(RECORD);
        return Err(Error::format(
            "file length",
            format!(
                "truncated: {len} bytes is not a whole number of {RECORD}-byte .splat records \
                 (expected {} bytes for {records} records, got {len}; the last record has {} of \
                 its {RECORD} bytes)",
                records * RECORD,
                len % RECORD
            ),
        ));
    }
    Ok(())
}

fn f32_at(r: &[u8; RECORD], at: usize) -> f32 {
    f32::from_le_bytes([r[at], r[at + 1], r[at + 2], r[at + 3]])
}

/// Decodes record `i` (see the module docs for the encoding).
fn decode_record(i: usize, r: &[u8; RECORD]) -> Result<Gaussian> {
    let position = Vec3::new(f32_at(r, 0), f32_at(r, 4), f32_at(r, 8));
    if !position.is_finite() {
        return Err(Error::format(
            format!("record[{i}].position"),
            "is not finite (NaN or infinity)",
        ));
    }
    let scale = Vec3::new(f32_at(r, 12), f32_at(r, 16), f32_at(r, 20));
    if !scale.is_finite() || scale.min_element() < 0.0 {
        return Err(Error::format(
            format!("record[{i}].scale"),
            format!("{scale} is not finite and non-negative (.splat scales are linear)"),
        ));
    }
    // A zero scale (a flat Gaussian) keeps a finite log.
    let log_scale = scale.to_array().map(|s| {
        if s > 0.0 {
            s.ln().max(MIN_LOG_SCALE)
        } else {
            MIN_LOG_SCALE
        }
    });
    let unit = |b: u8| f64::from(b) / 255.0;
    let sh_dc = [r[24], r[25], r[26]].map(|b| ((unit(b) - 0.5) / f64::from(SH_C0)) as f32);
    let alpha = unit(r[27]);
    let opacity_logit =
        (alpha.ln() - (-alpha).ln_1p()).clamp(-f64::from(MAX_LOGIT), f64::from(MAX_LOGIT)) as f32;
    let [w, x, y, z] = [r[28], r[29], r[30], r[31]].map(|b| (f32::from(b) - 128.0) / 128.0);
    let rotation = if [w, x, y, z] == [0.0; 4] {
        Quat::IDENTITY
    } else {
        Quat::from_xyzw(x, y, z, w)
    };
    Ok(Gaussian {
        position,
        rotation,
        log_scale: Vec3::from_array(log_scale),
        opacity_logit,
        sh_dc,
        sh_rest: [[0.0; 3]; 15],
        instance: 0,
    })
}

impl BlockDecoder for SplatDecoder<'_> {
    fn len(&self) -> usize {
        self.bytes.len() / RECORD
    }

    fn sh_degree(&self) -> u8 {
        0
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        let records = start
            .checked_add(out.len())
            .filter(|&end| end <= self.len())
            .and_then(|end| self.bytes.get(start * RECORD..end * RECORD))
            .ok_or_else(|| {
                Error::invalid(format!(
                    "Gaussians {start}..{} requested from a .splat of {}",
                    start.saturating_add(out.len()),
                    self.len()
                ))
            })?;
        let (chunks, _) = records.as_chunks::<RECORD>();
        for (j, (g, r)) in out.iter_mut().zip(chunks).enumerate() {
            *g = decode_record(start + j, r)?;
        }
        Ok(())
    }
}

/// A weak test, tried after every format with a magic number: the length is a non-zero
/// multiple of 32 and the first records look like Gaussians (finite positions within 10⁷,
/// scales in \[0, 10⁶), rotation bytes of a unit quaternion within 8-bit rounding).
pub fn sniff(bytes: &[u8]) -> bool {
    check(bytes).is_ok()
}

/// Why `bytes` are not a `.splat` by [`sniff`]'s test, for a file whose name says it is one
/// (`.splat` has no magic, so the test that tells it from other files is also what is wrong
/// with a damaged one).
///
/// # Errors
///
/// As [`check_length`], or the first of the leading records that does not look like a
/// Gaussian, naming it and the field (a non-finite value with the decoder's own message).
pub fn check(bytes: &[u8]) -> Result<()> {
    check_length(bytes)?;
    let (chunks, _) = bytes.as_chunks::<RECORD>();
    for (i, r) in chunks.iter().take(SNIFF_RECORDS).enumerate() {
        // Non-finite and negative values, as decoding refuses them.
        decode_record(i, r)?;
        let bad = |field: &str, why: String| {
            Err(Error::format(
                format!("record[{i}].{field}"),
                format!("{why}: not a .splat record"),
            ))
        };
        let position = Vec3::new(f32_at(r, 0), f32_at(r, 4), f32_at(r, 8));
        if position.abs().max_element() >= 1e7 {
            return bad("position", format!("{position} is beyond ±10⁷"));
        }
        let scale = Vec3::new(f32_at(r, 12), f32_at(r, 16), f32_at(r, 20));
        if scale.max_element() >= 1e6 {
            return bad("scale", format!("{scale} is 10⁶ or more"));
        }
        let bytes = [r[28], r[29], r[30], r[31]];
        let norm2: f32 = bytes
            .map(|b| (f32::from(b) - 128.0) / 128.0)
            .iter()
            .map(|v| v * v)
            .sum();
        if !(0.8..=1.2).contains(&norm2) {
            return bad(
                "rotation",
                format!("bytes {bytes:?} hold no unit quaternion (squared length {norm2})"),
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splats::gltf::tests::read_ply;
    use proptest::prelude::*;

    /// A `.splat` of `gaussians` by `convert.py`'s definition (bytes truncated after clipping),
    /// in the given order.
    fn write_splat(gaussians: &[Gaussian]) -> Vec<u8> {
        let byte = |v: f64| v.clamp(0.0, 255.0) as u8; // numpy's clip then astype(uint8)
        let mut out = Vec::with_capacity(gaussians.len() * RECORD);
        for g in gaussians {
            for v in g.position.to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for v in g.log_scale.to_array() {
                out.extend_from_slice(&v.exp().to_le_bytes());
            }
            for c in g.sh_dc {
                out.push(byte((0.5 + f64::from(SH_C0) * f64::from(c)) * 255.0));
            }
            out.push(byte(255.0 / (1.0 + (-f64::from(g.opacity_logit)).exp())));
            let q = g.rotation.as_dquat();
            let q = q / q.length();
            for v in [q.w, q.x, q.y, q.z] {
                out.push(byte(v * 128.0 + 128.0));
            }
        }
        out
    }

    fn sigmoid(x: f32) -> f64 {
        1.0 / (1.0 + (-f64::from(x)).exp())
    }

    #[test]
    fn decodes_a_splat_written_from_the_ply() {
        for stem in ["random_3k_sh0", "random_4k_sh3"] {
            let (ply, _) = read_ply(&format!("{stem}.ply"));
            let bytes = write_splat(&ply);
            assert!(sniff(&bytes));
            let d = SplatDecoder::open(&bytes).unwrap();
            assert_eq!((d.len(), d.sh_degree()), (ply.len(), 0));
            let out = d.to_table().unwrap().gaussians;
            let (mut pos, mut scale, mut color, mut alpha, mut rot) =
                (0f32, 0f32, 0f64, 0f64, 0f64);
            for (g, r) in out.iter().zip(&ply) {
                pos = pos.max((g.position - r.position).abs().max_element());
                // exp in f32, then ln: a few f32 ulps.
                scale = scale.max((g.log_scale - r.log_scale).abs().max_element());
                for c in 0..3 {
                    let want = (0.5 + f64::from(SH_C0) * f64::from(r.sh_dc[c])).clamp(0.0, 1.0);
                    let got = 0.5 + f64::from(SH_C0) * f64::from(g.sh_dc[c]);
                    color = color.max((got - want).abs());
                }
                alpha = alpha.max((sigmoid(g.opacity_logit) - sigmoid(r.opacity_logit)).abs());
                let q = r.rotation.as_dquat();
                let q = q / q.length();
                let got = g.rotation.as_dquat();
                rot = rot.max((got - q).to_array().iter().fold(0.0, |m, v| v.abs().max(m)));
                assert_eq!(g.sh_rest, [[0.0; 3]; 15]);
            }
            println!(
                "{stem}.splat vs {stem}.ply: position {pos:e}, log-scale {scale:e}, colour \
                 {color:e}, alpha {alpha:e}, rotation {rot:e} (per component)"
            );
            assert_eq!(pos, 0.0);
            assert!(scale < 1e-6, "{scale}");
            // Truncation: up to one step of 1/255 (1/128 for the rotation) below.
            assert!(color <= 1.0 / 255.0 + 1e-6, "{color}");
            assert!(alpha <= 1.0 / 255.0 + 1e-6, "{alpha}");
            assert!(rot <= 1.0 / 128.0 + 1e-6, "{rot}");
        }
    }

    #[test]
    fn lengths_and_ranges() {
        assert!(SplatDecoder::open(&[]).is_err());
        let e = SplatDecoder::open(&[0; 33]).unwrap_err().to_string();
        assert!(
            e.contains("truncated") && e.contains("expected 64 bytes for 2 records, got 33"),
            "{e}"
        );
        let (ply, _) = read_ply("random_3k_sh0.ply");
        let bytes = write_splat(&ply[..10]);
        let d = SplatDecoder::open(&bytes).unwrap();
        let mut out = vec![Gaussian::default(); 4];
        d.decode(6, &mut out).unwrap();
        assert!(d.decode(7, &mut out).is_err());
        assert!(d.decode(usize::MAX, &mut out).is_err());
    }

    #[test]
    fn damaged_records_are_named() {
        let (ply, _) = read_ply("random_3k_sh0.ply");
        let mut bytes = write_splat(&ply[..4]);
        bytes[2 * RECORD + 16..2 * RECORD + 20].copy_from_slice(&(-1.0f32).to_le_bytes());
        let e = SplatDecoder::open(&bytes)
            .unwrap()
            .to_table()
            .unwrap_err()
            .to_string();
        assert!(e.contains("record[2].scale"), "{e}");
        bytes[RECORD + 4..RECORD + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        let e = SplatDecoder::open(&bytes)
            .unwrap()
            .to_table()
            .unwrap_err()
            .to_string();
        assert!(e.contains("record[1].position"), "{e}");
    }

    #[test]
    fn edge_bytes() {
        let mut r = [0u8; RECORD];
        r[28..32].copy_from_slice(&[128; 4]);
        r[27] = 255;
        let g = decode_record(0, &r).unwrap();
        assert_eq!(g.rotation, Quat::IDENTITY);
        assert_eq!(g.opacity_logit, MAX_LOGIT);
        assert_eq!(g.log_scale, Vec3::splat(MIN_LOG_SCALE));
        r[27] = 0;
        assert_eq!(decode_record(0, &r).unwrap().opacity_logit, -MAX_LOGIT);
    }

    #[test]
    fn sniff_rejects_other_files() {
        for name in [
            "random_3k_sh0.ply",
            "random_3k_sh0.glb",
            "random_3k_sh0.spz",
        ] {
            let path = crate::splats::gltf::tests::testdata(name);
            let bytes = std::fs::read(path).unwrap();
            let cut = bytes.len() / RECORD * RECORD;
            assert!(!sniff(&bytes[..cut]), "{name}");
        }
        assert!(!sniff(&[0; 64]));
    }

    proptest! {
        #[test]
        fn any_bytes_decode_or_fail_cleanly(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            let _ = sniff(&bytes);
            if let Ok(d) = SplatDecoder::open(&bytes) {
                prop_assert_eq!(d.len() * RECORD, bytes.len());
                let _ = d.to_table();
            }
        }
    }
}
