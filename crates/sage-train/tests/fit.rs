//! Fitting a small scene: target views are rendered by `sage-splat` from a known Gaussian
//! scene (a checkered wall and floor); the fit starts from a coarser surface-sampled
//! initialisation whose colours are each plane's mean, so the checkers must be learnt.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_scene::Gaussians;
use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
use sage_train::density::DensityParams;
use sage_train::forward::forward;
use sage_train::loss::psnr;
use sage_train::params::Params;
use sage_train::{FitParams, FitReport, View, fit, init_gaussians};

/// A wall (x = 3 m) and a floor (z = 0), each checkered in two colours with cells of 0.5 m.
type Sample = (Vec3, [f32; 3], Vec3);

fn surfaces(spacing: f32, checkered: bool) -> Vec<Sample> {
    let wall = ([0.85, 0.3, 0.2], [0.2, 0.35, 0.8]);
    let floor = ([0.9, 0.85, 0.6], [0.25, 0.2, 0.15]);
    let mean = |(a, b): ([f32; 3], [f32; 3])| std::array::from_fn(|c| 0.5 * (a[c] + b[c]));
    let pick = |pair: ([f32; 3], [f32; 3]), u: f32, v: f32| {
        if !checkered {
            mean(pair)
        } else if ((u / 0.5).floor() + (v / 0.5).floor()) as i32 % 2 == 0 {
            pair.0
        } else {
            pair.1
        }
    };
    let steps = |lo: f32, hi: f32| {
        let n = ((hi - lo) / spacing).round() as usize;
        (0..=n).map(move |k| lo + k as f32 * spacing)
    };
    let mut out = Vec::new();
    for y in steps(-2.0, 2.0) {
        for z in steps(0.0, 2.4) {
            out.push((Vec3::new(3.0, y, z), pick(wall, y + 2.0, z), -Vec3::X));
        }
        for x in steps(0.0, 2.9) {
            out.push((Vec3::new(x, y, 0.0), pick(floor, x, y + 2.0), Vec3::Z));
        }
    }
    out
}

fn camera(position: Vec3, yaw: f32) -> Camera {
    Camera::from_yaw_pitch(
        Intrinsics::from_hfov(48, 36, 80.0).unwrap(),
        position,
        yaw,
        -0.3,
    )
}

/// Views of `truth` rendered by `sage-splat`, from cameras on an arc facing the wall.
fn views(truth: &Gaussians, seed: u64, n: usize) -> Vec<View> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut renderer = Renderer::new(truth);
    (0..n)
        .map(|_| {
            let position = Vec3::new(
                rng.random_range(0.2..0.8),
                rng.random_range(-0.8..0.8),
                rng.random_range(1.0..1.5),
            );
            let camera = camera(position, rng.random_range(-0.5..0.5));
            let out = renderer
                .render(truth, &[], &camera, &RenderOptions::default())
                .unwrap();
            View {
                camera,
                rgb: out.rgb,
            }
        })
        .collect()
}

struct Setup {
    init: Gaussians,
    train: Vec<View>,
    heldout: Vec<View>,
}

fn setup() -> Setup {
    let truth = init_gaussians(&surfaces(0.06, true), 0.06);
    Setup {
        init: init_gaussians(&surfaces(0.15, false), 0.15),
        train: views(&truth, 1, 10),
        heldout: views(&truth, 2, 3),
    }
}

fn run(s: &Setup, params: &FitParams) -> (Gaussians, FitReport) {
    fit(&s.init, &s.train, &s.heldout, params, &|_, _| {}).unwrap()
}

