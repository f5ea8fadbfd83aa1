//! `sage3d bench render`: frame times of the renderer from cameras inside a scene's largest
//! room, with their breakdown (CPU), the frames per second of batched cameras (GPU), and the
//! process's resident memory per Gaussian.

use crate::machine;
use sage_core::Result;
use sage_scene::Scene;
use sage_scene::ply::SplatLayout;
use sage_splat::{
    Backend, Blending, Camera, Channels, Device, Intrinsics, PassTimes, RenderOptions,
    RendererPool, Rendering,
};
use sage_synth::{SceneKind, SynthConfig};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// What `bench render` renders.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Scene folder to render (`None`: generate a 16-room home of `gaussians`).
    pub scene: Option<PathBuf>,
    /// Gaussians in the generated scene.
    pub gaussians: usize,
    /// Frames per resolution (headings spread over a full turn).
    pub frames: usize,
    /// Resolutions, (width, height) (`None`: [`CPU_SIZES`], or [`GPU_SIZES`] when the GPU
    /// renders).
    pub sizes: Option<Vec<(u32, u32)>>,
    /// Camera pitch in degrees (0: level, as the SAGE-Bench camera).
    pub pitch: f32,
    /// Give the scene SH degree 3 (bands 2–3 filled from a seeded hash), the memory worst case.
    pub sh3: bool,
    /// Where the frames are rendered.
    pub device: Device,
    /// Cameras per batch of the batched figures, measured when the GPU renders (the CPU
    /// renders a batch one camera after the other, so its rate is that of single frames).
    pub batches: Vec<usize>,
    /// Resolution of the batched cameras, (width, height).
    pub batch_size: (u32, u32),
    /// The images each frame renders out (on the GPU, the ones read back).
    pub channels: Channels,
    /// Depth slabs of every GPU batch, fixed (`None`: chosen from what its cameras see).
    pub slabs: Option<u32>,
    /// The GPU renderer's blending kernel.
    pub blending: Blending,
}

/// The resolutions measured on the CPU unless asked otherwise.
pub const CPU_SIZES: [(u32, u32); 2] = [(224, 224), (640, 480)];

/// The resolutions measured on the GPU unless asked otherwise: the CPU's and the published
/// pipeline's 1024×768.
pub const GPU_SIZES: [(u32, u32); 3] = [(224, 224), (640, 480), (1024, 768)];

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            scene: None,
            gaussians: 1_000_000,
            frames: 24,
            sizes: None,
            pitch: 0.0,
            sh3: false,
            device: Device::Cpu,
            batches: vec![1, 16, 64, 256, 1024],
            batch_size: (224, 224),
            channels: Channels::ALL,
            slabs: None,
            blending: Blending::default(),
        }
    }
}

/// What `bench render` measured. It deserialises too: a measuring process hands it back as
/// JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// The renderer that measured ([`Backend::describe`]: the CPU's threads or the GPU
    /// adapter).
    pub renderer: String,
    /// Gaussians in the scene.
    pub gaussians: usize,
    /// Their SH degree.
    pub sh_degree: u8,
    /// The camera position ([`sage_splat::camera::default_eye`]).
    pub eye: [f32; 3],
    /// Camera pitch, degrees.
    pub pitch: f32,
    /// The images each frame rendered out ([`Channels`]' list).
    #[serde(default = "all_images")]
    pub channels: String,
    /// Depth slabs of every GPU batch when they were fixed (`None`: chosen from the last
    /// batch's work).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slabs: Option<u32>,
    /// The GPU renderer's blending kernel, when the GPU rendered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blending: Option<Blending>,
    /// Milliseconds to set the renderer up: the CPU's spatial index, or the GPU's device (on
    /// first use) and the upload of the scene.
    pub index_ms: f64,
    /// Heap bytes of the CPU renderer's index (none on the GPU).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index_bytes: Option<usize>,
    /// Heap bytes of the Gaussian arrays.
    pub store_bytes: usize,
    /// One entry per resolution, in the order asked.
    pub sizes: Vec<FrameTimes>,
    /// One entry per batch size (GPU only), in the order asked.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub batches: Vec<BatchRate>,
    /// Resident set of the whole process after rendering, bytes (where the OS tells it; GPU
    /// memory is not in it).
    pub resident_bytes: Option<u64>,
    /// Device memory of the GPU renderer after the largest batch, bytes: the resident scene
    /// and the work space (none on the CPU).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_bytes: Option<u64>,
}

