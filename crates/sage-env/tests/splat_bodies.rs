//! The environment's choice of bodies recovered from Gaussians (`EnvConfig::splat_bodies`):
//! the scene is loaded with it, `never` keeps the boxes where `auto` recovers parts, an
//! environment asking for another choice than its scene's is refused, and the default leaves
//! the configuration's JSON as it was.

use sage_env::{Env, EnvConfig, SceneContext, SensorConfig};
use sage_physics::SplatBodies;
use sage_scene::{LoadOptions, SplatLayout};
use sage_synth::{SceneKind, SynthConfig, generate};
use std::path::Path;
use std::sync::Arc;

/// A home written without meshes, as InteriorGS ships its scenes: `auto` recovers its objects'
/// bodies from their Gaussians.
fn meshless_scene(dir: &Path) {
    let mut scene = generate(&SynthConfig {
        seed: 5,
        kind: SceneKind::Home,
        rooms: 2,
        objects: 8,
        gaussians: 40_000,
        ..SynthConfig::default()
    })
    .unwrap();
    for o in &mut scene.objects {
        o.mesh = None;
    }
    scene.structure_mesh = None;
    scene.save(dir, SplatLayout::Compressed).unwrap();
}

fn load(dir: &Path, choice: SplatBodies) -> SceneContext {
    let cache = dir.join("cache");
    SceneContext::load_with_bodies(
        &dir.join("scene"),
        Some(cache),
        &LoadOptions::default(),
        choice,
    )
    .unwrap()
}

fn blind(choice: SplatBodies) -> EnvConfig {
    EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        splat_bodies: choice,
        ..EnvConfig::default()
    }
}

#[test]
fn never_keeps_the_boxes_where_auto_recovers_parts_and_a_mismatch_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    meshless_scene(&tmp.path().join("scene"));
    let auto = load(tmp.path(), SplatBodies::Auto);
    let never = load(tmp.path(), SplatBodies::Never);
    let objects = auto.scene.objects.len();
    assert_eq!(auto.splat_bodies, Some(SplatBodies::Auto));
    assert_eq!(never.splat_bodies, Some(SplatBodies::Never));
    let count = |ctx: &SceneContext, source: &str| ctx.body_sources.get(source).copied();
    assert!(
        count(&auto, "gaussians").is_some_and(|n| n > 0),
        "{:?}",
        auto.body_sources
    );
    assert_eq!(count(&never, "gaussians"), None, "{:?}", never.body_sources);
    assert_eq!(
        count(&never, "box"),
        Some(objects),
        "{:?}",
        never.body_sources
    );
    // The plain loader is `auto`, as it always was.
    let plain =
        SceneContext::load(&tmp.path().join("scene"), Some(tmp.path().join("cache"))).unwrap();
    assert_eq!(plain.body_sources, auto.body_sources);

    // An environment runs on the bodies its configuration asks for, or not at all.
    let (auto, never) = (Arc::new(auto), Arc::new(never));
    Env::new(auto.clone(), blind(SplatBodies::Auto)).unwrap();
    Env::new(never.clone(), blind(SplatBodies::Never)).unwrap();
    let e = Env::new(auto, blind(SplatBodies::Never))
        .err()
        .expect("a mismatch is refused")
        .to_string();
    assert!(
        e.contains("splat_bodies") && e.contains("'never'") && e.contains("'auto'"),
        "{e}"
    );
}

#[test]
fn the_default_choice_is_left_out_of_the_json_and_another_is_read_by_name() {
    let default = serde_json::to_value(EnvConfig::default()).unwrap();
    assert!(default.get("splat_bodies").is_none(), "{default}");
    let never =
        EnvConfig::with_overrides("sage", &serde_json::json!({"splat_bodies": "never"})).unwrap();
    assert_eq!(never.splat_bodies, SplatBodies::Never);
    assert_eq!(
        serde_json::to_value(&never).unwrap()["splat_bodies"],
        "never"
    );
    let e = EnvConfig::with_overrides("sage", &serde_json::json!({"splat_bodies": "sometimes"}))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("splat_bodies") && e.contains("sometimes") && e.contains("auto, always, never"),
        "{e}"
    );
}
