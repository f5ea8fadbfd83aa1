//! Images of a scene from one camera, as `sage3d render` writes them: RGB, depth, alpha,
//! instance and semantic images with a legend, `render.json`, and an optional turntable of
//! frames about the camera with its GIF.

use glam::Vec3;
use sage_core::{Error, MAX_COORDINATE, Result, within_bounds};
use sage_io::files::{write_json, write_npy_f32, write_png, write_rgb_png};
use sage_io::gif::GifWriter;
use sage_nav::sampling::SamplingParams;
use sage_nav::{CostParams, GridParams, NavGrid};
use sage_scene::{InstanceKind, Scene};
use sage_splat::camera::{check_pitch_deg, default_eye};
use sage_splat::{
    Backend, Camera, CameraSpec, Channels, Device, Intrinsics, RenderOptions, RenderOutput,
    RendererPool,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A camera given by its image size, field of view and pose rather than by a camera file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPose {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Position in metres; `None` stands the camera at 1.2 m over the free cell nearest to the
    /// middle of the largest room ([`free_default_eye`]), which needs the scene, so it is
    /// resolved at render time.
    pub position: Option<Vec3>,
    /// Heading, degrees counter-clockwise from +X.
    pub yaw_deg: f32,
    /// Pitch, degrees, up positive.
    pub pitch_deg: f32,
}

impl CameraPose {
    /// The camera of a render given no camera: 640x480, 90° wide, level, facing +X from the
    /// default eye. A constant so that the command line's flag defaults can name it.
    pub const DEFAULT: CameraPose = CameraPose {
        width: 640,
        height: 480,
        hfov_deg: 90.0,
        position: None,
        yaw_deg: 0.0,
        pitch_deg: 0.0,
    };

    /// The camera in `scene`.
    ///
    /// # Errors
    ///
    /// A size or field of view that makes no camera.
    pub fn camera(&self, scene: &Scene) -> Result<Camera> {
        self.resolve(scene).map(|(camera, _)| camera)
    }

    /// The camera in `scene`, with how its eye was chosen when no position was given.
    ///
    /// # Errors
    ///
    /// A size or field of view that makes no camera.
    pub fn resolve(&self, scene: &Scene) -> Result<(Camera, Option<DefaultEye>)> {
        // Checked before the eye: a bad camera should not cost a navigation grid.
        self.validate()?;
        let intrinsics = Intrinsics::from_hfov(self.width, self.height, self.hfov_deg)?;
        let (eye, chosen) = match self.position {
            Some(p) => (p, None),
            None => {
                let chosen = free_default_eye(scene);
                (Vec3::from(chosen.position), Some(chosen))
            }
        };
        let camera = Camera::from_yaw_pitch(
            intrinsics,
            eye,
            self.yaw_deg.to_radians(),
            self.pitch_deg.to_radians(),
        );
        camera.validate()?;
        Ok((camera, chosen))
    }
}

impl CameraPose {
    /// Checks the pose as given, naming the setting at fault: a position within
    /// ±[`MAX_COORDINATE`] metres, a finite heading, and a pitch [`check_pitch_deg`] takes.
    fn validate(&self) -> Result<()> {
        if let Some(p) = self.position
            && !within_bounds(p)
        {
            return Err(Error::invalid(format!(
                "`position` must be finite and within ±{MAX_COORDINATE} m, got {}, {}, {}",
                p.x, p.y, p.z
            )));
        }
        if !self.yaw_deg.is_finite() {
            return Err(Error::invalid(format!(
                "`yaw` must be a finite angle in degrees, got {}",
                self.yaw_deg
            )));
        }
        check_pitch_deg(self.pitch_deg)
    }
}

/// Height of a default eye above the floor, metres: that of [`default_eye`], the SAGE-Bench
/// camera.
const EYE_HEIGHT: f32 = 1.2;

/// How a render given no camera position chose its eye ([`free_default_eye`]), as `render.json`
/// records it under `default_eye`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DefaultEye {
    /// Where the camera stands, metres.
    pub position: [f32; 3],
    /// The point it was sought near, metres: [`default_eye`], the middle of the largest room at
    /// 1.2 m, else the middle of the Gaussians.
    pub target: [f32; 3],
    /// The source of the navigation grid whose free cell it stands over
    /// ([`sage_nav::GridSource::as_str`]); `None` when it stands at `target`.
    pub grid: Option<&'static str>,
    /// Why it stands at `target`: the scene has no usable navigation grid.
    pub warning: Option<String>,
}

