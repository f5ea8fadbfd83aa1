//! The occupancy grid of an agent's height slab (SPEC §7).
//!
//! A cell is an obstacle when any object or wall geometry intersects the slab from
//! [`GridParams::slab_bottom`] (0.03 m) to [`GridParams::agent_height`] (1.2 m) above the floor
//! over the cell's square: mesh triangles are clipped to the slab and every cell their floor
//! projection touches is blocked (exact triangle–slab–cell overlap, so thin walls and table tops
//! do not leak), and the inside of each object's closed outline is filled. Walls come from
//! `structure.json`, minus the door and window holes that open the whole slab (a window's sill
//! still blocks; a closed door's hole does not open). Cells inside a room polygon are free, the
//! rest unknown. Objects without a mesh block with their oriented box; an open door leaf without a
//! mesh is no body (SPEC §6). Objects with given convex parts (a published collision file, or
//! parts recovered from their Gaussians) block with those parts, as physics does.
//!
//! That is source 2 of [`NavGrid::from_scene`] ([`crate::source`]), which prefers a scene's own
//! occupancy map where it has no meshes or no rooms, and builds the grid from the Gaussians
//! where it has neither rooms nor a map.
//!
//! Internally column `i` covers world x in `[origin.x + i·cell, origin.x + (i+1)·cell)` and row
//! `j` likewise in y. The InteriorGS `occupancy.png` mirrors x; [`NavGrid::to_occupancy`] and
//! [`NavGrid::from_occupancy`] convert.

use glam::{Vec2, Vec3};
use sage_core::{Error, Result};
use sage_scene::occupancy::{FREE, OCCUPIED, OccupancyMap, UNKNOWN};
use sage_scene::{DoorState, HoleKind, Scene, TriMesh, Wall};

/// Room index of a cell outside every room.
pub const NO_ROOM: u16 = u16::MAX;

/// How the grid is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridParams {
    /// Cell size, metres (default 0.05).
    pub cell: f32,
    /// Top of the agent's slab above the floor, metres (default 1.2).
    pub agent_height: f32,
    /// Bottom of the slab, metres (default 0.03, the lowest body clearance of the agent
    /// profiles, the wheeled robot's): rugs and thresholds below it do not block, an office
    /// chair's star base or a sofa's plinth does, as it blocks the agent's body.
    pub slab_bottom: f32,
    /// Unknown margin around the mapped area, metres (default 0.5).
    pub margin: f32,
}

impl Default for GridParams {
    fn default() -> Self {
        GridParams {
            cell: 0.05,
            agent_height: 1.2,
            slab_bottom: 0.03,
            margin: 0.5,
        }
    }
}

impl GridParams {
    /// Checks the ranges (cell 0.005–1 m, 0 ≤ bottom < height).
    pub fn validate(&self) -> Result<()> {
        if !(self.cell >= 0.005 && self.cell <= 1.0) {
            return Err(Error::invalid(format!(
                "`cell` (the grid cell) must be 0.005-1 m, got {}",
                self.cell
            )));
        }
        if !(self.slab_bottom >= 0.0 && self.slab_bottom.is_finite()) {
            return Err(Error::invalid(format!(
                "the slab bottom must be a finite height >= 0 m, got {}",
                self.slab_bottom
            )));
        }
        // Finite: the slab is what an agent of this height meets (an infinite one would take
        // in the ceiling, and a recorded height must be a JSON number).
        if !(self.agent_height.is_finite() && self.agent_height > self.slab_bottom) {
            return Err(Error::invalid(format!(
                "`agent_height` must be a finite height above the {} m the occupancy map's slab \
                 starts at, got {}",
                self.slab_bottom, self.agent_height
            )));
        }
        if !(self.margin >= 0.0 && self.margin.is_finite()) {
            return Err(Error::invalid("grid margin must be >= 0"));
        }
        Ok(())
    }
}

