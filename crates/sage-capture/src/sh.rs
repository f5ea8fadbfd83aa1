//! Rotating spherical harmonics: the coefficients of degrees 1–3 of a Gaussian turned with the
//! scene, so that it shows the same colour towards the same (turned) direction.
//!
//! A rotation maps each SH band onto itself, so band ℓ turns by a (2ℓ+1)² matrix M with
//! `Σ_k M c · Y_k(d) = Σ_k c · Y_k(Rᵀ d)` for every direction d. Rather than a closed-form
//! recurrence, whose sign conventions must match the renderer's basis term by term, M is
//! solved from that identity at 32 spread directions by least squares (in f64) with the
//! renderer's own basis ([`sage_splat::sh::basis`]); the identity is exact in the band, so the
//! solution is M to rounding, whatever convention the basis uses.

use glam::{DVec3, Mat3};
use sage_splat::sh::basis;

/// The first coefficient index (into `f_rest`, coefficient-major) and size of bands 1–3.
const BANDS: [(usize, usize); 3] = [(0, 3), (3, 5), (8, 7)];

/// Directions at which the rotation identity is solved.
const SAMPLES: usize = 32;

/// The SH rotation matrices of one rotation, bands 1–3.
#[derive(Debug, Clone, PartialEq)]
pub struct ShRotation {
    /// Row-major `n × n` matrices of bands 1, 2, 3.
    bands: [Vec<f64>; 3],
}

impl ShRotation {
    /// The matrices of rotation `r` (orthonormal, determinant 1).
    pub fn new(r: Mat3) -> ShRotation {
        let r = r.as_dmat3();
        let rt = r.transpose();
        let dirs: Vec<DVec3> = (0..SAMPLES)
            .map(|i| {
                // A Fibonacci sphere: spread, never degenerate for bands up to 3.
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / SAMPLES as f64;
                let rho = (1.0 - z * z).sqrt();
                let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                DVec3::new(rho * phi.cos(), rho * phi.sin(), z)
            })
            .collect();
        let eval = |d: DVec3| basis(d.as_vec3()).map(f64::from);
        let before: Vec<[f64; 15]> = dirs.iter().map(|&d| eval(rt * d)).collect();
        let after: Vec<[f64; 15]> = dirs.iter().map(|&d| eval(d)).collect();
        let bands = BANDS.map(|(o, n)| solve_band(&after, &before, o, n));
        ShRotation { bands }
    }

    /// Turns the higher-order coefficients `rest` (coefficient-major, 3, 8 or 15 used) in
    /// place; bands beyond `rest`'s length are absent and left alone.
    pub fn apply(&self, rest: &mut [[f32; 3]]) {
        for (b, &(o, n)) in BANDS.iter().enumerate() {
            if rest.len() < o + n {
                break;
            }
            let m = &self.bands[b];
            let old: Vec<[f64; 3]> = rest[o..o + n].iter().map(|c| c.map(f64::from)).collect();
            for (k, out) in rest[o..o + n].iter_mut().enumerate() {
                let mut acc = [0.0f64; 3];
                for (j, c) in old.iter().enumerate() {
                    let w = m[k * n + j];
                    for ch in 0..3 {
                        acc[ch] += w * c[ch];
                    }
                }
                *out = acc.map(|v| v as f32);
            }
        }
    }
}

/// Least squares for band `(o, n)`: the `n × n` M with `A M = B` over the samples, where
/// `A[i][k] = Y_{o+k}(d_i)` and `B[i][j] = Y_{o+j}(Rᵀ d_i)`; returned row-major.
fn solve_band(after: &[[f64; 15]], before: &[[f64; 15]], o: usize, n: usize) -> Vec<f64> {
    // Normal equations: (AᵀA) M = AᵀB, solved by Gauss–Jordan with partial pivoting.
    let mut ata = vec![0.0f64; n * n];
    let mut atb = vec![0.0f64; n * n];
    for (a, b) in after.iter().zip(before) {
        for r in 0..n {
            for c in 0..n {
                ata[r * n + c] += a[o + r] * a[o + c];
                atb[r * n + c] += a[o + r] * b[o + c];
            }
        }
    }
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&x, &y| ata[x * n + col].abs().total_cmp(&ata[y * n + col].abs()))
            .unwrap_or(col);
        for c in 0..n {
            ata.swap(col * n + c, pivot * n + c);
            atb.swap(col * n + c, pivot * n + c);
        }
        let p = ata[col * n + col];
        for c in 0..n {
            ata[col * n + c] /= p;
            atb[col * n + c] /= p;
        }
        for r in (0..n).filter(|&r| r != col) {
            let f = ata[r * n + col];
            if f != 0.0 {
                for c in 0..n {
                    ata[r * n + c] -= f * ata[col * n + c];
                    atb[r * n + c] -= f * atb[col * n + c];
                }
            }
        }
    }
    atb
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use proptest::prelude::*;
    use sage_splat::sh::color;

    fn unit(v: [f32; 3]) -> Option<Vec3> {
        let v = Vec3::from_array(v);
        (v.length() > 0.1).then(|| v.normalize())
    }

    proptest! {
        /// The rendering-free check: the colour of the original coefficients towards d equals the
        /// colour of the turned coefficients towards R d, for every degree.
        #[test]
        fn turned_coefficients_show_the_same_colour_in_the_turned_direction(
            axis in prop::array::uniform3(-1.0f32..1.0),
            angle in -3.2f32..3.2,
            dir in prop::array::uniform3(-1.0f32..1.0),
            coeffs in prop::collection::vec(-1.0f32..1.0, 45),
            degree in 1usize..=3,
        ) {
            let (Some(axis), Some(d)) = (unit(axis), unit(dir)) else { return Ok(()); };
            let r = Mat3::from_quat(Quat::from_axis_angle(axis, angle));
            let k = [0, 3, 8, 15][degree];
            let rest: Vec<[f32; 3]> = (0..k).map(|i| [coeffs[i * 3], coeffs[i * 3 + 1], coeffs[i * 3 + 2]]).collect();
            let mut turned = rest.clone();
            ShRotation::new(r).apply(&mut turned);
            // A large DC term keeps the colour above the clamp at 0, so the check sees every term.
            let dc = [8.0, 8.0, 8.0];
            let a = color(dc, &rest, d);
            let b = color(dc, &turned, r * d);
            for c in 0..3 {
                prop_assert!((a[c] - b[c]).abs() < 1e-4, "degree {degree}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn the_identity_leaves_coefficients_alone_and_a_turn_keeps_their_energy() {
        let rest: Vec<[f32; 3]> = (0..15).map(|i| [i as f32 * 0.1 - 0.7, 0.3, -0.2]).collect();
        let mut same = rest.clone();
        ShRotation::new(Mat3::IDENTITY).apply(&mut same);
        for (a, b) in rest.iter().zip(&same) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-6);
            }
        }
        // The basis is orthonormal, so each band's matrix is orthogonal: energy per band stays.
        let mut turned = rest.clone();
        ShRotation::new(Mat3::from_quat(
            Quat::from_rotation_x(0.7) * Quat::from_rotation_z(1.1),
        ))
        .apply(&mut turned);
        for &(o, n) in &BANDS {
            let e = |v: &[[f32; 3]]| v[o..o + n].iter().map(|c| c[0] * c[0]).sum::<f32>();
            assert!((e(&rest) - e(&turned)).abs() < 1e-4);
        }
    }
}
