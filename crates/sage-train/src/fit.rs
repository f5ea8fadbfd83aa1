//! The fitting loop: one training view per iteration in a seeded shuffled order, forward,
//! loss, backward, Adam, density control on its schedule, and held-out PSNR before, during
//! (every `eval_every` iterations) and after.

use crate::adam::{Adam, LearningRates};
use crate::backward::backward;
use crate::density::{DensityParams, DensityStats, densify_and_prune, reset_opacity};
use crate::forward::forward;
use crate::loss::{SSIM_WEIGHT, loss, psnr};
use crate::params::Params;
use glam::Vec3;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Result, ResultExt};
use sage_scene::Gaussians;
use sage_splat::Camera;

/// A posed image to fit against.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The camera that took it.
    pub camera: Camera,
    /// 8-bit RGB, `height × width × 3`, row-major.
    pub rgb: Vec<u8>,
}

/// Settings of a fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitParams {
    /// Optimisation steps (one training view each).
    pub iterations: usize,
    /// Seed of every random choice (view order, split positions).
    pub seed: u64,
    /// SH degree trained: 0 (colour only) or 1 (plus linear view dependence).
    pub sh_degree: u8,
    /// Learning rates.
    pub lr: LearningRates,
    /// Weight λ of the D-SSIM term.
    pub ssim_weight: f32,
    /// Colour behind all Gaussians (linear 0–1), in training and evaluation alike.
    pub background: [f32; 3],
    /// Densification and pruning.
    pub density: DensityParams,
    /// Held-out PSNR every this many iterations (0: only before and after).
    pub eval_every: usize,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            iterations: 2000,
            seed: 0,
            sh_degree: 0,
            lr: LearningRates::default(),
            ssim_weight: SSIM_WEIGHT,
            background: [0.0; 3],
            density: DensityParams::default(),
            eval_every: 0,
        }
    }
}

/// What a fit achieved.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FitReport {
    /// Mean PSNR (dB) over the held-out views of the initial Gaussians.
    pub initial_heldout_psnr: f32,
    /// Mean PSNR (dB) over the held-out views of the fitted Gaussians.
    pub final_heldout_psnr: f32,
    /// Mean PSNR (dB) over the training views of the fitted Gaussians.
    pub final_train_psnr: f32,
    /// The loss of every iteration.
    pub loss: Vec<f32>,
    /// Gaussians after fitting.
    pub gaussians: usize,
    /// (iteration, mean held-out PSNR) every `eval_every` iterations.
    pub heldout_curve: Vec<(usize, f32)>,
}

fn check_views(views: &[View], what: &str) -> Result<Vec<Vec<f32>>> {
    views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.camera
                .validate()
                .map_err(|e| e.within(format!("{what}[{i}].camera")))?;
            let (w, h) = (
                v.camera.intrinsics.width as usize,
                v.camera.intrinsics.height as usize,
            );
            if v.rgb.len() != w * h * 3 {
                return Err(Error::format(
                    format!("{what}[{i}].rgb"),
                    format!(
                        "{} bytes for a {w}x{h} camera (want {})",
                        v.rgb.len(),
                        w * h * 3
                    ),
                ));
            }
            Ok(v.rgb.iter().map(|&c| f32::from(c) / 255.0).collect())
        })
        .collect()
}

fn check_params(p: &FitParams) -> Result<()> {
    if !p.lr.valid() {
        return Err(Error::invalid(
            "learning rates must be finite and not negative (position rates positive)",
        ));
    }
    if !(0.0..=1.0).contains(&p.ssim_weight) {
        return Err(Error::invalid(format!(
            "ssim_weight must be in 0-1, got {}",
            p.ssim_weight
        )));
    }
    if !p.background.iter().all(|c| c.is_finite()) {
        return Err(Error::invalid("background must be finite"));
    }
    if p.sh_degree > 1 {
        return Err(Error::invalid(format!(
            "fitting trains SH degree 0 or 1, got {}",
            p.sh_degree
        )));
    }
    Ok(())
}

/// The scene extent that scales position learning rates and size thresholds: 1.1 × the
/// largest distance of a camera from the cameras' centroid (3DGS), or half the diagonal of
/// the Gaussians' bounds when the cameras (nearly) coincide.
pub fn scene_extent(views: &[View], init: &Gaussians) -> f32 {
    let centres: Vec<Vec3> = views.iter().map(|v| v.camera.position).collect();
    let centroid = centres.iter().copied().sum::<Vec3>() / centres.len().max(1) as f32;
    let radius = centres
        .iter()
        .map(|c| c.distance(centroid))
        .fold(0.0f32, f32::max)
        * 1.1;
    if radius > 1e-3 {
        return radius;
    }
    let bounds = init.bounds();
    let half_diagonal = if bounds.is_empty() {
        0.0
    } else {
        bounds.size().length() * 0.5
    };
    if half_diagonal > 1e-3 {
        half_diagonal
    } else {
        1.0
    }
}

