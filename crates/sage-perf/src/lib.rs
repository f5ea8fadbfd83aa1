//! `sage-perf`: the performance benchmarks behind `sage3d bench` (the figures of SPEC §12).
//!
//! One module per benchmark: [`load`], [`render`], [`nav`], [`physics`], [`bodies`], [`env`](mod@env),
//! [`fit`], [`traindata`] and [`view`].
//! Each has a settings struct whose `Default` is the command's defaults and a `run` function
//! that sets up the benchmark's scene (synthesising one when none is given), times the work and
//! returns a report: `Display` gives the lines `sage3d bench` prints, serde the same figures as
//! data. [`machine`] describes the machine a figure was measured on.
//!
//! `load` and `render` measure a generated or converted input in a new process (see
//! [`load::run`]), so that memory freed while making it does not hide, or inflate, the resident
//! figures; only a front end knows how to start itself again, so it passes that step in.

pub mod bodies;
pub mod env;
pub mod fit;
pub mod load;
pub mod machine;
pub mod nav;
pub mod physics;
pub mod render;
pub mod traindata;
pub mod view;

use sage_core::Result;
use sage_scene::Gaussians;
use std::path::PathBuf;

/// The folder of this process's generated benchmark inputs, under the system temp dir.
fn scratch_dir() -> PathBuf {
    std::env::temp_dir().join(format!("sage3d-bench-{}", std::process::id()))
}

/// The generated home the scene benchmarks run in: `objects` objects over one room per 14 of
/// them (1 to 64) and `gaussians` Gaussians, from `seed`; says on stderr what it makes.
///
/// # Errors
///
/// The generator's errors.
fn generated_home(seed: u64, objects: usize, gaussians: usize) -> Result<sage_scene::Scene> {
    eprintln!("generating a {objects}-object home of {gaussians} Gaussians …");
    sage_synth::generate(&sage_synth::SynthConfig {
        seed,
        kind: sage_synth::SceneKind::Home,
        rooms: (objects / 14).clamp(1, 64),
        objects,
        gaussians,
        ..sage_synth::SynthConfig::default()
    })
}

/// The median of `values` (the upper one of an even count; NaN when there are none).
fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The mean of `values` (NaN when there are none).
fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// The same Gaussians at SH degree 3, higher bands filled with small deterministic values.
fn to_sh3(g: &Gaussians) -> Result<Gaussians> {
    let items: Vec<_> = (0..g.len())
        .map(|i| {
            let mut x = g.get(i);
            for (k, coeff) in x.sh_rest.iter_mut().enumerate().skip(3) {
                for (c, v) in coeff.iter_mut().enumerate() {
                    let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                        ^ ((k * 3 + c) as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    *v = ((h >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.2;
                }
            }
            x
        })
        .collect();
    Gaussians::from_gaussians(&items, 3)
}
