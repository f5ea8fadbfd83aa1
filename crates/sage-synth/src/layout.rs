//! The floorplan of a synthetic scene: a rectangular footprint cut into rooms by recursive binary
//! space partitioning, one wall along each cut, doors that connect every room (a spanning tree
//! over shared walls plus a few extra), an entrance, windows on the outside walls, and a type and
//! finish for each room.

use crate::look::{Look, Material};
use crate::{SceneKind, SynthConfig, pick, uniform};
use glam::{Vec2, Vec3};
use rand::seq::{IndexedRandom, SliceRandom};
use rand::{Rng, RngCore};
use sage_core::Polygon2;
use sage_scene::floorplan::{Floorplan, Hole, HoleKind, Room, Wall};
use sage_scene::object::DoorState;

/// Thickness of the outside walls (m).
pub(crate) const EXTERIOR_WALL: f32 = 0.2;
/// Thickness of the walls between rooms (m).
pub(crate) const INTERIOR_WALL: f32 = 0.1;
/// Height of the top of a door opening (m).
pub(crate) const DOOR_TOP: f32 = 2.05;
/// No room is narrower than this (m).
const MIN_ROOM: f32 = 2.4;
/// Solid wall kept between an opening and the end of the wall stretch it is cut into (m).
const JAMB: f32 = 0.25;

/// An axis-aligned rectangle on the floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rect {
    /// Lower corner.
    pub min: Vec2,
    /// Upper corner.
    pub max: Vec2,
}

impl Rect {
    /// Edge lengths.
    pub fn size(&self) -> Vec2 {
        self.max - self.min
    }

    /// Centre.
    pub fn center(&self) -> Vec2 {
        (self.min + self.max) * 0.5
    }

    /// Area, m².
    pub fn area(&self) -> f32 {
        let s = self.size();
        s.x * s.y
    }

    /// True when `p` lies inside or on the boundary.
    pub fn contains(&self, p: Vec2) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The rectangle shrunk by `d` on every side.
    pub fn shrink(&self, d: f32) -> Rect {
        Rect {
            min: self.min + Vec2::splat(d),
            max: self.max - Vec2::splat(d),
        }
    }

    /// The extent along `axis`.
    pub fn extent(&self, axis: Axis) -> [f32; 2] {
        match axis {
            Axis::X => [self.min.x, self.max.x],
            Axis::Y => [self.min.y, self.max.y],
        }
    }

    /// The counter-clockwise outline.
    pub fn polygon(&self) -> Polygon2 {
        Polygon2::new(vec![
            self.min,
            Vec2::new(self.max.x, self.min.y),
            self.max,
            Vec2::new(self.min.x, self.max.y),
        ])
    }
}

/// The direction a wall runs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Axis {
    /// Along world x (the wall's "across" coordinate is y).
    X,
    /// Along world y (the wall's "across" coordinate is x).
    Y,
}

impl Axis {
    /// The other axis.
    pub fn other(self) -> Axis {
        match self {
            Axis::X => Axis::Y,
            Axis::Y => Axis::X,
        }
    }

    /// The floor point `along` this axis and `across` it.
    pub fn point(self, along: f32, across: f32) -> Vec2 {
        match self {
            Axis::X => Vec2::new(along, across),
            Axis::Y => Vec2::new(across, along),
        }
    }

    /// The 3-D point `along` this axis, `across` it and `z` high.
    pub fn point3(self, along: f32, across: f32, z: f32) -> Vec3 {
        self.point(along, across).extend(z)
    }

    /// Unit vector along the axis.
    pub fn dir(self) -> Vec3 {
        self.point3(1.0, 0.0, 0.0)
    }

    /// Unit vector of growing "across" coordinate.
    pub fn normal(self) -> Vec3 {
        self.point3(0.0, 1.0, 0.0)
    }

