//! The floorplan of `structure.json`: rooms, walls, door and window holes, structural items.

use crate::object::DoorState;
use glam::{Vec2, Vec3};
use sage_core::Polygon2;

/// A room: a polygon on the floor and its type (`"Living Room"`, `"Kitchen"`, `"Office"` …).
#[derive(Debug, Clone, PartialEq)]
pub struct Room {
    /// Outline on the floor plane, metres.
    pub profile: Polygon2,
    /// Free-text type as in InteriorGS.
    pub room_type: String,
}

/// A wall: a segment on the floor extruded up to `height`, `thickness` split evenly about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall {
    /// One end of the centre line.
    pub start: Vec2,
    /// The other end.
    pub end: Vec2,
    /// Total thickness, metres.
    pub thickness: f32,
    /// Height above the floor, metres.
    pub height: f32,
}

impl Wall {
    /// Length of the centre line.
    pub fn length(&self) -> f32 {
        self.start.distance(self.end)
    }

    /// Unit direction from start to end (zero for a degenerate wall).
    pub fn direction(&self) -> Vec2 {
        (self.end - self.start).normalize_or_zero()
    }

    /// The wall as an oriented box.
    pub fn obb(&self) -> sage_core::Obb {
        let d = self.end - self.start;
        let mid = (self.start + self.end) * 0.5;
        sage_core::Obb {
            center: Vec3::new(mid.x, mid.y, self.height * 0.5),
            half_extents: Vec3::new(d.length() * 0.5, self.thickness * 0.5, self.height * 0.5),
            yaw: d.y.atan2(d.x),
        }
    }
}

/// What a hole in a wall is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HoleKind {
    /// A doorway.
    Door,
    /// A window.
    Window,
}

/// An opening cut through a wall.
#[derive(Debug, Clone, PartialEq)]
pub struct Hole {
    /// Outline on the wall plane (3-D points, metres).
    pub profile: Vec<Vec3>,
    /// Extrusion depth through the wall.
    pub thickness: f32,
    /// Door or window.
    pub kind: HoleKind,
    /// For doors: the state of the leaf in the opening (ours; absent in InteriorGS files).
    pub state: Option<DoorState>,
}

impl Hole {
    /// Bounds of the outline: (lower corner, upper corner).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let lo = self.profile.iter().fold(Vec3::INFINITY, |m, p| m.min(*p));
        let hi = self
            .profile
            .iter()
            .fold(Vec3::NEG_INFINITY, |m, p| m.max(*p));
        (lo, hi)
    }
}

/// A structural item of `structure.json` `ins[]`: a labelled axis-aligned box.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureItem {
    /// Free-text label.
    pub label: String,
    /// Box centre.
    pub position: Vec3,
    /// Box size.
    pub size: Vec3,
}

/// Everything `structure.json` describes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Floorplan {
    /// Rooms.
    pub rooms: Vec<Room>,
    /// Walls.
    pub walls: Vec<Wall>,
    /// Door and window holes.
    pub holes: Vec<Hole>,
    /// Structural items.
    pub items: Vec<StructureItem>,
    /// The ceiling height where no wall gives one, metres: a capture's, as its import measured
    /// it (`capture.json`). Not part of `structure.json`.
    pub ceiling: Option<f32>,
}

impl Floorplan {
    /// Index of the room whose polygon holds `p` (the smallest such room).
    pub fn room_at(&self, p: Vec2) -> Option<usize> {
        self.rooms
            .iter()
            .enumerate()
            .filter(|(_, r)| r.profile.contains(p))
            .min_by(|a, b| a.1.profile.area().total_cmp(&b.1.profile.area()))
            .map(|(i, _)| i)
    }

    /// Index of the room holding `p`, else of the room whose outline passes nearest to `p`
    /// within `max_distance` (objects in a wall, such as windows and doors, sit on the outline).
    pub fn room_near(&self, p: Vec2, max_distance: f32) -> Option<usize> {
        self.room_at(p).or_else(|| {
            self.rooms
                .iter()
                .enumerate()
                .map(|(i, r)| (i, r.profile.distance_to_boundary(p)))
                .filter(|(_, d)| *d <= max_distance)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(i, _)| i)
        })
    }

    /// The ceiling height: the tallest wall; without walls, the one measured for the scene
    /// ([`Floorplan::ceiling`]), else 2.8 m (InteriorGS's common value).
    pub fn ceiling_height(&self) -> f32 {
        self.walls
            .iter()
            .map(|w| w.height)
            .fold(None, |m: Option<f32>, h| Some(m.map_or(h, |m| m.max(h))))
            .or(self.ceiling)
            .unwrap_or(2.8)
    }

    /// The doors.
    pub fn doors(&self) -> impl Iterator<Item = &Hole> {
        self.holes.iter().filter(|h| h.kind == HoleKind::Door)
    }

    /// The windows.
    pub fn windows(&self) -> impl Iterator<Item = &Hole> {
        self.holes.iter().filter(|h| h.kind == HoleKind::Window)
    }
}
