//! `sage3d bench …`: the performance figures of SPEC §12, measured on this machine.

use crate::machine;
use clap::{Args, Subcommand};
use sage_core::{Error, Result};
use sage_scene::ply::{self, SplatLayout};
use sage_synth::{SceneKind, SynthConfig};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Decode a compressed PLY and measure time and resident memory per Gaussian.
    /// Without --input, a synthetic office of --gaussians Gaussians (SH degree 1) is written
    /// first; use --sh3 to re-encode it at SH degree 3 (the memory target's case).
    Load(LoadArgs),
    /// Render a ≥1M-Gaussian synthetic home from cameras inside its largest room at 224×224
    /// and 640×480; report the median frame time and its breakdown.
    Render(RenderBenchArgs),
    /// Plan trajectories in a 20 × 20 m synthetic home: grid and EDT once, then sampling, A*,
    /// shortcut and resampling per trajectory, in parallel; report trajectories per second.
    Nav(crate::nav_cmd::NavBenchArgs),
    /// Step one agent through a 200-object synthetic home, physics only (no rendering), and
    /// report steps per second.
    Physics(crate::physics_cmd::PhysicsBenchArgs),
    /// Step the environment with a seeded random agent in a 200-object, 1M-Gaussian synthetic
    /// home: steps per second without rendering and with RGB + depth at 224×224 and 640×480.
    Env(crate::env_cmd::EnvBenchArgs),
    /// Fit a degraded copy of one synthetic room to views of it on the CPU (sage-train):
    /// held-out PSNR before and after, milliseconds per iteration.
    Fit(FitBenchArgs),
}

#[derive(Args)]
pub struct FitBenchArgs {
    /// Optimisation steps.
    #[arg(long, default_value_t = 300)]
    iterations: usize,
    /// Image size as WxH.
    #[arg(long, default_value = "128x96")]
    size: String,
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
    /// Resolutions as WxH.
    #[arg(long, value_delimiter = ',', default_value = "224x224,640x480")]
    sizes: Vec<String>,
    /// Camera pitch in degrees (0: level, as the SAGE-Bench camera).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pitch: f32,
    /// Give the scene SH degree 3 (bands 2–3 filled from a seeded hash), the memory worst case.
    #[arg(long)]
    sh3: bool,
}

#[derive(Args)]
pub struct LoadArgs {
    /// A compressed or standard PLY to decode (default: generate one).
    #[arg(long)]
    input: Option<PathBuf>,
    /// Gaussians in the generated scene.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// Give the generated file SH degree 3 (bands 2–3 filled from a seeded hash).
    #[arg(long)]
    sh3: bool,
    /// Timed decodes (the median is reported).
    #[arg(long, default_value_t = 7)]
    repeat: usize,
}

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Load(a) => load(a),
        BenchCommand::Render(a) => render(a),
        BenchCommand::Nav(a) => crate::nav_cmd::bench(a),
        BenchCommand::Physics(a) => crate::physics_cmd::bench(a),
        BenchCommand::Env(a) => crate::env_cmd::bench(a),
        BenchCommand::Fit(a) => fit(a),
    }
}

