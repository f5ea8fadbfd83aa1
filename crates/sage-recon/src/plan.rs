//! The plan: which cameras a scene is rendered from. [`make_plan`] runs a policy and the safety
//! filter; the plan file (`plan.json`) keeps both the kept views (numbered, in the order they
//! are rendered) and the dropped ones, and [`draw_plan`] draws them over the floorplan (kept
//! green, dropped red).

use crate::safety::{Checked, SafetyFilter};
use crate::surfaces::SceneSurfaces;
use crate::sweep::{SweepParams, perimeter, sweep};
use crate::volume::{VolumeParams, volume};
use crate::{PoseTag, ViewPose};
use glam::{Vec2, Vec3};
use sage_core::{Error, Result};
use sage_io::canvas::{Canvas, legend_height, legend_width};
use sage_scene::Scene;
use sage_splat::{Camera, Intrinsics};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The plan file's name in a reconstruction folder.
pub const PLAN_FILE: &str = "plan.json";
/// The plan picture's name.
pub const PLAN_PNG: &str = "plan.png";
/// The `format` field of plan files.
pub const FORMAT: &str = "sage3d-recon-plan/1";

/// Which camera placement policy made a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Policy {
    /// Perimeter-aware floorplan sweeps.
    Sweep,
    /// Volume-uniform Poisson-disk positions with six template views.
    Volume,
}

impl std::fmt::Display for Policy {
    /// The policy's name, as [`FromStr`](std::str::FromStr) reads it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Policy::Sweep => "sweep",
            Policy::Volume => "volume",
        })
    }
}

impl std::str::FromStr for Policy {
    type Err = Error;
    fn from_str(s: &str) -> Result<Policy> {
        match s {
            "sweep" => Ok(Policy::Sweep),
            "volume" => Ok(Policy::Volume),
            _ => Err(Error::invalid(format!(
                "unknown policy '{s}' (expected sweep or volume)"
            ))),
        }
    }
}

/// One camera of a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedView {
    /// Index among the kept views (names its image files); among the dropped, their index.
    pub id: usize,
    /// Camera centre, metres (W).
    pub position: [f32; 3],
    /// Heading, degrees.
    pub yaw_deg: f32,
    /// Pitch, degrees, up positive.
    pub pitch_deg: f32,
    /// Room index in the floorplan.
    pub room: usize,
    /// Where in the policy it comes from: `ring{j}/{tier}/{baseline}` or `pos{k}/view{v}`.
    pub tag: String,
    /// Distance to the nearest mesh surface, metres.
    pub clearance: f32,
}

impl PlannedView {
    fn from_checked(id: usize, c: &Checked) -> PlannedView {
        let tag = match c.pose.tag {
            PoseTag::Sweep {
                ring,
                tier,
                baseline,
            } => format!("ring{ring}/{}/{}", tier.as_str(), baseline.as_str()),
            PoseTag::Volume { position, view } => format!("pos{position}/view{view}"),
        };
        PlannedView {
            id,
            position: c.pose.position.to_array(),
            yaw_deg: c.pose.yaw.to_degrees(),
            pitch_deg: c.pose.pitch.to_degrees(),
            room: c.pose.room,
            tag,
            clearance: c.clearance,
        }
    }

    /// The camera of this view with `intrinsics` (OpenCV axes, SPEC §3).
    pub fn camera(&self, intrinsics: Intrinsics) -> Camera {
        Camera::from_yaw_pitch(
            intrinsics,
            Vec3::from_array(self.position),
            self.yaw_deg.to_radians(),
            self.pitch_deg.to_radians(),
        )
    }
}

/// One offset polygon of a sweep plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedRing {
    /// Room index in the floorplan.
    pub room: usize,
    /// Index in the offset schedule, 0 the outermost.
    pub ring: usize,
    /// Placements (of nine cameras) along it.
    pub placements: usize,
    /// Its length, metres.
    pub perimeter: f32,
    /// Its vertices, counter-clockwise, metres.
    pub points: Vec<[f32; 2]>,
}

