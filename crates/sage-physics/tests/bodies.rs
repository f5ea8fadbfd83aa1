//! Collision bodies of a synthetic scene: decomposition quality, the cache, walls with their
//! openings cut, and the doors of the generator in their three states.

use glam::Vec3;
use sage_core::Pose;
use sage_physics::{
    AgentBody, BodyKind, Command, Decomposer, HullCache, PartSource, SceneBodies, WorkList, World,
    WorldOptions,
};
use sage_scene::{DoorState, HoleKind, Scene};
use sage_synth::{SceneKind, SynthConfig, generate};

/// A coarse V-HACD: the tests exercise the pipeline, not the decomposer's fine quality.
const COARSE: Decomposer = Decomposer::Vhacd {
    resolution: 24,
    concavity: 0.02,
    max_hulls: 16,
};

fn scene() -> Scene {
    generate(&SynthConfig {
        seed: 5,
        kind: SceneKind::Home,
        rooms: 4,
        objects: 24,
        gaussians: 2000,
        ..SynthConfig::default()
    })
    .unwrap()
}

#[test]
fn hulls_cover_the_meshes_and_come_back_from_the_cache() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let cache = HullCache::new(dir.path());
    let (first, r1) = SceneBodies::build(&scene, &COARSE, &cache).unwrap();
    let meshed = scene.objects.iter().filter(|o| o.mesh.is_some()).count();
    assert_eq!(r1.decomposed, meshed);
    assert_eq!(r1.cached, 0);
    assert_eq!(r1.objects.len(), meshed);
    for o in &r1.objects {
        assert!(o.hulls >= 1 && o.hulls <= 16, "{o:?}");
        // Hulls of a voxelised surface never fall far short of the volume it encloses.
        assert!(o.hull_volume > 0.6 * o.mesh_volume, "{o:?}");
    }
    let ratio = r1.volume_ratio();
    assert!(ratio > 0.9 && ratio < 2.0, "{ratio}");
    // Every mesh vertex lies inside or near its object's hull set (at most one coarse voxel out).
    for (b, o) in first.bodies.iter().zip(&scene.objects) {
        let mesh = o.mesh.as_ref().unwrap();
        let cell = o.obb.half_extents.max_element() * 2.0 / 24.0;
        let lo = b
            .parts
            .iter()
            .flat_map(|p| p.vertices.iter())
            .fold(Vec3::INFINITY, |m, v| m.min(*v));
        let hi = b
            .parts
            .iter()
            .flat_map(|p| p.vertices.iter())
            .fold(Vec3::NEG_INFINITY, |m, v| m.max(*v));
        for v in &mesh.positions {
            assert!(
                v.cmpge(lo - Vec3::splat(2.0 * cell)).all()
                    && v.cmple(hi + Vec3::splat(2.0 * cell)).all()
            );
        }
    }
    let (second, r2) = SceneBodies::build(&scene, &COARSE, &cache).unwrap();
    assert_eq!((r2.decomposed, r2.cached), (0, meshed));
    let parts = |b: &SceneBodies| b.bodies.iter().map(|b| b.parts.clone()).collect::<Vec<_>>();
    assert!(
        parts(&first) == parts(&second),
        "cached hulls differ from the computed ones"
    );
    assert!(
        second
            .bodies
            .iter()
            .take(meshed)
            .all(|b| b.source == PartSource::Cached)
    );
    // Other settings are another key.
    let finer = Decomposer::Vhacd {
        resolution: 20,
        concavity: 0.02,
        max_hulls: 16,
    };
    let empty = tempfile::tempdir().unwrap();
    std::fs::copy(
        cache.path(sage_physics::cache_key(
            scene.objects[0].mesh.as_ref().unwrap(),
            &COARSE,
        )),
        empty.path().join("x.hulls"),
    )
    .unwrap();
    let (_, r3) = SceneBodies::build(&scene, &finer, &HullCache::new(empty.path())).unwrap();
    assert_eq!(r3.cached, 0);
}

