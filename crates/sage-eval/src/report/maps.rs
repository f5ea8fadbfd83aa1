//! Per-episode top-down maps: the scene's semantic map with the reference path, the agent's
//! path, start and goal, the goal region and the collision points (the paper's figure of ground
//! truth against agent trajectories).
//!
//! The overlays take the colour-blind-safe colours of [`sage_io::palette`] and differ in shape
//! or line style too (the reference dashed, the start a square, the goal a diamond, a collision
//! a cross), while the semantic map under them is drawn in muted tints, so the overlays stand
//! out. [`overlay`] draws one episode record over any semantic-map canvas, so other commands
//! can put paths on their own maps; [`episode_map`] is the report's whole image: the map, a
//! caption naming the episode and its SR, NE and nDTW, and a legend of what this map shows.

use crate::records::EvalRecord;
use glam::Vec2;
use sage_io::canvas::{self as draw, Canvas};
use sage_io::marks::{
    AGENT_WIDTH, COLLISION_RADIUS, GOAL_RADIUS, HALO, MARK_HALO, MARKER_RADIUS, REFERENCE_WIDTH,
    REGION_WIDTH, Shape, dashed_polyline, mark, polyline, stamp,
};
use sage_io::palette::AGENT_PATH as AGENT;
use sage_io::palette::REFERENCE_PATH as REFERENCE;
use sage_io::palette::{self, muted};
use sage_io::palette::{COLLISION, GOAL, START};
use sage_metrics::EpisodeRecord;
use sage_nav::grid::NO_ROOM;
use sage_nav::{NavGrid, SemanticMap};
use sage_scene::occupancy::OCCUPIED;
use std::collections::BTreeSet;

/// The folder of the maps, under the report folder.
pub const MAPS_DIR: &str = "maps";
/// Walls, dark so the light door colours show in them.
pub const WALL: [u8; 3] = [85, 85, 85];
/// Occupied slab cells.
pub const OCCUPIED_CELL: [u8; 3] = [178, 178, 178];
/// Floor outside every room.
pub const OUTSIDE: [u8; 3] = [236, 236, 236];
/// How much of its own colour an object category keeps ([`muted`]).
const CATEGORY_STRENGTH: f32 = 0.35;
/// How much of its own colour a room's floor keeps: paler than the objects on it.
const ROOM_STRENGTH: f32 = 0.15;
/// Target size of the map part of the image (pixels along the longer side).
const MAP_PIXELS: usize = 800;
/// Text.
const INK: [u8; 3] = [20, 20, 20];

