//! `sage3d bench render`: frame times of the renderer from cameras inside a scene's largest
//! room, with their breakdown, and the process's resident memory per Gaussian.

use crate::machine;
use sage_core::Result;
use sage_scene::Scene;
use sage_scene::ply::SplatLayout;
use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
use sage_synth::{SceneKind, SynthConfig};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

/// What `bench render` renders.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Scene folder to render (`None`: generate a 16-room home of `gaussians`).
    pub scene: Option<PathBuf>,
    /// Gaussians in the generated scene.
    pub gaussians: usize,
    /// Frames per resolution (headings spread over a full turn).
    pub frames: usize,
    /// Resolutions, (width, height).
    pub sizes: Vec<(u32, u32)>,
    /// Camera pitch in degrees (0: level, as the SAGE-Bench camera).
    pub pitch: f32,
    /// Give the scene SH degree 3 (bands 2–3 filled from a seeded hash), the memory worst case.
    pub sh3: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            scene: None,
            gaussians: 1_000_000,
            frames: 24,
            sizes: vec![(224, 224), (640, 480)],
            pitch: 0.0,
            sh3: false,
        }
    }
}

/// What `bench render` measured. It deserialises too: a measuring process hands it back as
/// JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Gaussians in the scene.
    pub gaussians: usize,
    /// Their SH degree.
    pub sh_degree: u8,
    /// The camera position ([`sage_splat::camera::default_eye`]).
    pub eye: [f32; 3],
    /// Camera pitch, degrees.
    pub pitch: f32,
    /// Milliseconds to build the renderer's spatial index.
    pub index_ms: f64,
    /// Heap bytes of the index.
    pub index_bytes: usize,
    /// Heap bytes of the Gaussian arrays.
    pub store_bytes: usize,
    /// One entry per resolution, in the order asked.
    pub sizes: Vec<FrameTimes>,
    /// Resident set of the whole process after rendering, bytes (where the OS tells it).
    pub resident_bytes: Option<u64>,
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

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.gaussians.max(1) as f64;
        let [x, y, z] = self.eye;
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            {} Gaussians (SH degree {}), camera at ({x:.2}, {y:.2}, {z:.2}) in the largest room, pitch {}°, HFOV 90°",
            self.gaussians, self.sh_degree, self.pitch
        )?;
        writeln!(
            f,
            "index            built in {:.0} ms, {:.1} bytes/Gaussian",
            self.index_ms,
            self.index_bytes as f64 / n
        )?;
        for t in &self.sizes {
            writeln!(
                f,
                "{}x{:<10} median {:.1} ms/frame (worst {:.1}), {:.0} frames/s; cull {:.2} + project {:.1} + sort {:.1} + raster {:.1} ms; {:.0} Gaussians examined, {:.0} splats",
                t.width,
                t.height,
                t.median_ms,
                t.worst_ms,
                1e3 / t.median_ms,
                t.cull_ms,
                t.project_ms,
                t.sort_ms,
                t.raster_ms,
                t.examined,
                t.splats
            )?;
        }
        if let Some(rss) = self.resident_bytes {
            writeln!(
                f,
                "resident         {:.1} bytes/Gaussian: the whole process (scene {:.1} + index {:.1} + frame buffers and the rest)",
                rss as f64 / n,
                self.store_bytes as f64 / n,
                self.index_bytes as f64 / n
            )?;
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
/// The scene cannot be loaded, generated or written, a size is empty, or `fresh` fails.
pub fn run(
    settings: &RenderSettings,
    fresh: &dyn Fn(&RenderSettings) -> Result<RenderReport>,
) -> Result<RenderReport> {
    if let (Some(dir), false) = (&settings.scene, settings.sh3) {
        return measure(&Scene::load(dir)?.0, settings);
    }
    let mut scene = match &settings.scene {
        Some(dir) => Scene::load(dir)?.0,
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

/// Renders `frames` headings at every size after one warm-up frame, which sizes the reusable
/// buffers.
fn measure(scene: &Scene, settings: &RenderSettings) -> Result<RenderReport> {
    let start = Instant::now();
    let mut renderer = Renderer::new(&scene.gaussians);
    let index_ms = start.elapsed().as_secs_f64() * 1e3;
    let eye = sage_splat::camera::default_eye(scene);
    let machine = machine::describe();
    let options = RenderOptions::default();
    let mut sizes = Vec::with_capacity(settings.sizes.len());
    for &(w, h) in &settings.sizes {
        let intrinsics = Intrinsics::from_hfov(w, h, 90.0)?;
        let frames = settings.frames.max(1);
        let cams: Vec<Camera> = (0..frames)
            .map(|f| {
                Camera::from_yaw_pitch(
                    intrinsics,
                    eye,
                    std::f32::consts::TAU * f as f32 / frames as f32,
                    settings.pitch.to_radians(),
                )
            })
            .collect();
        renderer.render(
            &scene.gaussians,
            &scene.instances.category_ids,
            &cams[0],
            &options,
        )?;
        let mut rows: Vec<[f64; 7]> = Vec::with_capacity(frames);
        for cam in &cams {
            let start = Instant::now();
            renderer.render(
                &scene.gaussians,
                &scene.instances.category_ids,
                cam,
                &options,
            )?;
            let total = start.elapsed().as_secs_f64() * 1e3;
            let s = renderer.stats();
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
        let col = |k: usize| crate::median(&rows.iter().map(|r| r[k]).collect::<Vec<_>>());
        sizes.push(FrameTimes {
            width: w,
            height: h,
            median_ms: col(0),
            worst_ms: rows.iter().map(|r| r[0]).fold(0.0, f64::max),
            cull_ms: col(1),
            project_ms: col(2),
            sort_ms: col(3),
            raster_ms: col(4),
            examined: col(5),
            splats: col(6),
        });
    }
    let resident_bytes = machine::resident_bytes();
    Ok(RenderReport {
        machine,
        gaussians: scene.gaussians.len(),
        sh_degree: scene.gaussians.sh_degree(),
        eye: eye.to_array(),
        pitch: settings.pitch,
        index_ms,
        index_bytes: renderer.index().heap_bytes(),
        store_bytes: scene.gaussians.heap_bytes(),
        sizes,
        resident_bytes,
    })
}
