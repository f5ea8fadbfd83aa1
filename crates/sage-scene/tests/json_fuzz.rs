//! Mutation fuzzing of a scene folder's JSON files (`labels.json`, `structure.json`,
//! `objects.json`, `occupancy.json`) and of the OBJ and GLB mesh readers: damaged files give an
//! `Err` naming the file and the field or line — never a panic — and every writer's output reads
//! back as what was written.
//! Run longer with `PROPTEST_CASES=10000 cargo test --release -p sage-scene --test json_fuzz`.

mod common;

use common::{glb, glb_container, glb_parts, same_triangles, tetrahedron};
use glam::{Vec2, Vec3};
use proptest::prelude::*;
use sage_core::{ErrorKind, Obb, Polygon2, Result};
use sage_scene::formats::{labels, objects_json, structure};
use sage_scene::{
    Attributes, DoorState, Floorplan, Hole, HoleKind, Object, OccupancyMap, PhysicsRole, RigidBody,
    Room, Scene, SplatLayout, StructureItem, TriMesh, Wall,
};
use sage_synth::{SynthConfig, generate};
use sage_testkit::{ODD, edit, mutate};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

/// The JSON files of the fixture scene folder.
const JSON_FILES: [&str; 4] = [
    "labels.json",
    "structure.json",
    "objects.json",
    "occupancy.json",
];

/// A small generated scene folder without Gaussians or meshes (their readers have their own
/// fuzz tests): name → bytes.
fn fixture() -> &'static BTreeMap<String, Vec<u8>> {
    static FILES: OnceLock<BTreeMap<String, Vec<u8>>> = OnceLock::new();
    FILES.get_or_init(|| {
        let mut scene = generate(&SynthConfig {
            seed: 3,
            rooms: 2,
            objects: 6,
            gaussians: 1000,
            ..SynthConfig::default()
        })
        .unwrap();
        for o in &mut scene.objects {
            o.mesh = None;
        }
        scene.structure_mesh = None;
        let dir = tempfile::tempdir().unwrap();
        scene.save(dir.path(), SplatLayout::Standard).unwrap();
        ["occupancy.png"]
            .into_iter()
            .chain(JSON_FILES)
            .map(|name| {
                (
                    name.to_string(),
                    std::fs::read(dir.path().join(name)).unwrap(),
                )
            })
            .collect()
    })
}

/// Asserts that a failed load names `file` and, for a format error, where in it.
fn assert_names(e: &sage_core::Error, file: &Path) {
    assert_eq!(e.file(), Some(file), "{e}");
    assert!(!e.message().is_empty(), "{e}");
    assert!(
        e.kind() != ErrorKind::Format || !e.location().is_empty(),
        "no field or line: {e}"
    );
}

/// A random box: centre, half extents, yaw.
fn obb() -> impl Strategy<Value = Obb> {
    (
        prop::array::uniform3(-50.0f32..50.0),
        prop::array::uniform3(0.05f32..3.0),
        -3.1f32..3.1,
    )
        .prop_map(|(c, h, yaw)| Obb {
            center: Vec3::from(c),
            half_extents: Vec3::from(h),
            yaw,
        })
}

fn object(ins_id: String, label: String, obb: Obb) -> Object {
    Object {
        id: sage_core::InstanceId::NONE,
        category: sage_scene::object::normalize_category(&label),
        ins_id,
        label,
        obb,
        room: None,
        attributes: Attributes::default(),
        role: PhysicsRole::Static,
        rigid_body: RigidBody::default(),
        mesh: None,
        body: None,
    }
}

fn point2() -> impl Strategy<Value = Vec2> {
    prop::array::uniform2(-1e4f32..1e4).prop_map(Vec2::from)
}

fn point3() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-1e4f32..1e4).prop_map(Vec3::from)
}

/// A point within half the coordinate bound: a mesh of such points, moved by another, stays
/// within the bound the mesh readers hold files to.
fn half_point3() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-5e3f32..5e3).prop_map(Vec3::from)
}

