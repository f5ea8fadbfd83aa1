//! `sage3d bench load`: decode a 3DGS file of any format into the scene store; time and
//! resident memory per Gaussian.

use crate::machine;
use sage_core::{Error, Result};
use sage_scene::ply::SplatLayout;
use sage_scene::splats::{self, Format};
use sage_synth::{SceneKind, SynthConfig};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `bench load` decodes, and how often.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadSettings {
    /// A 3DGS file of any format to decode (`None`: generate one).
    pub input: Option<PathBuf>,
    /// The format the generated file is written in (standard or compressed PLY, SPZ).
    pub format: Format,
    /// Gaussians in the generated scene.
    pub gaussians: usize,
    /// Give the generated file SH degree 3 (bands 2–3 filled from a seeded hash).
    pub sh3: bool,
    /// Timed decodes (the median is reported).
    pub repeat: usize,
}

impl Default for LoadSettings {
    fn default() -> Self {
        Self {
            input: None,
            format: Format::Ply(SplatLayout::Compressed),
            gaussians: 1_000_000,
            sh3: false,
            repeat: 7,
        }
    }
}

/// What `bench load` measured. It deserialises too: a measuring process hands it back as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoadReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// The decoded file.
    pub file: PathBuf,
    /// Its format, told from its content (`compressed-ply`, `ply`, `spz`, `sog`, `gltf`,
    /// `splat`).
    pub format: String,
    /// Its size, bytes.
    pub file_bytes: u64,
    /// SH degree of the Gaussians.
    pub sh_degree: u8,
    /// Gaussians decoded.
    pub gaussians: usize,
    /// Seconds of each timed decode, fastest first.
    pub decode_s: Vec<f64>,
    /// Heap bytes of the decoded Gaussian arrays.
    pub store_bytes: usize,
    /// Growth of the process's resident set while loading, bytes (where the OS tells it).
    pub resident_growth_bytes: Option<u64>,
}

impl LoadReport {
    /// Median seconds per decode.
    pub fn median_s(&self) -> f64 {
        crate::median(&self.decode_s)
    }
}

impl fmt::Display for LoadReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.gaussians.max(1) as f64;
        let median = self.median_s();
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "file             {} ({}, {:.1} MB, SH degree {})",
            self.file.display(),
            self.format,
            self.file_bytes as f64 / 1e6,
            self.sh_degree
        )?;
        writeln!(f, "gaussians        {}", self.gaussians)?;
        writeln!(
            f,
            "decode           median {:.3} s, best {:.3} s over {} runs ({:.1} M Gaussians/s)",
            median,
            self.decode_s.first().copied().unwrap_or(f64::NAN),
            self.decode_s.len(),
            n / median / 1e6
        )?;
        writeln!(
            f,
            "store            {:.1} bytes/Gaussian (heap of the Gaussian arrays)",
            self.store_bytes as f64 / n
        )?;
        if let Some(growth) = self.resident_growth_bytes {
            writeln!(
                f,
                "resident         +{:.1} bytes/Gaussian (process RSS growth while loading)",
                growth as f64 / n
            )?;
        }
        Ok(())
    }
}

/// Runs `bench load`. A given file is measured in this process. Otherwise the compressed PLY of
/// a synthetic office is written to a temporary folder and measured by `fresh`, which runs the
/// benchmark with these settings (the input now that file) in a new process and returns its
/// report; the folder is removed afterwards.
///
/// # Errors
///
/// The file cannot be read or decoded, the scene cannot be generated or written, or `fresh`
/// fails.
pub fn run(
    settings: &LoadSettings,
    fresh: &dyn Fn(&LoadSettings) -> Result<LoadReport>,
) -> Result<LoadReport> {
    if let Some(path) = &settings.input {
        return measure(path, settings.repeat);
    }
    if !settings.format.writable() {
        return Err(Error::invalid(format!(
            "bench load generates ply, compressed-ply or spz files; give a {} file as `input` \
             (splat-transform writes one: `splat-transform IN.ply OUT.{}`)",
            settings.format,
            match settings.format {
                Format::Gltf => "glb",
                other => other.as_str(),
            }
        )));
    }
    let dir = crate::scratch_dir();
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let file = dir.join(match settings.format {
        Format::Ply(SplatLayout::Compressed) => "bench.compressed.ply",
        Format::Ply(SplatLayout::Standard) => "bench.ply",
        _ => "bench.spz",
    });
    eprintln!(
        "generating a {}-Gaussian scene ({}) …",
        settings.gaussians, settings.format
    );
    let result =
        generate(&file, settings.gaussians, settings.sh3, settings.format).and_then(|()| {
            fresh(&LoadSettings {
                input: Some(file.clone()),
                ..settings.clone()
            })
        });
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// Decodes `path` once for the resident growth, then `repeat` times for the timings.
fn measure(path: &Path, repeat: usize) -> Result<LoadReport> {
    let size = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let rss_before = machine::resident_bytes();
    let (kept, format) = splats::read_gaussians_file(path)?;
    let rss_after = machine::resident_bytes();
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat.max(1) {
        let start = Instant::now();
        let (g, _) = splats::read_gaussians_file(path)?;
        times.push(start.elapsed().as_secs_f64());
        drop(g);
    }
    times.sort_by(f64::total_cmp);
    Ok(LoadReport {
        machine: machine::describe(),
        file: path.to_path_buf(),
        format: format.to_string(),
        file_bytes: size,
        sh_degree: kept.sh_degree(),
        gaussians: kept.len(),
        decode_s: times,
        store_bytes: kept.heap_bytes(),
        resident_growth_bytes: rss_before
            .zip(rss_after)
            .map(|(before, after)| after.saturating_sub(before)),
    })
}

/// Writes the Gaussians of a synthetic office with about `gaussians` Gaussians in `format`.
fn generate(path: &Path, gaussians: usize, sh3: bool, format: Format) -> Result<()> {
    let rooms = (gaussians / 60_000).clamp(4, 20);
    let config = SynthConfig {
        seed: 1,
        kind: SceneKind::Office,
        rooms,
        objects: rooms * 25,
        gaussians,
        ..SynthConfig::default()
    };
    let scene = sage_synth::generate(&config)?;
    let g = if sh3 {
        crate::to_sh3(&scene.gaussians)?
    } else {
        scene.gaussians
    };
    splats::write_file(path, &g, format)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> LoadReport {
        LoadReport {
            machine: "CPU, 2 cores visible, 2 threads used".into(),
            file: "scene/bench.compressed.ply".into(),
            format: "compressed-ply".into(),
            file_bytes: 25_300_000,
            sh_degree: 1,
            gaussians: 1_000_000,
            decode_s: vec![0.0625, 0.125, 0.25],
            store_bytes: 49_000_000,
            resident_growth_bytes: Some(50_100_000),
        }
    }

    #[test]
    fn text_is_the_command_output() {
        assert_eq!(
            report().to_string(),
            "machine          CPU, 2 cores visible, 2 threads used\n\
             file             scene/bench.compressed.ply (compressed-ply, 25.3 MB, SH degree 1)\n\
             gaussians        1000000\n\
             decode           median 0.125 s, best 0.062 s over 3 runs (8.0 M Gaussians/s)\n\
             store            49.0 bytes/Gaussian (heap of the Gaussian arrays)\n\
             resident         +50.1 bytes/Gaussian (process RSS growth while loading)\n"
        );
    }

    #[test]
    fn report_survives_json() {
        let json = serde_json::to_string(&report()).unwrap();
        assert_eq!(serde_json::from_str::<LoadReport>(&json).unwrap(), report());
    }
}
