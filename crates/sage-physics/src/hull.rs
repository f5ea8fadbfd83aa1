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

    /// True when `p` lies inside the part (or within `1e-5` m of its surface).
    pub fn contains(&self, p: Vec3) -> bool {
        let centroid = self.vertices.iter().copied().sum::<Vec3>() / self.vertices.len() as f32;
        self.triangles.iter().all(|t| {
            let [a, b, c] = t.map(|i| self.vertices[i as usize]);
            let n = (b - a).cross(c - a);
            // Orient each face away from the centroid, whatever the hull's winding.
            let n = if n.dot(a - centroid) < 0.0 { -n } else { n };
            n.dot(p - a) <= 1e-5 * n.length()
        })
    }

    /// The part moved by `offset`.
    pub fn translated(&self, offset: Vec3) -> ConvexPart {
        ConvexPart {
            vertices: self.vertices.iter().map(|v| *v + offset).collect(),
            triangles: self.triangles.clone(),
        }
    }
}

/// Volume intersection over union of two sets of parts (each the union of its parts), sampled
/// at the centres of a `cell`-sized grid over their joint bounds; 1 when both are empty.
pub fn volume_iou(a: &[ConvexPart], b: &[ConvexPart], cell: f32) -> f32 {
    let bounds =
        sage_core::Aabb::from_points(a.iter().chain(b).flat_map(|p| p.vertices.iter().copied()));
    if bounds.is_empty() {
        return 1.0;
    }
    let (sa, sb) = (Solid::of(a), Solid::of(b));
    let n = ((bounds.max - bounds.min) / cell).ceil().max(Vec3::ONE);
    let (mut both, mut either) = (0u64, 0u64);
    for z in 0..n.z as usize {
        for y in 0..n.y as usize {
            for x in 0..n.x as usize {
                let p = bounds.min + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                let (ia, ib) = (sa.contains(p), sb.contains(p));
                both += u64::from(ia && ib);
                either += u64::from(ia || ib);
            }
        }
    }
    if either == 0 {
        1.0
    } else {
        both as f32 / either as f32
    }
}

/// A union of convex parts as bounds and outward face planes, for many inside tests.
struct Solid {
    parts: Vec<(sage_core::Aabb, Vec<(Vec3, f32)>)>,
}

impl Solid {
    fn of(parts: &[ConvexPart]) -> Solid {
        let parts = parts
            .iter()
            .map(|q| {
                let centroid = q.vertices.iter().copied().sum::<Vec3>() / q.vertices.len() as f32;
                let planes = q
                    .triangles
                    .iter()
                    .map(|t| {
                        let [a, b, c] = t.map(|i| q.vertices[i as usize]);
                        let n = (b - a).cross(c - a).normalize_or_zero();
                        let n = if n.dot(a - centroid) < 0.0 { -n } else { n };
                        (n, n.dot(a))
                    })
                    .collect();
                (
                    sage_core::Aabb::from_points(q.vertices.iter().copied()),
                    planes,
                )
            })
            .collect();
        Solid { parts }
    }

    fn contains(&self, p: Vec3) -> bool {
        self.parts
            .iter()
            .any(|(bb, planes)| bb.contains(p) && planes.iter().all(|(n, d)| n.dot(p) <= d + 1e-5))
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
    fn iou_of_overlapping_boxes() {
        let a = Obb {
            center: Vec3::new(0.5, 0.5, 0.5),
            half_extents: Vec3::splat(0.5),
            yaw: 0.0,
        };
        let b = Obb {
            center: Vec3::new(1.0, 0.5, 0.5),
            ..a
        };
        let (pa, pb) = (
            ConvexPart::from_obb(&a).unwrap(),
            ConvexPart::from_obb(&b).unwrap(),
        );
        assert!(pa.contains(Vec3::splat(0.5)) && !pa.contains(Vec3::new(1.2, 0.5, 0.5)));
        // Overlap 0.5 of each unit cube: IoU = 0.5 / 1.5.
        let iou = volume_iou(std::slice::from_ref(&pa), &[pb], 0.02);
        assert!((iou - 1.0 / 3.0).abs() < 0.02, "{iou}");
        assert!(
            (volume_iou(std::slice::from_ref(&pa), std::slice::from_ref(&pa), 0.05) - 1.0).abs()
                < 1e-6
        );
    }

    #[test]
    fn flat_points_give_no_part() {
        let pts = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        assert!(ConvexPart::hull_of(&pts).is_none());
    }
}