#[test]
fn fitting_lowers_the_loss_and_beats_the_initialisation_on_held_out_views() {
    let s = setup();
    let params = FitParams {
        iterations: 200,
        seed: 7,
        eval_every: 50,
        density: DensityParams {
            from: 25,
            interval: 25,
            max_gaussians: 2500,
            ..DensityParams::default()
        },
        ..FitParams::default()
    };
    let (fitted, report) = run(&s, &params);
    eprintln!(
        "held-out PSNR {:.2} -> {:.2} dB, train {:.2} dB, {} -> {} Gaussians, curve {:?}",
        report.initial_heldout_psnr,
        report.final_heldout_psnr,
        report.final_train_psnr,
        s.init.len(),
        report.gaussians,
        report.heldout_curve
    );
    assert_eq!(report.loss.len(), 200);
    assert_eq!(report.gaussians, fitted.len());
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (first, last) = (mean(&report.loss[..20]), mean(&report.loss[180..]));
    assert!(last < 0.7 * first, "loss {first} -> {last}");
    // Monotone-ish: every window of 50 iterations is better on average than the one before.
    let windows: Vec<f32> = report.loss.chunks(50).map(mean).collect();
    assert!(windows.windows(2).all(|w| w[1] < w[0]), "{windows:?}");
    assert!(
        report.final_heldout_psnr > report.initial_heldout_psnr + 4.0,
        "held-out PSNR {} -> {}",
        report.initial_heldout_psnr,
        report.final_heldout_psnr
    );
    assert!(report.heldout_curve.len() == 4);
}

#[test]
fn the_renderer_draws_the_fitted_gaussians_as_the_fit_sees_them() {
    let s = setup();
    let params = FitParams {
        iterations: 60,
        seed: 3,
        sh_degree: 1,
        density: DensityParams {
            from: 20,
            interval: 20,
            ..DensityParams::default()
        },
        ..FitParams::default()
    };
    let (fitted, _) = run(&s, &params);
    assert_eq!(fitted.sh_degree(), 1);
    let as_fitted = Params::from_gaussians(&fitted, 1).unwrap();
    let mut renderer = Renderer::new(&fitted);
    for view in &s.heldout {
        let ours = forward(&as_fitted, &view.camera, [0.0; 3]);
        let theirs = renderer
            .render(&fitted, &[], &view.camera, &RenderOptions::default())
            .unwrap();
        let target: Vec<f32> = ours.rgb.iter().map(|v| v.clamp(0.0, 1.0)).collect();
        let p = psnr(&theirs.rgb_f32, &target);
        assert!(p > 45.0, "renderer vs trainer: {p:.1} dB");
    }
}

#[test]
fn same_seed_same_gaussians_for_any_thread_count() {
    let s = setup();
    let params = FitParams {
        iterations: 40,
        seed: 11,
        density: DensityParams {
            from: 10,
            interval: 10,
            grad_threshold: 1e-4,
            ..DensityParams::default()
        },
        ..FitParams::default()
    };
    let with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&s, &params))
    };
    let (one, report_one) = with(1);
    let (two, report_two) = with(2);
    assert_ne!(one.len(), s.init.len(), "densification should have acted");
    assert_eq!(one, two);
    assert_eq!(report_one, report_two);
    let (other_seed, _) = fit(
        &s.init,
        &s.train,
        &s.heldout,
        &FitParams { seed: 12, ..params },
        &|_, _| {},
    )
    .unwrap();
    assert_ne!(one, other_seed);
}

#[test]
fn bad_views_and_settings_are_errors_naming_the_field() {
    let s = setup();
    let mut train = s.train.clone();
    train[2].rgb.pop();
    let e = fit(
        &s.init,
        &train,
        &s.heldout,
        &FitParams::default(),
        &|_, _| {},
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("train[2].rgb:"), "{e}");
    let e = fit(&s.init, &s.train, &[], &FitParams::default(), &|_, _| {}).unwrap_err();
    assert!(e.to_string().contains("held-out"), "{e}");
    let bad = FitParams {
        sh_degree: 3,
        ..FitParams::default()
    };
    assert!(fit(&s.init, &s.train, &s.heldout, &bad, &|_, _| {}).is_err());
    let e = fit(
        &Gaussians::default(),
        &s.train,
        &s.heldout,
        &FitParams::default(),
        &|_, _| {},
    )
    .unwrap_err();
    assert!(e.to_string().contains("no initial Gaussians"), "{e}");
}