/// A top-down grid of free / occupied / unknown cells with the room of each cell.
#[derive(Debug, Clone, PartialEq)]
pub struct NavGrid {
    /// World (x, y) of the lower corner of cell (0, 0).
    pub origin: Vec2,
    /// Cell size, metres.
    pub cell: f32,
    /// Columns (along +x).
    pub width: usize,
    /// Rows (along +y).
    pub height: usize,
    /// Row-major cells: [`FREE`], [`OCCUPIED`] or [`UNKNOWN`].
    pub cells: Vec<u8>,
    /// Room index of each cell's centre ([`NO_ROOM`] outside the rooms).
    pub rooms: Vec<u16>,
}

impl NavGrid {
    /// An all-unknown grid covering `lo`…`hi`.
    pub fn new(lo: Vec2, hi: Vec2, cell: f32) -> Result<NavGrid> {
        let size = hi - lo;
        if !(size.x > 0.0 && size.y > 0.0 && size.is_finite()) {
            return Err(Error::invalid("the area to map is empty"));
        }
        let width = (size.x / cell).ceil() as usize;
        let height = (size.y / cell).ceil() as usize;
        if width.saturating_mul(height) > 200_000_000 {
            return Err(Error::invalid(format!(
                "a {width} x {height} grid is too large (cell {cell} m over {:.0} x {:.0} m)",
                size.x, size.y
            )));
        }
        Ok(NavGrid {
            origin: lo,
            cell,
            width,
            height,
            cells: vec![UNKNOWN; width * height],
            rooms: vec![NO_ROOM; width * height],
        })
    }