    /// The yaw of the axis direction.
    pub fn yaw(self) -> f32 {
        match self {
            Axis::X => 0.0,
            Axis::Y => std::f32::consts::FRAC_PI_2,
        }
    }
}

/// A wall: a centre line at `across = line` from `span[0]` to `span[1]` along `axis`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct WallLine {
    /// Direction of the wall.
    pub axis: Axis,
    /// The fixed "across" coordinate of the centre line.
    pub line: f32,
    /// The extent along the axis.
    pub span: [f32; 2],
    /// Total thickness.
    pub thickness: f32,
}

/// A door or window opening cut through a wall.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Opening {
    /// Door or window.
    pub kind: HoleKind,
    /// Direction of the wall it is cut into.
    pub axis: Axis,
    /// The wall's centre line ("across" coordinate).
    pub line: f32,
    /// Extent along the wall.
    pub span: [f32; 2],
    /// Bottom and top.
    pub z: [f32; 2],
    /// The wall's thickness.
    pub thickness: f32,
    /// The leaf's state (doors only).
    pub state: Option<DoorState>,
    /// The rooms on the lower and the upper "across" side (`None` outside the building).
    pub rooms: [Option<usize>; 2],
    /// The side a door leaf swings into: +1 towards growing "across", −1 the other way.
    pub swing: f32,
    /// True when the hinge is at `span[0]`, false at `span[1]`.
    pub hinge_at_start: bool,
}

impl Opening {
    /// Width along the wall.
    pub fn width(&self) -> f32 {
        self.span[1] - self.span[0]
    }

    /// Centre of the opening on the wall's centre line, on the floor.
    pub fn center(&self) -> Vec2 {
        self.axis
            .point(0.5 * (self.span[0] + self.span[1]), self.line)
    }

    /// True for a door whose leaf leaves the opening passable.
    pub fn is_open_door(&self) -> bool {
        self.kind == HoleKind::Door && self.state == Some(DoorState::Open)
    }
}

/// One room: its cell of the partition and its finishes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RoomCell {
    /// The cell, bounded by wall centre lines.
    pub rect: Rect,
    /// The floor area between the wall faces.
    pub inner: Rect,
    /// Room type (`"Kitchen"`).
    pub kind: &'static str,
    /// Floor finish.
    pub floor: Look,
    /// Wall paint.
    pub wall: Look,
    /// Ceiling paint.
    pub ceiling: Look,
}

/// Everything structural about a synthetic scene.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layout {
    /// The footprint, bounded by the outside walls' centre lines.
    pub footprint: Rect,
    /// Wall (and ceiling) height.
    pub height: f32,
    /// Rooms.
    pub rooms: Vec<RoomCell>,
    /// Walls: the four outside walls, then one per cut.
    pub walls: Vec<WallLine>,
    /// Doors (interior, then the entrance) and windows.
    pub openings: Vec<Opening>,
    /// The finish of the outside faces of the outside walls.
    pub outside: Look,
}

impl Layout {
    /// The floorplan of `structure.json`.
    pub fn floorplan(&self) -> Floorplan {
        let rooms = self
            .rooms
            .iter()
            .map(|r| Room {
                profile: r.rect.polygon(),
                room_type: r.kind.to_string(),
            })
            .collect();
        let walls = self
            .walls
            .iter()
            .map(|w| Wall {
                start: w.axis.point(w.span[0], w.line),
                end: w.axis.point(w.span[1], w.line),
                thickness: w.thickness,
                height: self.height,
            })
            .collect();
        let holes = self
            .openings
            .iter()
            .map(|o| {
                let [s0, s1] = o.span;
                let [z0, z1] = o.z;
                let profile = [(s0, z0), (s1, z0), (s1, z1), (s0, z1)]
                    .iter()
                    .map(|&(s, z)| o.axis.point3(s, o.line, z))
                    .collect();
                Hole {
                    profile,
                    thickness: o.thickness,
                    kind: o.kind,
                    state: o.state,
                }
            })
            .collect();
        Floorplan {
            rooms,
            walls,
            holes,
            items: Vec::new(),
            ceiling: None,
        }
    }

