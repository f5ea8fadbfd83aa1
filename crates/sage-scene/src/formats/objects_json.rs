//! Our `objects.json`: per-instance extras that InteriorGS lacks — category, room, attributes
//! (colour, material, state, size), physics role and rigid-body parameters, mesh file.
//!
//! ```json
//! {"format": "sage3d-objects", "version": 1, "frame": "W: right-handed, Z up, metres",
//!  "objects": [{"ins_id": "1001", "category": "chair", "room": 2, "room_type": "Kitchen",
//!               "attributes": {"color": "red", "material": "wood", "size": "medium"},
//!               "physics": {"role": "movable", "mass": 6.0, "friction": 0.5, "restitution": 0.0},
//!               "mesh": "meshes/1001.obj"}]}
//! ```
//! Entries are matched to `labels.json` by `ins_id`; fields left out keep their defaults.

use super::json::parse_text;
use crate::floorplan::Floorplan;
use crate::object::{Attributes, Object, PhysicsRole, RigidBody};
use sage_core::{Error, Result};
use serde::{Deserialize, Serialize};
use serde_json::Value;

/// Version written into the file.
pub const VERSION: u32 = 1;

#[derive(Debug, Serialize, Deserialize)]
struct Physics {
    #[serde(default)]
    role: PhysicsRole,
    #[serde(default = "default_mass")]
    mass: f32,
    #[serde(default = "default_friction")]
    friction: f32,
    #[serde(default)]
    restitution: f32,
}

fn default_mass() -> f32 {
    RigidBody::default().mass
}

fn default_friction() -> f32 {
    RigidBody::default().friction
}

#[derive(Debug, Serialize, Deserialize)]
struct Entry {
    ins_id: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    category: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    room: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    room_type: Option<String>,
    #[serde(default)]
    attributes: Attributes,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    physics: Option<Physics>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mesh: Option<String>,
}

#[derive(Debug, Deserialize)]
struct File {
    #[serde(default)]
    version: Option<u32>,
    objects: Vec<Entry>,
}

/// What applying `objects.json` found beyond the attributes it set.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Applied {
    /// Entries whose `ins_id` names no object.
    pub unmatched: usize,
    /// Per object (same index): the mesh file the entry names, relative to the scene folder.
    pub mesh_files: Vec<Option<String>>,
}

/// Applies `objects.json` to objects read from `labels.json`.
pub fn apply(text: &str, objects: &mut [Object]) -> Result<Applied> {
    let value = parse_text(text)?;
    let file: File =
        serde_json::from_value(value).map_err(|e| Error::format("objects", e.to_string()))?;
    if let Some(v) = file.version.filter(|v| *v > VERSION) {
        return Err(Error::format(
            "version",
            format!("version {v} is newer than this reader ({VERSION})"),
        ));
    }
    let mut applied = Applied {
        unmatched: 0,
        mesh_files: vec![None; objects.len()],
    };
    for (i, e) in file.objects.into_iter().enumerate() {
        let Some(k) = objects.iter().position(|o| o.ins_id == e.ins_id) else {
            applied.unmatched += 1;
            continue;
        };
        let o = &mut objects[k];
        applied.mesh_files[k] = e.mesh;
        if let Some(c) = e.category {
            o.category = c;
        }
        o.room = e.room;
        o.attributes = e.attributes;
        if let Some(p) = e.physics {
            if !(p.mass > 0.0
                && p.mass.is_finite()
                && p.friction >= 0.0
                && (0.0..=1.0).contains(&p.restitution))
            {
                return Err(Error::format(
                    format!("objects[{i}].physics"),
                    "expected mass > 0, friction >= 0 and restitution in [0, 1]",
                ));
            }
            o.role = p.role;
            o.rigid_body = RigidBody {
                mass: p.mass,
                friction: p.friction,
                restitution: p.restitution,
            };
        }
    }
    Ok(applied)
}

/// The objects' extras as `objects.json`.
pub fn to_json(objects: &[Object], floorplan: &Floorplan) -> Value {
    let entries: Vec<Entry> = objects
        .iter()
        .map(|o| Entry {
            ins_id: o.ins_id.clone(),
            category: Some(o.category.clone()),
            room: o.room,
            room_type: o
                .room
                .and_then(|r| floorplan.rooms.get(r))
                .map(|r| r.room_type.clone()),
            attributes: o.attributes.clone(),
            physics: Some(Physics {
                role: o.role,
                mass: o.rigid_body.mass,
                friction: o.rigid_body.friction,
                restitution: o.rigid_body.restitution,
            }),
            mesh: o.mesh.as_ref().map(|_| format!("meshes/{}.obj", o.ins_id)),
        })
        .collect();
    serde_json::json!({
        "format": "sage3d-objects",
        "version": VERSION,
        "frame": "W: right-handed, Z up, metres",
        "objects": entries,
    })
}