    /// The flat index of cell (column, row).
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.width + i
    }

    /// The world (x, y) of a cell's centre.
    pub fn center(&self, i: usize, j: usize) -> Vec2 {
        self.origin + Vec2::new(i as f32 + 0.5, j as f32 + 0.5) * self.cell
    }

    /// The world centre of the cell with flat index `k`.
    pub fn center_of(&self, k: usize) -> Vec2 {
        self.center(k % self.width, k / self.width)
    }

    /// The cell (column, row) holding world point `p`, if inside the grid.
    pub fn cell_at(&self, p: Vec2) -> Option<(usize, usize)> {
        let q = (p - self.origin) / self.cell;
        (q.x >= 0.0 && q.y >= 0.0 && (q.x as usize) < self.width && (q.y as usize) < self.height)
            .then_some((q.x as usize, q.y as usize))
    }

    /// Continuous cell coordinates of `p` (cell (i, j) spans [i, i+1) × [j, j+1)).
    pub fn to_cell_coords(&self, p: Vec2) -> Vec2 {
        (p - self.origin) / self.cell
    }

    /// World size of the grid, metres.
    pub fn size(&self) -> Vec2 {
        Vec2::new(self.width as f32, self.height as f32) * self.cell
    }

    /// The grid in the InteriorGS convention (x mirrored; see `sage_scene::occupancy`), with
    /// `z_range` as the vertical bounds it records.
    pub fn to_occupancy(&self, z_range: (f32, f32)) -> Result<OccupancyMap> {
        let lower = self.origin.extend(z_range.0);
        let upper = (self.origin + self.size()).extend(z_range.1);
        let mut map = OccupancyMap::new(lower, upper, self.cell)?;
        map.width = self.width;
        map.height = self.height;
        map.cells = vec![UNKNOWN; self.width * self.height];
        for j in 0..self.height {
            for i in 0..self.width {
                map.cells[j * self.width + (self.width - 1 - i)] = self.cells[self.index(i, j)];
            }
        }
        Ok(map)
    }

    /// A grid from an InteriorGS occupancy map: 255 free, 0 occupied, anything else unknown.
    pub fn from_occupancy(map: &OccupancyMap) -> Result<NavGrid> {
        if map.width == 0 || map.height == 0 || map.cells.len() != map.width * map.height {
            return Err(Error::format(
                "occupancy.png",
                format!(
                    "{} x {} image with {} cells",
                    map.width,
                    map.height,
                    map.cells.len()
                ),
            ));
        }
        let lo = Vec2::new(map.upper.x - map.scale * map.width as f32, map.lower.y);
        let mut grid = NavGrid {
            origin: lo,
            cell: map.scale,
            width: map.width,
            height: map.height,
            cells: vec![UNKNOWN; map.width * map.height],
            rooms: vec![NO_ROOM; map.width * map.height],
        };
        for j in 0..map.height {
            for c in 0..map.width {
                let v = map.cells[j * map.width + c];
                let k = grid.index(map.width - 1 - c, j);
                grid.cells[k] = match v {
                    FREE => FREE,
                    OCCUPIED => OCCUPIED,
                    _ => UNKNOWN,
                };
            }
        }
        Ok(grid)
    }

    /// Counts of (free, occupied, unknown) cells.
    pub fn counts(&self) -> (usize, usize, usize) {
        let free = self.cells.iter().filter(|&&v| v == FREE).count();
        let occ = self.cells.iter().filter(|&&v| v == OCCUPIED).count();
        (free, occ, self.cells.len() - free - occ)
    }

    /// Gives every cell the room (smallest polygon) holding its centre.
    pub(crate) fn mark_rooms(&mut self, scene: &Scene) {
        for (r, room) in scene.floorplan.rooms.iter().enumerate() {
            let (lo, hi) = room.profile.bounds();
            let Some((i0, j0, i1, j1)) = self.cell_range(lo, hi) else {
                continue;
            };
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = self.index(i, j);
                    if !room.profile.contains(self.center(i, j)) {
                        continue;
                    }
                    let smaller = self.rooms[k] == NO_ROOM
                        || scene.floorplan.rooms[self.rooms[k] as usize].profile.area()
                            > room.profile.area();
                    if smaller {
                        self.rooms[k] = r as u16;
                    }
                }
            }
        }
    }

    /// Inclusive cell range covering the world rectangle `lo`…`hi`, clipped; `None` if outside.
    pub fn cell_range(&self, lo: Vec2, hi: Vec2) -> Option<(usize, usize, usize, usize)> {
        let a = self.to_cell_coords(lo).floor();
        let b = self.to_cell_coords(hi).floor();
        let (w, h) = (self.width as f32, self.height as f32);
        if b.x < 0.0 || b.y < 0.0 || a.x >= w || a.y >= h || !(a.is_finite() && b.is_finite()) {
            return None;
        }
        Some((
            a.x.max(0.0) as usize,
            a.y.max(0.0) as usize,
            b.x.min(w - 1.0) as usize,
            b.y.min(h - 1.0) as usize,
        ))
    }

    /// Blocks every cell whose square overlaps (or touches) the convex polygon `poly`.
    pub fn block_convex(&mut self, poly: &[Vec2]) {
        let mut marks = Vec::new();
        self.convex_cells(poly, &mut marks);
        for k in marks {
            self.cells[k] = OCCUPIED;
        }
    }

    /// Appends the flat indices of the cells whose square overlaps or touches the convex
    /// polygon `poly` (any vertex order; segments and points count).
    pub fn convex_cells(&self, poly: &[Vec2], out: &mut Vec<usize>) {
        if poly.is_empty() {
            return;
        }
        let lo = poly.iter().fold(Vec2::INFINITY, |m, p| m.min(*p));
        let hi = poly.iter().fold(Vec2::NEG_INFINITY, |m, p| m.max(*p));
        let Some((i0, j0, i1, j1)) = self.cell_range(lo - TOUCH, hi + TOUCH) else {
            return;
        };
        let half = self.cell * 0.5;
        let n = poly.len();
        let normals: Vec<Vec2> = (0..n)
            .filter_map(|e| {
                let d = poly[(e + 1) % n] - poly[e];
                (d.length_squared() > 1e-12).then(|| d.perp().normalize())
            })
            .collect();
        for j in j0..=j1 {
            for i in i0..=i1 {
                let c = self.center(i, j);
                let inside_box = lo.x <= c.x + half + TOUCH
                    && hi.x >= c.x - half - TOUCH
                    && lo.y <= c.y + half + TOUCH
                    && hi.y >= c.y - half - TOUCH;
                if inside_box && !separated(poly, &normals, c, half) {
                    out.push(self.index(i, j));
                }
            }
        }
    }
}