    /// The thickness of the wall whose centre line is at `across` on `axis` (outside walls lie on
    /// the footprint's boundary).
    pub fn wall_thickness(&self, axis: Axis, across: f32) -> f32 {
        let [lo, hi] = self.footprint.extent(axis.other());
        if (across - lo).abs() < 1e-3 || (across - hi).abs() < 1e-3 {
            EXTERIOR_WALL
        } else {
            INTERIOR_WALL
        }
    }
}

/// Plans the floorplan for `config`.
pub(crate) fn plan(config: &SynthConfig, rng: &mut impl RngCore) -> Layout {
    let footprint = footprint(config, rng);
    let mut leaves = Vec::new();
    let mut cuts = Vec::new();
    partition(footprint, config.rooms, rng, &mut leaves, &mut cuts);
    let kinds = room_types(config.kind, &leaves);
    let mut layout = Layout {
        footprint,
        height: config.wall_height,
        rooms: Vec::with_capacity(leaves.len()),
        walls: outside_walls(footprint),
        openings: Vec::new(),
        outside: Look::named(
            pick(rng, &["white", "light gray", "beige"]),
            Material::Paint,
            rng.next_u32(),
        ),
    };
    layout.walls.extend(cuts);
    for (rect, kind) in leaves.iter().zip(&kinds) {
        let inner = Rect {
            min: rect.min
                + Vec2::new(
                    layout.wall_thickness(Axis::Y, rect.min.x),
                    layout.wall_thickness(Axis::X, rect.min.y),
                ) * 0.5,
            max: rect.max
                - Vec2::new(
                    layout.wall_thickness(Axis::Y, rect.max.x),
                    layout.wall_thickness(Axis::X, rect.max.y),
                ) * 0.5,
        };
        let (floor, wall, ceiling) = finishes(config.kind, kind, rng);
        layout.rooms.push(RoomCell {
            rect: *rect,
            inner,
            kind,
            floor,
            wall,
            ceiling,
        });
    }
    add_doors(&mut layout, config.kind, rng);
    add_windows(&mut layout, rng);
    layout
}

/// A footprint whose area grows with the room count, centred on the origin.
fn footprint(config: &SynthConfig, rng: &mut impl RngCore) -> Rect {
    let (lo, hi) = match config.kind {
        SceneKind::Home => (12.0, 18.0),
        SceneKind::Office => (18.0, 28.0),
        SceneKind::Shop => (22.0, 34.0),
    };
    let area = config.rooms as f32 * uniform(rng, lo, hi);
    let aspect = uniform(rng, 1.0, 1.5);
    let long = ((area * aspect).sqrt() * 20.0).round() / 20.0;
    let short = (area / long * 20.0).round() / 20.0;
    let size = if rng.random_bool(0.5) {
        Vec2::new(long, short)
    } else {
        Vec2::new(short, long)
    };
    Rect {
        min: -size * 0.5,
        max: size * 0.5,
    }
}

/// The four outside walls, each running past the corners so that they close them.
fn outside_walls(f: Rect) -> Vec<WallLine> {
    let e = EXTERIOR_WALL * 0.5;
    let along_x = [f.min.x - e, f.max.x + e];
    let along_y = [f.min.y - e, f.max.y + e];
    vec![
        WallLine {
            axis: Axis::X,
            line: f.min.y,
            span: along_x,
            thickness: EXTERIOR_WALL,
        },
        WallLine {
            axis: Axis::Y,
            line: f.max.x,
            span: along_y,
            thickness: EXTERIOR_WALL,
        },
        WallLine {
            axis: Axis::X,
            line: f.max.y,
            span: along_x,
            thickness: EXTERIOR_WALL,
        },
        WallLine {
            axis: Axis::Y,
            line: f.min.x,
            span: along_y,
            thickness: EXTERIOR_WALL,
        },
    ]
}

