//! Where a GPU render's time went — the device's stages, its copy of the images to memory the
//! host reads, and the host's unpacking of them — as plain data: [`Backend`](crate::Backend)
//! hands it out whichever executor was built in.

use sage_core::{Error, Result};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Most depth slabs a GPU batch renders in, front to back (the CPU renderer takes 8; on a GPU
/// each slab costs a round of dispatches, so fewer).
pub const GPU_SLABS: u32 = 4;

/// Visible chunks (of 256 Gaussians) below which a camera saves too little behind finished
/// tiles to pay for more than one GPU slab: its chunks then all go to its batch's first slab,
/// and a batch all of whose cameras see fewer is rendered in one slab. In more slabs a
/// chunk that spans several is marked in each, and most chunks of a view that sees little do
/// (its depth cuts fall among few chunks). Measured on lavapipe, 224² views of a 1M-Gaussian
/// home frame by frame: those facing a near wall (146–317 chunks) took 0.46–0.93 times as
/// long in one slab as in four, those of over 950 chunks 1.2–3.9 times; between, even.
pub const GPU_FEW_CHUNKS: u32 = 768;

/// How the GPU renderer's kernels that come in two shapes (the radix sort's two, and `mark`)
/// share their work between threads. Both shapes form the same bytes (a GPU test holds them to
/// it); a renderer takes the one for its adapter ([`KernelShape::for_adapter`]) unless told.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelShape {
    /// For hardware GPUs: a thread per element (a pair to sort, a Gaussian of a chunk), which
    /// rank or mark themselves together through workgroup memory or atomics.
    Lanes,
    /// For CPU drivers (lavapipe): a thread per run of elements (a block of 1,024 pairs, a
    /// chunk's 256 Gaussians), going through it one element at a time with no atomics and no
    /// barriers. A CPU driver runs a workgroup's threads a vector of lanes at a time and reads
    /// workgroup or storage memory at an index it cannot prove uniform lane by lane, so these
    /// do far fewer such reads; a hardware GPU would leave most of its lanes idle.
    Runs,
}

impl KernelShape {
    /// The shape for an adapter: [`KernelShape::Runs`] on a software one (a CPU driver).
    pub fn for_adapter(software: bool) -> KernelShape {
        if software {
            KernelShape::Runs
        } else {
            KernelShape::Lanes
        }
    }
}

/// The GPU renderer's blending kernel. Both blend every pixel by the same rules in the same
/// order and form the same bytes (a GPU test holds them to it); they differ in how threads share
/// a tile, which suits CPU drivers and hardware GPUs differently.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Blending {
    /// Shaped for CPU drivers (lavapipe): 32 threads per tile, each blending a column of eight
    /// pixels, eight threads per block of 8×8 stepping through only the splats whose box
    /// reaches their block, so a splat read from the textures serves eight pixels.
    #[default]
    Blocks,
    /// Shaped for hardware GPUs: 64 threads per tile, each blending a column of four pixels,
    /// all stepping through the tile's whole list together in batches of 64 splats read into
    /// workgroup memory (3 KB for two warps, where `Blocks` holds about 150 bytes for one).
    Columns,
}

impl Blending {
    /// Every kernel, in the order of [`Blending::NAMES`].
    pub const ALL: [Blending; 2] = [Blending::Blocks, Blending::Columns];

    /// The names accepted by [`Blending::from_str`], in the order of the variants.
    pub const NAMES: [&'static str; 2] = ["blocks", "columns"];
}

impl fmt::Display for Blending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(Self::NAMES[*self as usize])
    }
}

impl FromStr for Blending {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        // One list of names for parsing and printing.
        Self::NAMES
            .iter()
            .zip(Self::ALL)
            .find_map(|(name, b)| (*name == s).then_some(b))
            .ok_or_else(|| {
                Error::invalid(format!(
                    "blending: unknown kernel {s:?} (expected one of {})",
                    Self::NAMES.join(", ")
                ))
            })
    }
}

impl TryFrom<String> for Blending {
    type Error = Error;

    fn try_from(s: String) -> Result<Self> {
        s.parse()
    }
}

impl From<Blending> for String {
    fn from(b: Blending) -> String {
        b.to_string()
    }
}

/// Milliseconds of a batch on the GPU renderer: its stages on the device, summed over its depth
/// slabs (from timestamps the device writes between dispatches:
/// [`Backend::time_passes`](crate::Backend::time_passes)), the device's copy of the images to
/// memory the host reads, and the host's unpacking of them.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PassTimes {
    /// Clearing, culling the chunks and cutting the slabs.
    pub setup_ms: f64,
    /// Selecting the chunks, marking and projecting the splats.
    pub project_ms: f64,
    /// The radix sort by depth.
    pub depth_sort_ms: f64,
    /// Binning into tiles, the sort by tile and the tiles' ranges.
    pub bin_ms: f64,
    /// Blending.
    pub raster_ms: f64,
    /// Composing the images.
    pub compose_ms: f64,
    /// The device's copy of the images asked for to memory the host reads (timestamps around
    /// the copy, where the device writes them outside passes; 0 where it does not).
    #[serde(default)]
    pub read_back_ms: f64,
    /// Host time turning the read-back into [`RenderOutput`](crate::RenderOutput)s (wall time,
    /// cameras unpacked in parallel).
    #[serde(default)]
    pub unpack_ms: f64,
}

impl std::fmt::Display for PassTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "set-up {:.1} + project {:.1} + depth sort {:.1} + bin {:.1} + raster {:.1} + compose {:.1} ms, read-back copy {:.1} ms; unpacking on the host {:.1} ms",
            self.setup_ms,
            self.project_ms,
            self.depth_sort_ms,
            self.bin_ms,
            self.raster_ms,
            self.compose_ms,
            self.read_back_ms,
            self.unpack_ms
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blending_names_round_trip_and_unknown_ones_are_refused() {
        for (name, b) in Blending::NAMES.iter().zip(Blending::ALL) {
            assert_eq!(name.parse::<Blending>().unwrap(), b);
            assert_eq!(b.to_string(), *name);
            assert_eq!(serde_json::to_string(&b).unwrap(), format!("\"{name}\""));
        }
        let e = "pixels".parse::<Blending>().unwrap_err();
        assert!(e.message().contains("blocks, columns"), "{e}");
    }
}
