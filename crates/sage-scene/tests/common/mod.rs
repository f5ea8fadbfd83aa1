//! Meshes shared by the mesh tests: a tetrahedron, a GLB writer and a triangle comparison.

#![allow(dead_code)] // each test file uses its own subset

use glam::Vec3;
use sage_scene::TriMesh;
use serde_json::{Value, json};

/// A closed tetrahedron on the unit axes.
pub fn tetrahedron() -> TriMesh {
    TriMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    }
}

/// Asserts that `b` holds the triangles of `a` moved by `offset`, in order.
pub fn same_triangles(a: &TriMesh, b: &TriMesh, offset: Vec3) {
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

/// The JSON chunk and binary chunk of a GLB holding `mesh` under a node translated by `offset`.
pub fn glb_parts(mesh: &TriMesh, offset: Vec3) -> (Value, Vec<u8>) {
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
    let json = json!({
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
    (json, bin)
}

/// A GLB container of a JSON chunk (padded to 4 bytes here) and a binary chunk.
pub fn glb_container(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
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
    out.extend_from_slice(bin);
    out
}

/// A GLB holding `mesh` under a node translated by `offset`.
pub fn glb(mesh: &TriMesh, offset: Vec3) -> Vec<u8> {
    let (json, bin) = glb_parts(mesh, offset);
    glb_container(&serde_json::to_vec(&json).unwrap(), &bin)
}
