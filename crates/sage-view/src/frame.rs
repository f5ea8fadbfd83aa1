//! First-person frames: the agent camera at a pose, rendered by the scene's renderer and
//! encoded for the page.
//!
//! The camera is the one every observation uses ([`EnvConfig::camera`]): the preset's field of
//! view, the eye at the agent's camera height above the pose. So a frame at a recorded pose is
//! what the agent saw there (at the viewer's size) and what `sage3d render` gives for the same
//! eye, heading and pitch ([`render_command`]).

use crate::scenes::LoadedScene;
use glam::Vec3;
use sage_core::{Error, Pose, Result};
use sage_env::EnvConfig;
use sage_io::image::{encode_jpeg, encode_rgb_png};
use sage_io::palette::id_color;
use sage_physics::AgentProfile;
use sage_splat::{Channels, RenderOptions};
use serde::Deserialize;

/// Largest frame side the viewer renders, pixels.
pub const MAX_SIDE: u32 = 2048;
/// Depth shown as white at the camera fading to black at this distance, metres.
pub const DEPTH_RANGE_M: f32 = 10.0;
/// JPEG quality of the live view.
const JPEG_QUALITY: u8 = 85;

/// Which image of a render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Layer {
    /// Colour.
    #[default]
    Rgb,
    /// Median depth, grey: near is light, [`DEPTH_RANGE_M`] and beyond (or nothing) black.
    Depth,
    /// Category ids in their distinct colours (as `sage3d render`'s `semantic.png`).
    Semantic,
    /// Instance ids in their distinct colours (as `sage3d render`'s `instance.png`).
    Instance,
}

/// How a frame is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Baseline JPEG (the live view: small and quick).
    #[default]
    Jpeg,
    /// Lossless PNG (exact pixels).
    Png,
}

impl Format {
    /// The response's content type.
    pub fn content_type(self) -> &'static str {
        match self {
            Format::Jpeg => "image/jpeg",
            Format::Png => "image/png",
        }
    }
}

/// One frame: the agent's ground pose and camera pitch, the size, the image and its encoding.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct FrameRequest {
    /// Ground position x, metres (W frame).
    pub x: f32,
    /// Ground position y, metres.
    pub y: f32,
    /// Ground position z, metres (the floor under the agent).
    pub z: f32,
    /// Heading, radians counter-clockwise from +X.
    pub yaw: f32,
    /// Camera pitch, radians, up positive.
    #[serde(default)]
    pub pitch: f32,
    /// Width, pixels.
    #[serde(default = "default_width")]
    pub width: u32,
    /// Height, pixels.
    #[serde(default = "default_height")]
    pub height: u32,
    /// Which image.
    #[serde(default)]
    pub layer: Layer,
    /// Its encoding.
    #[serde(default)]
    pub format: Format,
}

fn default_width() -> u32 {
    640
}

fn default_height() -> u32 {
    480
}

impl FrameRequest {
    /// The pose of the request.
    pub fn pose(&self) -> Pose {
        Pose::new(Vec3::new(self.x, self.y, self.z), self.yaw)
    }

    /// Checks the numbers: positions and angles within ±[`sage_core::MAX_COORDINATE`] (metres,
    /// radians: so the angle in degrees of the `render` command it answers with stays a number),
    /// a size of 1 to [`MAX_SIDE`] pixels a side.
    ///
    /// # Errors
    ///
    /// The first field at fault, named.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("x", self.x),
            ("y", self.y),
            ("z", self.z),
            ("yaw", self.yaw),
            ("pitch", self.pitch),
        ] {
            // A NaN fails the bound; a query's number past f32's range arrives as inf.
            if !sage_core::within_bounds(glam::Vec3::splat(v)) {
                return Err(Error::invalid(format!(
                    "{name}: {v} is not a number within ±{}",
                    sage_core::MAX_COORDINATE
                )));
            }
        }
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_SIDE).contains(&v) {
                return Err(Error::invalid(format!(
                    "{name}: {v} is not 1–{MAX_SIDE} pixels"
                )));
            }
        }
        Ok(())
    }
}

/// Renders and encodes the frame `req` asks for in `scene` with the agent camera of
/// `config` and `profile`.
///
/// # Errors
///
/// A bad request ([`FrameRequest::validate`]), a render or encoding error.
pub fn render(
    scene: &LoadedScene,
    config: &EnvConfig,
    profile: &AgentProfile,
    req: &FrameRequest,
) -> Result<Vec<u8>> {
    req.validate()?;
    let camera = config.camera(profile, req.pose(), req.pitch, req.width, req.height)?;
    // Only the layer shown is rendered out (on the GPU, only it is read back).
    let none = Channels::NONE;
    let channels = match req.layer {
        Layer::Rgb => Channels::RGB,
        Layer::Depth => Channels {
            depth_median: true,
            ..none
        },
        Layer::Semantic => Channels {
            semantic: true,
            ..none
        },
        Layer::Instance => Channels {
            instance: true,
            ..none
        },
    };
    let options = RenderOptions {
        channels,
        ..RenderOptions::default()
    };
    let out = {
        let mut renderer = scene.ctx.renderer(scene.device)?;
        let gaussians = &scene.ctx.scene.gaussians;
        let categories = &scene.ctx.scene.instances.category_ids;
        renderer
            .render_batch(gaussians, categories, &[camera], &options)?
            .pop()
            .ok_or_else(|| Error::invalid("the renderer returned no image"))?
    };
    let rgb: Vec<u8> = match req.layer {
        Layer::Rgb => out.rgb,
        Layer::Depth => out
            .depth_median
            .iter()
            .flat_map(|&d| {
                let v = if d > 0.0 && d.is_finite() {
                    (255.0 * (1.0 - d / DEPTH_RANGE_M)).clamp(0.0, 255.0) as u8
                } else {
                    0
                };
                [v; 3]
            })
            .collect(),
        Layer::Semantic => out
            .semantic
            .iter()
            .flat_map(|&c| id_color(u32::from(c)))
            .collect(),
        Layer::Instance => out.instance.iter().flat_map(|&i| id_color(i)).collect(),
    };
    match req.format {
        Format::Jpeg => encode_jpeg(&rgb, out.width, out.height, JPEG_QUALITY),
        Format::Png => encode_rgb_png(out.width, out.height, &rgb),
    }
}

/// The `sage3d render` command that gives the same image as frame `req` of `scene_dir`: the
/// agent camera's eye, heading and pitch in degrees, field of view and size.
///
/// # Errors
///
/// A size or field of view that makes no camera.
pub fn render_command(
    scene_dir: &str,
    config: &EnvConfig,
    profile: &AgentProfile,
    req: &FrameRequest,
) -> Result<String> {
    let camera = config.camera(profile, req.pose(), req.pitch, req.width, req.height)?;
    let eye = camera.position;
    Ok(format!(
        "sage3d render {scene_dir} --out OUT --width {} --height {} --hfov {} --position {},{},{} --yaw {} --pitch {}",
        req.width,
        req.height,
        config.sensors.hfov_deg,
        eye.x,
        eye.y,
        eye.z,
        req.yaw.to_degrees(),
        req.pitch.to_degrees()
    ))
}