/// Cuts `rect` into `n` rooms (fewer only where it cannot hold `n` rooms of the minimum size),
/// recording one wall per cut.
fn partition(
    rect: Rect,
    n: usize,
    rng: &mut impl RngCore,
    leaves: &mut Vec<Rect>,
    cuts: &mut Vec<WallLine>,
) {
    if n <= 1 {
        leaves.push(rect);
        return;
    }
    let n1 = if n % 2 == 1 && rng.random_bool(0.5) {
        n / 2 + 1
    } else {
        n / 2
    };
    let n2 = n - n1;
    let size = rect.size();
    let longer = if size.x >= size.y { Axis::X } else { Axis::Y };
    for cut in [longer, longer.other()] {
        // The cut runs across `cut`, so the wall it leaves runs along the other axis.
        let wall_axis = cut.other();
        let [lo, hi] = rect.extent(cut);
        let [side0, side1] = rect.extent(wall_axis);
        // A part holding k rooms needs one row of minimum depth per `strips` rooms.
        let strips = ((side1 - side0) / MIN_ROOM).floor().max(1.0);
        let need = |k: usize| MIN_ROOM * (k as f32 / strips).ceil();
        let (a, b) = (lo + need(n1), hi - need(n2));
        if a > b {
            continue;
        }
        let fraction = n1 as f32 / n as f32 + uniform(rng, -0.08, 0.08);
        let at = (((lo + fraction * (hi - lo)) * 20.0).round() / 20.0).clamp(a, b);
        let first = Rect {
            min: rect.min,
            max: wall_axis.point(side1, at),
        };
        let second = Rect {
            min: wall_axis.point(side0, at),
            max: rect.max,
        };
        let wall = WallLine {
            axis: wall_axis,
            line: at,
            span: [side0, side1],
            thickness: INTERIOR_WALL,
        };
        cuts.push(wall);
        partition(first, n1, rng, leaves, cuts);
        partition(second, n2, rng, leaves, cuts);
        return;
    }
    leaves.push(rect);
}

/// How room types are dealt out for a kind of scene.
struct Scheme {
    /// Types for the rooms in order of decreasing area.
    sequence: &'static [&'static str],
    /// Types dealt in turn once `sequence` is used up.
    cycle: &'static [&'static str],
    /// The type of the smallest rooms …
    small: &'static str,
    /// … of which there is one per this many rooms …
    small_every: usize,
    /// … once there are at least this many rooms.
    small_from: usize,
    /// The type of the most elongated room, in scenes with at least 6 rooms.
    elongated: Option<&'static str>,
}

fn scheme(kind: SceneKind) -> Scheme {
    match kind {
        SceneKind::Home => Scheme {
            sequence: &[
                "Living Room",
                "Master Bedroom",
                "Kitchen",
                "Bedroom",
                "Dining Room",
                "Study",
            ],
            cycle: &["Bedroom", "Study", "Dining Room"],
            small: "Bathroom",
            small_every: 5,
            small_from: 3,
            elongated: Some("Corridor"),
        },
        SceneKind::Office => Scheme {
            sequence: &["Open Office", "Meeting Room", "Reception", "Manager Office"],
            cycle: &["Manager Office", "Meeting Room", "Open Office"],
            small: "Pantry",
            small_every: 8,
            small_from: 3,
            elongated: None,
        },
        SceneKind::Shop => Scheme {
            sequence: &["Sales Floor", "Storage Room", "Checkout"],
            cycle: &["Sales Floor", "Storage Room", "Sales Floor"],
            small: "Fitting Room",
            small_every: 6,
            small_from: 3,
            elongated: None,
        },
    }
}

