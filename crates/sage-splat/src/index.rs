//! The spatial index that makes large scenes cheap: consecutive runs of 256 Gaussians (chunks)
//! whose bounds (centres grown by the largest splat reach) are frustum-culled.
//!
//! Chunks are compact when the Gaussians are stored in Morton order, as
//! [`sage_scene::Scene::load`] and the synthetic generator keep them
//! ([`sage_scene::Gaussians::sort_morton`]); any other order renders the same images,
//! only culling gets coarser. No permutation is stored, so the index costs about 0.1 byte per
//! Gaussian.

use crate::camera::Camera;
use glam::Vec3;
use rayon::prelude::*;
use sage_core::Aabb;
use sage_scene::Gaussians;

/// Gaussians per chunk.
pub const CHUNK: usize = 256;

/// How far, in standard deviations, a Gaussian of opacity 1 stays above alpha 1/255:
/// sqrt(2 ln 255).
pub const MAX_SIGMAS: f32 = 3.33;

/// Chunks of spatially close Gaussians with conservative bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct SplatIndex {
    /// Per chunk (Gaussians `c*256 .. (c+1)*256`): the bounds of everything they can touch.
    pub bounds: Vec<Aabb>,
}

impl SplatIndex {
    /// Builds the index of `g`.
    pub fn build(g: &Gaussians) -> SplatIndex {
        let chunks = g.len().div_ceil(CHUNK);
        let bounds = (0..chunks)
            .into_par_iter()
            .map(|c| {
                (c * CHUNK..((c + 1) * CHUNK).min(g.len())).fold(Aabb::EMPTY, |b, i| {
                    let reach = g.max_log_scale(i).exp() * MAX_SIGMAS;
                    let p = Vec3::from_array(g.positions[i]);
                    b.grow(p - Vec3::splat(reach)).grow(p + Vec3::splat(reach))
                })
            })
            .collect();
        SplatIndex { bounds }
    }

    /// Heap bytes of the index.
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.bounds.as_slice())
    }

    /// The chunks whose bounds meet the camera's view volume, in order.
    fn visible(&self, camera: &Camera) -> impl Iterator<Item = u32> {
        let planes = frustum_planes(camera);
        self.bounds
            .iter()
            .enumerate()
            .filter(move |(_, b)| {
                !b.is_empty() && planes.iter().all(|(n, d)| box_reaches(b, *n, *d))
            })
            .map(|(c, _)| c as u32)
    }

    /// Appends to `out` the chunks whose bounds meet the camera's view volume.
    pub fn visible_chunks(&self, camera: &Camera, out: &mut Vec<u32>) {
        out.clear();
        out.extend(self.visible(camera));
    }

    /// How many chunks' bounds meet the camera's view volume, counted up to `limit` (the
    /// count stops there): what [`Self::visible_chunks`] would list, where only whether it
    /// reaches `limit` matters.
    pub fn visible_count(&self, camera: &Camera, limit: usize) -> usize {
        self.visible(camera).take(limit).count()
    }
}

/// True when some point of `b` satisfies n·p ≥ d.
fn box_reaches(b: &Aabb, n: Vec3, d: f32) -> bool {
    let far_corner = Vec3::select(n.cmpge(Vec3::ZERO), b.max, b.min);
    n.dot(far_corner) >= d
}

/// Inward planes (n, d) with n·p ≥ d inside: near, far and the four sides, the sides widened
/// by the 1.3× Jacobian clamp margin of the projection so no contributing splat is lost.
pub(crate) fn frustum_planes(c: &Camera) -> [(Vec3, f32); 6] {
    let (right, down, fwd) = (c.rotation.x_axis, c.rotation.y_axis, c.rotation.z_axis);
    let tan_l = (c.intrinsics.cx / c.intrinsics.fx) * 1.3 + 0.05;
    let tan_r = ((c.intrinsics.width as f32 - c.intrinsics.cx) / c.intrinsics.fx) * 1.3 + 0.05;
    let tan_t = (c.intrinsics.cy / c.intrinsics.fy) * 1.3 + 0.05;
    let tan_b = ((c.intrinsics.height as f32 - c.intrinsics.cy) / c.intrinsics.fy) * 1.3 + 0.05;
    let side = |n: Vec3| (n.normalize(), n.normalize().dot(c.position));
    [
        (fwd, fwd.dot(c.position) + c.near),
        (-fwd, -fwd.dot(c.position) - c.far),
        side(fwd * tan_l + right),
        side(fwd * tan_r - right),
        side(fwd * tan_t + down),
        side(fwd * tan_b - down),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use sage_scene::Gaussian;

    #[test]
    fn chunks_behind_the_camera_are_culled() {
        let mut g = Gaussians::new(0).unwrap();
        for i in 0..(CHUNK * 4) {
            let x = if i < CHUNK * 2 { 5.0 } else { -5.0 };
            g.push(&Gaussian {
                position: Vec3::new(x, (i % 16) as f32 * 0.01, 1.0),
                ..Gaussian::default()
            });
        }
        let index = SplatIndex::build(&g);
        assert_eq!(index.bounds.len(), 4);
        let cam = Camera::from_yaw_pitch(
            Intrinsics::from_hfov(64, 64, 90.0).unwrap(),
            Vec3::new(0.0, 0.0, 1.0),
            0.0,
            0.0,
        );
        let mut visible = Vec::new();
        index.visible_chunks(&cam, &mut visible);
        assert_eq!(visible.len(), 2);
        assert_eq!(index.visible_count(&cam, usize::MAX), 2);
        assert_eq!(index.visible_count(&cam, 1), 1);
        assert_eq!(index.visible_count(&cam, 0), 0);
        for c in visible {
            assert!(index.bounds[c as usize].min.x > 0.0);
        }
    }
}
