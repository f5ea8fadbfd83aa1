//! `sage3d render`: images of a scene from a camera — RGB, depth, instance and semantic, with a
//! legend — and an optional turntable.

use clap::Args;
use glam::Vec3;
use sage_core::{Error, Result};
use sage_io::files::{write_json, write_npy_f32, write_png, write_rgb_png};
use sage_scene::{InstanceKind, Scene};
use sage_splat::camera::default_eye;
use sage_splat::{
    Backend, Camera, CameraSpec, Device, Intrinsics, RenderOptions, RenderOutput, Renderer,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene folder.
    scene: PathBuf,
    /// Output folder: new, empty, or one this command wrote (rerunning replaces its images).
    #[arg(long)]
    out: PathBuf,
    /// Write into a folder holding other files (never replacing one of them).
    #[arg(long)]
    force: bool,
    /// Camera JSON: width, height, hfov_deg (or fx, fy, cx, cy), position with yaw_deg and
    /// pitch_deg (or c2w: 4x4, row-major, OpenCV axes), near, far. Without it the camera
    /// stands at 1.2 m in the middle of the largest room, set by the flags below.
    #[arg(long)]
    camera: Option<PathBuf>,
    /// Image width (without --camera).
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height (without --camera).
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Horizontal field of view, degrees (without --camera).
    #[arg(long, default_value_t = 90.0)]
    hfov: f32,
    /// Camera position x,y,z in metres (without --camera; default: largest room, 1.2 m).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "X,Y,Z",
        allow_hyphen_values = true
    )]
    position: Option<Vec<f32>>,
    /// Heading, degrees (without --camera).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    yaw: f32,
    /// Pitch, degrees, up positive (without --camera).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pitch: f32,
    /// Background colour r,g,b in 0–1.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "R,G,B",
        default_value = "0,0,0"
    )]
    background: Vec<f32>,
    /// Also render a full turn of N frames about the camera position: turntable/rgb_NNN.png and
    /// turntable.gif.
    #[arg(long)]
    turntable: Option<usize>,
    #[command(flatten)]
    device: crate::flags::DeviceFlag,
}

fn camera_from_args(a: &RenderArgs, scene: &Scene) -> Result<Camera> {
    if let Some(p) = &a.camera {
        let text = std::fs::read_to_string(p).map_err(|e| Error::io(p, e))?;
        return CameraSpec::parse(&text)
            .and_then(|s| s.camera())
            .map_err(|e| e.in_file(p));
    }
    let eye = match a.position.as_deref() {
        Some(&[x, y, z]) => Vec3::new(x, y, z),
        Some(other) => {
            return Err(Error::invalid(format!(
                "--position needs 3 numbers x,y,z, got {}",
                other.len()
            )));
        }
        None => default_eye(scene),
    };
    let camera = Camera::from_yaw_pitch(
        Intrinsics::from_hfov(a.width, a.height, a.hfov)?,
        eye,
        a.yaw.to_radians(),
        a.pitch.to_radians(),
    );
    camera.validate()?;
    Ok(camera)
}

pub fn run(a: RenderArgs) -> Result<()> {
    let (scene, _) = Scene::load(&a.scene)?;
    let camera = camera_from_args(&a, &scene)?;
    let background: [f32; 3] = a.background.as_slice().try_into().map_err(|_| {
        Error::invalid(format!(
            "--background needs 3 numbers r,g,b, got {}",
            a.background.len()
        ))
    })?;
    render_to_dir(
        &scene,
        a.device.device,
        &camera,
        &RenderOptions { background },
        &a.out,
        a.turntable,
        a.force,
    )
}

/// The command, as the run record names it.
const COMMAND: &str = "render";

/// Everything the command may write at the top of its output folder.
const OUTPUTS: [&str; 12] = [
    "rgb.png",
    "depth.npy",
    "depth_median.npy",
    "alpha.npy",
    "depth.png",
    "instance.png",
    "semantic.png",
    "legend.json",
    "render.json",
    "turntable",
    "turntable.gif",
    sage_io::RUN_RECORD,
];

