//! Gaussians sampled on surfaces.
//!
//! The budget is shared out over all patches (rectangles of the structure, triangles of the object
//! meshes) in proportion to their area, so the density is the same everywhere. Points are spread
//! on a jittered grid, so there are no holes. Each Gaussian is a flat disc on its surface (local z
//! along the normal) whose in-plane size is a fixed fraction of the mean spacing, so neighbours
//! overlap; its colour comes from the patch's procedural texture, and a small degree-1 SH term
//! makes it brighter seen head-on than at a grazing angle (more on glossy materials).
//!
//! Patches are sampled in parallel, each with its own random stream derived from the seed and the
//! patch's index, and the output keeps patch order, so the result does not depend on threads.

use crate::look::Look;
use glam::{Mat3, Quat, Vec2, Vec3};
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_scene::gaussians::{Gaussian, Gaussians, SH_C0, opacity_to_logit};

/// `Y_1^m` normalisation: the degree-1 SH basis is `SH_C1 · (−y, z, −x)` of the view direction.
const SH_C1: f32 = 0.488_602_5;
/// In-plane standard deviation as a fraction of the mean spacing.
const SIGMA: f32 = 0.7;
/// Thickness along the normal as a fraction of the in-plane size.
const FLATNESS: f32 = 0.15;
/// Gaussians written per parallel chunk.
const CHUNK: usize = 4096;

/// The flat piece of surface a patch covers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Geometry {
    /// The parallelogram `origin + a·u + b·v`, a and b in [0, 1]; its normal is `u × v`.
    Rect {
        /// A corner.
        origin: Vec3,
        /// First edge.
        u: Vec3,
        /// Second edge.
        v: Vec3,
    },
    /// A triangle, counter-clockwise seen from the side its normal points to.
    Tri([Vec3; 3]),
}

impl Geometry {
    /// The rectangle from `origin` along `u` and `v`, flipped if needed so its normal is on the
    /// side of `facing`.
    pub fn rect_facing(origin: Vec3, u: Vec3, v: Vec3, facing: Vec3) -> Geometry {
        if u.cross(v).dot(facing) >= 0.0 {
            Geometry::Rect { origin, u, v }
        } else {
            Geometry::Rect {
                origin: origin + u,
                u: -u,
                v,
            }
        }
    }

    /// Area, m².
    pub fn area(&self) -> f32 {
        match *self {
            Geometry::Rect { u, v, .. } => u.cross(v).length(),
            Geometry::Tri([a, b, c]) => 0.5 * (b - a).cross(c - a).length(),
        }
    }

    /// Unit normal and a unit tangent in the plane.
    fn basis(&self) -> (Vec3, Vec3) {
        let (e, n) = match *self {
            Geometry::Rect { u, v, .. } => (u, u.cross(v)),
            Geometry::Tri([a, b, c]) => (b - a, (b - a).cross(c - a)),
        };
        let n = n.normalize_or(Vec3::Z);
        let t = (e - n * e.dot(n)).normalize_or(n.any_orthonormal_vector());
        (n, t)
    }

    /// `n` points spread evenly over the patch.
    fn points(&self, n: usize, rng: &mut impl RngCore) -> Vec<Vec3> {
        match *self {
            Geometry::Rect { origin, u, v } => rect_points(origin, u, v, n, rng),
            Geometry::Tri(t) => tri_points(t, n, rng),
        }
    }
}

/// The frame a patch's texture is evaluated in: an object's own frame, so its texture turns with
/// it (the world frame for the structure).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    /// Origin.
    pub origin: Vec3,
    /// Heading about +Z.
    pub yaw: f32,
}

impl Frame {
    /// The world frame.
    pub const WORLD: Frame = Frame {
        origin: Vec3::ZERO,
        yaw: 0.0,
    };
}

/// A surface to sample: geometry, look, texture frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Patch {
    /// Where.
    pub geometry: Geometry,
    /// How it looks.
    pub look: Look,
    /// The texture's frame.
    pub frame: Frame,
}

/// A sampled surface point before it is packed into a Gaussian.
#[derive(Debug, Clone, Copy)]
struct Surfel {
    position: Vec3,
    rotation: Quat,
    rgb: Vec3,
    gloss: f32,
    opacity_logit: f32,
    sigma: f32,
}

