//! Placed objects before they become [`Object`]s: label, box, attributes, physics and the parts
//! that make up the mesh and carry the looks the Gaussians are sampled with.

use crate::shapes::{Part, first_use_order};
use crate::surfaces::{Frame, Geometry, Patch};
use glam::{Mat4, Quat, Vec3};
use sage_core::{Aabb, InstanceId, Obb};
use sage_scene::mesh::TriMesh;
use sage_scene::object::{Attributes, Object, PhysicsRole, RigidBody, normalize_category};

/// The first `ins_id` of a synthetic scene (InteriorGS numbers its instances from the thousands).
const FIRST_INS_ID: usize = 1001;

/// An object placed in the world.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Item {
    /// Human label.
    pub label: &'static str,
    /// The box tight around the parts.
    pub obb: Obb,
    /// Descriptive attributes.
    pub attributes: Attributes,
    /// Physics role.
    pub role: PhysicsRole,
    /// Rigid-body parameters.
    pub rigid_body: RigidBody,
    /// Parts in the world frame.
    pub parts: Vec<Part>,
}

impl Item {
    /// Places local-frame `parts` at `origin` turned by `yaw` about +Z, with the box fitted
    /// around them in the object's own frame.
    pub fn place(
        label: &'static str,
        parts: Vec<Part>,
        origin: Vec3,
        yaw: f32,
        attributes: Attributes,
        role: PhysicsRole,
        rigid_body: RigidBody,
    ) -> Item {
        let local = Aabb::from_points(parts.iter().flat_map(|p| p.mesh.positions.iter().copied()));
        let (lo, hi) = if local.is_empty() {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (local.min, local.max)
        };
        let rotation = Quat::from_rotation_z(yaw);
        let to_world = Mat4::from_rotation_translation(rotation, origin);
        let obb = Obb {
            center: to_world.transform_point3((lo + hi) * 0.5),
            half_extents: (hi - lo) * 0.5,
            yaw,
        };
        let parts = parts.iter().map(|p| p.transformed(&to_world)).collect();
        Item {
            label,
            obb,
            attributes,
            role,
            rigid_body,
            parts,
        }
    }

    /// The scene object for the `index`-th item (instance id and room are filled by
    /// `Scene::finish`).
    pub fn to_object(&self, index: usize) -> Object {
        let mut mesh = TriMesh::default();
        for p in &self.parts {
            mesh.append(&p.mesh);
        }
        Object {
            id: InstanceId::NONE,
            ins_id: (FIRST_INS_ID + index).to_string(),
            label: self.label.to_string(),
            category: normalize_category(self.label),
            obb: self.obb,
            room: None,
            attributes: self.attributes.clone(),
            role: self.role,
            rigid_body: self.rigid_body,
            mesh: Some(first_use_order(&mesh)),
            body: None,
        }
    }

    /// Appends the item's surfaces to sample Gaussians on: every triangle of its parts, textured
    /// in its own frame, except faces resting on the floor (they are never seen).
    pub fn patches(&self, out: &mut Vec<Patch>) {
        let frame = Frame {
            origin: self.obb.center,
            yaw: self.obb.yaw,
        };
        for part in &self.parts {
            for t in 0..part.mesh.triangles.len() {
                let corners = part.mesh.triangle(t);
                let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
                let on_floor = normal.z < 0.0
                    && normal.z * normal.z > 0.98 * normal.length_squared()
                    && corners.iter().all(|c| c.z < 0.005);
                if !on_floor {
                    out.push(Patch {
                        geometry: Geometry::Tri(corners),
                        look: part.look,
                        frame,
                    });
                }
            }
        }
    }
}
