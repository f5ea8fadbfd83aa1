//! `splat convert`: any readable 3DGS file to a writable format, at full precision in between,
//! with a statement of what the target format cannot hold. Standard PLY output is streamed
//! block by block from the decoder; the other writers take the whole table.

use super::format::open_named;
use super::{BlockDecoder, Format, SplatTable, decode_blocks, write_file};
use crate::gaussians::{Gaussian, sh_rest_count};
use crate::mapped::{refuse_non_file, with_mapped_file};
use crate::ply::{SplatLayout, compressed, standard};
use sage_core::{Error, Result};
use std::io::Write;
use std::path::Path;

/// How to convert.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ConvertOptions {
    /// Keep SH bands up to this degree (`None`: all the input has); never more than the input.
    pub sh_degree: Option<u8>,
    /// Replace an existing output file.
    pub force: bool,
}

/// What [`convert`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertReport {
    /// The input's format, told from its content.
    pub input_format: Format,
    /// The output's format, from its name.
    pub output_format: Format,
    /// Gaussians converted.
    pub gaussians: usize,
    /// SH degree of the input.
    pub sh_degree_in: u8,
    /// SH degree written.
    pub sh_degree_out: u8,
    /// What the output does not hold of the input, one sentence each (empty: nothing lost).
    pub losses: Vec<String>,
    /// True when the output holds the Gaussians in another order than the input: a compressed
    /// PLY of an input whose 256-Gaussian chunks were loose is written along a Z-order curve
    /// ([`ply::compressed::write_order`](crate::ply::compressed::write_order)).
    pub reordered: bool,
}

/// Converts `input` (any format sage3d reads) to `output` (standard PLY, compressed PLY or SPZ,
/// from its name), passing every value at full precision from reader to writer.
///
/// A value the scene loaders refuse (a NaN or infinite position, scale, opacity or colour:
/// [`super::check_finite`], the loaders' own check and message) is refused here too, for every
/// input and output format, and nothing is written: a conversion never hands on a file that
/// sage3d would not load, nor quantises a NaN into some other value.
///
/// # Errors
///
/// An output name that names no writable format, an input that is a directory, an existing
/// output without `force`, the input and output being one file, an SH degree above the
/// input's, a value that is not finite (naming the input, the Gaussian and the field), or the
/// reader's and writer's errors (naming the file).
pub fn convert(input: &Path, output: &Path, options: ConvertOptions) -> Result<ConvertReport> {
    let output_format = Format::from_output_name(output)?;
    // Refused before the output is claimed, as reading it would refuse it.
    refuse_non_file(input)?;
    sage_io::run::claim_output_file(output, &[input.to_path_buf()], "the input", options.force)?;
    // Errors of the input name it; the output's name the output already.
    with_mapped_file(input, |bytes| {
        convert_bytes(bytes, input, output, output_format, options.sh_degree)
    })
}

/// [`convert`] of the bytes of the file `input`.
fn convert_bytes(
    bytes: &[u8],
    input: &Path,
    output: &Path,
    output_format: Format,
    sh_degree: Option<u8>,
) -> Result<ConvertReport> {
    let (decoder, input_format) = open_named(bytes, Some(input))?;
    let sh_degree_in = decoder.sh_degree();
    let sh_degree_out = match sh_degree {
        Some(d) if d > sh_degree_in => {
            return Err(Error::invalid(format!(
                "`sh_degree` {d}: the input has SH degree {sh_degree_in}; bands can be dropped, not added"
            )));
        }
        Some(d) => d,
        None => sh_degree_in,
    };
    let mut reordered = false;
    let mut fraction_bits = None;
    if output_format == Format::Ply(SplatLayout::Standard) {
        stream_standard(decoder.as_ref(), sh_degree_out, output)?;
    } else {
        // Every value checked before anything is written.
        let mut table = decoder.to_table()?;
        drop_sh_bands(&mut table, sh_degree_out);
        if output_format == Format::Ply(SplatLayout::Compressed) {
            // The order taken once, to write and to report.
            let order = compressed::write_order(&table);
            reordered = order.is_some();
            sage_io::files::write_atomic(output, |w| {
                compressed::write_in_order(w, &table, order.as_deref())
            })?;
        } else {
            write_file(output, &table, output_format)?;
            if output_format == Format::Spz {
                // A scene beyond ±2048 m was written with coarser steps than `losses` states.
                fraction_bits = Some(super::spz::position_fraction_bits(&table)?);
            }
        }
    }
    let mut losses = losses(output_format, sh_degree_in, sh_degree_out);
    if let Some(bits) = fraction_bits
        && let Some(line) = losses.iter_mut().find(|l| l.starts_with(SPZ_POSITIONS))
    {
        *line = spz_position_loss(bits);
    }
    if reordered {
        losses.push(
            "the Gaussians' order: the input's spread each 256-Gaussian chunk over the scene, so \
             they are written along a Z-order curve (Gaussian i of the output is not the input's)"
                .to_string(),
        );
    }
    Ok(ConvertReport {
        input_format,
        output_format,
        gaussians: decoder.len(),
        sh_degree_in,
        sh_degree_out,
        losses,
        reordered,
    })
}

