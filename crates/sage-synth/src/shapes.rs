//! Closed mesh primitives (boxes, surfaces of revolution, rods) that furniture is assembled from.
//!
//! Every primitive is a closed, consistently wound mesh: triangles are counter-clockwise seen from
//! outside, so a part's signed volume is positive.

use crate::look::Look;
use glam::{Mat4, Quat, Vec3};
use sage_scene::mesh::TriMesh;

/// One piece of an object: a closed mesh with a single look.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Part {
    /// The geometry (in the object's local frame while building, in the world frame after).
    pub mesh: TriMesh,
    /// The finish it is rendered with.
    pub look: Look,
}

impl Part {
    /// A part from a mesh and a look.
    pub fn new(mesh: TriMesh, look: Look) -> Part {
        Part { mesh, look }
    }

    /// The part with its mesh transformed by `m` (a rigid motion or positive scaling).
    pub fn transformed(&self, m: &Mat4) -> Part {
        Part {
            mesh: self.mesh.transformed(m),
            look: self.look,
        }
    }
}

/// Segments around a surface of revolution: enough to look round, few enough to stay cheap.
pub(crate) const SEGMENTS: u32 = 16;

/// The axis-aligned box from `min` to `max`.
pub(crate) fn cuboid(min: Vec3, max: Vec3) -> TriMesh {
    let positions = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            )
        })
        .collect();
    // Corner i has x from bit 0, y from bit 1, z from bit 2; each face is a counter-clockwise quad.
    let faces: [[u32; 4]; 6] = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let triangles = faces
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    TriMesh {
        positions,
        triangles,
    }
}

/// A box of size `size` whose bottom face is centred on `base`.
pub(crate) fn block(base: Vec3, size: Vec3) -> TriMesh {
    let half = Vec3::new(size.x * 0.5, size.y * 0.5, 0.0);
    cuboid(base - half, base + half + Vec3::Z * size.z)
}

/// A surface of revolution about the vertical axis through `base`.
///
/// `profile` lists (radius, height above `base`) from bottom to top. A zero radius at either end
/// closes the surface in a point; a non-zero one is closed by a flat cap.
pub(crate) fn lathe(base: Vec3, profile: &[(f32, f32)], segments: u32) -> TriMesh {
    let mut mesh = TriMesh::default();
    let segments = segments.max(3);
    let point = |r: f32, z: f32, i: u32| {
        let a = std::f32::consts::TAU * i as f32 / segments as f32;
        base + Vec3::new(r * a.cos(), r * a.sin(), z)
    };
    // Each ring is either one apex vertex or `segments` vertices; remember where each starts.
    let mut rings: Vec<(u32, bool)> = Vec::with_capacity(profile.len());
    for &(r, z) in profile {
        let start = mesh.positions.len() as u32;
        if r <= 1e-6 {
            mesh.positions.push(base + Vec3::Z * z);
            rings.push((start, true));
        } else {
            mesh.positions.extend((0..segments).map(|i| point(r, z, i)));
            rings.push((start, false));
        }
    }
    let at = |ring: (u32, bool), i: u32| {
        if ring.1 {
            ring.0
        } else {
            ring.0 + i % segments
        }
    };
    for w in rings.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        for i in 0..segments {
            let (a, b, c, d) = (at(lo, i), at(lo, i + 1), at(hi, i + 1), at(hi, i));
            if !lo.1 {
                mesh.triangles.push([a, b, c]);
            }
            if !hi.1 {
                mesh.triangles.push([a, c, d]);
            }
        }
    }
    if let (Some(&first), Some(&(r0, z0))) = (rings.first(), profile.first())
        && !first.1
        && r0 > 1e-6
    {
        let centre = mesh.positions.len() as u32;
        mesh.positions.push(base + Vec3::Z * z0);
        mesh.triangles
            .extend((0..segments).map(|i| [centre, at(first, i + 1), at(first, i)]));
    }
    if let (Some(&last), Some(&(_, z1))) = (rings.last(), profile.last())
        && !last.1
        && rings.len() > 1
    {
        let centre = mesh.positions.len() as u32;
        mesh.positions.push(base + Vec3::Z * z1);
        mesh.triangles
            .extend((0..segments).map(|i| [centre, at(last, i), at(last, i + 1)]));
    }
    mesh
}

