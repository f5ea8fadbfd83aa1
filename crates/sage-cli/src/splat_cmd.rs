//! `sage3d splat …`: 3DGS PLY conversions.

use clap::{Args, Subcommand};
use sage_core::Result;
use sage_scene::ply::{self, SplatLayout};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum SplatCommand {
    /// Convert between the standard and compressed layouts. The input layout is read from its
    /// header; the output layout comes from the output name (`*.compressed.ply` → compressed,
    /// other `*.ply` → standard). Gaussian order is preserved.
    Convert(ConvertArgs),
}

#[derive(Args)]
pub struct ConvertArgs {
    /// Input PLY (standard or compressed).
    input: PathBuf,
    /// Output PLY.
    output: PathBuf,
}

pub fn run(cmd: SplatCommand) -> Result<()> {
    match cmd {
        SplatCommand::Convert(a) => convert(a),
    }
}

fn convert(a: ConvertArgs) -> Result<()> {
    let out_layout = SplatLayout::from_file_name(&a.output)?;
    let start = Instant::now();
    let (g, in_layout) = ply::read_splats_file(&a.input)?;
    ply::write_splats_file(&a.output, &g, out_layout)?;
    println!(
        "{} ({}, {} Gaussians, SH degree {}) -> {} ({}) in {:.2} s",
        a.input.display(),
        in_layout.as_str(),
        g.len(),
        g.sh_degree(),
        a.output.display(),
        out_layout.as_str(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
