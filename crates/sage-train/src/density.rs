//! Adaptive density control of 3DGS: Gaussians whose projected centres keep large gradients
//! are cloned (small ones) or split in two (large ones); nearly transparent or oversized ones
//! are pruned; opacities are periodically reset so that occluded clutter can be pruned.

use crate::params::{Param, Params};
use glam::{Quat, Vec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// When and how density control acts (3DGS defaults, with the schedule shortened for CPU fits
/// of a few thousand iterations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DensityParams {
    /// First iteration at which to densify.
    pub from: usize,
    /// No densification at or after this iteration, nor in the second half of a fit.
    pub until: usize,
    /// Densify every this many iterations (0: never).
    pub interval: usize,
    /// Mean gradient norm of the projected centre, in NDC units (pixels × 2 / size), above
    /// which a Gaussian is densified.
    pub grad_threshold: f32,
    /// Gaussians whose largest scale is at most this fraction of the scene extent are cloned,
    /// larger ones split.
    pub percent_dense: f32,
    /// Gaussians below this opacity are pruned.
    pub min_opacity: f32,
    /// Reset every opacity to at most 0.01 every this many iterations (0: never).
    pub opacity_reset_interval: usize,
    /// After the first opacity reset, also prune Gaussians larger than this fraction of the
    /// scene extent…
    pub max_world_fraction: f32,
    /// …or whose 3σ screen radius exceeded this fraction of the image's larger side.
    pub max_screen_fraction: f32,
    /// Densification never grows the set beyond this many Gaussians.
    pub max_gaussians: usize,
}

impl Default for DensityParams {
    fn default() -> Self {
        DensityParams {
            from: 100,
            until: 1500,
            interval: 100,
            grad_threshold: 2e-4,
            percent_dense: 0.01,
            min_opacity: 0.005,
            opacity_reset_interval: 3000,
            max_world_fraction: 0.1,
            max_screen_fraction: 0.5,
            max_gaussians: 200_000,
        }
    }
}

/// Per-Gaussian statistics gathered between densifications.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DensityStats {
    /// Σ ‖∂L/∂(projected centre)‖ in NDC units over the views that saw it.
    pub grad_sum: Vec<f32>,
    /// Views that saw it.
    pub seen: Vec<u32>,
    /// Largest 3σ screen radius, as a fraction of the image's larger side.
    pub max_screen: Vec<f32>,
}

impl DensityStats {
    /// Zero statistics for `n` Gaussians.
    pub fn new(n: usize) -> DensityStats {
        DensityStats {
            grad_sum: vec![0.0; n],
            seen: vec![0; n],
            max_screen: vec![0.0; n],
        }
    }

    /// Adds one view: Gaussian `index` was seen with screen radius `radius` (pixels) and
    /// centre gradient `grad` (pixels) in a `width × height` image.
    pub fn record(&mut self, index: usize, radius: f32, grad: [f32; 2], width: f32, height: f32) {
        let ndc = [grad[0] * width * 0.5, grad[1] * height * 0.5];
        self.grad_sum[index] += (ndc[0] * ndc[0] + ndc[1] * ndc[1]).sqrt();
        self.seen[index] += 1;
        self.max_screen[index] = self.max_screen[index].max(radius / width.max(height));
    }

    fn mean_grad(&self, i: usize) -> f32 {
        if self.seen[i] == 0 {
            0.0
        } else {
            self.grad_sum[i] / self.seen[i] as f32
        }
    }
}

/// One standard normal sample (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f32 {
    let u1: f32 = rng.random_range(f32::EPSILON..1.0);
    let u2: f32 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// Clones, splits and prunes `params` by `stats`; returns, per new row, the old row whose
