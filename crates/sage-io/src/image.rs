//! Images encoded in memory: PNG (8- or 16-bit) and baseline JPEG, for the files, frames and
//! responses every pipeline writes.

use sage_core::{Error, Result};

/// Encodes an 8- or 16-bit PNG with fast compression (frames are written by the million).
/// `data` holds the rows top to bottom, samples big-endian for 16 bits.
///
/// # Errors
///
/// A size beyond PNG's sides or data that does not fill the image.
pub fn encode_png(
    width: usize,
    height: usize,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let err = |e: png::EncodingError| Error::invalid(format!("PNG encoding: {e}"));
    let (w32, h32) = (
        u32::try_from(width).map_err(|_| Error::invalid("image too wide"))?,
        u32::try_from(height).map_err(|_| Error::invalid("image too tall"))?,
    );
    let mut enc = png::Encoder::new(&mut out, w32, h32);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.set_compression(png::Compression::Fast);
    let mut writer = enc.write_header().map_err(err)?;
    writer.write_image_data(data).map_err(err)?;
    writer.finish().map_err(err)?;
    Ok(out)
}

/// Encodes a row-major 8-bit RGB image as PNG.
///
/// # Errors
///
/// As [`encode_png`].
pub fn encode_rgb_png(width: usize, height: usize, rgb: &[u8]) -> Result<Vec<u8>> {
    encode_png(
        width,
        height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        rgb,
    )
}

/// Encodes a row-major RGB image as a baseline JPEG of `quality` (1–100).
///
/// # Errors
///
/// A size that does not match the pixels or exceeds JPEG's 65,535-pixel sides.
pub fn encode_jpeg(rgb: &[u8], width: usize, height: usize, quality: u8) -> Result<Vec<u8>> {
    let side = |n: usize| u16::try_from(n).ok().filter(|n| *n > 0);
    let (Some(w), Some(h)) = (side(width), side(height)) else {
        return Err(Error::invalid(format!(
            "jpeg: image size {width}×{height} is not 1–65535 pixels a side"
        )));
    };
    if rgb.len() != width * height * 3 {
        return Err(Error::invalid(format!(
            "jpeg: {} bytes are not a {width}×{height} RGB image",
            rgb.len()
        )));
    }
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, quality.clamp(1, 100))
        .encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| Error::invalid(format!("jpeg: {e}")))?;
    Ok(out)
}
