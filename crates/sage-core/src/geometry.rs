//! Plain geometry: axis-aligned boxes, yaw-oriented boxes (the InteriorGS `bounding_box`) and
//! simple polygons on the floor plane.

use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// The largest coordinate magnitude sage3d accepts from a file or a caller, metres: far beyond
/// any indoor scene, small enough that f32 keeps millimetres there and that work that grows
/// with a scene's extent (grids, maps, paths, shape casts) stays bounded. A number too large
/// for f32 reads as infinity, which the bound refuses too.
pub const MAX_COORDINATE: f32 = 1.0e4;

/// Whether every coordinate of `p` is finite and within ±[`MAX_COORDINATE`].
pub fn within_bounds(p: Vec3) -> bool {
    // Written out rather than with `max_element`: a NaN must fail the comparison, not be
    // skipped by `f32::max`.
    p.to_array().iter().all(|c| c.abs() <= MAX_COORDINATE)
}

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (grows from nothing with [`Aabb::grow`]).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    /// The smallest box holding all `points` ([`Aabb::EMPTY`] when there are none).
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(p))
    }

    /// This box grown to hold `p`.
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The union of two boxes.
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when no point was ever added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    /// Edge lengths (zero for the empty box).
    pub fn size(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// True when `p` lies inside or on the boundary.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// A box rotated about the vertical axis only: the shape of an InteriorGS `bounding_box`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Obb {
    /// Centre in metres.
    pub center: Vec3,
    /// Half the edge lengths along the box's own x (at `yaw`), y and z axes.
    pub half_extents: Vec3,
    /// Rotation of the box's x axis about +Z, radians.
    pub yaw: f32,
}

impl Obb {
    /// The box's own x and y axes on the floor plane.
    pub fn axes(&self) -> (Vec2, Vec2) {
        let (s, c) = self.yaw.sin_cos();
        (Vec2::new(c, s), Vec2::new(-s, c))
    }

    /// The 8 corners in InteriorGS order: 0–3 the bottom face counter-clockwise, 4–7 the top face
    /// above 0–3.
    pub fn corners(&self) -> [Vec3; 8] {
        let f = self.footprint();
        let (lo, hi) = (self.min_z(), self.max_z());
        std::array::from_fn(|i| {
            let p = f[i % 4];
            Vec3::new(p.x, p.y, if i < 4 { lo } else { hi })
        })
    }

    /// The footprint rectangle, counter-clockwise.
    pub fn footprint(&self) -> [Vec2; 4] {
        let (ax, ay) = self.axes();
        let c = self.center.truncate();
        let (hx, hy) = (ax * self.half_extents.x, ay * self.half_extents.y);
        [c - hx - hy, c + hx - hy, c + hx + hy, c - hx + hy]
    }

    /// Bottom of the box.
    pub fn min_z(&self) -> f32 {
        self.center.z - self.half_extents.z
    }

    /// Top of the box.
    pub fn max_z(&self) -> f32 {
        self.center.z + self.half_extents.z
    }

    /// Volume in m³.
    pub fn volume(&self) -> f32 {
        8.0 * self.half_extents.x * self.half_extents.y * self.half_extents.z
    }

