//! Start and goal sampling (paper appendix A; SPEC §7): endpoints over rooms, functional areas
//! and object instances, each with stand points on navigable cells.
//!
//! - An **object** endpoint stands beside its footprint: a navigable cell whose distance to the
//!   polygon lies between `stand_min` (the safety distance) and `stand_max`, facing the object's
//!   centre. Up to eight stand points are kept, one per 45° sector around the object; a pair
//!   uses the one on the side facing the other endpoint. Only roomy cells (clearance ≥
//!   [`roomy_clearance`](crate::cost::CostParams::roomy_clearance): radius, safety margin and
//!   shortcut margin) stand when the object has any: an agent stopping at bare navigable
//!   clearance touches what is beside it. Cells `stand_slack` inside `stand_max` stand first
//!   (then roomy cells out to `stand_max`, then navigable ones likewise): an agent that stops a
//!   step short of the end point is still within the success distance, where from the edge of
//!   that distance it would take one more step, into the clutter around the object.
//! - An **area** is a functional group around an anchor object (a dining table and the chairs
//!   around it, a bed and its nightstands, …): the objects of the anchor's room whose footprints
//!   lie within `area_reach` of the anchor's; its polygon is the hull of their footprints, and it
//!   stands like an object.
//! - A **room** endpoint stands at the room's centre, as instructions name it ("the center of
//!   the kitchen"): a cell drawn uniformly among those within [`ROOM_CENTRE_RADIUS`] of the
//!   room's central cell, the cell with clearance ≥ `room_clearance` nearest to the centroid of
//!   the room's outline (of its navigable cells when none has that much clearance), on the
//!   island holding most of the room. An agent
//!   that stops at the centre is then within the success distance of the goal, and a room
//!   still gives trips many start and goal points.
//!
//! - A scene with neither rooms nor objects (an imported capture) has **regions** instead: its
//!   navigable cells cut into [`REGION`]-metre squares, each with at least 1 m² of them a room
//!   endpoint `region_{i}` (label `region`). Unlike a room, a region stands on any of its
//!   square's cells with `room_clearance` (any of its navigable cells when none has it): no
//!   instruction names a region's centre, so its trips may end anywhere in the square.
//!
//! Doors and windows are never endpoints, nor are objects whose base is above
//! `max_object_base` (ceiling lamps, pictures hung high): nobody is sent to stand beside those.

use crate::pathfinder::PathFinder;
use crate::semantic_map::{SemanticMap, convex_hull};
use glam::Vec2;
use rand::Rng;
use sage_core::{Error, Polygon2, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What an endpoint refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EndpointKind {
    /// A room (by index).
    Room,
    /// An object instance (by item id).
    Object,
    /// A functional area (by area id).
    Area,
}

impl EndpointKind {
    /// All kinds, in the order of [`SamplingParams::kind_weights`].
    pub const ALL: [EndpointKind; 3] =
        [EndpointKind::Room, EndpointKind::Object, EndpointKind::Area];

    /// `room`, `object` or `area`.
    pub fn as_str(self) -> &'static str {
        match self {
            EndpointKind::Room => "room",
            EndpointKind::Object => "object",
            EndpointKind::Area => "area",
        }
    }
}

/// Functional areas: the anchor category and the area's name.
pub const AREA_ANCHORS: [(&str, &str); 10] = [
    ("dining_table", "dining_area"),
    ("sofa", "lounge_area"),
    ("bed", "sleeping_area"),
    ("desk", "work_area"),
    ("meeting_table", "meeting_area"),
    ("stove", "cooking_area"),
    ("cash_counter", "checkout_area"),
    ("reception_desk", "reception_area"),
    ("bathtub", "bathing_area"),
    ("display_table", "display_area"),
];

