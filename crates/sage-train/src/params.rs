//! The trainable parameters: one full-precision row of f32 per Gaussian (mean, log-scales,
//! quaternion, opacity logit, SH degree 0 and optionally degree 1), with conversions from and to
//! the quantised scene store.
//!
//! A row is plain old data, so the optimiser and the densifier can treat every parameter of
//! every Gaussian as one flat `[f32]` (see [`Param::LEN`] and [`Group::of_offset`]).

use bytemuck::{Pod, Zeroable};
use glam::{Quat, Vec3};
use sage_core::{Error, Result};
use sage_scene::{Gaussian, Gaussians};

/// One Gaussian's trainable values (also used for their gradients and Adam moments).
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[repr(C)]
pub struct Param {
    /// Centre, metres (world frame).
    pub mean: [f32; 3],
    /// Natural-log standard deviations along the local axes.
    pub log_scale: [f32; 3],
    /// Rotation (w, x, y, z), any non-zero length (normalised where it is used).
    pub rotation: [f32; 4],
    /// Opacity before the sigmoid.
    pub opacity_logit: f32,
    /// SH degree-0 coefficients (RGB).
    pub sh_dc: [f32; 3],
    /// SH degree-1 coefficients, coefficient-major (`[k][channel]`); zero and untouched at
    /// degree 0.
    pub sh_rest: [[f32; 3]; 3],
}

/// The parameter groups, each with its own learning rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    /// Centres.
    Mean,
    /// Log-scales.
    LogScale,
    /// Quaternions.
    Rotation,
    /// Opacity logits.
    Opacity,
    /// SH degree 0.
    ShDc,
    /// SH degree 1.
    ShRest,
}

impl Param {
    /// The number of f32 in a row.
    pub const LEN: usize = std::mem::size_of::<Param>() / 4;

    /// The row of a stored Gaussian (degree-1 SH kept when `sh_degree` is 1).
    pub fn from_gaussian(g: &Gaussian, sh_degree: u8) -> Param {
        let q = g.rotation.normalize();
        let mut sh_rest = [[0.0; 3]; 3];
        if sh_degree >= 1 {
            sh_rest.copy_from_slice(&g.sh_rest[..3]);
        }
        Param {
            mean: g.position.to_array(),
            log_scale: g.log_scale.to_array(),
            rotation: [q.w, q.x, q.y, q.z],
            opacity_logit: g.opacity_logit,
            sh_dc: g.sh_dc,
            sh_rest,
        }
    }

    /// The Gaussian of this row with instance id `instance`.
    pub fn to_gaussian(&self, instance: u32) -> Gaussian {
        let [w, x, y, z] = self.rotation;
        let mut sh_rest = [[0.0; 3]; 15];
        sh_rest[..3].copy_from_slice(&self.sh_rest);
        Gaussian {
            position: Vec3::from_array(self.mean),
            rotation: Quat::from_xyzw(x, y, z, w),
            log_scale: Vec3::from_array(self.log_scale),
            opacity_logit: self.opacity_logit,
            sh_dc: self.sh_dc,
            sh_rest,
            instance,
        }
    }

    /// Opacity after the sigmoid.
    pub fn opacity(&self) -> f32 {
        sigmoid(self.opacity_logit)
    }

    /// The largest standard deviation (metres).
    pub fn max_scale(&self) -> f32 {
        self.log_scale[0]
            .max(self.log_scale[1])
            .max(self.log_scale[2])
            .exp()
    }
}

impl Group {
    /// The group of the f32 at `offset` (0..[`Param::LEN`]) within a row.
    pub fn of_offset(offset: usize) -> Group {
        match offset {
            0..3 => Group::Mean,
            3..6 => Group::LogScale,
            6..10 => Group::Rotation,
            10 => Group::Opacity,
            11..14 => Group::ShDc,
            _ => Group::ShRest,
        }
    }
}

/// The logistic sigmoid.
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// The Gaussians being fitted: their rows, instance ids (carried, not trained) and SH degree.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// SH degree trained (0 or 1).
    pub sh_degree: u8,
    /// One row per Gaussian.
    pub rows: Vec<Param>,
    /// Instance id per Gaussian.
    pub instances: Vec<u32>,
}

impl Params {
    /// The rows of a scene store at `sh_degree` (0 or 1; higher bands of the store are dropped).
    pub fn from_gaussians(store: &Gaussians, sh_degree: u8) -> Result<Params> {
        if sh_degree > 1 {
            return Err(Error::invalid(format!(
                "fitting trains SH degree 0 or 1, got {sh_degree}"
            )));
        }
        store.validate()?;
        let degree = sh_degree.min(store.sh_degree());
        let mut rows = Vec::with_capacity(store.len());
        let mut instances = Vec::with_capacity(store.len());
        for i in 0..store.len() {
            let g = store.get(i);
            rows.push(Param::from_gaussian(&g, degree));
            instances.push(g.instance);
        }
        Ok(Params {
            sh_degree,
            rows,
            instances,
        })
    }

    /// The scene store of these rows (quantised as the store documents).
    pub fn to_gaussians(&self) -> Result<Gaussians> {
        let items: Vec<Gaussian> = self
            .rows
            .iter()
            .zip(&self.instances)
            .map(|(p, &i)| p.to_gaussian(i))
            .collect();
        Gaussians::from_gaussians(&items, self.sh_degree)
    }

    /// The number of Gaussians.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_the_row_in_field_order() {
        let p = Param::default();
        let base = &p as *const Param as usize;
        let offset = |field: *const f32| (field as usize - base) / 4;
        assert_eq!(Group::of_offset(offset(&p.mean[2])), Group::Mean);
        assert_eq!(Group::of_offset(offset(&p.log_scale[0])), Group::LogScale);
        assert_eq!(Group::of_offset(offset(&p.rotation[3])), Group::Rotation);
        assert_eq!(Group::of_offset(offset(&p.opacity_logit)), Group::Opacity);
        assert_eq!(Group::of_offset(offset(&p.sh_dc[0])), Group::ShDc);
        assert_eq!(Group::of_offset(offset(&p.sh_rest[2][2])), Group::ShRest);
        assert_eq!(offset(&p.sh_rest[2][2]), Param::LEN - 1);
    }

    #[test]
    fn store_round_trip_keeps_values_within_quantisation() {
        let g = Gaussian {
            position: Vec3::new(1.0, -2.0, 0.5),
            rotation: Quat::from_rotation_z(0.4),
            log_scale: Vec3::new(-3.0, -2.5, -4.0),
            opacity_logit: 1.5,
            sh_dc: [0.3, -0.2, 0.9],
            instance: 7,
            ..Gaussian::default()
        };
        let mut store = Gaussians::new(1).unwrap();
        store.push(&g);
        let params = Params::from_gaussians(&store, 1).unwrap();
        let back = params.to_gaussians().unwrap().get(0);
        assert_eq!(back.instance, 7);
        assert!((back.log_scale - g.log_scale).abs().max_element() < 1e-3);
        assert!(Params::from_gaussians(&store, 2).is_err());
    }
}
