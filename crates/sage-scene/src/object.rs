//! Objects: the annotated instances of a scene (furniture, doors, windows, small items).

use crate::mesh::TriMesh;
use sage_core::{InstanceId, Obb};
use serde::{Deserialize, Serialize};

/// How an object takes part in physics (SPEC §6).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhysicsRole {
    /// Fixed in the world (default).
    #[default]
    Static,
    /// A dynamic rigid body that agents can push.
    Movable,
    /// Jointed (a door on a revolute hinge).
    Articulated,
}

/// The state of a door leaf.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DoorState {
    /// Swung fully open (90°): the opening is passable.
    Open,
    /// Shut: the opening is blocked.
    Closed,
    /// Swung to 45°: partly blocking.
    HalfOpen,
}

impl DoorState {
    /// All states, in a fixed order.
    pub const ALL: [DoorState; 3] = [DoorState::Open, DoorState::Closed, DoorState::HalfOpen];

    /// The leaf's swing angle from closed, radians.
    pub fn swing_angle(self) -> f32 {
        match self {
            DoorState::Open => std::f32::consts::FRAC_PI_2,
            DoorState::Closed => 0.0,
            DoorState::HalfOpen => std::f32::consts::FRAC_PI_4,
        }
    }

    /// The word used in files (`open`, `closed`, `half-open`).
    pub fn as_str(self) -> &'static str {
        match self {
            DoorState::Open => "open",
            DoorState::Closed => "closed",
            DoorState::HalfOpen => "half-open",
        }
    }

    /// Parses `open`, `closed` or `half-open` (also `half_open`).
    pub fn parse(s: &str) -> Option<DoorState> {
        match s.to_ascii_lowercase().as_str() {
            "open" => Some(DoorState::Open),
            "closed" => Some(DoorState::Closed),
            "half-open" | "half_open" => Some(DoorState::HalfOpen),
            _ => None,
        }
    }
}

/// Descriptive attributes an instruction can refer to (SPEC §4 `objects.json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Attributes {
    /// Colour name, e.g. `red`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<String>,
    /// Material name, e.g. `wood`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
    /// State, e.g. `open`, `closed`, `half-open`, `on`, `off`, `empty`, `full`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<String>,
    /// Size class (`small`, `medium`, `large`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<String>,
}

/// Rigid-body parameters (used by the physics layer when the role is movable or articulated).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidBody {
    /// Mass in kilograms.
    pub mass: f32,
    /// Coulomb friction coefficient.
    pub friction: f32,
    /// Restitution (bounciness), 0–1.
    pub restitution: f32,
}

impl Default for RigidBody {
    fn default() -> Self {
        RigidBody {
            mass: 10.0,
            friction: 0.5,
            restitution: 0.0,
        }
    }
}

/// Where an object's collision body comes from, in the order a scene prefers them
/// (docs/physics.md, "Body sources").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BodySource {
    /// Convex parts read from a published collision file (SAGE-Bench's
    /// `{scene}_collision.usd`): the bodies the paper's agents collided with.
    Published,
    /// Convex decomposition of the object's own mesh.
    Mesh,
    /// Recovered from the object's own Gaussians (no mesh and no published body).
    Gaussians,
    /// The object's oriented box (nothing better was available).
    Box,
}

impl BodySource {
    /// The word used in reports and files (`published`, `mesh`, `gaussians`, `box`).
    pub fn as_str(self) -> &'static str {
        match self {
            BodySource::Published => "published",
            BodySource::Mesh => "mesh",
            BodySource::Gaussians => "gaussians",
            BodySource::Box => "box",
        }
    }
}

/// An object's collision body given as ready convex parts (each a closed, convex triangle
/// mesh in W), instead of decomposed from its mesh: read from a published collision file or
/// recovered from the Gaussians.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyParts {
    /// Where the parts came from ([`BodySource::Published`] or [`BodySource::Gaussians`]).
    pub source: BodySource,
    /// The convex parts, world frame.
    pub parts: Vec<TriMesh>,
}

/// One annotated object of a scene, in the world frame W.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Dense id inside the scene (see [`InstanceId`]).
    pub id: InstanceId,
    /// The source id (`ins_id` of `labels.json`), kept verbatim.
    pub ins_id: String,
    /// The source label as written (`"Dining Chair"`).
    pub label: String,
    /// The normalised category (`"dining_chair"`): lower case, words joined by `_`.
    pub category: String,
    /// Oriented bounding box.
    pub obb: Obb,
    /// Index of the room (in the floorplan) that holds the box centre, if any.
    pub room: Option<usize>,
    /// Descriptive attributes.
    pub attributes: Attributes,
    /// Physics role.
    pub role: PhysicsRole,
    /// Rigid-body parameters.
    pub rigid_body: RigidBody,
    /// Triangle mesh in world coordinates, when the scene has one for this object.
    pub mesh: Option<TriMesh>,
    /// Ready convex parts of its collision body, when given (they win over the mesh's
    /// decomposition: see [`Object::body_source`]).
    pub body: Option<BodyParts>,
}

impl Object {
    /// Where this object's collision body comes from: its given parts, else its mesh, else its
    /// box.
    pub fn body_source(&self) -> BodySource {
        match (&self.body, &self.mesh) {
            (Some(b), _) => b.source,
            (None, Some(m)) if !m.triangles.is_empty() => BodySource::Mesh,
            _ => BodySource::Box,
        }
    }

    /// The door state, for doors whose `state` attribute names one.
    pub fn door_state(&self) -> Option<DoorState> {
        self.attributes.state.as_deref().and_then(DoorState::parse)
    }
}

/// Normalises a free-text label into a category: lower case, runs of non-alphanumerics → `_`.
pub fn normalize_category(label: &str) -> String {
    let mut out = String::with_capacity(label.len());
    for ch in label.trim().chars() {
        if ch.is_alphanumeric() {
            out.extend(ch.to_lowercase());
        } else if !out.ends_with('_') && !out.is_empty() {
            out.push('_');
        }
    }
    while out.ends_with('_') {
        out.pop();
    }
    if out.is_empty() {
        "unknown".to_string()
    } else {
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn categories_normalise() {
        assert_eq!(normalize_category("Dining Chair"), "dining_chair");
        assert_eq!(normalize_category("  TV-stand "), "tv_stand");
        assert_eq!(normalize_category("??"), "unknown");
    }

    #[test]
    fn door_states_round_trip() {
        for s in DoorState::ALL {
            assert_eq!(DoorState::parse(s.as_str()), Some(s));
        }
    }
}