/// The eye of `sage3d render` given no camera position: 1.2 m over the free stand cell of the
/// scene's navigation grid ([`NavGrid::from_scene`] with the default [`GridParams`]) nearest to
/// [`default_eye`]. A stand cell is navigable (free, with the clearance of the default agent,
/// [`CostParams::navigable_clearance`]) and its eye lies outside every object's box, which also
/// covers bodies the grid lets through (an open door leaf). In a scene with rooms the cell is
/// sought as `sage-nav` seeks a room's central cell: among the largest room's cells with the
/// clearance a room centre prefers ([`SamplingParams::room_clearance`]), else its other stand
/// cells (without the island rule, which is about reaching the centre, not seeing from it);
/// then anywhere. Ties go to the lower cell index, so the choice is stable.
///
/// [`default_eye`] itself can sit inside furniture (a table in the middle of the room) or
/// outside the free space (a captured scene with no rooms, whose fallback is the middle of the
/// Gaussians), and the default image would then show the inside of an object. `sage3d bench
/// render` keeps [`default_eye`] unchanged, so that its figures compare across history. A scene
/// with no usable grid, or no such cell, keeps [`default_eye`] and says why in
/// [`DefaultEye::warning`] rather than failing the render.
pub fn free_default_eye(scene: &Scene) -> DefaultEye {
    let target = default_eye(scene);
    let at_target = |warning: String| DefaultEye {
        position: target.to_array(),
        target: target.to_array(),
        grid: None,
        warning: Some(warning),
    };
    let (grid, source) = match NavGrid::from_scene(scene, &GridParams::default()) {
        Ok(built) => built,
        Err(e) => {
            return at_target(format!(
                "no navigation grid ({}); the camera stands at the middle of the largest room or of the Gaussians, which may be inside an object",
                e.message()
            ));
        }
    };
    let clearance = sage_nav::cost::clearance(&grid);
    let navigable = sage_nav::cost::navigable(
        &grid,
        &clearance,
        CostParams::default().navigable_clearance(),
    );
    let roomy = SamplingParams::default().room_clearance;
    // The room `default_eye` stands in (the same choice, ties included).
    let room = scene
        .floorplan
        .rooms
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.profile.area().total_cmp(&b.1.profile.area()))
        .map(|(i, _)| i);
    // Tier 0: roomy cells of that room, 1: its other stand cells, 2: stand cells elsewhere. The
    // roomy preference stays inside the room: elsewhere a roomy cell may be rooms away.
    let tier = |k: usize| {
        if room != Some(grid.rooms[k] as usize) {
            2u8
        } else if clearance[k] >= roomy {
            0
        } else {
            1
        }
    };
    let to = target.truncate();
    let mut cells: Vec<(u8, f32, usize)> = (0..grid.cells.len())
        .filter(|&k| navigable[k])
        .map(|k| (tier(k), grid.center_of(k).distance_squared(to), k))
        .collect();
    cells.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    let eye = cells
        .iter()
        .map(|&(_, _, k)| grid.center_of(k).extend(EYE_HEIGHT))
        .find(|&p| !scene.objects.iter().any(|o| o.obb.contains(p, 0.0)));
    match eye {
        Some(p) => DefaultEye {
            position: p.to_array(),
            target: target.to_array(),
            grid: Some(source.as_str()),
            warning: None,
        },
        None => at_target(format!(
            "the navigation grid ({}) has no free cell with room for the agent; the camera stands at the middle of the largest room or of the Gaussians, which may be inside an object",
            source.as_str()
        )),
    }
}

impl Default for CameraPose {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Where a render's camera comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraSource {
    /// A camera JSON file ([`CameraSpec`]): width, height, hfov_deg or fx/fy/cx/cy, a pose,
    /// near and far.
    File(PathBuf),
    /// A camera set field by field.
    Pose(CameraPose),
}

impl CameraSource {
    /// The camera in `scene`.
    ///
    /// # Errors
    ///
    /// An unreadable or malformed camera file (naming it), or a pose that makes no camera.
    pub fn camera(&self, scene: &Scene) -> Result<Camera> {
        self.resolve(scene).map(|(camera, _)| camera)
    }

