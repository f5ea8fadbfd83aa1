//! Poses of agents and cameras in the world frame W, and angle helpers.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::{PI, TAU};

/// Wraps an angle in radians to (−π, π].
pub fn wrap_angle(a: f32) -> f32 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

/// A ground pose in W: position (metres, Z up) and heading ψ about +Z from +X, counter-clockwise.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Position in metres, world frame W.
    pub position: Vec3,
    /// Heading in radians, wrapped to (−π, π].
    pub yaw: f32,
}

impl Pose {
    /// A pose at `position` facing `yaw` (wrapped).
    pub fn new(position: Vec3, yaw: f32) -> Self {
        Pose {
            position,
            yaw: wrap_angle(yaw),
        }
    }

    /// The unit forward direction on the floor: (cos ψ, sin ψ).
    pub fn forward(&self) -> Vec2 {
        Vec2::new(self.yaw.cos(), self.yaw.sin())
    }

    /// The unit right direction on the floor: (sin ψ, −cos ψ) (SPEC §3).
    pub fn right(&self) -> Vec2 {
        Vec2::new(self.yaw.sin(), -self.yaw.cos())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn wrap_is_in_range_and_equivalent(a in -100.0f32..100.0) {
            let w = wrap_angle(a);
            prop_assert!(w > -PI - 1e-6 && w <= PI + 1e-6);
            prop_assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-4);
        }
    }

    #[test]
    fn pi_maps_to_pi() {
        assert!((wrap_angle(PI) - PI).abs() < 1e-6);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-6);
    }

    #[test]
    fn right_is_forward_rotated_clockwise() {
        let p = Pose::new(Vec3::ZERO, 0.3);
        let f = p.forward();
        let r = p.right();
        assert!((f.perp_dot(r) + 1.0).abs() < 1e-6);
    }
}
