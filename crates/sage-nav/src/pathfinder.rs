//! A Habitat-like path finder over a scene's navigable grid: `find_path`, `geodesic_distance`
//! (to a point or to a polygon goal region), `is_navigable`, `snap_point`,
//! `sample_navigable_point` and connected islands; [`GeodesicField`] answers many goals from one
//! Dijkstra search.
//!
//! Geodesic distances are path lengths in metres: the length-optimal grid path (penalty off)
//! shortened by line of sight, which removes most of the 8-connected grid's detour. Islands are
//! the 4-connected components of the navigable cells; with no corner cutting, two cells are
//! mutually reachable exactly when they share an island.

use crate::GridSource;
use crate::astar::{DistanceField, Graph, Search};
use crate::cost::{self, CostParams};
use crate::grid::{GridParams, NavGrid};
use crate::path;
use glam::Vec2;
use rand::Rng;
use sage_core::{Error, Polygon2, Result};
use sage_scene::{Floorplan, Scene};
use std::cell::RefCell;

/// Island label of a cell that is not navigable.
const NO_ISLAND: u32 = u32::MAX;

thread_local! {
    /// One reusable search per thread: queries allocate no grid-sized arrays.
    static SEARCH: RefCell<Search> = RefCell::new(Search::new());
}

/// A planned path.
#[derive(Debug, Clone, PartialEq)]
pub struct NavPath {
    /// The optimal grid path, flat cell indices from start to goal.
    pub cells: Vec<usize>,
    /// World points after line-of-sight shortcutting, first = start, last = goal.
    pub waypoints: Vec<Vec2>,
    /// The optimal cost (metres × cost multipliers).
    pub cost: f32,
}

impl NavPath {
    /// Length of the shortcut path, metres.
    pub fn length(&self) -> f32 {
        path::polyline_length(&self.waypoints)
    }
}

/// The navigable grid of a scene with its clearance, costs and islands.
#[derive(Debug, Clone)]
pub struct PathFinder {
    /// The occupancy grid.
    pub grid: NavGrid,
    /// Clearance per cell, metres.
    pub clearance: Vec<f32>,
    /// Navigable cells (free with clearance ≥ robot radius + safety margin).
    pub passable: Vec<bool>,
    /// Cells a shortcut segment may cross (see [`CostParams::roomy_clearance`]).
    pub roomy: Vec<bool>,
    /// Cost multiplier per cell.
    pub weights: Vec<f32>,
    /// The cost parameters in force.
    pub params: CostParams,
    min_weight: f32,
    islands: Vec<u32>,
    island_sizes: Vec<usize>,
    navigable_cells: Vec<u32>,
}

impl PathFinder {
    /// Builds the grid of `scene` and the path finder over it.
    pub fn from_scene(
        scene: &Scene,
        grid: &GridParams,
        params: CostParams,
    ) -> Result<(PathFinder, GridSource)> {
        let (g, source) = NavGrid::from_scene(scene, grid)?;
        let pf = PathFinder::new(g, &scene.floorplan, params)
            .map_err(|e| Error::invalid(format!("scene {}: {}", scene.name, e.message())))?;
        Ok((pf, source))
    }

    /// Clearance, costs and islands of `grid`.
    ///
    /// # Errors
    ///
    /// An `invalid` error when the parameters are out of range or no cell is navigable.
    pub fn new(grid: NavGrid, floorplan: &Floorplan, params: CostParams) -> Result<PathFinder> {
        params.validate()?;
        let clearance = cost::clearance(&grid);
        let passable = cost::navigable(&grid, &clearance, params.navigable_clearance());
        let roomy = cost::navigable(&grid, &clearance, params.roomy_clearance());
        let navigable_cells: Vec<u32> = (0..passable.len() as u32)
            .filter(|&k| passable[k as usize])
            .collect();
        if navigable_cells.is_empty() {
            let (free, _, _) = grid.counts();
            return Err(Error::invalid(format!(
                "no navigable space: {free} free cells, none with clearance >= the robot radius {} m + the safety margin {} m",
                params.robot_radius, params.safety_margin
            )));
        }
        let weights = cost::multipliers(&grid, &clearance, floorplan, &params);
        let min_weight = navigable_cells
            .iter()
            .map(|&k| weights[k as usize])
            .fold(f32::INFINITY, f32::min);
        let (islands, island_sizes) = label_islands(grid.width, &passable);
        Ok(PathFinder {
            grid,
            clearance,
            passable,
            roomy,
            weights,
            params,
            min_weight,
            islands,
            island_sizes,
            navigable_cells,
        })
    }