/// Room types by area: the largest room is the main one (living room, open office, sales floor),
/// the smallest are bathrooms, pantries or fitting rooms, an elongated one may be a corridor.
fn room_types(kind: SceneKind, rects: &[Rect]) -> Vec<&'static str> {
    let s = scheme(kind);
    let n = rects.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| rects[b].area().total_cmp(&rects[a].area()).then(a.cmp(&b)));
    let mut types: Vec<Option<&'static str>> = vec![None; n];
    let smalls = if n >= s.small_from {
        (n / s.small_every).max(1)
    } else {
        0
    };
    for &i in order.iter().rev().take(smalls) {
        types[i] = Some(s.small);
    }
    if let Some(corridor) = s.elongated.filter(|_| n >= 6) {
        let aspect = |r: &Rect| r.size().max_element() / r.size().min_element();
        let candidate = order[1..]
            .iter()
            .copied()
            .filter(|&i| types[i].is_none() && aspect(&rects[i]) >= 1.8)
            .max_by(|&a, &b| {
                aspect(&rects[a])
                    .total_cmp(&aspect(&rects[b]))
                    .then(b.cmp(&a))
            });
        if let Some(i) = candidate {
            types[i] = Some(corridor);
        }
    }
    let mut deal = s.sequence.iter().chain(s.cycle.iter().cycle());
    for &i in &order {
        if types[i].is_none() {
            types[i] = deal.next().copied();
        }
    }
    types.into_iter().map(|t| t.unwrap_or(s.small)).collect()
}

/// Floor, wall and ceiling finishes for a room type.
fn finishes(kind: SceneKind, room: &str, rng: &mut impl RngCore) -> (Look, Look, Look) {
    let (material, colors): (Material, &[&str]) = match (kind, room) {
        (_, "Kitchen" | "Bathroom" | "Pantry") => (
            Material::Tiles,
            &["white", "light gray", "beige", "cream", "light blue"],
        ),
        (SceneKind::Home, "Bedroom" | "Master Bedroom") if rng.random_bool(0.4) => {
            (Material::Carpet, &["beige", "gray", "cream"])
        }
        (SceneKind::Home, _) => (Material::Planks, &["tan", "brown", "beige"]),
        (SceneKind::Office, "Reception") => (Material::Marble, &["white", "beige", "light gray"]),
        (SceneKind::Office, _) => (Material::Carpet, &["gray", "beige", "navy", "light gray"]),
        (SceneKind::Shop, "Fitting Room") => (Material::Carpet, &["beige", "gray"]),
        (SceneKind::Shop, "Storage Room") => (Material::Concrete, &["gray", "light gray"]),
        (SceneKind::Shop, _) if rng.random_bool(0.5) => {
            (Material::Concrete, &["light gray", "gray", "beige"])
        }
        (SceneKind::Shop, _) => (Material::Tiles, &["white", "light gray", "beige"]),
    };
    let floor = Look::named(pick(rng, colors), material, rng.next_u32());
    let paint = [
        "white",
        "white",
        "cream",
        "light gray",
        "beige",
        "light blue",
        "pink",
    ];
    let wall = Look::named(pick(rng, &paint), Material::Paint, rng.next_u32());
    // A slightly different shade per room, so neighbouring rooms read apart.
    let tint = Vec3::new(
        uniform(rng, 0.97, 1.03),
        uniform(rng, 0.97, 1.03),
        uniform(rng, 0.97, 1.03),
    );
    let wall = wall.with_rgb((wall.rgb * tint).min(Vec3::ONE));
    let ceiling = Look::named("white", Material::Paint, rng.next_u32());
    (floor, wall, ceiling)
}

/// A stretch of wall shared by two rooms, `a` on the lower "across" side.
#[derive(Debug, Clone, Copy)]
struct Shared {
    a: usize,
    b: usize,
    axis: Axis,
    line: f32,
    span: [f32; 2],
}