fn floorplan() -> impl Strategy<Value = Floorplan> {
    let room = (prop::collection::vec(point2(), 3..8), "[A-Za-z ]{1,12}").prop_map(
        |(points, room_type)| Room {
            profile: Polygon2::new(points),
            room_type,
        },
    );
    let wall = (point2(), point2(), 0.0f32..1.0, 0.0f32..5.0).prop_map(
        |(start, end, thickness, height)| Wall {
            start,
            end,
            thickness,
            height,
        },
    );
    let hole = (
        prop::collection::vec(point3(), 3..6),
        0.0f32..1.0,
        any::<bool>(),
        prop::option::of(prop_oneof![
            Just(DoorState::Open),
            Just(DoorState::Closed),
            Just(DoorState::HalfOpen)
        ]),
    )
        .prop_map(|(profile, thickness, door, state)| Hole {
            profile,
            thickness,
            kind: if door {
                HoleKind::Door
            } else {
                HoleKind::Window
            },
            state,
        });
    let item =
        ("[a-z]{1,8}", point3(), point3()).prop_map(|(label, position, size)| StructureItem {
            label,
            position,
            size,
        });
    (
        prop::collection::vec(room, 0..4),
        prop::collection::vec(wall, 0..6),
        prop::collection::vec(hole, 0..4),
        prop::collection::vec(item, 0..3),
    )
        .prop_map(|(rooms, walls, holes, items)| Floorplan {
            rooms,
            walls,
            holes,
            items,
            ceiling: None,
        })
}

/// A mesh of `n` vertices and triangles indexing them.
fn mesh() -> impl Strategy<Value = TriMesh> {
    (3usize..12).prop_flat_map(|n| {
        (
            prop::collection::vec(half_point3(), n),
            prop::collection::vec(prop::array::uniform3(0..n as u32), 1..10),
        )
            .prop_map(|(positions, triangles)| TriMesh {
                positions,
                triangles,
            })
    })
}

