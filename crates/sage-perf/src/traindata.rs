//! `sage3d bench train-data`: the whole training-data pipeline (walk through physics, render,
//! JPEG encoding, writing the NaVILA layout) on a generated 1M-Gaussian home, in frames per
//! second per core at each resolution, and the CPU-hours that implies for the paper's 500k
//! training pairs.

use crate::machine;
use sage_core::{Error, Result};
use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::split::SplitParams;
use sage_splat::Device;
use sage_traindata::{Layout, PresetName, Progress, Settings};
use serde::Serialize;
use std::fmt;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// The training pairs NaVILA-SAGE and NaVid-SAGE were trained on (the paper, §Experiments).
pub const PAPER_PAIRS: f64 = 500_000.0;

/// What `bench train-data` renders.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainDataSettings {
    /// Objects in the generated home.
    pub objects: usize,
    /// Gaussians in the generated home.
    pub gaussians: usize,
    /// Seed of the scene and its dataset.
    pub seed: u64,
    /// Trajectories planned in the home (each gives several episodes, which share its walk).
    pub trajectories: usize,
    /// Resolutions, (width, height).
    pub sizes: Vec<(u32, u32)>,
    /// The action preset.
    pub preset: PresetName,
    /// Where the frames are rendered.
    pub device: Device,
}

impl Default for TrainDataSettings {
    fn default() -> Self {
        Self {
            objects: 200,
            gaussians: 1_000_000,
            seed: 1,
            trajectories: 40,
            sizes: vec![(224, 224), (384, 384), (640, 480)],
            preset: PresetName::default(),
            device: Device::Cpu,
        }
    }
}

/// One resolution's figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SizedThroughput {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Walks rendered.
    pub walks: usize,
    /// Frames rendered (kept and dropped walks alike).
    pub frames: usize,
    /// Seconds for the whole render: scene load, walks, encoding, writing, manifest.
    pub seconds: f64,
    /// Seconds of it spent loading the scene (once per scene).
    pub load_seconds: f64,
    /// Frames per second over the render without the scene load.
    pub frames_per_s: f64,
    /// The same per core.
    pub frames_per_s_per_core: f64,
    /// Mean JPEG bytes per frame.
    pub bytes_per_frame: f64,
    /// CPU-hours for the paper's 500k pairs, one walk per pair.
    pub paper_cpu_hours: f64,
}

/// What `bench train-data` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrainDataReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// The renderer ([`Device::probe`]).
    pub renderer: String,
    /// Threads used.
    pub threads: usize,
    /// Gaussians in the home.
    pub gaussians: usize,
    /// The preset.
    pub preset: PresetName,
    /// Episodes rendered (goal-directed episodes of the generated dataset).
    pub episodes: usize,
    /// Mean frames per walk.
    pub frames_per_walk: f64,
    /// One entry per resolution, in the order asked.
    pub sizes: Vec<SizedThroughput>,
}

impl fmt::Display for TrainDataReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(f, "renderer         {}", self.renderer)?;
        writeln!(
            f,
            "scene            generated home, {} Gaussians; {} episodes, preset {}, {:.1} frames per walk; {} threads",
            self.gaussians, self.episodes, self.preset, self.frames_per_walk, self.threads
        )?;
        for s in &self.sizes {
            writeln!(
                f,
                "{:<16} {:.1} frames/s ({:.1} per core; {} frames of {} walks in {:.1} s + scene load {:.1} s; {:.1} KB per JPEG) -> 500k pairs: {:.0} CPU-hours",
                format!("{}x{}", s.width, s.height),
                s.frames_per_s,
                s.frames_per_s_per_core,
                s.frames,
                s.walks,
                s.seconds - s.load_seconds,
                s.load_seconds,
                s.bytes_per_frame / 1e3,
                s.paper_cpu_hours
            )?;
        }
        writeln!(
            f,
            "                 (whole pipeline: physics + render + JPEG + NaVILA files; CPU-hours = 500k x frames per walk / frames per core-second)"
        )
    }
}

