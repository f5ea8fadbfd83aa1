//! Fast elementary functions for the hot loops (scalar and four lanes): exponentials and
//! logarithms by exponent splitting and short polynomials, accurate to what 8-bit images
//! and the 1/255 alpha threshold need, and far cheaper than the library calls.

use wide::bytemuck::cast;
use wide::{f32x4, i32x4};

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

/// The coefficients of 2^f for f in [−½, ½] after the leading 1 (degree 5): [`exp4`]'s, and the
/// GPU renderer's (its prelude takes them from here).
pub const EXP2_POLY: [f32; 5] = [
    std::f32::consts::LN_2,
    0.240_226_5,
    0.055_504_11,
    0.009_618_129,
    0.001_333_355_8,
];

/// e^x, four lanes, for |x| up to about 87 (relative error below 5e-6): 2^(x log₂e) split
/// at the nearest integer, the fraction in [−½, ½] by a degree-5 polynomial.
#[inline]
pub fn exp4(x: f32x4) -> f32x4 {
    let y = (x * f32x4::splat(std::f32::consts::LOG2_E))
        .max(f32x4::splat(-126.0))
        .min(f32x4::splat(126.0));
    let n = y.round_int();
    let f = y - f32x4::from_i32x4(n);
    // Estrin's scheme: the same polynomial as Horner's, with half the dependent steps.
    let c = |v: f32| f32x4::splat(v);
    let f2 = f * f;
    let [c1, c2, c3, c4, c5] = EXP2_POLY;
    let low = f32x4::ONE + f * c(c1);
    let mid = c(c2) + f * c(c3);
    let high = c(c4) + f * c(c5);
    let p = low + f2 * (mid + f2 * high);
    let scale: f32x4 = cast((n + i32x4::splat(127)) << 23);
    scale * p
}

/// ln x in four lanes for positive normal x, absolute error below 1e-4 (the lane-wise
/// [`ln_fast`]).
#[inline]
pub fn ln4(x: f32x4) -> f32x4 {
    let bits: i32x4 = cast(x);
    let exponent = ((bits >> 23) & i32x4::splat(0xff)) - i32x4::splat(127);
    let m: f32x4 = cast((bits & i32x4::splat(0x007f_ffff)) | i32x4::splat(0x3f80_0000));
    let high = m.simd_gt(f32x4::splat(std::f32::consts::SQRT_2));
    let m = high.select(m * f32x4::splat(0.5), m);
    let e = f32x4::from_i32x4(exponent) + (high & f32x4::ONE);
    let s = (m - f32x4::ONE) / (m + f32x4::ONE);
    let s2 = s * s;
    let series = f32x4::ONE
        + s2 * (f32x4::splat(1.0 / 3.0) + s2 * (f32x4::splat(0.2) + s2 * f32x4::splat(1.0 / 7.0)));
    e * f32x4::splat(std::f32::consts::LN_2) + f32x4::splat(2.0) * s * series
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn exp4_is_accurate() {
        let mut x = -20.0f32;
        while x <= 20.0 {
            let got = exp4(f32x4::new([x, x - 1e-3, x - 2e-3, x - 3e-3])).to_array();
            for (k, g) in got.iter().enumerate() {
                let want = (x - k as f32 * 1e-3).exp();
                assert!((g - want).abs() <= want * 5e-6, "exp({x}) = {g} vs {want}");
            }
            x += 0.004;
        }
    }

    #[test]
    fn ln4_matches_the_scalar_version() {
        let mut x = 1e-3f32;
        while x < 1e3 {
            let got = ln4(f32x4::new([x, x * 1.3, x * 2.0, x * 3.7])).to_array();
            for (g, v) in got.iter().zip([x, x * 1.3, x * 2.0, x * 3.7]) {
                assert!((g - v.ln()).abs() < 1e-4, "ln({v}) = {g}");
                assert!((g - ln_fast(v)).abs() < 1e-5);
            }
            x *= 1.01;
        }
    }
}
