//! The files of `testdata/splats` for the readers' tests. A file of its own so that the
//! `splats` module itself never imports the PLY readers, which import it.

use super::{BlockDecoder, SplatTable};
use crate::ply::{header::parse_header, standard::StandardDecoder};

/// A standard PLY (the reference tool's decodings are) at full precision.
pub fn standard_table(bytes: &[u8]) -> SplatTable {
    let header = parse_header(bytes).expect("a PLY header");
    StandardDecoder::open(&header, bytes)
        .and_then(|d| d.to_table())
        .expect("a standard 3DGS PLY")
}
