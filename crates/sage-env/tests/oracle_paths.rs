//! Reference paths an agent can execute: on 200 planned trajectories over four generated
//! scenes (homes and an office, their doors in every state), the oracle of the default
//! (wheeled) profile reaches every goal and touches something on at most 3% of them (measured:
//! 5 of 200, CR 0.025). A benchmark whose ground truth collides cannot score collisions.
//! The wider profiles (go2, g1, h1) plan on their own radius but are not yet held to this.

use sage_env::agents::{OracleAgent, run_episode};
use sage_env::scoring::score;
use sage_env::{Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig};
use sage_metrics::Mode;
use sage_nav::TrajectoryParams;
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_synth::{SceneKind, SynthConfig, generate};
use std::sync::Arc;

/// Trajectories per scene (four scenes: 200 in all).
const PER_SCENE: usize = 50;

/// The four scenes with their trajectories as VLN episodes.
fn scenes() -> Vec<(Arc<SceneContext>, Vec<EnvEpisode>)> {
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
        let params = TrajectoryParams {
            count: PER_SCENE,
            seed,
            ..TrajectoryParams::default()
        };
        let prep = sage_nav::trajectory::prepare(&scene, &params).unwrap();
        let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params).unwrap();
        let episodes: Vec<EnvEpisode> = set
            .trajectories
            .iter()
            .map(|t| EnvEpisode::from_trajectory(format!("{}-t{}", scene.name, t.id), t, "go"))
            .collect();
        let ctx = SceneContext::new(scene, bodies, &params.grid, params.cost).unwrap();
        (Arc::new(ctx), episodes)
    })
    .collect()
}

#[test]
fn the_oracle_reaches_every_goal_and_almost_never_touches() {
    let scenes = scenes();
    let total: usize = scenes.iter().map(|(_, e)| e.len()).sum();
    assert!(total >= 200, "{total} trajectories");
    for profile in ["wheeled"] {
        let (mut success, mut collisions, mut contact_episodes) = (0.0, 0.0, Vec::new());
        for (ctx, episodes) in &scenes {
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
            for e in episodes {
                let trace = run_episode(&mut env, &mut OracleAgent::new(0.25), e).unwrap();
                let m = score(ctx, &trace, Mode::Sage).unwrap();
                success += m.sr.unwrap();
                collisions += m.cr.unwrap();
                if m.cr.unwrap() > 0.0 || m.sr.unwrap() < 1.0 {
                    contact_episodes.push(format!(
                        "{} (CR {}, SR {})",
                        e.id,
                        m.cr.unwrap(),
                        m.sr.unwrap()
                    ));
                }
            }
        }
        let (sr, cr) = (success / total as f64, collisions / total as f64);
        eprintln!("{profile}: SR {sr:.3} CR {cr:.3} {contact_episodes:?}");
        assert_eq!(sr, 1.0, "{profile}: SR {sr}: {contact_episodes:?}");
        assert!(cr <= 0.03, "{profile}: CR {cr}: {contact_episodes:?}");
    }
}
