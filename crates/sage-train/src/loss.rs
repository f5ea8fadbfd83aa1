//! The photometric loss of 3DGS, (1 − λ)·L1 + λ·(1 − SSIM), with its gradient, and PSNR.
//!
//! SSIM is the usual one: per channel, an 11×11 Gaussian window (σ = 1.5) applied as a "same"
//! convolution with zero padding, C₁ = 0.01², C₂ = 0.03², averaged over pixels and channels.
//! Images are interleaved RGB, `height × width × 3`, in 0–1.

use rayon::prelude::*;

/// The default weight λ of the D-SSIM term (as in 3DGS).
pub const SSIM_WEIGHT: f32 = 0.2;

const WINDOW: usize = 11;
const C1: f32 = 0.01 * 0.01;
const C2: f32 = 0.03 * 0.03;

/// The normalised 1-D Gaussian window.
fn window() -> [f32; WINDOW] {
    let mut w: [f32; WINDOW] =
        std::array::from_fn(|k| (-((k as f32 - 5.0).powi(2)) / (2.0 * 1.5 * 1.5)).exp());
    let sum: f32 = w.iter().sum();
    w.iter_mut().for_each(|v| *v /= sum);
    w
}

/// The separable window applied to a `w × h` plane with zero padding (symmetric, so it is its
/// own adjoint).
fn blur(plane: &[f32], w: usize, h: usize, win: &[f32; WINDOW]) -> Vec<f32> {
    let r = WINDOW as isize / 2;
    let mut rows = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, g) in win.iter().enumerate() {
                let xx = x as isize + k as isize - r;
                if xx >= 0 && (xx as usize) < w {
                    s += g * plane[y * w + xx as usize];
                }
            }
            rows[y * w + x] = s;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, g) in win.iter().enumerate() {
                let yy = y as isize + k as isize - r;
                if yy >= 0 && (yy as usize) < h {
                    s += g * rows[yy as usize * w + x];
                }
            }
            out[y * w + x] = s;
        }
    }
    out
}

/// Mean SSIM of `pred` against `target` and, when `grad` is given, adds `scale` × ∂SSIM/∂pred
/// into it. Channels are computed in parallel and combined in order.
pub fn ssim(
    pred: &[f32],
    target: &[f32],
    w: usize,
    h: usize,
    grad: Option<(&mut [f32], f32)>,
) -> f32 {
    let win = window();
    let n = (w * h * 3) as f32;
    let want_grad = grad.is_some();
    let channels: Vec<(f64, Vec<f32>)> = (0..3)
        .into_par_iter()
        .map(|c| ssim_channel(pred, target, c, w, h, &win, want_grad))
        .collect();
    if let Some((out, scale)) = grad {
        for (c, (_, g)) in channels.iter().enumerate() {
            for (i, v) in g.iter().enumerate() {
                out[i * 3 + c] += scale / n * v;
            }
        }
    }
    (channels.iter().map(|(t, _)| t).sum::<f64>() / n as f64) as f32
}

/// Channel `c`'s SSIM summed over its pixels and, when `want_grad`, ∂(that sum)/∂pred per
/// pixel.
fn ssim_channel(
    pred: &[f32],
    target: &[f32],
    c: usize,
    w: usize,
    h: usize,
    win: &[f32; WINDOW],
    want_grad: bool,
) -> (f64, Vec<f32>) {
    let x: Vec<f32> = pred.iter().skip(c).step_by(3).copied().collect();
    let y: Vec<f32> = target.iter().skip(c).step_by(3).copied().collect();
    let prod = |a: &[f32], b: &[f32]| -> Vec<f32> { a.iter().zip(b).map(|(p, q)| p * q).collect() };
    let mu_x = blur(&x, w, h, win);
    let mu_y = blur(&y, w, h, win);
    let e_xx = blur(&prod(&x, &x), w, h, win);
    let e_yy = blur(&prod(&y, &y), w, h, win);
    let e_xy = blur(&prod(&x, &y), w, h, win);
    // Per pixel ∂S/∂(μx, E[x²], E[xy]).
    let mut g1 = vec![0.0f32; w * h];
    let mut g2 = vec![0.0f32; w * h];
    let mut g3 = vec![0.0f32; w * h];
    let mut total = 0.0f64;
    for i in 0..w * h {
        let (mx, my) = (mu_x[i], mu_y[i]);
        let sxx = e_xx[i] - mx * mx;
        let syy = e_yy[i] - my * my;
        let sxy = e_xy[i] - mx * my;
        let a1 = 2.0 * mx * my + C1;
        let a2 = 2.0 * sxy + C2;
        let b1 = mx * mx + my * my + C1;
        let b2 = sxx + syy + C2;
        let s = a1 * a2 / (b1 * b2);
        total += s as f64;
        let d_sxy = 2.0 * a1 / (b1 * b2);
        let d_sxx = -s / b2;
        let d_mx = 2.0 * my * a2 / (b1 * b2) - s * 2.0 * mx / b1;
        g1[i] = d_mx - 2.0 * mx * d_sxx - my * d_sxy;
        g2[i] = d_sxx;
        g3[i] = d_sxy;
    }
    if !want_grad {
        return (total, Vec::new());
    }
    let (b1, b2, b3) = (
        blur(&g1, w, h, win),
        blur(&g2, w, h, win),
        blur(&g3, w, h, win),
    );
    let grad = (0..w * h)
        .map(|i| b1[i] + 2.0 * x[i] * b2[i] + y[i] * b3[i])
        .collect();
    (total, grad)
}

