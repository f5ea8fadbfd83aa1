//! Dataset files: our JSONL ([`jsonl`], W frame), the SAGE-Bench GVLN JSON ([`gvln`], W or S
//! frame, stated in the file) and R2R-VLNCE ([`r2r`], Habitat frame). Each is read and written.

pub mod gvln;
pub mod jsonl;
pub mod r2r;
