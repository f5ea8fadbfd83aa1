//! The perimeter-aware floorplan sweep ("surround", paper appendix B, policy 1).
//!
//! Per room polygon, `m` inward-offset polygons ("rings") at the distances of
//! [`SweepParams::offsets`]. The budget, in placements of nine cameras, is split over all rings
//! of all rooms in proportion to their perimeters; along a ring the placements are evenly spaced
//! (the seed sets where the first one falls), each looking along the inward normal of its edge.
//! Every placement holds three tangential baselines (left / centre / right, shifted along the
//! edge by [`SweepParams::baseline`]) times three vertical tiers:
//!
//! | tier | outer ring (j = 0) | inner ring j (of m) |
//! |---|---|---|
//! | low | 150 mm above the floor, pitch +30° | height lerp(low, mid, j/m), pitch +15° |
//! | mid | half the ceiling height, pitch 0° | the same |
//! | high | 500 mm below the ceiling, pitch −30° | height lerp(high, mid, j/m), pitch −15° |

use crate::{PoseTag, ViewPose, apportion};
use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Polygon2, Result};
use sage_scene::Floorplan;
use serde::{Deserialize, Serialize};

/// Cameras at one placement: three baselines × three tiers.
pub const CAMERAS_PER_PLACEMENT: usize = 9;

/// A vertical tier of the sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Tier {
    /// Near the floor, looking up.
    Low,
    /// At mid-height, level.
    Mid,
    /// Under the ceiling, looking down.
    High,
}

/// A tangential baseline of the sweep (seen from the camera, facing into the room).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Baseline {
    /// Shifted to the camera's left.
    Left,
    /// On the ring.
    Centre,
    /// Shifted to the camera's right.
    Right,
}

impl Tier {
    /// All tiers, low to high.
    pub const ALL: [Tier; 3] = [Tier::Low, Tier::Mid, Tier::High];

    /// The word used in files.
    pub fn as_str(self) -> &'static str {
        match self {
            Tier::Low => "low",
            Tier::Mid => "mid",
            Tier::High => "high",
        }
    }
}

impl Baseline {
    /// All baselines, left to right.
    pub const ALL: [Baseline; 3] = [Baseline::Left, Baseline::Centre, Baseline::Right];

    /// The word used in files.
    pub fn as_str(self) -> &'static str {
        match self {
            Baseline::Left => "left",
            Baseline::Centre => "centre",
            Baseline::Right => "right",
        }
    }

    /// Signed multiple of the baseline along the camera's right axis.
    pub fn sign(self) -> f32 {
        match self {
            Baseline::Left => -1.0,
            Baseline::Centre => 0.0,
            Baseline::Right => 1.0,
        }
    }
}

/// The sweep's settings (the paper fixes the tiers; the schedule and baseline are ours).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepParams {
    /// Inward offsets of the rings from the room outline, metres, outermost first.
    pub offsets: Vec<f32>,
    /// Tangential shift of the left and right baselines, metres.
    pub baseline: f32,
    /// Height of the outer low tier above the floor, metres.
    pub low_height: f32,
    /// Gap from the outer high tier to the ceiling, metres.
    pub high_gap: f32,
    /// Pitch of the outer low and high tiers, degrees (up for low, down for high).
    pub outer_pitch_deg: f32,
    /// Pitch of the inner low and high tiers, degrees.
    pub inner_pitch_deg: f32,
}

impl Default for SweepParams {
    fn default() -> Self {
        SweepParams {
            offsets: vec![0.4, 0.9, 1.4],
            baseline: 0.2,
            low_height: 0.15,
            high_gap: 0.5,
            outer_pitch_deg: 30.0,
            inner_pitch_deg: 15.0,
        }
    }
}

impl SweepParams {
    /// Checks the schedule and distances.
    pub fn validate(&self) -> Result<()> {
        if self.offsets.is_empty()
            || self.offsets.iter().any(|d| !(d.is_finite() && *d > 0.0))
            || self.offsets.windows(2).any(|w| w[1] <= w[0])
        {
            return Err(Error::invalid(format!(
                "sweep: `offsets` must be positive, increasing, and at least one, got {:?}",
                self.offsets
            )));
        }
        if !(self.baseline.is_finite() && self.baseline >= 0.0) {
            return Err(Error::invalid(format!(
                "sweep: `baseline` must be >= 0 m, got {}",
                self.baseline
            )));
        }
        Ok(())
    }

