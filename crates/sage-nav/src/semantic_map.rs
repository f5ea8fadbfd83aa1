//! The 2-D semantic top-down map (SPEC §5): object footprints, walls, doors with their state and
//! typed rooms, as JSON and as a colour PNG with a legend.
//!
//! A footprint is the 2-D convex hull of the object's mesh vertices projected on the floor (the
//! mesh surface's hull), or its oriented box footprint when it has no mesh. Item ids are
//! `{category}_{n}` with `n` counted from 1 per category over every object in `labels.json`
//! order, none skipped, so that the same object has the same id in the map, the trajectories and
//! the instructions.

use crate::grid::NavGrid;
use glam::Vec2;
use sage_core::{Polygon2, Result};
use sage_io::canvas::{self as draw, Canvas};
use sage_scene::occupancy::OCCUPIED;
use sage_scene::{DoorState, HoleKind, Object, Scene};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// One object of the map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapItem {
    /// Stable id, `{category}_{n}` (see the module docs).
    pub item_id: String,
    /// Normalised category.
    pub category: String,
    /// Dense instance id of the scene (as in rendered instance images).
    pub instance_id: u32,
    /// The source `ins_id` of `labels.json`.
    pub ins_id: String,
    /// Index of the room holding the object, if any.
    pub room: Option<usize>,
    /// Footprint polygon (counter-clockwise), metres.
    pub polygon: Vec<Vec2>,
    /// `mesh` (convex hull of the mesh) or `box` (oriented box footprint).
    pub footprint: &'static str,
    /// `[x_min, y_min, x_max, y_max]` of the polygon, metres.
    pub bbox_m: [f32; 4],
    /// Lowest point above the floor, metres.
    pub min_z: f32,
    /// Highest point, metres.
    pub max_z: f32,
    /// For doors: `open`, `closed` or `half-open`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state: Option<&'static str>,
}

impl MapItem {
    /// The footprint as a polygon.
    pub fn footprint_polygon(&self) -> Polygon2 {
        Polygon2::new(self.polygon.clone())
    }
}

/// A wall of `structure.json` as its floor rectangle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapWall {
    /// Floor rectangle, metres.
    pub polygon: Vec<Vec2>,
    /// Height, metres.
    pub height: f32,
}

/// A door opening of `structure.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapDoor {
    /// The opening's floor rectangle, metres.
    pub polygon: Vec<Vec2>,
    /// `open`, `closed`, `half-open`, or `unknown` when the file does not say.
    pub state: &'static str,
}

/// A room.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapRoom {
    /// Index in `structure.json` `rooms`.
    pub index: usize,
    /// Room type as written.
    pub room_type: String,
    /// Outline, metres.
    pub polygon: Vec<Vec2>,
    /// Area, m².
    pub area_m2: f32,
}

/// The semantic top-down map of a scene.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SemanticMap {
    /// Scene name.
    pub scene: String,
    /// Frame of every coordinate (`W`: Z up, metres).
    pub frame: &'static str,
    /// Objects, in `labels.json` order.
    pub items: Vec<MapItem>,
    /// Walls.
    pub walls: Vec<MapWall>,
    /// Door openings.
    pub doors: Vec<MapDoor>,
    /// Rooms.
    pub rooms: Vec<MapRoom>,
}

/// The item id of every object (see the module docs).
pub fn item_ids(objects: &[Object]) -> Vec<String> {
    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    objects
        .iter()
        .map(|o| {
            let n = seen.entry(o.category.as_str()).or_insert(0);
            *n += 1;
            format!("{}_{n}", o.category)
        })
        .collect()
}

