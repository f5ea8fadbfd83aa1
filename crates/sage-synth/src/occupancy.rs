//! The occupancy map of a synthetic scene: free inside the footprint, occupied where a wall stands
//! (open doorways stay free; closed and half-open doors block) or where an object's box reaches
//! into the height band an agent's body sweeps, unknown outside.

use crate::item::Item;
use crate::layout::{Axis, Layout};
use glam::{Vec2, Vec3};
use sage_core::{Obb, Result};
use sage_scene::occupancy::{FREE, OCCUPIED, OccupancyMap};

/// Margin of the map around the footprint (m).
const MARGIN: f32 = 0.5;
/// The height band an object must reach into to block (m).
const BAND: (f32, f32) = (0.1, 1.2);

/// Builds the map at `cell` metres per cell.
pub(crate) fn build(layout: &Layout, items: &[Item], cell: f32) -> Result<OccupancyMap> {
    let f = layout.footprint;
    let lower = (f.min - Vec2::splat(MARGIN)).extend(0.0);
    let upper = (f.max + Vec2::splat(MARGIN)).extend(layout.height);
    let mut map = OccupancyMap::new(lower, upper, cell)?;
    for r in 0..map.height {
        for c in 0..map.width {
            if f.contains(map.cell_center(c, r)) {
                map.cells[r * map.width + c] = FREE;
            }
        }
    }
    for o in layout.openings.iter().filter(|o| o.is_open_door()) {
        let doorway = flat_box(o.axis, o.line, o.span, o.thickness);
        fill(&mut map, &doorway, FREE, |m, c, r| {
            doorway.contains(m.cell_center(c, r).extend(0.0), 1e-4)
        });
    }
    for w in &layout.walls {
        let mut at = w.span[0];
        let mut doors: Vec<[f32; 2]> = layout
            .openings
            .iter()
            .filter(|o| o.is_open_door() && o.axis == w.axis && (o.line - w.line).abs() < 1e-3)
            .map(|o| o.span)
            .filter(|s| s[0] < w.span[1] && s[1] > w.span[0])
            .collect();
        doors.sort_by(|a, b| a[0].total_cmp(&b[0]));
        doors.push([w.span[1], w.span[1]]);
        for d in doors {
            if d[0] > at {
                block(&mut map, &flat_box(w.axis, w.line, [at, d[0]], w.thickness));
            }
            at = at.max(d[1]);
        }
    }
    for item in items
        .iter()
        .filter(|i| i.obb.min_z() < BAND.1 && i.obb.max_z() > BAND.0)
    {
        block(&mut map, &item.obb);
    }
    Ok(map)
}

/// The floor box of a wall stretch (zero height; only its footprint matters).
fn flat_box(axis: Axis, line: f32, span: [f32; 2], thickness: f32) -> Obb {
    let c = axis.point(0.5 * (span[0] + span[1]), line);
    Obb {
        center: c.extend(0.0),
        half_extents: Vec3::new(0.5 * (span[1] - span[0]), 0.5 * thickness, 0.0),
        yaw: axis.yaw(),
    }
}

/// Marks every cell whose square overlaps the footprint of `b` as occupied.
fn block(map: &mut OccupancyMap, b: &Obb) {
    fill(map, b, OCCUPIED, |m, c, r| {
        square_overlaps(m.cell_center(c, r), m.scale * 0.5, b)
    });
}

/// Sets the cells near `b` that pass `hit` to `value`.
fn fill(
    map: &mut OccupancyMap,
    b: &Obb,
    value: u8,
    hit: impl Fn(&OccupancyMap, usize, usize) -> bool,
) {
    let bounds = b.aabb();
    let (lo, hi) = (bounds.min.truncate(), bounds.max.truncate());
    let column = |x: f32| ((map.upper.x - x) / map.scale).floor();
    let row = |y: f32| ((y - map.lower.y) / map.scale).floor();
    let clamp = |v: f32, n: usize| v.clamp(0.0, n.saturating_sub(1) as f32) as usize;
    let (c0, c1) = (
        clamp(column(hi.x) - 1.0, map.width),
        clamp(column(lo.x) + 1.0, map.width),
    );
    let (r0, r1) = (
        clamp(row(lo.y) - 1.0, map.height),
        clamp(row(hi.y) + 1.0, map.height),
    );
    for r in r0..=r1 {
        for c in c0..=c1 {
            if hit(map, c, r) {
                map.cells[r * map.width + c] = value;
            }
        }
    }
}

/// True when the axis-aligned square of half-size `h` at `p` overlaps the footprint of `b` by more
/// than a hair.
fn square_overlaps(p: Vec2, h: f32, b: &Obb) -> bool {
    let d = b.center.truncate() - p;
    let (ax, ay) = b.axes();
    let (ex, ey) = (b.half_extents.x, b.half_extents.y);
    let eps = 1e-4;
    let separated = |n: Vec2, r_square: f32| {
        let r_box = ex * ax.dot(n).abs() + ey * ay.dot(n).abs();
        d.dot(n).abs() >= r_square + r_box - eps
    };
    !(separated(Vec2::X, h)
        || separated(Vec2::Y, h)
        || separated(ax, h * (ax.x.abs() + ax.y.abs()))
        || separated(ay, h * (ay.x.abs() + ay.y.abs())))
}
