//! The safety filter of the paper's appendix B: a pose closer than a threshold to the nearest
//! mesh surface (structure, object meshes, object boxes where there is no mesh) is dropped.

use crate::ViewPose;
use crate::bvh::Bvh;
use rayon::prelude::*;

/// Default threshold, metres: under the 150 mm of the sweep's low tier, so the floor alone
/// never drops a low camera, and over the near plane of the views.
pub const DEFAULT_THRESHOLD: f32 = 0.12;

/// A pose with its distance to the nearest surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checked {
    /// The pose.
    pub pose: ViewPose,
    /// Distance from its centre to the nearest triangle, metres (infinite in an empty scene).
    pub clearance: f32,
}

/// Poses split by the filter, each list in input order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Filtered {
    /// Poses at least the threshold away from every surface.
    pub kept: Vec<Checked>,
    /// Poses nearer than the threshold.
    pub dropped: Vec<Checked>,
}

/// Distance queries against every triangle of a scene.
#[derive(Debug, Clone)]
pub struct SafetyFilter<'a> {
    bvh: &'a Bvh,
    /// Least distance to keep a pose, metres.
    pub threshold: f32,
}

impl<'a> SafetyFilter<'a> {
    /// A filter over `bvh` dropping poses nearer than `threshold`.
    pub fn new(bvh: &'a Bvh, threshold: f32) -> Self {
        SafetyFilter { bvh, threshold }
    }

    /// Distance from `p` to the nearest surface.
    pub fn clearance(&self, p: glam::Vec3) -> f32 {
        self.bvh.nearest(p).map_or(f32::INFINITY, |(d, _)| d)
    }

    /// Splits `poses` into kept and dropped (in parallel; the order is the input's).
    pub fn split(&self, poses: &[ViewPose]) -> Filtered {
        let checked: Vec<Checked> = poses
            .par_iter()
            .map(|&pose| Checked {
                pose,
                clearance: self.clearance(pose.position),
            })
            .collect();
        let (kept, dropped) = checked
            .into_iter()
            .partition(|c| c.clearance >= self.threshold);
        Filtered { kept, dropped }
    }
}
