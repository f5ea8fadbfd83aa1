//! `transforms.json` in the nerfstudio layout, which nerfstudio and gsplat train from.
//!
//! Our cameras use OpenCV axes (x right, y down, z forward, SPEC §3); nerfstudio's
//! `transform_matrix` is camera-to-world in OpenGL axes (x right, y up, z back). The world frame
//! stays W (Z up, metres). So `c2w_gl = c2w_cv · diag(1, −1, −1, 1)`: the same centre, the
//! camera's y and z columns negated — a sign flip, exact in floating point both ways.
//!
//! Intrinsics are `fl_x, fl_y, cx, cy, w, h` with `camera_model: "OPENCV"` and zero distortion;
//! pixel centres sit at +0.5 as in nerfstudio. Every frame names its RGB image and its depth
//! (16-bit PNG, millimetres: nerfstudio's default depth scale 0.001). Views whose index is a
//! multiple of [`HELDOUT_EVERY`] are held out (`val_filenames` and `test_filenames`); the rest
//! are `train_filenames` — the same views gsplat's `test_every = 8` holds out.

use crate::plan::PLAN_FILE;
use glam::{Mat3, Mat4, Vec4};
use sage_core::{Error, Result, ResultExt};
use sage_io::limits::JSON_MB;
use sage_splat::{Camera, Intrinsics};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Every `HELDOUT_EVERY`-th view (0, 8, 16, …) is held out of training.
pub const HELDOUT_EVERY: usize = 8;
/// The export's file name.
pub const TRANSFORMS_FILE: &str = "transforms.json";

/// The flip between OpenCV and OpenGL camera axes (its own inverse).
const FLIP_YZ: Mat4 = Mat4::from_cols(
    Vec4::new(1.0, 0.0, 0.0, 0.0),
    Vec4::new(0.0, -1.0, 0.0, 0.0),
    Vec4::new(0.0, 0.0, -1.0, 0.0),
    Vec4::new(0.0, 0.0, 0.0, 1.0),
);

/// Camera-to-world in OpenGL axes from camera-to-world in OpenCV axes.
pub fn opencv_to_opengl(c2w: Mat4) -> Mat4 {
    c2w * FLIP_YZ
}

/// Camera-to-world in OpenCV axes from camera-to-world in OpenGL axes.
pub fn opengl_to_opencv(c2w: Mat4) -> Mat4 {
    c2w * FLIP_YZ
}

/// One frame of `transforms.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// RGB image, relative to the file.
    pub file_path: String,
    /// Depth image (16-bit PNG, millimetres), relative to the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_file_path: Option<String>,
    /// Camera-to-world, OpenGL axes, row-major.
    pub transform_matrix: [[f32; 4]; 4],
}

/// The whole file (shared intrinsics; the fields nerfstudio's dataparser reads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Transforms {
    /// `"OPENCV"`.
    pub camera_model: String,
    /// Focal length x, pixels.
    pub fl_x: f32,
    /// Focal length y, pixels.
    pub fl_y: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Width, pixels.
    pub w: u32,
    /// Height, pixels.
    pub h: u32,
    /// Radial distortion (zero: the views are ideal pinhole images).
    pub k1: f32,
    /// Radial distortion.
    pub k2: f32,
    /// Tangential distortion.
    pub p1: f32,
    /// Tangential distortion.
    pub p2: f32,
    /// The frames, in view order.
    pub frames: Vec<Frame>,
    /// Images to train on.
    pub train_filenames: Vec<String>,
    /// Held-out images (the same list as `test_filenames`).
    pub val_filenames: Vec<String>,
    /// Held-out images.
    pub test_filenames: Vec<String>,
    /// Coloured points to start Gaussians from (nerfstudio's splatfacto reads them), relative
    /// to the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ply_file_path: Option<String>,
}

/// A view to export: its camera and its files (relative to `transforms.json`).
#[derive(Debug, Clone, PartialEq)]
pub struct ExportView {
    /// The camera (OpenCV axes).
    pub camera: Camera,
    /// RGB image path.
    pub rgb: String,
    /// Depth image path, when there is one.
    pub depth: Option<String>,
}

/// True for the views held out of training.
pub fn is_heldout(index: usize) -> bool {
    index.is_multiple_of(HELDOUT_EVERY)
}