fn shared_walls(rooms: &[RoomCell]) -> Vec<Shared> {
    let mut out = Vec::new();
    for i in 0..rooms.len() {
        for j in 0..rooms.len() {
            let (ri, rj) = (rooms[i].rect, rooms[j].rect);
            // Room j right of room i (a wall along Y), then above it (a wall along X).
            let sides = [
                (
                    ri.max.x,
                    rj.min.x,
                    Axis::Y,
                    [ri.min.y.max(rj.min.y), ri.max.y.min(rj.max.y)],
                ),
                (
                    ri.max.y,
                    rj.min.y,
                    Axis::X,
                    [ri.min.x.max(rj.min.x), ri.max.x.min(rj.max.x)],
                ),
            ];
            for (edge, other, axis, span) in sides {
                if (edge - other).abs() < 1e-3 && span[1] > span[0] {
                    out.push(Shared {
                        a: i,
                        b: j,
                        axis,
                        line: edge,
                        span,
                    });
                }
            }
        }
    }
    out
}

/// How private a room type is: 0 for shared spaces people walk through, 1 for private rooms,
/// 2 for rooms that should have a single door. Doors are laid out from shared spaces first.
fn privacy(kind: &str) -> u8 {
    match kind {
        "Bathroom" | "Fitting Room" | "Pantry" | "Storage Room" => 2,
        "Bedroom" | "Master Bedroom" | "Study" | "Manager Office" | "Meeting Room" => 1,
        _ => 0,
    }
}

/// Where along `span` a door of `width` goes, if it fits between jambs.
fn door_center(span: [f32; 2], width: f32, rng: &mut impl RngCore) -> Option<f32> {
    let (lo, hi) = (span[0] + JAMB + width * 0.5, span[1] - JAMB - width * 0.5);
    if lo > hi {
        return None;
    }
    // Doors often sit near a corner.
    Some(match rng.random_range(0..3) {
        0 => lo + uniform(rng, 0.0, 0.3).min(hi - lo),
        1 => hi - uniform(rng, 0.0, 0.3).min(hi - lo),
        _ => uniform(rng, lo, hi),
    })
}

/// Doors along a random spanning tree of the rooms (so every room is reachable; private rooms and
/// bathrooms hang off shared spaces where they can), a few extra doors from shared spaces, an
/// entrance, and a state for each door.
fn add_doors(layout: &mut Layout, kind: SceneKind, rng: &mut impl RngCore) {
    let width = if kind == SceneKind::Home { 0.9 } else { 1.0 };
    let n = layout.rooms.len();
    let edges: Vec<Shared> = shared_walls(&layout.rooms)
        .into_iter()
        .filter(|s| s.span[1] - s.span[0] >= width + 2.0 * JAMB)
        .collect();
    let root = (0..n).max_by(|&a, &b| {
        layout.rooms[a]
            .rect
            .area()
            .total_cmp(&layout.rooms[b].rect.area())
            .then(b.cmp(&a))
    });
    let mut chosen = Vec::new();
    let mut joined = vec![false; n];
    if let Some(r) = root {
        joined[r] = true;
    }
    loop {
        let frontier: Vec<usize> = (0..edges.len())
            .filter(|&e| joined[edges[e].a] != joined[edges[e].b])
            .collect();
        // Grow the tree from the most public rooms reachable so far.
        let rank = |e: usize| {
            privacy(
                layout.rooms[if joined[edges[e].a] {
                    edges[e].a
                } else {
                    edges[e].b
                }]
                .kind,
            )
        };
        let Some(best) = frontier.iter().map(|&e| rank(e)).min() else {
            break;
        };
        let pool: Vec<usize> = frontier.into_iter().filter(|&e| rank(e) == best).collect();
        let Some(&e) = pool.choose(rng) else { break };
        joined[edges[e].a] = true;
        joined[edges[e].b] = true;
        chosen.push(e);
    }
    let mut rest: Vec<usize> = (0..edges.len()).filter(|e| !chosen.contains(e)).collect();
    rest.shuffle(rng);
    let extra_max = n / 4;
    for e in rest {
        let s = edges[e];
        let (pa, pb) = (
            privacy(layout.rooms[s.a].kind),
            privacy(layout.rooms[s.b].kind),
        );
        if chosen.len() < n - 1 + extra_max
            && pa.max(pb) < 2
            && pa.min(pb) == 0
            && rng.random_bool(0.35)
        {
            chosen.push(e);
        }
    }
    for &e in &chosen {
        let s = edges[e];
        let stretch = Stretch {
            axis: s.axis,
            line: s.line,
            span: s.span,
            rooms: [Some(s.a), Some(s.b)],
        };
        if let Some(d) = place_door(&layout.openings, &stretch, width, None, rng) {
            layout.openings.push(d);
        }
    }
    if let Some(r) = root {
        add_entrance(layout, r, width + 0.1, rng);
    }
    assign_states(&mut layout.openings, rng);
}

