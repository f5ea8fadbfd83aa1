//! EWA projection of Gaussians into screen-space splats (the standard 3DGS formation), four at
//! a time: 3-D covariance from rotation and scale, the pinhole Jacobian with the 1.3×
//! frustum-edge clamp, a 0.3 px² low-pass, and the opacity-aware screen box of the 1/255 ellipse.

use crate::camera::Camera;
use crate::fastmath::{exp4, ln4};
use wide::f32x4;

/// The low-pass added to the 2-D covariance diagonal (px²).
pub const LOW_PASS: f32 = 0.3;
/// Blending stops contributing below this alpha.
pub const MIN_ALPHA: f32 = 1.0 / 255.0;
/// Alpha never exceeds this.
pub const MAX_ALPHA: f32 = 0.99;

/// A Gaussian projected to the screen, ready to be blended.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Splat {
    /// Centre in pixels (pixel i covers [i, i+1)).
    pub x: f32,
    /// Centre in pixels.
    pub y: f32,
    /// Inverse 2-D covariance (a, b, c): power = −½(a dx² + c dy²) − b dx dy.
    pub conic: [f32; 3],
    /// Opacity after the sigmoid.
    pub opacity: f32,
    /// View-dependent colour (≥ 0).
    pub color: [f32; 3],
    /// Camera-space z (metres along the optical axis).
    pub depth: f32,
    /// Instance id.
    pub instance: u32,
    /// Half-width and half-height (pixels) of the box around the ellipse outside which
    /// alpha < 1/255: sqrt(cutoff · Σ'ₓₓ) and sqrt(cutoff · Σ'ᵧᵧ).
    pub extent: [f32; 2],
    /// Mahalanobis distance² at which alpha falls to 1/255: 2 ln(255 · opacity).
    pub cutoff: f32,
}

/// Four Gaussians to project, one per lane.
#[derive(Debug, Clone, Copy)]
pub struct Gaussians4 {
    /// Centres in camera coordinates (x, y, z).
    pub t: [f32x4; 3],
    /// Rotations as (w, x, y, z), of any non-zero length.
    pub rotation: [f32x4; 4],
    /// Natural logarithms of the standard deviations along the local axes.
    pub log_scale: [f32x4; 3],
    /// Opacities after the sigmoid.
    pub opacity: f32x4,
}

/// Four projected Gaussians' screen-space footprints, one per lane (see [`Splat`]).
#[derive(Debug, Clone, Copy)]
pub struct Footprints4 {
    /// Centres in pixels.
    pub x: f32x4,
    /// Centres in pixels.
    pub y: f32x4,
    /// Inverse 2-D covariances (a, b, c).
    pub conic: [f32x4; 3],
    /// Half-width and half-height of the 1/255 ellipse's box (pixels).
    pub extent: [f32x4; 2],
    /// Mahalanobis cut-offs.
    pub cutoff: f32x4,
    /// Bit `k` set when lane `k` survived: centre within the clip range, opacity at least
    /// 1/255, a non-degenerate covariance, and a footprint that reaches the image.
    pub visible: u32,
}

