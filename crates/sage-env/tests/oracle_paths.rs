//! Reference paths an agent can execute: on 200 trajectories over four generated scenes
//! (homes and an office, their doors in every state), each planned for the agent profile's
//! radius as `sage3d data build --agent` plans them, the oracle of every ground profile reaches
//! every goal and touches something on at most 2% of them (measured: wheeled 0 of 200, go2 3,
//! g1 0, h1 0). A benchmark whose ground truth collides cannot score collisions.

use sage_env::agents::{OracleAgent, run_episode};
use sage_env::scoring::score;
use sage_env::{Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig, Termination};
use sage_metrics::Mode;
use sage_nav::TrajectoryParams;
use sage_physics::{AgentProfile, Decomposer, HullCache, SceneBodies};
use sage_scene::Scene;
use sage_synth::{SceneKind, SynthConfig, generate};
use std::sync::Arc;

/// Trajectories per scene (four scenes: 200 in all).
const PER_SCENE: usize = 50;

/// The four scenes with their collision bodies.
fn scenes() -> Vec<(Scene, SceneBodies, u64)> {
    let cache = tempfile::tempdir().unwrap();
    [
        (11, SceneKind::Home, 4, 50),
        (12, SceneKind::Home, 6, 90),
        (13, SceneKind::Office, 6, 80),
        (14, SceneKind::Home, 8, 120),
    ]
    .into_iter()
    .map(|(seed, kind, rooms, objects)| {
        let scene = generate(&SynthConfig {
            seed,
            kind,
            rooms,
            objects,
            gaussians: 1000,
            ..SynthConfig::default()
        })
        .unwrap();
        let (bodies, _) = SceneBodies::build(
            &scene,
            &Decomposer::default(),
            &HullCache::new(cache.path()),
        )
        .unwrap();
        (scene, bodies, seed)
    })
    .collect()
}

/// A scene's context and its trajectories planned for an agent of `radius` as VLN episodes.
fn episodes(
    scene: &Scene,
    bodies: &SceneBodies,
    seed: u64,
    radius: f32,
) -> (Arc<SceneContext>, Vec<EnvEpisode>) {
    let mut params = TrajectoryParams {
        count: PER_SCENE,
        seed,
        ..TrajectoryParams::default()
    };
    params.cost.robot_radius = radius;
    let prep = sage_nav::trajectory::prepare(scene, &params).unwrap();
    let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params).unwrap();
    let episodes = set
        .trajectories
        .iter()
        .map(|t| EnvEpisode::from_trajectory(format!("{}-t{}", scene.name, t.id), t, "go"))
        .collect();
    // The evaluator's context: geodesics on the default grid, whatever the profile.
    let defaults = TrajectoryParams::default();
    let ctx =
        SceneContext::new(scene.clone(), bodies.clone(), &defaults.grid, defaults.cost).unwrap();
    (Arc::new(ctx), episodes)
}

#[test]
fn the_oracle_of_every_ground_profile_reaches_every_goal_and_almost_never_touches() {
    let scenes = scenes();
    for profile in ["wheeled", "go2", "g1", "h1"] {
        let radius = profile.parse::<AgentProfile>().unwrap().radius;
        let (mut total, mut success, mut collisions, mut touched) = (0, 0.0, 0.0, Vec::new());
        for (scene, bodies, seed) in &scenes {
            let (ctx, episodes) = episodes(scene, bodies, *seed, radius);
            let config = EnvConfig {
                agent: profile.into(),
                sensors: SensorConfig {
                    rgb: false,
                    depth: false,
                    ..SensorConfig::default()
                },
                ..EnvConfig::default()
            };
            let mut env = Env::new(ctx.clone(), config).unwrap();
            for e in &episodes {
                let trace = run_episode(&mut env, &mut OracleAgent::new(0.25), e).unwrap();
                let m = score(&ctx, &trace, Mode::Sage).unwrap();
                total += 1;
                success += m.sr.unwrap();
                collisions += m.cr.unwrap();
                if m.cr.unwrap() > 0.0 || m.sr.unwrap() < 1.0 {
                    touched.push(format!(
                        "{} (CR {}, SR {})",
                        e.id,
                        m.cr.unwrap(),
                        m.sr.unwrap()
                    ));
                }
            }
        }
        assert!(total >= 200, "{profile}: {total} trajectories");
        let (sr, cr) = (success / total as f64, collisions / total as f64);
        eprintln!("{profile}: SR {sr:.3} CR {cr:.3} {touched:?}");
        assert_eq!(sr, 1.0, "{profile}: SR {sr}: {touched:?}");
        assert!(cr <= 0.02, "{profile}: CR {cr}: {touched:?}");
    }
}

/// With the training-data presets' longer steps the oracle still calls STOP at its goals: a
/// step of 0.75 m cannot land within the 0.25 m stop radius, and an oracle that waited for it
/// stepped back and forth across the goal until the step limit.
#[test]
fn the_oracle_stops_at_its_goals_with_every_training_presets_steps() {
    let scenes = scenes();
    for preset in ["navila_small", "navila_large", "custom_small"] {
        let (mut total, mut success, mut unstopped) = (0, 0.0, Vec::new());
        for (scene, bodies, seed) in &scenes[..2] {
            let (ctx, episodes) = episodes(scene, bodies, *seed, 0.25);
            let config = EnvConfig {
                sensors: SensorConfig {
                    rgb: false,
                    depth: false,
                    ..SensorConfig::default()
                },
                ..EnvConfig::preset(preset).unwrap()
            };
            let mut env = Env::new(ctx.clone(), config).unwrap();
            for e in &episodes {
                let trace = run_episode(&mut env, &mut OracleAgent::new(0.25), e).unwrap();
                total += 1;
                success += score(&ctx, &trace, Mode::Sage).unwrap().sr.unwrap();
                if trace.termination != Some(Termination::Stop) {
                    unstopped.push(format!("{} ({:?})", e.id, trace.termination));
                }
            }
        }
        let sr = success / total as f64;
        eprintln!("{preset}: SR {sr:.3}, not stopped: {unstopped:?}");
        assert!(unstopped.is_empty(), "{preset}: {unstopped:?}");
        assert!(sr >= 0.9, "{preset}: SR {sr}");
    }
}