/// A cache folder that cannot be written (on Linux, one under `/proc`, where the file system
/// refuses new folders even to root, as a read-only mount does) does not stop the build: the
/// bodies are those a writable cache gives, every build decomposes them again, and the report
/// names the write error.
#[cfg(target_os = "linux")]
#[test]
fn a_cache_that_cannot_be_written_gives_the_same_bodies_and_says_so() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let (made, kept) = SceneBodies::build(&scene, &COARSE, &HullCache::new(dir.path())).unwrap();
    assert!(kept.unstored.is_empty());
    let meshed = scene.objects.iter().filter(|o| o.mesh.is_some()).count();
    let unwritable = HullCache::new("/proc/self/sage3d-hulls");
    for _ in 0..2 {
        let (bodies, report) = SceneBodies::build(&scene, &COARSE, &unwritable).unwrap();
        assert!(bodies == made, "the bodies differ from a writable cache's");
        assert_eq!((report.decomposed, report.cached), (meshed, 0));
        assert!(!report.unstored.is_empty());
        for e in &report.unstored {
            assert!(e.starts_with("/proc/self/sage3d-hulls"), "{e}");
        }
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(
            json["unstored"].as_array().unwrap().len(),
            report.unstored.len()
        );
    }
}

#[test]
fn a_damaged_cache_entry_is_made_anew_and_reported() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let cache = HullCache::new(dir.path());
    let (made, _) = SceneBodies::build(&scene, &COARSE, &cache).unwrap();
    let meshed = scene.objects.iter().filter(|o| o.mesh.is_some()).count();
    let key = |o: usize| sage_physics::cache_key(scene.objects[o].mesh.as_ref().unwrap(), &COARSE);
    // Cut short, another format version, another key's entry.
    let whole = std::fs::read(cache.path(key(3))).unwrap();
    std::fs::write(cache.path(key(3)), &whole[..whole.len() - 5]).unwrap();
    let mut version = std::fs::read(cache.path(key(5))).unwrap();
    version[8] = 9;
    std::fs::write(cache.path(key(5)), version).unwrap();
    std::fs::copy(cache.path(key(0)), cache.path(key(7))).unwrap();
    let pending = WorkList::of(&scene, &COARSE, &cache).unwrap();
    let listed: Vec<u32> = pending.meshes.iter().map(|m| m.instance).collect();
    let ids = [3, 5, 7].map(|o| scene.objects[o].id.0);
    assert_eq!(listed, ids, "the work list names the damaged entries");

    let (again, report) = SceneBodies::build(&scene, &COARSE, &cache).unwrap();
    assert_eq!((report.decomposed, report.cached), (3, meshed - 3));
    assert_eq!(report.remade.len(), 3);
    for (o, remade) in [3, 5, 7].into_iter().zip(&report.remade) {
        let file = cache.path(key(o)).display().to_string();
        assert!(remade.starts_with(&file), "{remade}");
    }
    assert!(
        report.remade[0].contains("file size"),
        "{}",
        report.remade[0]
    );
    assert!(report.remade[1].contains("version"), "{}", report.remade[1]);
    assert!(report.remade[2].contains("key"), "{}", report.remade[2]);
    let parts = |b: &SceneBodies| b.bodies.iter().map(|b| b.parts.clone()).collect::<Vec<_>>();
    assert!(
        parts(&made) == parts(&again),
        "the hulls made anew are those first made"
    );
    let (_, third) = SceneBodies::build(&scene, &COARSE, &cache).unwrap();
    assert_eq!((third.decomposed, third.cached), (0, meshed));
    assert!(third.remade.is_empty());
    assert!(
        WorkList::of(&scene, &COARSE, &cache)
            .unwrap()
            .meshes
            .is_empty()
    );
}