/// EWA projection of four Gaussians at once: Σ = R S² Rᵀ, the pinhole Jacobian J at the
/// mean with the 1.3× frustum-edge clamp, Σ' = J W Σ Wᵀ Jᵀ + 0.3 I, its inverse (the conic)
/// and the box outside which alpha < 1/255.
pub fn project4(camera: &Camera, g: &Gaussians4) -> Footprints4 {
    let k = camera.intrinsics;
    let splat = f32x4::splat;
    let [tx, ty, tz] = g.t;
    let lim_x = splat(1.3 * (k.width as f32 * 0.5) / k.fx);
    let lim_y = splat(1.3 * (k.height as f32 * 0.5) / k.fy);
    let inv_z = f32x4::ONE / tz;
    let sx = (tx * inv_z).max(-lim_x).min(lim_x);
    let sy = (ty * inv_z).max(-lim_y).min(lim_y);
    // Rows of J·W: the Jacobian at the clamped mean times world→camera, whose rows are the
    // camera's right, down and forward axes.
    let (right, down, forward) = (
        camera.rotation.x_axis,
        camera.rotation.y_axis,
        camera.rotation.z_axis,
    );
    let (fx_z, fy_z) = (splat(k.fx) * inv_z, splat(k.fy) * inv_z);
    let r0 = [0, 1, 2].map(|i| (splat(right[i]) - splat(forward[i]) * sx) * fx_z);
    let r1 = [0, 1, 2].map(|i| (splat(down[i]) - splat(forward[i]) * sy) * fy_z);
    // With the rotation's columns R_j and variances s_j², Σ' = Σ_j s_j² (R_j·r0, R_j·r1)ᵀ(…).
    let axes = rotation_columns(g.rotation);
    let (mut a, mut b, mut c) = (splat(LOW_PASS), f32x4::ZERO, splat(LOW_PASS));
    for (axis, log_scale) in axes.iter().zip(g.log_scale) {
        let variance = exp4(log_scale + log_scale);
        let d0 = axis[0] * r0[0] + axis[1] * r0[1] + axis[2] * r0[2];
        let d1 = axis[0] * r1[0] + axis[1] * r1[1] + axis[2] * r1[2];
        a += variance * d0 * d0;
        b += variance * d0 * d1;
        c += variance * d1 * d1;
    }
    let det = a * c - b * b;
    let inv_det = f32x4::ONE / det;
    // A hair above 2 ln(255 o): the cutoff only bounds where pixels are visited (each one
    // still checks alpha ≥ 1/255 exactly), so rounding must err outwards.
    let cutoff = splat(2.0) * ln4(splat(255.0) * g.opacity.max(splat(MIN_ALPHA))) + splat(1e-3);
    let extent = [(cutoff * a).sqrt(), (cutoff * c).sqrt()];
    let x = splat(k.fx) * tx * inv_z + splat(k.cx);
    let y = splat(k.fy) * ty * inv_z + splat(k.cy);
    let (w_px, h_px) = (splat(k.width as f32), splat(k.height as f32));
    let visible = tz.simd_ge(splat(camera.near))
        & tz.simd_le(splat(camera.far))
        & g.opacity.simd_ge(splat(MIN_ALPHA))
        & det.simd_gt(f32x4::ZERO)
        & det.simd_lt(splat(f32::INFINITY))
        & (x + extent[0]).simd_ge(f32x4::ZERO)
        & (x - extent[0]).simd_le(w_px)
        & (y + extent[1]).simd_ge(f32x4::ZERO)
        & (y - extent[1]).simd_le(h_px);
    Footprints4 {
        x,
        y,
        conic: [c * inv_det, -b * inv_det, a * inv_det],
        extent,
        cutoff,
        visible: visible.to_bitmask(),
    }
}

/// The columns of the rotation matrices of four quaternions (w, x, y, z), normalised first.
fn rotation_columns([w, x, y, z]: [f32x4; 4]) -> [[f32x4; 3]; 3] {
    let inv_norm = f32x4::ONE / (w * w + x * x + y * y + z * z).sqrt();
    let (w, x, y, z) = (w * inv_norm, x * inv_norm, y * inv_norm, z * inv_norm);
    let (x2, y2, z2) = (x + x, y + y, z + z);
    let (xx, xy, xz) = (x * x2, x * y2, x * z2);
    let (yy, yz, zz) = (y * y2, y * z2, z * z2);
    let (wx, wy, wz) = (w * x2, w * y2, w * z2);
    let one = f32x4::ONE;
    [
        [one - (yy + zz), xy + wz, xz - wy],
        [xy - wz, one - (xx + zz), yz + wx],
        [xz + wy, yz - wx, one - (xx + yy)],
    ]
}

impl Splat {
    /// The exponent at pixel centre (px, py): −½(a dx² + c dy²) − b dx dy.
    #[inline]
    pub fn power(&self, px: f32, py: f32) -> f32 {
        let dx = self.x - px;
        let dy = self.y - py;
        -0.5 * (self.conic[0] * dx * dx + self.conic[2] * dy * dy) - self.conic[1] * dx * dy
    }

