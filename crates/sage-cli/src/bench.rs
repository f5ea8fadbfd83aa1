//! `sage3d bench …`: the performance figures of SPEC §12, measured on this machine by
//! sage-perf. This module turns flags into the benchmarks' settings and prints their reports.

use crate::flags::parse_size;
use clap::{Args, Subcommand};
use sage_core::{Error, Result};
use sage_perf::bodies::BodiesSettings;
use sage_perf::env::EnvSettings;
use sage_perf::fit::FitSettings;
use sage_perf::load::LoadSettings;
use sage_perf::nav::NavSettings;
use sage_perf::physics::PhysicsSettings;
use sage_perf::render::RenderSettings;
use sage_perf::traindata::TrainDataSettings;
use sage_perf::view::ViewSettings;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::ffi::OsString;
use std::fmt::Display;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Decode a 3DGS file into the scene store and measure time and resident memory per
    /// Gaussian. Without --input, a synthetic office of --gaussians Gaussians (SH degree 1) is
    /// written first in --format; use --sh3 to re-encode it at SH degree 3 (the memory target's
    /// case).
    Load(LoadArgs),
    /// Render a ≥1M-Gaussian synthetic home from cameras inside its largest room at 224×224
    /// and 640×480 (and 1024×768 on a GPU); report the median frame time and its breakdown,
    /// and on a GPU the frames per second of batches of cameras rendered in one submission.
    Render(RenderBenchArgs),
    /// Plan trajectories in a 27-room synthetic home (about 23.5 × 19.8 m): grid and EDT once, then sampling, A*,
    /// shortcut and resampling per trajectory, in parallel; report trajectories per second.
    Nav(NavBenchArgs),
    /// Step one agent through a 200-object synthetic home, physics only (no rendering), and
    /// report steps per second.
    Physics(PhysicsBenchArgs),
    /// Compare bodies recovered from the Gaussians alone with bodies decomposed from the meshes
    /// in generated homes: per-object volume IoU, and the CR and ICP of the same oracle walks in
    /// a world of each; --picture draws a section through a table and a chair.
    Bodies(BodiesBenchArgs),
    /// Step the environment with a seeded random agent in a 200-object, 1M-Gaussian synthetic
    /// home: steps per second without rendering and with RGB + depth at 224×224 and 640×480.
    Env(EnvBenchArgs),
    /// Fit a degraded copy of one synthetic room to views of it on the CPU (sage-train):
    /// held-out PSNR before and after, milliseconds per iteration.
    Fit(FitBenchArgs),
    /// Render the training set of a generated 1M-Gaussian home (walks through physics, frames,
    /// JPEG, NaVILA files) at each size: frames per second per core and the CPU-hours of the
    /// paper's 500k training pairs.
    TrainData(TrainDataBenchArgs),
    /// Serve a generated 1M-Gaussian home in the browser viewer on loopback and time what the
    /// page asks for: a keypress (a step through physics) and the 640×480 first-person frame at
    /// the new pose (CPU render + JPEG + HTTP); report frames per second.
    View(ViewBenchArgs),
}

#[derive(Args)]
pub struct ViewBenchArgs {
    /// Gaussians in the generated home.
    #[arg(long, default_value_t = ViewSettings::default().gaussians)]
    gaussians: usize,
    /// Objects in the generated home.
    #[arg(long, default_value_t = ViewSettings::default().objects)]
    objects: usize,
    /// Seed of the home.
    #[arg(long, default_value_t = ViewSettings::default().seed)]
    seed: u64,
    /// Keypresses to time (each a step and a frame).
    #[arg(long, default_value_t = ViewSettings::default().steps)]
    steps: usize,
    /// Frame size, WxH.
    #[arg(long, default_value = "640x480", value_parser = parse_size)]
    size: (u32, u32),
}

impl ViewBenchArgs {
    fn settings(&self) -> Result<ViewSettings> {
        Ok(ViewSettings {
            gaussians: self.gaussians,
            objects: self.objects,
            seed: self.seed,
            steps: self.steps,
            size: self.size,
        })
    }
}

