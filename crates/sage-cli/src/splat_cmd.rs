//! `sage3d splat …`: 3DGS file conversions.

use clap::{Args, Subcommand};
use sage_core::Result;
use sage_scene::splats::convert::{ConvertOptions, convert};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum SplatCommand {
    /// Convert between 3DGS formats. The input may be standard or compressed PLY, SPZ, SOG,
    /// glTF/GLB (KHR_gaussian_splatting) or .splat, told from its content; the output format
    /// comes from its name: NAME.ply (standard; NAME.decompressed.ply too), NAME.compressed.ply
    /// or NAME_compressed.ply, or NAME.spz. Values pass at full precision from reader to writer
    /// (standard PLY output is lossless); what the output format cannot hold is listed.
    /// Gaussian order is kept, except in a compressed PLY of an input whose 256-Gaussian chunks
    /// would spread over the scene (a trained PLY's order): that is written along a Z-order
    /// curve, and the conversion says so.
    Convert(ConvertArgs),
}

#[derive(Args)]
pub struct ConvertArgs {
    /// Input 3DGS file (any format sage3d reads).
    input: PathBuf,
    /// Output file: NAME.ply, NAME.compressed.ply (or NAME_compressed.ply) or NAME.spz.
    output: PathBuf,
    /// Keep SH bands up to this degree (0–3; default: all the input has).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=3))]
    sh_degree: Option<u8>,
    /// Replace the output file if it exists.
    #[arg(long)]
    force: bool,
}

pub fn run(cmd: SplatCommand) -> Result<()> {
    match cmd {
        SplatCommand::Convert(a) => run_convert(a),
    }
}

fn run_convert(a: ConvertArgs) -> Result<()> {
    let start = Instant::now();
    let r = convert(
        &a.input,
        &a.output,
        ConvertOptions {
            sh_degree: a.sh_degree,
            force: a.force,
        },
    )?;
    println!(
        "{} ({}, {} Gaussians, SH degree {}) -> {} ({}, SH degree {}) in {:.2} s",
        a.input.display(),
        r.input_format,
        r.gaussians,
        r.sh_degree_in,
        a.output.display(),
        r.output_format,
        r.sh_degree_out,
        start.elapsed().as_secs_f64()
    );
    if r.losses.is_empty() {
        println!("lossless: every value is written as read");
    }
    for loss in &r.losses {
        println!("lost: {loss}");
    }
    Ok(())
}