/// The frames of one resolution: medians over the frames unless said otherwise.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameTimes {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Milliseconds per frame.
    pub median_ms: f64,
    /// The slowest frame, milliseconds.
    pub worst_ms: f64,
    /// The mean frame, milliseconds: what a batch of these headings would cost rendered one
    /// camera at a time, per camera (headings differ in their work, so the mean can lie well
    /// above the median).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_ms: Option<f64>,
    /// When the GPU renders: the CPU renderer's median on the same headings, in rounds with
    /// the GPU's (each renderer's pass over the headings, then the other's, three times), so
    /// both medians come from the same minutes and their ratio is that of the renderers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu_median_ms: Option<f64>,
    /// Where the CPU renderer's time went (the GPU's frames are timed whole, read-back
    /// included).
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub breakdown: Option<Breakdown>,
    /// Where the GPU renderer's time went on the device, medians of each stage (where the
    /// device writes timestamps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu_passes: Option<PassTimes>,
}

/// The CPU renderer's stages and work, medians over the frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Breakdown {
    /// Frustum culling, milliseconds.
    pub cull_ms: f64,
    /// Projection, milliseconds.
    pub project_ms: f64,
    /// Sorting, milliseconds.
    pub sort_ms: f64,
    /// Blending, milliseconds.
    pub raster_ms: f64,
    /// Gaussians examined.
    pub examined: f64,
    /// Splats blended.
    pub splats: f64,
}

/// Batches of cameras rendered in one call ([`Backend::render_batch`]: on the GPU one
/// submission and one read-back) over the same headings for every batch size: medians over the
/// timed batches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BatchRate {
    /// Cameras per batch.
    pub cameras: usize,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Milliseconds per batch, read-back included.
    pub batch_ms: f64,
    /// Frames per second: cameras over the batch's time.
    pub frames_per_s: f64,
    /// The median single frame of the same headings at the batch's size, one camera per
    /// call, timed in rounds with the batches (a pass of single frames, then a share of the
    /// batches, three times), so that the batch's ratio to it comes from the same minutes of a
    /// machine whose speed drifts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub single_ms: Option<f64>,
    /// The mean of those single frames: times the batch's cameras, what they cost rendered one
    /// at a time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub single_mean_ms: Option<f64>,
    /// Frames per second of batches rendered back to back, each submitted before the images
    /// of the one before are waited for ([`Backend::submit_batch`]): the read-back and
    /// unpacking of one overlap the rendering of the next, as in a training-data render.
    pub streamed_frames_per_s: f64,
    /// Where the batch's time went on the device, medians of each stage (where the device
    /// writes timestamps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu_passes: Option<PassTimes>,
}