/// A stretch of wall a door can go into, with the rooms on its lower and upper "across" side.
#[derive(Debug, Clone, Copy)]
struct Stretch {
    axis: Axis,
    line: f32,
    span: [f32; 2],
    rooms: [Option<usize>; 2],
}

/// The floor a door leaf sweeps: the square over the opening on the side it swings into.
fn sweep(o: &Opening) -> Rect {
    let face = o.line + o.swing * o.thickness * 0.5;
    let a = o.axis.point(o.span[0], face);
    let b = o.axis.point(o.span[1], face + o.swing * o.width());
    Rect {
        min: a.min(b),
        max: a.max(b),
    }
}

/// A door in `stretch` whose leaf sweeps clear of the other doors' (the last try if none does),
/// swinging to the side `swing` (random when `None`).
fn place_door(
    openings: &[Opening],
    stretch: &Stretch,
    width: f32,
    swing: Option<f32>,
    rng: &mut impl RngCore,
) -> Option<Opening> {
    let mut last = None;
    for _ in 0..30 {
        let center = door_center(stretch.span, width, rng)?;
        let swing = swing.unwrap_or_else(|| if rng.random_bool(0.5) { 1.0 } else { -1.0 });
        let d = Opening {
            kind: HoleKind::Door,
            axis: stretch.axis,
            line: stretch.line,
            span: [center - width * 0.5, center + width * 0.5],
            z: [0.0, DOOR_TOP],
            thickness: if stretch.rooms.contains(&None) {
                EXTERIOR_WALL
            } else {
                INTERIOR_WALL
            },
            state: None,
            rooms: stretch.rooms,
            swing,
            hinge_at_start: rng.random_bool(0.5),
        };
        let mine = sweep(&d).shrink(-0.05);
        let clear = openings
            .iter()
            .filter(|o| o.kind == HoleKind::Door)
            .all(|o| {
                let other = sweep(o);
                mine.max.x <= other.min.x
                    || other.max.x <= mine.min.x
                    || mine.max.y <= other.min.y
                    || other.max.y <= mine.min.y
            });
        if clear {
            return Some(d);
        }
        last = Some(d);
    }
    last
}

/// The sides of room `r` on the outside walls.
fn outside_sides(layout: &Layout, r: usize) -> Vec<Stretch> {
    let (rect, f) = (layout.rooms[r].rect, layout.footprint);
    let (along_x, along_y) = ([rect.min.x, rect.max.x], [rect.min.y, rect.max.y]);
    // (room edge, footprint edge, wall axis, span, room below / above the line)
    let candidates = [
        (rect.min.y, f.min.y, Axis::X, along_x, [None, Some(r)]),
        (rect.max.y, f.max.y, Axis::X, along_x, [Some(r), None]),
        (rect.min.x, f.min.x, Axis::Y, along_y, [None, Some(r)]),
        (rect.max.x, f.max.x, Axis::Y, along_y, [Some(r), None]),
    ];
    candidates
        .into_iter()
        .filter(|(edge, outer, ..)| (edge - outer).abs() < 1e-3)
        .map(|(_, line, axis, span, rooms)| Stretch {
            axis,
            line,
            span,
            rooms,
        })
        .collect()
}