/// How endpoints and pairs are drawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SamplingParams {
    /// Nearest a stand point may be to its object or area, metres: the safety distance
    /// (default 0.5).
    pub stand_min: f32,
    /// Farthest, metres (default 1.0, the success distance).
    pub stand_max: f32,
    /// How far inside `stand_max` a stand point lies where the object's surroundings allow,
    /// metres (default 0.3): an agent that stops a step (0.25 m) short of it still stands
    /// within the success distance, instead of stepping on into the clutter around the object.
    #[serde(default = "default_stand_slack")]
    pub stand_slack: f32,
    /// Clearance a room's stand cells prefer, metres (default 0.5).
    pub room_clearance: f32,
    /// How far around its anchor an area gathers objects, metres (default 1.0).
    pub area_reach: f32,
    /// Least straight-line distance between start and goal, metres (default 2.0).
    pub min_distance: f32,
    /// Least path length, metres (default 2.0).
    pub min_length: f32,
    /// Relative weights of start / goal kinds: room, object, area (default 1, 2, 1).
    pub kind_weights: [f32; 3],
    /// Path-length bin edges, metres (default [`PATH_EDGES`], SPEC §9: short, medium, long);
    /// [`length_bin`] says which bin a length on an edge falls in.
    pub length_edges: Vec<f32>,
    /// Wanted share of each length bin (one more than the edges); `None`: no quota.
    pub length_mix: Option<Vec<f32>>,
    /// Candidate pairs tried per wanted trajectory before giving up (default 50).
    pub attempts_per_trajectory: usize,
    /// Highest base (lowest point above the floor) an object endpoint may have, metres
    /// (default 1.2, the agent's height).
    pub max_object_base: f32,
}

fn default_stand_slack() -> f32 {
    0.3
}

impl Default for SamplingParams {
    fn default() -> Self {
        SamplingParams {
            stand_min: 0.5,
            stand_max: 1.0,
            stand_slack: default_stand_slack(),
            room_clearance: 0.5,
            area_reach: 1.0,
            min_distance: 2.0,
            min_length: 2.0,
            kind_weights: [1.0, 2.0, 1.0],
            length_edges: PATH_EDGES.to_vec(),
            length_mix: None,
            attempts_per_trajectory: 50,
            max_object_base: 1.2,
        }
    }
}

impl SamplingParams {
    /// Checks the ranges and that the mix has one share per bin.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::invalid(format!("sampling: {m}")));
        if !(self.stand_min >= 0.0 && self.stand_max > self.stand_min) {
            return bad(format!(
                "need 0 <= stand_min < stand_max, got {} and {}",
                self.stand_min, self.stand_max
            ));
        }
        if !(self.stand_slack >= 0.0 && self.stand_slack < self.stand_max - self.stand_min) {
            return bad(format!(
                "stand_slack must be >= 0 and below stand_max - stand_min, got {}",
                self.stand_slack
            ));
        }
        if !self.kind_weights.iter().all(|w| *w >= 0.0 && w.is_finite())
            || self.kind_weights.iter().sum::<f32>() <= 0.0
        {
            return bad(format!(
                "`kind_weights` must be >= 0 and not all 0, got {:?}",
                self.kind_weights
            ));
        }
        if !self.length_edges.windows(2).all(|w| w[0] < w[1]) {
            return bad("length edges must increase".into());
        }
        if let Some(mix) = &self.length_mix
            && (mix.len() != self.length_edges.len() + 1
                || !mix.iter().all(|m| *m >= 0.0)
                || mix.iter().sum::<f32>() <= 0.0)
        {
            return bad(format!(
                "`length_mix` needs {} shares >= 0 (one per length bin), got {mix:?}",
                self.length_edges.len() + 1
            ));
        }
        if !(self.min_distance >= 0.0 && self.min_distance.is_finite()) {
            return bad(format!(
                "`min_distance` must be a finite distance >= 0 m, got {}",
                self.min_distance
            ));
        }
        if self.attempts_per_trajectory == 0 {
            return bad("attempts_per_trajectory must be >= 1".into());
        }
        Ok(())
    }

    /// The length bin of a path length ([`length_bin`] over `length_edges`).
    pub fn bin_of(&self, length: f32) -> usize {
        length_bin(&self.length_edges, length)
    }
}

