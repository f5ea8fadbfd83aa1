//! Animated GIFs: one writer for every animation sage3d makes (the render's turntable, the
//! training-data preview, the report's episode videos), so they loop, quantise and fail alike.
//!
//! Each frame gets its own palette (its colours exactly when it has 256 or fewer, else
//! NeuQuant's 256 at [`SPEED`]); the encoding is deterministic, so the same frames give the
//! same bytes.

use std::io::{Error, ErrorKind, Result, Write};

/// NeuQuant's sampling step for frames of more than 256 colours (1 best, 30 fastest): fast,
/// and good enough to look at.
pub const SPEED: i32 = 10;

/// An animated GIF being written to `W`, looping forever; frames of RGB pixels are added one
/// at a time, so a caller can make each as it goes.
pub struct GifWriter<W: Write> {
    encoder: ::gif::Encoder<W>,
    width: u16,
    height: u16,
}

impl<W: Write> std::fmt::Debug for GifWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GifWriter")
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl<W: Write> GifWriter<W> {
    /// Starts a looping GIF of `width × height` pixels on `out`.
    ///
    /// # Errors
    ///
    /// A size of 0 or over 65535 pixels on a side (`InvalidInput`), or a write error.
    pub fn new(out: W, width: usize, height: usize) -> Result<Self> {
        let side = |v: usize| u16::try_from(v).ok().filter(|v| *v > 0);
        let (Some(w), Some(h)) = (side(width), side(height)) else {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("{width}×{height} pixels is not a GIF size (1 to 65535 a side)"),
            ));
        };
        let mut encoder = ::gif::Encoder::new(out, w, h, &[]).map_err(Error::other)?;
        encoder
            .set_repeat(::gif::Repeat::Infinite)
            .map_err(Error::other)?;
        Ok(GifWriter {
            encoder,
            width: w,
            height: h,
        })
    }

    /// Adds a frame of RGB pixels (rows top to bottom, the writer's size) shown for `delay_cs`
    /// hundredths of a second.
    ///
    /// # Errors
    ///
    /// Pixels that are not `width × height × 3` bytes (`InvalidInput`), or a write error.
    pub fn frame(&mut self, rgb: &[u8], delay_cs: u16) -> Result<()> {
        let (w, h) = (self.width, self.height);
        if rgb.len() != w as usize * h as usize * 3 {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!(
                    "a GIF frame of {w}×{h} pixels needs {} bytes of RGB, not {}",
                    w as usize * h as usize * 3,
                    rgb.len()
                ),
            ));
        }
        let mut frame = ::gif::Frame::from_rgb_speed(w, h, rgb, SPEED);
        frame.delay = delay_cs;
        self.encoder.write_frame(&frame).map_err(Error::other)
    }

    /// Ends the GIF (its trailer) and hands back the output.
    ///
    /// # Errors
    ///
    /// A write error.
    pub fn finish(self) -> Result<W> {
        self.encoder.into_inner().map_err(Error::other)
    }
}

/// The bytes of a looping GIF of `width × height` pixels showing `frames` (RGB pixels and
/// the delay of each, hundredths of a second) in order.
///
/// # Errors
///
/// As [`GifWriter::new`] and [`GifWriter::frame`].
pub fn encode<'a>(
    width: usize,
    height: usize,
    frames: impl IntoIterator<Item = (&'a [u8], u16)>,
) -> Result<Vec<u8>> {
    let mut writer = GifWriter::new(Vec::new(), width, height)?;
    for (rgb, delay) in frames {
        writer.frame(rgb, delay)?;
    }
    writer.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Decodes a GIF into its frames as (RGBA pixels, delay), with its size.
    fn decode(bytes: &[u8]) -> (u16, u16, Vec<(Vec<u8>, u16)>) {
        let mut opts = ::gif::DecodeOptions::new();
        opts.set_color_output(::gif::ColorOutput::RGBA);
        let mut d = opts.read_info(bytes).unwrap();
        let (w, h) = (d.width(), d.height());
        let mut frames = Vec::new();
        while let Some(f) = d.read_next_frame().unwrap() {
            frames.push((f.buffer.to_vec(), f.delay));
        }
        (w, h, frames)
    }

    #[test]
    fn frames_of_few_colours_come_back_exactly_with_their_delays() {
        let a: Vec<u8> = (0..6).flat_map(|k| [k * 40, 255 - k * 40, 7]).collect();
        let b: Vec<u8> = a.iter().rev().copied().collect();
        let bytes = encode(3, 2, [(&a[..], 25), (&b[..], 200)]).unwrap();
        let (w, h, frames) = decode(&bytes);
        assert_eq!((w, h), (3, 2));
        assert_eq!(frames.len(), 2);
        for ((rgba, delay), (rgb, want)) in frames.iter().zip([(&a, 25), (&b, 200)]) {
            let back: Vec<u8> = rgba.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
            assert_eq!(&back, rgb);
            assert_eq!(*delay, want);
        }
        assert_eq!(encode(3, 2, [(&a[..], 25), (&b[..], 200)]).unwrap(), bytes);
    }

    #[test]
    fn bad_sizes_are_errors_not_panics() {
        let e = encode(0, 2, []).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        assert!(encode(70_000, 1, []).is_err());
        let e = encode(2, 2, [(&[0u8; 11][..], 1)]).unwrap_err();
        assert!(e.to_string().contains("12 bytes"), "{e}");
    }
}