/// A plan file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// [`FORMAT`].
    pub format: String,
    /// Scene name.
    pub scene: String,
    /// The scene folder as given when planning (the default of `recon render`).
    pub scene_dir: String,
    /// The policy.
    pub policy: Policy,
    /// Cameras asked for.
    pub budget: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// Horizontal field of view of the views, degrees.
    pub hfov_deg: f32,
    /// Safety threshold, metres.
    pub safety_threshold: f32,
    /// Sweep settings (sweep plans).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepParams>,
    /// Volume settings (volume plans).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume: Option<VolumeParams>,
    /// The sweep's offset polygons.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rings: Vec<PlannedRing>,
    /// Kept views, in render order.
    pub views: Vec<PlannedView>,
    /// Views dropped by the safety filter.
    pub dropped: Vec<PlannedView>,
}

/// The most cameras a plan may be asked for.
pub const MAX_VIEWS: usize = 100_000;

/// How a plan is made.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSettings {
    /// Policy.
    pub policy: Policy,
    /// Cameras asked for.
    pub budget: usize,
    /// Seed.
    pub seed: u64,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Safety threshold, metres.
    pub safety_threshold: f32,
    /// Sweep settings.
    pub sweep: SweepParams,
    /// Volume settings.
    pub volume: VolumeParams,
}

impl Default for PlanSettings {
    fn default() -> Self {
        PlanSettings {
            policy: Policy::Sweep,
            budget: 3000,
            seed: 0,
            hfov_deg: 90.0,
            safety_threshold: crate::safety::DEFAULT_THRESHOLD,
            sweep: SweepParams::default(),
            volume: VolumeParams::default(),
        }
    }
}

/// Samples cameras for `scene` with `settings` and filters them against `surfaces`.
///
/// # Errors
///
/// A scene without rooms, settings out of range, or a plan that keeps no camera (the budget
/// placed none, or the safety filter dropped every one).
pub fn make_plan(
    scene: &Scene,
    scene_dir: &str,
    surfaces: &SceneSurfaces,
    settings: &PlanSettings,
) -> Result<Plan> {
    if scene.floorplan.rooms.is_empty() {
        return Err(Error::invalid(format!(
            "scene {} has no rooms in structure.json: nothing to sample cameras in",
            scene.name
        )));
    }
    if settings.budget > MAX_VIEWS {
        return Err(Error::invalid(format!(
            "`budget` must be at most {MAX_VIEWS} cameras, got {}",
            settings.budget
        )));
    }
    if !(settings.hfov_deg > 0.0 && settings.hfov_deg < 180.0) {
        return Err(Error::invalid("hfov must be in (0, 180) degrees"));
    }
    if !(settings.safety_threshold.is_finite() && settings.safety_threshold >= 0.0) {
        return Err(Error::invalid(format!(
            "the safety threshold must be >= 0 m, got {}",
            settings.safety_threshold
        )));
    }
    let (poses, rings): (Vec<ViewPose>, Vec<PlannedRing>) = match settings.policy {
        Policy::Sweep => {
            let s = sweep(
                &scene.floorplan,
                settings.budget,
                settings.seed,
                &settings.sweep,
            )?;
            let rings = s
                .rings
                .iter()
                .map(|r| PlannedRing {
                    room: r.room,
                    ring: r.ring,
                    placements: r.placements,
                    perimeter: perimeter(&r.polygon),
                    points: r.polygon.points.iter().map(|p| p.to_array()).collect(),
                })
                .collect();
            (s.poses, rings)
        }
        Policy::Volume => (
            volume(scene, settings.budget, settings.seed, &settings.volume)?.poses,
            Vec::new(),
        ),
    };
    let bvh = surfaces.bvh();
    let filtered = SafetyFilter::new(&bvh, settings.safety_threshold).split(&poses);
    // A plan of no camera would only fail at the export or the fit, steps later.
    if poses.is_empty() {
        return Err(Error::invalid(format!(
            "`budget` {} placed no camera in the scene's {} rooms: raise it",
            settings.budget,
            scene.floorplan.rooms.len()
        )));
    }
    if filtered.kept.is_empty() {
        return Err(Error::invalid(format!(
            "every one of the {} cameras sampled lies within the safety threshold ({} m) of a surface: lower the threshold or raise `budget`",
            poses.len(),
            settings.safety_threshold
        )));
    }
    Ok(Plan {
        format: FORMAT.to_string(),
        scene: scene.name.clone(),
        scene_dir: scene_dir.to_string(),
        policy: settings.policy,
        budget: settings.budget,
        seed: settings.seed,
        hfov_deg: settings.hfov_deg,
        safety_threshold: settings.safety_threshold,
        sweep: (settings.policy == Policy::Sweep).then(|| settings.sweep.clone()),
        volume: (settings.policy == Policy::Volume).then(|| settings.volume.clone()),
        rings,
        views: filtered
            .kept
            .iter()
            .enumerate()
            .map(|(i, c)| PlannedView::from_checked(i, c))
            .collect(),
        dropped: filtered
            .dropped
            .iter()
            .enumerate()
            .map(|(i, c)| PlannedView::from_checked(i, c))
            .collect(),
    })
}

