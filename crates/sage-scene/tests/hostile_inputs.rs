//! Hostile scene files: names read from data that would become paths outside the scene folder
//! (an object's `ins_id`, a glTF buffer's `uri`), buffers that would be read without end, boxes
//! given inverted or twice with different values, and numbers beyond single precision. Each is
//! refused with an error naming the file and the field; the valid forms next to them still load.

mod common;

use common::{glb_parts, same_triangles, tetrahedron};
use glam::Vec3;
use sage_scene::formats::labels;
use sage_scene::occupancy::{OccupancyMap, parse_placement};
use sage_scene::{Scene, SplatLayout, TriMesh};
use sage_synth::{SynthConfig, generate};
use serde_json::{Value, json};
use std::path::Path;

/// The eight corners of the box 1 m wide, deep and high with its lower corner at the origin, as
/// `labels.json` gives them.
fn unit_box() -> Value {
    let bottom = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let corners: Vec<Value> = [0.0, 1.0]
        .iter()
        .flat_map(|z| bottom.map(|[x, y]| json!({"x": x, "y": y, "z": z})))
        .collect();
    Value::Array(corners)
}

/// A `labels.json` of one object per id, each a unit box.
fn labels_with(ids: &[Value]) -> String {
    let entries: Vec<Value> = ids
        .iter()
        .map(|id| json!({"ins_id": id, "label": "chair", "bounding_box": unit_box()}))
        .collect();
    Value::Array(entries).to_string()
}

#[test]
fn an_ins_id_that_is_not_one_file_name_is_refused_naming_the_entry() {
    let long = "7".repeat(labels::MAX_INS_ID + 1);
    let cases = [
        ("../../victim", "holds '/'"),
        ("", "is empty"),
        ("..", "starts with '.'"),
        (".hidden", "starts with '.'"),
        ("a/b", "holds '/'"),
        ("a\\b", "holds '\\\\'"),
        ("C:victim", "holds ':'"),
        ("x\0y", "holds '\\0'"),
        ("line\nbreak", "holds '\\n'"),
        (long.as_str(), "is longer than 128 bytes"),
        ("structure", "is the structure mesh's name"),
        ("Structure", "is the structure mesh's name"),
    ];
    for (id, why) in cases {
        let text = labels_with(&[json!("1"), json!(id)]);
        let e = labels::parse(&text).unwrap_err();
        assert_eq!(e.location(), "[1].ins_id", "{id:?}: {e}");
        assert!(
            e.message().contains(why) && e.message().contains("names its mesh file"),
            "{id:?}: {e}"
        );
    }
}

#[test]
fn ins_ids_that_are_one_file_name_stay_accepted() {
    // InteriorGS numbers its instances (as strings or numbers); other tools use words.
    let ids = [
        json!("1003"),
        json!(1004),
        json!("wall_3"),
        json!("sofa-2"),
        json!("Chair 1"),
        json!("椅子"),
        json!("v1.2"),
        json!("structure_2"),
        json!("7".repeat(labels::MAX_INS_ID)),
    ];
    let (objects, skipped) = labels::parse(&labels_with(&ids)).unwrap();
    assert_eq!(skipped, 0);
    let got: Vec<&str> = objects.iter().map(|o| o.ins_id.as_str()).collect();
    assert_eq!(got[..3], ["1003", "1004", "wall_3"]);
    // An entry without a box (an InteriorGS wall) names no file: its id is not a file name.
    let text = json!([{"ins_id": "../wall", "label": "wall"}]).to_string();
    assert_eq!(labels::parse(&text).unwrap().1, 1);
}