    /// Height and pitch (radians) of `tier` on ring `ring`, under a ceiling at `height`.
    pub fn tier_pose(&self, tier: Tier, ring: usize, height: f32) -> (f32, f32) {
        let mid = 0.5 * height;
        let t = ring as f32 / self.offsets.len() as f32;
        let pitch = if ring == 0 {
            self.outer_pitch_deg
        } else {
            self.inner_pitch_deg
        }
        .to_radians();
        match tier {
            Tier::Low => (self.low_height + (mid - self.low_height) * t, pitch),
            Tier::Mid => (mid, 0.0),
            Tier::High => {
                let high = height - self.high_gap;
                (high + (mid - high) * t, -pitch)
            }
        }
    }
}

/// One offset polygon of a room.
#[derive(Debug, Clone, PartialEq)]
pub struct Ring {
    /// Room index in the floorplan.
    pub room: usize,
    /// Index in the schedule, 0 the outermost.
    pub ring: usize,
    /// The polygon, counter-clockwise.
    pub polygon: Polygon2,
    /// Placements along it.
    pub placements: usize,
}

/// What the sweep made.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// Every ring that exists (rings that collapse in narrow rooms are left out).
    pub rings: Vec<Ring>,
    /// The poses, ring by ring, placement by placement, tier by tier, baseline by baseline.
    pub poses: Vec<ViewPose>,
}

/// `poly` offset inwards by `d` (counter-clockwise result), or `None` when the room is too
/// narrow for it: an edge would flip or vanish, or a vertex would come nearer than `d` to the
/// outline.
pub fn inset(poly: &Polygon2, d: f32) -> Option<Polygon2> {
    let mut pts = poly.points.clone();
    pts.dedup_by(|a, b| a.distance(*b) < 1e-6);
    if pts.len() > 1 && pts[0].distance(pts[pts.len() - 1]) < 1e-6 {
        pts.pop();
    }
    if pts.len() < 3 {
        return None;
    }
    let ccw = Polygon2::new(pts);
    let ccw = if ccw.signed_area() < 0.0 {
        Polygon2::new(ccw.points.iter().rev().copied().collect())
    } else {
        ccw
    };
    let n = ccw.points.len();
    let edge = |i: usize| (ccw.points[i], ccw.points[(i + 1) % n]);
    let inward = |i: usize| {
        let (a, b) = edge(i);
        (b - a).normalize_or_zero().perp()
    };
    let out: Vec<Vec2> = (0..n)
        .map(|i| {
            let prev = (i + n - 1) % n;
            let (pa, pb) = edge(prev);
            let (ca, cb) = edge(i);
            let (np, nc) = (inward(prev), inward(i));
            let (p0, dp) = (pa + np * d, pb - pa);
            let (c0, dc) = (ca + nc * d, cb - ca);
            let denom = dp.perp_dot(dc);
            if denom.abs() < 1e-9 * dp.length() * dc.length() {
                // Collinear neighbours: the vertex moves straight in.
                ccw.points[i] + nc * d
            } else {
                let s = (c0 - p0).perp_dot(dc) / denom;
                p0 + dp * s
            }
        })
        .collect();
    let result = Polygon2::new(out);
    let flipped = (0..n).any(|i| {
        let (a, b) = edge(i);
        let (c, e) = (result.points[i], result.points[(i + 1) % n]);
        (e - c).dot(b - a) <= 1e-6
    });
    let too_near = result
        .points
        .iter()
        .any(|p| !ccw.contains(*p) || ccw.distance_to_boundary(*p) < d - 1e-3);
    (!flipped && !too_near && result.signed_area() > 1e-4).then_some(result)
}

/// The point at arc length `s` along the closed polygon and the inward normal of its edge.
fn along(poly: &Polygon2, s: f32) -> (Vec2, Vec2) {
    let mut left = s;
    let n = poly.points.len();
    for (i, (a, b)) in poly.edges().enumerate() {
        let len = a.distance(b);
        if left <= len || i == n - 1 {
            let dir = (b - a).normalize_or_zero();
            return (a + dir * left.min(len), dir.perp());
        }
        left -= len;
    }
    (Vec2::ZERO, Vec2::X)
}

