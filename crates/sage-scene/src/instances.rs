//! The instance table (dense id → object or structure element, category) and the rule that gives
//! every Gaussian an instance (SPEC §4): the object whose oriented box holds it (the smallest box
//! wins), else the structure element it lies on (wall, then floor, then ceiling), else none.

use crate::floorplan::Floorplan;
use crate::gaussians::Gaussians;
use crate::object::Object;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use sage_core::{InstanceId, Obb};

/// How far outside an object's box a Gaussian centre may lie and still belong to it (metres):
/// surface Gaussians sit on the box faces, and compressed positions are quantised.
pub const OBJECT_MARGIN: f32 = 0.01;
/// How far from a wall's or floor's or ceiling's surface a Gaussian may lie and belong to it.
pub const STRUCTURE_MARGIN: f32 = 0.03;

/// What an instance id stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InstanceKind {
    /// Id 0: nothing.
    None,
    /// `objects[i]`.
    Object(usize),
    /// `floorplan.walls[i]`.
    Wall(usize),
    /// The floor of `floorplan.rooms[i]`.
    Floor(usize),
    /// The ceiling of `floorplan.rooms[i]`.
    Ceiling(usize),
}

/// The instances of a scene and their categories; index = [`InstanceId`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InstanceTable {
    /// What each id stands for (`kinds[0]` is [`InstanceKind::None`]).
    pub kinds: Vec<InstanceKind>,
    /// The category id of each instance (index into `categories`; 0 = none).
    pub category_ids: Vec<u16>,
    /// Category names, sorted, with `categories[0] = "none"`.
    pub categories: Vec<String>,
}

impl InstanceTable {
    /// Numbers objects from 1 (in order), then walls, floors and ceilings; fills `objects[i].id`.
    pub fn build(objects: &mut [Object], floorplan: &Floorplan) -> InstanceTable {
        let mut kinds = vec![InstanceKind::None];
        for (i, o) in objects.iter_mut().enumerate() {
            o.id = InstanceId(kinds.len() as u32);
            kinds.push(InstanceKind::Object(i));
        }
        kinds.extend((0..floorplan.walls.len()).map(InstanceKind::Wall));
        kinds.extend((0..floorplan.rooms.len()).map(InstanceKind::Floor));
        kinds.extend((0..floorplan.rooms.len()).map(InstanceKind::Ceiling));
        let name_of = |k: &InstanceKind| match *k {
            InstanceKind::None => "none",
            InstanceKind::Object(i) => objects[i].category.as_str(),
            InstanceKind::Wall(_) => "wall",
            InstanceKind::Floor(_) => "floor",
            InstanceKind::Ceiling(_) => "ceiling",
        };
        let mut categories: Vec<String> = kinds
            .iter()
            .skip(1)
            .map(|k| name_of(k).to_string())
            .collect();
        categories.sort();
        categories.dedup();
        categories.retain(|c| c != "none");
        categories.insert(0, "none".to_string());
        let category_ids = kinds
            .iter()
            .map(|k| {
                categories
                    .binary_search_by(|c| c.as_str().cmp(name_of(k)))
                    .map_or(0, |i| i as u16)
            })
            .collect();
        InstanceTable {
            kinds,
            category_ids,
            categories,
        }
    }

    /// The number of ids, including 0.
    pub fn len(&self) -> usize {
        self.kinds.len()
    }

    /// True when the table holds only id 0 (or nothing).
    pub fn is_empty(&self) -> bool {
        self.kinds.len() <= 1
    }

    /// The category name of an instance ("none" for unknown ids).
    pub fn category_name(&self, id: InstanceId) -> &str {
        let c = self.category_ids.get(id.0 as usize).copied().unwrap_or(0);
        &self.categories[c as usize]
    }
}

/// A uniform 2-D grid over the floor that lists, per cell, the boxes overlapping it. Only an
/// acceleration structure: a point's cell lists every box whose footprint, grown by the margin
/// any lookup tests, can hold the point (in index order), so what a lookup finds after
/// filtering its candidates does not depend on the cells' size or number.
struct BoxGrid {
    origin: Vec2,
    cell: f32,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<u32>>,
}

/// Cells a grid may have per box (plus [`MIN_GRID_CELLS`]): enough for boxes spread over a
/// home at the requested cell size, while a few boxes far apart (a stray label kilometres out)
/// coarsen the cells instead of allocating millions of empty ones.
const GRID_CELLS_PER_BOX: usize = 16;

/// Cells a grid may always have, however few its boxes.
const MIN_GRID_CELLS: usize = 1024;

