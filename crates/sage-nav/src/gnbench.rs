//! GN-Bench's distance to goal (metric mode `gnbench`; research notes gn_bench.md §A1, §A2):
//! its definition, re-implemented from the description of its simulator, not a sage3d geodesic.
//!
//! GN-Bench measures on the scene's `occupancy.png` alone: a pixel is passable where its value
//! is at least 200, and four copies of that grid are inflated by discs of 7, 6, 5 and 4 pixels
//! (a pixel is blocked when a blocked pixel lies within that radius, centre to centre). The
//! distance from a position to the goal is then:
//!
//! 1. both mapped to pixels (`col = round((upper.x − x)/sx − ½)`, `row = round((y − lower.y)/sy
//!    − ½)`, rounding half to even as Python does, clamped to the image; sx, sy the image's
//!    extent over its size);
//! 2. a start pixel not passable on the least inflated grid is replaced by the pixel of the last
//!    passable position of the episode, else by the nearest passable pixel (ring search); the
//!    goal pixel by the nearest passable pixel;
//! 3. 0 when both are the same pixel; otherwise an 8-connected A* without corner cutting, tried
//!    on the grid inflated by 7 px, then 6, 5, 4 until one finds a path (none: ∞);
//! 4. the path is smoothed greedily by line of sight (Bresenham, on the 7 px grid), the kept
//!    keypoints joined again by Bresenham lines, and the length of that pixel chain summed in
//!    metres.
//!
//! The A* is GN-Bench's: Euclidean heuristic, unit and √2 step costs, a node's score improved
//! only when strictly lower, the open list ordered by (f, column, row), which decides between
//! equally short paths and so what the smoothing sees.

use crate::edt;
use sage_scene::occupancy::OccupancyMap;
use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, HashMap};

/// The inflation radii GN-Bench tries, in pixels, most inflated first.
pub const MARGINS: [usize; 4] = [7, 6, 5, 4];
/// The lowest occupancy value GN-Bench counts as passable.
pub const PASSABLE_MIN: u8 = 200;

/// A pixel `(column, row)` of the occupancy image.
pub type Pixel = (usize, usize);

/// Where the image lies in the world W: `upper.x` and `lower.y` of `occupancy.json` and the
/// pixel size per axis (the image's extent over its width and height).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnFrame {
    /// World x of the image's left edge (column 0 is at max-x).
    pub upper_x: f64,
    /// World y of the image's first row.
    pub lower_y: f64,
    /// Metres per column.
    pub sx: f64,
    /// Metres per row.
    pub sy: f64,
}

/// The occupancy image as GN-Bench plans on it: the passable grid inflated by each margin,
/// built once per scene.
#[derive(Debug, Clone)]
pub struct GnBenchGrid {
    width: usize,
    height: usize,
    frame: GnFrame,
    margins: Vec<usize>,
    /// One passable mask per margin, in the order of `margins`.
    inflated: Vec<Vec<bool>>,
}

/// The key of GN-Bench's open list: (f, column, row), smallest first.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OpenKey(f64, usize, usize);

impl Eq for OpenKey {}

impl PartialOrd for OpenKey {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OpenKey {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0
            .total_cmp(&other.0)
            .then(self.1.cmp(&other.1))
            .then(self.2.cmp(&other.2))
    }
}