/// The paper's path-length edges, metres (SPEC §9): `short` below 8.4, `long` above 29.0,
/// `medium` between them, both bounds included. The dataset's path slice and the sampler's
/// length bins both use these edges through [`length_bin`], so a trajectory counted in a bin
/// is tagged with that bin's slice.
pub const PATH_EDGES: [f32; 2] = [8.4, 29.0];

/// The bin of a path `length` among increasing `edges`: 0 below the first edge, `edges.len()`
/// above the last, one more for each edge passed. A length exactly on an edge falls in the bin
/// nearer the middle: an edge of the lower half of the list belongs to the bin above it, one of
/// the upper half to the bin below. With [`PATH_EDGES`] that is the paper's strict thresholds
/// (`short` < 8.4 m ≤ `medium` ≤ 29.0 m < `long`); with a single edge a length on it stays in
/// the lower bin.
pub fn length_bin(edges: &[f32], length: f32) -> usize {
    let lower_half = edges.len() / 2;
    edges
        .iter()
        .enumerate()
        .filter(|&(i, &e)| {
            if i < lower_half {
                length >= e
            } else {
                length > e
            }
        })
        .count()
}

/// A place to stand: a navigable cell, its centre and the heading that faces the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stand {
    /// Flat cell index.
    pub cell: usize,
    /// Cell centre, metres.
    pub point: Vec2,
    /// Heading facing the object or area (`None` for rooms).
    pub facing: Option<f32>,
}

/// A room, area or object that a trajectory can start or end at.
#[derive(Debug, Clone, PartialEq)]
pub struct Endpoint {
    /// Room, object or area.
    pub kind: EndpointKind,
    /// `room_{index}`, the item id, or the area id.
    pub reference: String,
    /// Room type, category or area name.
    pub label: String,
    /// Its outline (room polygon, footprint, area hull).
    pub polygon: Polygon2,
    /// Centre of the outline.
    pub centre: Vec2,
    /// Where to stand (never empty).
    pub stands: Vec<Stand>,
    /// Item ids of an area's objects (empty otherwise).
    pub members: Vec<String>,
}

/// All endpoints of a scene, grouped by kind.
#[derive(Debug, Clone, PartialEq)]
pub struct Endpoints {
    /// The endpoints: rooms, then objects, then areas.
    pub list: Vec<Endpoint>,
    by_kind: [Vec<usize>; 3],
}

impl Endpoints {
    /// Finds every endpoint of the scene that has a stand point.
    pub fn collect(map: &SemanticMap, pf: &PathFinder, params: &SamplingParams) -> Endpoints {
        let mut list = Vec::new();
        for room in &map.rooms {
            let polygon = Polygon2::new(room.polygon.clone());
            let stands = room_stands(pf, room.index, polygon.centroid(), params.room_clearance);
            if !stands.is_empty() {
                list.push(Endpoint {
                    kind: EndpointKind::Room,
                    reference: format!("room_{}", room.index),
                    label: room.room_type.clone(),
                    centre: polygon.centroid(),
                    polygon,
                    stands,
                    members: Vec::new(),
                });
            }
        }
        if map.rooms.is_empty() && map.items.is_empty() {
            list.extend(region_endpoints(pf, params));
        }
        let objects = map
            .items
            .iter()
            .filter(|i| !(i.category.contains("door") || i.category.contains("window")))
            .filter(|i| i.min_z <= params.max_object_base);
        for item in objects.clone() {
            let polygon = item.footprint_polygon();
            let stands = ring_stands(pf, &polygon, params);
            if !stands.is_empty() {
                list.push(Endpoint {
                    kind: EndpointKind::Object,
                    reference: item.item_id.clone(),
                    label: item.category.clone(),
                    centre: polygon.centroid(),
                    polygon,
                    stands,
                    members: Vec::new(),
                });
            }
        }
        let mut area_count: BTreeMap<&str, usize> = BTreeMap::new();
        for anchor in objects.clone() {
            let Some((_, name)) = AREA_ANCHORS.iter().find(|(c, _)| *c == anchor.category) else {
                continue;
            };
            let apoly = anchor.footprint_polygon();
            let members: Vec<_> = objects
                .clone()
                .filter(|o| o.room == anchor.room)
                .filter(|o| {
                    o.item_id == anchor.item_id
                        || polygon_gap(&apoly, &o.footprint_polygon()) <= params.area_reach
                })
                .collect();
            let pts: Vec<Vec2> = members
                .iter()
                .flat_map(|m| m.polygon.iter().copied())
                .collect();
            let polygon = Polygon2::new(convex_hull(&pts));
            let stands = ring_stands(pf, &polygon, params);
            let n = area_count.entry(name).or_insert(0);
            *n += 1;
            if !stands.is_empty() {
                list.push(Endpoint {
                    kind: EndpointKind::Area,
                    reference: format!("{name}_{n}"),
                    label: name.to_string(),
                    centre: polygon.centroid(),
                    polygon,
                    stands,
                    members: members.iter().map(|m| m.item_id.clone()).collect(),
                });
            }
        }
        let mut by_kind: [Vec<usize>; 3] = Default::default();
        for (i, e) in list.iter().enumerate() {
            by_kind[e.kind as usize].push(i);
        }
        Endpoints { list, by_kind }
    }