    /// The axis-aligned box around this one.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points(self.corners())
    }

    /// `p` in the box's own frame (origin at the centre, axes x, y, z).
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        let (ax, ay) = self.axes();
        let d = p - self.center;
        Vec3::new(d.truncate().dot(ax), d.truncate().dot(ay), d.z)
    }

    /// True when `p` lies inside the box grown by `margin` on every side.
    pub fn contains(&self, p: Vec3, margin: f32) -> bool {
        let l = self.to_local(p).abs();
        l.cmple(self.half_extents + Vec3::splat(margin)).all()
    }

    /// True when the boxes overlap: their height ranges share more than 0.1 mm and their
    /// footprints come closer than `gap` (separating-axis test). A negative `gap` asks for a
    /// penetration deeper than `-gap`.
    pub fn overlaps(&self, other: &Obb, gap: f32) -> bool {
        if self.min_z() >= other.max_z() - 1e-4 || other.min_z() >= self.max_z() - 1e-4 {
            return false;
        }
        let d = (other.center - self.center).truncate();
        let (ax, ay) = self.axes();
        let (bx, by) = other.axes();
        [ax, ay, bx, by].iter().all(|&n| {
            let ra = self.half_extents.x * ax.dot(n).abs() + self.half_extents.y * ay.dot(n).abs();
            let rb =
                other.half_extents.x * bx.dot(n).abs() + other.half_extents.y * by.dot(n).abs();
            d.dot(n).abs() < ra + rb + gap
        })
    }

    /// Reads a box from its 8 corners (InteriorGS `bounding_box`).
    ///
    /// Corners 0–3 must form one horizontal face in cyclic order and corners 4–7 the other face
    /// over the same footprint; the face may be given in either winding. `tolerance` (metres)
    /// absorbs rounding in the file.
    pub fn from_corners(corners: &[Vec3], tolerance: f32) -> Result<Obb> {
        if corners.len() != 8 {
            return Err(Error::format(
                "bounding_box",
                format!("expected 8 corners, found {}", corners.len()),
            ));
        }
        if let Some(i) = corners.iter().position(|c| !c.is_finite()) {
            return Err(Error::format(
                format!("bounding_box[{i}]"),
                "corner is not finite",
            ));
        }
        let face: [Vec3; 4] = [corners[0], corners[1], corners[2], corners[3]];
        let z0 = face[0].z;
        if let Some(i) = face.iter().position(|c| (c.z - z0).abs() > tolerance) {
            return Err(Error::format(
                format!("bounding_box[{i}]"),
                "corners 0-3 must form one horizontal face (their z differ)",
            ));
        }
        let e0 = (face[1] - face[0]).truncate();
        let e1 = (face[2] - face[1]).truncate();
        let closes = face[0].truncate() + e1 - face[3].truncate();
        if closes.length() > tolerance * 2.0
            || e0.dot(e1).abs() > tolerance * (e0.length() + e1.length()).max(1.0)
        {
            return Err(Error::format(
                "bounding_box",
                "corners 0-3 are not a rectangle in cyclic order",
            ));
        }
        let z_min = corners.iter().map(|c| c.z).fold(f32::INFINITY, f32::min);
        let z_max = corners
            .iter()
            .map(|c| c.z)
            .fold(f32::NEG_INFINITY, f32::max);
        for (i, c) in corners.iter().enumerate().skip(4) {
            let on_footprint = face
                .iter()
                .any(|f| (f.truncate() - c.truncate()).length() <= tolerance * 2.0);
            if !on_footprint {
                return Err(Error::format(
                    format!("bounding_box[{i}]"),
                    "corner does not lie above or below the face of corners 0-3 (only yaw-rotated boxes are supported)",
                ));
            }
        }
        // A degenerate first edge (a flat or zero-width box) takes its direction from the second.
        let yaw = if e0.length() > 1e-6 {
            e0.y.atan2(e0.x)
        } else if e1.length() > 1e-6 {
            e1.y.atan2(e1.x) - std::f32::consts::FRAC_PI_2
        } else {
            0.0
        };
        let centre2 = face.iter().map(|c| c.truncate()).sum::<Vec2>() / 4.0;
        Ok(Obb {
            center: Vec3::new(centre2.x, centre2.y, 0.5 * (z_min + z_max)),
            half_extents: Vec3::new(0.5 * e0.length(), 0.5 * e1.length(), 0.5 * (z_max - z_min)),
            yaw: crate::wrap_angle(yaw),
        })
    }
}

/// A simple polygon on the floor plane (no self-intersections), in metres.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Polygon2 {
    /// Vertices in order; the closing edge back to the first is implied.
    pub points: Vec<Vec2>,
}

