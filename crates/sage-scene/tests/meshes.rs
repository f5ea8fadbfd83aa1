//! Mesh readers: OBJ (tobj), glTF/GLB (gltf) and PLY, each against a mesh we know.

mod common;

use common::{glb, same_triangles, tetrahedron};
use glam::Vec3;
use sage_scene::TriMesh;
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