    /// How many endpoints of each kind (room, object, area).
    pub fn counts(&self) -> [usize; 3] {
        [0, 1, 2].map(|k| self.by_kind[k].len())
    }

    /// Draws a candidate pair: kinds by weight (among kinds that have endpoints), endpoints
    /// uniformly within a kind, distinct, with the stand points that face each other. `None`
    /// when the scene has fewer than two endpoints.
    pub fn draw_pair(&self, rng: &mut impl Rng, params: &SamplingParams) -> Option<Pair> {
        if self.list.len() < 2 {
            return None;
        }
        let start = self.draw_endpoint(rng, params)?;
        let mut goal = self.draw_endpoint(rng, params)?;
        if goal == start {
            // Redraw once uniformly among the others: keeps the draw count fixed per pair.
            let k = rng.random_range(0..self.list.len() - 1);
            goal = if k >= start { k + 1 } else { k };
        }
        let (s, g) = (&self.list[start], &self.list[goal]);
        Some(Pair {
            start,
            goal,
            start_stand: pick_stand(s, g.centre, rng),
            goal_stand: pick_stand(g, s.centre, rng),
        })
    }

    fn draw_endpoint(&self, rng: &mut impl Rng, params: &SamplingParams) -> Option<usize> {
        let w: Vec<f32> = (0..3)
            .map(|k| {
                if self.by_kind[k].is_empty() {
                    0.0
                } else {
                    params.kind_weights[k]
                }
            })
            .collect();
        let total: f32 = w.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let mut x = rng.random::<f32>() * total;
        let mut kind = 0;
        for (k, wk) in w.iter().enumerate() {
            if *wk > 0.0 {
                kind = k;
                if x < *wk {
                    break;
                }
                x -= wk;
            }
        }
        let group = &self.by_kind[kind];
        Some(group[rng.random_range(0..group.len())])
    }
}

/// A drawn start–goal pair (indices into [`Endpoints::list`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Start endpoint.
    pub start: usize,
    /// Goal endpoint.
    pub goal: usize,
    /// Where the start stands.
    pub start_stand: Stand,
    /// Where the goal stands.
    pub goal_stand: Stand,
}

/// The stand of `e` for a trip to or from `other`: for rooms a uniform draw, else the stand on
/// the side facing `other` (largest cosine; first on ties).
fn pick_stand(e: &Endpoint, other: Vec2, rng: &mut impl Rng) -> Stand {
    if e.kind == EndpointKind::Room {
        return e.stands[rng.random_range(0..e.stands.len())];
    }
    let toward = (other - e.centre).normalize_or_zero();
    let mut best = e.stands[0];
    let mut best_dot = f32::NEG_INFINITY;
    for s in &e.stands {
        let d = (s.point - e.centre).normalize_or_zero().dot(toward);
        if d > best_dot + 1e-6 {
            best = *s;
            best_dot = d;
        }
    }
    best
}

