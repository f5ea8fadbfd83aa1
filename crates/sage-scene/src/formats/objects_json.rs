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

use super::json::{array, parse_text};
use crate::floorplan::Floorplan;
use crate::object::{Attributes, Object, PhysicsRole, RigidBody};
use sage_core::{Error, Result, ResultExt};
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

/// Version written into the file.
pub const VERSION: u32 = 1;

/// Left-out physics fields keep the [`RigidBody`] defaults (and the static role).
#[derive(Debug, Serialize)]
struct Physics {
    role: PhysicsRole,
    mass: f32,
    friction: f32,
    restitution: f32,
}

fn default_mass() -> f32 {
    RigidBody::default().mass
}

fn default_friction() -> f32 {
    RigidBody::default().friction
}

#[derive(Debug, Serialize)]
struct Entry {
    ins_id: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    category: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    room: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    room_type: Option<String>,
    attributes: Attributes,
    #[serde(skip_serializing_if = "Option::is_none")]
    physics: Option<Physics>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mesh: Option<String>,
}

/// `v[key]` as a `T`, `None` when absent or null; an error names `key`.
fn optional<T: DeserializeOwned>(v: &Value, key: &str) -> Result<Option<T>> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => serde_json::from_value(x.clone())
            .map(Some)
            .map_err(|e| Error::format(key, e.to_string())),
    }
}

fn parse_physics(p: &Value) -> Result<Physics> {
    Ok(Physics {
        role: optional(p, "role")?.unwrap_or_default(),
        mass: optional(p, "mass")?.unwrap_or_else(default_mass),
        friction: optional(p, "friction")?.unwrap_or_else(default_friction),
        restitution: optional(p, "restitution")?.unwrap_or_default(),
    })
}

/// One entry, field by field, so that an error names the field at fault.
fn parse_entry(v: &Value) -> Result<Entry> {
    if !v.is_object() {
        return Err(Error::format("(entry)", "expected an object"));
    }
    let physics = match v.get("physics") {
        None | Some(Value::Null) => None,
        Some(p) if p.is_object() => Some(parse_physics(p).within("physics")?),
        Some(_) => return Err(Error::format("physics", "expected an object")),
    };
    Ok(Entry {
        ins_id: optional(v, "ins_id")?.ok_or_else(|| Error::format("ins_id", "missing"))?,
        category: optional(v, "category")?,
        room: optional(v, "room")?,
        room_type: optional(v, "room_type")?,
        attributes: optional(v, "attributes")?.unwrap_or_default(),
        physics,
        mesh: optional::<String>(v, "mesh")?
            .map(|m| sage_io::names::check_relative("mesh", &m).map(|()| m))
            .transpose()
            .within("mesh")?,
    })
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
    let root = parse_text(text)?;
    if !root.is_object() {
        return Err(Error::format(
            "(top level)",
            "expected an object with objects",
        ));
    }
    if let Some(v) = optional::<u32>(&root, "version")?.filter(|v| *v > VERSION) {
        return Err(Error::format(
            "version",
            format!("version {v} is newer than this reader ({VERSION})"),
        ));
    }
    let entries = match root.get("objects") {
        None | Some(Value::Null) => return Err(Error::format("objects", "missing")),
        Some(list) => array(list, "objects")?
            .iter()
            .enumerate()
            .map(|(i, v)| parse_entry(v).within(format!("objects[{i}]")))
            .collect::<Result<Vec<_>>>()?,
    };
    let mut applied = Applied {
        unmatched: 0,
        mesh_files: vec![None; objects.len()],
    };
    for (i, e) in entries.into_iter().enumerate() {
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
            // A number too large for f32 reads as infinity: finite bounds reject it.
            if !(p.mass > 0.0
                && p.mass.is_finite()
                && p.friction >= 0.0
                && p.friction.is_finite()
                && (0.0..=1.0).contains(&p.restitution))
            {
                return Err(Error::format(
                    format!("objects[{i}].physics"),
                    "expected finite mass > 0, finite friction >= 0 and restitution in [0, 1]",
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mesh_path_that_leaves_the_scene_folder_is_refused() {
        for mesh in ["/etc/passwd", "../../secret.obj", "meshes/../../x.obj"] {
            let text = serde_json::json!({"objects": [{"ins_id": "7", "mesh": mesh}]}).to_string();
            let e = apply(&text, &mut []).unwrap_err().to_string();
            assert!(
                e.contains("objects[0].mesh") && e.contains("not a path inside"),
                "{mesh}: {e}"
            );
        }
        let text = serde_json::json!({"objects": [{"ins_id": "7", "mesh": "meshes/7.obj"}]});
        assert!(apply(&text.to_string(), &mut []).is_ok());
    }
}