impl Surfel {
    fn gaussian(&self) -> Gaussian {
        let n = self.rotation * Vec3::Z;
        // A highlight facing the normal: colour += −k (view · n), i.e. +k seen head-on.
        let k = self.gloss * (Vec3::splat(0.6) + 0.4 * self.rgb) / SH_C1;
        let mut sh_rest = [[0.0; 3]; 15];
        sh_rest[0] = (k * n.y).to_array();
        sh_rest[1] = (-k * n.z).to_array();
        sh_rest[2] = (k * n.x).to_array();
        Gaussian {
            position: self.position,
            rotation: self.rotation,
            log_scale: Vec3::new(
                self.sigma.ln(),
                self.sigma.ln(),
                (self.sigma * FLATNESS).ln(),
            ),
            opacity_logit: self.opacity_logit,
            sh_dc: ((self.rgb - Vec3::splat(0.5)) / SH_C0).to_array(),
            sh_rest,
            instance: 0,
        }
    }
}

/// Samples `budget` Gaussians (SH degree 1) over `patches`, area-weighted.
pub(crate) fn sample(patches: &[Patch], budget: usize, seed: u64) -> Result<Gaussians> {
    let areas: Vec<f64> = patches
        .iter()
        .map(|p| f64::from(p.geometry.area()))
        .collect();
    let total: f64 = areas.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(Error::invalid(
            "the scene has no surface to put Gaussians on",
        ));
    }
    let spacing = (total / budget as f64).sqrt() as f32;
    // Cumulative rounding hands out exactly `budget` points with no bias towards big patches.
    let mut counts = Vec::with_capacity(patches.len());
    let (mut acc, mut given) = (0.0f64, 0usize);
    for a in &areas {
        acc += a / total * budget as f64;
        let upto = (acc.round() as usize).min(budget);
        counts.push(upto - given);
        given = upto;
    }
    if let Some(last) = counts.last_mut() {
        *last += budget - given;
    }
    let surfels: Vec<Surfel> = patches
        .par_iter()
        .zip(counts.par_iter())
        .enumerate()
        .flat_map_iter(|(i, (patch, &n))| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(i as u64);
            surfels(patch, n, spacing, &mut rng)
        })
        .collect();
    let mut store = Gaussians::with_len(surfels.len(), 1)?;
    store
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, mut window)| {
            for j in 0..window.len() {
                window.set(j, &surfels[c * CHUNK + j].gaussian());
            }
        });
    Ok(store)
}

/// `n` surfels on `patch`.
fn surfels(patch: &Patch, n: usize, spacing: f32, rng: &mut ChaCha8Rng) -> Vec<Surfel> {
    if n == 0 {
        return Vec::new();
    }
    let (normal, tangent) = patch.geometry.basis();
    let rotation =
        Quat::from_mat3(&Mat3::from_cols(tangent, normal.cross(tangent), normal)).normalize();
    let to_texture = Quat::from_rotation_z(-patch.frame.yaw);
    let texture_normal = to_texture * normal;
    let material = patch.look.material;
    let base_logit = opacity_to_logit(material.opacity());
    patch
        .geometry
        .points(n, rng)
        .into_iter()
        .map(|position| Surfel {
            position,
            rotation,
            rgb: patch.look.shade(
                to_texture * (position - patch.frame.origin),
                texture_normal,
                spacing,
            ),
            gloss: material.gloss(),
            opacity_logit: if base_logit > 2.5 {
                rng.random_range(2.6..3.8)
            } else {
                base_logit
            },
            sigma: spacing * SIGMA * rng.random_range(0.9..1.1),
        })
        .collect()
}

/// Exactly `n` points on the parallelogram: one per cell of a near-square grid (jittered within the
/// middle of each cell), the remainder uniformly.
fn rect_points(origin: Vec3, u: Vec3, v: Vec3, n: usize, rng: &mut impl RngCore) -> Vec<Vec3> {
    let (lu, lv) = (u.length().max(1e-9), v.length().max(1e-9));
    let rows = ((n as f32 * lv / lu).sqrt().floor() as usize).clamp(1, n);
    let cols = (n / rows).max(1);
    let mut out = Vec::with_capacity(n);
    for j in 0..rows {
        for i in 0..cols {
            let a = (i as f32 + rng.random_range(0.2..0.8)) / cols as f32;
            let b = (j as f32 + rng.random_range(0.2..0.8)) / rows as f32;
            out.push(origin + u * a + v * b);
        }
    }
    while out.len() < n {
        out.push(origin + u * rng.random::<f32>() + v * rng.random::<f32>());
    }
    out
}