/// Runs the sweep over every room of `floorplan` with `budget` cameras (rounded down to whole
/// placements of [`CAMERAS_PER_PLACEMENT`]); the seed sets the phase of the placements along
/// each ring.
pub fn sweep(
    floorplan: &Floorplan,
    budget: usize,
    seed: u64,
    params: &SweepParams,
) -> Result<Sweep> {
    params.validate()?;
    let height = floorplan.ceiling_height();
    let mut rings: Vec<Ring> = floorplan
        .rooms
        .iter()
        .enumerate()
        .flat_map(|(room, r)| {
            params
                .offsets
                .iter()
                .enumerate()
                .filter_map(move |(ring, &d)| {
                    inset(&r.profile, d).map(|polygon| Ring {
                        room,
                        ring,
                        polygon,
                        placements: 0,
                    })
                })
        })
        .collect();
    let perimeters: Vec<f64> = rings.iter().map(|r| perimeter(&r.polygon) as f64).collect();
    let shares = apportion(budget / CAMERAS_PER_PLACEMENT, &perimeters);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut poses = Vec::with_capacity(budget);
    for (r, share) in rings.iter_mut().zip(shares) {
        r.placements = share;
        let phase: f32 = rng.random();
        let length = perimeter(&r.polygon);
        for k in 0..share {
            let (p, normal) = along(&r.polygon, (k as f32 + phase) / share as f32 * length);
            let yaw = normal.y.atan2(normal.x);
            // The camera's right axis for heading ψ is (sin ψ, −cos ψ).
            let right = Vec2::new(yaw.sin(), -yaw.cos());
            for tier in Tier::ALL {
                let (z, pitch) = params.tier_pose(tier, r.ring, height);
                for baseline in Baseline::ALL {
                    let q = p + right * (baseline.sign() * params.baseline);
                    poses.push(ViewPose {
                        position: Vec3::new(q.x, q.y, z),
                        yaw,
                        pitch,
                        room: r.room,
                        tag: PoseTag::Sweep {
                            ring: r.ring,
                            tier,
                            baseline,
                        },
                    });
                }
            }
        }
    }
    Ok(Sweep { rings, poses })
}

/// Length of the closed outline.
pub fn perimeter(p: &Polygon2) -> f32 {
    p.edges().map(|(a, b)| a.distance(b)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(w: f32, h: f32) -> Polygon2 {
        Polygon2::new(vec![
            Vec2::ZERO,
            Vec2::new(w, 0.0),
            Vec2::new(w, h),
            Vec2::new(0.0, h),
        ])
    }

    #[test]
    fn inset_of_a_rectangle_and_an_l_shape() {
        let r = inset(&rect(4.0, 3.0), 0.5).unwrap();
        assert!((r.area() - 3.0 * 2.0).abs() < 1e-4);
        assert!((perimeter(&r) - 10.0).abs() < 1e-4);
        assert!(inset(&rect(4.0, 3.0), 1.6).is_none(), "collapses");
        // Clockwise input comes back counter-clockwise.
        let cw = Polygon2::new(rect(4.0, 3.0).points.into_iter().rev().collect());
        assert!(inset(&cw, 0.5).unwrap().signed_area() > 0.0);
        let l = Polygon2::new(vec![
            Vec2::ZERO,
            Vec2::new(4.0, 0.0),
            Vec2::new(4.0, 2.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(2.0, 4.0),
            Vec2::new(0.0, 4.0),
        ]);
        let li = inset(&l, 0.5).unwrap();
        // Convex corners sit 0.5 from the outline, the reflex one farther (√2 · 0.5).
        assert!((li.area() - 5.0).abs() < 1e-4);
        for p in &li.points {
            assert!(l.distance_to_boundary(*p) > 0.5 - 1e-4, "{p}");
        }
    }

    #[test]
    fn placements_face_inwards_along_the_ring() {
        let poly = rect(4.0, 3.0);
        for s in [0.3f32, 4.5, 7.2, 12.9] {
            let (p, n) = along(&poly, s);
            assert!(poly.distance_to_boundary(p) < 1e-5);
            assert!(poly.contains(p + n * 0.1), "{s}: {p} {n}");
        }
    }
}