/// GN-Bench's neighbour order: the four axis steps, then the four diagonals.
const NEIGHBOURS: [(isize, isize); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// The pixels of the Bresenham line from `a` to `b`, both included, as GN-Bench walks it.
pub fn bresenham(a: Pixel, b: Pixel) -> Vec<Pixel> {
    let (x0, y0) = (a.0 as isize, a.1 as isize);
    let (x1, y1) = (b.0 as isize, b.1 as isize);
    let (dx, dy) = ((x1 - x0).abs(), (y1 - y0).abs());
    let sx = if x1 >= x0 { 1 } else { -1 };
    let sy = if y1 >= y0 { 1 } else { -1 };
    let (mut x, mut y) = (x0, y0);
    let mut out = vec![a];
    if dx >= dy {
        let mut err = dx / 2;
        while x != x1 {
            x += sx;
            err -= dy;
            if err < 0 {
                y += sy;
                err += dx;
            }
            out.push((x as usize, y as usize));
        }
    } else {
        let mut err = dy / 2;
        while y != y1 {
            y += sy;
            err -= dx;
            if err < 0 {
                x += sx;
                err += dy;
            }
            out.push((x as usize, y as usize));
        }
    }
    out
}

impl GnBenchGrid {
    /// The grids of a scene's occupancy map with GN-Bench's margins.
    pub fn from_occupancy(occ: &OccupancyMap) -> GnBenchGrid {
        let [_, x0, y0] = occ.exact_placement;
        let frame = GnFrame {
            upper_x: f64::from(occ.upper.x),
            lower_y: y0,
            sx: (f64::from(occ.upper.x) - x0) / occ.width.max(1) as f64,
            sy: (f64::from(occ.upper.y) - y0) / occ.height.max(1) as f64,
        };
        GnBenchGrid::new(occ.width, occ.height, &occ.cells, frame, &MARGINS)
    }

    /// The grids of a `width × height` image (`cells` row-major, row 0 at min-y) inflated by
    /// each of `margins` (pixels, tried in this order; the last is the passability test).
    ///
    /// # Panics
    ///
    /// When `cells` does not hold `width × height` values or `margins` is empty (a caller's
    /// bug, not bad input: [`GnBenchGrid::from_occupancy`] is what reads files).
    pub fn new(
        width: usize,
        height: usize,
        cells: &[u8],
        frame: GnFrame,
        margins: &[usize],
    ) -> GnBenchGrid {
        assert_eq!(cells.len(), width * height, "image size");
        assert!(!margins.is_empty(), "at least one margin");
        let blocked: Vec<bool> = cells.iter().map(|&v| v < PASSABLE_MIN).collect();
        // A pixel is blocked at margin m when its nearest blocked pixel is within m pixels
        // (GN-Bench stamps a disc dx² + dy² ≤ m² around every blocked pixel; the exact squared
        // distance transform gives the same mask at once for every margin).
        let d2 = edt::squared_distance(width, height, &blocked);
        let inflated = margins
            .iter()
            .map(|&m| {
                let r2 = (m * m) as f32;
                d2.iter().map(|&d| d > r2).collect()
            })
            .collect();
        GnBenchGrid {
            width,
            height,
            frame,
            margins: margins.to_vec(),
            inflated,
        }
    }

    /// Image width and height, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixel of world point `p` (clamped to the image), as GN-Bench maps it.
    pub fn pixel(&self, p: [f64; 2]) -> Pixel {
        let f = &self.frame;
        let clamp = |v: f64, n: usize| {
            let v = v.round_ties_even();
            if v.is_nan() || v < 0.0 {
                0
            } else {
                (v as usize).min(n.saturating_sub(1))
            }
        };
        (
            clamp((f.upper_x - p[0]) / f.sx - 0.5, self.width),
            clamp((p[1] - f.lower_y) / f.sy - 0.5, self.height),
        )
    }

    /// True when `px` is passable on the grid inflated by margin index `k`.
    fn open(&self, k: usize, px: Pixel) -> bool {
        px.0 < self.width && px.1 < self.height && self.inflated[k][px.1 * self.width + px.0]
    }

    /// GN-Bench's passability test: inside the image and free on the least inflated grid.
    pub fn is_passable(&self, px: Pixel) -> bool {
        self.open(self.margins.len() - 1, px)
    }

    /// The nearest passable pixel by GN-Bench's ring search around `px` (clamped first):
    /// rings of growing Chebyshev radius, each scanned along its top and bottom rows column by
    /// column, then its sides row by row; `None` when nothing is passable.
    pub fn nearest_passable(&self, px: Pixel) -> Option<Pixel> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return None;
        }
        let (x0, y0) = (px.0.min(w - 1), px.1.min(h - 1));
        if self.is_passable((x0, y0)) {
            return Some((x0, y0));
        }
        for r in 1..=w.max(h) {
            let (left, right) = (x0.saturating_sub(r), (x0 + r).min(w - 1));
            let (top, bottom) = (y0.saturating_sub(r), (y0 + r).min(h - 1));
            for x in left..=right {
                for p in [(x, top), (x, bottom)] {
                    if self.is_passable(p) {
                        return Some(p);
                    }
                }
            }
            for y in top + 1..bottom {
                for p in [(left, y), (right, y)] {
                    if self.is_passable(p) {
                        return Some(p);
                    }
                }
            }
        }
        None
    }

    /// GN-Bench's A* from `start` to `goal` on the grid of margin index `k`: the pixel path,
    /// or `None` when the goal cannot be reached.
    pub fn astar(&self, k: usize, start: Pixel, goal: Pixel) -> Option<Vec<Pixel>> {
        let w = self.width;
        let idx = |p: Pixel| p.1 * w + p.0;
        let h = |p: Pixel| {
            let dx = p.0 as f64 - goal.0 as f64;
            let dy = p.1 as f64 - goal.1 as f64;
            (dx * dx + dy * dy).sqrt()
        };
        let mut g = vec![f64::INFINITY; w * self.height];
        let mut from = vec![usize::MAX; w * self.height];
        let mut open = BinaryHeap::new();
        g[idx(start)] = 0.0;
        open.push(Reverse(OpenKey(h(start), start.0, start.1)));
        // No closed set: like GN-Bench, a node popped again is expanded again with its best
        // score (which changes nothing), so the order of expansions is its order.
        while let Some(Reverse(OpenKey(_, cx, cy))) = open.pop() {
            let current = (cx, cy);
            if current == goal {
                let mut path = vec![current];
                let mut at = idx(current);
                while from[at] != usize::MAX {
                    at = from[at];
                    path.push((at % w, at / w));
                }
                path.reverse();
                return Some(path);
            }
            let gc = g[idx(current)];
            for (dx, dy) in NEIGHBOURS {
                let (nx, ny) = (cx as isize + dx, cy as isize + dy);
                if nx < 0 || ny < 0 {
                    continue;
                }
                let next = (nx as usize, ny as usize);
                if !self.open(k, next) {
                    continue;
                }
                // No corner cutting: a diagonal step needs both side pixels free.
                if dx != 0 && dy != 0 && !(self.open(k, (next.0, cy)) && self.open(k, (cx, next.1)))
                {
                    continue;
                }
                let step = if dx != 0 && dy != 0 {
                    std::f64::consts::SQRT_2
                } else {
                    1.0
                };
                let tentative = gc + step;
                if tentative >= g[idx(next)] {
                    continue;
                }
                from[idx(next)] = idx(current);
                g[idx(next)] = tentative;
                open.push(Reverse(OpenKey(tentative + h(next), next.0, next.1)));
            }
        }
        None
    }

    /// The A* path on the most inflated grid that has one (GN-Bench's margin fallback).
    pub fn path(&self, start: Pixel, goal: Pixel) -> Option<Vec<Pixel>> {
        (0..self.margins.len()).find_map(|k| self.astar(k, start, goal))
    }

    /// True when every pixel of the Bresenham line from `a` to `b` is free on the most
    /// inflated grid (GN-Bench's line-of-sight test).
    pub fn line_of_sight(&self, a: Pixel, b: Pixel) -> bool {
        bresenham(a, b).into_iter().all(|p| self.open(0, p))
    }

    /// GN-Bench's greedy smoothing: from each kept point, the farthest later point of the path
    /// in line of sight (the next one when none is).
    pub fn smooth(&self, path: &[Pixel]) -> Vec<Pixel> {
        if path.len() <= 2 {
            return path.to_vec();
        }
        let last = path.len() - 1;
        let mut out = vec![path[0]];
        let mut i = 0;
        while i < last {
            let next = (i + 1..=last)
                .rev()
                .find(|&j| self.line_of_sight(path[i], path[j]))
                .unwrap_or(i + 1);
            out.push(path[next]);
            i = next;
        }
        out
    }

    /// The length in metres of a keypoint path joined by Bresenham lines, as GN-Bench sums
    /// it: pixel step by pixel step.
    pub fn chain_length(&self, keypoints: &[Pixel]) -> f64 {
        let (sx, sy) = (self.frame.sx, self.frame.sy);
        keypoints
            .windows(2)
            .flat_map(|w| {
                let line = bresenham(w[0], w[1]);
                line.windows(2)
                    .map(|s| {
                        let dc = s[1].0 as f64 - s[0].0 as f64;
                        let dr = s[1].1 as f64 - s[0].1 as f64;
                        (dc * sx).hypot(dr * sy)
                    })
                    .collect::<Vec<_>>()
            })
            .sum()
    }

    /// GN-Bench's distance between two (already resolved) pixels: 0 for the same pixel, ∞
    /// without a path on any grid.
    pub fn pixel_distance(&self, start: Pixel, goal: Pixel) -> f64 {
        if start == goal {
            return 0.0;
        }
        match self.path(start, goal) {
            Some(path) => self.chain_length(&self.smooth(&path)),
            None => f64::INFINITY,
        }
    }

    /// GN-Bench's distance to `goal` from every position of an episode, in order (the start
    /// first): a position off the passable grid falls back to the episode's last passable
    /// position so far (the start included), else to the nearest passable pixel; `None` where
    /// the goal cannot be reached. Distances are computed once per distinct start pixel.
    pub fn trace_distances(&self, positions: &[[f64; 2]], goal: [f64; 2]) -> Vec<Option<f64>> {
        let g = self.pixel(goal);
        let goal_px = if self.is_passable(g) {
            g
        } else {
            self.nearest_passable(g).unwrap_or(g)
        };
        let mut last_passable: Option<Pixel> = None;
        let mut memo: HashMap<Pixel, f64> = HashMap::new();
        positions
            .iter()
            .map(|p| {
                let px = self.pixel(*p);
                let start = if self.is_passable(px) {
                    last_passable = Some(px);
                    px
                } else {
                    last_passable
                        .or_else(|| self.nearest_passable(px))
                        .unwrap_or(px)
                };
                let d = *memo
                    .entry(start)
                    .or_insert_with(|| self.pixel_distance(start, goal_px));
                d.is_finite().then_some(d)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
