//! From a finished episode to its scores: the metrics' record of a trace and its metrics in a
//! mode. The evaluator, `env run` and the Python environments all score through here, so an
//! episode gets the same numbers whichever front end ran it.

use crate::context::SceneContext;
use crate::episode::EpisodeTrace;
use glam::Vec2;
use sage_core::Result;
use sage_metrics::distance::{GoalRegion, OfficialGoal, official_goal_box};
use sage_metrics::gnbench::GnBenchDistances;
use sage_metrics::{EpisodeMetrics, EpisodeRecord, Geodesics, Mode, StepRecord};

/// GN-Bench's distances to the goal point from the start and after every step of a VLN
/// trace, on the scene's occupancy image (`None` without a goal or an occupancy image).
pub fn gnbench_distances(ctx: &SceneContext, t: &EpisodeTrace) -> Option<GnBenchDistances> {
    let xy = |p: glam::Vec3| [f64::from(p.x), f64::from(p.y)];
    let goal = xy(t.episode.goal.as_ref()?.point);
    let grid = ctx.gnbench_grid()?;
    let positions: Vec<[f64; 2]> = std::iter::once(xy(t.episode.start.position))
        .chain(t.steps.iter().map(|s| xy(s.pose.position)))
        .collect();
    let mut d = grid.trace_distances(&positions, goal).into_iter();
    Some(GnBenchDistances {
        start: d.next().flatten(),
        steps: d.collect(),
    })
}

/// The metrics' record of a finished trace, for scoring in `mode`; the published code's goal
/// box is chosen among the entries of the scene's published map (no map: its distance rule).
/// GN-Bench's distances, an A* per position the agent reached, are only computed for mode
/// `gnbench`.
pub fn metric_record(ctx: &SceneContext, t: &EpisodeTrace, mode: Mode) -> EpisodeRecord {
    let f = |v: Vec2| [f64::from(v.x), f64::from(v.y)];
    let e = &t.episode;
    let goal = e.goal.as_ref().map(|g| GoalRegion {
        point: f(g.point.truncate()),
        footprint: t.goal_footprint.as_ref().map(|p| {
            p.iter()
                .map(|q| [f64::from(q[0]), f64::from(q[1])])
                .collect()
        }),
        heading: g.heading.map(f64::from),
    });
    let official_goal = match &ctx.published_boxes {
        None => OfficialGoal::NoMap,
        Some(boxes) => OfficialGoal::Map {
            chosen: e
                .reference_path
                .last()
                .or(e.goal.as_ref().map(|g| &g.point))
                .and_then(|p| official_goal_box(boxes, f(p.truncate()))),
        },
    };
    EpisodeRecord {
        episode_id: e.id.clone(),
        task: e.task,
        start: e.start.position.to_array(),
        start_yaw: e.start.yaw,
        steps: t
            .steps
            .iter()
            .enumerate()
            .map(|(k, s)| StepRecord {
                position: s.pose.position.to_array(),
                yaw: s.pose.yaw,
                time: s.time,
                commanded: s.commanded,
                achieved: s.achieved,
                contact: !s.touched.is_empty(),
                intensity: s.intensity,
                geodesic_to_goal_point: t.geodesics.steps_to_point.get(k).copied().flatten(),
            })
            .collect(),
        stop_called: t.stop_called(),
        reference_path: e.reference_path.iter().map(|p| p.to_array()).collect(),
        goal,
        geodesics: Geodesics {
            start_to_region: t.geodesics.start_to_region,
            final_to_region: t.geodesics.final_to_region,
            start_to_point: t.geodesics.start_to_point,
        },
        official_goal,
        gnbench: if mode == Mode::GnBench {
            gnbench_distances(ctx, t)
        } else {
            None
        },
    }
}

/// The metrics of a finished trace in `mode`.
///
/// # Errors
///
/// The metrics' own checks of the record (see [`sage_metrics::evaluate`]).
pub fn score(ctx: &SceneContext, trace: &EpisodeTrace, mode: Mode) -> Result<EpisodeMetrics> {
    sage_metrics::evaluate(&metric_record(ctx, trace, mode), mode)
}