#[test]
fn a_damaged_coacd_entry_is_an_error_naming_the_file_and_object() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let cache = HullCache::new(dir.path());
    let coacd = Decomposer::Coacd {
        threshold: 0.05,
        max_hulls: 8,
    };
    // Every entry made offline (a box stands in for CoACD's hulls), then one damaged.
    for o in scene.objects.iter() {
        if let Some(mesh) = &o.mesh {
            let part = sage_physics::ConvexPart::from_obb(&o.obb).unwrap();
            cache
                .store(sage_physics::cache_key(mesh, &coacd), &[part])
                .unwrap();
        }
    }
    SceneBodies::build(&scene, &coacd, &cache).unwrap();
    let mesh = scene.objects[3].mesh.as_ref().unwrap();
    let path = cache.path(sage_physics::cache_key(mesh, &coacd));
    std::fs::write(&path, b"SAGEHULL\x01\0\0\0short").unwrap();
    let e = SceneBodies::build(&scene, &coacd, &cache)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&path.display().to_string())
            && e.contains("object 4")
            && e.contains("cannot be read")
            && e.contains("physics pending"),
        "{e}"
    );
}

#[test]
fn walls_are_cut_at_every_opening() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let (bodies, report) =
        SceneBodies::build(&scene, &COARSE, &HullCache::new(dir.path())).unwrap();
    assert!(report.openings_cut >= scene.floorplan.holes.len());
    let world = World::new(&scene, bodies, &WorldOptions::default());
    let qp = world.physics.query_pipeline();
    let walls_hit = |p: Vec3| {
        qp.intersect_point(p)
            .filter(|(h, _)| matches!(world.body_of(*h).map(|b| b.kind), Some(BodyKind::Wall(_))))
            .count()
    };
    for hole in &scene.floorplan.holes {
        let (lo, hi) = hole.bounds();
        let centre = (lo + hi) * 0.5;
        assert_eq!(
            walls_hit(centre),
            0,
            "{:?} hole at {centre} is not open",
            hole.kind
        );
        if hole.kind == HoleKind::Door {
            assert_eq!(
                walls_hit(centre.truncate().extend(0.3)),
                0,
                "door sill at {centre}"
            );
        }
        // Beside the opening, along the wall, the wall is solid.
        let along = (hole.profile[1] - hole.profile[0]).truncate().normalize();
        let beside = centre.truncate() + along * ((hi - lo).truncate().length() * 0.5 + 0.1);
        let inside_plan = scene.floorplan.walls.iter().any(|w| {
            let t = (beside - w.start).dot(w.direction());
            t > 0.05
                && t < w.length() - 0.05
                && (beside - w.start).perp_dot(w.direction()).abs() < 0.01
        });
        if inside_plan {
            assert!(
                walls_hit(beside.extend(1.0)) > 0,
                "no wall beside the hole at {beside}"
            );
        }
    }
}

#[test]
fn synthetic_doors_block_by_state() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let (bodies, _) = SceneBodies::build(&scene, &COARSE, &HullCache::new(dir.path())).unwrap();
    let mut world = World::new(&scene, bodies, &WorldOptions::default());
    let mut seen = Vec::new();
    for hole in scene.floorplan.doors() {
        let (lo, hi) = hole.bounds();
        let centre = ((lo + hi) * 0.5).truncate();
        let along = (hole.profile[1] - hole.profile[0]).truncate().normalize();
        let normal = along.perp();
        let state = hole.state.unwrap_or(DoorState::Closed);
        // Cross the doorway both ways through its middle; a door that blocks stops at least
        // one crossing short (the leaf is on one side of the wall or in the opening).
        let crossed = [1.0f32, -1.0].map(|s| {
            let start = centre - normal * s * 1.0;
            let yaw = (normal * s).y.atan2((normal * s).x);
            let mut a = AgentBody::new(
                "wheeled".parse().unwrap(),
                Pose::new(start.extend(0.0), yaw),
            );
            a.step(&mut world, &Command::Stop).unwrap();
            let from = a.pose.position.truncate();
            for _ in 0..8 {
                a.step(&mut world, &Command::Forward { distance: 0.25 })
                    .unwrap();
            }
            (a.pose.position.truncate() - from).dot(normal * s)
        });
        seen.push(state);
        match state {
            DoorState::Closed => assert!(
                crossed.iter().all(|&d| d < 1.0),
                "closed door crossed: {crossed:?}"
            ),
            DoorState::Open => assert!(
                crossed.iter().all(|&d| d > 1.5),
                "open door blocked: {crossed:?}"
            ),
            DoorState::HalfOpen => {}
        }
    }
    assert!(
        seen.contains(&DoorState::Closed) && seen.contains(&DoorState::Open),
        "{seen:?}"
    );
}