/// Exactly `n` points on the triangle: a jittered grid of the point spacing over its bounding
/// rectangle (laid along its longest edge), keeping the points inside, thinned evenly or topped up
/// with uniform points.
fn tri_points(t: [Vec3; 3], n: usize, rng: &mut impl RngCore) -> Vec<Vec3> {
    let uniform_point = |rng: &mut dyn RngCore| {
        let (mut a, mut b) = (rng.random::<f32>(), rng.random::<f32>());
        if a + b > 1.0 {
            (a, b) = (1.0 - a, 1.0 - b);
        }
        t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
    };
    if n < 4 {
        return (0..n).map(|_| uniform_point(rng)).collect();
    }
    // x runs along the longest edge from its first corner; the third corner projects inside it.
    let k = (0..3)
        .max_by(|&i, &j| {
            (t[(i + 1) % 3] - t[i])
                .length()
                .total_cmp(&(t[(j + 1) % 3] - t[j]).length())
        })
        .unwrap_or(0);
    let (p0, p1, p2) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    let len = (p1 - p0).length();
    let x_axis = (p1 - p0) / len.max(1e-12);
    let apex = Vec2::new((p2 - p0).dot(x_axis), 0.0);
    let y_vec = (p2 - p0) - x_axis * apex.x;
    let height = y_vec.length();
    let y_axis = y_vec / height.max(1e-12);
    let area = 0.5 * len * height;
    let step = (area / n as f32).sqrt().max(1e-9);
    let (nx, ny) = (
        ((len / step).round() as usize).max(1),
        ((height / step).round() as usize).max(1),
    );
    let mut inside = Vec::with_capacity(nx * ny / 2 + 1);
    for j in 0..ny {
        for i in 0..nx {
            let x = (i as f32 + rng.random_range(0.2..0.8)) * len / nx as f32;
            let y = (j as f32 + rng.random_range(0.2..0.8)) * height / ny as f32;
            let f = y / height.max(1e-12);
            if x >= apex.x * f && x <= len + (apex.x - len) * f {
                inside.push(p0 + x_axis * x + y_axis * y);
            }
        }
    }
    let m = inside.len();
    let mut out: Vec<Vec3> = if m > n {
        (0..n).map(|i| inside[i * m / n]).collect()
    } else {
        inside
    };
    while out.len() < n {
        out.push(uniform_point(rng));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_counts_are_exact_and_points_lie_on_the_patch() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let t = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.3, 0.1, 1.0),
        ];
        for n in [1, 3, 4, 17, 200, 1001] {
            let pts = tri_points(t, n, &mut rng);
            assert_eq!(pts.len(), n);
            let normal = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            for p in pts {
                assert!((p - t[0]).dot(normal).abs() < 1e-4);
            }
            let pts = rect_points(
                Vec3::ZERO,
                Vec3::new(4.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.5),
                n,
                &mut rng,
            );
            assert_eq!(pts.len(), n);
            assert!(pts.iter().all(|p| p.x >= 0.0
                && p.x <= 4.0
                && p.z >= 0.0
                && p.z <= 0.5
                && p.y == 0.0));
        }
    }

    #[test]
    fn surfels_face_their_normal_and_have_a_highlight() {
        let look = Look::named("red", crate::look::Material::Metal, 3);
        let patch = Patch {
            geometry: Geometry::rect_facing(Vec3::ZERO, Vec3::X, Vec3::Y, -Vec3::Z),
            look,
            frame: Frame::WORLD,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for s in surfels(&patch, 10, 0.05, &mut rng) {
            let g = s.gaussian();
            assert!((g.rotation * Vec3::Z - (-Vec3::Z)).length() < 1e-5);
            assert!(g.sh_rest[1].iter().all(|c| *c > 0.0));
            assert!(g.log_scale.z < g.log_scale.x);
        }
    }
}