/// Distance between two polygons' outlines (0 when one holds a vertex of the other).
fn polygon_gap(a: &Polygon2, b: &Polygon2) -> f32 {
    let one_way = |p: &Polygon2, q: &Polygon2| {
        p.points
            .iter()
            .map(|v| {
                if q.contains(*v) {
                    0.0
                } else {
                    q.distance_to_boundary(*v)
                }
            })
            .fold(f32::INFINITY, f32::min)
    };
    one_way(a, b).min(one_way(b, a))
}

/// Side of the squares that stand in for rooms in a scene with neither rooms nor objects, m.
pub const REGION: f32 = 3.0;

/// The room endpoints of a scene with neither rooms nor objects: its navigable cells cut into
/// [`REGION`]-metre squares, each square holding at least 1 m² of them a region.
fn region_endpoints(pf: &PathFinder, params: &SamplingParams) -> Vec<Endpoint> {
    let g = &pf.grid;
    let mut squares: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
    for &k in pf.navigable_cells() {
        let p = g.center_of(k as usize) / REGION;
        squares
            .entry((p.x.floor() as i64, p.y.floor() as i64))
            .or_default()
            .push(k as usize);
    }
    let enough = ((1.0 / (g.cell * g.cell)).ceil() as usize).max(1);
    squares
        .into_iter()
        .filter(|(_, cells)| cells.len() >= enough)
        .enumerate()
        .map(|(i, ((sx, sy), cells))| {
            let roomy: Vec<usize> = cells
                .iter()
                .copied()
                .filter(|&k| pf.clearance[k] >= params.room_clearance)
                .collect();
            let chosen = if roomy.is_empty() { cells } else { roomy };
            let lo = Vec2::new(sx as f32, sy as f32) * REGION;
            let polygon = Polygon2::new(vec![
                lo,
                lo + Vec2::X * REGION,
                lo + Vec2::splat(REGION),
                lo + Vec2::Y * REGION,
            ]);
            Endpoint {
                kind: EndpointKind::Room,
                reference: format!("region_{i}"),
                label: "region".to_string(),
                centre: polygon.centroid(),
                polygon,
                stands: chosen
                    .into_iter()
                    .map(|k| Stand {
                        cell: k,
                        point: g.center_of(k),
                        facing: None,
                    })
                    .collect(),
                members: Vec::new(),
            }
        })
        .collect()
}

/// How far from a room's central cell its stand cells lie, metres: half the default success
/// distance, so that an agent stopping at the room's centre succeeds on a trip to the room
/// whichever of them the trip ends at.
pub const ROOM_CENTRE_RADIUS: f32 = 0.5;

/// Stand cells of a room: those within [`ROOM_CENTRE_RADIUS`] of its central cell (the one
/// nearest to `centre`, the centroid of its outline; first in index order on ties), all among
/// the room's cells with `clearance` (its navigable cells when none has it) on the island that
/// holds most of those.
fn room_stands(pf: &PathFinder, room: usize, centre: Vec2, clearance: f32) -> Vec<Stand> {
    let g = &pf.grid;
    let cells: Vec<usize> = pf
        .navigable_cells()
        .iter()
        .map(|&k| k as usize)
        .filter(|&k| g.rooms[k] as usize == room)
        .collect();
    let roomy: Vec<usize> = cells
        .iter()
        .copied()
        .filter(|&k| pf.clearance[k] >= clearance)
        .collect();
    let chosen = if roomy.is_empty() { cells } else { roomy };
    // The centre is sought on the island holding most of the room (the first on ties): a
    // central cell walled in by furniture would make every trip to the room unreachable.
    let mut by_island: BTreeMap<u32, usize> = BTreeMap::new();
    for &k in &chosen {
        *by_island.entry(pf.island_of_cell(k)).or_default() += 1;
    }
    let Some(island) = by_island
        .iter()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))
        .map(|(&id, _)| id)
    else {
        return Vec::new();
    };
    let chosen: Vec<usize> = chosen
        .into_iter()
        .filter(|&k| pf.island_of_cell(k) == island)
        .collect();
    let mut central: Option<(f32, Vec2)> = None;
    for &k in &chosen {
        let d = g.center_of(k).distance_squared(centre);
        if central.is_none_or(|(best, _)| d < best) {
            central = Some((d, g.center_of(k)));
        }
    }
    let Some((_, middle)) = central else {
        return Vec::new();
    };
    chosen
        .into_iter()
        .filter(|&k| g.center_of(k).distance(middle) <= ROOM_CENTRE_RADIUS)
        .map(|k| Stand {
            cell: k,
            point: g.center_of(k),
            facing: None,
        })
        .collect()
}

