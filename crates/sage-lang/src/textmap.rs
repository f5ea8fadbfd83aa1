//! The text map (SPEC §5): what an instruction writer reads about a scene — rooms, functional
//! areas, objects with ids and attributes, and spatial relations — as data for the grammar and
//! as text for an LLM.
//!
//! Relations (W frame, footprints of the semantic map; see `docs/instructions.md`):
//! - **on** A B: A's footprint centre lies in B's footprint, A's bottom is within 5 cm of B's
//!   top, and A's footprint is smaller;
//! - **next to** A B (symmetric): both stand on the floor in the same room and their footprints
//!   are at most 0.6 m apart;
//! - **across from** A B (symmetric): both stand on the floor in the same room, are not next to
//!   each other, their centres are 1.2–5 m apart and the segment between the centres crosses no
//!   other floor object's footprint;
//! - **left of / right of** A B: A is next to B and, seen from the centre of their room looking
//!   at B, A is at least 10° to the left (right);
//! - **in room**: the object's room (a field of the object, not a relation line).
//!
//! Doors, windows, rugs, ceiling and wall-hung things take part in no relation: a robot cannot
//! stand "next to" a ceiling lamp in any useful sense.

use crate::words;
use glam::Vec2;
use sage_core::Polygon2;
use sage_nav::EndpointKind;
use sage_nav::sampling::Endpoints;
use sage_nav::semantic_map::SemanticMap;
use sage_scene::{Attributes, Scene};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Most a standing object's bottom may be above the floor, metres.
const FLOOR_MAX_Z: f32 = 0.15;
/// Largest footprint gap of "next to", metres.
const NEXT_TO_GAP: f32 = 0.6;
/// Centre distance range of "across from", metres.
const ACROSS_RANGE: (f32, f32) = (1.2, 5.0);
/// Largest height gap between a thing and what it stands on, metres.
const ON_GAP: f32 = 0.05;
/// Least bearing difference of "left of" / "right of", radians.
const SIDE_MIN_ANGLE: f32 = 10.0 * std::f32::consts::PI / 180.0;

/// A room of the text map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TmRoom {
    /// `room_{index}` (the id of trajectory endpoints).
    pub id: String,
    /// Index in `structure.json`.
    pub index: usize,
    /// Room type as written.
    pub room_type: String,
    /// How it is said (`living room`).
    pub name: String,
    /// Floor area, m².
    pub area_m2: f32,
    /// Centre of its outline.
    pub centre: [f32; 2],
    /// Indices of the rooms whose outlines come within [`NEIGHBOUR_GAP`] of this one (across
    /// one wall), in index order.
    #[serde(skip)]
    pub neighbours: Vec<usize>,
}

/// Rooms whose outlines come this close (metres; a wall's thickness and some) are neighbours.
pub const NEIGHBOUR_GAP: f32 = 0.35;

/// A functional area (from the navigation layer's area endpoints).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TmArea {
    /// Area id (`dining_area_1`).
    pub id: String,
    /// How it is said (`dining area`).
    pub name: String,
    /// Its room, if any.
    pub room: Option<usize>,
    /// Item ids of its objects.
    pub members: Vec<String>,
}

/// An object of the text map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TmObject {
    /// Item id (`chair_3`).
    pub item_id: String,
    /// Category (`dining_chair`).
    pub category: String,
    /// How it is said (`dining chair`).
    pub noun: String,
    /// Its room, if any.
    pub room: Option<usize>,
    /// Colour, material, state, size.
    pub attributes: Attributes,
    /// Footprint centre, metres.
    pub centre: [f32; 2],
    /// Bottom and top, metres.
    pub z: [f32; 2],
    /// Whether it takes part in relations (stands on the floor or on another object).
    #[serde(skip)]
    pub relatable: bool,
    #[serde(skip)]
    footprint: Polygon2,
}

