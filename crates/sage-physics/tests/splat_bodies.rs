//! Bodies recovered from the Gaussians of a synthetic scene, against the bodies decomposed from
//! the same scene's meshes: volume IoU, the space under tables kept free, the choice of objects,
//! determinism. `sage3d bench bodies` measures the same on larger homes.

use glam::Vec3;
use sage_core::Pose;
use sage_physics::{
    AgentBody, AgentProfile, BodyKind, Command, ConvexPart, Decomposer, HullCache, SceneBodies,
    SplatBodies, SplatBodyParams, World, WorldOptions, splat_bodies, volume_iou,
};
use sage_scene::{BodySource, Scene};
use sage_synth::{SceneKind, SynthConfig, generate};

const COARSE: Decomposer = Decomposer::Vhacd {
    resolution: 32,
    concavity: 0.01,
    max_hulls: 16,
};

fn scene() -> Scene {
    generate(&SynthConfig {
        seed: 11,
        kind: SceneKind::Home,
        rooms: 2,
        objects: 14,
        gaussians: 120_000,
        ..SynthConfig::default()
    })
    .unwrap()
}

/// `full` as a capture shows it: its Gaussians alone, none given an instance, and no objects,
/// floorplan, map or structure.
fn capture_of(full: &Scene) -> Scene {
    let mut capture = Scene {
        objects: Vec::new(),
        floorplan: Default::default(),
        occupancy: None,
        structure_mesh: None,
        structure_body: None,
        ..full.clone()
    };
    capture.gaussians.instances.fill(0);
    capture
}

fn object_parts(bodies: &SceneBodies, i: usize) -> Vec<ConvexPart> {
    bodies
        .bodies
        .iter()
        .filter(|b| b.kind == BodyKind::Object(i))
        .flat_map(|b| b.parts.iter().cloned())
        .collect()
}

#[test]
fn recovered_bodies_match_the_mesh_hulls_and_keep_the_space_under_tables() {
    let truth_scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let cache = HullCache::new(dir.path());
    let (truth, _) = SceneBodies::build(&truth_scene, &COARSE, &cache).unwrap();

    // Every object here has a mesh: `auto` leaves them all alone.
    let mut auto = truth_scene.clone();
    let r =
        splat_bodies::attach(&mut auto, SplatBodies::Auto, &SplatBodyParams::default()).unwrap();
    assert_eq!(r.recovered, 0);
    assert_eq!(auto, truth_scene);

    let mut recovered = truth_scene.clone();
    let r = splat_bodies::attach(
        &mut recovered,
        SplatBodies::Always,
        &SplatBodyParams::default(),
    )
    .unwrap();
    assert_eq!(r.recovered + r.too_few_gaussians, truth_scene.objects.len());
    assert!(r.recovered >= truth_scene.objects.len() - 1, "{r:?}");
    let (derived, report) = SceneBodies::build(&recovered, &COARSE, &cache).unwrap();
    let gaussians = report
        .sources
        .iter()
        .filter(|o| o.source == BodySource::Gaussians)
        .count();
    assert_eq!(
        gaussians, r.recovered,
        "physics reports where each body came from"
    );

    let mut ious: Vec<f32> = (0..truth_scene.objects.len())
        .map(|i| volume_iou(&object_parts(&truth, i), &object_parts(&derived, i), 0.02))
        .collect();
    ious.sort_by(f32::total_cmp);
    let median = ious[ious.len() / 2];
    assert!(median >= 0.6, "median IoU {median}: {ious:?}");

    // Under a table or desk top, the box is solid but the recovered body is not.
    let mut tables = 0;
    for (i, o) in truth_scene.objects.iter().enumerate() {
        if !(o.category.ends_with("table") || o.category == "desk") {
            continue;
        }
        tables += 1;
        let below_top = o.obb.center - Vec3::Z * (o.obb.half_extents.z * 0.4);
        assert!(o.obb.contains(below_top, 0.0));
        let parts = object_parts(&derived, i);
        assert!(
            !parts.iter().any(|p| p.contains(below_top)),
            "{} is solid under its top",
            o.category
        );
        let top = o.obb.center + Vec3::Z * (o.obb.half_extents.z - 0.015);
        assert!(
            parts.iter().any(|p| p.contains(top)),
            "{} lost its top",
            o.category
        );
    }
    assert!(tables > 0, "the test scene should hold a table or a desk");
}

#[test]
fn recovered_bodies_do_not_depend_on_the_thread_count() {
    let s = scene();
    let run = |threads: usize| {
        let mut x = s.clone();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                splat_bodies::attach(&mut x, SplatBodies::Always, &SplatBodyParams::default())
            })
            .unwrap();
        x
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn bad_parameters_and_choices_are_refused() {
    let mut s = scene();
    for bad in [
        SplatBodyParams {
            voxel: 0.0,
            ..SplatBodyParams::default()
        },
        SplatBodyParams {
            reach: f32::NAN,
            ..SplatBodyParams::default()
        },
        SplatBodyParams {
            max_parts: 0,
            ..SplatBodyParams::default()
        },
    ] {
        assert!(splat_bodies::attach(&mut s, SplatBodies::Always, &bad).is_err());
    }
    let err = "sometimes".parse::<SplatBodies>().unwrap_err();
    assert!(err.contains("auto, always, never"), "{err}");
}