/// Renders `scene` on `device` from `camera` into `out`: every channel, the legend,
/// `render.json`, a turntable of `turntable` frames if asked, and the run record. `out` must be new, empty or a render's; with `force`, a folder of other files is
/// written into, provided none of them would be replaced ([`sage_io::run::claim_folder`]).
fn render_to_dir(
    scene: &Scene,
    device: Device,
    camera: &Camera,
    options: &RenderOptions,
    out: &Path,
    turntable: Option<usize>,
    force: bool,
) -> Result<()> {
    sage_io::run::claim_folder(out, &[COMMAND], &OUTPUTS, force)?;
    let mut backend = Backend::open(device, &scene.gaussians)?;
    eprintln!("renderer: {}", backend.describe());
    let start = Instant::now();
    let image = backend.render(
        &scene.gaussians,
        &scene.instances.category_ids,
        camera,
        options,
    )?;
    // The CPU renderer times its stages; the GPU's frame is timed whole, read-back included.
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let stats = backend.as_cpu().map(Renderer::stats);
    // Made only now, so a render that failed leaves no empty folder behind.
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    write_images(out, &image)?;
    write_legend(&out.join("legend.json"), scene, &image)?;
    let mut record = serde_json::json!({
        "renderer": backend.describe(),
        "camera": {"width": camera.intrinsics.width, "height": camera.intrinsics.height, "fx": camera.intrinsics.fx, "fy": camera.intrinsics.fy, "cx": camera.intrinsics.cx, "cy": camera.intrinsics.cy,
                   "c2w_row_major": camera.c2w().transpose().to_cols_array_2d(), "near": camera.near, "far": camera.far},
        "files": {
            "rgb.png": "colour, 8-bit",
            "depth.npy": "expected z-depth, float32 metres along the optical axis (sum w z / sum w); 0 where nothing was hit",
            "depth_median.npy": "median z-depth, float32 metres: z where transmittance first drops to 0.5; 0 where alpha < 0.5",
            "alpha.npy": "accumulated alpha, float32",
            "depth.png": "expected z-depth, 16-bit millimetres (clamped at 65.535 m)",
            "instance.png": "instance of the largest blending weight, colour-coded (legend.json)",
            "semantic.png": "category of that instance, colour-coded (legend.json)",
        },
    });
    let (ms, splats) = match stats {
        Some(stats) => {
            record["stats_ms"] = serde_json::json!({"cull": stats.cull_ms, "project": stats.project_ms, "sort": stats.sort_ms, "raster": stats.raster_ms});
            record["splats"] = stats.splats.into();
            (
                stats.cull_ms + stats.project_ms + stats.sort_ms + stats.raster_ms,
                format!(" ({} splats)", stats.splats),
            )
        }
        None => {
            record["frame_ms"] = wall_ms.into();
            (wall_ms, String::new())
        }
    };
    write_json(&out.join("render.json"), &record)?;
    if let Some(n) = turntable {
        write_turntable(out, &mut backend, scene, camera, options, n)?;
    }
    sage_io::run::write_run_record(
        out,
        COMMAND,
        None,
        serde_json::json!({ "scene": scene.name, "camera": record["camera"], "turntable": turntable, "device": device }),
    )?;
    eprintln!(
        "rendered {}x{} in {ms:.1} ms{splats} -> {}",
        camera.intrinsics.width,
        camera.intrinsics.height,
        out.display()
    );
    Ok(())
}

/// A distinct, stable colour per id (golden-ratio hues); id 0 is black.
pub fn id_color(id: u32) -> [u8; 3] {
    if id == 0 {
        return [0, 0, 0];
    }
    sage_io::palette::distinct_color(id)
}

fn colorize(ids: impl Iterator<Item = u32>) -> Vec<u8> {
    ids.flat_map(id_color).collect()
}

