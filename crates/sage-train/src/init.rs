//! The surface-sampled initialisation: one flat, fairly opaque Gaussian per surface sample,
//! lying in the surface's tangent plane, sized so that neighbours `spacing` apart overlap.

use glam::{Quat, Vec3};
use sage_scene::gaussians::SH_C0;
use sage_scene::{Gaussian, Gaussians};

/// Standard deviation along the surface, in units of the sample spacing.
const TANGENT_SIGMA: f32 = 0.6;
/// Standard deviation along the normal, in units of the sample spacing.
const NORMAL_SIGMA: f32 = 0.05;
/// Initial opacity.
const OPACITY: f32 = 0.7;

/// One Gaussian (SH degree 0) per `(position, rgb 0–1, surface normal)` sample: a disc of
/// σ = 0.6·`spacing` in the tangent plane, 0.05·`spacing` thick, opacity 0.7, colour `rgb`.
/// A zero normal gives a round Gaussian of σ = 0.6·`spacing`.
pub fn init_gaussians(points: &[(Vec3, [f32; 3], Vec3)], spacing: f32) -> Gaussians {
    let tangent = (TANGENT_SIGMA * spacing).max(1e-6).ln();
    let logit = (OPACITY / (1.0 - OPACITY)).ln();
    // The default store is SH degree 0.
    let mut store = Gaussians::default();
    for &(position, rgb, normal) in points {
        let n = normal.normalize_or_zero();
        let (rotation, thickness) = if n == Vec3::ZERO {
            (Quat::IDENTITY, tangent)
        } else {
            (
                Quat::from_rotation_arc(Vec3::Z, n),
                (NORMAL_SIGMA * spacing).max(1e-6).ln(),
            )
        };
        store.push(&Gaussian {
            position,
            rotation,
            log_scale: Vec3::new(tangent, tangent, thickness),
            opacity_logit: logit,
            sh_dc: rgb.map(|c| (c.clamp(0.0, 1.0) - 0.5) / SH_C0),
            ..Gaussian::default()
        });
    }
    store
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discs_lie_in_the_tangent_plane_with_the_sample_colour() {
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let g = init_gaussians(&[(Vec3::ONE, [0.9, 0.2, 0.5], n * 3.0)], 0.1);
        let x = g.get(0);
        // The thin axis (local z) is the normal.
        assert!((x.rotation * Vec3::Z).dot(n) > 0.9999);
        assert!((x.log_scale.z.exp() - 0.005).abs() < 1e-5);
        assert!((x.log_scale.x.exp() - 0.06).abs() < 1e-4);
        for (c, want) in x.base_color().iter().zip([0.9, 0.2, 0.5]) {
            assert!((c - want).abs() < 1e-3);
        }
        assert!((x.opacity() - 0.7).abs() < 1e-3);
    }
}