fn write_folder(dir: &Path, replace: Option<(&str, &[u8])>) {
    for (name, bytes) in fixture() {
        let bytes = match replace {
            Some((r, b)) if r == name => b,
            _ => bytes,
        };
        std::fs::write(dir.join(name), bytes).unwrap();
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 192, ..ProptestConfig::default() })]

    #[test]
    fn mutated_scene_json_never_panics_and_errors_name_the_file(
        file in 0..JSON_FILES.len(),
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let name = JSON_FILES[file];
        let bytes = mutate(&fixture()[name], &edits);
        let dir = tempfile::tempdir().unwrap();
        write_folder(dir.path(), Some((name, &bytes[..])));
        match Scene::load(dir.path()) {
            Ok((scene, _)) => {
                for o in &scene.objects {
                    prop_assert!(o.obb.center.is_finite() && o.obb.half_extents.is_finite());
                }
            }
            // A box too small for the image is a mismatch of two files: the error names the
            // image, whose size is checked, and says which box it was checked against.
            Err(e) if name == "occupancy.json" && e.file() == Some(&dir.path().join("occupancy.png")) => {
                prop_assert!(e.message().contains("box of occupancy.json"), "{}", e);
            }
            Err(e) => assert_names(&e, &dir.path().join(name)),
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_the_json_readers(text in ".{0,200}") {
        let located = |r: Result<()>| match r {
            Ok(()) => Ok(()),
            Err(e) if e.location().is_empty() => Err(TestCaseError::fail(format!("no location: {e}"))),
            Err(_) => Ok(()),
        };
        located(labels::parse(&text).map(|_| ()))?;
        located(structure::parse(&text).map(|_| ()))?;
        located(objects_json::apply(&text, &mut []).map(|_| ()))?;
        located(sage_scene::occupancy::parse_placement(&text).map(|_| ()))?;
    }

    #[test]
    fn structure_round_trips(f in floorplan()) {
        let back = structure::parse(&structure::to_json(&f).to_string()).unwrap();
        prop_assert_eq!(back, f);
    }

    #[test]
    fn labels_round_trip(boxes in prop::collection::vec((obb(), "[ -~]{0,12}"), 1..6)) {
        let objects: Vec<Object> = boxes
            .into_iter()
            .enumerate()
            .map(|(i, (b, label))| object(format!("{}", 1000 + i), label, b))
            .collect();
        let (back, skipped) = labels::parse(&labels::to_json(&objects).to_string()).unwrap();
        prop_assert_eq!(skipped, 0);
        prop_assert_eq!(back.len(), objects.len());
        for (a, b) in objects.iter().zip(&back) {
            prop_assert_eq!((&a.ins_id, &a.label, &a.category), (&b.ins_id, &b.label, &b.category));
            // A box may come back with another yaw and its axes swapped: compare corners.
            for c in a.obb.corners() {
                let nearest = b.obb.corners().iter().map(|d| d.distance(c)).fold(f32::MAX, f32::min);
                prop_assert!(nearest < 1e-3, "corner {} of {}: {}", c, a.ins_id, nearest);
            }
        }
    }

    #[test]
    fn objects_json_round_trips(
        extras in prop::collection::vec(
            (
                "[a-z_]{1,10}",
                prop::option::of(0usize..3),
                prop::option::of("[a-z]{1,6}"),
                prop_oneof![Just(PhysicsRole::Static), Just(PhysicsRole::Movable), Just(PhysicsRole::Articulated)],
                (0.01f32..500.0, 0.0f32..2.0, 0.0f32..=1.0),
            ),
            1..5,
        ),
        f in floorplan(),
    ) {
        let b = Obb { center: Vec3::ZERO, half_extents: Vec3::ONE, yaw: 0.0 };
        let written: Vec<Object> = extras
            .iter()
            .enumerate()
            .map(|(i, (category, room, color, role, (mass, friction, restitution)))| Object {
                category: category.clone(),
                room: *room,
                attributes: Attributes { color: color.clone(), ..Attributes::default() },
                role: *role,
                rigid_body: RigidBody { mass: *mass, friction: *friction, restitution: *restitution },
                ..object(i.to_string(), "thing".into(), b)
            })
            .collect();
        let mut read: Vec<Object> = (0..written.len())
            .map(|i| object(i.to_string(), "thing".into(), b))
            .collect();
        let text = objects_json::to_json(&written, &f).to_string();
        let applied = objects_json::apply(&text, &mut read).unwrap();
        prop_assert_eq!(applied.unmatched, 0);
        prop_assert_eq!(read, written);
    }

    #[test]
    fn occupancy_round_trips(
        lower in prop::array::uniform3(-100.0f32..100.0),
        size in prop::array::uniform2(0.2f32..4.0),
        scale in 0.02f32..0.5,
        seed in any::<u64>(),
    ) {
        let lower = Vec3::from(lower);
        let upper = lower + Vec3::new(size[0], size[1], 3.0);
        let mut m = OccupancyMap::new(lower, upper, scale).unwrap();
        for (i, c) in m.cells.iter_mut().enumerate() {
            *c = [0, 127, 255][(seed >> (i % 60)) as usize % 3];
        }
        let dir = tempfile::tempdir().unwrap();
        m.save(dir.path()).unwrap();
        let back = OccupancyMap::load(dir.path()).unwrap();
        // The double-precision placement may come back an ulp off: the JSON parser does not
        // round every decimal exactly. Everything else is exact.
        for (a, b) in back.exact_placement.iter().zip(m.exact_placement) {
            prop_assert!((a - b).abs() <= f64::EPSILON * b.abs(), "{} vs {}", a, b);
        }
        prop_assert_eq!(OccupancyMap { exact_placement: m.exact_placement, ..back }, m);
    }

    #[test]
    fn obj_and_glb_round_trip(m in mesh(), offset in half_point3()) {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("m.obj");
        let mut text = Vec::new();
        m.write_obj(&mut text, "m").unwrap();
        std::fs::write(&obj, text).unwrap();
        // OBJ reading keeps triangle order but re-indexes vertices, so triangles are compared.
        same_triangles(&m, &TriMesh::load(&obj).unwrap(), Vec3::ZERO);
        let p = dir.path().join("m.glb");
        std::fs::write(&p, glb(&m, offset)).unwrap();
        let back = TriMesh::load(&p).unwrap();
        prop_assert_eq!(back.triangles, m.triangles.clone());
        for (a, b) in m.positions.iter().zip(&back.positions) {
            prop_assert!((*a + offset - *b).length() <= 1e-3 * (1.0 + b.length()));
        }
    }

    #[test]
    fn mutated_obj_files_never_panic(
        edits in prop::collection::vec((any::<usize>(), 0..ODD.len()), 1..4),
        keep in any::<usize>(),
    ) {
        let mut text = Vec::new();
        tetrahedron().write_obj(&mut text, "tet").unwrap();
        // Words of the text replaced by odd tokens (bare, as OBJ has no quoting), then a cut.
        let mut words: Vec<String> = String::from_utf8(text).unwrap().split(' ').map(str::to_string).collect();
        for (at, odd) in edits {
            let n = words.len();
            words[at % n] = ODD[odd].trim_matches('"').to_string();
        }
        let mut bytes = words.join(" ").into_bytes();
        bytes.truncate(keep % (bytes.len() + 1));
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.obj");
        std::fs::write(&p, &bytes).unwrap();
        match TriMesh::load(&p) {
            Ok(m) => prop_assert!(m.validate().is_ok()),
            Err(e) => assert_names(&e, &p),
        }
    }

    #[test]
    fn mutated_glb_files_never_panic(
        edits in prop::collection::vec(edit(), 1..4),
        flip in prop::option::of((any::<usize>(), any::<u8>())),
    ) {
        // The JSON chunk is edited as a document, the container's bytes (lengths, magic,
        // binary chunk) by an optional flip.
        let (json, bin) = glb_parts(&tetrahedron(), Vec3::ZERO);
        let mut bytes = glb_container(&mutate(&serde_json::to_vec(&json).unwrap(), &edits), &bin);
        if let Some((at, byte)) = flip {
            let i = at % bytes.len();
            bytes[i] = byte;
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.glb");
        std::fs::write(&p, &bytes).unwrap();
        match TriMesh::load(&p) {
            Ok(m) => prop_assert!(m.validate().is_ok()),
            Err(e) => assert_names(&e, &p),
        }
    }
}

/// Loads the fixture folder with `name` edited by `f`; returns the error text.
fn load_error(name: &str, f: impl FnOnce(&mut Value)) -> String {
    let mut doc: Value = serde_json::from_slice(&fixture()[name]).unwrap();
    f(&mut doc);
    let dir = tempfile::tempdir().unwrap();
    write_folder(dir.path(), Some((name, doc.to_string().as_bytes())));
    let e = Scene::load(dir.path()).map(|_| ()).unwrap_err();
    assert_names(&e, &dir.path().join(name));
    e.to_string()
}

/// A file of the fixture, an edit of it and the error text it must give.
type Case = (&'static str, fn(&mut Value), &'static str);

#[test]
fn specific_bad_values_name_the_field() {
    let cases: [Case; 7] = [
        (
            "labels.json",
            |d| d[0]["bounding_box"][0]["x"] = serde_json::json!(1e39),
            // Finite in the file's double precision: the error says which range it leaves.
            "[0].bounding_box[0].x: 1e+39 is out of the single-precision (f32) range",
        ),
        (
            "labels.json",
            |d| d[1]["ins_id"] = d[0]["ins_id"].clone(),
            "[1].ins_id: duplicate ins_id",
        ),
        (
            "structure.json",
            |d| d["walls"][0]["height"] = serde_json::json!("NaN"),
            "walls[0].height: expected a finite number",
        ),
        (
            "objects.json",
            |d| d["objects"][0]["physics"]["mass"] = serde_json::json!("heavy"),
            "objects[0].physics.mass: invalid type: string \"heavy\"",
        ),
        (
            "objects.json",
            |d| d["objects"][0]["physics"]["friction"] = serde_json::json!(1e39),
            "objects[0].physics: expected finite mass > 0, finite friction >= 0",
        ),
        (
            "objects.json",
            |d| {
                d["objects"][1].as_object_mut().unwrap().remove("ins_id");
            },
            "objects[1].ins_id: missing",
        ),
        (
            "occupancy.json",
            |d| d["scale"] = serde_json::json!(1e39),
            "scale: missing or not a positive number",
        ),
    ];
    for (name, edit, want) in cases {
        let e = load_error(name, edit);
        assert!(e.contains(&format!("{name}: {want}")), "{e}");
    }
}

#[test]
fn a_glb_naming_a_missing_position_accessor_is_an_error() {
    // The glTF reader's validation used to panic on this index instead of rejecting it.
    let (mut json, bin) = glb_parts(&tetrahedron(), Vec3::ZERO);
    json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = serde_json::json!(5);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.glb");
    std::fs::write(&p, glb_container(&serde_json::to_vec(&json).unwrap(), &bin)).unwrap();
    let e = TriMesh::load(&p).unwrap_err();
    assert_names(&e, &p);
    assert_eq!(
        e.location(),
        "meshes[0].primitives[0].attributes.POSITION",
        "{e}"
    );
}
