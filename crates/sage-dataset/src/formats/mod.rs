//! Dataset files: our JSONL ([`jsonl`], W frame), the SAGE-Bench GVLN JSON ([`gvln`], W or S
//! frame, stated in the file), R2R-VLNCE ([`r2r`], Habitat frame) and GN-Bench's Parquet splits
//! ([`gnbench`], GN-Bench's frame, a translation of W per scene). Each is read and written.

pub mod gnbench;
pub mod gvln;
pub mod jsonl;
pub mod r2r;