/// Writes the standard PLY of `decoder` block by block (never the whole file at full
/// precision in memory), with SH up to `degree`; a decoding error or a value that is not
/// finite ([`decode_blocks`]) is returned as it is and leaves no output (the file is written
/// under a temporary name, removed on error).
fn stream_standard(decoder: &dyn BlockDecoder, degree: u8, output: &Path) -> Result<()> {
    const STREAM: usize = 1 << 16;
    let failure = std::cell::RefCell::new(None);
    let written = sage_io::files::write_atomic(output, |w| {
        w.write_all(standard::header_text(decoder.len(), degree).as_bytes())?;
        let mut rows = vec![Gaussian::default(); STREAM.min(decoder.len())];
        for start in (0..decoder.len()).step_by(STREAM) {
            let rows = &mut rows[..STREAM.min(decoder.len() - start)];
            if let Err(e) = decode_blocks(decoder, start, rows) {
                *failure.borrow_mut() = Some(e);
                return Err(std::io::Error::other("the input could not be decoded"));
            }
            zero_sh_above(rows, degree);
            standard::write_rows(w, rows, degree)?;
        }
        Ok(())
    });
    match failure.into_inner() {
        Some(e) => Err(e),
        None => written,
    }
}

/// Zeroes the SH coefficients above `degree` and lowers the table's degree to it.
pub fn drop_sh_bands(table: &mut SplatTable, degree: u8) {
    zero_sh_above(&mut table.gaussians, degree);
    table.sh_degree = table.sh_degree.min(degree);
}

/// Zeroes the SH coefficients of `gaussians` above `degree`.
fn zero_sh_above(gaussians: &mut [Gaussian], degree: u8) {
    let keep = sh_rest_count(degree);
    for g in gaussians {
        g.sh_rest[keep..].fill([0.0; 3]);
    }
}

/// How every SPZ position loss begins.
const SPZ_POSITIONS: &str = "positions quantised to 24-bit fixed point";

/// The SPZ position loss for `bits` fraction bits: steps of 2^-bits m, which the writer makes
/// coarser than the usual 1/4096 m only for a scene reaching beyond ±2048 m along an axis.
fn spz_position_loss(bits: u8) -> String {
    let step = match bits {
        0 => "1 m".to_string(),
        b => format!("1/{} m", 1u32 << b),
    };
    if bits >= super::spz::DEFAULT_FRACTION_BITS {
        format!("{SPZ_POSITIONS} ({step} steps)")
    } else {
        format!(
            "{SPZ_POSITIONS} ({step} steps: the scene reaches beyond ±2048 m along an axis, \
             where 1/4096 m steps would overflow 24 bits)"
        )
    }
}

/// What a file written in `to` does not hold of Gaussians of SH degree `from_degree` written
/// with degree `to_degree`; an SPZ's positions as for a scene within ±2048 m (`convert`
/// reports the step it actually wrote).
pub fn losses(to: Format, from_degree: u8, to_degree: u8) -> Vec<String> {
    let mut out = Vec::new();
    if to_degree < from_degree {
        let bands = if to_degree + 1 == from_degree {
            format!("SH band {from_degree}")
        } else {
            format!("SH bands {}–{from_degree}", to_degree + 1)
        };
        out.push(format!(
            "{bands} dropped ({} of {} coefficients per colour channel kept)",
            sh_rest_count(to_degree) + 1,
            sh_rest_count(from_degree) + 1
        ));
    }
    // The SH quantisation is lost only where the output holds higher SH at all.
    match to {
        Format::Ply(SplatLayout::Standard) => {}
        Format::Ply(SplatLayout::Compressed) => {
            out.extend(
                [
                    "positions and log-scales quantised to 11-10-11 bits between the bounds of each 256-Gaussian chunk",
                    "rotations normalised and quantised to 10 bits per component (smallest three)",
                    "base colour quantised to 8 bits per channel between each chunk's colour bounds, opacity to 8 bits after the sigmoid",
                ]
                .map(String::from),
            );
            if to_degree >= 1 {
                out.push("higher SH quantised to 8 bits over [-4, 4]".to_string());
            }
        }
        _ => {
            out.push(spz_position_loss(super::spz::DEFAULT_FRACTION_BITS));
            out.extend(
                [
                    "log-scales quantised to 8 bits (1/16 steps over [-10, 6))",
                    "rotations normalised and quantised (smallest three, 9 bits per component)",
                    "base colour and opacity quantised to 8 bits",
                ]
                .map(String::from),
            );
            match to_degree {
                0 => {}
                1 => out.push("higher SH quantised to 5 bits per coefficient".to_string()),
                2 => out.push(
                    "higher SH quantised to 5 bits (degree 1) and 4 bits (degree 2) per coefficient"
                        .to_string(),
                ),
                d => out.push(format!(
                    "higher SH quantised to 5 bits (degree 1) and 4 bits (degrees 2–{d}) per coefficient"
                )),
            }
        }
    }
    out
}
