//! Fits a degraded copy of one synthetic room to views of the original and prints held-out
//! PSNR before and after and the time per iteration.
//!
//! `cargo run --release -p sage-train --example fit_room -- [iterations] [width] [gaussians]`
//! (defaults 300, 128 px wide at 4:3, 20 000 Gaussians in the room).
//!
//! The views are rendered by `sage-splat` from cameras inside the room; the initialisation is
//! every fourth Gaussian of the room with its colour perturbed and its scales grown by 1.6.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_scene::synth::{SynthConfig, generate};
use sage_scene::{Gaussian, Gaussians};
use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
use sage_train::{FitParams, View, fit};
use std::time::Instant;

fn main() -> sage_core::Result<()> {
    let arg = |k: usize, default: usize| {
        std::env::args()
            .nth(k)
            .and_then(|a| a.parse().ok())
            .unwrap_or(default)
    };
    let (iterations, width, gaussians) = (arg(1, 300), arg(2, 128) as u32, arg(3, 20_000));
    let scene = generate(&SynthConfig {
        seed: 5,
        rooms: 1,
        objects: 10,
        gaussians,
        ..SynthConfig::default()
    })?;
    let truth = &scene.gaussians;
    let centre = scene.floorplan.rooms[0].profile.centroid();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut renderer = Renderer::new(truth);
    let mut view = |rng: &mut ChaCha8Rng| -> sage_core::Result<View> {
        let position = Vec3::new(
            centre.x + rng.random_range(-0.6..0.6),
            centre.y + rng.random_range(-0.6..0.6),
            rng.random_range(1.1..1.6),
        );
        let camera = Camera::from_yaw_pitch(
            Intrinsics::from_hfov(width, width * 3 / 4, 90.0)?,
            position,
            rng.random_range(-std::f32::consts::PI..std::f32::consts::PI),
            rng.random_range(-0.4..0.1),
        );
        let rgb = renderer
            .render(truth, &[], &camera, &RenderOptions::default())?
            .rgb;
        Ok(View { camera, rgb })
    };
    let train = (0..24)
        .map(|_| view(&mut rng))
        .collect::<sage_core::Result<Vec<_>>>()?;
    let heldout = (0..6)
        .map(|_| view(&mut rng))
        .collect::<sage_core::Result<Vec<_>>>()?;
    let mut init = Gaussians::new(0)?;
    for i in (0..truth.len()).step_by(4) {
        let g = truth.get(i);
        init.push(&Gaussian {
            log_scale: g.log_scale + Vec3::splat(1.6f32.ln()),
            sh_dc: g.sh_dc.map(|c| c + rng.random_range(-0.6..0.6)),
            ..g
        });
    }
    let params = FitParams {
        iterations,
        seed: 1,
        ..FitParams::default()
    };
    println!(
        "{} Gaussians in the room, {} in the initialisation; {} training and {} held-out views at {}x{}",
        truth.len(),
        init.len(),
        train.len(),
        heldout.len(),
        width,
        width * 3 / 4
    );
    let start = Instant::now();
    let every = (iterations / 10).max(1);
    let (fitted, report) = fit(&init, &train, &heldout, &params, &|it, loss| {
        if it % every == 0 {
            println!("iteration {it}: loss {loss:.4}");
        }
    })?;
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "held-out PSNR {:.2} -> {:.2} dB, training PSNR {:.2} dB, {} Gaussians, {:.1} ms per iteration ({} threads, evaluation included)",
        report.initial_heldout_psnr,
        report.final_heldout_psnr,
        report.final_train_psnr,
        fitted.len(),
        seconds * 1e3 / iterations.max(1) as f64,
        rayon::current_num_threads()
    );
    Ok(())
}