/// The images of a report from before the images could be chosen: all of them.
fn all_images() -> String {
    Channels::ALL.to_string()
}

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.gaussians.max(1) as f64;
        let [x, y, z] = self.eye;
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(f, "renderer         {}", self.renderer)?;
        writeln!(
            f,
            "scene            {} Gaussians (SH degree {}), camera at ({x:.2}, {y:.2}, {z:.2}) in the largest room, pitch {}°, HFOV 90°",
            self.gaussians, self.sh_degree, self.pitch
        )?;
        writeln!(f, "images           {}", self.channels)?;
        if let Some(slabs) = self.slabs {
            writeln!(f, "depth slabs      {slabs} in every batch (fixed)")?;
        }
        if let Some(blending) = self.blending {
            writeln!(f, "blending         {blending}")?;
        }
        match self.index_bytes {
            Some(bytes) => writeln!(
                f,
                "index            built in {:.0} ms, {:.1} bytes/Gaussian",
                self.index_ms,
                bytes as f64 / n
            )?,
            None => writeln!(
                f,
                "upload           device and scene in {:.0} ms",
                self.index_ms
            )?,
        }
        for t in &self.sizes {
            write!(
                f,
                "{}x{:<10} median {:.1} ms/frame (",
                t.width, t.height, t.median_ms
            )?;
            if let Some(mean) = t.mean_ms {
                write!(f, "mean {mean:.1}, ")?;
            }
            write!(
                f,
                "worst {:.1}), {:.0} frames/s",
                t.worst_ms,
                1e3 / t.median_ms
            )?;
            match &t.breakdown {
                Some(b) => writeln!(
                    f,
                    "; cull {:.2} + project {:.1} + sort {:.1} + raster {:.1} ms; {:.0} Gaussians examined, {:.0} splats",
                    b.cull_ms, b.project_ms, b.sort_ms, b.raster_ms, b.examined, b.splats
                )?,
                None => write!(f, ", one camera per call, read-back included")?,
            }
            if let Some(cpu) = t.cpu_median_ms {
                write!(
                    f,
                    "; CPU renderer {cpu:.1} ms on the same headings, in the same rounds ({:.2}×)",
                    t.median_ms / cpu
                )?;
            }
            match &t.gpu_passes {
                Some(p) => writeln!(f, "; on the GPU: {p}")?,
                None if t.breakdown.is_none() => writeln!(f)?,
                None => {}
            }
        }
        for b in &self.batches {
            write!(
                f,
                "batch {:<4} {:>4}x{:<4} {:.1} ms per batch, {:.0} frames/s",
                b.cameras, b.width, b.height, b.batch_ms, b.frames_per_s
            )?;
            if let (Some(single), Some(mean)) = (b.single_ms, b.single_mean_ms) {
                write!(
                    f,
                    " ({:.1}× a single frame of {single:.1} ms in the same rounds, {:.2}× its cameras one at a time)",
                    b.batch_ms / single,
                    b.batch_ms / (mean * b.cameras as f64)
                )?;
            }
            write!(
                f,
                "; streamed, the next batch in flight: {:.0} frames/s",
                b.streamed_frames_per_s
            )?;
            match &b.gpu_passes {
                Some(p) => writeln!(f, "; on the GPU: {p}")?,
                None => writeln!(f)?,
            }
        }
        if let Some(bytes) = self.device_bytes {
            writeln!(
                f,
                "GPU memory       {:.0} MB: the resident scene and the work space of the last batch",
                bytes as f64 / 1048576.0,
            )?;
        }
        if let Some(rss) = self.resident_bytes {
            match self.index_bytes {
                Some(index) => writeln!(
                    f,
                    "resident         {:.1} bytes/Gaussian: the whole process (scene {:.1} + index {:.1} + frame buffers and the rest)",
                    rss as f64 / n,
                    self.store_bytes as f64 / n,
                    index as f64 / n
                )?,
                None => writeln!(
                    f,
                    "resident         {:.1} bytes/Gaussian: the whole process on the host (scene {:.1} + frame buffers, driver and the rest; GPU memory not counted)",
                    rss as f64 / n,
                    self.store_bytes as f64 / n
                )?,
            }
        }
        Ok(())
    }
}

