//! The backward pass: analytic gradients of a loss on a [`Frame`]'s colour with respect to
//! every Gaussian's parameters.
//!
//! Two stages, as in the reference 3DGS implementation:
//!
//! 1. **compositing** (per tile, in parallel): each pixel walks its list back to front from the
//!    last splat it blended, recovering Tᵢ = Tᵢ₊₁ / (1 − αᵢ) and the colour behind, and adds
//!    ∂L/∂(centre, conic, opacity, colour) of each splat into that tile's partial sums. The
//!    partials are then summed per splat tile by tile in a fixed order, so the result does not
//!    depend on the thread count.
//! 2. **projection** (per splat, in parallel): through the conic to the 2-D covariance, through
//!    M = J·W and Σ' = Σⱼ sⱼ² (Rⱼ·m₀, Rⱼ·m₁)(…)ᵀ to the quaternion and log-scales, through the
//!    pinhole Jacobian (no gradient through a clamped slope) and the projected centre to the
//!    mean, and through the SH colour (nothing where it was clamped at 0) to the coefficients
//!    and, at degree 1, the viewing direction.

use crate::forward::{C1, Frame, Projected, ViewGeometry, normalized, rotation_columns, sh1_basis};
use crate::params::{Param, Params};
use glam::Vec3;
use rayon::prelude::*;
use sage_splat::Camera;
use sage_splat::project::MAX_ALPHA;
use sage_splat::sh::C0;

/// Per splat, ∂L with respect to its screen-space quantities.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct ScreenGrad {
    mean: [f32; 2],
    conic: [f32; 3],
    opacity: f32,
    color: [f32; 3],
}

impl ScreenGrad {
    fn add(&mut self, o: &ScreenGrad) {
        for k in 0..2 {
            self.mean[k] += o.mean[k];
        }
        for k in 0..3 {
            self.conic[k] += o.conic[k];
            self.color[k] += o.color[k];
        }
        self.opacity += o.opacity;
    }
}

/// The gradients of one view.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradients {
    /// ∂L/∂parameters, one row per Gaussian (zero for those not in the view).
    pub params: Vec<Param>,
    /// ∂L/∂(projected centre) in pixels, per Gaussian: what densification thresholds.
    pub mean2d: Vec<[f32; 2]>,
}

/// Back-propagates `d_rgb` (∂L/∂`frame.rgb`) through the frame to the parameters.
pub fn backward(params: &Params, camera: &Camera, frame: &Frame, d_rgb: &[f32]) -> Gradients {
    let grid = frame.grid;
    let n_tiles = grid.tiles_x * grid.tiles_y;
    let partials: Vec<Vec<ScreenGrad>> = (0..n_tiles)
        .into_par_iter()
        .map(|t| tile_backward(frame, t, d_rgb))
        .collect();
    let mut screen = vec![ScreenGrad::default(); frame.splats.len()];
    for (t, tile) in partials.iter().enumerate() {
        let list = &frame.lists[frame.tile_start[t] as usize..frame.tile_start[t + 1] as usize];
        for (&s, g) in list.iter().zip(tile) {
            screen[s as usize].add(g);
        }
    }
    let view = ViewGeometry::new(camera);
    let per_splat: Vec<Param> = frame
        .splats
        .par_iter()
        .zip(&screen)
        .map(|(sp, g)| {
            project_backward(
                &params.rows[sp.index as usize],
                params.sh_degree,
                sp,
                g,
                &view,
            )
        })
        .collect();
    let mut out = Gradients {
        params: vec![Param::default(); params.len()],
        mean2d: vec![[0.0; 2]; params.len()],
    };
    for ((sp, g), s) in frame.splats.iter().zip(per_splat).zip(&screen) {
        out.params[sp.index as usize] = g;
        out.mean2d[sp.index as usize] = s.mean;
    }
    out
}

