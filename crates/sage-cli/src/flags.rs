//! Flag values that several commands parse the same way.

use sage_core::{Error, Result};

/// A `WxH` image size (`--size`, `--sizes`) as (width, height).
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| Error::invalid(format!("size '{s}' is not WxH")))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| Error::invalid(format!("size '{s}' is not WxH")))
    };
    Ok((parse(w)?, parse(h)?))
}
