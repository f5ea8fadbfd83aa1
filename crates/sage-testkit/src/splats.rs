//! For renderer tests: random Gaussians — a cloud in front of a camera at the origin looking
//! along +x, with every SH band large enough that a wrong sign or order in any of them costs
//! far more than a 40 dB bound allows — and the PSNR two images are compared by.

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_scene::{Gaussian, Gaussians};

/// `n` Gaussians of SH `degree` drawn from `seed`: centres 1–6 m ahead along +x, within
/// ±`spread` sideways and around 1.2 m high; instances 1–7 in turn.
pub fn random_gaussians(seed: u64, n: usize, degree: u8, spread: f32) -> Gaussians {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = Gaussians::new(degree).unwrap();
    for i in 0..n {
        let q = Quat::from_xyzw(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let mut x = Gaussian {
            position: Vec3::new(
                rng.random_range(1.0..6.0),
                rng.random_range(-spread..spread),
                rng.random_range(-spread..spread) + 1.2,
            ),
            rotation: if q.length() > 0.1 { q } else { Quat::IDENTITY },
            log_scale: Vec3::new(
                rng.random_range(-4.5..-1.5),
                rng.random_range(-4.5..-1.5),
                rng.random_range(-4.5..-1.5),
            ),
            opacity_logit: rng.random_range(-3.0..5.0),
            sh_dc: [
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
            ],
            instance: (i % 7) as u32 + 1,
            ..Gaussian::default()
        };
        // Higher bands large enough that a wrong sign or order in any of them costs far more
        // than the PSNR bound allows.
        for coeff in x.sh_rest.iter_mut() {
            *coeff = [
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
            ];
        }
        g.push(&x);
    }
    g
}

/// The PSNR (dB) of colour image `b` against `a` (values clamped to 0–1); infinite when equal.
pub fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| ((x.clamp(0.0, 1.0) - y.clamp(0.0, 1.0)) as f64).powi(2))
        .sum::<f64>()
        / a.len() as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }
}
