//! The GPU time of the GPU renderer's stages, as plain data: [`Backend`](crate::Backend) hands
//! it out whichever executor was built in.

use serde::{Deserialize, Serialize};

/// GPU milliseconds of a batch's stages on the GPU renderer, summed over its depth slabs (from
/// timestamps the device writes between dispatches: [`Backend::time_passes`]).
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
}

impl std::fmt::Display for PassTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "set-up {:.1} + project {:.1} + depth sort {:.1} + bin {:.1} + raster {:.1} + compose {:.1} ms",
            self.setup_ms,
            self.project_ms,
            self.depth_sort_ms,
            self.bin_ms,
            self.raster_ms,
            self.compose_ms
        )
    }
}
