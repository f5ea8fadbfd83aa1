//! Shortest paths on the navigable grid: A* with the octile heuristic, region queries and
//! Dijkstra distance fields, 8-connected without corner cutting (a diagonal step needs both
//! cells beside it navigable).
//!
//! Costs are in cell units: a step costs its length (1 or √2) times the mean of its two cells'
//! multipliers. The scratch arrays of a [`Search`] are stamped with a generation counter, so one
//! `Search` serves any number of queries without clearing or reallocating grid-sized arrays.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f32::consts::SQRT_2;

/// The graph: the navigable mask (its border must be all false) and optional cell multipliers.
#[derive(Debug, Clone, Copy)]
pub struct Graph<'a> {
    /// Cells per row.
    pub width: usize,
    /// Navigable cells.
    pub passable: &'a [bool],
    /// Cost multiplier per cell (`None`: every step costs its length).
    pub weight: Option<&'a [f32]>,
    /// A lower bound of the multipliers of navigable cells (keeps the heuristic admissible).
    pub min_weight: f32,
}

impl Graph<'_> {
    fn step(&self, a: usize, b: usize, len: f32) -> f32 {
        match self.weight {
            Some(w) => len * 0.5 * (w[a] + w[b]),
            None => len,
        }
    }

    /// Calls `f(neighbour, cost)` for every legal step out of navigable cell `k`.
    #[inline]
    fn neighbours(&self, k: usize, mut f: impl FnMut(usize, f32)) {
        let w = self.width;
        let p = self.passable;
        let (e, wst, n, s) = (k + 1, k - 1, k + w, k - w);
        let (pe, pw, pn, ps) = (p[e], p[wst], p[n], p[s]);
        for (ok, m) in [(pe, e), (pw, wst), (pn, n), (ps, s)] {
            if ok {
                f(m, self.step(k, m, 1.0));
            }
        }
        for (ok, m) in [
            (pe && pn, n + 1),
            (pw && pn, n - 1),
            (pe && ps, s + 1),
            (pw && ps, s - 1),
        ] {
            if ok && p[m] {
                f(m, self.step(k, m, SQRT_2));
            }
        }
    }
}

/// A heap entry; ordered so that `BinaryHeap` pops the lowest `f`, then the highest `g`.
#[derive(Debug, Clone, Copy)]
struct Node {
    f: f32,
    g: f32,
    cell: u32,
}

impl PartialEq for Node {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Node {}
impl PartialOrd for Node {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Node {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .f
            .total_cmp(&self.f)
            .then(self.g.total_cmp(&other.g))
            .then(other.cell.cmp(&self.cell))
    }
}

/// Per-cell scratch of a [`Search`], kept together so a relaxation touches one cache line.
#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    g: f32,
    parent: u32,
    stamp: u32,
}

/// Reusable search state (see the module docs).
#[derive(Debug, Default)]
pub struct Search {
    slots: Vec<Slot>,
    generation: u32,
    heap: BinaryHeap<Node>,
    /// Cells expanded by the last query.
    pub expanded: usize,
}

impl Search {
    /// An empty search; it grows to the grid on first use.
    pub fn new() -> Search {
        Search::default()
    }

    fn begin(&mut self, cells: usize) {
        if self.slots.len() < cells {
            self.slots.resize(cells, Slot::default());
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.slots.iter_mut().for_each(|s| s.stamp = 0);
            self.generation = 1;
        }
        self.heap.clear();
        self.expanded = 0;
    }

    fn cost(&self, k: usize) -> f32 {
        let s = self.slots[k];
        if s.stamp == self.generation {
            s.g
        } else {
            f32::INFINITY
        }
    }

    fn open(&mut self, k: usize, g: f32, f: f32, parent: usize) {
        self.slots[k] = Slot {
            g,
            parent: parent as u32,
            stamp: self.generation,
        };
        self.heap.push(Node {
            f,
            g,
            cell: k as u32,
        });
    }