/// Tolerance of "touching" (m): a face exactly on a cell border blocks both cells.
const TOUCH: f32 = 1e-5;

/// True when a polygon edge normal separates the square at `c` of half-size `half` from `poly`.
fn separated(poly: &[Vec2], normals: &[Vec2], c: Vec2, half: f32) -> bool {
    normals.iter().any(|n| {
        let r = half * (n.x.abs() + n.y.abs());
        let mid = c.dot(*n);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for p in poly {
            let d = p.dot(*n);
            lo = lo.min(d);
            hi = hi.max(d);
        }
        lo > mid + r + TOUCH || hi < mid - r - TOUCH
    })
}

/// Clips a triangle to the slab `z0 ≤ z ≤ z1`; returns the clipped polygon's floor projection
/// (empty when the triangle misses the slab).
pub fn clip_to_slab(tri: [Vec3; 3], z0: f32, z1: f32) -> Vec<Vec2> {
    let mut poly: Vec<Vec3> = tri.to_vec();
    for (level, keep_above) in [(z0, true), (z1, false)] {
        let inside = |p: &Vec3| {
            if keep_above {
                p.z >= level
            } else {
                p.z <= level
            }
        };
        let mut out = Vec::with_capacity(poly.len() + 2);
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                let t = (level - a.z) / (b.z - a.z);
                out.push(a + (b - a) * t);
            }
        }
        poly = out;
        if poly.is_empty() {
            break;
        }
    }
    poly.iter().map(|p| p.truncate()).collect()
}

/// The grid of a scene's geometry (see the module docs).
pub(crate) fn rasterize(scene: &Scene, params: &GridParams) -> Result<NavGrid> {
    let fp = &scene.floorplan;
    if fp.rooms.is_empty() {
        return Err(Error::invalid(format!(
            "scene {}: structure.json has no rooms, so free space is undefined (and the scene has no occupancy map to fall back on)",
            scene.name
        )));
    }
    let parts: Vec<ExtentPart> = room_parts(scene).chain(wall_parts(scene)).collect();
    let (lo, hi) = extent(&parts);
    let margin = Vec2::splat(params.margin);
    let mut grid = NavGrid::new(lo - margin, hi + margin, params.cell).map_err(|e| {
        Error::invalid(format!(
            "scene {}: {}{}",
            scene.name,
            e.message(),
            farthest(&parts)
        ))
    })?;
    grid.mark_rooms(scene);
    for k in 0..grid.cells.len() {
        if grid.rooms[k] != NO_ROOM {
            grid.cells[k] = FREE;
        }
    }
    block_geometry(&mut grid, scene, (params.slab_bottom, params.agent_height));
    Ok(grid)
}

/// A part of a scene that a grid covers, named by the file and entry it comes from, with its
/// floor-plane bounds: what an error about the grid's extent names.
pub(crate) struct ExtentPart {
    /// `structure.json rooms[2]`, `labels.json object 1003`, …
    pub(crate) name: String,
    /// Lower corner, metres.
    pub(crate) lo: Vec2,
    /// Upper corner, metres.
    pub(crate) hi: Vec2,
}

/// The rooms of `scene`, as parts of its extent.
fn room_parts(scene: &Scene) -> impl Iterator<Item = ExtentPart> + '_ {
    scene.floorplan.rooms.iter().enumerate().map(|(i, r)| {
        let (lo, hi) = r.profile.bounds();
        ExtentPart {
            name: format!("structure.json rooms[{i}]"),
            lo,
            hi,
        }
    })
}

/// The walls of `scene`, as parts of its extent.
fn wall_parts(scene: &Scene) -> impl Iterator<Item = ExtentPart> + '_ {
    scene.floorplan.walls.iter().enumerate().map(|(i, w)| {
        let b = w.obb().aabb();
        ExtentPart {
            name: format!("structure.json walls[{i}]"),
            lo: b.min.truncate(),
            hi: b.max.truncate(),
        }
    })
}