#[test]
fn loading_refuses_an_ins_id_that_leaves_the_mesh_folder() {
    let root = tempfile::tempdir().unwrap();
    let scene = root.path().join("a/scene");
    std::fs::create_dir_all(scene.join("meshes")).unwrap();
    // What `meshes/../../victim.obj` would read: a mesh outside the scene folder.
    let victim = root.path().join("a/victim.obj");
    let mut f = std::fs::File::create(&victim).unwrap();
    tetrahedron().write_obj(&mut f, "victim").unwrap();
    let labels_path = scene.join("labels.json");
    std::fs::write(
        &labels_path,
        labels_with(&[json!("1"), json!("../../victim")]),
    )
    .unwrap();
    let e = Scene::load(&scene).unwrap_err();
    assert_eq!(e.file(), Some(labels_path.as_path()));
    assert_eq!(e.location(), "[1].ins_id");
    assert!(e.message().starts_with("'../../victim' holds '/'"), "{e}");
    // The same folder with a plain id loads, its mesh found by that id.
    std::fs::write(&labels_path, labels_with(&[json!("1"), json!("victim")])).unwrap();
    std::fs::rename(&victim, scene.join("meshes/victim.obj")).unwrap();
    let (loaded, report) = Scene::load(&scene).unwrap();
    assert_eq!(report.meshes, 1);
    assert!(loaded.objects[1].mesh.is_some() && loaded.objects[0].mesh.is_none());
}

fn small() -> SynthConfig {
    SynthConfig {
        seed: 3,
        rooms: 2,
        objects: 6,
        gaussians: 4_000,
        ..SynthConfig::default()
    }
}

#[test]
fn saving_refuses_an_ins_id_that_leaves_the_folder_and_writes_nothing() {
    let mut scene = generate(&small()).unwrap();
    let k = scene.objects.iter().position(|o| o.mesh.is_some()).unwrap();
    scene.objects[k].ins_id = "../../victim".to_string();
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("a/out");
    let e = scene.save(&out, SplatLayout::Compressed).unwrap_err();
    assert_eq!(e.file(), Some(out.as_path()));
    let msg = e.to_string();
    assert!(
        msg.contains(&format!(
            "objects[{k}] (label '{}')",
            scene.objects[k].label
        )) && msg.contains("'../../victim' holds '/'")
            && msg.contains("nothing was written"),
        "{msg}"
    );
    // `out/meshes/../../victim.obj` is `a/victim.obj`.
    assert!(!root.path().join("a/victim.obj").exists());
    assert!(!out.exists());
    // An id without a mesh is refused too: labels.json would hold what loading refuses.
    let mut scene = generate(&small()).unwrap();
    scene.objects[k].mesh = None;
    scene.objects[k].ins_id = String::new();
    let e = scene.save(&out, SplatLayout::Compressed).unwrap_err();
    assert!(e.to_string().contains("ins_id '' is empty"), "{e}");
    assert!(!out.exists());
}