/// A vertical cylinder of radius `r` standing on `base`, `h` tall.
pub(crate) fn cylinder(base: Vec3, r: f32, h: f32) -> TriMesh {
    lathe(base, &[(r, 0.0), (r, h)], SEGMENTS)
}

/// An ellipsoid with centre `centre` and semi-axes `radii`.
pub(crate) fn ellipsoid(centre: Vec3, radii: Vec3) -> TriMesh {
    let rings = 8;
    let profile: Vec<(f32, f32)> = (0..=rings)
        .map(|k| {
            let phi = std::f32::consts::PI * k as f32 / rings as f32;
            (phi.sin(), -phi.cos())
        })
        .collect();
    let unit = lathe(Vec3::ZERO, &profile, SEGMENTS);
    unit.transformed(&Mat4::from_scale_rotation_translation(
        radii,
        Quat::IDENTITY,
        centre,
    ))
}

/// A round rod of radius `r` from `a` to `b`.
pub(crate) fn rod(a: Vec3, b: Vec3, r: f32) -> TriMesh {
    let d = b - a;
    let rotation = Quat::from_rotation_arc(Vec3::Z, d.normalize_or(Vec3::Z));
    cylinder(Vec3::ZERO, r, d.length()).transformed(&Mat4::from_rotation_translation(rotation, a))
}

/// The mesh with its vertices in order of first use by the triangles (unused ones dropped): the
/// order OBJ readers give back, so a mesh written and read again compares equal.
pub(crate) fn first_use_order(mesh: &TriMesh) -> TriMesh {
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    let mut positions = Vec::with_capacity(mesh.positions.len());
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                let slot = &mut remap[i as usize];
                if *slot == u32::MAX {
                    *slot = positions.len() as u32;
                    positions.push(mesh.positions[i as usize]);
                }
                *slot
            })
        })
        .collect();
    TriMesh {
        positions,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_use_order_keeps_the_shape() {
        let b = cuboid(Vec3::ZERO, Vec3::ONE);
        let c = first_use_order(&b);
        assert_eq!(c.positions.len(), 8);
        assert_eq!(c.triangles[0], [0, 1, 2]);
        for t in 0..b.triangles.len() {
            assert_eq!(b.triangle(t), c.triangle(t));
        }
    }

    #[test]
    fn primitives_are_closed_and_outward() {
        let b = cuboid(Vec3::new(1.0, 2.0, 3.0), Vec3::new(2.0, 4.0, 6.0));
        assert!((b.signed_volume() - 6.0).abs() < 1e-4);
        let c = cylinder(Vec3::new(3.0, -1.0, 0.5), 0.5, 2.0);
        let exact = std::f32::consts::PI * 0.25 * 2.0;
        assert!(c.signed_volume() > 0.9 * exact && c.signed_volume() < exact);
        let cone = lathe(Vec3::ZERO, &[(1.0, 0.0), (0.0, 3.0)], 32);
        assert!((cone.signed_volume() - std::f32::consts::PI).abs() < 0.05);
        let e = ellipsoid(Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 2.0, 0.5));
        let exact = 4.0 / 3.0 * std::f32::consts::PI;
        assert!(e.signed_volume() > 0.85 * exact && e.signed_volume() < exact);
        let r = rod(Vec3::new(0.0, 0.0, 1.0), Vec3::new(2.0, 0.0, 1.0), 0.1);
        assert!(r.signed_volume() > 0.0);
        assert!((r.aabb().size().x - 2.0).abs() < 1e-4);
    }
}
