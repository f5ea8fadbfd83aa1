//! Mesh readers: OBJ (tobj), glTF/GLB (gltf) and PLY, each against a mesh we know.

mod common;

use common::{glb, glb_container, glb_parts, same_triangles, tetrahedron};
use glam::Vec3;
use sage_scene::TriMesh;
use serde_json::json;
use std::path::Path;

#[test]
fn obj_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.obj");
    let mut f = std::fs::File::create(&p).unwrap();
    tetrahedron().write_obj(&mut f, "tet").unwrap();
    drop(f);
    same_triangles(&tetrahedron(), &TriMesh::load(&p).unwrap(), Vec3::ZERO);
}

#[test]
fn ply_ascii_and_binary_with_quads() {
    let dir = tempfile::tempdir().unwrap();
    let ascii = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    let p = dir.path().join("quad.ply");
    std::fs::write(&p, ascii).unwrap();
    let m = TriMesh::load(&p).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert!((m.area() - 1.0).abs() < 1e-6);

    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_index\nend_header\n".to_vec();
    for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]] {
        v.iter()
            .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
    }
    bin.push(3);
    [0u32, 1, 2]
        .iter()
        .for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
    let p = dir.path().join("tri.ply");
    std::fs::write(&p, &bin).unwrap();
    assert!((TriMesh::load(&p).unwrap().area() - 2.0).abs() < 1e-6);
}

#[test]
fn glb_applies_node_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.glb");
    let offset = Vec3::new(1.0, -2.0, 0.5);
    std::fs::write(&p, glb(&tetrahedron(), offset)).unwrap();
    same_triangles(&tetrahedron(), &TriMesh::load(&p).unwrap(), offset);
}

#[test]
fn bad_meshes_name_file_and_face() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.ply");
    std::fs::write(&p, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n").unwrap();
    let e = TriMesh::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("bad.ply") && e.contains("face[0]") && e.contains("out of range"),
        "{e}"
    );
    let e = TriMesh::load(Path::new("missing.obj"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.obj"), "{e}");
    let p = dir.path().join("trunc.glb");
    std::fs::write(&p, &glb(&tetrahedron(), Vec3::ZERO)[..40]).unwrap();
    let e = TriMesh::load(&p).unwrap_err().to_string();
    assert!(e.contains("trunc.glb"), "{e}");
    let p = dir.path().join("x.stl");
    std::fs::write(&p, "solid").unwrap();
    assert!(
        TriMesh::load(&p)
            .unwrap_err()
            .to_string()
            .contains("unknown mesh format")
    );
}

#[test]
fn vertices_beyond_the_coordinate_bound_are_refused_naming_their_line() {
    let dir = tempfile::tempdir().unwrap();
    // The vertices of the faces, renumbered by the reader, are traced back to their lines.
    let cases = [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1e30 0\nf 1 2 3\n",
            "line 3: vertex (0.0, 1e30, 0.0)",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 -2e4\nf 4 2 3\n",
            "line 4: vertex",
        ),
        (
            "v 0 0 0\nv 1e40 0 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: vertex (inf, 0.0, 0.0)",
        ),
        (
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: vertex (NaN, 0.0, 0.0)",
        ),
    ];
    for (k, (text, said)) in cases.into_iter().enumerate() {
        let p = dir.path().join(format!("far{k}.obj"));
        std::fs::write(&p, text).unwrap();
        let e = TriMesh::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("far{k}.obj: {said}")) && e.contains("within ±10000 m"),
            "{e}"
        );
    }
    // The bound itself is accepted.
    let p = dir.path().join("edge.obj");
    std::fs::write(&p, "v 0 0 0\nv 1e4 0 0\nv 0 -1e4 0\nf 1 2 3\n").unwrap();
    assert_eq!(TriMesh::load(&p).unwrap().positions.len(), 3);
    // PLY and glTF vertices are numbered by the file itself.
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 0 1e5\n3 0 1 2\n";
    let p = dir.path().join("far.ply");
    std::fs::write(&p, ply).unwrap();
    let e = TriMesh::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("far.ply: vertex[2]: vertex (0.0, 0.0, 100000.0)"),
        "{e}"
    );
    let p = dir.path().join("far.glb");
    std::fs::write(&p, glb(&tetrahedron(), Vec3::new(0.0, 2e4, 0.0))).unwrap();
    let e = TriMesh::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("far.glb") && e.contains("within ±10000 m"),
        "{e}"
    );
}

