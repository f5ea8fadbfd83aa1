//! EWA projection of one Gaussian into a screen-space splat (the standard 3DGS formation):
//! 3-D covariance from rotation and scale, the pinhole Jacobian with the 1.3× frustum-edge
//! clamp, a 0.3 px² low-pass, and an opacity-aware screen radius.

use crate::camera::Camera;
use glam::{Mat3, Quat, Vec3};

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
    /// Half-width of the screen square outside which alpha < 1/255 (pixels).
    pub radius: f32,
    /// Mahalanobis distance² at which alpha falls to 1/255: 2 ln(255 · opacity).
    pub cutoff: f32,
}

/// e^x for |x| ≤ 87 with relative error below 2e-5: 2^(x log₂e) split into an exponent and a
/// degree-6 polynomial of the fraction; far cheaper than the library call in the projection.
#[inline]
pub fn exp_fast(x: f32) -> f32 {
    let y = (x * std::f32::consts::LOG2_E).clamp(-126.0, 126.0);
    // floor without a library call: truncate, then step down for negative fractions.
    let t = y as i32;
    let n = if (t as f32) > y { t - 1 } else { t };
    let f = y - n as f32;
    let p = 1.0
        + f * (std::f32::consts::LN_2
            + f * (0.240_226_5
                + f * (0.055_504_11
                    + f * (0.009_618_129 + f * (0.001_333_355_8 + f * 0.000_154_035_3)))));
    f32::from_bits(((n + 127) as u32) << 23) * p
}

/// ln x for positive normal x, absolute error below 1e-4: the exponent plus a polynomial of the
/// mantissa around 1 (cheaper than the library call in the projection).
#[inline]
pub fn ln_fast(x: f32) -> f32 {
    let bits = x.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    // Mantissa in [√½, √2): ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.172.
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let mut e = exponent as f32;
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1.0;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    e * std::f32::consts::LN_2 + 2.0 * s * (1.0 + s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0))))
}

/// The logistic sigmoid 1 / (1 + e^−x), through [`exp_fast`].
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp_fast(-x))
}

/// The covariance factor M = R S (columns: the Gaussian's axes scaled by its standard
/// deviations), so that Σ = M Mᵀ.
pub fn scaled_axes(rotation: Quat, log_scale: Vec3) -> Mat3 {
    let r = Mat3::from_quat(rotation.normalize());
    Mat3::from_cols(
        r.x_axis * exp_fast(log_scale.x),
        r.y_axis * exp_fast(log_scale.y),
        r.z_axis * exp_fast(log_scale.z),
    )
}

/// Projects a Gaussian whose centre is `t` in camera coordinates and whose covariance factor is
/// `m` (see [`scaled_axes`]); `None` when it is culled (centre nearer than the near plane or
/// beyond the far plane, degenerate, too transparent, or wholly off screen). `color` is
/// evaluated by the caller from the view direction.
pub fn project(
    camera: &Camera,
    t: Vec3,
    m: Mat3,
    opacity: f32,
    color: [f32; 3],
    instance: u32,
) -> Option<Splat> {
    if opacity < MIN_ALPHA || !(t.z >= camera.near && t.z <= camera.far) {
        return None;
    }
    let k = camera.intrinsics;
    let lim_x = 1.3 * (k.width as f32 * 0.5) / k.fx;
    let lim_y = 1.3 * (k.height as f32 * 0.5) / k.fy;
    let inv_z = 1.0 / t.z;
    let (sx, sy) = (
        (t.x * inv_z).clamp(-lim_x, lim_x),
        (t.y * inv_z).clamp(-lim_y, lim_y),
    );
    // Rows of J·W: the pinhole Jacobian at the clamped mean times world→camera, whose rows are
    // the camera's right, down and forward axes.
    let [right, down, forward] = [
        camera.rotation.x_axis,
        camera.rotation.y_axis,
        camera.rotation.z_axis,
    ];
    let r0 = (right - forward * sx) * (k.fx * inv_z);
    let r1 = (down - forward * sy) * (k.fy * inv_z);
    // Σ' = (J W) M Mᵀ (J W)ᵀ: with u = Mᵀ r, its entries are dot products of u0 and u1.
    let u0 = Vec3::new(m.x_axis.dot(r0), m.y_axis.dot(r0), m.z_axis.dot(r0));
    let u1 = Vec3::new(m.x_axis.dot(r1), m.y_axis.dot(r1), m.z_axis.dot(r1));
    let a = u0.dot(u0) + LOW_PASS;
    let b = u0.dot(u1);
    let c = u1.dot(u1) + LOW_PASS;
    let det = a * c - b * b;
    if det <= 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    // A hair above 2 ln(255 o): the cutoff only bounds where pixels are visited (each one
    // still checks alpha ≥ 1/255 exactly), so rounding must err outwards.
    let cutoff = 2.0 * ln_fast(255.0 * opacity) + 1e-3;
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let radius = (cutoff * lambda).sqrt();
    let (x, y) = camera.project(t);
    let (w_px, h_px) = (k.width as f32, k.height as f32);
    if x + radius < 0.0 || x - radius > w_px || y + radius < 0.0 || y - radius > h_px {
        return None;
    }
    Some(Splat {
        x,
        y,
        conic: [c * inv_det, -b * inv_det, a * inv_det],
        opacity,
        color,
        depth: t.z,
        instance,
        radius,
        cutoff,
    })
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
    use proptest::prelude::*;

    #[test]
    fn ln_fast_is_accurate() {
        let mut x = 1e-3f32;
        while x < 1e3 {
            assert!(
                (ln_fast(x) - x.ln()).abs() < 1e-4,
                "ln({x}) = {} vs {}",
                ln_fast(x),
                x.ln()
            );
            x *= 1.001;
        }
    }

    #[test]
    fn exp_fast_is_accurate() {
        let mut x = -30.0f32;
        while x <= 30.0 {
            let (a, b) = (exp_fast(x), x.exp());
            assert!((a - b).abs() <= b * 2e-5, "exp({x}) = {a} vs {b}");
            x += 0.001;
        }
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
