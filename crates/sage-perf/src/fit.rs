//! `sage3d bench fit`: fit a degraded copy of one synthetic room to views of it on the CPU
//! (sage-train); held-out PSNR before and after, milliseconds per iteration.

use crate::machine;
use rand::{Rng, SeedableRng};
use sage_core::Result;
use sage_scene::{Gaussian, Gaussians};
use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
use sage_synth::SynthConfig;
use sage_train::{FitParams, View};
use serde::Serialize;
use std::fmt;
use std::sync::Mutex;
use std::time::Instant;

/// What `bench fit` fits.
#[derive(Clone, Debug, PartialEq)]
pub struct FitSettings {
    /// Optimisation steps.
    pub iterations: usize,
    /// Image size, (width, height).
    pub size: (u32, u32),
    /// Gaussians in the generated room (the initialisation keeps every fourth).
    pub gaussians: usize,
    /// Training views.
    pub views: usize,
    /// Held-out views.
    pub heldout: usize,
    /// Seed of the room, the cameras, the degradation and the fit.
    pub seed: u64,
}

impl Default for FitSettings {
    fn default() -> Self {
        Self {
            iterations: 300,
            size: (128, 96),
            gaussians: 20_000,
            views: 24,
            heldout: 6,
            seed: 1,
        }
    }
}

/// What `bench fit` measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The machine ([`machine::describe`]).
    pub machine: String,
    /// Gaussians in the room.
    pub gaussians: usize,
    /// Gaussians of the initialisation.
    pub initial_gaussians: usize,
    /// Training views.
    pub views: usize,
    /// Held-out views.
    pub heldout: usize,
    /// Image size, (width, height).
    pub size: (u32, u32),
    /// Mean held-out PSNR (dB) of the initialisation.
    pub initial_heldout_psnr: f32,
    /// Mean held-out PSNR (dB) after the fit.
    pub final_heldout_psnr: f32,
    /// Mean training PSNR (dB) after the fit.
    pub final_train_psnr: f32,
    /// Iterations run.
    pub iterations: usize,
    /// Gaussians after the fit.
    pub final_gaussians: usize,
    /// Milliseconds per iteration (`None` with fewer than 2 iterations to time).
    pub ms_per_iteration: Option<f64>,
    /// Worker threads.
    pub threads: usize,
}

impl fmt::Display for FitReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (width, height) = self.size;
        let per_iteration = match self.ms_per_iteration {
            Some(ms) => format!("{ms:.1} ms"),
            None => "n/a (fewer than 2 iterations)".into(),
        };
        writeln!(f, "machine          {}", self.machine)?;
        writeln!(
            f,
            "scene            one room, {} Gaussians; initialisation {} Gaussians",
            self.gaussians, self.initial_gaussians
        )?;
        writeln!(
            f,
            "views            {} training, {} held-out, {width}x{height}",
            self.views, self.heldout
        )?;
        writeln!(
            f,
            "held-out PSNR    {:.2} dB -> {:.2} dB (training {:.2} dB)",
            self.initial_heldout_psnr, self.final_heldout_psnr, self.final_train_psnr
        )?;
        writeln!(
            f,
            "fit              {} iterations, {} Gaussians at the end, {per_iteration} per iteration ({} threads)",
            self.iterations, self.final_gaussians, self.threads
        )
    }
}

/// Runs `bench fit`: views of a one-room synthetic scene rendered by `sage-splat` from cameras
/// near its middle (random headings, slightly downward), fitted from every fourth Gaussian with
/// perturbed colours and scales grown by 1.6.
///
/// # Errors
///
/// The scene cannot be generated, the size is empty, or the fit fails.
pub fn run(settings: &FitSettings) -> Result<FitReport> {
    let (width, height) = settings.size;
    eprintln!(
        "generating a one-room scene of {} Gaussians …",
        settings.gaussians
    );
    let scene = sage_synth::generate(&SynthConfig {
        seed: settings.seed,
        rooms: 1,
        objects: 10,
        gaussians: settings.gaussians,
        ..SynthConfig::default()
    })?;
    let truth = &scene.gaussians;
    let centre = scene.floorplan.rooms[0].profile.centroid();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(settings.seed);
    let mut renderer = Renderer::new(truth);
    let intrinsics = Intrinsics::from_hfov(width, height, 90.0)?;
    let mut views = (0..settings.views + settings.heldout)
        .map(|_| {
            let position = glam::Vec3::new(
                centre.x + rng.random_range(-0.6..0.6),
                centre.y + rng.random_range(-0.6..0.6),
                rng.random_range(1.1..1.6),
            );
            let camera = Camera::from_yaw_pitch(
                intrinsics,
                position,
                rng.random_range(-std::f32::consts::PI..std::f32::consts::PI),
                rng.random_range(-0.4..0.1),
            );
            let rgb = renderer
                .render(truth, &[], &camera, &RenderOptions::default())?
                .rgb;
            Ok(View { camera, rgb })
        })
        .collect::<Result<Vec<_>>>()?;
    let heldout = views.split_off(settings.views);
    let mut init = Gaussians::new(0)?;
    for i in (0..truth.len()).step_by(4) {
        let g = truth.get(i);
        init.push(&Gaussian {
            log_scale: g.log_scale + glam::Vec3::splat(1.6f32.ln()),
            sh_dc: g.sh_dc.map(|c| c + rng.random_range(-0.6..0.6)),
            ..g
        });
    }
    let params = FitParams {
        iterations: settings.iterations,
        seed: settings.seed,
        ..FitParams::default()
    };
    // Iterations are timed between the first and the last progress call, so the held-out
    // evaluations before and after are left out.
    let marks = Mutex::new((None, None));
    let (fitted, report) = sage_train::fit(&init, &views, &heldout, &params, &|it, _| {
        let mut m = marks.lock().unwrap_or_else(|e| e.into_inner());
        let now = Some((it, Instant::now()));
        if m.0.is_none() {
            m.0 = now;
        }
        m.1 = now;
    })?;
    let ms_per_iteration = match marks.into_inner().unwrap_or_else(|e| e.into_inner()) {
        (Some((i0, t0)), Some((i1, t1))) if i1 > i0 => {
            Some((t1 - t0).as_secs_f64() * 1e3 / (i1 - i0) as f64)
        }
        _ => None,
    };
    Ok(FitReport {
        machine: machine::describe(),
        gaussians: truth.len(),
        initial_gaussians: init.len(),
        views: views.len(),
        heldout: heldout.len(),
        size: settings.size,
        initial_heldout_psnr: report.initial_heldout_psnr,
        final_heldout_psnr: report.final_heldout_psnr,
        final_train_psnr: report.final_train_psnr,
        iterations: settings.iterations,
        final_gaussians: fitted.len(),
        ms_per_iteration,
        threads: rayon::current_num_threads(),
    })
}