/// A spatial relation between two objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RelKind {
    /// Standing on top of.
    On,
    /// Beside.
    NextTo,
    /// Facing across the room.
    AcrossFrom,
    /// Beside, to the left as seen from the room centre.
    LeftOf,
    /// Beside, to the right as seen from the room centre.
    RightOf,
}

impl RelKind {
    /// The phrase that precedes the landmark (`next to`, `across from`, …).
    pub fn phrase(self) -> &'static str {
        match self {
            RelKind::On => "on top of",
            RelKind::NextTo => "next to",
            RelKind::AcrossFrom => "across from",
            RelKind::LeftOf => "to the left of",
            RelKind::RightOf => "to the right of",
        }
    }
}

/// `subject` is `kind` `object` (indices into [`TextMap::objects`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Relation {
    /// The object described.
    pub subject: usize,
    /// How.
    pub kind: RelKind,
    /// The landmark.
    pub object: usize,
}

/// The text map of a scene.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TextMap {
    /// Scene name.
    pub scene: String,
    /// Rooms.
    pub rooms: Vec<TmRoom>,
    /// Functional areas.
    pub areas: Vec<TmArea>,
    /// Objects, in semantic-map order.
    pub objects: Vec<TmObject>,
    /// Relations, sorted.
    pub relations: Vec<Relation>,
    #[serde(skip)]
    index: BTreeMap<String, usize>,
}

/// Categories that never take part in relations.
fn unrelatable(category: &str) -> bool {
    [
        "door",
        "window",
        "rug",
        "ceiling",
        "painting",
        "mirror",
        "whiteboard",
        "curtain",
    ]
    .iter()
    .any(|w| category.contains(w))
}

/// Distance between two footprints (0 when they touch or overlap).
fn gap(a: &Polygon2, b: &Polygon2) -> f32 {
    let one_way = |p: &Polygon2, q: &Polygon2| {
        p.points
            .iter()
            .map(|v| {
                if q.points.len() >= 3 && q.contains(*v) {
                    0.0
                } else {
                    q.distance_to_boundary(*v)
                }
            })
            .fold(f32::INFINITY, f32::min)
    };
    one_way(a, b).min(one_way(b, a))
}

/// True when segment `a`–`b` crosses polygon `p` (an edge crossing or an end inside).
fn segment_hits(p: &Polygon2, a: Vec2, b: Vec2) -> bool {
    if p.points.len() < 3 {
        return false;
    }
    if p.contains(a) || p.contains(b) {
        return true;
    }
    let cross = |o: Vec2, u: Vec2, v: Vec2| (u - o).perp_dot(v - o);
    p.edges().any(|(c, d)| {
        let (d1, d2) = (cross(a, b, c), cross(a, b, d));
        let (d3, d4) = (cross(c, d, a), cross(c, d, b));
        d1 * d2 < 0.0 && d3 * d4 < 0.0
    })
}