    /// True when some pixel centre in [x0, x1] × [y0, y1] gets alpha ≥ 1/255: the exact
    /// ellipse–rectangle test (the minimum of the quadratic form over the rectangle).
    pub fn reaches_rect(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> bool {
        let [a, b, c] = self.conic;
        let q = |dx: f32, dy: f32| a * dx * dx + 2.0 * b * dx * dy + c * dy * dy;
        if (x0..=x1).contains(&self.x) && (y0..=y1).contains(&self.y) {
            return true;
        }
        let (dx0, dx1, dy0, dy1) = (x0 - self.x, x1 - self.x, y0 - self.y, y1 - self.y);
        let along_y = |dx: f32| q(dx, (-b * dx / c).clamp(dy0, dy1));
        let along_x = |dy: f32| q((-b * dy / a).clamp(dx0, dx1), dy);
        let min = along_y(dx0)
            .min(along_y(dx1))
            .min(along_x(dy0))
            .min(along_x(dy1));
        min <= self.cutoff
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use proptest::prelude::*;

    /// Lane `k` of `g` copied into all four lanes.
    fn broadcast(g: &Gaussians4, k: usize) -> Gaussians4 {
        let one = |v: f32x4| f32x4::splat(v.to_array()[k]);
        Gaussians4 {
            t: g.t.map(one),
            rotation: g.rotation.map(one),
            log_scale: g.log_scale.map(one),
            opacity: one(g.opacity),
        }
    }

    #[test]
    fn lanes_are_projected_independently() {
        let cam = crate::Camera::from_yaw_pitch(
            Intrinsics::from_hfov(64, 48, 90.0).unwrap(),
            glam::Vec3::ZERO,
            0.0,
            0.0,
        );
        // A regular splat, one behind the camera, a degenerate rotation, one far off screen.
        let g = Gaussians4 {
            t: [
                f32x4::new([0.1, 0.0, 0.2, 40.0]),
                f32x4::new([-0.2, 0.0, 0.1, 0.0]),
                f32x4::new([2.0, -1.0, 3.0, 2.0]),
            ],
            rotation: [
                f32x4::new([1.0, 1.0, 0.0, 1.0]),
                f32x4::new([0.2, 0.0, 0.0, 0.0]),
                f32x4::new([-0.4, 0.0, 0.0, 0.0]),
                f32x4::new([0.1, 0.0, 0.0, 0.0]),
            ],
            log_scale: [f32x4::splat(-3.0), f32x4::splat(-2.5), f32x4::splat(-4.0)],
            opacity: f32x4::splat(0.8),
        };
        let all = project4(&cam, &g);
        assert_eq!(all.visible, 0b0001);
        let alone = project4(&cam, &broadcast(&g, 0));
        assert_eq!(alone.visible, 0b1111);
        for (x, y) in [
            (all.x, alone.x),
            (all.extent[0], alone.extent[0]),
            (all.conic[1], alone.conic[1]),
        ] {
            assert_eq!(x.to_array()[0], y.to_array()[0]);
        }
        // The centre lands where the pinhole model puts it.
        let expected_x = cam.intrinsics.fx * 0.1 / 2.0 + cam.intrinsics.cx;
        assert!((all.x.to_array()[0] - expected_x).abs() < 1e-4);
    }

    fn splat(a: f32, b: f32, c: f32) -> Splat {
        Splat {
            x: 10.3,
            y: 7.9,
            conic: [a, b, c],
            opacity: 0.9,
            cutoff: 2.0 * (255.0f32 * 0.9).ln(),
            ..Splat::default()
        }
    }

    proptest! {
        #[test]
        fn rect_test_agrees_with_a_dense_scan(
            s in 0.05f32..3.0, t in 0.05f32..3.0, rho in -0.9f32..0.9,
            x0 in 0.0f32..20.0, y0 in 0.0f32..20.0, w in 0.0f32..8.0, h in 0.0f32..8.0,
        ) {
            // Conic of a covariance with stds s, t and correlation rho.
            let (ca, cb, cc) = (s * s, rho * s * t, t * t);
            let det = ca * cc - cb * cb;
            let sp = splat(cc / det, -cb / det, ca / det);
            let (x1, y1) = (x0 + w, y0 + h);
            let n = 80;
            let mut hit = false;
            let mut min_q = f32::INFINITY;
            for i in 0..=n {
                for j in 0..=n {
                    let px = x0 + w * i as f32 / n as f32;
                    let py = y0 + h * j as f32 / n as f32;
                    let q = -2.0 * sp.power(px, py);
                    min_q = min_q.min(q);
                    hit |= q <= sp.cutoff;
                }
            }
            let exact = sp.reaches_rect(x0, y0, x1, y1);
            // The scan is a lower bound of coverage; near the boundary allow its resolution.
            if hit { prop_assert!(exact); }
            if exact && !hit { prop_assert!(min_q < sp.cutoff * 1.05 + 0.05, "min {min_q} cutoff {}", sp.cutoff); }
        }
    }
}