/// Loads a GLB made of `json` and `bin` and returns its error.
#[test]
fn a_bad_obj_line_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let good = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: [(&[u8], &str); 5] = [
        (
            b"v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: position parse error",
        ),
        (
            b"# tetra\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 q\r\n",
            "line 5: face parse error",
        ),
        (
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nvn 0 0",
            "line 5: normal parse error",
        ),
        (b"v 0 0 0\nv 1 0 \xff\nv 0 1 0\n", "line 2: read error"),
        (b"v 0 0\n", "line 1: position parse error"),
    ];
    for (k, (text, said)) in cases.into_iter().enumerate() {
        let p = dir.path().join(format!("bad{k}.obj"));
        std::fs::write(&p, text).unwrap();
        let e = TriMesh::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("bad{k}.obj")) && e.contains(said),
            "{e}"
        );
    }
    // A face past the vertices is found when its object ends: no line to name.
    let p = dir.path().join("past.obj");
    std::fs::write(&p, format!("{good}f 1 2 9\n")).unwrap();
    let e = TriMesh::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("past.obj") && e.contains("out of bounds") && !e.contains("line"),
        "{e}"
    );
    // The material library is not read: a missing one is no error.
    let p = dir.path().join("mtl.obj");
    std::fs::write(&p, format!("mtllib nowhere.mtl\n{good}f 1 2 3\n")).unwrap();
    assert_eq!(TriMesh::load(&p).unwrap().triangles.len(), 1);
}

fn glb_error(json: &serde_json::Value, bin: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("hostile.glb");
    std::fs::write(&p, glb_container(&serde_json::to_vec(json).unwrap(), bin)).unwrap();
    let e = TriMesh::load(&p).unwrap_err();
    assert_eq!(e.file(), Some(p.as_path()));
    e.to_string()
}

#[test]
fn glb_accessors_declaring_more_than_the_file_holds_are_refused() {
    // A sparse accessor without a buffer view stands for `count` zeros (and its few sparse
    // values): a million vertices here, from a file of a few hundred bytes.
    let (mut json, bin) = glb_parts(&tetrahedron(), Vec3::ZERO);
    json["accessors"][0] = json!({
        "componentType": 5126, "count": 1_000_000, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 1],
        "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5125},
                   "values": {"bufferView": 0}}
    });
    let primitive = json["meshes"][0]["primitives"][0].as_object_mut().unwrap();
    primitive.remove("indices");
    let e = glb_error(&json, &bin);
    assert!(
        e.ends_with(&format!(
            "meshes[0].primitives[0].attributes.POSITION: accessor 0 declares 1000000 elements \
             of 12 bytes; the file's buffers hold {} bytes",
            bin.len()
        )),
        "{e}"
    );
}

#[test]
fn glb_nodes_reached_twice_are_refused() {
    let (mut json, bin) = glb_parts(&tetrahedron(), Vec3::ZERO);
    // A node listed twice under its parent: each level of such nodes would double the mesh.
    json["nodes"] = json!([{"children": [1, 1]}, {"mesh": 0}]);
    let e = glb_error(&json, &bin);
    assert!(
        e.ends_with(
            "nodes[1]: reached twice from the scene (glTF nodes form trees: one parent \
             each, never their own ancestor)"
        ),
        "{e}"
    );
    // A node that is its own child: following it would never end.
    json["nodes"] = json!([{"mesh": 0, "children": [0]}]);
    assert!(glb_error(&json, &bin).contains("nodes[0]: reached twice"));
}

#[test]
fn ply_headers_declaring_more_than_the_file_holds_are_refused_before_allocating() {
    let header = |format: &str, vertices: u64, faces: u64| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\n\
             property float y\nproperty float z\nelement face {faces}\n\
             property list uchar int vertex_indices\nend_header\n"
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("hostile.ply");
    let load = |bytes: Vec<u8>| {
        std::fs::write(&p, bytes).unwrap();
        TriMesh::load(&p).unwrap_err().to_string()
    };
    // 10^9 vertices (12 GB of rows) declared over one vertex's bytes.
    let mut bin = header("binary_little_endian", 1_000_000_000, 0).into_bytes();
    bin.extend_from_slice(&[0; 12]);
    let e = load(bin);
    assert!(
        e.ends_with(
            "element 'vertex': file is truncated: 1000000000 rows need 12000000000 more bytes, \
             12 remain"
        ),
        "{e}"
    );
    // A count no file could hold is refused by the header alone.
    let e = load(header("binary_little_endian", u64::MAX / 4, 0).into_bytes());
    assert!(e.contains("element 'vertex' has a bad count"), "{e}");
    // 10^9 faces (rows of a list, read one by one) over one face's bytes.
    let mut bin = header("binary_little_endian", 3, 1_000_000_000).into_bytes();
    bin.extend_from_slice(&[0; 36]);
    bin.push(3);
    [0u32, 1, 2]
        .iter()
        .for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
    let e = load(bin);
    assert!(
        e.ends_with("element 'face' row 1: file is truncated"),
        "{e}"
    );
    // The same in ASCII.
    let e = load(format!("{}0 0 0\n", header("ascii", 1_000_000_000, 0)).into_bytes());
    assert!(
        e.ends_with("element 'vertex': file ends after 1 of 1000000000 rows"),
        "{e}"
    );
}
