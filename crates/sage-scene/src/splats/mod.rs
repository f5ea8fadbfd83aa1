//! 3DGS files of every format users bring: what each reader decodes to and each writer encodes
//! from, and the format of a file told from its content (magic bytes, header), never its name.
//!
//! Readers are [`BlockDecoder`]s: a file opened once (its header parsed, its container unpacked)
//! that decodes any run of Gaussians at full precision into [`Gaussian`] records, in parallel
//! blocks. The same decoder fills the compact scene store ([`BlockDecoder::to_gaussians`]) or a
//! full-precision [`SplatTable`] ([`BlockDecoder::to_table`]), which is what `splat convert`
//! writes from, so a conversion never passes values through the compact store's quantisation.
//! Writers take any [`SplatSource`]: the compact store or a table.
//!
//! | format | module | read | write |
//! |---|---|---|---|
//! | standard (Inria) PLY | [`crate::ply::standard`] | yes | yes |
//! | compressed (SuperSplat) PLY | [`crate::ply::compressed`] | yes | yes |
//! | SPZ (Niantic) | [`spz`] | yes | yes |
//! | SOG (PlayCanvas) | [`sog`] | yes | no |
//! | glTF / GLB with `KHR_gaussian_splatting` | [`gltf`] | yes | no |
//! | `.splat` (antimatter15) | [`antimatter`] | yes | no |

use crate::gaussians::{Gaussian, Gaussians};
use rayon::prelude::*;
use sage_core::{Error, Result};

/// Gaussians decoded in blocks of this many, one block per task.
pub const BLOCK: usize = 4096;
/// Gaussians staged at full precision at a time on their way into the compact store
/// (64 KiB of records: they stay in cache).
const STAGE: usize = 256;

/// A 3DGS file opened for decoding.
pub trait BlockDecoder: Sync {
    /// The number of Gaussians in the file.
    fn len(&self) -> usize;

    /// True when the file holds no Gaussian.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The SH degree of the file (0–3).
    fn sh_degree(&self) -> u8;

    /// Decodes Gaussians `start .. start + out.len()` into `out`, at full precision: positions,
    /// the rotation as stored (w, x, y, z; not normalised), natural-log scales, the opacity
    /// logit, `f_dc` and the higher-order SH coefficient-major (`sh_rest[k][channel]`, unused
    /// ones zero), instance 0.
    ///
    /// # Errors
    ///
    /// A value the format cannot hold or a damaged record, naming the Gaussian and field.
    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()>;

    /// [`BlockDecoder::decode`], then [`check_finite`]: refuses what the scene store refuses
    /// ([`BlockDecoder::to_gaussians`]), with the same message.
    ///
    /// # Errors
    ///
    /// As [`BlockDecoder::decode`] and [`check_finite`].
    fn decode_finite(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        self.decode(start, out)?;
        check_finite(start, out)
    }

    /// Every Gaussian at full precision, refusing a value the scene store refuses (so that a
    /// file is read as a table exactly when it loads as a scene).
    ///
    /// # Errors
    ///
    /// As [`BlockDecoder::decode_finite`]: the error of the first block that fails.
    fn to_table(&self) -> Result<SplatTable> {
        let mut gaussians = vec![Gaussian::default(); self.len()];
        decode_blocks(self, 0, &mut gaussians)?;
        Ok(SplatTable {
            gaussians,
            sh_degree: self.sh_degree(),
        })
    }

    /// Every Gaussian in the compact scene store (decoded block by block, never all at full
    /// precision at once).
    ///
    /// # Errors
    ///
    /// As [`BlockDecoder::decode`], and the store's validation.
    fn to_gaussians(&self) -> Result<Gaussians> {
        let mut store = Gaussians::with_len(self.len(), self.sh_degree())?;
        store
            .par_chunks_mut(BLOCK)
            .enumerate()
            .try_for_each(|(b, mut window)| {
                // Decoded through a small buffer that stays in cache, then quantised.
                let mut buffer = vec![Gaussian::default(); STAGE.min(window.len())];
                for at in (0..window.len()).step_by(STAGE) {
                    let staged = &mut buffer[..STAGE.min(window.len() - at)];
                    self.decode(b * BLOCK + at, staged)?;
                    for (j, g) in staged.iter().enumerate() {
                        window.set(at + j, g);
                    }
                }
                Ok::<_, sage_core::Error>(())
            })?;
        store.validate()?;
        Ok(store)
    }
}