/// optimiser state it keeps (`None` for new Gaussians). `prune_large` enables the size
/// pruning (3DGS: only after the first opacity reset).
pub fn densify_and_prune(
    params: &mut Params,
    stats: &DensityStats,
    settings: &DensityParams,
    extent: f32,
    prune_large: bool,
    rng: &mut ChaCha8Rng,
) -> Vec<Option<u32>> {
    let n = params.len();
    // Candidates by decreasing mean gradient (ties by index), so a cap keeps the neediest.
    let mut candidates: Vec<usize> = (0..n)
        .filter(|&i| stats.mean_grad(i) >= settings.grad_threshold && stats.seen[i] > 0)
        .collect();
    candidates.sort_by(|&a, &b| {
        stats
            .mean_grad(b)
            .total_cmp(&stats.mean_grad(a))
            .then(a.cmp(&b))
    });
    let mut room = settings.max_gaussians.saturating_sub(n);
    let mut split = vec![false; n];
    let mut added: Vec<(Param, u32)> = Vec::new();
    for i in candidates {
        let p = params.rows[i];
        let instance = params.instances[i];
        if p.max_scale() <= settings.percent_dense * extent {
            if room == 0 {
                continue;
            }
            room -= 1;
            added.push((p, instance));
        } else {
            // Two samples from the Gaussian replace it, each scaled down by 1 / (0.8 · 2).
            if room == 0 {
                continue;
            }
            room -= 1;
            split[i] = true;
            let [w, x, y, z] = p.rotation;
            let q = Quat::from_xyzw(x, y, z, w).normalize();
            let scale = Vec3::from_array(p.log_scale).exp();
            for _ in 0..2 {
                let offset = q * (scale * Vec3::new(normal(rng), normal(rng), normal(rng)));
                let mut child = p;
                child.mean = (Vec3::from_array(p.mean) + offset).to_array();
                child.log_scale = p.log_scale.map(|l| l - (1.6f32).ln());
                added.push((child, instance));
            }
        }
    }
    let keep = |i: usize| {
        let p = &params.rows[i];
        let transparent = p.opacity() < settings.min_opacity;
        let large = prune_large
            && (p.max_scale() > settings.max_world_fraction * extent
                || stats.max_screen[i] > settings.max_screen_fraction);
        !split[i] && !transparent && !large
    };
    let mut origin = Vec::with_capacity(n + added.len());
    let mut rows = Vec::with_capacity(n + added.len());
    let mut instances = Vec::with_capacity(n + added.len());
    for i in 0..n {
        if keep(i) {
            origin.push(Some(i as u32));
            rows.push(params.rows[i]);
            instances.push(params.instances[i]);
        }
    }
    for (p, instance) in added {
        if p.opacity() >= settings.min_opacity {
            origin.push(None);
            rows.push(p);
            instances.push(instance);
        }
    }
    params.rows = rows;
    params.instances = instances;
    origin
}

/// Caps every opacity at 0.01 (the 3DGS reset).
pub fn reset_opacity(params: &mut Params) {
    let cap = (0.01f32 / 0.99).ln();
    for p in &mut params.rows {
        p.opacity_logit = p.opacity_logit.min(cap);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn row(scale: f32, opacity_logit: f32) -> Param {
        Param {
            log_scale: [scale.ln(); 3],
            rotation: [1.0, 0.0, 0.0, 0.0],
            opacity_logit,
            ..Param::default()
        }
    }

    #[test]
    fn clones_small_splits_large_prunes_transparent() {
        let mut params = Params {
            sh_degree: 0,
            rows: vec![
                row(0.01, 2.0),
                row(0.5, 2.0),
                row(0.01, -8.0),
                row(0.01, 2.0),
            ],
            instances: vec![1, 2, 3, 4],
        };
        let mut stats = DensityStats::new(4);
        for i in 0..3 {
            stats.record(i, 3.0, [0.01, 0.0], 64.0, 48.0);
        }
        stats.record(3, 3.0, [1e-7, 0.0], 64.0, 48.0);
        let settings = DensityParams::default();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let origin = densify_and_prune(&mut params, &stats, &settings, 2.0, false, &mut rng);
        // Kept: 0 and 3 (1 was split, 2 is transparent); added: a clone of 0, two halves of 1
        // and a clone of 2 that is transparent too.
        assert_eq!(origin, vec![Some(0), Some(3), None, None, None]);
        assert_eq!(params.instances, vec![1, 4, 1, 2, 2]);
        assert_eq!(params.rows[2], row(0.01, 2.0));
        for child in &params.rows[3..] {
            assert!((child.max_scale() - 0.5 / 1.6).abs() < 1e-5);
            assert_ne!(child.mean, [0.0; 3]);
        }
        reset_opacity(&mut params);
        assert!(params.rows.iter().all(|p| p.opacity() <= 0.01 + 1e-6));
    }

    #[test]
    fn the_cap_keeps_the_largest_gradients() {
        let mut params = Params {
            sh_degree: 0,
            rows: vec![row(0.01, 2.0); 3],
            instances: vec![0, 1, 2],
        };
        let mut stats = DensityStats::new(3);
        for (i, g) in [0.01, 0.03, 0.02].into_iter().enumerate() {
            stats.record(i, 3.0, [g, 0.0], 64.0, 48.0);
        }
        let settings = DensityParams {
            max_gaussians: 4,
            ..DensityParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        densify_and_prune(&mut params, &stats, &settings, 2.0, false, &mut rng);
        assert_eq!(params.instances, vec![0, 1, 2, 1]);
    }
}