#[test]
fn valid_scenes_still_save_and_load_with_their_meshes() {
    let scene = generate(&small()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    scene.save(dir.path(), SplatLayout::Standard).unwrap();
    let (back, report) = Scene::load(dir.path()).unwrap();
    let with_mesh = scene.objects.iter().filter(|o| o.mesh.is_some()).count();
    assert!(with_mesh > 0);
    assert_eq!(report.meshes, with_mesh);
    for (a, b) in scene.objects.iter().zip(&back.objects) {
        assert_eq!((&a.ins_id, &a.mesh), (&b.ins_id, &b.mesh));
    }
    assert_eq!(back.occupancy, scene.occupancy);
}

#[test]
fn box_values_beyond_single_precision_are_named_as_such() {
    let with = |x: Value| {
        let mut corners = unit_box();
        corners[2]["x"] = x;
        json!([{"ins_id": "1", "label": "chair", "bounding_box": corners}]).to_string()
    };
    for big in [json!(1e300), json!("-1e300")] {
        let e = labels::parse(&with(big.clone())).unwrap_err();
        assert_eq!(e.location(), "[0].bounding_box[2].x", "{e}");
        assert!(
            e.message()
                .contains("out of the single-precision (f32) range")
                && !e.message().contains("expected a finite number"),
            "{big}: {e}"
        );
    }
    // Within f32 but beyond the coordinate bound, and not a number at all: as before.
    let e = labels::parse(&with(json!(2e4))).unwrap_err();
    assert!(e.message().contains("is beyond ±10000 m"), "{e}");
    let e = labels::parse(&with(json!("a"))).unwrap_err();
    assert!(e.message().starts_with("expected a finite number"), "{e}");
    // An earlier fault keeps its own error: here the y before the huge z.
    let mut corners = unit_box();
    corners[0]["y"] = json!("a");
    corners[0]["z"] = json!(1e300);
    let text = json!([{"ins_id": "1", "label": "c", "bounding_box": corners}]).to_string();
    let e = labels::parse(&text).unwrap_err();
    assert_eq!(e.location(), "[0].bounding_box[0].y", "{e}");
}

/// Writes `hostile.gltf` into `dir` holding the tetrahedron with its buffer at `uri` declared
/// `byte_length` long (the tetrahedron's own bytes when `None`), and returns its path and the
/// buffer's bytes.
fn gltf_at(dir: &Path, uri: &str, byte_length: Option<u64>) -> (std::path::PathBuf, Vec<u8>) {
    let (mut json, bin) = glb_parts(&tetrahedron(), Vec3::ZERO);
    json["buffers"][0] = json!({
        "uri": uri,
        "byteLength": byte_length.unwrap_or(bin.len() as u64),
    });
    let p = dir.join("hostile.gltf");
    std::fs::write(&p, serde_json::to_vec(&json).unwrap()).unwrap();
    (p, bin)
}

/// The error of loading the mesh `p`, checked to name it and the first buffer's uri.
fn buffer_error(p: &Path) -> String {
    let e = TriMesh::load(p).unwrap_err();
    assert_eq!(e.file(), Some(p), "{e}");
    assert_eq!(e.location(), "buffers[0].uri", "{e}");
    e.message().to_string()
}

#[test]
fn a_gltf_buffer_outside_the_mesh_folder_is_refused() {
    let root = tempfile::tempdir().unwrap();
    let meshes = root.path().join("scene/meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    let (_, bin) = gltf_at(&meshes, "x", None);
    std::fs::write(root.path().join("outside.bin"), &bin).unwrap();
    let cases = [
        ("../../outside.bin", "has a '..' component"),
        ("sub/../../../outside.bin", "has a '..' component"),
        ("..\\..\\outside.bin", "has a '..' component"),
        ("/dev/zero", "is an absolute path"),
        ("\\\\server\\share\\x.bin", "is an absolute path"),
        ("file:///dev/zero", "names a scheme"),
        ("C:outside.bin", "names a scheme or a drive"),
        ("", "is empty"),
        ("a\0.bin", "holds a control character"),
    ];
    for (uri, why) in cases {
        let (p, _) = gltf_at(&meshes, uri, None);
        let e = buffer_error(&p);
        assert!(
            e.contains(why) && e.contains("relative path"),
            "{uri:?}: {e}"
        );
    }
}

#[test]
fn a_gltf_buffer_beside_or_below_the_mesh_loads() {
    let dir = tempfile::tempdir().unwrap();
    for uri in ["tet.bin", "bin/tet.bin", "./tet.bin", "a..b.bin"] {
        let (p, bin) = gltf_at(dir.path(), uri, None);
        let bin_path = dir.path().join(uri);
        std::fs::create_dir_all(bin_path.parent().unwrap()).unwrap();
        std::fs::write(&bin_path, &bin).unwrap();
        same_triangles(&tetrahedron(), &TriMesh::load(&p).unwrap(), Vec3::ZERO);
    }
    // Bytes past the declared length are not read (nor needed).
    let (p, mut bin) = gltf_at(dir.path(), "long.bin", None);
    bin.extend_from_slice(&[0xff; 1000]);
    std::fs::write(dir.path().join("long.bin"), &bin).unwrap();
    same_triangles(&tetrahedron(), &TriMesh::load(&p).unwrap(), Vec3::ZERO);
}

#[cfg(unix)]
#[test]
fn a_gltf_buffer_that_is_not_a_regular_file_is_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    // A link inside the folder to a device that never ends: reading it would take all memory.
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.bin")).unwrap();
    let (p, _) = gltf_at(dir.path(), "zero.bin", None);
    let e = buffer_error(&p);
    assert!(e.starts_with("'zero.bin' is not a regular file"), "{e}");
    std::fs::create_dir(dir.path().join("folder.bin")).unwrap();
    let (p, _) = gltf_at(dir.path(), "folder.bin", None);
    assert!(buffer_error(&p).contains("is not a regular file"));
    let (p, _) = gltf_at(dir.path(), "missing.bin", None);
    assert!(buffer_error(&p).starts_with("'missing.bin' cannot be read"));
}

#[test]
fn a_gltf_buffer_is_checked_against_its_byte_length_and_the_limit_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    // A file shorter than its declared length.
    let (p, bin) = gltf_at(dir.path(), "short.bin", None);
    std::fs::write(dir.path().join("short.bin"), &bin[..bin.len() - 4]).unwrap();
    assert_eq!(
        buffer_error(&p),
        format!(
            "'short.bin' holds {} bytes; its byteLength declares {}",
            bin.len() - 4,
            bin.len()
        )
    );
    // A sparse file of 2 GiB, declared whole: over the default 1024 MB, refused from its
    // declared length alone (a read would take the 2 GiB first).
    let big = 2u64 << 30;
    let (p, _) = gltf_at(dir.path(), "huge.bin", Some(big));
    std::fs::File::create(dir.path().join("huge.bin"))
        .unwrap()
        .set_len(big)
        .unwrap();
    let e = TriMesh::load(&p).unwrap_err();
    assert_eq!(e.file(), Some(p.as_path()));
    assert_eq!(e.location(), "buffers[0].byteLength");
    assert_eq!(
        e.message(),
        "2048 MB, over the limit of 1024 MB on a mesh file; set the environment variable \
         SAGE3D_MAX_MESH_MB to raise it"
    );
    // Two buffers, each within the limit, together over it: refused before either is read.
    let (mut json, _) = glb_parts(&tetrahedron(), Vec3::ZERO);
    let half = 600u64 << 20;
    json["buffers"] = json!([
        {"uri": "huge.bin", "byteLength": half},
        {"uri": "huge.bin", "byteLength": half}
    ]);
    let p = dir.path().join("two.gltf");
    std::fs::write(&p, serde_json::to_vec(&json).unwrap()).unwrap();
    let e = TriMesh::load(&p).unwrap_err();
    assert_eq!(
        e.location(),
        "buffers[*].byteLength (the external buffers together)",
        "{e}"
    );
    assert!(e.message().starts_with("1200 MB, over the limit"), "{e}");
}