#[derive(Args)]
pub struct TrainDataBenchArgs {
    /// Objects in the generated home.
    #[arg(long, default_value_t = 200)]
    objects: usize,
    /// Gaussians in the generated home.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Seed of the scene and its dataset.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Trajectories planned in the home.
    #[arg(long, default_value_t = 40)]
    trajectories: usize,
    /// Resolutions as WxH.
    #[arg(long, value_delimiter = ',', default_value = "224x224,384x384,640x480", value_parser = parse_size)]
    sizes: Vec<(u32, u32)>,
    /// Action preset.
    #[arg(long, default_value_t = TrainDataSettings::default().preset)]
    preset: sage_traindata::PresetName,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
}

impl TrainDataBenchArgs {
    fn settings(&self) -> Result<TrainDataSettings> {
        Ok(TrainDataSettings {
            objects: self.objects,
            gaussians: self.gaussians,
            seed: self.seed,
            trajectories: self.trajectories,
            sizes: self.sizes.clone(),
            preset: self.preset,
            device: self.device.device,
        })
    }
}

#[derive(Args)]
pub struct FitBenchArgs {
    /// Optimisation steps.
    #[arg(long, default_value_t = 300)]
    iterations: usize,
    /// Image size as WxH.
    #[arg(long, default_value = "128x96", value_parser = parse_size)]
    size: (u32, u32),
    /// Gaussians in the generated room (the initialisation keeps every fourth).
    #[arg(long, default_value_t = 20_000)]
    gaussians: usize,
    /// Training views.
    #[arg(long, default_value_t = 24)]
    views: usize,
    /// Held-out views.
    #[arg(long, default_value_t = 6)]
    heldout: usize,
    /// Seed of the room, the cameras, the degradation and the fit.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Args)]
pub struct RenderBenchArgs {
    /// Scene folder to render (default: generate a 16-room home of --gaussians).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Gaussians in the generated scene.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Frames per resolution (headings spread over a full turn).
    #[arg(long, default_value_t = 24)]
    frames: usize,
    /// Resolutions as WxH (default: 224x224,640x480, and 1024x768 when the GPU renders).
    #[arg(long, value_delimiter = ',', value_parser = parse_size)]
    sizes: Option<Vec<(u32, u32)>>,
    /// Camera pitch in degrees (0: level, as the SAGE-Bench camera).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pitch: f32,
    /// Give the scene SH degree 3 (bands 2–3 filled from a seeded hash), the memory worst case.
    #[arg(long)]
    sh3: bool,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
    /// Cameras per batch for the batched figures, measured when the GPU renders (headings
    /// spread over a full turn, all rendered in one submission).
    #[arg(long, value_delimiter = ',', default_value = "1,16,64,256,1024")]
    batches: Vec<usize>,
    /// Resolution of the batched cameras as WxH.
    #[arg(long, default_value = "224x224", value_parser = parse_size)]
    batch_size: (u32, u32),
    /// The images each frame renders out, as `RenderOutput` fields: all, or some of rgb,
    /// rgb_f32, alpha, depth_expected, depth_median, instance, semantic (on the GPU only
    /// these are read back; an RGB-D agent's sensors are rgb,depth_median).
    #[arg(long, default_value = "all")]
    channels: String,
    /// Render every GPU batch and each of its cameras in this many depth slabs, 1 to 4
    /// (default: one for a batch every camera of which sees fewer than 768 chunks of 256
    /// Gaussians, else four, with such a camera in the first alone). The images do not
    /// change; the work skipped behind finished tiles and the dispatches of each slab do.
    #[arg(long)]
    slabs: Option<u32>,
    /// The GPU renderer's blending kernel: blocks (shaped for CPU drivers such as lavapipe: 32
    /// threads per tile, each a column of eight pixels) or columns (shaped for hardware GPUs:
    /// 64 threads per tile, each a column of four). The images do not change.
    #[arg(long, default_value = "blocks")]
    blending: String,
    /// Print the report as JSON: how the measuring process hands it back.
    #[arg(long, hide = true)]
    json: bool,
}

#[derive(Args)]
pub struct LoadArgs {
    /// A 3DGS file to decode, any format sage3d reads (default: generate one).
    #[arg(long)]
    input: Option<PathBuf>,
    /// Format of the generated file: compressed-ply, ply or spz (SOG, glTF and .splat files
    /// come with --input).
    #[arg(long, default_value = "compressed-ply")]
    format: String,
    /// Gaussians in the generated scene.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Give the generated file SH degree 3 (bands 2–3 filled from a seeded hash).
    #[arg(long)]
    sh3: bool,
    /// Timed decodes (the median is reported).
    #[arg(long, default_value_t = 7)]
    repeat: usize,
    /// Print the report as JSON: how the measuring process hands it back.
    #[arg(long, hide = true)]
    json: bool,
}

#[derive(Args)]
pub struct NavBenchArgs {
    /// Trajectories to plan.
    #[arg(long, default_value_t = 4000)]
    count: usize,
    /// Seed of the scene and of the sampling.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Rooms of the generated home (about 15–17 m² each; 27 make about 23.5 × 19.8 m).
    #[arg(long, default_value_t = 27)]
    rooms: usize,
    /// Scene folder to use instead of a generated home.
    #[arg(long)]
    scene: Option<PathBuf>,
}

#[derive(Args)]
pub struct PhysicsBenchArgs {
    /// Scene folder (default: generate a home with --objects objects).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Objects in the generated scene (doors and windows included).
    #[arg(long, default_value_t = 200)]
    objects: usize,
    /// Hull cache (default: SCENE/.sage3d/collision, or a folder in the system temp dir for a
    /// generated scene, so repeated runs reuse it).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Agent profile.
    #[arg(long, default_value = "wheeled")]
    agent: String,
    /// Agent steps per timed run.
    #[arg(long, default_value_t = 100_000)]
    steps: usize,
    /// Timed runs (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Seed of the generated scene and of the command sequence.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Args)]
pub struct BodiesBenchArgs {
    /// Seeds of the generated homes, comma-separated (one home each).
    #[arg(long, value_delimiter = ',', default_values_t = BodiesSettings::default().seeds)]
    seeds: Vec<u64>,
    /// Rooms per home.
    #[arg(long, default_value_t = BodiesSettings::default().rooms)]
    rooms: usize,
    /// Objects per home (doors and windows included).
    #[arg(long, default_value_t = BodiesSettings::default().objects)]
    objects: usize,
    /// Gaussians per home.
    #[arg(long, default_value_t = BodiesSettings::default().gaussians)]
    gaussians: usize,
    /// Oracle walks per home.
    #[arg(long, default_value_t = BodiesSettings::default().walks)]
    walks: usize,
    /// IoU sampling cell, metres.
    #[arg(long, default_value_t = BodiesSettings::default().cell)]
    cell: f32,
    /// Hull cache (default: a folder in the system temp dir, so repeated runs reuse it).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Write a PNG section through a table and a chair: mesh hulls vs recovered parts.
    #[arg(long)]
    picture: Option<PathBuf>,
    /// Print the report as one line of JSON.
    #[arg(long)]
    json: bool,
}

impl BodiesBenchArgs {
    fn settings(&self) -> BodiesSettings {
        BodiesSettings {
            seeds: self.seeds.clone(),
            rooms: self.rooms,
            objects: self.objects,
            gaussians: self.gaussians,
            walks: self.walks,
            cell: self.cell,
            cache: self.cache.clone(),
            picture: self.picture.clone(),
        }
    }
}

#[derive(Args)]
pub struct EnvBenchArgs {
    /// Objects in the generated home.
    #[arg(long, default_value_t = 200)]
    objects: usize,
    /// Gaussians in the generated home.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Seed of the scene, the episodes and the random agent.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Steps without rendering.
    #[arg(long, default_value_t = 20_000)]
    steps: usize,
    /// Steps per rendered resolution.
    #[arg(long, default_value_t = 200)]
    render_steps: usize,
    /// Resolutions as WxH (RGB + depth each).
    #[arg(long, value_delimiter = ',', default_value = "224x224,640x480", value_parser = parse_size)]
    sizes: Vec<(u32, u32)>,
    /// Hull cache folder.
    #[arg(long)]
    cache: Option<PathBuf>,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
    /// Sub-environments of the vector environment stepped in lockstep with RGB + depth at the
    /// first size (0: not measured); on the GPU each lockstep step renders them in one batch.
    #[arg(long, default_value_t = EnvSettings::default().envs)]
    envs: usize,
}

impl LoadArgs {
    fn settings(&self) -> Result<LoadSettings> {
        Ok(LoadSettings {
            input: self.input.clone(),
            format: self.format.parse()?,
            gaussians: self.gaussians,
            sh3: self.sh3,
            repeat: self.repeat,
        })
    }
}

impl RenderBenchArgs {
    fn settings(&self) -> Result<RenderSettings> {
        Ok(RenderSettings {
            scene: self.scene.clone(),
            gaussians: self.gaussians,
            frames: self.frames,
            sizes: self.sizes.clone(),
            pitch: self.pitch,
            sh3: self.sh3,
            device: self.device.device,
            batches: self.batches.clone(),
            batch_size: self.batch_size,
            channels: self.channels.parse()?,
            slabs: self.slabs,
            blending: self.blending.parse()?,
        })
    }
}

impl NavBenchArgs {
    fn settings(&self) -> NavSettings {
        NavSettings {
            count: self.count,
            seed: self.seed,
            rooms: self.rooms,
            scene: self.scene.clone(),
        }
    }
}

impl PhysicsBenchArgs {
    fn settings(&self) -> PhysicsSettings {
        PhysicsSettings {
            scene: self.scene.clone(),
            objects: self.objects,
            cache: self.cache.clone(),
            agent: self.agent.clone(),
            steps: self.steps,
            repeat: self.repeat,
            seed: self.seed,
        }
    }
}

impl EnvBenchArgs {
    fn settings(&self) -> Result<EnvSettings> {
        Ok(EnvSettings {
            objects: self.objects,
            gaussians: self.gaussians,
            seed: self.seed,
            steps: self.steps,
            render_steps: self.render_steps,
            sizes: self.sizes.clone(),
            cache: self.cache.clone(),
            device: self.device.device,
            envs: self.envs,
        })
    }
}

impl FitBenchArgs {
    fn settings(&self) -> Result<FitSettings> {
        Ok(FitSettings {
            iterations: self.iterations,
            size: self.size,
            gaussians: self.gaussians,
            views: self.views,
            heldout: self.heldout,
            seed: self.seed,
        })
    }
}

/// Runs one `sage3d bench` subcommand and prints its report.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Load(a) => {
            let report = sage_perf::load::run(&a.settings()?, &|s| {
                let mut args = vec![
                    "load".into(),
                    "--repeat".into(),
                    s.repeat.to_string().into(),
                ];
                if let Some(input) = &s.input {
                    args.extend(["--input".into(), input.into()]);
                }
                in_fresh_process(args)
            })?;
            print_report(&report, a.json)
        }
        BenchCommand::Render(a) => {
            let settings = a.settings()?;
            // A GPU that cannot be had fails before the scene is generated; the measuring
            // process says which renderer it measures.
            a.device.probe()?;
            let report = sage_perf::render::run(&settings, &|s| {
                let batches: Vec<String> = s.batches.iter().map(usize::to_string).collect();
                let (bw, bh) = s.batch_size;
                let mut args: Vec<OsString> = vec![
                    "render".into(),
                    "--frames".into(),
                    s.frames.to_string().into(),
                    "--pitch".into(),
                    s.pitch.to_string().into(),
                    "--device".into(),
                    s.device.to_string().into(),
                    "--batches".into(),
                    batches.join(",").into(),
                    "--batch-size".into(),
                    format!("{bw}x{bh}").into(),
                    "--channels".into(),
                    s.channels.to_string().into(),
                ];
                if let Some(sizes) = &s.sizes {
                    let sizes: Vec<String> =
                        sizes.iter().map(|(w, h)| format!("{w}x{h}")).collect();
                    args.extend(["--sizes".into(), sizes.join(",").into()]);
                }
                if let Some(scene) = &s.scene {
                    args.extend(["--scene".into(), scene.into()]);
                }
                if let Some(slabs) = s.slabs {
                    args.extend(["--slabs".into(), slabs.to_string().into()]);
                }
                args.extend(["--blending".into(), s.blending.to_string().into()]);
                in_fresh_process(args)
            })?;
            print_report(&report, a.json)
        }
        BenchCommand::Nav(a) => print_report(&sage_perf::nav::run(&a.settings())?, false),
        BenchCommand::Physics(a) => print_report(&sage_perf::physics::run(&a.settings())?, false),
        BenchCommand::Bodies(a) => print_report(&sage_perf::bodies::run(&a.settings())?, a.json),
        BenchCommand::Env(a) => print_report(&sage_perf::env::run(&a.settings()?)?, false),
        BenchCommand::Fit(a) => print_report(&sage_perf::fit::run(&a.settings()?)?, false),
        BenchCommand::TrainData(a) => {
            print_report(&sage_perf::traindata::run(&a.settings()?)?, false)
        }
        BenchCommand::View(a) => print_report(&sage_perf::view::run(&a.settings()?)?, false),
    }
}