impl TextMap {
    /// Builds the text map from a scene, its semantic map and its endpoints (for the areas).
    /// Objects take their attributes from the scene (same order as the semantic map).
    pub fn build(scene: &Scene, map: &SemanticMap, endpoints: &Endpoints) -> TextMap {
        let rooms: Vec<TmRoom> = map
            .rooms
            .iter()
            .map(|r| {
                let c = Polygon2::new(r.polygon.clone()).centroid();
                TmRoom {
                    id: format!("room_{}", r.index),
                    index: r.index,
                    room_type: r.room_type.clone(),
                    name: words::room_name(&r.room_type),
                    area_m2: r.area_m2,
                    centre: [c.x, c.y],
                    neighbours: Vec::new(),
                }
            })
            .collect();
        let mut rooms = rooms;
        let outlines: Vec<Polygon2> = map
            .rooms
            .iter()
            .map(|r| Polygon2::new(r.polygon.clone()))
            .collect();
        // Two outlines are within the gap when a vertex of one is near the other's boundary
        // (rooms sharing a stretch of wall have a corner at one end of it).
        let near = |a: &Polygon2, b: &Polygon2| {
            a.points
                .iter()
                .any(|&p| b.distance_to_boundary(p) <= NEIGHBOUR_GAP)
        };
        for i in 0..rooms.len() {
            rooms[i].neighbours = (0..rooms.len())
                .filter(|&j| {
                    j != i && (near(&outlines[i], &outlines[j]) || near(&outlines[j], &outlines[i]))
                })
                .map(|j| rooms[j].index)
                .collect();
        }
        let objects: Vec<TmObject> = map
            .items
            .iter()
            .enumerate()
            .map(|(k, item)| {
                let footprint = item.footprint_polygon();
                let c = footprint.centroid();
                TmObject {
                    item_id: item.item_id.clone(),
                    category: item.category.clone(),
                    noun: words::noun(&item.category),
                    room: item.room,
                    attributes: scene
                        .objects
                        .get(k)
                        .map(|o| o.attributes.clone())
                        .unwrap_or_default(),
                    centre: [c.x, c.y],
                    z: [item.min_z, item.max_z],
                    relatable: !unrelatable(&item.category),
                    footprint,
                }
            })
            .collect();
        let index = objects
            .iter()
            .enumerate()
            .map(|(k, o)| (o.item_id.clone(), k))
            .collect();
        let room_of = |i: usize| map.items.get(i).and_then(|it| it.room);
        let areas = endpoints
            .list
            .iter()
            .filter(|e| e.kind == EndpointKind::Area)
            .map(|e| TmArea {
                id: e.reference.clone(),
                name: words::noun(&e.label),
                room: e
                    .members
                    .first()
                    .and_then(|m| map.items.iter().position(|i| &i.item_id == m))
                    .and_then(room_of),
                members: e.members.clone(),
            })
            .collect();
        let mut tm = TextMap {
            scene: scene.name.clone(),
            rooms,
            areas,
            objects,
            relations: Vec::new(),
            index,
        };
        tm.relations = tm.compute_relations();
        tm
    }

    fn compute_relations(&self) -> Vec<Relation> {
        let o = &self.objects;
        let on_floor = |a: &TmObject| a.relatable && a.z[0] <= FLOOR_MAX_Z;
        let mut out = Vec::new();
        for (i, a) in o.iter().enumerate() {
            for (j, b) in o.iter().enumerate() {
                if i == j || !a.relatable || !b.relatable {
                    continue;
                }
                let (ca, cb) = (Vec2::from(a.centre), Vec2::from(b.centre));
                if b.footprint.points.len() >= 3
                    && b.footprint.contains(ca)
                    && (a.z[0] - b.z[1]).abs() <= ON_GAP
                    && a.footprint.area() < b.footprint.area()
                {
                    out.push(Relation {
                        subject: i,
                        kind: RelKind::On,
                        object: j,
                    });
                    continue;
                }
                if !(on_floor(a) && on_floor(b)) || a.room.is_none() || a.room != b.room {
                    continue;
                }
                let g = gap(&a.footprint, &b.footprint);
                if g <= NEXT_TO_GAP {
                    out.push(Relation {
                        subject: i,
                        kind: RelKind::NextTo,
                        object: j,
                    });
                    if let Some(room) = self.rooms.iter().find(|r| Some(r.index) == a.room) {
                        let v = Vec2::from(room.centre);
                        let (da, db) = (ca - v, cb - v);
                        if db.length() > 0.5 && da.length() > 0.5 {
                            let angle = db.perp_dot(da).atan2(db.dot(da));
                            if angle >= SIDE_MIN_ANGLE {
                                out.push(Relation {
                                    subject: i,
                                    kind: RelKind::LeftOf,
                                    object: j,
                                });
                            } else if angle <= -SIDE_MIN_ANGLE {
                                out.push(Relation {
                                    subject: i,
                                    kind: RelKind::RightOf,
                                    object: j,
                                });
                            }
                        }
                    }
                    continue;
                }
                let d = ca.distance(cb);
                if (ACROSS_RANGE.0..=ACROSS_RANGE.1).contains(&d)
                    && !o.iter().enumerate().any(|(k, c)| {
                        k != i && k != j && on_floor(c) && segment_hits(&c.footprint, ca, cb)
                    })
                {
                    out.push(Relation {
                        subject: i,
                        kind: RelKind::AcrossFrom,
                        object: j,
                    });
                }
            }
        }
        out.sort();
        out
    }