/// The eight corners and twelve triangles of an axis-aligned box.
fn box_mesh(lo: Vec3, hi: Vec3) -> sage_scene::TriMesh {
    let positions = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    sage_scene::TriMesh {
        positions,
        triangles,
    }
}

#[test]
fn published_parts_make_object_bodies_and_a_static_structure_body() {
    use sage_scene::{BodyParts, BodySource};
    let mut scene = scene();
    let o = &scene.objects[0];
    let (lo, hi) = (o.obb.aabb().min, o.obb.aabb().max);
    let mid = (lo + hi) * 0.5;
    scene.objects[0].body = Some(BodyParts {
        source: BodySource::Published,
        parts: vec![box_mesh(lo, mid), box_mesh(mid, hi)],
    });
    // Given parts all too flat to span a volume: the body is made from the mesh, as if none
    // were given, and the work list names the mesh as the build needs it.
    let flat = box_mesh(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
    scene.objects[1].body = Some(BodyParts {
        source: BodySource::Published,
        parts: vec![flat],
    });
    let coacd = Decomposer::Coacd {
        threshold: 0.05,
        max_hulls: 8,
    };
    let pending = WorkList::of(&scene, &coacd, &HullCache::new("no-cache-here")).unwrap();
    let listed: Vec<u32> = pending.meshes.iter().map(|m| m.instance).collect();
    let meshed: Vec<u32> = scene.objects[1..]
        .iter()
        .filter(|o| o.mesh.is_some())
        .map(|o| o.id.0)
        .collect();
    assert_eq!(listed, meshed);
    // A relative cache folder is written out whole: the decomposer runs in a working folder of
    // its own.
    let here = std::env::current_dir().unwrap();
    assert_eq!(pending.cache_dir, here.join("no-cache-here"));
    for m in &pending.meshes {
        assert!(m.cache_file.is_absolute(), "{}", m.cache_file.display());
        assert_eq!(m.cache_file.parent(), Some(pending.cache_dir.as_path()));
    }
    scene.structure_body = Some(BodyParts {
        source: BodySource::Published,
        parts: vec![
            box_mesh(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(-0.9, 5.0, 2.5)),
            // Too flat to span a volume: dropped.
            box_mesh(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
        ],
    });
    let dir = tempfile::tempdir().unwrap();
    let (bodies, report) =
        SceneBodies::build(&scene, &COARSE, &HullCache::new(dir.path())).unwrap();
    assert_eq!(report.sources[0].source, BodySource::Published);
    assert_eq!(report.sources[0].parts, 2);
    assert_eq!(bodies.bodies[1].source, PartSource::Decomposed);
    assert_eq!(report.structure_parts, 1);
    let s = bodies
        .bodies
        .iter()
        .find(|b| b.kind == BodyKind::Structure)
        .unwrap();
    assert_eq!((s.parts.len(), s.source), (1, PartSource::Given));
    assert_eq!(s.given, Some(BodySource::Published));
    assert_eq!(bodies.bodies[0].given, Some(BodySource::Published));
    let usda = sage_physics::usd::to_usda("t", &bodies, None);
    assert!(usda.contains("def Xform \"structure\""), "{usda}");
    assert_eq!(usda.matches("sage3d:bodySource = \"published\"").count(), 2);
    // The world holds the structure: a point inside the published wall hits it.
    let world = World::new(&scene, bodies, &WorldOptions::default());
    let qp = world.physics.query_pipeline();
    let hits = qp
        .intersect_point(Vec3::new(-0.95, 2.0, 1.0))
        .filter(|(h, _)| world.body_of(*h).map(|b| b.kind) == Some(BodyKind::Structure))
        .count();
    assert_eq!(hits, 1);
}