fn write_images(dir: &Path, image: &RenderOutput) -> Result<()> {
    let (w, h) = (image.width, image.height);
    write_rgb_png(&dir.join("rgb.png"), w, h, &image.rgb)?;
    write_npy_f32(&dir.join("depth.npy"), &[h, w], &image.depth_expected)?;
    write_npy_f32(&dir.join("depth_median.npy"), &[h, w], &image.depth_median)?;
    write_npy_f32(&dir.join("alpha.npy"), &[h, w], &image.alpha)?;
    let mm: Vec<u8> = image
        .depth_expected
        .iter()
        .flat_map(|d| ((d * 1000.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes())
        .collect();
    write_png(
        &dir.join("depth.png"),
        w,
        h,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &mm,
    )?;
    write_rgb_png(
        &dir.join("instance.png"),
        w,
        h,
        &colorize(image.instance.iter().copied()),
    )?;
    write_rgb_png(
        &dir.join("semantic.png"),
        w,
        h,
        &colorize(image.semantic.iter().map(|&c| c as u32)),
    )
}

fn instance_name(scene: &Scene, id: u32) -> String {
    match scene.instances.kinds.get(id as usize) {
        Some(InstanceKind::Object(i)) => scene.objects[*i].ins_id.clone(),
        Some(InstanceKind::Wall(i)) => format!("wall_{i}"),
        Some(InstanceKind::Floor(r)) => format!("floor_{r}"),
        Some(InstanceKind::Ceiling(r)) => format!("ceiling_{r}"),
        _ => "none".to_string(),
    }
}

/// The ids present in the image, with names, categories, colours and pixel counts.
fn write_legend(path: &Path, scene: &Scene, image: &RenderOutput) -> Result<()> {
    let mut instances: BTreeMap<u32, usize> = BTreeMap::new();
    for &i in &image.instance {
        *instances.entry(i).or_insert(0) += 1;
    }
    let mut categories: BTreeMap<u16, usize> = BTreeMap::new();
    for &c in &image.semantic {
        *categories.entry(c).or_insert(0) += 1;
    }
    let legend = serde_json::json!({
        "instances": instances.iter().map(|(&id, &pixels)| serde_json::json!({
            "id": id, "name": instance_name(scene, id), "category": scene.instances.category_name(sage_core::InstanceId(id)),
            "color": id_color(id), "pixels": pixels,
        })).collect::<Vec<_>>(),
        "categories": categories.iter().map(|(&id, &pixels)| serde_json::json!({
            "id": id, "name": scene.instances.categories.get(id as usize).cloned().unwrap_or_default(),
            "color": id_color(id as u32), "pixels": pixels,
        })).collect::<Vec<_>>(),
    });
    write_json(path, &legend)
}

/// Turntable frames rendered per [`Backend::render_batch`] call: one GPU submission each,
/// while the images held at once stay small.
const TURNTABLE_BATCH: usize = 32;

fn write_turntable(
    dir: &Path,
    backend: &mut Backend,
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    frames: usize,
) -> Result<()> {
    if frames == 0 || frames > 3600 {
        return Err(Error::invalid(format!(
            "--turntable must be 1-3600 frames, got {frames}"
        )));
    }
    let folder = dir.join("turntable");
    std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, e))?;
    let forward = camera.rotation.z_axis;
    let (yaw0, pitch) = (
        forward.y.atan2(forward.x),
        forward.z.clamp(-1.0, 1.0).asin(),
    );
    let cameras: Vec<Camera> = (0..frames)
        .map(|f| {
            let yaw = yaw0 + std::f32::consts::TAU * f as f32 / frames as f32;
            Camera {
                near: camera.near,
                far: camera.far,
                ..Camera::from_yaw_pitch(camera.intrinsics, camera.position, yaw, pitch)
            }
        })
        .collect();
    let mut images = Vec::with_capacity(frames);
    for batch in cameras.chunks(TURNTABLE_BATCH) {
        let rendered = backend.render_batch(
            &scene.gaussians,
            &scene.instances.category_ids,
            batch,
            options,
        )?;
        for image in rendered {
            let f = images.len();
            write_rgb_png(
                &folder.join(format!("rgb_{f:03}.png")),
                image.width,
                image.height,
                &image.rgb,
            )?;
            images.push(image.rgb);
        }
    }
    let (w, h) = (
        camera.intrinsics.width as u16,
        camera.intrinsics.height as u16,
    );
    sage_io::files::write_atomic(&dir.join("turntable.gif"), |out| {
        let mut enc = gif::Encoder::new(out, w, h, &[]).map_err(std::io::Error::other)?;
        enc.set_repeat(gif::Repeat::Infinite)
            .map_err(std::io::Error::other)?;
        for rgb in &images {
            let mut frame = gif::Frame::from_rgb_speed(w, h, rgb, 10);
            frame.delay = 8;
            enc.write_frame(&frame).map_err(std::io::Error::other)?;
        }
        Ok(())
    })
}