/// How far around its footprint a box is listed: lookups test `contains` with at most
/// [`STRUCTURE_MARGIN`] along the box's own (rotated) axes, which reaches up to √2 times that
/// beyond its axis-aligned bounds at a corner.
const GRID_MARGIN: f32 = 2.0 * STRUCTURE_MARGIN;

impl BoxGrid {
    /// A grid of cells of `cell` metres, coarser where that would make more than
    /// [`GRID_CELLS_PER_BOX`] cells per box (and [`MIN_GRID_CELLS`]).
    fn new(boxes: &[(Obb, u32)], cell: f32) -> BoxGrid {
        let max_cells = boxes
            .len()
            .saturating_mul(GRID_CELLS_PER_BOX)
            .saturating_add(MIN_GRID_CELLS);
        BoxGrid::with_max_cells(boxes, cell, max_cells)
    }

    /// A grid of cells of at least `cell` metres and at most `max_cells` cells (and 4096 along
    /// a side).
    fn with_max_cells(boxes: &[(Obb, u32)], cell: f32, max_cells: usize) -> BoxGrid {
        let bounds = boxes
            .iter()
            .fold(sage_core::Aabb::EMPTY, |b, (o, _)| b.union(o.aabb()));
        let origin = if bounds.is_empty() {
            Vec2::ZERO
        } else {
            bounds.min.truncate()
        };
        let size = bounds.size().truncate();
        let count = |cell: f32| {
            (
                ((size.x / cell).ceil() as usize).clamp(1, 4096),
                ((size.y / cell).ceil() as usize).clamp(1, 4096),
            )
        };
        let mut cell = cell;
        let (mut nx, mut ny) = count(cell);
        // Ends at the latest with one cell, which `max_cells` (at least 1) allows.
        while nx * ny > max_cells.max(1) {
            cell *= 1.25;
            (nx, ny) = count(cell);
        }
        let mut grid = BoxGrid {
            origin,
            cell: cell.max(size.x / nx as f32).max(size.y / ny as f32),
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
        };
        for (i, (o, _)) in boxes.iter().enumerate() {
            let bb = o.aabb();
            let (x0, y0) = grid.index(bb.min.truncate() - Vec2::splat(GRID_MARGIN));
            let (x1, y1) = grid.index(bb.max.truncate() + Vec2::splat(GRID_MARGIN));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    grid.cells[y * nx + x].push(i as u32);
                }
            }
        }
        grid
    }

    fn index(&self, p: Vec2) -> (usize, usize) {
        let q = (p - self.origin) / self.cell;
        (
            (q.x.max(0.0) as usize).min(self.nx - 1),
            (q.y.max(0.0) as usize).min(self.ny - 1),
        )
    }

    fn candidates(&self, p: Vec2) -> &[u32] {
        let (x, y) = self.index(p);
        &self.cells[y * self.nx + x]
    }
}

