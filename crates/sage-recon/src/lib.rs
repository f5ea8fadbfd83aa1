//! `sage-recon`: how a Gaussian scene is made from a mesh scene, the way InteriorGS was made
//! (artist meshes → a few thousand rendered views per scene → 3DGS fitted to them).
//!
//! Its one job is everything on the mesh side of that fit:
//!
//! - [`sweep`] and [`volume`]: the two camera placement policies of the paper's appendix B
//!   (perimeter-aware floorplan sweeps; volume-uniform Poisson-disk positions with six template
//!   views each), each from a camera budget and a seed;
//! - [`safety`]: the filter that drops poses closer than a threshold to the nearest mesh
//!   surface, over a [`bvh::Bvh`] of every triangle of the scene ([`surfaces`]);
//! - [`plan`]: the plan file (kept and dropped poses) and its picture over the floorplan;
//! - [`raster`]: the ground-truth views, RGB and z-depth, ray traced on the CPU from the scene's
//!   coloured, Lambert-shaded triangles;
//! - [`export`]: `transforms.json` in the nerfstudio layout that gsplat and nerfstudio train
//!   from, with a train / held-out split;
//! - [`surfaces::surface_samples`]: coloured points on the meshes to start the Gaussians from.
//!
//! Same seed, same bytes, whatever the thread count.

pub mod bvh;
pub mod export;
pub mod plan;
pub mod raster;
pub mod safety;
pub mod surfaces;
pub mod sweep;
pub mod views;
pub mod volume;

pub use bvh::Bvh;
pub use export::{Transforms, read_transforms, transforms_for};
pub use plan::{Plan, PlannedView, Policy};
pub use raster::{MeshImage, render_view};
pub use safety::SafetyFilter;
pub use surfaces::{SceneSurfaces, SurfaceKind, surface_samples};
pub use sweep::SweepParams;
pub use volume::VolumeParams;

use glam::Vec3;

/// One sampled camera pose before the safety filter: where it stands and where it looks. Named
/// apart from `sage_core::Pose`, a ground pose (position and heading only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewPose {
    /// Camera centre in W, metres.
    pub position: Vec3,
    /// Heading about +Z from +X, radians.
    pub yaw: f32,
    /// Pitch, radians, up positive.
    pub pitch: f32,
    /// Index of the room the pose was sampled for.
    pub room: usize,
    /// Which part of the policy made it.
    pub tag: PoseTag,
}

/// Where in its policy a pose comes from: enough to count poses per polygon, tier or template
/// view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseTag {
    /// A perimeter sweep camera: offset polygon `ring` (0 = outermost), vertical `tier`,
    /// tangential `baseline`.
    Sweep {
        /// Offset polygon index within its room, 0 the outermost.
        ring: usize,
        /// Vertical tier.
        tier: sweep::Tier,
        /// Tangential baseline.
        baseline: sweep::Baseline,
    },
    /// A volume-uniform camera: Poisson-disk `position` (numbered across the scene) and the
    /// index of its template `view` (0–5).
    Volume {
        /// Position index across the scene.
        position: usize,
        /// Template view index.
        view: usize,
    },
}

/// Splits `total` into whole shares proportional to `weights` by largest remainders (ties to
/// the lower index): every share is within one of its exact quota and the shares sum to
/// `total` (to 0 when no weight is positive).
pub fn apportion(total: usize, weights: &[f64]) -> Vec<usize> {
    let sum: f64 = weights.iter().filter(|w| **w > 0.0).sum();
    if sum <= 0.0 {
        return vec![0; weights.len()];
    }
    let quotas: Vec<f64> = weights
        .iter()
        .map(|w| w.max(0.0) / sum * total as f64)
        .collect();
    let mut shares: Vec<usize> = quotas.iter().map(|q| q.floor() as usize).collect();
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (quotas[a] - quotas[a].floor(), quotas[b] - quotas[b].floor());
        rb.total_cmp(&ra).then(a.cmp(&b))
    });
    let left = total - shares.iter().sum::<usize>();
    for &i in order.iter().filter(|&&i| weights[i] > 0.0).take(left) {
        shares[i] += 1;
    }
    shares
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn apportion_sums_and_stays_near_quota(total in 0usize..500, w in proptest::collection::vec(0.0f64..10.0, 1..8)) {
            let s = apportion(total, &w);
            let sum: f64 = w.iter().sum();
            if sum > 0.0 {
                prop_assert_eq!(s.iter().sum::<usize>(), total);
                for (share, wi) in s.iter().zip(&w) {
                    prop_assert!((*share as f64 - wi / sum * total as f64).abs() < 1.0 + 1e-9);
                }
            }
        }
    }
}
