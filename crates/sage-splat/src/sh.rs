//! Spherical-harmonics colour, degrees 0–3, in the basis and sign convention of the reference
//! 3DGS implementation (the coefficient order of the Inria `f_rest_*`).

use glam::Vec3;

/// `Y_0^0`.
pub const C0: f32 = 0.282_094_8;
/// The degree-1 constant.
pub const C1: f32 = 0.488_602_52;
/// The degree-2 constants, in basis order.
pub const C2: [f32; 5] = [
    1.092_548_4,
    -1.092_548_4,
    0.315_391_57,
    -1.092_548_4,
    0.546_274_2,
];
/// The degree-3 constants, in basis order.
pub const C3: [f32; 7] = [
    -0.590_043_6,
    2.890_611_4,
    -0.457_045_8,
    0.373_176_33,
    -0.457_045_8,
    1.445_305_7,
    -0.590_043_6,
];

/// The basis values for coefficients 1–15 at unit direction `d`.
pub fn basis(d: Vec3) -> [f32; 15] {
    let (x, y, z) = (d.x, d.y, d.z);
    let (xx, yy, zz, xy, yz, xz) = (x * x, y * y, z * z, x * y, y * z, x * z);
    [
        -C1 * y,
        C1 * z,
        -C1 * x,
        C2[0] * xy,
        C2[1] * yz,
        C2[2] * (2.0 * zz - xx - yy),
        C2[3] * xz,
        C2[4] * (xx - yy),
        C3[0] * y * (3.0 * xx - yy),
        C3[1] * xy * z,
        C3[2] * y * (4.0 * zz - xx - yy),
        C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
        C3[4] * x * (4.0 * zz - xx - yy),
        C3[5] * z * (xx - yy),
        C3[6] * x * (xx - 3.0 * yy),
    ]
}

/// The colour seen from direction `d` (unit, camera centre → Gaussian): `max(0, Σ c·Y + 0.5)`.
/// `rest` holds the higher-order coefficients (0, 3, 8 or 15 of them), coefficient-major.
pub fn color(dc: [f32; 3], rest: &[[f32; 3]], d: Vec3) -> [f32; 3] {
    let mut c = Vec3::from_array(dc) * C0;
    let add = |c: &mut Vec3, coeffs: &[[f32; 3]], basis: &[f32]| {
        for (coeff, y) in coeffs.iter().zip(basis) {
            *c += Vec3::from_array(*coeff) * *y;
        }
    };
    match rest.len() {
        0 => {}
        3 => add(&mut c, rest, &[-C1 * d.y, C1 * d.z, -C1 * d.x]),
        _ => add(&mut c, rest, &basis(d)),
    }
    (c + Vec3::splat(0.5)).max(Vec3::ZERO).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degree_one_is_linear_in_the_direction() {
        // With only the third coefficient (−C1·x), the colour changes sign with x.
        let mut rest = [[0.0f32; 3]; 3];
        rest[2] = [1.0, 0.0, 0.0];
        let a = color([0.0; 3], &rest, Vec3::X);
        let b = color([0.0; 3], &rest, -Vec3::X);
        assert!((a[0] - (0.5 - C1)).abs() < 1e-6);
        assert!((b[0] - (0.5 + C1)).abs() < 1e-6);
    }

    #[test]
    fn bands_are_orthonormal_on_the_sphere() {
        // Monte-Carlo-free check: a Fibonacci sphere integrates Y_i Y_j to δ_ij / (4π) · 4π.
        let n = 20_000;
        let mut gram = [[0.0f64; 15]; 15];
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let b = basis(Vec3::new(
                (r * phi.cos()) as f32,
                (r * phi.sin()) as f32,
                z as f32,
            ));
            for (row, bp) in gram.iter_mut().zip(b) {
                for (cell, bq) in row.iter_mut().zip(b) {
                    *cell += (bp * bq) as f64 * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (p, row) in gram.iter().enumerate() {
            for (q, value) in row.iter().enumerate() {
                let want = if p == q { 1.0 } else { 0.0 };
                assert!((value - want).abs() < 2e-3, "({p},{q}) = {value}");
            }
        }
    }
}