/// The partial screen-space gradients of tile `t`'s list entries, summed over its pixels in
/// raster order.
fn tile_backward(frame: &Frame, t: usize, d_rgb: &[f32]) -> Vec<ScreenGrad> {
    let start = frame.tile_start[t] as usize;
    let list = &frame.lists[start..frame.tile_start[t + 1] as usize];
    let mut out = vec![ScreenGrad::default(); list.len()];
    let bg = Vec3::from_array(frame.background);
    for (x, y) in frame.grid.tile_pixels(t) {
        let p = y * frame.grid.width + x;
        let g = Vec3::new(d_rgb[p * 3], d_rgb[p * 3 + 1], d_rgb[p * 3 + 2]);
        if g == Vec3::ZERO {
            continue;
        }
        let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
        let final_t = frame.final_t[p];
        let bg_term = bg.dot(g) * final_t;
        let mut t_after = final_t;
        // Colour of what lies behind the current splat, per unit of its transmittance.
        let mut behind = Vec3::ZERO;
        for k in (0..frame.last[p] as usize).rev() {
            let sp = &frame.splats[list[k] as usize];
            let Some(alpha) = sp.alpha_at(px, py) else {
                continue;
            };
            let t_before = t_after / (1.0 - alpha);
            let color = Vec3::from_array(sp.color);
            let acc = &mut out[k];
            for c in 0..3 {
                acc.color[c] += alpha * t_before * g[c];
            }
            let d_alpha = t_before * (color - behind).dot(g) - bg_term / (1.0 - alpha);
            behind = alpha * color + (1.0 - alpha) * behind;
            t_after = t_before;
            let gauss = (sp.power(px, py)).exp();
            if sp.opacity * gauss > MAX_ALPHA {
                continue;
            }
            acc.opacity += gauss * d_alpha;
            let d_power = alpha * d_alpha;
            let (dx, dy) = (sp.mean[0] - px, sp.mean[1] - py);
            let [a, b, c] = sp.conic;
            acc.mean[0] -= d_power * (a * dx + b * dy);
            acc.mean[1] -= d_power * (c * dy + b * dx);
            acc.conic[0] -= 0.5 * d_power * dx * dx;
            acc.conic[1] -= d_power * dx * dy;
            acc.conic[2] -= 0.5 * d_power * dy * dy;
        }
    }
    out
}

