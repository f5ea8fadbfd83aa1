//! Ground-truth views of the mesh scene: one ray per pixel centre through a [`Bvh`] of every
//! triangle, the first hit's shaded colour ([`crate::surfaces::shade`]) and its z-depth. Rows
//! run in parallel; every pixel is a pure function of the scene and the camera, so the image
//! does not depend on the thread count.

use crate::bvh::Bvh;
use crate::surfaces::SceneSurfaces;
use glam::Vec3;
use rayon::prelude::*;
use sage_splat::Camera;

/// An RGB image with its z-depth.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshImage {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `height × width × 3` bytes, rows top to bottom; black where the ray hits nothing.
    pub rgb: Vec<u8>,
    /// Z-depth (along the optical axis), metres; 0 where the ray hits nothing.
    pub depth: Vec<f32>,
}

impl MeshImage {
    /// Depth in whole millimetres (16-bit, saturating; 0 where nothing was hit), the unit
    /// nerfstudio reads depth PNGs in.
    pub fn depth_mm(&self) -> Vec<u16> {
        self.depth
            .iter()
            .map(|d| (d * 1000.0).round().clamp(0.0, 65535.0) as u16)
            .collect()
    }
}

/// The world direction of the ray through pixel centre `(i + 0.5, j + 0.5)`, scaled so its
/// component along the optical axis is 1 (the hit's ray parameter is then its z-depth).
pub fn pixel_ray(camera: &Camera, i: usize, j: usize) -> Vec3 {
    let k = &camera.intrinsics;
    let c = Vec3::new(
        (i as f32 + 0.5 - k.cx) / k.fx,
        (j as f32 + 0.5 - k.cy) / k.fy,
        1.0,
    );
    camera.rotation * c
}

/// Renders `surfaces` (with `bvh` built from them) from `camera`; hits nearer than the
/// camera's near plane or beyond its far plane are ignored.
pub fn render_view(surfaces: &SceneSurfaces, bvh: &Bvh, camera: &Camera) -> MeshImage {
    let (w, h) = (
        camera.intrinsics.width as usize,
        camera.intrinsics.height as usize,
    );
    let mut rgb = vec![0u8; w * h * 3];
    let mut depth = vec![0f32; w * h];
    rgb.par_chunks_mut(w * 3)
        .zip(depth.par_chunks_mut(w))
        .enumerate()
        .for_each(|(j, (row_rgb, row_depth))| {
            for i in 0..w {
                let dir = pixel_ray(camera, i, j);
                if let Some(hit) = bvh.raycast(camera.position, dir, camera.near, camera.far) {
                    let c = surfaces.colors[hit.triangle];
                    row_rgb[i * 3..i * 3 + 3].copy_from_slice(&c.map(to_u8));
                    row_depth[i] = hit.t;
                }
            }
        });
    MeshImage {
        width: w,
        height: h,
        rgb,
        depth,
    }
}

/// An sRGB value in 0–1 as an 8-bit sample.
pub fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}