/// Up to eight stand points around a polygon (see the module docs): from the first of these
/// that has any — roomy cells within the slack, roomy cells, navigable cells within the slack,
/// navigable cells.
fn ring_stands(pf: &PathFinder, polygon: &Polygon2, params: &SamplingParams) -> Vec<Stand> {
    let inner = params.stand_max - params.stand_slack;
    [
        (true, inner),
        (true, params.stand_max),
        (false, inner),
        (false, params.stand_max),
    ]
    .into_iter()
    .map(|(roomy_only, reach)| ring_stands_on(pf, polygon, params, roomy_only, reach))
    .find(|stands| !stands.is_empty())
    .unwrap_or_default()
}

/// [`ring_stands`] among the roomy cells only (`roomy_only`) or among all navigable ones, at
/// most `reach` from the polygon.
fn ring_stands_on(
    pf: &PathFinder,
    polygon: &Polygon2,
    params: &SamplingParams,
    roomy_only: bool,
    reach: f32,
) -> Vec<Stand> {
    if polygon.points.is_empty() {
        return Vec::new();
    }
    let g = &pf.grid;
    let (lo, hi) = polygon.bounds();
    let r = Vec2::splat(reach);
    let Some((i0, j0, i1, j1)) = g.cell_range(lo - r, hi + r) else {
        return Vec::new();
    };
    let centre = polygon.centroid();
    let ideal = 0.5 * (params.stand_min + reach);
    let mut best: [Option<(f32, usize)>; 8] = [None; 8];
    for j in j0..=j1 {
        for i in i0..=i1 {
            let k = g.index(i, j);
            // Stand points keep the shortcut margin where the object's surroundings allow: the
            // agent stops there, and at bare radius clearance it touches what is beside it.
            if !(if roomy_only {
                pf.roomy[k]
            } else {
                pf.passable[k]
            }) {
                continue;
            }
            let p = g.center(i, j);
            if polygon.points.len() >= 3 && polygon.contains(p) {
                continue;
            }
            let d = polygon.distance_to_boundary(p);
            if d < params.stand_min || d > reach {
                continue;
            }
            let a = (p - centre).y.atan2((p - centre).x);
            let sector =
                (((a + std::f32::consts::PI) / std::f32::consts::FRAC_PI_4) as usize).min(7);
            let score = (d - ideal).abs();
            if best[sector].is_none_or(|(s, _)| score < s) {
                best[sector] = Some((score, k));
            }
        }
    }
    best.iter()
        .flatten()
        .map(|&(_, k)| {
            let p = g.center_of(k);
            let to = centre - p;
            Stand {
                cell: k,
                point: p,
                facing: Some(to.y.atan2(to.x)),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_on_the_paper_edges_are_medium() {
        let bin = |l: f32| length_bin(&PATH_EDGES, l);
        assert_eq!(bin(8.39), 0);
        assert_eq!(bin(8.4), 1);
        assert_eq!(bin(29.0), 1);
        assert_eq!(bin(29.01), 2);
        assert_eq!(SamplingParams::default().bin_of(8.4), 1);
        // Other edges follow the same rule: the lower half's edges go up, the upper half's down.
        assert_eq!(length_bin(&[5.0], 5.0), 0);
        assert_eq!(length_bin(&[5.0], 5.01), 1);
        let four = [1.0, 2.0, 3.0, 4.0];
        let bins: Vec<usize> = [1.0, 2.0, 3.0, 4.0].map(|l| length_bin(&four, l)).to_vec();
        assert_eq!(bins, [1, 2, 2, 3]);
        assert_eq!(length_bin(&four, 0.5), 0);
        assert_eq!(length_bin(&four, 4.5), 4);
    }
}