/// Sets every Gaussian's instance by the rule of the module docs. Deterministic and parallel.
pub fn assign_instances(
    gaussians: &mut Gaussians,
    objects: &[Object],
    floorplan: &Floorplan,
    table: &InstanceTable,
) {
    let object_boxes: Vec<(Obb, u32)> = objects.iter().map(|o| (o.obb, o.id.0)).collect();
    let first_wall = table
        .kinds
        .iter()
        .position(|k| matches!(k, InstanceKind::Wall(_)))
        .unwrap_or(0) as u32;
    let first_floor = table
        .kinds
        .iter()
        .position(|k| matches!(k, InstanceKind::Floor(_)))
        .unwrap_or(0) as u32;
    let first_ceiling = table
        .kinds
        .iter()
        .position(|k| matches!(k, InstanceKind::Ceiling(_)))
        .unwrap_or(0) as u32;
    let wall_boxes: Vec<(Obb, u32)> = floorplan
        .walls
        .iter()
        .enumerate()
        .map(|(i, w)| (w.obb(), first_wall + i as u32))
        .collect();
    let object_grid = BoxGrid::new(&object_boxes, 0.5);
    let wall_grid = BoxGrid::new(&wall_boxes, 0.5);
    let ceiling = floorplan.ceiling_height();
    let classify = |p: Vec3| -> u32 {
        let xy = p.truncate();
        let best = object_grid
            .candidates(xy)
            .iter()
            .map(|&i| &object_boxes[i as usize])
            .filter(|(o, _)| o.contains(p, OBJECT_MARGIN))
            .min_by(|a, b| a.0.volume().total_cmp(&b.0.volume()).then(a.1.cmp(&b.1)));
        if let Some((_, id)) = best {
            return *id;
        }
        if let Some(&i) = wall_grid
            .candidates(xy)
            .iter()
            .find(|&&i| wall_boxes[i as usize].0.contains(p, STRUCTURE_MARGIN))
        {
            return wall_boxes[i as usize].1;
        }
        let near_floor = p.z.abs() <= STRUCTURE_MARGIN;
        let near_ceiling = (p.z - ceiling).abs() <= STRUCTURE_MARGIN;
        if (near_floor || near_ceiling)
            && let Some(room) = floorplan.room_at(xy)
        {
            return if near_floor {
                first_floor
            } else {
                first_ceiling
            } + room as u32;
        }
        0
    };
    let positions = &gaussians.positions;
    gaussians
        .instances
        .par_chunks_mut(4096)
        .enumerate()
        .for_each(|(c, ids)| {
            for (j, id) in ids.iter_mut().enumerate() {
                *id = classify(Vec3::from_array(positions[c * 4096 + j]));
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The boxes holding `p` (within `margin`) among the candidates of its cell, in order.
    fn found(grid: &BoxGrid, boxes: &[(Obb, u32)], p: Vec3, margin: f32) -> Vec<u32> {
        grid.candidates(p.truncate())
            .iter()
            .copied()
            .filter(|&i| boxes[i as usize].0.contains(p, margin))
            .collect()
    }

    /// The same without a grid: every box, in order.
    fn brute(boxes: &[(Obb, u32)], p: Vec3, margin: f32) -> Vec<u32> {
        (0..boxes.len() as u32)
            .filter(|&i| boxes[i as usize].0.contains(p, margin))
            .collect()
    }

    /// Points on a lattice of 0.1 m (and three heights) over `half` metres around `c`.
    fn around(c: Vec2, half: f32) -> Vec<Vec3> {
        let n = (half / 0.1) as i32;
        let mut out = Vec::new();
        for i in -n..=n {
            for j in -n..=n {
                for z in [-0.02, 0.5, 1.01] {
                    out.push((c + Vec2::new(i as f32, j as f32) * 0.1).extend(z));
                }
            }
        }
        out
    }

    fn obb(x: f32, y: f32, yaw: f32) -> Obb {
        Obb {
            center: Vec3::new(x, y, 0.5),
            half_extents: Vec3::new(0.6, 0.3, 0.5),
            yaw,
        }
    }

    #[test]
    fn far_apart_boxes_build_a_small_grid_that_finds_what_every_box_would() {
        // Two small boxes 2 km apart along both axes: 0.5 m cells would be 4096 × 4096.
        let boxes = vec![(obb(0.0, 0.0, 0.0), 1), (obb(2000.0, 2000.0, 0.7), 2)];
        let grid = BoxGrid::new(&boxes, 0.5);
        assert!(
            grid.cells.len() <= MIN_GRID_CELLS + 2 * GRID_CELLS_PER_BOX,
            "{} cells",
            grid.cells.len()
        );
        for (o, _) in &boxes {
            for p in around(o.center.truncate(), 1.0) {
                for margin in [OBJECT_MARGIN, STRUCTURE_MARGIN] {
                    assert_eq!(
                        found(&grid, &boxes, p, margin),
                        brute(&boxes, p, margin),
                        "{p}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_coarsened_grid_finds_what_the_fine_grid_finds() {
        // 100 m apart (40,000 cells at 0.5 m, which the bound coarsens), the far box turned so
        // that its grown corners reach past its axis-aligned bounds.
        let boxes = vec![
            (obb(0.0, 0.0, 0.0), 1),
            (obb(0.9, 0.2, 0.3), 2),
            (obb(100.0, 100.0, std::f32::consts::FRAC_PI_4), 3),
        ];
        let fine = BoxGrid::with_max_cells(&boxes, 0.5, usize::MAX);
        let coarse = BoxGrid::new(&boxes, 0.5);
        assert!(fine.cells.len() > 40_000, "{} cells", fine.cells.len());
        assert!(coarse.cells.len() <= MIN_GRID_CELLS + 3 * GRID_CELLS_PER_BOX);
        for (o, _) in &boxes {
            for p in around(o.center.truncate(), 1.0) {
                for margin in [OBJECT_MARGIN, STRUCTURE_MARGIN] {
                    let want = brute(&boxes, p, margin);
                    assert_eq!(found(&fine, &boxes, p, margin), want, "{p}");
                    assert_eq!(found(&coarse, &boxes, p, margin), want, "{p}");
                }
            }
        }
    }
}