/// Runs `bench train-data`: generates the home and a dataset on it in a scratch folder, then
/// renders its training set at each size.
///
/// # Errors
///
/// The scene or dataset cannot be made, or the render fails.
pub fn run(settings: &TrainDataSettings) -> Result<TrainDataReport> {
    let scratch = crate::scratch_dir().join("train-data");
    let result = run_in(settings, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    result
}

fn run_in(settings: &TrainDataSettings, scratch: &std::path::Path) -> Result<TrainDataReport> {
    let home = scratch.join("scenes").join("home");
    crate::generated_home(settings.seed, settings.objects, settings.gaussians)?
        .save(&home, sage_scene::SplatLayout::Compressed)?;
    let dataset = scratch.join("data");
    let assemble = AssembleParams {
        seed: settings.seed,
        split: SplitParams {
            scene_unseen: 0.0,
            val: 0.0,
            donor_share: 0.0,
        },
        balanced: 0,
    };
    build::build(
        std::slice::from_ref(&home),
        &dataset,
        &SceneParams::new(settings.trajectories, settings.seed),
        &assemble,
        &|_| {},
    )?;
    // The first load of a scene builds and caches its collision hulls; every render after it
    // (and every size here) loads the cached ones.
    let load_seconds = {
        load_time(&scratch.join("scenes"))?;
        load_time(&scratch.join("scenes"))?
    };
    let threads = rayon::current_num_threads();
    let mut sizes = Vec::new();
    let mut episodes = 0;
    let mut frames_per_walk = 0.0;
    for &(width, height) in &settings.sizes {
        let out: PathBuf = scratch.join(format!("out-{width}x{height}"));
        let s = Settings {
            width,
            height,
            preset: settings.preset.preset(),
            format: Layout::Navila,
            keep_failed: true,
            device: settings.device,
            ..Settings::new(&dataset, &scratch.join("scenes"))?
        };
        eprintln!("rendering at {width}x{height} …");
        let start = Instant::now();
        let (frames, walks) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let manifest = sage_traindata::render(&s, &out, false, &|p| {
            if let Progress::Route(r) = p {
                frames.fetch_add(r.frames, Ordering::Relaxed);
                walks.fetch_add(1, Ordering::Relaxed);
            }
        })?;
        let seconds = start.elapsed().as_secs_f64();
        let (frames, walks) = (frames.into_inner(), walks.into_inner());
        if frames == 0 {
            return Err(Error::invalid(
                "the generated dataset gave no frame to render",
            ));
        }
        let work = (seconds - load_seconds).max(1e-9);
        let jpeg_bytes = jpeg_bytes(&out.join(sage_traindata::sample::IMAGES_DIR))?;
        let fps = frames as f64 / work;
        episodes = manifest.counts.episodes;
        frames_per_walk = frames as f64 / walks as f64;
        sizes.push(SizedThroughput {
            width,
            height,
            walks,
            frames,
            seconds,
            load_seconds,
            frames_per_s: fps,
            frames_per_s_per_core: fps / threads as f64,
            bytes_per_frame: jpeg_bytes as f64 / frames as f64,
            paper_cpu_hours: PAPER_PAIRS * frames_per_walk / (fps / threads as f64) / 3600.0,
        });
        std::fs::remove_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    }
    Ok(TrainDataReport {
        renderer: Device::probe(settings.device)?,
        machine: machine::describe(),
        threads,
        gaussians: settings.gaussians,
        preset: settings.preset,
        episodes,
        frames_per_walk,
        sizes,
    })
}

/// Seconds to load the scene: what a render spends once before walking, taken out of its
/// rate (a training set of many walks per scene pays it once per scene).
fn load_time(scenes: &std::path::Path) -> Result<f64> {
    let start = Instant::now();
    let dir = scenes.join("home");
    let ctx = sage_env::SceneContext::load(&dir, None)?;
    drop(ctx);
    Ok(start.elapsed().as_secs_f64())
}

/// Total bytes of the JPEG frames under `dir`.
fn jpeg_bytes(dir: &std::path::Path) -> Result<u64> {
    let tree = sage_io::files::read_tree(dir)?;
    Ok(tree
        .iter()
        .filter(|(k, _)| k.ends_with(".jpg"))
        .map(|(_, v)| v.len() as u64)
        .sum())
}