/// The convex hull of `points` (Andrew's monotone chain), counter-clockwise, without collinear
/// points; fewer than three distinct points come back as they are (deduplicated).
pub fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut p: Vec<Vec2> = points.iter().copied().filter(|q| q.is_finite()).collect();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<Vec2> = Vec::with_capacity(p.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// The footprint of an object and where it came from.
pub fn footprint(o: &Object) -> (Vec<Vec2>, &'static str) {
    match &o.mesh {
        Some(m) if !m.positions.is_empty() => {
            let pts: Vec<Vec2> = m.positions.iter().map(|p| p.truncate()).collect();
            (convex_hull(&pts), "mesh")
        }
        _ => (convex_hull(&o.obb.footprint()), "box"),
    }
}

impl SemanticMap {
    /// Builds the map of `scene`.
    pub fn build(scene: &Scene) -> SemanticMap {
        let ids = item_ids(&scene.objects);
        let items = scene
            .objects
            .iter()
            .zip(ids)
            .map(|(o, item_id)| {
                let (polygon, source) = footprint(o);
                let (lo, hi) = Polygon2::new(polygon.clone()).bounds();
                let (min_z, max_z) = match &o.mesh {
                    Some(m) if !m.positions.is_empty() => {
                        let b = m.aabb();
                        (b.min.z, b.max.z)
                    }
                    _ => (o.obb.min_z(), o.obb.max_z()),
                };
                MapItem {
                    item_id,
                    category: o.category.clone(),
                    instance_id: o.id.0,
                    ins_id: o.ins_id.clone(),
                    room: o.room,
                    polygon,
                    footprint: source,
                    bbox_m: [lo.x, lo.y, hi.x, hi.y],
                    min_z,
                    max_z,
                    state: o
                        .door_state()
                        .filter(|_| o.category.contains("door"))
                        .map(DoorState::as_str),
                }
            })
            .collect();
        let fp = &scene.floorplan;
        let walls = fp
            .walls
            .iter()
            .map(|w| MapWall {
                polygon: w.obb().footprint().to_vec(),
                height: w.height,
            })
            .collect();
        let doors = fp
            .holes
            .iter()
            .filter(|h| h.kind == HoleKind::Door)
            .map(|h| {
                let (lo, hi) = h.bounds();
                let along = (hi - lo).truncate();
                let dir = along.normalize_or_zero();
                let half = dir.perp() * (h.thickness * 0.5);
                let (a, b) = (lo.truncate(), lo.truncate() + along);
                MapDoor {
                    polygon: vec![a - half, b - half, b + half, a + half],
                    state: h.state.map_or("unknown", DoorState::as_str),
                }
            })
            .collect();
        let rooms = fp
            .rooms
            .iter()
            .enumerate()
            .map(|(index, r)| MapRoom {
                index,
                room_type: r.room_type.clone(),
                polygon: r.profile.points.clone(),
                area_m2: r.profile.area(),
            })
            .collect();
        SemanticMap {
            scene: scene.name.clone(),
            frame: "W",
            items,
            walls,
            doors,
            rooms,
        }
    }

    /// The item with this id.
    pub fn item(&self, item_id: &str) -> Option<&MapItem> {
        self.items.iter().find(|i| i.item_id == item_id)
    }

    /// Writes the map as pretty JSON (atomically).
    pub fn save_json(&self, path: &Path) -> Result<()> {
        sage_io::files::write_json(path, self)
    }

    /// Draws the map over `grid`'s extent (rooms, objects by category, walls, doors by state),
    /// with a legend column on the right; returns the canvas and the width of the map part.
    pub fn draw(&self, grid: &NavGrid, extra_legend: &[([u8; 3], String)]) -> (Canvas, usize) {
        let categories: BTreeSet<&str> = self.items.iter().map(|i| i.category.as_str()).collect();
        let colour_of =
            |c: &str| draw::palette(categories.iter().position(|x| *x == c).unwrap_or(0));
        let mut legend: Vec<([u8; 3], String)> =
            vec![(WALL, "wall".into()), (OBSTACLE, "occupied (slab)".into())];
        legend.extend(DOOR_STATES.iter().map(|(s, c)| (*c, format!("door {s}"))));
        legend.extend(extra_legend.iter().cloned());
        legend.extend(categories.iter().map(|c| (colour_of(c), c.to_string())));
        let chars = legend.iter().map(|(_, l)| l.len()).max().unwrap_or(8);
        // Whole pixels per cell, so that a typical floor plan is drawn about 800 pixels across.
        let zoom = (MAP_PIXELS / grid.width.max(grid.height).max(1)).clamp(1, 8);
        let (map_w, map_h) = (grid.width * zoom, grid.height * zoom);
        let width = map_w + draw::legend_width(chars);
        let height = map_h.max(draw::legend_height(legend.len()));
        let mut canvas = Canvas::new(
            width,
            height,
            [255, 255, 255],
            grid.origin,
            grid.cell / zoom as f32,
            map_h,
        );
        for j in 0..grid.height {
            for i in 0..grid.width {
                let c = match (grid.cells[grid.index(i, j)], grid.rooms[grid.index(i, j)]) {
                    (OCCUPIED, _) => OBSTACLE,
                    (_, crate::grid::NO_ROOM) => OUTSIDE,
                    (_, r) => room_tint(r as usize),
                };
                let (x0, y0) = (i * zoom, (grid.height - 1 - j) * zoom);
                for y in y0..y0 + zoom {
                    for x in x0..x0 + zoom {
                        canvas.put(x as i64, y as i64, c);
                    }
                }
            }
        }
        for item in self.items.iter().filter(|i| i.state.is_none()) {
            canvas.fill_polygon(&item.polygon, colour_of(&item.category));
        }
        for w in &self.walls {
            canvas.fill_polygon(&w.polygon, WALL);
        }
        for d in &self.doors {
            let c = DOOR_STATES
                .iter()
                .find(|(s, _)| *s == d.state)
                .map_or([128; 3], |x| x.1);
            canvas.fill_polygon(&d.polygon, c);
        }
        canvas.legend(map_w as i64 + 10, &self.scene, &legend);
        (canvas, map_w)
    }
}

/// Target size of the map part of the images (pixels along the longer side).
const MAP_PIXELS: usize = 800;
/// Walls in the PNG.
const WALL: [u8; 3] = [30, 30, 30];
/// Occupied slab cells in the PNG.
const OBSTACLE: [u8; 3] = [150, 150, 150];
/// Outside every room.
const OUTSIDE: [u8; 3] = [215, 215, 215];
/// Door colours by state.
const DOOR_STATES: [(&str, [u8; 3]); 4] = [
    ("open", [40, 170, 60]),
    ("closed", [200, 40, 40]),
    ("half-open", [240, 150, 20]),
    ("unknown", [128, 128, 128]),
];

/// A pale tint per room, so neighbouring rooms differ.
fn room_tint(r: usize) -> [u8; 3] {
    draw::palette(r + 101).map(|c| 255 - (255 - c) / 4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn hull_is_convex_and_holds_every_point(pts in proptest::collection::vec((-5.0f32..5.0, -5.0f32..5.0), 3..40)) {
            let pts: Vec<Vec2> = pts.into_iter().map(|(x, y)| Vec2::new(x, y)).collect();
            let hull = convex_hull(&pts);
            if hull.len() >= 3 {
                let n = hull.len();
                for k in 0..n {
                    let (a, b) = (hull[k], hull[(k + 1) % n]);
                    for p in &pts {
                        prop_assert!((b - a).perp_dot(*p - a) >= -1e-3);
                    }
                }
                prop_assert!(Polygon2::new(hull).signed_area() > 0.0);
            }
        }
    }

    #[test]
    fn hull_of_a_square_with_inner_points() {
        let pts = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.5, 0.5),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(0.5, 0.0),
        ];
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4);
        assert!((Polygon2::new(h).area() - 1.0).abs() < 1e-6);
    }
}