/// A front door on the longest outside side of the main room (or of the largest room that has one).
fn add_entrance(layout: &mut Layout, main: usize, width: f32, rng: &mut impl RngCore) {
    let mut order: Vec<usize> = (0..layout.rooms.len()).collect();
    order.sort_by(|&a, &b| {
        layout.rooms[b]
            .rect
            .area()
            .total_cmp(&layout.rooms[a].rect.area())
            .then(a.cmp(&b))
    });
    order.retain(|&r| r != main);
    order.insert(0, main);
    for r in order {
        let longest = outside_sides(layout, r)
            .into_iter()
            .max_by(|a, b| (a.span[1] - a.span[0]).total_cmp(&(b.span[1] - b.span[0])));
        if let Some(side) = longest {
            let inwards = if side.rooms[1] == Some(r) { 1.0 } else { -1.0 };
            if let Some(d) = place_door(&layout.openings, &side, width, Some(inwards), rng) {
                layout.openings.push(d);
                return;
            }
        }
    }
}

/// Door states: with three or more doors each state occurs at least once; most doors are open.
fn assign_states(openings: &mut [Opening], rng: &mut impl RngCore) {
    let mut doors: Vec<usize> = (0..openings.len())
        .filter(|&i| openings[i].kind == HoleKind::Door)
        .collect();
    doors.shuffle(rng);
    for (k, &i) in doors.iter().enumerate() {
        let state = match k {
            0 => DoorState::Open,
            1 if doors.len() >= 3 => DoorState::Closed,
            2 => DoorState::HalfOpen,
            _ => match rng.random_range(0..20) {
                0..14 => DoorState::Open,
                14..17 => DoorState::Closed,
                _ => DoorState::HalfOpen,
            },
        };
        openings[i].state = Some(state);
    }
}

/// Windows on most outside sides of every room (two on long sides), clear of doors.
fn add_windows(layout: &mut Layout, rng: &mut impl RngCore) {
    let top = (layout.height - 0.25).min(2.1);
    for r in 0..layout.rooms.len() {
        let bathroom = layout.rooms[r].kind == "Bathroom";
        let (sill, widths) = if bathroom {
            (1.4, (0.6, 0.8))
        } else {
            (0.9, (0.9, 1.6))
        };
        for Stretch {
            axis,
            line,
            span,
            rooms,
        } in outside_sides(layout, r)
        {
            if !rng.random_bool(0.8) {
                continue;
            }
            let (lo, hi) = (span[0] + JAMB + 0.15, span[1] - JAMB - 0.15);
            let count = if hi - lo > 4.5 { 2 } else { 1 };
            let step = (hi - lo) / count as f32;
            for k in 0..count {
                let (a, b) = (lo + step * k as f32, lo + step * (k + 1) as f32);
                let width = uniform(rng, widths.0, widths.1).min(b - a - 0.1);
                if width < 0.5 {
                    continue;
                }
                let c = uniform(rng, a + width * 0.5, b - width * 0.5);
                let clear = layout.openings.iter().all(|o| {
                    o.axis != axis
                        || (o.line - line).abs() > 1e-3
                        || o.span[1] + 0.3 < c - width * 0.5
                        || o.span[0] - 0.3 > c + width * 0.5
                });
                if clear {
                    layout.openings.push(Opening {
                        kind: HoleKind::Window,
                        axis,
                        line,
                        span: [c - width * 0.5, c + width * 0.5],
                        z: [sill, top],
                        thickness: EXTERIOR_WALL,
                        state: None,
                        rooms,
                        swing: 0.0,
                        hinge_at_start: false,
                    });
                }
            }
        }
    }
}