    /// The weighted planning graph.
    pub fn graph(&self) -> Graph<'_> {
        Graph {
            width: self.grid.width,
            passable: &self.passable,
            weight: Some(&self.weights),
            min_weight: self.min_weight,
        }
    }

    /// The graph whose costs are lengths.
    pub fn length_graph(&self) -> Graph<'_> {
        Graph {
            width: self.grid.width,
            passable: &self.passable,
            weight: None,
            min_weight: 1.0,
        }
    }

    /// The navigable cell holding `p`, if any.
    pub fn cell_of(&self, p: Vec2) -> Option<usize> {
        let (i, j) = self.grid.cell_at(p)?;
        let k = self.grid.index(i, j);
        self.passable[k].then_some(k)
    }

    /// True when `p` lies in a navigable cell.
    pub fn is_navigable(&self, p: Vec2) -> bool {
        self.cell_of(p).is_some()
    }

    /// The centre of the navigable cell nearest to `p` within `max_distance` metres.
    pub fn snap_point(&self, p: Vec2, max_distance: f32) -> Option<Vec2> {
        self.snap_cell(p, max_distance)
            .map(|k| self.grid.center_of(k))
    }

    /// The navigable cell nearest to `p` within `max_distance` metres (any distance when it is
    /// infinite; none when it is negative or NaN).
    pub fn snap_cell(&self, p: Vec2, max_distance: f32) -> Option<usize> {
        if max_distance.is_nan() || max_distance < 0.0 {
            return None;
        }
        if let Some(k) = self.cell_of(p) {
            return Some(k);
        }
        // The window clamped to the grid, so an infinite bound searches all of it.
        let (lo, hi) = (self.grid.origin, self.grid.origin + self.grid.size());
        let r = Vec2::splat(max_distance);
        let (i0, j0, i1, j1) = self
            .grid
            .cell_range((p - r).clamp(lo, hi), (p + r).clamp(lo, hi))?;
        let mut best: Option<(usize, f32)> = None;
        for j in j0..=j1 {
            for i in i0..=i1 {
                let k = self.grid.index(i, j);
                if !self.passable[k] {
                    continue;
                }
                let d = self.grid.center(i, j).distance(p);
                if d <= max_distance && best.is_none_or(|(_, b)| d < b) {
                    best = Some((k, d));
                }
            }
        }
        best.map(|(k, _)| k)
    }

    /// A navigable cell centre drawn uniformly, optionally from one island only.
    pub fn sample_navigable_point(&self, rng: &mut impl Rng, island: Option<u32>) -> Option<Vec2> {
        let k = match island {
            None => self.navigable_cells[rng.random_range(0..self.navigable_cells.len())],
            Some(id) => {
                let size = *self.island_sizes.get(id as usize)?;
                let nth = rng.random_range(0..size);
                *self
                    .navigable_cells
                    .iter()
                    .filter(|&&k| self.islands[k as usize] == id)
                    .nth(nth)?
            }
        };
        Some(self.grid.center_of(k as usize))
    }

    /// The island of the navigable cell at `p`.
    pub fn island(&self, p: Vec2) -> Option<u32> {
        self.cell_of(p).map(|k| self.islands[k])
    }

    /// The island of navigable cell `k`.
    pub fn island_of_cell(&self, k: usize) -> u32 {
        self.islands[k]
    }

    /// The area of each island, m², indexed by island id (largest first is not implied).
    pub fn island_areas(&self) -> Vec<f32> {
        let a = self.grid.cell * self.grid.cell;
        self.island_sizes.iter().map(|&n| n as f32 * a).collect()
    }

    /// The navigable cells, in index order.
    pub fn navigable_cells(&self) -> &[u32] {
        &self.navigable_cells
    }

    fn endpoint(&self, p: Vec2, what: &str) -> Result<usize> {
        self.cell_of(p).ok_or_else(|| {
            let why = match self.grid.cell_at(p) {
                None => "outside the map",
                Some(_) => "not navigable (blocked or too close to an obstacle)",
            };
            Error::invalid(format!("{what} ({:.2}, {:.2}) is {why}", p.x, p.y))
        })
    }

    /// The cheapest path from `start` to `goal` under the cost function, shortcut.
    ///
    /// # Errors
    ///
    /// An `invalid` error when an endpoint is not navigable or the goal is on another island
    /// (detected before any search).
    pub fn find_path(&self, start: Vec2, goal: Vec2) -> Result<NavPath> {
        let (s, g) = (self.endpoint(start, "start")?, self.endpoint(goal, "goal")?);
        SEARCH.with_borrow_mut(|search| self.plan_cells(search, s, g))
            .map(|mut p| {
                let n = p.waypoints.len();
                p.waypoints[0] = start;
                p.waypoints[n - 1] = goal;
                p
            })
            .ok_or_else(|| {
                Error::invalid(format!(
                    "goal ({:.2}, {:.2}) is unreachable from start ({:.2}, {:.2}): different islands",
                    goal.x, goal.y, start.x, start.y
                ))
            })
    }

    /// Plans between two navigable cells with the given search state; `None` when they are on
    /// different islands.
    pub fn plan_cells(&self, search: &mut Search, start: usize, goal: usize) -> Option<NavPath> {
        if self.islands[start] != self.islands[goal] {
            return None;
        }
        let cost = search.astar(&self.graph(), start, goal)?;
        let mut cells = Vec::new();
        search.path_to(goal, &mut cells);
        let waypoints = self.waypoints(&cells);
        Some(NavPath {
            cells,
            waypoints,
            cost: cost * self.grid.cell,
        })
    }

    /// World points of the line-of-sight shortcut of a grid path: the shortest polyline in
    /// the grid path's corridor (what geodesic distances measure).
    pub fn shortcut_points(&self, cells: &[usize]) -> Vec<Vec2> {
        self.points(path::shortcut(self.grid.width, &self.passable, cells))
    }

    /// World points of a grid path for an agent to follow: shortcut segments only across
    /// cells with the shortcut margin of clearance to spare, the grid path cell by cell
    /// elsewhere (see [`CostParams::shortcut_margin`]).
    pub fn waypoints(&self, cells: &[usize]) -> Vec<Vec2> {
        self.points(path::shortcut(self.grid.width, &self.roomy, cells))
    }

    fn points(&self, cells: Vec<usize>) -> Vec<Vec2> {
        cells.into_iter().map(|k| self.grid.center_of(k)).collect()
    }

    /// The geodesic distance between two navigable cells (see the module docs), or `None`.
    pub fn geodesic_cells(&self, search: &mut Search, start: usize, goal: usize) -> Option<f32> {
        if self.islands[start] != self.islands[goal] {
            return None;
        }
        search.astar(&self.length_graph(), start, goal)?;
        let mut cells = Vec::new();
        search.path_to(goal, &mut cells);
        Some(path::polyline_length(&self.shortcut_points(&cells)))
    }

    /// The geodesic distance between two points, or `None` when either is not navigable or they
    /// are not connected.
    pub fn geodesic_distance(&self, a: Vec2, b: Vec2) -> Option<f32> {
        let (s, g) = (self.cell_of(a)?, self.cell_of(b)?);
        SEARCH.with_borrow_mut(|search| self.geodesic_cells(search, s, g))
    }

    /// The distance from `a` to a polygon goal region (SPEC §10): the geodesic distance to the
    /// navigable cell within `within` metres of the polygon that minimises it plus that cell's
    /// Euclidean distance to the polygon (0 inside). `None` when no such cell is reachable.
    pub fn geodesic_distance_to_region(
        &self,
        a: Vec2,
        region: &Polygon2,
        within: f32,
    ) -> Option<f32> {
        let s = self.cell_of(a)?;
        let gap = |k: usize| {
            let c = self.grid.center_of(k);
            if region.contains(c) {
                0.0
            } else {
                region.distance_to_boundary(c)
            }
        };
        let cell = self.grid.cell;
        SEARCH.with_borrow_mut(|search| {
            let (k, _) = search.nearest_goal(&self.length_graph(), s, |k| {
                let d = gap(k);
                (d <= within).then_some(d / cell)
            })?;
            let mut cells = Vec::new();
            search.path_to(k, &mut cells);
            Some(path::polyline_length(&self.shortcut_points(&cells)) + gap(k))
        })
    }

    /// One Dijkstra search from `start` under the length cost: then any number of goals.
    pub fn geodesic_field(&self, start: Vec2) -> Result<GeodesicField<'_>> {
        let s = self.endpoint(start, "start")?;
        Ok(GeodesicField {
            finder: self,
            field: DistanceField::build(&self.length_graph(), &[s]),
        })
    }
}