    /// The index of an object by item id.
    pub fn object_index(&self, item_id: &str) -> Option<usize> {
        self.index.get(item_id).copied()
    }

    /// The room with structure index `index`.
    pub fn room(&self, index: usize) -> Option<&TmRoom> {
        self.rooms.iter().find(|r| r.index == index)
    }

    /// The area with this id.
    pub fn area(&self, id: &str) -> Option<&TmArea> {
        self.areas.iter().find(|a| a.id == id)
    }

    /// True when `kind` relates `subject` to `object`.
    pub fn holds(&self, subject: usize, kind: RelKind, object: usize) -> bool {
        self.relations
            .binary_search(&Relation {
                subject,
                kind,
                object,
            })
            .is_ok()
    }

    /// Every id of the map (objects, rooms, areas): words an instruction must never contain.
    pub fn ids(&self) -> impl Iterator<Item = &str> {
        self.objects
            .iter()
            .map(|o| o.item_id.as_str())
            .chain(self.rooms.iter().map(|r| r.id.as_str()))
            .chain(self.areas.iter().map(|a| a.id.as_str()))
    }

    /// The text an LLM reads: rooms, areas, objects with attributes, relations.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let room_name = |r: Option<usize>| {
            r.and_then(|i| self.room(i)).map_or_else(
                || "no room".to_string(),
                |r| format!("the {} ({})", r.name, r.id),
            )
        };
        let _ = writeln!(s, "Scene: {}", self.scene);
        let _ = writeln!(s, "Rooms:");
        for r in &self.rooms {
            let _ = writeln!(s, "- {}: {} ({:.0} m2)", r.id, r.name, r.area_m2);
        }
        if !self.areas.is_empty() {
            let _ = writeln!(s, "Functional areas:");
            for a in &self.areas {
                let _ = writeln!(
                    s,
                    "- {}: {} in {}, around {}",
                    a.id,
                    a.name,
                    room_name(a.room),
                    a.members.join(", ")
                );
            }
        }
        let _ = writeln!(s, "Objects:");
        for o in &self.objects {
            let a = &o.attributes;
            let attrs: Vec<String> = [
                ("color", &a.color),
                ("material", &a.material),
                ("state", &a.state),
                ("size", &a.size),
            ]
            .iter()
            .filter_map(|(k, v)| v.as_ref().map(|v| format!("{k} {v}")))
            .collect();
            let _ = write!(s, "- {}: {} in {}", o.item_id, o.noun, room_name(o.room));
            if !attrs.is_empty() {
                let _ = write!(s, "; {}", attrs.join(", "));
            }
            s.push('\n');
        }
        if !self.relations.is_empty() {
            let _ = writeln!(s, "Spatial relations:");
            for r in &self.relations {
                let (a, b) = (&self.objects[r.subject], &self.objects[r.object]);
                let seen = match r.kind {
                    RelKind::LeftOf | RelKind::RightOf => " (seen from the middle of the room)",
                    _ => "",
                };
                let _ = writeln!(
                    s,
                    "- {} is {} {}{seen}",
                    a.item_id,
                    r.kind.phrase(),
                    b.item_id
                );
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_crossing() {
        let sq = Polygon2::new(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]);
        assert!(segment_hits(&sq, Vec2::new(-1.0, 0.5), Vec2::new(2.0, 0.5)));
        assert!(!segment_hits(
            &sq,
            Vec2::new(-1.0, 1.5),
            Vec2::new(2.0, 1.5)
        ));
        assert!(gap(&sq, &sq) == 0.0);
    }
}