/// The walls, objects and structure mesh of `scene`, as parts of its extent.
pub(crate) fn geometry_parts(scene: &Scene) -> Vec<ExtentPart> {
    let mut parts: Vec<ExtentPart> = wall_parts(scene).collect();
    parts.extend(scene.objects.iter().map(|o| {
        let b = o.obb.aabb();
        ExtentPart {
            name: format!("labels.json object {}", o.ins_id),
            lo: b.min.truncate(),
            hi: b.max.truncate(),
        }
    }));
    if let Some(m) = &scene.structure_mesh {
        let b = m.aabb();
        parts.push(ExtentPart {
            name: "meshes/structure.obj".to_string(),
            lo: b.min.truncate(),
            hi: b.max.truncate(),
        });
    }
    parts
}

/// `; it reaches farthest at NAME, which spans …` for the part of `parts` farthest from the
/// median of their centres (the one that stretches the extent when one part is broken), or
/// nothing without parts.
pub(crate) fn farthest(parts: &[ExtentPart]) -> String {
    let centres: Vec<Vec2> = parts.iter().map(|p| (p.lo + p.hi) * 0.5).collect();
    let median = |axis: fn(&Vec2) -> f32| {
        let mut v: Vec<f32> = centres.iter().map(axis).collect();
        v.sort_by(f32::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let m = Vec2::new(median(|c| c.x), median(|c| c.y));
    // How far a part reaches from the median: its farthest corner.
    let reach = |p: &ExtentPart| (p.lo - m).abs().max((p.hi - m).abs()).max_element();
    parts
        .iter()
        .max_by(|a, b| reach(a).total_cmp(&reach(b)))
        .map_or_else(String::new, |p| {
            format!(
                "; it reaches farthest at {}, which spans x {} to {} and y {} to {} m",
                p.name, p.lo.x, p.hi.x, p.lo.y, p.hi.y
            )
        })
}

/// The floor-plane bounds (lower, upper corner) of the walls, objects and structure mesh of
/// `scene`.
pub(crate) fn geometry_bounds(scene: &Scene) -> (Vec2, Vec2) {
    extent(&geometry_parts(scene))
}

/// The floor-plane bounds (lower, upper corner) that `parts` span together.
fn extent(parts: &[ExtentPart]) -> (Vec2, Vec2) {
    parts
        .iter()
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.lo), hi.max(p.hi))
        })
}

/// Blocks the cells of every wall, the structure mesh and every object body that reach into
/// the slab (see the module docs).
pub(crate) fn block_geometry(grid: &mut NavGrid, scene: &Scene, slab: (f32, f32)) {
    for w in &scene.floorplan.walls {
        for rect in wall_blocks(w, scene, slab) {
            grid.block_convex(&rect);
        }
    }
    if let Some(m) = &scene.structure_mesh {
        block_mesh_surface(grid, m, slab);
    }
    if let Some(s) = &scene.structure_body {
        for part in &s.parts {
            block_solid(grid, part, slab);
        }
    }
    for o in &scene.objects {
        match (&o.body, &o.mesh) {
            (Some(given), _) if !given.parts.is_empty() => {
                for part in &given.parts {
                    block_solid(grid, part, slab);
                }
            }
            (_, Some(m)) => block_solid(grid, m, slab),
            _ => {
                let open_door =
                    o.category.contains("door") && o.door_state() == Some(DoorState::Open);
                if !open_door && o.obb.min_z() < slab.1 && o.obb.max_z() > slab.0 {
                    grid.block_convex(&o.obb.footprint());
                }
            }
        }
    }
}