/// Prints a report: its lines, or with `json` one line of JSON.
fn print_report(report: &(impl Display + Serialize), json: bool) -> Result<()> {
    if json {
        let line = serde_json::to_string(report).map_err(|e| Error::invalid(e.to_string()))?;
        println!("{line}");
    } else {
        print!("{report}");
    }
    Ok(())
}

/// Runs `sage3d bench ARGS… --json` in a new process with this process's thread count and reads
/// back its report (sage-perf measures generated inputs so; see `sage_perf::load::run`).
fn in_fresh_process<R: DeserializeOwned>(args: Vec<OsString>) -> Result<R> {
    let exe = std::env::current_exe().map_err(|e| Error::io("current executable", e))?;
    let out = std::process::Command::new(&exe)
        .args([
            "--threads",
            &rayon::current_num_threads().to_string(),
            "bench",
        ])
        .args(args)
        .arg("--json")
        .stderr(std::process::Stdio::inherit())
        .output()
        .map_err(|e| Error::io(&exe, e))?;
    if !out.status.success() {
        return Err(Error::invalid(format!(
            "the measuring process failed ({})",
            out.status
        )));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| Error::invalid(format!("the measuring process's report: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Bench {
        #[command(subcommand)]
        command: BenchCommand,
    }

    fn parse(args: &[&str]) -> BenchCommand {
        Bench::try_parse_from(std::iter::once("bench").chain(args.iter().copied()))
            .unwrap()
            .command
    }

    /// The flags' defaults are the benchmarks' defaults.
    #[test]
    fn default_flags_give_default_settings() {
        for name in [
            "load",
            "render",
            "nav",
            "physics",
            "bodies",
            "env",
            "fit",
            "train-data",
            "view",
        ] {
            match parse(&[name]) {
                BenchCommand::Load(a) => assert_eq!(a.settings().unwrap(), LoadSettings::default()),
                BenchCommand::Render(a) => {
                    assert_eq!(a.settings().unwrap(), RenderSettings::default());
                }
                BenchCommand::Nav(a) => assert_eq!(a.settings(), NavSettings::default()),
                BenchCommand::Physics(a) => {
                    assert_eq!(a.settings(), PhysicsSettings::default());
                }
                BenchCommand::Bodies(a) => assert_eq!(a.settings(), BodiesSettings::default()),
                BenchCommand::Env(a) => assert_eq!(a.settings().unwrap(), EnvSettings::default()),
                BenchCommand::Fit(a) => assert_eq!(a.settings().unwrap(), FitSettings::default()),
                BenchCommand::TrainData(a) => {
                    assert_eq!(a.settings().unwrap(), TrainDataSettings::default());
                }
                BenchCommand::View(a) => assert_eq!(a.settings().unwrap(), ViewSettings::default()),
            }
        }
    }

    /// The help of `--slabs` states the renderer's own bound, which a doc comment can only
    /// spell as a literal.
    #[test]
    fn the_slabs_help_states_the_renderers_bound() {
        use clap::CommandFactory;
        let mut bench = Bench::command();
        let render = bench.find_subcommand_mut("render").unwrap();
        // Words joined by single spaces, however the help is wrapped.
        let help = render.render_long_help().to_string();
        let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
        let bound = format!("fewer than {} chunks", sage_splat::passes::GPU_FEW_CHUNKS);
        assert!(help.contains(&bound), "{help}");
    }

    /// Sizes are refused by the parser, naming the flag, before any work.
    #[test]
    fn sizes_are_checked_before_any_work() {
        for (size, why) in [
            ("32x24,10", "'10' is not WxH"),
            ("32x0", "0 is not in 1..=16384 pixels"),
            ("16385x8", "16385 is not in 1..=16384 pixels"),
        ] {
            let e = Bench::try_parse_from(["bench", "render", "--sizes", size])
                .err()
                .unwrap_or_else(|| panic!("{size} was taken"));
            assert_eq!(e.kind(), clap::error::ErrorKind::ValueValidation);
            let e = e.to_string();
            assert!(e.contains("--sizes") && e.contains(why), "{e}");
        }
        let BenchCommand::Render(a) = parse(&["render", "--sizes", "32x24,1x16384"]) else {
            unreachable!()
        };
        assert_eq!(a.sizes, Some(vec![(32, 24), (1, 16384)]));
    }
}
