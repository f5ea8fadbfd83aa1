//! Similarity transforms of Gaussians: scale, rotate, translate, with each Gaussian's
//! orientation, size and view-dependent colour turned along.

use crate::sh::ShRotation;
use glam::{Mat3, Mat4, Quat, Vec3};
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use sage_scene::gaussians::sh_rest_count;
use serde::Serialize;

/// `p ↦ rotation · (scale · p) + translation`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Similarity {
    /// Uniform scale (> 0).
    pub scale: f32,
    /// Rotation (unit).
    pub rotation: Quat,
    /// Translation, applied last.
    pub translation: Vec3,
}

impl Default for Similarity {
    fn default() -> Self {
        Similarity::IDENTITY
    }
}

impl Similarity {
    /// The identity.
    pub const IDENTITY: Similarity = Similarity {
        scale: 1.0,
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// The image of point `p`.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.rotation * (p * self.scale) + self.translation
    }

    /// `other` after `self`: the map `p ↦ other.apply(self.apply(p))`.
    pub fn then(&self, other: &Similarity) -> Similarity {
        Similarity {
            scale: self.scale * other.scale,
            rotation: (other.rotation * self.rotation).normalize(),
            translation: other.apply(self.translation),
        }
    }

    /// The inverse map.
    pub fn inverse(&self) -> Similarity {
        let r = self.rotation.inverse();
        Similarity {
            scale: 1.0 / self.scale,
            rotation: r,
            translation: -(r * self.translation) / self.scale,
        }
    }

    /// The 4 × 4 matrix acting on `[x, y, z, 1]` columns.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }

    /// The matrix as four rows, for files (`p_out = M · [p, 1]`).
    pub fn rows(&self) -> [[f32; 4]; 4] {
        self.matrix().transpose().to_cols_array_2d()
    }
}

/// Gaussians `keep` of `src` (in that order) moved by `t`: centres mapped, orientations turned,
/// log-scales shifted by ln(scale), and SH degrees 1–3 turned so that each Gaussian shows the
/// same colour towards the turned direction. Opacity, base colour and instance stay.
///
/// # Errors
///
/// A scale that is not finite and positive, or an index out of range.
pub fn transform(src: &Gaussians, keep: &[u32], t: &Similarity) -> Result<Gaussians> {
    if !(t.scale.is_finite() && t.scale > 0.0) {
        return Err(Error::invalid(format!(
            "scale must be finite and > 0, got {}",
            t.scale
        )));
    }
    if let Some(&bad) = keep.iter().find(|&&i| i as usize >= src.len()) {
        return Err(Error::invalid(format!(
            "Gaussian {bad} is out of range ({} Gaussians)",
            src.len()
        )));
    }
    let degree = src.sh_degree();
    let k = sh_rest_count(degree);
    let sh = ShRotation::new(Mat3::from_quat(t.rotation));
    let ln_scale = t.scale.ln();
    let mut out = Gaussians::with_len(keep.len(), degree)?;
    const CHUNK: usize = 4096;
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, mut window)| {
            for j in 0..window.len() {
                let mut g = src.get(keep[c * CHUNK + j] as usize);
                g.position = t.apply(g.position);
                g.rotation = (t.rotation * g.rotation).normalize();
                g.log_scale += Vec3::splat(ln_scale);
                sh.apply(&mut g.sh_rest[..k]);
                window.set(j, &g);
            }
        });
    Ok(out)
}

/// All indices of `g`, for [`transform`] of a whole store.
pub fn all(g: &Gaussians) -> Vec<u32> {
    (0..g.len() as u32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_scene::gaussians::Gaussian;

    #[test]
    fn composition_inverse_and_matrix_agree() {
        let a = Similarity {
            scale: 2.0,
            rotation: Quat::from_rotation_x(0.3),
            translation: Vec3::new(1.0, -2.0, 0.5),
        };
        let b = Similarity {
            scale: 0.7,
            rotation: Quat::from_rotation_z(-1.2),
            translation: Vec3::new(0.0, 3.0, -1.0),
        };
        let p = Vec3::new(0.3, -0.4, 2.0);
        assert!((a.then(&b).apply(p) - b.apply(a.apply(p))).length() < 1e-5);
        assert!((a.inverse().apply(a.apply(p)) - p).length() < 1e-5);
        assert!((a.matrix().transform_point3(p) - a.apply(p)).length() < 1e-5);
        let rows = a.rows();
        let x = rows[0][0] * p.x + rows[0][1] * p.y + rows[0][2] * p.z + rows[0][3];
        assert!((x - a.apply(p).x).abs() < 1e-5);
    }

    #[test]
    fn a_gaussian_moves_turns_and_grows_with_the_scene() {
        let mut src = Gaussians::new(1).unwrap();
        let mut sh_rest = [[0.0; 3]; 15];
        sh_rest[0] = [0.5, -0.25, 0.125];
        src.push(&Gaussian {
            position: Vec3::new(1.0, 2.0, 3.0),
            rotation: Quat::from_rotation_y(0.4),
            log_scale: Vec3::new(-3.0, -2.0, -4.0),
            opacity_logit: 1.5,
            sh_dc: [0.1, 0.2, 0.3],
            sh_rest,
            instance: 7,
        });
        let t = Similarity {
            scale: 2.0,
            rotation: Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
            translation: Vec3::new(0.0, 0.0, 1.0),
        };
        let out = transform(&src, &all(&src), &t).unwrap().get(0);
        assert!((out.position - Vec3::new(2.0, -6.0, 5.0)).length() < 1e-5);
        let want = t.rotation * Quat::from_rotation_y(0.4);
        assert!(out.rotation.dot(want).abs() > 1.0 - 1e-4);
        assert!(
            (out.log_scale - Vec3::new(-3.0, -2.0, -4.0) - Vec3::splat(2f32.ln()))
                .abs()
                .max_element()
                < 1e-3
        );
        assert!((out.opacity_logit - 1.5).abs() < 1e-3);
        assert_eq!(out.instance, 7);
        // Degree 1 is a vector: (−y, z, −x) coefficients turn as the vector does.
        assert!(out.sh_rest[0] != sh_rest[0]);
        assert!(transform(&src, &[1], &t).is_err());
        let bad = Similarity { scale: 0.0, ..t };
        assert!(transform(&src, &[0], &bad).is_err());
    }
}
