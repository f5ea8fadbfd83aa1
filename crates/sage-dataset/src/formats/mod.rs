//! Dataset files: our JSONL ([`jsonl`], W frame), the SAGE-Bench GVLN JSON ([`gvln`], W or S
//! frame, stated in the file), R2R-VLNCE ([`r2r`], Habitat frame) and GN-Bench's Parquet splits
//! ([`gnbench`], GN-Bench's frame, a translation of W per scene). Each is read and written.

pub mod gnbench;
pub mod gvln;
pub mod jsonl;
pub mod r2r;

use crate::Episode;

/// The episodes of a GVLN or R2R-VLNCE file, and which of them it gave no asset slice.
///
/// The published files of those benchmarks hold no scene object counts, so such an episode
/// reads as `medium` until its scene's folder tells ([`crate::import::import`] with a scenes
/// folder re-tags it by [`crate::slices::scene_assets_slice`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ReadEpisodes {
    /// The episodes, in file order.
    pub episodes: Vec<Episode>,
    /// The indices into `episodes` of those without sage3d's asset slice, in order.
    pub assets_unknown: Vec<usize>,
}