    /// The camera in `scene`, with how its eye was chosen when a pose gave no position
    /// ([`CameraPose::resolve`]; a camera file always places its camera).
    ///
    /// # Errors
    ///
    /// As [`CameraSource::camera`].
    pub fn resolve(&self, scene: &Scene) -> Result<(Camera, Option<DefaultEye>)> {
        match self {
            CameraSource::File(path) => {
                let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
                CameraSpec::parse(&text)
                    .and_then(|s| s.camera())
                    .map(|camera| (camera, None))
                    .map_err(|e| e.in_file(path))
            }
            CameraSource::Pose(pose) => pose.resolve(scene),
        }
    }
}

/// What [`render_to_folder`] renders, and on what.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// The scene folder.
    pub scene: PathBuf,
    /// The camera.
    pub camera: CameraSource,
    /// Background colour, r,g,b in 0–1.
    pub background: [f32; 3],
    /// Also a full turn of this many frames (1–[`MAX_TURNTABLE_FRAMES`]) about the camera.
    pub turntable: Option<usize>,
    /// Where the images are rendered.
    pub device: Device,
}

impl RenderSettings {
    /// The background of a render given none: black.
    pub const DEFAULT_BACKGROUND: [f32; 3] = [0.0, 0.0, 0.0];

    /// A render of the scene in `scene` with every other setting at its default: the
    /// [`CameraPose::DEFAULT`] camera, a black background, no turntable, on the CPU.
    pub fn new(scene: impl Into<PathBuf>) -> Self {
        RenderSettings {
            scene: scene.into(),
            camera: CameraSource::Pose(CameraPose::DEFAULT),
            background: Self::DEFAULT_BACKGROUND,
            turntable: None,
            device: Device::default(),
        }
    }

    /// Checks what can be checked without the scene, so that a bad setting fails before any
    /// work.
    ///
    /// # Errors
    ///
    /// A background channel outside 0–1 (NaN included), or a turntable of no frames or of more
    /// than [`MAX_TURNTABLE_FRAMES`], naming the field.
    pub fn validate(&self) -> Result<()> {
        if let Some(v) = self.background.iter().find(|v| !(0.0..=1.0).contains(*v)) {
            return Err(Error::invalid(format!(
                "each of r,g,b must be a linear colour in 0-1, got {v}"
            ))
            .within("`background`"));
        }
        match self.turntable {
            Some(n) if n == 0 || n > MAX_TURNTABLE_FRAMES => Err(Error::invalid(format!(
                "must be 1-{MAX_TURNTABLE_FRAMES} frames, got {n}"
            ))
            .within("`turntable`")),
            _ => Ok(()),
        }
    }
}

/// The most turntable frames a render makes (one every 0.1°).
pub const MAX_TURNTABLE_FRAMES: usize = 3600;

/// What [`render_to_folder`] tells its caller as it goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RenderProgress<'a> {
    /// The renderer is open, before the first image; in words ([`Backend::describe`]).
    Opened(&'a str),
    /// `done` of the turntable's `frames` frames are written.
    Turntable {
        /// Frames written so far.
        done: usize,
        /// Frames in all.
        frames: usize,
    },
}

/// What [`render_to_folder`] wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RenderReport {
    /// The scene's name.
    pub scene: String,
    /// The renderer, in words.
    pub renderer: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Time of the main image, ms: the CPU renderer's stages summed, or the GPU's frame timed
    /// whole, read-back included.
    pub frame_ms: f64,
    /// Splats drawn, where the renderer counts them (the CPU's).
    pub splats: Option<usize>,
    /// Turntable frames written.
    pub turntable: Option<usize>,
    /// How the eye was chosen, when no camera position was given (its warning, if any, is one
    /// to show).
    pub default_eye: Option<DefaultEye>,
    /// The files written, relative to the output folder, in the order written.
    pub files: Vec<PathBuf>,
}

/// The command that writes a render folder, as its run record names it.
pub const RENDER_COMMAND: &str = "render";

/// The folder of turntable frames inside a render folder.
pub const TURNTABLE_DIR: &str = "turntable";