#[test]
fn a_bare_capture_gets_a_structure_body_with_its_air_left_free() {
    let full = scene();
    let mut capture = capture_of(&full);
    let r =
        splat_bodies::attach(&mut capture, SplatBodies::Auto, &SplatBodyParams::default()).unwrap();
    let body = capture
        .structure_body
        .as_ref()
        .expect("a body from the loose Gaussians");
    assert_eq!(body.source, BodySource::Gaussians);
    assert_eq!(r.structure_parts, body.parts.len());
    assert!(body.parts.len() > 10);
    // Walls, floor and ceiling enclose the rooms' air; it must not be filled.
    let parts: Vec<ConvexPart> = body
        .parts
        .iter()
        .filter_map(|m| ConvexPart::hull_of(&m.positions))
        .collect();
    let solid: f32 = parts.iter().map(ConvexPart::volume).sum();
    let b = full.gaussians.bounds();
    let total = (b.max - b.min).x * (b.max - b.min).y * (b.max - b.min).z;
    assert!(solid < 0.3 * total, "{solid} m³ of {total} m³ solid");
    let (bodies, _) = SceneBodies::build(
        &capture,
        &COARSE,
        &HullCache::new(tempfile::tempdir().unwrap().path()),
    )
    .unwrap();
    assert!(bodies.bodies.iter().any(|b| b.kind == BodyKind::Structure));
    // Never: no object's body comes from its Gaussians, but the capture keeps its walls (its
    // structure body is not an object's): without them nothing would stop an agent.
    let mut never = Scene {
        structure_body: None,
        ..capture.clone()
    };
    let r =
        splat_bodies::attach(&mut never, SplatBodies::Never, &SplatBodyParams::default()).unwrap();
    assert_eq!(r.recovered, 0);
    assert_eq!(never.structure_body, capture.structure_body);
}

/// A ground agent at `(x, y)` of `world`, after turning in place: what it touched.
fn touched_turning(world: &mut World, profile: &str, x: f32, y: f32) -> Vec<u32> {
    let profile: AgentProfile = profile.parse().unwrap();
    let mut agent = AgentBody::new(profile, Pose::new(Vec3::new(x, y, 0.0), 0.0));
    let report = agent.step(world, &Command::Turn { angle: 0.5 }).unwrap();
    report.touched.iter().map(|t| t.instance.0).collect()
}

#[test]
fn an_agent_standing_free_in_a_capture_touches_nothing_and_its_ceiling_caps_the_capture() {
    // Five rooms: over ten metres, so the body's voxels are coarser than a ground robot's
    // clearance, as in a captured home.
    let full = generate(&SynthConfig {
        seed: 11,
        kind: SceneKind::Home,
        rooms: 5,
        objects: 60,
        gaussians: 150_000,
        ..SynthConfig::default()
    })
    .unwrap();
    let mut capture = capture_of(&full);
    splat_bodies::attach(&mut capture, SplatBodies::Auto, &SplatBodyParams::default()).unwrap();
    let cache = tempfile::tempdir().unwrap();
    let world_of = |scene: &Scene| {
        let (bodies, _) =
            SceneBodies::build(scene, &COARSE, &HullCache::new(cache.path())).unwrap();
        let ceiling = bodies.ceiling_height;
        (World::new(scene, bodies, &WorldOptions::default()), ceiling)
    };
    let (mut truth, _) = world_of(&full);
    let (mut world, ceiling) = world_of(&capture);
    // The slab caps everything the capture holds: it has no wall heights to take a ceiling from.
    assert!(ceiling >= capture.gaussians.bounds().max.z);
    // Wherever the scene's own bodies leave a wide agent (h1, 0.30 m) free, the capture's
    // body leaves the wheeled robot (0.20 m) free: its floor is no obstacle.
    let b = full.gaussians.bounds();
    let mut free = 0;
    for i in 0..40 {
        for j in 0..40 {
            let x = b.min.x + (b.max.x - b.min.x) * (i as f32 + 0.5) / 40.0;
            let y = b.min.y + (b.max.y - b.min.y) * (j as f32 + 0.5) / 40.0;
            if full.floorplan.room_at(glam::Vec2::new(x, y)).is_none()
                || !touched_turning(&mut truth, "h1", x, y).is_empty()
            {
                continue;
            }
            free += 1;
            let touched = touched_turning(&mut world, "wheeled", x, y);
            assert!(
                touched.is_empty(),
                "at ({x}, {y}) the agent touched {touched:?}"
            );
        }
    }
    assert!(free > 100, "only {free} free places");
}
