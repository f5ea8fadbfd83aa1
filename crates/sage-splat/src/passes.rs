//! Where a GPU render's time went — the device's stages, its copy of the images to memory the
//! host reads, and the host's unpacking of them — as plain data: [`Backend`](crate::Backend)
//! hands it out whichever executor was built in.

use serde::{Deserialize, Serialize};

/// Most depth slabs a GPU batch renders in, front to back (the CPU renderer takes 8; on a GPU
/// each slab costs a round of dispatches, so fewer).
pub const GPU_SLABS: u32 = 4;

/// Milliseconds of a batch on the GPU renderer: its stages on the device, summed over its depth
/// slabs (from timestamps the device writes between dispatches: [`Backend::time_passes`]), the
/// device's copy of the images to memory the host reads, and the host's unpacking of them.
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