/// The floor rectangles of the stretches of wall `w` that reach into the slab: the whole wall
/// minus the holes through it that leave the slab open (doors, unless closed).
fn wall_blocks(w: &Wall, scene: &Scene, slab: (f32, f32)) -> Vec<[Vec2; 4]> {
    let len = w.length();
    if len <= 0.0 || w.height <= slab.0 {
        return Vec::new();
    }
    let dir = w.direction();
    let normal = dir.perp();
    let mut gaps: Vec<(f32, f32)> = scene
        .floorplan
        .holes
        .iter()
        .filter(|h| !(h.kind == HoleKind::Door && h.state == Some(DoorState::Closed)))
        .filter_map(|h| {
            let (lo, hi) = h.bounds();
            let opens_slab = lo.z <= slab.0 && hi.z >= slab.1.min(w.height);
            let centre = ((lo + hi) * 0.5).truncate();
            let off = (centre - w.start).dot(normal).abs();
            if !opens_slab || off > w.thickness * 0.5 + 0.05 {
                return None;
            }
            let s: Vec<f32> = h
                .profile
                .iter()
                .map(|p| (p.truncate() - w.start).dot(dir))
                .collect();
            let a = s.iter().copied().fold(f32::INFINITY, f32::min).max(0.0);
            let b = s.iter().copied().fold(f32::NEG_INFINITY, f32::max).min(len);
            (b > a).then_some((a, b))
        })
        .collect();
    gaps.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = normal * (w.thickness * 0.5);
    let rect = |a: f32, b: f32| {
        let (p, q) = (w.start + dir * a, w.start + dir * b);
        [p - half, q - half, q + half, p + half]
    };
    let mut out = Vec::new();
    let mut at = 0.0;
    for (a, b) in gaps {
        if a > at {
            out.push(rect(at, a));
        }
        at = at.max(b);
    }
    if at < len {
        out.push(rect(at, len));
    }
    out
}

/// Blocks the cells touched by the slab part of every triangle of `m`.
fn block_mesh_surface(grid: &mut NavGrid, m: &TriMesh, slab: (f32, f32)) {
    for t in 0..m.triangles.len() {
        let poly = clip_to_slab(m.triangle(t), slab.0, slab.1);
        grid.block_convex(&poly);
    }
}

/// Blocks the cells touched by the slab part of a closed mesh and the cells its outline encloses
/// (found by flooding the outside of the mesh's cell window).
fn block_solid(grid: &mut NavGrid, m: &TriMesh, slab: (f32, f32)) {
    let mut marks = Vec::new();
    for t in 0..m.triangles.len() {
        grid.convex_cells(&clip_to_slab(m.triangle(t), slab.0, slab.1), &mut marks);
    }
    if marks.is_empty() {
        return;
    }
    let (mut i0, mut j0, mut i1, mut j1) = (usize::MAX, usize::MAX, 0, 0);
    for &k in &marks {
        let (i, j) = (k % grid.width, k / grid.width);
        (i0, j0, i1, j1) = (i0.min(i), j0.min(j), i1.max(i), j1.max(j));
    }
    // A local window one cell larger on every side, so the outside is connected.
    let (w, h) = (i1 - i0 + 3, j1 - j0 + 3);
    let mut local = vec![0u8; w * h];
    for &k in &marks {
        let (i, j) = (k % grid.width, k / grid.width);
        local[(j - j0 + 1) * w + (i - i0 + 1)] = 1;
    }
    local[0] = 2;
    flood4(
        w,
        h,
        &mut vec![0usize],
        |n| {
            let outside = local[n] == 0;
            if outside {
                local[n] = 2;
            }
            outside
        },
        |_| {},
    );
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            if local[y * w + x] != 2 {
                let k = grid.index(i0 + x - 1, j0 + y - 1);
                grid.cells[k] = OCCUPIED;
            }
        }
    }
}

/// Floods a 4-connected region of a `width`-column row-major raster of `height` rows from the
/// cells on `stack` (each already taken), calling `reached(k)` on each cell of the region and
/// `take(n)` on each neighbour of one: `true` takes the neighbour in, and `take` marks it so
/// that it is not taken twice.
pub(crate) fn flood4(
    width: usize,
    height: usize,
    stack: &mut Vec<usize>,
    mut take: impl FnMut(usize) -> bool,
    mut reached: impl FnMut(usize),
) {
    while let Some(k) = stack.pop() {
        reached(k);
        let (x, y) = (k % width, k / width);
        let neighbours = [
            (x > 0).then(|| k - 1),
            (x + 1 < width).then(|| k + 1),
            (y > 0).then(|| k - width),
            (y + 1 < height).then(|| k + width),
        ];
        for n in neighbours.into_iter().flatten() {
            if take(n) {
                stack.push(n);
            }
        }
    }
}