/// (1 − λ)·L1 + λ·(1 − SSIM) of `pred` against `target` (`w × h` RGB) and its gradient with
/// respect to `pred`.
pub fn loss(pred: &[f32], target: &[f32], w: usize, h: usize, ssim_weight: f32) -> (f32, Vec<f32>) {
    let n = pred.len() as f32;
    let l1_weight = 1.0 - ssim_weight;
    let mut l1 = 0.0f64;
    let mut grad: Vec<f32> = pred
        .iter()
        .zip(target)
        .map(|(p, t)| {
            let d = p - t;
            l1 += d.abs() as f64;
            if d > 0.0 {
                l1_weight / n
            } else if d < 0.0 {
                -l1_weight / n
            } else {
                0.0
            }
        })
        .collect();
    let mut value = l1_weight * (l1 / n as f64) as f32;
    if ssim_weight > 0.0 {
        let s = ssim(pred, target, w, h, Some((&mut grad, -ssim_weight)));
        value += ssim_weight * (1.0 - s);
    }
    (value, grad)
}

/// Peak signal-to-noise ratio (dB) of `pred`, clamped to 0–1, against `target`.
pub fn psnr(pred: &[f32], target: &[f32]) -> f32 {
    let mse = pred
        .iter()
        .zip(target)
        .map(|(p, t)| (p.clamp(0.0, 1.0) - t) as f64)
        .map(|d| d * d)
        .sum::<f64>()
        / pred.len().max(1) as f64;
    if mse == 0.0 {
        f32::INFINITY
    } else {
        (10.0 * (1.0 / mse).log10()) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_image(seed: u64, w: usize, h: usize) -> Vec<f32> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..w * h * 3).map(|_| rng.random_range(0.0..1.0)).collect()
    }

    #[test]
    fn ssim_of_an_image_with_itself_is_one_and_psnr_is_infinite() {
        let a = random_image(1, 13, 9);
        assert!((ssim(&a, &a, 13, 9, None) - 1.0).abs() < 1e-5);
        assert_eq!(psnr(&a, &a), f32::INFINITY);
        let b = random_image(2, 13, 9);
        assert!(ssim(&a, &b, 13, 9, None) < 0.5);
        // Uniform error 0.1 → 20 dB.
        let c: Vec<f32> = a.iter().map(|v| v * 0.5 + 0.1).collect();
        let d: Vec<f32> = a.iter().map(|v| v * 0.5).collect();
        assert!((psnr(&c, &d) - 20.0).abs() < 1e-3);
    }

    #[test]
    fn loss_gradient_matches_finite_differences() {
        let (w, h) = (14, 12);
        let target = random_image(3, w, h);
        let pred = random_image(4, w, h);
        let (_, grad) = loss(&pred, &target, w, h, SSIM_WEIGHT);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..25 {
            let i = rng.random_range(0..pred.len());
            let eps = 1e-3;
            let eval = |d: f32| {
                let mut p = pred.clone();
                p[i] += d;
                loss(&p, &target, w, h, SSIM_WEIGHT).0 as f64
            };
            let fd = ((eval(eps) - eval(-eps)) / (2.0 * eps as f64)) as f32;
            assert!(
                (fd - grad[i]).abs() <= 2e-2 * grad[i].abs() + 2e-5,
                "pixel value {i}: analytic {} vs finite difference {fd}",
                grad[i]
            );
        }
    }
}
