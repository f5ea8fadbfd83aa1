//! What the renderer's test programs share: generated homes and level cameras.

use glam::Vec3;
use sage_splat::{Camera, Intrinsics};
use sage_synth::{SynthConfig, generate};

/// A generated home of `rooms` rooms, `objects` objects and `gaussians` Gaussians.
pub fn home(seed: u64, rooms: usize, objects: usize, gaussians: usize) -> sage_scene::scene::Scene {
    generate(&SynthConfig {
        seed,
        rooms,
        objects,
        gaussians,
        ..SynthConfig::default()
    })
    .unwrap()
}

/// A camera of `w` × `h` pixels and 90° horizontal field of view at `position`, turned by
/// `yaw` and `pitch` (radians).
pub fn camera(w: u32, h: u32, position: Vec3, yaw: f32, pitch: f32) -> Camera {
    Camera::from_yaw_pitch(
        Intrinsics::from_hfov(w, h, 90.0).unwrap(),
        position,
        yaw,
        pitch,
    )
}