impl Polygon2 {
    /// A polygon through `points`.
    pub fn new(points: Vec<Vec2>) -> Self {
        Polygon2 { points }
    }

    /// Signed area (positive when counter-clockwise).
    pub fn signed_area(&self) -> f32 {
        self.edges().map(|(a, b)| a.perp_dot(b)).sum::<f32>() * 0.5
    }

    /// Area in m².
    pub fn area(&self) -> f32 {
        self.signed_area().abs()
    }

    /// The edges as `(start, end)` pairs, including the closing edge.
    pub fn edges(&self) -> impl Iterator<Item = (Vec2, Vec2)> + '_ {
        let n = self.points.len();
        (0..n).map(move |i| (self.points[i], self.points[(i + 1) % n]))
    }

    /// True when `p` lies inside (even-odd rule; points on an edge may go either way).
    pub fn contains(&self, p: Vec2) -> bool {
        let mut inside = false;
        for (a, b) in self.edges() {
            if (a.y > p.y) != (b.y > p.y) {
                let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
                if p.x < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Distance from `p` to the nearest edge (0 on the outline).
    pub fn distance_to_boundary(&self, p: Vec2) -> f32 {
        self.nearest_boundary_point(p)
            .map_or(f32::INFINITY, |q| p.distance(q))
    }

    /// The point of the outline nearest to `p` (`None` for a polygon without vertices).
    pub fn nearest_boundary_point(&self, p: Vec2) -> Option<Vec2> {
        self.edges()
            .map(|(a, b)| {
                let ab = b - a;
                let t = if ab.length_squared() > 0.0 {
                    ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                a + ab * t
            })
            .min_by(|q, r| p.distance_squared(*q).total_cmp(&p.distance_squared(*r)))
    }

    /// The area centroid (the vertex mean for degenerate polygons).
    pub fn centroid(&self) -> Vec2 {
        let a = self.signed_area();
        if a.abs() < 1e-9 {
            return self.points.iter().copied().sum::<Vec2>() / self.points.len().max(1) as f32;
        }
        let c: Vec2 = self.edges().map(|(p, q)| (p + q) * p.perp_dot(q)).sum();
        c / (6.0 * a)
    }

    /// Lower and upper corners of the bounding rectangle.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let lo = self.points.iter().fold(Vec2::INFINITY, |m, p| m.min(*p));
        let hi = self
            .points
            .iter()
            .fold(Vec2::NEG_INFINITY, |m, p| m.max(*p));
        (lo, hi)
    }
}

/// Points every `step` metres along the polyline from its first point, plus its last point.
pub fn resample_polyline(points: &[Vec2], step: f32) -> Vec<Vec2> {
    let Some(&first) = points.first() else {
        return Vec::new();
    };
    let mut out = vec![first];
    let mut carried = 0.0f32;
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = a.distance(b);
        if len <= 0.0 {
            continue;
        }
        let mut t = step - carried;
        while t < len - 1e-4 {
            out.push(a + (b - a) * (t / len));
            t += step;
        }
        carried = len - (t - step);
    }
    let last = *points.last().unwrap_or(&first);
    if out.last().is_none_or(|p| p.distance(last) > 1e-4) {
        out.push(last);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn points_beyond_the_bound_or_not_finite_are_out_of_bounds() {
        assert!(within_bounds(Vec3::new(
            MAX_COORDINATE,
            -MAX_COORDINATE,
            0.0
        )));
        for bad in [1.0001e4, 1e30, f32::INFINITY, f32::NAN, -f32::INFINITY] {
            for axis in 0..3 {
                let mut p = [0.0; 3];
                p[axis] = bad;
                assert!(!within_bounds(Vec3::from_array(p)), "{p:?}");
            }
        }
    }

    proptest! {
        #[test]
        fn obb_corner_round_trip(
            cx in -20.0f32..20.0, cy in -20.0f32..20.0, cz in 0.0f32..3.0,
            hx in 0.01f32..3.0, hy in 0.01f32..3.0, hz in 0.0f32..2.0,
            yaw in -3.1f32..3.1,
        ) {
            let b = Obb { center: Vec3::new(cx, cy, cz), half_extents: Vec3::new(hx, hy, hz), yaw };
            let r = Obb::from_corners(&b.corners(), 1e-3).unwrap();
            prop_assert!((r.center - b.center).length() < 1e-3);
            prop_assert!((r.half_extents - b.half_extents).abs().max_element() < 1e-3);
            for (p, q) in r.corners().iter().zip(b.corners().iter()) {
                prop_assert!((*p - *q).length() < 2e-3);
            }
        }

        #[test]
        fn obb_contains_its_centre_and_not_far_points(yaw in -3.1f32..3.1, hx in 0.1f32..2.0) {
            let b = Obb { center: Vec3::new(1.0, 2.0, 0.5), half_extents: Vec3::new(hx, 0.3, 0.5), yaw };
            prop_assert!(b.contains(b.center, 0.0));
            prop_assert!(!b.contains(b.center + Vec3::new(0.0, 0.0, 0.6), 0.0));
            for c in b.corners() {
                prop_assert!(b.contains(c, 1e-4));
            }
        }
    }

    #[test]
    fn overlap_respects_gap_height_and_rotation() {
        let a = Obb {
            center: Vec3::new(0.0, 0.0, 0.5),
            half_extents: Vec3::new(1.0, 0.5, 0.5),
            yaw: 0.0,
        };
        let b = Obb {
            center: Vec3::new(2.1, 0.0, 0.5),
            ..a
        };
        assert!(!a.overlaps(&b, 0.0));
        assert!(a.overlaps(&b, 0.2));
        let above = Obb {
            center: Vec3::new(0.0, 0.0, 1.5),
            ..a
        };
        assert!(
            !a.overlaps(&above, 0.5),
            "stacked boxes touch, they do not overlap"
        );
        // Rotated 45°, the corner of b reaches into a only when close enough.
        let r = Obb {
            center: Vec3::new(1.6, 0.0, 0.5),
            half_extents: Vec3::new(0.5, 0.5, 0.5),
            yaw: std::f32::consts::FRAC_PI_4,
        };
        assert!(a.overlaps(&r, 0.0));
        let r = Obb {
            center: Vec3::new(1.8, 0.0, 0.5),
            ..r
        };
        assert!(!a.overlaps(&r, 0.0));
    }

    #[test]
    fn seven_corners_is_an_error() {
        let b = Obb {
            center: Vec3::ZERO,
            half_extents: Vec3::ONE,
            yaw: 0.0,
        };
        let e = Obb::from_corners(&b.corners()[..7], 1e-3).unwrap_err();
        assert!(e.to_string().contains("expected 8 corners, found 7"));
    }

    #[test]
    fn tilted_face_is_an_error() {
        let b = Obb {
            center: Vec3::ZERO,
            half_extents: Vec3::ONE,
            yaw: 0.0,
        };
        let mut c = b.corners();
        c[2].z += 0.5;
        assert!(Obb::from_corners(&c, 1e-3).is_err());
    }

    #[test]
    fn square_polygon() {
        let p = Polygon2::new(vec![
            Vec2::ZERO,
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(0.0, 2.0),
        ]);
        assert_eq!(p.area(), 4.0);
        assert!(p.signed_area() > 0.0);
        assert!(p.contains(Vec2::new(1.0, 1.0)));
        assert!(!p.contains(Vec2::new(3.0, 1.0)));
        assert!((p.centroid() - Vec2::ONE).length() < 1e-6);
        assert!((p.distance_to_boundary(Vec2::new(1.0, 0.5)) - 0.5).abs() < 1e-6);
        assert!((p.distance_to_boundary(Vec2::new(3.0, 1.0)) - 1.0).abs() < 1e-6);
    }
}