/// Runs `bench render`. A given scene without `sh3` is measured in this process. Otherwise
/// the scene (generated, or given and converted to SH degree 3) is written to a temporary
/// folder and measured by `fresh`, which runs the benchmark with these settings (the scene now
/// that folder, `sh3` off) in a new process and returns its report, so that the resident
/// figure is that of a scene loaded from disk; the folder is removed afterwards.
///
/// # Errors
///
/// The pitch is past ±90°, the scene cannot be loaded, generated or written, a size or a batch
/// is empty, the device cannot be opened, or `fresh` fails.
pub fn run(
    settings: &RenderSettings,
    fresh: &dyn Fn(&RenderSettings) -> Result<RenderReport>,
) -> Result<RenderReport> {
    if settings.batches.contains(&0) {
        return Err(sage_core::Error::invalid(
            "batches: a batch needs at least 1 camera",
        ));
    }
    sage_splat::camera::check_pitch_deg(settings.pitch)?;
    settings.device.check_slabs(settings.slabs)?;
    settings.device.check_blending(settings.blending)?;
    if let (Some(dir), false) = (&settings.scene, settings.sh3) {
        return measure(&Scene::load_for_rendering(dir)?.0, settings);
    }
    let mut scene = match &settings.scene {
        Some(dir) => Scene::load_for_rendering(dir)?.0,
        None => {
            eprintln!("generating a {}-Gaussian home …", settings.gaussians);
            sage_synth::generate(&SynthConfig {
                seed: 1,
                kind: SceneKind::Home,
                rooms: 16,
                objects: 400,
                gaussians: settings.gaussians,
                ..SynthConfig::default()
            })?
        }
    };
    if settings.sh3 {
        scene.gaussians = crate::to_sh3(&scene.gaussians)?;
    }
    let dir = crate::scratch_dir();
    let result = scene.save(&dir, SplatLayout::Compressed).and_then(|()| {
        drop(scene);
        fresh(&RenderSettings {
            scene: Some(dir.clone()),
            sh3: false,
            ..settings.clone()
        })
    });
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// The median of each stage over `passes`.
fn median_passes(passes: &[PassTimes]) -> PassTimes {
    let stage = |f: fn(&PassTimes) -> f64| crate::median(&passes.iter().map(f).collect::<Vec<_>>());
    PassTimes {
        setup_ms: stage(|p| p.setup_ms),
        project_ms: stage(|p| p.project_ms),
        depth_sort_ms: stage(|p| p.depth_sort_ms),
        bin_ms: stage(|p| p.bin_ms),
        raster_ms: stage(|p| p.raster_ms),
        compose_ms: stage(|p| p.compose_ms),
        read_back_ms: stage(|p| p.read_back_ms),
        unpack_ms: stage(|p| p.unpack_ms),
    }
}

/// The cameras of the benchmark: `count` headings spread over a full turn at `eye`.
fn cameras(intrinsics: Intrinsics, eye: glam::Vec3, pitch_deg: f32, count: usize) -> Vec<Camera> {
    (0..count)
        .map(|f| {
            Camera::from_yaw_pitch(
                intrinsics,
                eye,
                std::f32::consts::TAU * f as f32 / count as f32,
                pitch_deg.to_radians(),
            )
        })
        .collect()
}

/// Rounds over the headings when the GPU renders: its frames, then the CPU renderer's, three
/// times, so that both renderers' medians come from the same minutes of a machine whose speed
/// drifts, and each renders its headings one after another as it would alone (a CPU frame
/// right after each GPU frame would find its caches cold). Each batch size takes as many
/// rounds of single frames and batches, for the same reason.
const ROUNDS: usize = 3;

/// How long the measured renderer renders before each timed pass: a GPU left idle (while the
/// CPU renderer takes its round, or between sizes) lowers its clocks, and frames timed before
/// they are up again would measure the clock governor rather than the renderer (seen on an
/// H200: a batch of one at four to five times a single frame's GPU time).
const WARM_UP: Duration = Duration::from_millis(500);

/// Renders `batches` in turn until [`WARM_UP`] has passed and at least `at_least` of them
/// were rendered. A first pass over all of them also grows a GPU renderer's work space to what
/// each needs before any is timed: a batch that finds more than the work space holds is
/// rendered again after it grows, which a timed batch must not pay.
fn warm_up(
    backend: &mut Backend,
    scene: &Scene,
    batches: &[&[Camera]],
    options: &RenderOptions,
    at_least: usize,
) -> Result<()> {
    let start = Instant::now();
    for (rendered, batch) in batches.iter().cycle().enumerate() {
        backend.render_batch(
            &scene.gaussians,
            &scene.instances.category_ids,
            batch,
            options,
        )?;
        if rendered + 1 >= at_least && start.elapsed() >= WARM_UP {
            break;
        }
    }
    Ok(())
}

/// Frames per second of `batches` rendered back to back, each submitted before the one
/// before is waited for, so that one batch's read-back overlaps the next one's rendering.
fn streamed(
    backend: &mut Backend,
    scene: &Scene,
    batches: &[&[Camera]],
    options: &RenderOptions,
) -> Result<f64> {
    let start = Instant::now();
    let mut frames = 0;
    let mut in_flight: Option<Rendering> = None;
    for batch in batches {
        let next = backend.submit_batch(
            &scene.gaussians,
            &scene.instances.category_ids,
            batch,
            options,
        )?;
        if let Some(last) = in_flight.replace(next) {
            frames += last.wait()?.len();
        }
    }
    if let Some(last) = in_flight {
        frames += last.wait()?.len();
    }
    Ok(frames as f64 / start.elapsed().as_secs_f64())
}

/// Renders `frames` headings at every size, each pass over them after [`WARM_UP`] of rendering
/// them (on the GPU in [`ROUNDS`] with the CPU renderer); on the GPU then the batches, each
/// size after a warm-up, timed one at a time (in [`ROUNDS`] with single frames of the same
/// headings, so the batch's ratio to them comes from the same minutes) and then streamed.
/// Every heading and every batch is rendered once before the first is timed ([`warm_up`]).
fn measure(scene: &Scene, settings: &RenderSettings) -> Result<RenderReport> {
    let start = Instant::now();
    let mut backend = Backend::open(settings.device, &scene.gaussians)?;
    let index_ms = start.elapsed().as_secs_f64() * 1e3;
    backend.set_slabs(settings.slabs)?;
    backend.set_blending(settings.blending)?;
    eprintln!("renderer: {}", backend.describe());
    let eye = sage_splat::camera::default_eye(scene);
    let machine = machine::describe();
    let options = RenderOptions {
        channels: settings.channels,
        ..RenderOptions::default()
    };
    let (gaussians, categories) = (&scene.gaussians, &scene.instances.category_ids);
    let asked = match (&settings.sizes, backend.is_gpu()) {
        (Some(sizes), _) => sizes.clone(),
        (None, true) => GPU_SIZES.to_vec(),
        (None, false) => CPU_SIZES.to_vec(),
    };
    let mut sizes = Vec::with_capacity(asked.len());
    // On the GPU, the CPU renderer too, in rounds after the GPU's ([`ROUNDS`]): the ratio asked
    // of the GPU renderer is to the CPU's time in the same run.
    let mut cpu = if backend.is_gpu() {
        Some(Backend::open(Device::Cpu, gaussians)?)
    } else {
        None
    };
    // Timestamps between the stages, where the device writes them (the CPU renderer: never).
    let timed = backend.time_passes(true);
    for (w, h) in asked {
        let frames = settings.frames.max(1);
        let cams = cameras(
            Intrinsics::from_hfov(w, h, 90.0)?,
            eye,
            settings.pitch,
            frames,
        );
        let singles: Vec<&[Camera]> = cams.chunks(1).collect();
        if let Some(cpu) = &mut cpu {
            cpu.render(gaussians, categories, &cams[0], &options)?;
        }
        let rounds = if cpu.is_some() { ROUNDS } else { 1 };
        let mut rows: Vec<[f64; 7]> = Vec::with_capacity(frames * rounds);
        let mut cpu_ms = Vec::with_capacity(frames * rounds);
        let mut passes: Vec<PassTimes> = Vec::with_capacity(frames * rounds);
        for round in 0..rounds {
            let at_least = if round == 0 { singles.len() } else { 1 };
            warm_up(&mut backend, scene, &singles, &options, at_least)?;
            for cam in &cams {
                let start = Instant::now();
                backend.render(gaussians, categories, cam, &options)?;
                let total = start.elapsed().as_secs_f64() * 1e3;
                let s = backend
                    .as_cpu()
                    .map(RendererPool::stats)
                    .unwrap_or_default();
                passes.extend(backend.pass_times());
                rows.push([
                    total,
                    s.cull_ms,
                    s.project_ms,
                    s.sort_ms,
                    s.raster_ms,
                    s.examined as f64,
                    s.splats as f64,
                ]);
            }
            if let Some(cpu) = &mut cpu {
                for cam in &cams {
                    let start = Instant::now();
                    cpu.render(gaussians, categories, cam, &options)?;
                    cpu_ms.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        let col = |k: usize| crate::median(&rows.iter().map(|r| r[k]).collect::<Vec<_>>());
        sizes.push(FrameTimes {
            width: w,
            height: h,
            median_ms: col(0),
            worst_ms: rows.iter().map(|r| r[0]).fold(0.0, f64::max),
            mean_ms: Some(crate::mean(&rows.iter().map(|r| r[0]).collect::<Vec<_>>())),
            cpu_median_ms: cpu.is_some().then(|| crate::median(&cpu_ms)),
            breakdown: (!backend.is_gpu()).then(|| Breakdown {
                cull_ms: col(1),
                project_ms: col(2),
                sort_ms: col(3),
                raster_ms: col(4),
                examined: col(5),
                splats: col(6),
            }),
            gpu_passes: timed.then(|| median_passes(&passes)),
        });
    }
    // The batches are the GPU renderer's alone: the CPU renderer's frame buffers go first.
    drop(cpu);
    let mut batches = Vec::new();
    if backend.is_gpu() {
        let (w, h) = settings.batch_size;
        let intrinsics = Intrinsics::from_hfov(w, h, 90.0)?;
        // Every batch size renders the headings of the single frames, cycled to fill whole
        // batches, so the rates compare the same frames.
        let headings = cameras(intrinsics, eye, settings.pitch, settings.frames.max(1));
        for &count in &settings.batches {
            let cams: Vec<Camera> = (0..headings.len().div_ceil(count) * count)
                .map(|i| headings[i % headings.len()])
                .collect();
            let parts: Vec<&[Camera]> = cams.chunks(count).collect();
            warm_up(&mut backend, scene, &parts, &options, parts.len())?;
            // Every part once, and at least three timed batches for a median, shared out over
            // the rounds, each after a pass of the single frames it is compared with.
            let timed_batches = parts.len().max(ROUNDS);
            let mut times = Vec::with_capacity(timed_batches);
            let mut passes = Vec::with_capacity(timed_batches);
            let mut single_times = Vec::with_capacity(ROUNDS * headings.len());
            let mut order = parts.iter().cycle();
            for round in 0..ROUNDS {
                for cam in &headings {
                    let start = Instant::now();
                    backend.render(gaussians, categories, cam, &options)?;
                    single_times.push(start.elapsed().as_secs_f64() * 1e3);
                }
                let share = timed_batches * (round + 1) / ROUNDS - timed_batches * round / ROUNDS;
                for part in order.by_ref().take(share) {
                    let start = Instant::now();
                    backend.render_batch(gaussians, categories, part, &options)?;
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                    passes.extend(backend.pass_times());
                }
            }
            // Twice the timed batches again, streamed.
            let stream: Vec<&[Camera]> = parts
                .iter()
                .cycle()
                .take(2 * times.len())
                .copied()
                .collect();
            let streamed_frames_per_s = streamed(&mut backend, scene, &stream, &options)?;
            let batch_ms = crate::median(&times);
            batches.push(BatchRate {
                cameras: count,
                width: w,
                height: h,
                batch_ms,
                frames_per_s: count as f64 * 1e3 / batch_ms,
                single_ms: Some(crate::median(&single_times)),
                single_mean_ms: Some(crate::mean(&single_times)),
                streamed_frames_per_s,
                gpu_passes: timed.then(|| median_passes(&passes)),
            });
        }
    }
    backend.time_passes(false);
    let resident_bytes = machine::resident_bytes();
    Ok(RenderReport {
        machine,
        renderer: backend.describe().to_string(),
        gaussians: scene.gaussians.len(),
        sh_degree: scene.gaussians.sh_degree(),
        eye: eye.to_array(),
        pitch: settings.pitch,
        channels: settings.channels.to_string(),
        slabs: settings.slabs,
        blending: backend.is_gpu().then_some(settings.blending),
        index_ms,
        index_bytes: backend.as_cpu().map(|r| r.index().heap_bytes()),
        store_bytes: scene.gaussians.heap_bytes(),
        sizes,
        batches,
        resident_bytes,
        device_bytes: backend.device_bytes(),
    })
}