/// The turntable's animation inside a render folder.
pub const TURNTABLE_GIF: &str = "turntable.gif";
/// How long each turntable frame is shown, hundredths of a second.
const TURNTABLE_DELAY: u16 = 8;

/// The images of one view, written at the top of a render folder, in the order written.
const IMAGES: [&str; 7] = [
    "rgb.png",
    "depth.npy",
    "depth_median.npy",
    "alpha.npy",
    "depth.png",
    "instance.png",
    "semantic.png",
];

/// Everything a render may write at the top of its output folder.
const OUTPUTS: [&str; 12] = [
    IMAGES[0],
    IMAGES[1],
    IMAGES[2],
    IMAGES[3],
    IMAGES[4],
    IMAGES[5],
    IMAGES[6],
    "legend.json",
    "render.json",
    TURNTABLE_DIR,
    TURNTABLE_GIF,
    sage_io::RUN_RECORD,
];

/// Renders as `settings` say into `out`: every channel, the legend, `render.json`, the
/// turntable if asked, and the run record, marked unfinished before the first file and written
/// in full after the last ([`sage_io::run::mark_unfinished`]). `out` must be new, empty or a
/// render's, finished or not (a rerun replaces its files); with `force`, a folder of other
/// files is written into, provided none of them would be replaced
/// ([`sage_io::run::claim_folder`]). `on_progress` hears when the renderer is open and as
/// turntable frames are written.
///
/// # Errors
///
/// A bad setting, a scene or camera file that cannot be read, a scene without Gaussians
/// ([`Scene::load_for_rendering`]), an output folder holding files a render did not write, a
/// device that cannot render, or a write error.
pub fn render_to_folder(
    settings: &RenderSettings,
    out: &Path,
    force: bool,
    on_progress: &mut dyn FnMut(RenderProgress),
) -> Result<RenderReport> {
    settings.validate()?;
    let (scene, _) = Scene::load_for_rendering(&settings.scene)?;
    let (camera, default_eye) = settings.camera.resolve(&scene)?;
    let options = RenderOptions {
        background: settings.background,
        ..RenderOptions::default()
    };
    let _lock = sage_io::run::claim_folder(out, &[RENDER_COMMAND], &OUTPUTS, force)?;
    let mut backend = Backend::open(settings.device, &scene.gaussians)?;
    let renderer = backend.describe().to_string();
    on_progress(RenderProgress::Opened(&renderer));
    let start = Instant::now();
    let image = backend.render(
        &scene.gaussians,
        &scene.instances.category_ids,
        &camera,
        &options,
    )?;
    // The CPU renderer times its stages; the GPU's frame is timed whole, read-back included.
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let stats = backend.as_cpu().map(RendererPool::stats);
    sage_io::run::mark_unfinished(out, RENDER_COMMAND, None)?;
    remove_turntable(out)?;
    write_images(out, &image)?;
    write_legend(&out.join("legend.json"), &scene, &image)?;
    let mut files: Vec<PathBuf> = IMAGES.iter().map(PathBuf::from).collect();
    files.push("legend.json".into());
    let mut record = serde_json::json!({
        "renderer": renderer,
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
    if let Some(eye) = &default_eye {
        record["default_eye"] = serde_json::json!(eye);
    }
    let (frame_ms, splats) = match stats {
        Some(stats) => {
            record["stats_ms"] = serde_json::json!({"cull": stats.cull_ms, "project": stats.project_ms, "sort": stats.sort_ms, "raster": stats.raster_ms});
            record["splats"] = stats.splats.into();
            (
                stats.cull_ms + stats.project_ms + stats.sort_ms + stats.raster_ms,
                Some(stats.splats),
            )
        }
        None => {
            record["frame_ms"] = wall_ms.into();
            (wall_ms, None)
        }
    };
    write_json(&out.join("render.json"), &record)?;
    files.push("render.json".into());
    if let Some(n) = settings.turntable {
        write_turntable(out, &mut backend, &scene, &camera, &options, n, on_progress)?;
        files.extend((0..n).map(|f| Path::new(TURNTABLE_DIR).join(frame_name(f))));
        files.push(TURNTABLE_GIF.into());
    }
    sage_io::run::write_run_record(
        out,
        RENDER_COMMAND,
        None,
        serde_json::json!({
            "scene": scene.name,
            "settings": {
                "scene": settings.scene,
                "camera": record["camera"],
                "background": settings.background,
                "turntable": settings.turntable,
                "device": settings.device,
            },
            "inputs": sage_scene::input_hashes(&settings.scene),
        }),
    )?;
    files.push(sage_io::RUN_RECORD.into());
    Ok(RenderReport {
        scene: scene.name,
        renderer,
        width: camera.intrinsics.width,
        height: camera.intrinsics.height,
        frame_ms,
        splats,
        turntable: settings.turntable,
        default_eye,
        files,
    })
}

pub use sage_io::palette::id_color;

fn colorize(ids: impl Iterator<Item = u32>) -> Vec<u8> {
    ids.flat_map(id_color).collect()
}

fn write_images(dir: &Path, image: &RenderOutput) -> Result<()> {
    let (w, h) = (image.width, image.height);
    write_rgb_png(&dir.join("rgb.png"), w, h, &image.rgb)?;
    write_npy_f32(&dir.join("depth.npy"), &[h, w], &image.depth_expected)?;
    write_npy_f32(&dir.join("depth_median.npy"), &[h, w], &image.depth_median)?;
    write_npy_f32(&dir.join("alpha.npy"), &[h, w], &image.alpha)?;
    write_png(
        &dir.join("depth.png"),
        w,
        h,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &depth_mm(&image.depth_expected),
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

/// Depths in metres as 16-bit big-endian millimetres, the bytes of a 16-bit grey PNG
/// (clamped at 65.535 m; negative and NaN depths are 0).
fn depth_mm(depth: &[f32]) -> Vec<u8> {
    depth
        .iter()
        .flat_map(|d| ((d * 1000.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes())
        .collect()
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

/// Removes an earlier render's turntable from the render folder `out` (claimed, so what
/// stands under the turntable's names is a render's): its frames (files named as
/// [`frame_name`] names them; anything else in the folder stays, and keeps the folder) and
/// its animation. A rerun with fewer frames, or none, would otherwise leave frames of another
/// size or camera beside its own.
fn remove_turntable(out: &Path) -> Result<()> {
    let gif = out.join(TURNTABLE_GIF);
    if gif.is_file() {
        std::fs::remove_file(&gif).map_err(|e| Error::io(&gif, e))?;
    }
    let folder = out.join(TURNTABLE_DIR);
    let Ok(entries) = std::fs::read_dir(&folder) else {
        return Ok(());
    };
    for entry in entries {
        let path = entry.map_err(|e| Error::io(&folder, e))?.path();
        let is_frame = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_prefix("rgb_")?.strip_suffix(".png"))
            .is_some_and(|f| f.len() >= 3 && f.bytes().all(|b| b.is_ascii_digit()));
        if is_frame && path.is_file() {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    // Left where anything else is in it.
    let _ = std::fs::remove_dir(&folder);
    Ok(())
}

/// The file of turntable frame `f` inside [`TURNTABLE_DIR`].
fn frame_name(f: usize) -> String {
    format!("rgb_{f:03}.png")
}

/// The cameras of a full turn of `frames` about `camera`'s position, starting at its heading
/// and keeping its pitch, intrinsics and depth range.
fn turntable_cameras(camera: &Camera, frames: usize) -> Vec<Camera> {
    let forward = camera.rotation.z_axis;
    let (yaw0, pitch) = (
        forward.y.atan2(forward.x),
        forward.z.clamp(-1.0, 1.0).asin(),
    );
    (0..frames)
        .map(|f| {
            let yaw = yaw0 + std::f32::consts::TAU * f as f32 / frames as f32;
            Camera {
                near: camera.near,
                far: camera.far,
                ..Camera::from_yaw_pitch(camera.intrinsics, camera.position, yaw, pitch)
            }
        })
        .collect()
}

fn write_turntable(
    dir: &Path,
    backend: &mut Backend,
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    frames: usize,
    on_progress: &mut dyn FnMut(RenderProgress),
) -> Result<()> {
    let folder = dir.join(TURNTABLE_DIR);
    std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, e))?;
    let cameras = turntable_cameras(camera, frames);
    let options = RenderOptions {
        channels: Channels::RGB,
        ..*options
    };
    let mut images = Vec::with_capacity(frames);
    for batch in cameras.chunks(TURNTABLE_BATCH) {
        let rendered = backend.render_batch(
            &scene.gaussians,
            &scene.instances.category_ids,
            batch,
            &options,
        )?;
        for image in rendered {
            write_rgb_png(
                &folder.join(frame_name(images.len())),
                image.width,
                image.height,
                &image.rgb,
            )?;
            images.push(image.rgb);
            on_progress(RenderProgress::Turntable {
                done: images.len(),
                frames,
            });
        }
    }
    let (w, h) = (
        camera.intrinsics.width as usize,
        camera.intrinsics.height as usize,
    );
    sage_io::files::write_atomic(&dir.join(TURNTABLE_GIF), |out| {
        let mut gif = GifWriter::new(out, w, h)?;
        for rgb in &images {
            gif.frame(rgb, TURNTABLE_DELAY)?;
        }
        gif.finish().map(|_| ())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_zero_is_black_and_others_are_distinct() {
        assert_eq!(id_color(0), [0, 0, 0]);
        let colors: std::collections::BTreeSet<[u8; 3]> = (1..64).map(id_color).collect();
        assert_eq!(colors.len(), 63);
        assert!(!colors.contains(&[0, 0, 0]));
    }

    #[test]
    fn depth_is_big_endian_millimetres_clamped() {
        let bytes = depth_mm(&[0.0, 1.2346, -1.0, 70.0, f32::NAN]);
        let mm: Vec<u16> = bytes
            .chunks(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(mm, [0, 1235, 0, 65535, 0]);
    }

    #[test]
    fn a_turntable_turns_once_at_the_camera_keeping_its_pitch() {
        let intrinsics = Intrinsics::from_hfov(40, 30, 90.0).unwrap();
        let eye = Vec3::new(1.0, 2.0, 1.2);
        let camera = Camera::from_yaw_pitch(intrinsics, eye, 0.5, -0.2);
        let cameras = turntable_cameras(&camera, 4);
        assert_eq!(cameras.len(), 4);
        let first = cameras[0].rotation.z_axis;
        assert!(first.abs_diff_eq(camera.rotation.z_axis, 1e-5), "{first}");
        for c in &cameras {
            assert_eq!(c.position, eye);
            assert!((c.rotation.z_axis.z - camera.rotation.z_axis.z).abs() < 1e-5);
            assert_eq!((c.near, c.far), (camera.near, camera.far));
        }
        // A quarter turn a frame: the second frame looks 90° left of the first.
        let (a, b) = (cameras[0].rotation.z_axis, cameras[1].rotation.z_axis);
        let turn = b.y.atan2(b.x) - a.y.atan2(a.x);
        assert!(
            (turn.rem_euclid(std::f32::consts::TAU) - std::f32::consts::FRAC_PI_2).abs() < 1e-4
        );
    }

    #[test]
    fn a_pose_out_of_range_is_refused_naming_its_setting() {
        let pose = |position: Option<Vec3>, yaw_deg: f32, pitch_deg: f32| CameraPose {
            position,
            yaw_deg,
            pitch_deg,
            ..CameraPose::DEFAULT
        };
        let refused = |p: CameraPose| p.validate().unwrap_err().message().to_string();
        assert!(
            pose(Some(Vec3::new(1e4, -1e4, 0.0)), -720.0, 90.0)
                .validate()
                .is_ok()
        );
        assert!(pose(None, 0.0, -90.0).validate().is_ok());
        for bad in [f32::NAN, f32::INFINITY, 1.0001e4] {
            let message = refused(pose(Some(Vec3::new(0.0, bad, 1.2)), 0.0, 0.0));
            assert!(message.contains("`position`"), "{message}");
        }
        for bad in [f32::NAN, f32::NEG_INFINITY] {
            assert!(refused(pose(None, bad, 0.0)).contains("`yaw`"));
        }
        for bad in [f32::NAN, 90.01, -400.0, f32::INFINITY] {
            assert!(refused(pose(None, 0.0, bad)).contains("`pitch`"));
        }
    }

    #[test]
    fn a_render_writes_what_it_reports_and_tells_its_progress() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        let config = sage_synth::SynthConfig {
            seed: 4,
            rooms: 2,
            objects: 6,
            gaussians: 2000,
            ..sage_synth::SynthConfig::default()
        };
        crate::scene::synthesize(&config, &scene, sage_scene::SplatLayout::Standard, &|_| {})
            .unwrap();
        let settings = RenderSettings {
            camera: CameraSource::Pose(CameraPose {
                width: 24,
                height: 16,
                ..CameraPose::DEFAULT
            }),
            turntable: Some(3),
            ..RenderSettings::new(&scene)
        };
        let out = dir.path().join("render");
        let mut heard = Vec::new();
        let report = render_to_folder(&settings, &out, false, &mut |p| {
            heard.push(match p {
                RenderProgress::Opened(r) => r.to_string(),
                RenderProgress::Turntable { done, frames } => format!("{done}/{frames}"),
            })
        })
        .unwrap();
        assert_eq!(heard[1..], ["1/3", "2/3", "3/3"]);
        assert_eq!(heard[0], report.renderer);
        assert_eq!(
            (report.width, report.height, report.turntable),
            (24, 16, Some(3))
        );
        assert_eq!(report.files.len(), 7 + 2 + 3 + 1 + 1);
        for f in &report.files {
            assert!(out.join(f).is_file(), "{}", f.display());
        }
        // Every file at the top of the folder is one the render may write.
        for name in sage_io::run::entries(&out).unwrap() {
            assert!(OUTPUTS.contains(&name.as_str()), "{name}");
        }
        // A rerun with a shorter turntable, then none, leaves no frame of the earlier ones;
        // a file of the user's in the turntable folder stays.
        std::fs::write(out.join(TURNTABLE_DIR).join("notes.txt"), "mine").unwrap();
        let fewer = RenderSettings {
            turntable: Some(2),
            ..settings.clone()
        };
        render_to_folder(&fewer, &out, false, &mut |_| {}).unwrap();
        let listed = |dir: &Path| sage_io::run::entries(dir).unwrap();
        assert_eq!(
            listed(&out.join(TURNTABLE_DIR)),
            ["notes.txt", "rgb_000.png", "rgb_001.png"]
        );
        let none = RenderSettings {
            turntable: None,
            ..settings.clone()
        };
        render_to_folder(&none, &out, false, &mut |_| {}).unwrap();
        assert_eq!(listed(&out.join(TURNTABLE_DIR)), ["notes.txt"]);
        assert!(!out.join(TURNTABLE_GIF).exists());
        std::fs::remove_file(out.join(TURNTABLE_DIR).join("notes.txt")).unwrap();
        render_to_folder(&none, &out, false, &mut |_| {}).unwrap();
        assert!(!out.join(TURNTABLE_DIR).exists());
        // A bad setting fails before the folder is claimed.
        let bad = RenderSettings {
            turntable: Some(0),
            ..settings
        };
        let fresh = dir.path().join("fresh");
        assert!(render_to_folder(&bad, &fresh, false, &mut |_| {}).is_err());
        assert!(!fresh.exists());
    }

    #[test]
    fn settings_default_once_and_turntables_are_bounded() {
        let s = RenderSettings::new("scene");
        assert_eq!(s.camera, CameraSource::Pose(CameraPose::default()));
        assert_eq!((s.background, s.turntable), ([0.0; 3], None));
        assert_eq!(s.device, Device::Cpu);
        assert!(s.validate().is_ok());
        let background = |v: f32| RenderSettings {
            background: [0.5, v, 0.5],
            ..RenderSettings::new("scene")
        };
        let turntable = |n: usize| RenderSettings {
            turntable: Some(n),
            ..RenderSettings::new("scene")
        };
        let colour_error = Some("`background`: each of r,g,b");
        let frames_error = Some("`turntable`: must be 1-3600");
        let cases = [
            (background(0.0), None),
            (background(1.0), None),
            (background(1.5), colour_error),
            (background(-0.1), colour_error),
            (background(f32::NAN), colour_error),
            (turntable(1), None),
            (turntable(MAX_TURNTABLE_FRAMES), None),
            (turntable(0), frames_error),
            (turntable(3601), frames_error),
        ];
        for (s, error) in cases {
            match (s.validate(), error) {
                (Ok(()), None) => {}
                (Err(e), Some(start)) => assert!(e.to_string().starts_with(start), "{e}"),
                (r, _) => panic!("{:?} / {:?}: {r:?}", s.background, s.turntable),
            }
        }
    }
}