/// The `transforms.json` content for `views`, which must share their intrinsics.
pub fn transforms_for(views: &[ExportView]) -> Result<Transforms> {
    let Some(first) = views.first() else {
        return Err(Error::invalid("export: no views to export"));
    };
    let k = first.camera.intrinsics;
    if let Some(i) = views.iter().position(|v| v.camera.intrinsics != k) {
        return Err(Error::invalid(format!(
            "export: view {i} has other intrinsics than view 0 (one camera model per file)"
        )));
    }
    let mut t = Transforms {
        camera_model: "OPENCV".to_string(),
        fl_x: k.fx,
        fl_y: k.fy,
        cx: k.cx,
        cy: k.cy,
        w: k.width,
        h: k.height,
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        frames: Vec::with_capacity(views.len()),
        train_filenames: Vec::new(),
        val_filenames: Vec::new(),
        test_filenames: Vec::new(),
        ply_file_path: None,
    };
    for (i, v) in views.iter().enumerate() {
        t.frames.push(Frame {
            file_path: v.rgb.clone(),
            depth_file_path: v.depth.clone(),
            transform_matrix: opencv_to_opengl(v.camera.c2w())
                .transpose()
                .to_cols_array_2d(),
        });
        if is_heldout(i) {
            t.val_filenames.push(v.rgb.clone());
            t.test_filenames.push(v.rgb.clone());
        } else {
            t.train_filenames.push(v.rgb.clone());
        }
    }
    Ok(t)
}

impl Transforms {
    /// The intrinsics of every frame.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            width: self.w,
            height: self.h,
            fx: self.fl_x,
            fy: self.fl_y,
            cx: self.cx,
            cy: self.cy,
        }
    }

    /// The cameras of the frames, back in OpenCV axes (errors name the frame).
    pub fn cameras(&self) -> Result<Vec<Camera>> {
        self.frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let cv =
                    opengl_to_opencv(Mat4::from_cols_array_2d(&f.transform_matrix).transpose());
                // Checked as a rigid motion, then taken as written: the flip is exact, so a
                // camera comes back bit for bit.
                let mut camera = Camera::from_c2w(self.intrinsics(), cv)
                    .map_err(|e| Error::format("transform_matrix", e.message()))
                    .within(format!("frames[{i}]"))?;
                camera.rotation = Mat3::from_mat4(cv);
                Ok(camera)
            })
            .collect()
    }
}

/// The point cloud's file name beside `transforms.json`.
pub const POINTS_FILE: &str = "points3d.ply";

/// Writes coloured points as a binary PLY (`x, y, z` float, `red, green, blue` uchar), the
/// layout nerfstudio loads through `ply_file_path` (atomically).
pub fn write_points_ply(path: &Path, points: &[(glam::Vec3, [f32; 3], glam::Vec3)]) -> Result<()> {
    sage_io::files::write_atomic(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
            points.len()
        )?;
        for (p, rgb, _) in points {
            for v in p.to_array() {
                w.write_all(&v.to_le_bytes())?;
            }
            w.write_all(&rgb.map(crate::raster::to_u8))?;
        }
        Ok(())
    })
}

/// Writes `transforms.json` (atomically). When `t` names no point cloud, the [`POINTS_FILE`]
/// beside `path` goes too if the export owns it: the file `path` replaces referenced it, or the
/// folder is a reconstruction folder (it holds [`PLAN_FILE`], whose `recon plan` claimed the
/// folder with [`POINTS_FILE`] among the files the reconstruction writes). Otherwise an export
/// with `--points 0` would leave the points of an earlier one beside it, and a reader that
/// looks for them there (splatfacto's `--load-3D-points`) would start from stale points. The
/// file is removed after the new `transforms.json` is in place, so the index never names a
/// missing file; any other `points3d.ply` (a user's, in a folder that is no reconstruction's)
/// is left alone.
///
/// Returns the point cloud it removed, if any, for the caller to say so.
///
/// # Errors
///
/// A write error, or an owned point cloud that cannot be removed (naming it).
pub fn write_transforms(path: &Path, t: &Transforms) -> Result<Option<PathBuf>> {
    // Read before the write replaces it: only the old file tells whether it named the points.
    let referenced = previous_points_reference(path)?;
    sage_io::files::write_json(path, t)?;
    if t.ply_file_path.is_some() {
        return Ok(None);
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    let owned = referenced || dir.join(PLAN_FILE).is_file();
    let points = dir.join(POINTS_FILE);
    if !(owned && points.is_file()) {
        return Ok(None);
    }
    std::fs::remove_file(&points).map_err(|e| Error::io(&points, e))?;
    Ok(Some(points))
}

/// Whether the `transforms.json` at `path` names [`POINTS_FILE`] beside it as its
/// `ply_file_path` (false when it is missing, unreadable or not JSON: then nothing shows the
/// export wrote the points). Only that exact name counts: a hand-edited file may name any point
/// cloud, which is then the user's.
///
/// # Errors
///
/// A file over `SAGE3D_MAX_JSON_MB`, refused from its size (naming it and the limit) rather
/// than read whole or taken for one that names no points.
fn previous_points_reference(path: &Path) -> Result<bool> {
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(false);
    };
    JSON_MB.check(meta.len(), "file size").in_file(path)?;
    Ok(sage_io::files::read_text(path, &JSON_MB)
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
        .is_some_and(|v| v.get("ply_file_path").and_then(|p| p.as_str()) == Some(POINTS_FILE)))
}

/// Reads a `transforms.json` written by [`write_transforms`] (or any file with its fields).
pub fn read_transforms(path: &Path) -> Result<Transforms> {
    sage_io::files::read_json(path)
}