fn xy(p: &[f32; 3]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

/// The goal region's outline, closed, when the record has one.
fn region(rec: &EpisodeRecord) -> Option<Vec<Vec2>> {
    let poly = rec.goal.as_ref()?.footprint.as_ref()?;
    (poly.len() >= 2).then(|| {
        poly.iter()
            .chain(poly.first())
            .map(|p| Vec2::new(p[0] as f32, p[1] as f32))
            .collect()
    })
}

/// The positions of the steps that ended in contact.
fn contacts(rec: &EpisodeRecord) -> Vec<Vec2> {
    rec.steps
        .iter()
        .filter(|s| s.contact)
        .map(|s| xy(&s.position))
        .collect()
}

/// Draws `rec` over `canvas`: the goal region's outline, the reference path (dashed), the
/// agent's path (start, then every step's position), the start square and the goal diamond,
/// and a cross at every step that ended in contact — drawn last, so no collision is hidden.
pub fn overlay(canvas: &mut Canvas, rec: &EpisodeRecord) {
    if let Some(outline) = region(rec) {
        polyline(canvas, &outline, GOAL, REGION_WIDTH);
    }
    let reference: Vec<Vec2> = rec.reference_path.iter().map(xy).collect();
    dashed_polyline(canvas, &reference, REFERENCE, REFERENCE_WIDTH);
    let agent: Vec<Vec2> = std::iter::once(&rec.start)
        .chain(rec.steps.iter().map(|s| &s.position))
        .map(xy)
        .collect();
    polyline(canvas, &agent, AGENT, AGENT_WIDTH);
    mark(canvas, xy(&rec.start), Shape::Square, MARKER_RADIUS, START);
    if let Some(goal) = &rec.goal {
        let g = Vec2::new(goal.point[0] as f32, goal.point[1] as f32);
        mark(canvas, g, Shape::Diamond, GOAL_RADIUS, GOAL);
    }
    // All halos before all crosses: a halo never covers a neighbouring collision.
    let hits = contacts(rec);
    for p in &hits {
        stamp(canvas, *p, Shape::Cross, COLLISION_RADIUS, MARK_HALO, HALO);
    }
    for p in &hits {
        stamp(canvas, *p, Shape::Cross, COLLISION_RADIUS, 0, COLLISION);
    }
}

/// One thing an episode map can show, as its legend names and draws it.
#[derive(Debug, Clone, PartialEq)]
pub enum Key {
    /// The reference path.
    Reference,
    /// The agent's path.
    Agent,
    /// The start.
    Start,
    /// The goal point.
    Goal,
    /// The goal region's outline.
    GoalRegion,
    /// Steps that ended in contact.
    Collision,
    /// Door openings in a state (`open`, `half-open`, `closed`, `unknown`).
    Door(&'static str),
    /// Walls.
    Wall,
    /// Occupied slab cells.
    Occupied,
    /// Objects of a category, with its colour.
    Category(String, [u8; 3]),
}

impl Key {
    /// The legend's label.
    pub fn label(&self) -> String {
        match self {
            Key::Reference => "reference path".into(),
            Key::Agent => "agent path".into(),
            Key::Start => "start".into(),
            Key::Goal => "goal".into(),
            Key::GoalRegion => "goal region".into(),
            Key::Collision => "collision".into(),
            Key::Door(state) => format!("door {state}"),
            Key::Wall => "wall".into(),
            Key::Occupied => "occupied".into(),
            Key::Category(name, _) => name.clone(),
        }
    }

    /// The main colour.
    pub fn colour(&self) -> [u8; 3] {
        match self {
            Key::Reference => REFERENCE,
            Key::Agent => AGENT,
            Key::Start => START,
            Key::Goal | Key::GoalRegion => GOAL,
            Key::Collision => COLLISION,
            Key::Door(state) => palette::door_colour(state),
            Key::Wall => WALL,
            Key::Occupied => OCCUPIED_CELL,
            Key::Category(_, c) => *c,
        }
    }

    /// Draws the key's swatch with the same marks the map uses, in the box of
    /// [`SWATCH_W`] × 16 pixels whose top-left is pixel (x, y).
    fn swatch(&self, canvas: &mut Canvas, x: i64, y: i64) {
        let at = |dx: i64, dy: i64| canvas.to_world(Vec2::new((x + dx) as f32, (y + dy) as f32));
        let line = [at(2, 8), at(SWATCH_W - 2, 8)];
        let centre = at(SWATCH_W / 2, 8);
        match self {
            Key::Reference => dashed_polyline(canvas, &line, REFERENCE, REFERENCE_WIDTH),
            Key::Agent => polyline(canvas, &line, AGENT, AGENT_WIDTH),
            Key::GoalRegion => {
                let square = [at(6, 2), at(30, 2), at(30, 14), at(6, 14), at(6, 2)];
                polyline(canvas, &square, GOAL, REGION_WIDTH);
            }
            Key::Start => mark(canvas, centre, Shape::Square, MARKER_RADIUS, START),
            Key::Goal => mark(canvas, centre, Shape::Diamond, GOAL_RADIUS, GOAL),
            Key::Collision => mark(canvas, centre, Shape::Cross, COLLISION_RADIUS, COLLISION),
            // A door in a stretch of wall, as the map shows it.
            Key::Door(_) => {
                fill(canvas, x, y + 4, SWATCH_W, 8, WALL);
                fill(canvas, x + 10, y + 4, SWATCH_W - 20, 8, self.colour());
            }
            Key::Wall | Key::Occupied | Key::Category(..) => {
                fill(canvas, x + 4, y + 1, SWATCH_W - 8, 14, self.colour());
            }
        }
    }
}

/// Pixel width of a legend swatch.
const SWATCH_W: i64 = 36;
/// Pixel height of a legend row.
const LEGEND_ROW: i64 = 22;
/// Pixel height of one caption line (bitmap font at scale 2) with its spacing.
const CAPTION_LINE: usize = 20;
/// Pixel width of one character of the bitmap font at scale 2.
const CHAR_W: usize = 12;

/// Fills the pixel rectangle with top-left (x, y).
fn fill(canvas: &mut Canvas, x: i64, y: i64, w: i64, h: i64, c: [u8; 3]) {
    for py in y..y + h {
        for px in x..x + w {
            canvas.put(px, py, c);
        }
    }
}

/// The colour of an object category in the report's maps: the semantic map's distinct colour
/// for its index among the scene's categories, muted.
pub fn category_colour(index: usize) -> [u8; 3] {
    muted(draw::palette(index), CATEGORY_STRENGTH)
}

/// The floor colour of room `r`: a pale tint, so neighbouring rooms differ and the objects on
/// them show.
pub fn room_colour(r: usize) -> [u8; 3] {
    muted(draw::palette(r + 101), ROOM_STRENGTH)
}

/// The map's object categories (sorted, as their colours are assigned), with their colours.
pub fn categories(map: &SemanticMap) -> Vec<(String, [u8; 3])> {
    let names: BTreeSet<&str> = map
        .items
        .iter()
        .filter(|i| i.state.is_none())
        .map(|i| i.category.as_str())
        .collect();
    names
        .into_iter()
        .enumerate()
        .map(|(k, c)| (c.to_string(), category_colour(k)))
        .collect()
}

/// What the map of `rec` over `map` and `grid` shows, in legend order: the overlays the record
/// draws, then the doors by the states present, walls, occupied cells and the object
/// categories present.
pub fn legend_keys(map: &SemanticMap, grid: &NavGrid, rec: &EvalRecord) -> Vec<Key> {
    let mut keys = Vec::new();
    if let Some(r) = &rec.record {
        if r.reference_path.len() >= 2 {
            keys.push(Key::Reference);
        }
        if !r.steps.is_empty() {
            keys.push(Key::Agent);
        }
        keys.push(Key::Start);
        if r.goal.is_some() {
            keys.push(Key::Goal);
        }
        if region(r).is_some() {
            keys.push(Key::GoalRegion);
        }
        if r.steps.iter().any(|s| s.contact) {
            keys.push(Key::Collision);
        }
    }
    for (state, _) in palette::DOOR_STATES {
        if map.doors.iter().any(|d| d.state == state) {
            keys.push(Key::Door(state));
        }
    }
    if !map.walls.is_empty() {
        keys.push(Key::Wall);
    }
    if grid.cells.contains(&OCCUPIED) {
        keys.push(Key::Occupied);
    }
    keys.extend(
        categories(map)
            .into_iter()
            .map(|(name, c)| Key::Category(name, c)),
    );
    keys
}

/// The semantic map drawn for the report over `grid`'s extent, `width` pixels wide (at least
/// the map's) and `height` pixels tall (at least the map's), white beyond the map: rooms and
/// objects by category in muted tints, walls, and doors by state. The map is drawn at
/// [`map_zoom`] whole pixels per grid cell.
pub fn base_map(map: &SemanticMap, grid: &NavGrid, width: usize, height: usize) -> Canvas {
    base_map_rows(map, grid, grid.height * map_zoom(grid), width, height)
}

/// [`base_map`] with the map drawn `map_rows` pixels tall (any number, so a map can fit a
/// panel of another image: the episode videos'); the cells take whole pixels, each as many as
/// its share of the rows rounds to, and walls and doors are drawn with their outlines, so thin
/// ones show at any size.
pub fn base_map_rows(
    map: &SemanticMap,
    grid: &NavGrid,
    map_rows: usize,
    width: usize,
    height: usize,
) -> Canvas {
    let map_rows = map_rows.max(1);
    // Pixels per cell: a whole number for the report's own maps, so they stay as they were.
    let zoom = map_rows as f32 / grid.height.max(1) as f32;
    let mut canvas = Canvas::new(
        width,
        height,
        [255; 3],
        grid.origin,
        grid.cell / zoom,
        map_rows,
    );
    // The pixel edges of cells 0..=n along an axis.
    let edges = |n: usize| -> Vec<i64> {
        (0..=n)
            .map(|k| (k as f64 * f64::from(zoom)).floor() as i64)
            .collect()
    };
    let (xs, ys) = (edges(grid.width), edges(grid.height));
    for j in 0..grid.height {
        for i in 0..grid.width {
            let k = grid.index(i, j);
            let c = match (grid.cells[k], grid.rooms[k]) {
                (OCCUPIED, _) => OCCUPIED_CELL,
                (_, NO_ROOM) => OUTSIDE,
                (_, r) => room_colour(r as usize),
            };
            // Row 0 of the image is the grid's top row.
            let (y0, y1) = (ys[grid.height - 1 - j], ys[grid.height - j]);
            fill(&mut canvas, xs[i], y0, xs[i + 1] - xs[i], y1 - y0, c);
        }
    }
    let colours = categories(map);
    for item in map.items.iter().filter(|i| i.state.is_none()) {
        let c = colours
            .iter()
            .find(|(name, _)| *name == item.category)
            .map_or(OUTSIDE, |x| x.1);
        canvas.fill_polygon(&item.polygon, c);
    }
    for w in &map.walls {
        canvas.fill_polygon(&w.polygon, WALL);
    }
    for d in &map.doors {
        canvas.fill_polygon(&d.polygon, palette::door_colour(d.state));
    }
    canvas
}

/// Pixels per grid cell of the map part.
pub fn map_zoom(grid: &NavGrid) -> usize {
    (MAP_PIXELS / grid.width.max(grid.height).max(1)).clamp(1, 8)
}

/// A metric for a caption: three decimals, `-` where undefined.
fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3}"))
}

