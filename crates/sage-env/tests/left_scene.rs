//! Agents stay in the world: an agent that walks out through the entrance of a generated home
//! ends its episode with `left_scene` one step past the bound, with a finite distance to the
//! goal, while walking into a wall inside never ends an episode that way.

use glam::Vec2;
use sage_core::{Pose, Task};
use sage_env::agents::{ForwardAgent, run_episode};
use sage_env::env::LEAVE_DISTANCE;
use sage_env::{Env, EnvConfig, EnvEpisode, EnvGoal, SceneContext, SensorConfig, Termination};
use sage_nav::TrajectoryParams;
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_scene::{DoorState, HoleKind, Scene};
use sage_synth::{SynthConfig, generate};
use std::sync::Arc;

/// The first generated home (seeds 0, 1, …) whose entrance door stands open, with a pose just
/// inside it facing out.
fn home_with_open_entrance() -> (Scene, Pose) {
    for seed in 0..40 {
        let mut scene = generate(&SynthConfig {
            seed,
            rooms: 3,
            objects: 20,
            gaussians: 2000,
            ..SynthConfig::default()
        })
        .unwrap();
        for o in &mut scene.objects {
            o.mesh = None;
        }
        let inside = |p: Vec2| scene.floorplan.rooms.iter().any(|r| r.profile.contains(p));
        let entrance = scene.floorplan.holes.iter().find_map(|h| {
            if h.kind != HoleKind::Door || h.state.is_some_and(|s| s != DoorState::Open) {
                return None;
            }
            let (lo, hi) = h.bounds();
            let c = ((lo + hi) * 0.5).truncate();
            // The wall's normal is the thin axis of the opening.
            let n = if hi.x - lo.x < hi.y - lo.y {
                Vec2::X
            } else {
                Vec2::Y
            };
            let out = [n, -n]
                .into_iter()
                .find(|&d| !inside(c + d * 0.6) && inside(c - d * 0.6))?;
            Some(Pose::new((c - out * 0.6).extend(0.0), out.y.atan2(out.x)))
        });
        if let Some(start) = entrance {
            return (scene, start);
        }
    }
    panic!("no generated home with an open entrance among 40 seeds");
}

#[test]
fn walking_out_of_the_entrance_ends_the_episode_with_left_scene() {
    let (scene, start) = home_with_open_entrance();
    let cache = tempfile::tempdir().unwrap();
    let (bodies, _) = SceneBodies::build(
        &scene,
        &Decomposer::default(),
        &HullCache::new(cache.path()),
    )
    .unwrap();
    let params = TrajectoryParams::default();
    let ctx = Arc::new(SceneContext::new(scene, bodies, &params.grid, params.cost).unwrap());
    let config = EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    };
    let mut env = Env::new(ctx.clone(), config).unwrap();
    let episode = |start: Pose| EnvEpisode {
        id: "out".into(),
        task: Task::Vln,
        instruction: "walk straight on".into(),
        start,
        goal: Some(EnvGoal {
            point: start.position,
            object: None,
            heading: None,
        }),
        reference_path: vec![start.position],
    };
    let trace = run_episode(&mut env, &mut ForwardAgent::new(None), &episode(start)).unwrap();
    assert_eq!(trace.termination, Some(Termination::LeftScene));
    let last = trace.steps.last().unwrap().pose.position.truncate();
    let pf = &ctx.pathfinder;
    // It ended at the first step past the bound: beyond it now, not one step before.
    assert!(pf.snap_point(last, LEAVE_DISTANCE).is_none());
    let before = trace.steps[trace.steps.len() - 2].pose.position.truncate();
    assert!(
        pf.snap_point(before, LEAVE_DISTANCE).is_some()
            || ctx
                .scene
                .floorplan
                .rooms
                .iter()
                .any(|r| r.profile.contains(before))
    );
    assert!(trace.steps.len() < 60, "{} steps", trace.steps.len());
    // Where it stands still has a distance to the goal (NE is not null).
    assert!(trace.geodesics.final_to_region.is_some_and(f32::is_finite));

    // Facing into the building from the same door, the agent walks until a wall stops it and
    // the step limit ends the episode: never `left_scene`.
    let inward = Pose::new(start.position, start.yaw + std::f32::consts::PI);
    let trace = run_episode(&mut env, &mut ForwardAgent::new(None), &episode(inward)).unwrap();
    assert_eq!(trace.termination, Some(Termination::MaxSteps));
    assert!(
        ctx.pathfinder
            .snap_point(trace.steps.last().unwrap().pose.position.truncate(), 1.0)
            .is_some()
    );
}