/// Decodes Gaussians `start ..` into `out` with [`BlockDecoder::decode_finite`], in parallel
/// blocks of [`BLOCK`] (counted from `start`, which callers keep a multiple of it); of several
/// failing blocks the first is reported, so the error does not depend on thread timing.
///
/// # Errors
///
/// The first failing block's.
pub fn decode_blocks(
    decoder: &(impl BlockDecoder + ?Sized),
    start: usize,
    out: &mut [Gaussian],
) -> Result<()> {
    let results: Vec<Result<()>> = out
        .par_chunks_mut(BLOCK)
        .enumerate()
        .map(|(b, block)| decoder.decode_finite(start + b * BLOCK, block))
        .collect();
    results.into_iter().collect()
}

/// Checks decoded Gaussians `start .. start + rows.len()` with the scene store's own check,
/// [`Gaussians::validate`] (position, scale, opacity and `f_dc` finite, positions within
/// ±10⁷ m), and its message, `vertex[i].field: value is not finite (NaN or infinity)`, with `i`
/// the Gaussian's index in the file: what a scene loader refuses, a conversion refuses too.
/// (Rotations and higher SH are checked by the decoders of the formats that store them as
/// floats.)
///
/// # Errors
///
/// The first Gaussian that fails, naming it and the field.
pub fn check_finite(start: usize, rows: &[Gaussian]) -> Result<()> {
    // One Gaussian at a time through a one-Gaussian store, so the store's message names the
    // index within the file instead of within the block.
    let mut one = Gaussians::with_len(1, 0)?;
    for (j, g) in rows.iter().enumerate() {
        one.set(0, g);
        if let Err(e) = one.validate() {
            let location = e.location();
            return Err(match location.strip_prefix("vertex[0]") {
                Some(field) => Error::format(format!("vertex[{}]{field}", start + j), e.message()),
                None => e,
            });
        }
    }
    Ok(())
}

/// Gaussians at full precision, as a file held them: what conversions pass from reader to
/// writer.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SplatTable {
    /// The Gaussians, in file order.
    pub gaussians: Vec<Gaussian>,
    /// The SH degree (0–3); coefficients above it are zero.
    pub sh_degree: u8,
}

/// What a writer encodes from: Gaussians by index.
pub trait SplatSource: Sync {
    /// The number of Gaussians.
    fn len(&self) -> usize;

    /// True when there is no Gaussian.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The SH degree (0–3).
    fn sh_degree(&self) -> u8;

    /// Gaussian `i`.
    fn get(&self, i: usize) -> Gaussian;

    /// The centre of Gaussian `i` (what a writer orders by, without decoding the rest).
    fn position(&self, i: usize) -> glam::Vec3 {
        self.get(i).position
    }
}

impl SplatSource for SplatTable {
    fn len(&self) -> usize {
        self.gaussians.len()
    }

    fn sh_degree(&self) -> u8 {
        self.sh_degree
    }

    fn get(&self, i: usize) -> Gaussian {
        self.gaussians[i]
    }
}

impl SplatSource for Gaussians {
    fn len(&self) -> usize {
        Gaussians::len(self)
    }

    fn sh_degree(&self) -> u8 {
        Gaussians::sh_degree(self)
    }

    fn get(&self, i: usize) -> Gaussian {
        Gaussians::get(self, i)
    }

    fn position(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::from_array(self.positions[i])
    }
}

pub mod antimatter;
pub mod convert;
pub mod format;
pub mod gltf;
pub mod sog;
pub mod spz;

pub use format::{Format, open, open_named, read_gaussians_file, read_table_file, write_file};

#[cfg(test)]
pub(crate) mod test_files;
