//! Mesh readers: OBJ (tobj), glTF/GLB (gltf) and PLY, each against a mesh we know.

use glam::Vec3;
use sage_scene::TriMesh;
use std::path::Path;

fn tetrahedron() -> TriMesh {
    TriMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    }
}

fn same_triangles(a: &TriMesh, b: &TriMesh, offset: Vec3) {
    assert_eq!(a.triangles.len(), b.triangles.len());
    for t in 0..a.triangles.len() {
        let (x, y) = (a.triangle(t), b.triangle(t));
        for k in 0..3 {
            assert!(
                (x[k] + offset - y[k]).length() < 1e-6,
                "triangle {t}: {x:?} vs {y:?}"
            );
        }
    }
}

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

/// Builds a GLB holding `mesh` under a node translated by `offset`.
fn glb(mesh: &TriMesh, offset: Vec3) -> Vec<u8> {
    let mut bin = Vec::new();
    mesh.positions.iter().for_each(|p| {
        p.to_array()
            .iter()
            .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()))
    });
    let index_offset = bin.len();
    mesh.triangles
        .iter()
        .flatten()
        .for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
    let (lo, hi) = (mesh.aabb().min, mesh.aabb().max);
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": offset.to_array()}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": index_offset},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": bin.len() - index_offset}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": mesh.positions.len(), "type": "VEC3", "min": lo.to_array(), "max": hi.to_array()},
            {"bufferView": 1, "componentType": 5125, "count": mesh.triangles.len() * 3, "type": "SCALAR"}
        ]
    });
    let mut json = serde_json::to_vec(&json).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
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