/// Mean PSNR of `params` over `views` (targets already in 0–1).
fn evaluate(params: &Params, views: &[View], targets: &[Vec<f32>], background: [f32; 3]) -> f32 {
    let total: f64 = views
        .iter()
        .zip(targets)
        .map(|(v, t)| psnr(&forward(params, &v.camera, background).rgb, t) as f64)
        .sum();
    (total / views.len().max(1) as f64) as f32
}

/// Optimises `init` against the `train` views and reports PSNR on `heldout`; `progress` is
/// called after every iteration with its number (from 1) and loss. The result is in Morton
/// order, SH degree `params.sh_degree`, and the same for a seed whatever the thread count.
pub fn fit(
    init: &Gaussians,
    train: &[View],
    heldout: &[View],
    params: &FitParams,
    progress: &(dyn Fn(usize, f32) + Sync),
) -> Result<(Gaussians, FitReport)> {
    check_params(params)?;
    if train.is_empty() {
        return Err(Error::invalid("no training views"));
    }
    if heldout.is_empty() {
        return Err(Error::invalid(
            "no held-out views (the fit is judged by PSNR on them)",
        ));
    }
    let train_targets = check_views(train, "train")?;
    let heldout_targets = check_views(heldout, "heldout")?;
    let mut gaussians =
        Params::from_gaussians(init, params.sh_degree).within("initial Gaussians")?;
    if gaussians.is_empty() {
        return Err(Error::invalid("no initial Gaussians to fit"));
    }
    let extent = scene_extent(train, init);
    let bg = params.background;
    let density = &params.density;
    let mut report = FitReport {
        initial_heldout_psnr: evaluate(&gaussians, heldout, &heldout_targets, bg),
        ..FitReport::default()
    };
    let mut adam = Adam::new(gaussians.len());
    let mut stats = DensityStats::new(gaussians.len());
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut order: Vec<usize> = Vec::new();
    let last = params.iterations.saturating_sub(1).max(1) as f32;
    // As in 3DGS (15 000 of 30 000), the second half of a fit only refines.
    let densify_until = density.until.min(params.iterations / 2);
    for it in 0..params.iterations {
        if order.is_empty() {
            order = (0..train.len()).collect();
            order.shuffle(&mut rng);
        }
        let v = order.pop().unwrap_or(0);
        let camera = &train[v].camera;
        let frame = forward(&gaussians, camera, bg);
        let (w, h) = (frame.grid.width, frame.grid.height);
        let (value, d_rgb) = loss(&frame.rgb, &train_targets[v], w, h, params.ssim_weight);
        if !value.is_finite() {
            return Err(Error::invalid(format!(
                "the fit diverged at iteration {} (loss is not finite); lower the learning rates",
                it + 1
            )));
        }
        let grads = backward(&gaussians, camera, &frame, &d_rgb);
        let step = it + 1;
        if step < densify_until {
            for sp in &frame.splats {
                let i = sp.index as usize;
                stats.record(i, sp.radius, grads.mean2d[i], w as f32, h as f32);
            }
        }
        let lr = params.lr.per_offset(it as f32 / last, extent);
        adam.step(&mut gaussians.rows, &grads.params, &lr);
        if step < densify_until {
            if step >= density.from && density.interval > 0 && step % density.interval == 0 {
                let prune_large =
                    density.opacity_reset_interval > 0 && step > density.opacity_reset_interval;
                let origin = densify_and_prune(
                    &mut gaussians,
                    &stats,
                    density,
                    extent,
                    prune_large,
                    &mut rng,
                );
                adam.remap(&origin);
                stats = DensityStats::new(gaussians.len());
            }
            if density.opacity_reset_interval > 0 && step % density.opacity_reset_interval == 0 {
                reset_opacity(&mut gaussians);
                adam.reset_opacity();
            }
        }
        if gaussians.is_empty() {
            return Err(Error::invalid(format!(
                "every Gaussian was pruned by iteration {step}"
            )));
        }
        if params.eval_every > 0 && step % params.eval_every == 0 {
            let p = evaluate(&gaussians, heldout, &heldout_targets, bg);
            report.heldout_curve.push((step, p));
        }
        report.loss.push(value);
        progress(step, value);
    }
    report.final_heldout_psnr = evaluate(&gaussians, heldout, &heldout_targets, bg);
    report.final_train_psnr = evaluate(&gaussians, train, &train_targets, bg);
    report.gaussians = gaussians.len();
    let mut out = gaussians.to_gaussians()?;
    out.sort_morton();
    Ok((out, report))
}