/// The caption lines of an episode's map.
pub fn caption(rec: &EvalRecord) -> [String; 2] {
    let m = rec.metrics.clone().unwrap_or_default();
    let contacts = rec
        .record
        .as_ref()
        .map_or(0, |r| r.steps.iter().filter(|s| s.contact).count());
    [
        format!("episode {} (scene {})", rec.episode_id, rec.scene),
        format!(
            "sr {}  ne {}  ndtw {}  contact steps {contacts}",
            fmt(m.sr),
            fmt(m.ne),
            fmt(m.ndtw)
        ),
    ]
}

/// The map image of one episode: the report's semantic map of `map` over `grid` with the
/// episode's [`overlay`], then under the map its [`caption`] and a legend of what the image
/// shows ([`legend_keys`]) in as many columns as fit. An episode without a record (it was
/// faulted) gets the plain map, its caption and the map's legend.
pub fn episode_map(map: &SemanticMap, grid: &NavGrid, rec: &EvalRecord) -> Canvas {
    let zoom = map_zoom(grid);
    let (map_w, map_h) = (grid.width * zoom, grid.height * zoom);
    let lines = caption(rec);
    let keys = legend_keys(map, grid, rec);
    let widest_caption = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0);
    let widest_label = keys
        .iter()
        .map(|k| k.label().chars().count())
        .max()
        .unwrap_or(0);
    let column = SWATCH_W as usize + 8 + widest_label * CHAR_W + 16;
    let width = map_w.max(16 + widest_caption * CHAR_W).max(column + 16);
    let columns = ((width - 16) / column).max(1);
    let rows = keys.len().div_ceil(columns);
    let caption_top = map_h + 8;
    let legend_top = caption_top + lines.len() * CAPTION_LINE + 8;
    let height = legend_top + rows * LEGEND_ROW as usize + 8;
    let mut canvas = base_map(map, grid, width, height);
    if let Some(r) = &rec.record {
        overlay(&mut canvas, r);
    }
    // Caption and legend go on white: a path that leaves the map below is cut at its edge.
    fill(
        &mut canvas,
        0,
        map_h as i64,
        width as i64,
        (height - map_h) as i64,
        [255; 3],
    );
    for (k, line) in lines.iter().enumerate() {
        canvas.text(8, (caption_top + k * CAPTION_LINE) as i64, line, INK, 2);
    }
    for (n, key) in keys.iter().enumerate() {
        let x = (8 + (n % columns) * column) as i64;
        let y = (legend_top + (n / columns) * LEGEND_ROW as usize) as i64;
        key.swatch(&mut canvas, x, y);
        canvas.text(x + SWATCH_W + 8, y + 1, &key.label(), INK, 2);
    }
    canvas
}