/// Geodesic distances from one start to every cell (see [`PathFinder::geodesic_field`]).
#[derive(Debug, Clone)]
pub struct GeodesicField<'a> {
    finder: &'a PathFinder,
    /// The underlying Dijkstra field (cell units).
    pub field: DistanceField,
}

impl GeodesicField<'_> {
    /// The geodesic distance from the start to `p` (shortcut path length), or `None`.
    pub fn distance_to(&self, p: Vec2) -> Option<f32> {
        let k = self.finder.cell_of(p)?;
        let mut cells = self.field.path_from(k);
        if cells.is_empty() {
            return None;
        }
        cells.reverse();
        Some(path::polyline_length(&self.finder.shortcut_points(&cells)))
    }

    /// The grid (unshortcut) path cost from the start to `p`, metres.
    pub fn grid_distance_to(&self, p: Vec2) -> Option<f32> {
        let k = self.finder.cell_of(p)?;
        let c = self.field.cost[k];
        c.is_finite().then_some(c * self.finder.grid.cell)
    }
}

/// 4-connected component labels of the passable cells and the size of each component.
fn label_islands(width: usize, passable: &[bool]) -> (Vec<u32>, Vec<usize>) {
    let mut label = vec![NO_ISLAND; passable.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..passable.len() {
        if !passable[seed] || label[seed] != NO_ISLAND {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        label[seed] = id;
        stack.push(seed);
        while let Some(k) = stack.pop() {
            size += 1;
            // The border is never passable, so the four neighbours exist.
            for m in [k + 1, k - 1, k + width, k - width] {
                if passable[m] && label[m] == NO_ISLAND {
                    label[m] = id;
                    stack.push(m);
                }
            }
        }
        sizes.push(size);
    }
    (label, sizes)
}