/// Views of a one-room synthetic scene rendered by `sage-splat` from cameras near its middle
/// (random headings, slightly downward), fitted from every fourth Gaussian with perturbed
/// colours and scales grown by 1.6.
fn fit(a: FitBenchArgs) -> Result<()> {
    use rand::{Rng, SeedableRng};
    let (width, height) = parse_size(&a.size)?;
    eprintln!("generating a one-room scene of {} Gaussians …", a.gaussians);
    let scene = sage_synth::generate(&SynthConfig {
        seed: a.seed,
        rooms: 1,
        objects: 10,
        gaussians: a.gaussians,
        ..SynthConfig::default()
    })?;
    let truth = &scene.gaussians;
    let centre = scene.floorplan.rooms[0].profile.centroid();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(a.seed);
    let mut renderer = sage_splat::Renderer::new(truth);
    let intrinsics = sage_splat::Intrinsics::from_hfov(width, height, 90.0)?;
    let mut views = (0..a.views + a.heldout)
        .map(|_| {
            let position = glam::Vec3::new(
                centre.x + rng.random_range(-0.6..0.6),
                centre.y + rng.random_range(-0.6..0.6),
                rng.random_range(1.1..1.6),
            );
            let camera = sage_splat::Camera::from_yaw_pitch(
                intrinsics,
                position,
                rng.random_range(-std::f32::consts::PI..std::f32::consts::PI),
                rng.random_range(-0.4..0.1),
            );
            let rgb = renderer
                .render(truth, &[], &camera, &sage_splat::RenderOptions::default())?
                .rgb;
            Ok(sage_train::View { camera, rgb })
        })
        .collect::<Result<Vec<_>>>()?;
    let heldout = views.split_off(a.views);
    let mut init = sage_scene::Gaussians::new(0)?;
    for i in (0..truth.len()).step_by(4) {
        let g = truth.get(i);
        init.push(&sage_scene::Gaussian {
            log_scale: g.log_scale + glam::Vec3::splat(1.6f32.ln()),
            sh_dc: g.sh_dc.map(|c| c + rng.random_range(-0.6..0.6)),
            ..g
        });
    }
    let params = sage_train::FitParams {
        iterations: a.iterations,
        seed: a.seed,
        ..sage_train::FitParams::default()
    };
    // Iterations are timed between the first and the last progress call, so the held-out
    // evaluations before and after are left out.
    let marks = std::sync::Mutex::new((None, None));
    let (fitted, report) = sage_train::fit(&init, &views, &heldout, &params, &|it, _| {
        let mut m = marks.lock().unwrap_or_else(|e| e.into_inner());
        let now = Some((it, Instant::now()));
        if m.0.is_none() {
            m.0 = now;
        }
        m.1 = now;
    })?;
    let per_iteration = match marks.into_inner().unwrap_or_else(|e| e.into_inner()) {
        (Some((i0, t0)), Some((i1, t1))) if i1 > i0 => {
            format!("{:.1} ms", (t1 - t0).as_secs_f64() * 1e3 / (i1 - i0) as f64)
        }
        _ => "n/a (fewer than 2 iterations)".into(),
    };
    println!("machine          {}", machine::describe());
    println!(
        "scene            one room, {} Gaussians; initialisation {} Gaussians",
        truth.len(),
        init.len()
    );
    println!(
        "views            {} training, {} held-out, {width}x{height}",
        views.len(),
        heldout.len()
    );
    println!(
        "held-out PSNR    {:.2} dB -> {:.2} dB (training {:.2} dB)",
        report.initial_heldout_psnr, report.final_heldout_psnr, report.final_train_psnr
    );
    println!(
        "fit              {} iterations, {} Gaussians at the end, {per_iteration} per iteration ({} threads)",
        a.iterations,
        fitted.len(),
        rayon::current_num_threads()
    );
    Ok(())
}

fn load(a: LoadArgs) -> Result<()> {
    match a.input {
        Some(p) => measure_load(&p, a.repeat),
        None => {
            let dir = std::env::temp_dir().join(format!("sage3d-bench-{}", std::process::id()));
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            let file = dir.join("bench.compressed.ply");
            eprintln!("generating a {}-Gaussian scene …", a.gaussians);
            let result = generate(&file, a.gaussians, a.sh3).and_then(|()| {
                let repeat = a.repeat.to_string();
                bench_in_fresh_process(&[
                    "load".as_ref(),
                    "--repeat".as_ref(),
                    repeat.as_ref(),
                    "--input".as_ref(),
                    file.as_os_str(),
                ])
            });
            let _ = std::fs::remove_dir_all(&dir);
            result
        }
    }
}

/// Runs `sage3d bench ARGS…` in a new process with this process's thread count, so that
/// memory freed by a generator does not hide (or inflate) the measured resident figures.
fn bench_in_fresh_process(args: &[&std::ffi::OsStr]) -> Result<()> {
    let exe = std::env::current_exe().map_err(|e| Error::io("current executable", e))?;
    let status = std::process::Command::new(&exe)
        .args([
            "--threads",
            &rayon::current_num_threads().to_string(),
            "bench",
        ])
        .args(args)
        .status()
        .map_err(|e| Error::io(&exe, e))?;
    if status.success() {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "the measuring process failed ({status})"
        )))
    }
}

fn measure_load(path: &Path, repeat: usize) -> Result<()> {
    let size = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let rss_before = machine::resident_bytes();
    let (kept, layout) = ply::read_splats_file(path)?;
    let rss_after = machine::resident_bytes();
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat.max(1) {
        let start = Instant::now();
        let (g, _) = ply::read_splats_file(path)?;
        times.push(start.elapsed().as_secs_f64());
        drop(g);
    }
    times.sort_by(f64::total_cmp);
    let n = kept.len().max(1) as f64;
    let median = times[times.len() / 2];
    println!("machine          {}", machine::describe());
    println!(
        "file             {} ({} layout, {:.1} MB, SH degree {})",
        path.display(),
        layout.as_str(),
        size as f64 / 1e6,
        kept.sh_degree()
    );
    println!("gaussians        {}", kept.len());
    println!(
        "decode           median {:.3} s, best {:.3} s over {} runs ({:.1} M Gaussians/s)",
        median,
        times[0],
        times.len(),
        n / median / 1e6
    );
    println!(
        "store            {:.1} bytes/Gaussian (heap of the Gaussian arrays)",
        kept.heap_bytes() as f64 / n
    );
    if let (Some(b), Some(a)) = (rss_before, rss_after) {
        println!(
            "resident         +{:.1} bytes/Gaussian (process RSS growth while loading)",
            a.saturating_sub(b) as f64 / n
        );
    }
    Ok(())
}

