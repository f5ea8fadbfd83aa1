//! The three frames of SPEC §3 and the fixed conversions between them.
//!
//! - **W** (internal, InteriorGS): right-handed, Z up, metres, floor at z = 0.
//! - **Habitat** (R2R-VLNCE files): Y up, agents face −Z; quaternions stored `[x, y, z, w]`.
//!   `H = R·W` with `R` the rotation of −90° about X: `(x, y, z)_H = (x, z, −y)_W`.
//!   An agent with identity rotation in Habitat faces −Z_H = +Y_W, i.e. W heading π/2, so a
//!   Habitat yaw θ about +Y_H is the W heading ψ = θ + π/2.
//! - **S** (published SAGE-Bench trajectories): W rotated 180° about Z plus a per-scene offset
//!   `(δx, δy)`: `x_S = −x_W + δx`, `y_S = −y_W + δy`, `z_S = z_W`; headings differ by π.

use crate::pose::{Pose, wrap_angle};
use glam::{Quat, Vec2, Vec3};
use std::f32::consts::FRAC_PI_2;

/// Converts a point from W to Habitat.
pub fn world_to_habitat(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// Converts a point from Habitat to W.
pub fn habitat_to_world(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.z, p.y)
}

/// The Habitat agent rotation (as `[x, y, z, w]`) for a W heading ψ.
pub fn heading_to_habitat_quat(yaw: f32) -> [f32; 4] {
    let q = Quat::from_rotation_y(yaw - FRAC_PI_2);
    [q.x, q.y, q.z, q.w]
}

/// The W heading ψ of a Habitat agent rotation `[x, y, z, w]`.
///
/// The heading is read from where the rotation sends the agent's forward axis (−Z_H), so it is
/// correct for any rotation, not only for pure rotations about Y.
pub fn habitat_quat_to_heading(xyzw: [f32; 4]) -> f32 {
    let q = Quat::from_xyzw(xyzw[0], xyzw[1], xyzw[2], xyzw[3]).normalize();
    let forward_h = q * Vec3::NEG_Z;
    let forward_w = habitat_to_world(forward_h);
    forward_w.y.atan2(forward_w.x)
}

/// A pose in W as the Habitat `(position, rotation [x, y, z, w])` pair.
pub fn pose_to_habitat(pose: &Pose) -> (Vec3, [f32; 4]) {
    (
        world_to_habitat(pose.position),
        heading_to_habitat_quat(pose.yaw),
    )
}

/// The per-scene offset of the SAGE "S" frame (research notes §1.6).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SageFrame {
    /// `(δx, δy)` in metres: `x_S = −x_W + δx`, `y_S = −y_W + δy`.
    pub offset: Vec2,
}

impl SageFrame {
    /// Converts a point from W to S.
    pub fn world_to_sage(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.offset.x - p.x, self.offset.y - p.y, p.z)
    }

    /// Converts a point from S to W (the map is its own inverse up to the offset).
    pub fn sage_to_world(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.offset.x - p.x, self.offset.y - p.y, p.z)
    }

    /// Converts a W heading to an S heading (π apart).
    pub fn heading_to_sage(&self, yaw: f32) -> f32 {
        wrap_angle(yaw + std::f32::consts::PI)
    }

    /// Converts an S heading to a W heading.
    pub fn heading_to_world(&self, yaw: f32) -> f32 {
        wrap_angle(yaw - std::f32::consts::PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-4
    }

    fn angle_close(a: f32, b: f32) -> bool {
        wrap_angle(a - b).abs() < 1e-4
    }

    #[test]
    fn up_maps_to_up_and_is_a_rotation() {
        assert!(close(world_to_habitat(Vec3::Z), Vec3::Y));
        let x = world_to_habitat(Vec3::X);
        let y = world_to_habitat(Vec3::Y);
        let z = world_to_habitat(Vec3::Z);
        assert!(
            (x.cross(y).dot(z) - 1.0).abs() < 1e-6,
            "determinant must be +1"
        );
    }

    #[test]
    fn identity_habitat_agent_faces_world_plus_y() {
        assert!(angle_close(
            habitat_quat_to_heading([0.0, 0.0, 0.0, 1.0]),
            FRAC_PI_2
        ));
        let q = heading_to_habitat_quat(FRAC_PI_2);
        assert!(q[1].abs() < 1e-6 && (q[3] - 1.0).abs() < 1e-6);
    }

    proptest! {
        #[test]
        fn habitat_round_trip(x in -50.0f32..50.0, y in -50.0f32..50.0, z in -5.0f32..5.0, yaw in -3.1f32..3.1) {
            let p = Vec3::new(x, y, z);
            prop_assert!(close(habitat_to_world(world_to_habitat(p)), p));
            prop_assert!(close(world_to_habitat(habitat_to_world(p)), p));
            prop_assert!(angle_close(habitat_quat_to_heading(heading_to_habitat_quat(yaw)), yaw));
        }

        #[test]
        fn habitat_quat_rotates_forward_consistently(yaw in -3.1f32..3.1) {
            // The W forward of heading ψ, mapped to Habitat, must equal the quaternion applied to −Z.
            let q = heading_to_habitat_quat(yaw);
            let q = Quat::from_xyzw(q[0], q[1], q[2], q[3]);
            let fw = Vec3::new(yaw.cos(), yaw.sin(), 0.0);
            prop_assert!(close(q * Vec3::NEG_Z, world_to_habitat(fw)));
        }

        #[test]
        fn sage_round_trip(x in -50.0f32..50.0, y in -50.0f32..50.0, dx in -5.0f32..5.0, dy in -5.0f32..5.0, yaw in -3.1f32..3.1) {
            let s = SageFrame { offset: Vec2::new(dx, dy) };
            let p = Vec3::new(x, y, 0.5);
            prop_assert!(close(s.sage_to_world(s.world_to_sage(p)), p));
            prop_assert!(angle_close(s.heading_to_world(s.heading_to_sage(yaw)), yaw));
            // A step forward in W is a step forward in S along the converted heading.
            let fw = Vec3::new(yaw.cos(), yaw.sin(), 0.0);
            let d = s.world_to_sage(p + fw) - s.world_to_sage(p);
            let ys = s.heading_to_sage(yaw);
            prop_assert!(close(d, Vec3::new(ys.cos(), ys.sin(), 0.0)));
        }
    }
}