impl Plan {
    /// Reads a plan file (at most `SAGE3D_MAX_JSON_MB`, refused from its size before it is
    /// read).
    pub fn load(path: &Path) -> Result<Plan> {
        let plan: Plan = sage_io::files::read_json(path)?;
        if plan.format != FORMAT {
            return Err(Error::format(
                "format",
                format!("expected {FORMAT}, found {}", plan.format),
            )
            .in_file(path));
        }
        if let Some(v) = plan.views.iter().enumerate().find(|(i, v)| v.id != *i) {
            return Err(Error::format(
                format!("views[{}].id", v.0),
                "kept views must be numbered 0, 1, 2, … in order",
            )
            .in_file(path));
        }
        Ok(plan)
    }

    /// Writes the plan file (atomically).
    pub fn save(&self, path: &Path) -> Result<()> {
        sage_io::files::write_json(path, self)
    }

    /// Intrinsics of the views at `width × height` (square pixels from the plan's field of
    /// view).
    pub fn intrinsics(&self, width: u32, height: u32) -> Result<Intrinsics> {
        Intrinsics::from_hfov(width, height, self.hfov_deg)
    }
}

/// Pixels per metre of the plan picture.
const PX_PER_M: f32 = 40.0;

/// Draws the rooms (grey), walls (dark), the sweep's rings (blue), kept views (green) and
/// dropped views (red), each view a dot with a short tick along its heading, and a legend
/// with the counts.
pub fn draw_plan(scene: &Scene, plan: &Plan) -> Canvas {
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for r in &scene.floorplan.rooms {
        let (a, b) = r.profile.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    for w in &scene.floorplan.walls {
        lo = lo.min(w.start.min(w.end));
        hi = hi.max(w.start.max(w.end));
    }
    let margin = Vec2::splat(0.5);
    let (lo, hi) = (lo - margin, hi + margin);
    let scale = 1.0 / PX_PER_M;
    let size = ((hi - lo) / scale).ceil();
    let (w, h) = (
        (size.x as usize).clamp(1, 8192),
        (size.y as usize).clamp(1, 8192),
    );
    let (kept, dropped, ring_ink) = ([20, 160, 40], [220, 30, 30], [150, 170, 230]);
    let mut legend = vec![
        (kept, format!("kept {}", plan.views.len())),
        (dropped, format!("dropped {}", plan.dropped.len())),
    ];
    if !plan.rings.is_empty() {
        legend.push((ring_ink, format!("rings {}", plan.rings.len())));
    }
    let chars = legend.iter().map(|e| e.1.len()).max().unwrap_or(0).max(7);
    let mut c = Canvas::new(
        w + legend_width(chars),
        h.max(legend_height(legend.len())),
        [255, 255, 255],
        lo,
        scale,
        h,
    );
    c.legend(w as i64 + 10, "cameras", &legend);
    for r in &scene.floorplan.rooms {
        c.fill_polygon(&r.profile.points, [232, 232, 232]);
    }
    for wall in &scene.floorplan.walls {
        c.line(wall.start, wall.end, [60, 60, 60], 3);
    }
    for ring in &plan.rings {
        let pts: Vec<Vec2> = ring.points.iter().map(|p| Vec2::from_array(*p)).collect();
        for k in 0..pts.len() {
            c.line(pts[k], pts[(k + 1) % pts.len()], ring_ink, 1);
        }
    }
    let mut mark = |v: &PlannedView, colour: [u8; 3]| {
        let p = Vec2::new(v.position[0], v.position[1]);
        let yaw = v.yaw_deg.to_radians();
        c.line(p, p + Vec2::new(yaw.cos(), yaw.sin()) * 0.2, colour, 1);
        c.disc(p, 2, colour);
    };
    for v in &plan.views {
        mark(v, kept);
    }
    for v in &plan.dropped {
        mark(v, dropped);
    }
    c
}