/// ∂L/∂parameters of one splat from its screen-space gradient.
fn project_backward(
    p: &Param,
    sh_degree: u8,
    sp: &Projected,
    g: &ScreenGrad,
    v: &ViewGeometry,
) -> Param {
    let mut out = Param::default();
    let mean = Vec3::from_array(p.mean);
    let t = sp.t;
    // Colour, through the clamp at 0, to the SH coefficients and the viewing direction.
    let d_color = Vec3::from_array(std::array::from_fn(|c| {
        if sp.color_clamped[c] { 0.0 } else { g.color[c] }
    }));
    out.sh_dc = (d_color * C0).to_array();
    let mut d_mean = Vec3::ZERO;
    if sh_degree >= 1 {
        let to_mean = mean - v.position;
        let dist = to_mean.length();
        if dist > 0.0 {
            let dir = to_mean / dist;
            let basis = sh1_basis(dir);
            for (k, y) in basis.iter().enumerate() {
                out.sh_rest[k] = (d_color * *y).to_array();
            }
            // ∂colour/∂dir · d_color, with Y = (−C1 y, C1 z, −C1 x).
            let coeff = |k: usize| Vec3::from_array(p.sh_rest[k]).dot(d_color);
            let d_dir = Vec3::new(-C1 * coeff(2), -C1 * coeff(0), C1 * coeff(1));
            d_mean += (d_dir - dir * dir.dot(d_dir)) / dist;
        }
    }
    // Opacity through the sigmoid.
    out.opacity_logit = g.opacity * sp.opacity * (1.0 - sp.opacity);
    // Conic (A, B, C) = (c, −b, a) / D of the covariance (a, b, c), D = ac − b².
    let [a, b, c] = sp.cov;
    let [ga, gb, gc] = g.conic;
    let det = a * c - b * b;
    let inv2 = 1.0 / (det * det);
    let d_a = inv2 * (-c * c * ga + b * c * gb - b * b * gc);
    let d_b = inv2 * (2.0 * b * c * ga - (det + 2.0 * b * b) * gb + 2.0 * a * b * gc);
    let d_c = inv2 * (-b * b * ga + a * b * gb - a * a * gc);
    // Covariance through uⱼ = Rⱼ·m₀, vⱼ = Rⱼ·m₁ and σⱼ = sⱼ².
    let (u_slopes, clamped) = v.clamped_slopes(t);
    let [m0, m1] = v.jw_rows(t, u_slopes);
    let (q, q_norm) = normalized(p.rotation);
    let axes = rotation_columns(q);
    let (mut d_m0, mut d_m1) = (Vec3::ZERO, Vec3::ZERO);
    let mut d_axes = [Vec3::ZERO; 3];
    for j in 0..3 {
        let variance = (2.0 * p.log_scale[j]).exp();
        let (u, w) = (axes[j].dot(m0), axes[j].dot(m1));
        let d_var = d_a * u * u + d_b * u * w + d_c * w * w;
        out.log_scale[j] = d_var * 2.0 * variance;
        let d_u = variance * (2.0 * d_a * u + d_b * w);
        let d_w = variance * (2.0 * d_c * w + d_b * u);
        d_axes[j] = d_u * m0 + d_w * m1;
        d_m0 += d_u * axes[j];
        d_m1 += d_w * axes[j];
    }
    out.rotation = quaternion_backward(q, q_norm, &d_axes);
    // M's rows: m₀ = (fx/z)(right − u₀ forward), m₁ = (fy/z)(down − u₁ forward).
    let (right, down, forward) = (v.w2c.row(0), v.w2c.row(1), v.w2c.row(2));
    let mut d_t = Vec3::ZERO;
    for (k, (d_m, focal, axis)) in [(d_m0, v.fx, right), (d_m1, v.fy, down)]
        .into_iter()
        .enumerate()
    {
        let e = axis - forward * u_slopes[k];
        d_t.z -= d_m.dot(e) * focal / (t.z * t.z);
        if !clamped[k] {
            let d_slope = -(focal / t.z) * d_m.dot(forward);
            d_t[k] += d_slope / t.z;
            d_t.z -= d_slope * t[k] / (t.z * t.z);
        }
    }
    // The projected centre (fx x/z + cx, fy y/z + cy).
    d_t.x += g.mean[0] * v.fx / t.z;
    d_t.y += g.mean[1] * v.fy / t.z;
    d_t.z -= (g.mean[0] * v.fx * t.x + g.mean[1] * v.fy * t.y) / (t.z * t.z);
    d_mean += v.w2c.transpose() * d_t;
    out.mean = d_mean.to_array();
    out
}

/// ∂L/∂(unnormalised quaternion) from ∂L/∂(rotation columns), for the unit quaternion `q`
/// (w, x, y, z) obtained by dividing by `norm`.
fn quaternion_backward(q: [f32; 4], norm: f32, d_axes: &[Vec3; 3]) -> [f32; 4] {
    let [w, x, y, z] = q;
    // g(i, j): ∂L/∂R[i][j], row i, column j.
    let g = |i: usize, j: usize| d_axes[j][i];
    let dw =
        2.0 * (-z * g(0, 1) + y * g(0, 2) + z * g(1, 0) - x * g(1, 2) - y * g(2, 0) + x * g(2, 1));
    let dx = 2.0
        * (y * g(0, 1) + z * g(0, 2) + y * g(1, 0) - 2.0 * x * g(1, 1) - w * g(1, 2)
            + z * g(2, 0)
            + w * g(2, 1)
            - 2.0 * x * g(2, 2));
    let dy = 2.0
        * (-2.0 * y * g(0, 0) + x * g(0, 1) + w * g(0, 2) + x * g(1, 0) + z * g(1, 2)
            - w * g(2, 0)
            + z * g(2, 1)
            - 2.0 * y * g(2, 2));
    let dz = 2.0
        * (-2.0 * z * g(0, 0) - w * g(0, 1) + x * g(0, 2) + w * g(1, 0) - 2.0 * z * g(1, 1)
            + y * g(1, 2)
            + x * g(2, 0)
            + y * g(2, 1));
    let d_unit = [dw, dx, dy, dz];
    let along: f32 = q.iter().zip(&d_unit).map(|(a, b)| a * b).sum();
    std::array::from_fn(|k| (d_unit[k] - q[k] * along) / norm)
}
