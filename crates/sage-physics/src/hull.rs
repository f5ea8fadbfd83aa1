//! Convex parts: the pieces a collision body is made of, and their volumes.

use glam::Vec3;
use sage_scene::TriMesh;

/// One convex piece of a collision body: a closed triangle mesh (its convex hull), metres, W frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexPart {
    /// Hull vertices.
    pub vertices: Vec<Vec3>,
    /// Hull triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

impl ConvexPart {
    /// The convex hull of `points` (parry's quickhull); `None` when they span no volume.
    pub fn hull_of(points: &[Vec3]) -> Option<ConvexPart> {
        let (vertices, triangles) = parry3d::transformation::try_convex_hull(points).ok()?;
        let part = ConvexPart {
            vertices,
            triangles,
        };
        (part.volume() > 1e-12).then_some(part)
    }

    /// The eight corners of an oriented box as a part.
    pub fn from_obb(obb: &sage_core::Obb) -> Option<ConvexPart> {
        ConvexPart::hull_of(&obb.corners())
    }

    /// Enclosed volume, m³ (the absolute signed volume of the closed hull).
    pub fn volume(&self) -> f32 {
        self.as_mesh().signed_volume().abs()
    }

    /// The part as a triangle mesh (for volumes and export).
    pub fn as_mesh(&self) -> TriMesh {
        TriMesh {
            positions: self.vertices.clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// The part moved by `offset`.
    pub fn translated(&self, offset: Vec3) -> ConvexPart {
        ConvexPart {
            vertices: self.vertices.iter().map(|v| *v + offset).collect(),
            triangles: self.triangles.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_core::Obb;

    #[test]
    fn box_part_has_the_box_volume() {
        let obb = Obb {
            center: Vec3::new(1.0, 2.0, 0.5),
            half_extents: Vec3::new(0.5, 0.25, 0.5),
            yaw: 0.7,
        };
        let part = ConvexPart::from_obb(&obb).unwrap();
        assert!((part.volume() - obb.volume()).abs() < 1e-5);
        assert_eq!(part.vertices.len(), 8);
    }

    #[test]
    fn flat_points_give_no_part() {
        let pts = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        assert!(ConvexPart::hull_of(&pts).is_none());
    }
}
