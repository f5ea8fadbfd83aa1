//! Volume-uniform sampling (paper appendix B, policy 2).
//!
//! The budget, in positions of six cameras, is split over the rooms in proportion to their
//! volume (floor area × ceiling height). Inside each room, positions are drawn by Poisson-disk
//! dart throwing: the first radius is 0.8 · (V / k)^(1/3) for k positions in a free volume V,
//! shrunk by 0.8 whenever a round of 60 · k darts cannot place them all, so the result is spread
//! like a Poisson-disk set and still has exactly k points. The free volume keeps
//! [`VolumeParams::wall_margin`] from the outline, the floor and ceiling margins, and leaves out
//! every object's box (a camera inside a closed cabinet would see only its inside). Each
//! position gets the six views of [`TEMPLATE`], all turned by one shared random perturbation.

use crate::{PoseTag, ViewPose, apportion};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_core::{Error, Result};
use sage_scene::Scene;
use serde::{Deserialize, Serialize};

/// The canonical views at every position, (yaw, pitch) in degrees: the four horizontal
/// directions, one view up and one down on the diagonals between them.
pub const TEMPLATE: [(f32, f32); 6] = [
    (0.0, 0.0),
    (90.0, 0.0),
    (180.0, 0.0),
    (270.0, 0.0),
    (45.0, 40.0),
    (225.0, -40.0),
];

/// Dart-throwing rounds before a room gives up (the radius is then ~1e-4 of the first one, so
/// only an empty free volume gets here).
const MAX_ROUNDS: usize = 40;

/// The volume policy's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VolumeParams {
    /// Least distance of a position from the room outline, metres.
    pub wall_margin: f32,
    /// Least height above the floor, metres.
    pub floor_margin: f32,
    /// Least gap below the ceiling, metres.
    pub ceiling_margin: f32,
    /// The shared yaw perturbation is uniform in ±this, degrees.
    pub yaw_jitter_deg: f32,
    /// The shared pitch perturbation is uniform in ±this, degrees.
    pub pitch_jitter_deg: f32,
}

impl Default for VolumeParams {
    fn default() -> Self {
        VolumeParams {
            wall_margin: 0.3,
            floor_margin: 0.3,
            ceiling_margin: 0.3,
            yaw_jitter_deg: 10.0,
            pitch_jitter_deg: 5.0,
        }
    }
}

/// What the volume policy made.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeSamples {
    /// Positions asked of each room (its share of the budget).
    pub requested: Vec<usize>,
    /// Positions placed in each room (fewer only when its free volume is empty).
    pub placed: Vec<usize>,
    /// The poses, position by position, template view by template view.
    pub poses: Vec<ViewPose>,
}

/// Samples `budget` cameras (rounded down to whole positions of six) over the rooms of `scene`.
pub fn volume(
    scene: &Scene,
    budget: usize,
    seed: u64,
    params: &VolumeParams,
) -> Result<VolumeSamples> {
    let margins = [
        params.wall_margin,
        params.floor_margin,
        params.ceiling_margin,
        params.yaw_jitter_deg,
        params.pitch_jitter_deg,
    ];
    if margins.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
        return Err(Error::invalid("volume: margins and jitters must be >= 0"));
    }
    let height = scene.floorplan.ceiling_height();
    let rooms = &scene.floorplan.rooms;
    let volumes: Vec<f64> = rooms
        .iter()
        .map(|r| (r.profile.area() * height) as f64)
        .collect();
    let requested = apportion(budget / TEMPLATE.len(), &volumes);
    let (z_lo, z_hi) = (params.floor_margin, height - params.ceiling_margin);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut placed = Vec::with_capacity(rooms.len());
    let mut poses = Vec::with_capacity(budget);
    let mut position = 0;
    for (room, (r, &k)) in rooms.iter().zip(&requested).enumerate() {
        let free = |p: Vec3| {
            r.profile.contains(p.truncate())
                && r.profile.distance_to_boundary(p.truncate()) >= params.wall_margin
                && !scene.objects.iter().any(|o| o.obb.contains(p, 0.0))
        };
        let (lo, hi) = r.profile.bounds();
        let points = poisson_disk(
            &mut rng,
            k,
            lo.extend(z_lo),
            hi.extend(z_hi),
            r.profile.area() * (z_hi - z_lo).max(0.0),
            free,
        );
        placed.push(points.len());
        for p in points {
            let dyaw = (rng.random::<f32>() * 2.0 - 1.0) * params.yaw_jitter_deg;
            let dpitch = (rng.random::<f32>() * 2.0 - 1.0) * params.pitch_jitter_deg;
            for (view, (yaw, pitch)) in TEMPLATE.iter().enumerate() {
                poses.push(ViewPose {
                    position: p,
                    yaw: sage_core::wrap_angle((yaw + dyaw).to_radians()),
                    pitch: (pitch + dpitch).to_radians(),
                    room,
                    tag: PoseTag::Volume { position, view },
                });
            }
            position += 1;
        }
    }
    Ok(VolumeSamples {
        requested,
        placed,
        poses,
    })
}

/// `k` points of the box `[lo, hi]` where `free` holds, pairwise at least a radius apart that
/// starts from the volume per point and shrinks until all fit (see the module docs).
fn poisson_disk(
    rng: &mut ChaCha8Rng,
    k: usize,
    lo: Vec3,
    hi: Vec3,
    volume: f32,
    free: impl Fn(Vec3) -> bool,
) -> Vec<Vec3> {
    let mut points: Vec<Vec3> = Vec::with_capacity(k);
    if k == 0 || hi.cmplt(lo).any() {
        return points;
    }
    let mut radius = 0.8 * (volume.max(1e-6) / k as f32).cbrt();
    for _ in 0..MAX_ROUNDS {
        for _ in 0..60 * k {
            if points.len() == k {
                return points;
            }
            let u = Vec3::new(rng.random(), rng.random(), rng.random());
            let p = lo + (hi - lo) * u;
            if free(p)
                && points
                    .iter()
                    .all(|q| q.distance_squared(p) >= radius * radius)
            {
                points.push(p);
            }
        }
        radius *= 0.8;
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// Unit forward vector of template view `view` at zero perturbation.
    fn template_forward(view: usize) -> Vec3 {
        let (yaw, pitch) = TEMPLATE[view];
        let (y, p) = (yaw.to_radians(), pitch.to_radians());
        Vec2::new(y.cos(), y.sin()).extend(0.0) * p.cos() + Vec3::Z * p.sin()
    }

    #[test]
    fn template_covers_all_four_sides_and_up_and_down() {
        let f: Vec<Vec3> = (0..6).map(template_forward).collect();
        for axis in [Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y] {
            assert!(f.iter().any(|v| v.dot(axis) > 0.99));
        }
        assert!(f.iter().any(|v| v.z > 0.5) && f.iter().any(|v| v.z < -0.5));
    }

    #[test]
    fn poisson_points_are_free_and_spread() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let free = |p: Vec3| p.x < 2.0 || p.y < 1.0;
        let pts = poisson_disk(
            &mut rng,
            40,
            Vec3::ZERO,
            Vec3::new(4.0, 3.0, 2.0),
            20.0,
            free,
        );
        assert_eq!(pts.len(), 40);
        assert!(pts.iter().all(|p| free(*p)));
        let min_gap = pts
            .iter()
            .enumerate()
            .flat_map(|(i, p)| pts[i + 1..].iter().map(move |q| p.distance(*q)))
            .fold(f32::INFINITY, f32::min);
        // Far better spread than 40 uniform points, whose closest pair is ~0.1 m apart.
        assert!(min_gap > 0.4, "{min_gap}");
    }
}
