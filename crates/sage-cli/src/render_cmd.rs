//! `sage3d render`: images of a scene from a camera — RGB, depth, instance and semantic, with a
//! legend — and an optional turntable.

use clap::Args;
use glam::Vec3;
use sage_core::{Error, Result};
use sage_pipeline::render::{
    CameraPose, CameraSource, RenderProgress, RenderSettings, render_to_folder,
};
use std::path::PathBuf;

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
    /// stands at 1.2 m over the free floor nearest the middle of the largest room (or of the
    /// Gaussians), set by the flags below.
    #[arg(
        long,
        conflicts_with_all = ["width", "height", "hfov", "position", "yaw", "pitch"]
    )]
    camera: Option<PathBuf>,
    /// Image width (without --camera).
    #[arg(
        long,
        default_value_t = CameraPose::DEFAULT.width,
        value_parser = clap::value_parser!(u32).range(1..=i64::from(sage_splat::MAX_IMAGE_SIDE))
    )]
    width: u32,
    /// Image height (without --camera).
    #[arg(
        long,
        default_value_t = CameraPose::DEFAULT.height,
        value_parser = clap::value_parser!(u32).range(1..=i64::from(sage_splat::MAX_IMAGE_SIDE))
    )]
    height: u32,
    /// Horizontal field of view, degrees (without --camera).
    #[arg(long, default_value_t = CameraPose::DEFAULT.hfov_deg, value_parser = sage_env::config::parse_hfov)]
    hfov: f32,
    /// Camera position x,y,z in metres (without --camera; default: free floor nearest the middle of the largest room, 1.2 m).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "X,Y,Z",
        allow_hyphen_values = true
    )]
    position: Option<Vec<f32>>,
    /// Heading, degrees (without --camera).
    #[arg(long, default_value_t = CameraPose::DEFAULT.yaw_deg, allow_hyphen_values = true)]
    yaw: f32,
    /// Pitch, degrees, up positive (without --camera).
    #[arg(
        long,
        default_value_t = CameraPose::DEFAULT.pitch_deg,
        allow_hyphen_values = true
    )]
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

/// Three numbers from a comma-separated flag value; `names` says which (`x,y,z`).
fn three(values: &[f32], names: &str) -> Result<[f32; 3]> {
    values
        .try_into()
        .map_err(|_| Error::invalid(format!("needs 3 numbers {names}, got {}", values.len())))
}

impl RenderArgs {
    /// The flags as the pipeline's settings.
    fn settings(&self) -> Result<RenderSettings> {
        let camera = match &self.camera {
            Some(path) => CameraSource::File(path.clone()),
            None => CameraSource::Pose(CameraPose {
                width: self.width,
                height: self.height,
                hfov_deg: self.hfov,
                position: self
                    .position
                    .as_deref()
                    .map(|p| three(p, "x,y,z").map_err(|e| e.within("--position")))
                    .transpose()?
                    .map(Vec3::from),
                yaw_deg: self.yaw,
                pitch_deg: self.pitch,
            }),
        };
        Ok(RenderSettings {
            camera,
            background: three(&self.background, "r,g,b").map_err(|e| e.within("--background"))?,
            turntable: self.turntable,
            device: self.device.device,
            ..RenderSettings::new(&self.scene)
        })
    }
}

/// The settings name a bad field; the user typed its flag, so the error names that.
fn name_the_flag(e: Error) -> Error {
    match e.location().as_str() {
        "turntable" => Error::invalid(e.message()).within("--turntable"),
        _ => e,
    }
}

pub fn run(a: RenderArgs) -> Result<()> {
    let settings = a.settings()?;
    // Hidden when standard error is not a terminal.
    let bar = crate::progress::bar("turntable {bar:40} {pos}/{len} frames {elapsed}");
    let rendered = render_to_folder(&settings, &a.out, a.force, &mut |p| match p {
        RenderProgress::Opened(renderer) => eprintln!("renderer: {renderer}"),
        RenderProgress::Turntable { done, frames } => {
            bar.set_length(frames as u64);
            bar.set_position(done as u64);
        }
    });
    bar.finish_and_clear();
    let report = rendered.map_err(name_the_flag)?;
    if let Some(warning) = report.default_eye.as_ref().and_then(|e| e.warning.as_ref()) {
        eprintln!("warning: {warning}");
    }
    let splats = report
        .splats
        .map_or(String::new(), |n| format!(" ({n} splats)"));
    eprintln!(
        "rendered {}x{} in {:.1} ms{splats} -> {}",
        report.width,
        report.height,
        report.frame_ms,
        a.out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        render: RenderArgs,
    }

    fn settings(args: &[&str]) -> Result<RenderSettings> {
        let mut argv = vec!["sage3d", "scene", "--out", "out"];
        argv.extend(args);
        Cli::parse_from(argv).render.settings()
    }

    #[test]
    fn the_flag_defaults_are_the_settings_defaults() {
        assert_eq!(settings(&[]).unwrap(), RenderSettings::new("scene"));
    }

    #[test]
    fn flags_become_settings_and_bad_counts_name_the_flag() {
        let s = settings(&[
            "--position",
            "1,-2,1.5",
            "--yaw",
            "-30",
            "--background",
            "1,1,1",
            "--turntable",
            "8",
        ])
        .unwrap();
        let CameraSource::Pose(pose) = s.camera else {
            panic!("{:?}", s.camera)
        };
        assert_eq!(pose.position, Some(Vec3::new(1.0, -2.0, 1.5)));
        assert_eq!(pose.yaw_deg, -30.0);
        assert_eq!((s.background, s.turntable), ([1.0; 3], Some(8)));
        let camera = settings(&["--camera", "cam.json"]).unwrap().camera;
        assert_eq!(camera, CameraSource::File("cam.json".into()));
        let e = settings(&["--position", "1,2"]).unwrap_err().to_string();
        assert_eq!(e, "--position: needs 3 numbers x,y,z, got 2");
        let e = settings(&["--background", "1"]).unwrap_err().to_string();
        assert_eq!(e, "--background: needs 3 numbers r,g,b, got 1");
    }
}