/// Writes the compressed PLY of a synthetic office with about `gaussians` Gaussians.
fn generate(path: &Path, gaussians: usize, sh3: bool) -> Result<()> {
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
        to_sh3(&scene.gaussians)?
    } else {
        scene.gaussians
    };
    ply::write_splats_file(path, &g, SplatLayout::Compressed)
}

/// The same Gaussians at SH degree 3, higher bands filled with small deterministic values.
fn to_sh3(g: &sage_scene::Gaussians) -> Result<sage_scene::Gaussians> {
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
    sage_scene::Gaussians::from_gaussians(&items, 3)
}

pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| Error::invalid(format!("size '{s}' is not WxH")))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| Error::invalid(format!("size '{s}' is not WxH")))
    };
    Ok((parse(w)?, parse(h)?))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn render(a: RenderBenchArgs) -> Result<()> {
    match (&a.scene, a.sh3) {
        (Some(dir), false) => measure_render(&sage_scene::Scene::load(dir)?.0, &a),
        (given, sh3) => {
            // Generated or converted scenes are written to a temporary folder and measured
            // from a fresh process, so the resident figure is that of a scene loaded from disk.
            let mut scene = match given {
                Some(dir) => sage_scene::Scene::load(dir)?.0,
                None => {
                    eprintln!("generating a {}-Gaussian home …", a.gaussians);
                    sage_synth::generate(&SynthConfig {
                        seed: 1,
                        kind: SceneKind::Home,
                        rooms: 16,
                        objects: 400,
                        gaussians: a.gaussians,
                        ..SynthConfig::default()
                    })?
                }
            };
            if sh3 {
                scene.gaussians = to_sh3(&scene.gaussians)?;
            }
            let dir = std::env::temp_dir().join(format!("sage3d-bench-{}", std::process::id()));
            let result = scene.save(&dir, SplatLayout::Compressed).and_then(|()| {
                drop(scene);
                let (frames, sizes, pitch) =
                    (a.frames.to_string(), a.sizes.join(","), a.pitch.to_string());
                bench_in_fresh_process(&[
                    "render".as_ref(),
                    "--frames".as_ref(),
                    frames.as_ref(),
                    "--sizes".as_ref(),
                    sizes.as_ref(),
                    "--pitch".as_ref(),
                    pitch.as_ref(),
                    "--scene".as_ref(),
                    dir.as_os_str(),
                ])
            });
            let _ = std::fs::remove_dir_all(&dir);
            result
        }
    }
}

fn measure_render(scene: &sage_scene::Scene, a: &RenderBenchArgs) -> Result<()> {
    use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
    let start = Instant::now();
    let mut renderer = Renderer::new(&scene.gaussians);
    let index_ms = start.elapsed().as_secs_f64() * 1e3;
    let eye = crate::render_cmd::default_eye(scene);
    println!("machine          {}", machine::describe());
    println!(
        "scene            {} Gaussians (SH degree {}), camera at ({:.2}, {:.2}, {:.2}) in the largest room, pitch {}°, HFOV 90°",
        scene.gaussians.len(),
        scene.gaussians.sh_degree(),
        eye.x,
        eye.y,
        eye.z,
        a.pitch
    );
    println!(
        "index            built in {index_ms:.0} ms, {:.1} bytes/Gaussian",
        renderer.index().heap_bytes() as f64 / scene.gaussians.len().max(1) as f64
    );
    let options = RenderOptions::default();
    let n = scene.gaussians.len().max(1) as f64;
    for size in &a.sizes {
        let (w, h) = parse_size(size)?;
        let intrinsics = Intrinsics::from_hfov(w, h, 90.0)?;
        let frames = a.frames.max(1);
        let cams: Vec<Camera> = (0..frames)
            .map(|f| {
                Camera::from_yaw_pitch(
                    intrinsics,
                    eye,
                    std::f32::consts::TAU * f as f32 / frames as f32,
                    a.pitch.to_radians(),
                )
            })
            .collect();
        // One warm-up frame sizes the reusable buffers.
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
        let col = |k: usize| median(rows.iter().map(|r| r[k]).collect());
        let worst = rows.iter().map(|r| r[0]).fold(0.0, f64::max);
        println!(
            "{w}x{h:<10} median {:.1} ms/frame (worst {:.1}), {:.0} frames/s; cull {:.2} + project {:.1} + sort {:.1} + raster {:.1} ms; {:.0} Gaussians examined, {:.0} splats",
            col(0),
            worst,
            1e3 / col(0),
            col(1),
            col(2),
            col(3),
            col(4),
            col(5),
            col(6)
        );
    }
    if let Some(rss) = machine::resident_bytes() {
        println!(
            "resident         {:.1} bytes/Gaussian: the whole process (scene {:.1} + index {:.1} + frame buffers and the rest)",
            rss as f64 / n,
            scene.gaussians.heap_bytes() as f64 / n,
            renderer.index().heap_bytes() as f64 / n
        );
    }
    Ok(())
}
