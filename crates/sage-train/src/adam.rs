//! Adam with one learning rate per parameter group (the 3DGS settings) and the exponential
//! decay of the position learning rate.

use crate::params::{Group, Param};
use rayon::prelude::*;

/// Learning rates per parameter group (3DGS defaults). Positions are in units of the scene
/// extent and decay log-linearly from `mean` to `mean_final` over the fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearningRates {
    /// Position, at the first iteration (× scene extent).
    pub mean: f32,
    /// Position, at the last iteration (× scene extent).
    pub mean_final: f32,
    /// Log-scales.
    pub log_scale: f32,
    /// Quaternions.
    pub rotation: f32,
    /// Opacity logits.
    pub opacity: f32,
    /// SH degree 0.
    pub sh_dc: f32,
    /// SH degree 1 (3DGS: the degree-0 rate / 20).
    pub sh_rest: f32,
}

impl Default for LearningRates {
    fn default() -> Self {
        LearningRates {
            mean: 1.6e-4,
            mean_final: 1.6e-6,
            log_scale: 5e-3,
            rotation: 1e-3,
            opacity: 5e-2,
            sh_dc: 2.5e-3,
            sh_rest: 2.5e-3 / 20.0,
        }
    }
}

impl LearningRates {
    /// The rate of every f32 of a row at `progress` (0 at the first iteration, 1 at the last),
    /// for a scene of `extent` metres.
    pub fn per_offset(&self, progress: f32, extent: f32) -> [f32; Param::LEN] {
        let t = progress.clamp(0.0, 1.0);
        let mean = (self.mean.ln() * (1.0 - t) + self.mean_final.ln() * t).exp() * extent;
        std::array::from_fn(|k| match Group::of_offset(k) {
            Group::Mean => mean,
            Group::LogScale => self.log_scale,
            Group::Rotation => self.rotation,
            Group::Opacity => self.opacity,
            Group::ShDc => self.sh_dc,
            Group::ShRest => self.sh_rest,
        })
    }

    /// True when every rate is finite and not negative.
    pub fn valid(&self) -> bool {
        [
            self.mean,
            self.mean_final,
            self.log_scale,
            self.rotation,
            self.opacity,
            self.sh_dc,
            self.sh_rest,
        ]
        .iter()
        .all(|v| v.is_finite() && *v >= 0.0)
            && self.mean > 0.0
            && self.mean_final > 0.0
    }
}

/// Adam's moments, one row per Gaussian, kept aligned with the parameters through
/// densification ([`Adam::remap`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Adam {
    /// First moments.
    pub m: Vec<Param>,
    /// Second moments.
    pub v: Vec<Param>,
    /// Steps taken (for bias correction).
    pub steps: u32,
}

const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
const EPSILON: f32 = 1e-15;

impl Adam {
    /// Zero moments for `n` Gaussians.
    pub fn new(n: usize) -> Adam {
        Adam {
            m: vec![Param::default(); n],
            v: vec![Param::default(); n],
            steps: 0,
        }
    }

    /// One step on `params` along `grads` with per-offset rates `lr`.
    pub fn step(&mut self, params: &mut [Param], grads: &[Param], lr: &[f32; Param::LEN]) {
        self.steps += 1;
        let c1 = 1.0 - BETA1.powi(self.steps as i32);
        let c2 = 1.0 - BETA2.powi(self.steps as i32);
        params
            .par_iter_mut()
            .zip(grads)
            .zip(self.m.par_iter_mut().zip(self.v.par_iter_mut()))
            .for_each(|((p, g), (m, v))| {
                let p: &mut [f32; Param::LEN] = bytemuck::cast_mut(p);
                let g: &[f32; Param::LEN] = bytemuck::cast_ref(g);
                let m: &mut [f32; Param::LEN] = bytemuck::cast_mut(m);
                let v: &mut [f32; Param::LEN] = bytemuck::cast_mut(v);
                for k in 0..Param::LEN {
                    m[k] = BETA1 * m[k] + (1.0 - BETA1) * g[k];
                    v[k] = BETA2 * v[k] + (1.0 - BETA2) * g[k] * g[k];
                    p[k] -= lr[k] * (m[k] / c1) / ((v[k] / c2).sqrt() + EPSILON);
                }
            });
    }

    /// Rebuilds the moments after densification: new row `j` takes old row `origin[j]`'s
    /// moments, or zeros where it is `None` (a new Gaussian).
    pub fn remap(&mut self, origin: &[Option<u32>]) {
        let pick = |rows: &[Param]| -> Vec<Param> {
            origin
                .iter()
                .map(|o| o.map_or(Param::default(), |i| rows[i as usize]))
                .collect()
        };
        self.m = pick(&self.m);
        self.v = pick(&self.v);
    }

    /// Forgets the opacity moments (after an opacity reset, as 3DGS does).
    pub fn reset_opacity(&mut self) {
        for (m, v) in self.m.iter_mut().zip(&mut self.v) {
            m.opacity_logit = 0.0;
            v.opacity_logit = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_moves_each_value_by_its_rate_against_the_gradient() {
        let mut params = vec![Param::default(); 2];
        let mut grads = vec![Param::default(); 2];
        grads[0].mean = [2.0, -0.5, 0.0];
        grads[1].opacity_logit = 3.0;
        let lr = LearningRates::default().per_offset(0.0, 2.0);
        let mut adam = Adam::new(2);
        adam.step(&mut params, &grads, &lr);
        // Bias-corrected Adam's first step is lr · sign(g).
        assert!((params[0].mean[0] + 3.2e-4).abs() < 1e-9);
        assert!((params[0].mean[1] - 3.2e-4).abs() < 1e-9);
        assert_eq!(params[0].mean[2], 0.0);
        assert!((params[1].opacity_logit + 0.05).abs() < 1e-7);
        let end = LearningRates::default().per_offset(1.0, 2.0);
        assert!((end[0] - 3.2e-6).abs() < 1e-10);
        adam.remap(&[Some(1), None]);
        assert_eq!(adam.m[1], Param::default());
        assert!(adam.m[0].opacity_logit != 0.0);
    }
}