    /// The cheapest cost from `start` to `goal` (cell units), or `None` when unreachable; the
    /// path is then read with [`Search::path_to`]. Both cells must be navigable.
    pub fn astar(&mut self, graph: &Graph, start: usize, goal: usize) -> Option<f32> {
        self.begin(graph.passable.len());
        if !(graph.passable[start] && graph.passable[goal]) {
            return None;
        }
        let w = graph.width;
        let (gx, gy) = ((goal % w) as i32, (goal / w) as i32);
        let scale = graph.min_weight;
        // The octile distance to the goal from cell coordinates (no division per neighbour).
        let h = |x: i32, y: i32| {
            let (dx, dy) = (
                (x - gx).unsigned_abs() as f32,
                (y - gy).unsigned_abs() as f32,
            );
            (dx.max(dy) + (SQRT_2 - 1.0) * dx.min(dy)) * scale
        };
        let w32 = w as i32;
        self.open(start, 0.0, h((start % w) as i32, (start / w) as i32), start);
        while let Some(node) = self.heap.pop() {
            let k = node.cell as usize;
            if node.g > self.cost(k) {
                continue;
            }
            if k == goal {
                return Some(node.g);
            }
            self.expanded += 1;
            let (x, y) = ((k % w) as i32, (k / w) as i32);
            graph.neighbours(k, |m, c| {
                let g = node.g + c;
                if g < self.cost(m) {
                    let d = m as i32 - k as i32;
                    // m = k + dx + dy·w with dx, dy in −1..=1.
                    let dy = (d + w32 + 1).div_euclid(w32) - 1;
                    let dx = d - dy * w32;
                    self.open(m, g, g + h(x + dx, y + dy), k);
                }
            });
        }
        None
    }

    /// Dijkstra from `start` to a goal region: `bonus(cell)` is `Some(extra)` for goal cells, and
    /// the result minimises `g(cell) + extra`; returns that cell and the total, or `None` when no
    /// goal cell is reachable.
    pub fn nearest_goal(
        &mut self,
        graph: &Graph,
        start: usize,
        bonus: impl Fn(usize) -> Option<f32>,
    ) -> Option<(usize, f32)> {
        self.begin(graph.passable.len());
        if !graph.passable[start] {
            return None;
        }
        let mut best: Option<(usize, f32)> = None;
        self.open(start, 0.0, 0.0, start);
        while let Some(node) = self.heap.pop() {
            let k = node.cell as usize;
            if node.g > self.cost(k) {
                continue;
            }
            if best.is_some_and(|(_, b)| node.g >= b) {
                break;
            }
            if let Some(extra) = bonus(k)
                && best.is_none_or(|(_, b)| node.g + extra < b)
            {
                best = Some((k, node.g + extra));
            }
            self.expanded += 1;
            graph.neighbours(k, |m, c| {
                let g = node.g + c;
                if g < self.cost(m) {
                    self.open(m, g, g, k);
                }
            });
        }
        best
    }

    /// Writes the cells from the last query's start to `goal` into `out` (cleared first).
    pub fn path_to(&self, goal: usize, out: &mut Vec<usize>) {
        out.clear();
        let mut k = goal;
        out.push(k);
        while self.slots[k].parent as usize != k {
            k = self.slots[k].parent as usize;
            out.push(k);
        }
        out.reverse();
    }
}

/// The cost from a set of sources to every cell, with the way back: one Dijkstra answers any
/// number of goals.
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceField {
    /// Cost per cell (cell units; infinite where unreachable).
    pub cost: Vec<f32>,
    /// The previous cell on a cheapest path towards a source (a source is its own parent).
    pub parent: Vec<u32>,
}

impl DistanceField {
    /// Dijkstra from every navigable cell of `sources` over the whole graph.
    pub fn build(graph: &Graph, sources: &[usize]) -> DistanceField {
        let n = graph.passable.len();
        let mut cost = vec![f32::INFINITY; n];
        let mut parent: Vec<u32> = (0..n as u32).collect();
        let mut heap = BinaryHeap::new();
        for &s in sources.iter().filter(|&&s| graph.passable[s]) {
            cost[s] = 0.0;
            heap.push(Node {
                f: 0.0,
                g: 0.0,
                cell: s as u32,
            });
        }
        while let Some(node) = heap.pop() {
            let k = node.cell as usize;
            if node.g > cost[k] {
                continue;
            }
            graph.neighbours(k, |m, c| {
                let g = node.g + c;
                if g < cost[m] {
                    cost[m] = g;
                    parent[m] = k as u32;
                    heap.push(Node {
                        f: g,
                        g,
                        cell: m as u32,
                    });
                }
            });
        }
        DistanceField { cost, parent }
    }

    /// The cells from `cell` back to its nearest source (empty when unreachable).
    pub fn path_from(&self, cell: usize) -> Vec<usize> {
        if !self.cost[cell].is_finite() {
            return Vec::new();
        }
        let mut out = vec![cell];
        let mut k = cell;
        while self.parent[k] as usize != k {
            k = self.parent[k] as usize;
            out.push(k);
        }
        out
    }
}