#[test]
fn a_mesh_file_that_is_not_a_regular_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["m.obj", "m.ply", "m.glb"] {
        let p = dir.path().join(name);
        std::fs::create_dir(&p).unwrap();
        let e = TriMesh::load(&p).unwrap_err();
        assert_eq!(e.file(), Some(p.as_path()));
        assert_eq!(e.message(), "not a regular file", "{e}");
    }
}

/// The error of loading a scene folder's occupancy map whose `occupancy.json` is `json`,
/// checked to name that file.
fn placement_error(json: &str) -> sage_core::Error {
    let dir = tempfile::tempdir().unwrap();
    let m = OccupancyMap::new(Vec3::ZERO, Vec3::new(1.0, 0.5, 2.0), 0.1).unwrap();
    m.save(dir.path()).unwrap();
    let json_path = dir.path().join("occupancy.json");
    std::fs::write(&json_path, json).unwrap();
    let e = OccupancyMap::load(dir.path()).unwrap_err();
    assert_eq!(e.file(), Some(json_path.as_path()), "{e}");
    e
}

#[test]
fn an_inverted_occupancy_box_is_refused_naming_the_axis() {
    let e = placement_error(r#"{"scale": 0.1, "min": [1, 0, 0], "max": [0, 0.5, 2]}"#);
    assert_eq!(e.location(), "min[0]/max[0]");
    assert_eq!(
        e.message(),
        "min[0] is 1 but max[0] is 0: the box is inverted (min is its lower corner, max its \
         upper)"
    );
    let e = placement_error(r#"{"scale": 0.1, "lower": [0, 0.5], "upper": [1, 0.25]}"#);
    assert_eq!(e.location(), "lower[1]/upper[1]");
    let e = parse_placement(r#"{"scale": 0.1, "min": [0, 0, 3], "max": [1, 1, 2]}"#).unwrap_err();
    assert_eq!(e.location(), "min[2]/max[2]");
    // A z only one corner gives is not compared; an empty extent is no inversion.
    parse_placement(r#"{"scale": 0.1, "min": [0, 0, 3], "max": [1, 1]}"#).unwrap();
    parse_placement(r#"{"scale": 0.1, "min": [0, 0, 0], "max": [0, 1, 0]}"#).unwrap();
}

#[test]
fn two_spellings_of_a_corner_that_disagree_are_refused_naming_both() {
    let e = placement_error(
        r#"{"scale": 0.1, "min": [0, 0, 0], "lower": [0, 0.2, 0], "max": [1, 0.5, 2]}"#,
    );
    assert_eq!(e.location(), "min[1]/lower[1]");
    assert_eq!(
        e.message(),
        "min[1] is 0 but lower[1] is 0.2: the two spellings of one corner disagree (keep one, \
         or make them equal)"
    );
    let e = placement_error(
        r#"{"scale": 0.1, "min": [0, 0, 0], "max": [1, 0.5, 2], "upper": [2, 0.5, 2]}"#,
    );
    assert_eq!(e.location(), "max[0]/upper[0]");
    // A bad value under the second spelling is an error too, not ignored.
    let e = placement_error(r#"{"scale": 0.1, "min": [0, 0], "lower": "x", "max": [1, 0.5]}"#);
    assert_eq!(e.location(), "lower");
}

#[test]
fn placements_sage3d_and_interiorgs_write_still_load() {
    // Both spellings, equal (what `OccupancyMap::save` writes), the map loads back unchanged.
    let dir = tempfile::tempdir().unwrap();
    let m = OccupancyMap::new(Vec3::new(-1.0, -0.5, 0.0), Vec3::new(1.0, 0.5, 2.0), 0.1).unwrap();
    m.save(dir.path()).unwrap();
    let text = std::fs::read_to_string(dir.path().join("occupancy.json")).unwrap();
    assert!(
        text.contains("\"lower\"") && text.contains("\"min\""),
        "{text}"
    );
    assert_eq!(OccupancyMap::load(dir.path()).unwrap(), m);
    // One spelling, 2 or 3 numbers, and the two spellings given at different lengths.
    for text in [
        r#"{"scale": 0.05, "min": [-5.7, -4.325, 0.0], "max": [5.7, 4.325, 2.8]}"#,
        r#"{"scale": 0.05, "lower": [-5.7, -4.325], "upper": [5.7, 4.325]}"#,
        r#"{"scale": 0.05, "min": [-5.7, -4.325], "lower": [-5.7, -4.325, 0], "max": [5.7, 4.325]}"#,
    ] {
        let (scale, lower, upper) = parse_placement(text).unwrap();
        assert_eq!((scale, lower[0], upper[1]), (0.05, -5.7, 4.325), "{text}");
    }
}

/// An OBJ's material file is read only from beside it: a `mtllib` naming a path outside the
/// folder, an absolute one or a device is treated as missing (never opened), and the one beside
/// the mesh gives each triangle its `Kd`.
#[test]
fn an_obj_reads_its_material_file_only_from_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    std::fs::create_dir(&meshes).unwrap();
    let red = "newmtl red\nKd 1 0 0\n";
    std::fs::write(meshes.join("red.mtl"), red).unwrap();
    std::fs::write(dir.path().join("outside.mtl"), red).unwrap();
    let obj = |mtllib: &str| {
        let path = meshes.join("m.obj");
        std::fs::write(
            &path,
            format!("mtllib {mtllib}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl red\nf 1 2 3\nf 1 3 4\n"),
        )
        .unwrap();
        sage_scene::mesh::obj_material_colors(&path).unwrap()
    };
    assert_eq!(obj("red.mtl"), Some(vec![Some([1.0, 0.0, 0.0]); 2]));
    let outside = dir.path().join("outside.mtl");
    for refused in [
        "../outside.mtl",
        outside.to_str().unwrap(),
        "/dev/zero",
        "missing.mtl",
    ] {
        assert_eq!(obj(refused), None, "{refused}");
    }
}
