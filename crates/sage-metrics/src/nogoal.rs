//! NoGoal-Nav metrics: Episode Time and Explored Area (SPEC §10) and the published variants.

use std::collections::BTreeSet;

/// Side of an exploration cell (metres).
pub const EXPLORE_CELL: f64 = 0.5;
/// Simulated seconds after which a NoGoal episode ends by default (the environment's
/// `task.nogoal_time_limit`), whatever the metric mode.
pub const NOGOAL_TIME_LIMIT: f64 = 120.0;
/// The published code's coverage target: 400 cells (its coverage is cells / 400, capped at 1).
pub const OFFICIAL_COVERAGE_CELLS: f64 = 400.0;

/// The distinct 0.5 m floor cells holding a point: ⌊x/0.5⌋, ⌊y/0.5⌋ in mode `sage`; truncation
/// toward zero when `truncate` (the published code, whose cells touching 0 span 1 m).
pub fn visited_cells(points: &[[f64; 2]], truncate: bool) -> usize {
    let cell = |v: f64| {
        let q = v / EXPLORE_CELL;
        (if truncate { q.trunc() } else { q.floor() }) as i64
    };
    points
        .iter()
        .map(|p| (cell(p[0]), cell(p[1])))
        .collect::<BTreeSet<_>>()
        .len()
}

/// Explored area in m² from a cell count.
pub fn explored_area(cells: usize) -> f64 {
    cells as f64 * EXPLORE_CELL * EXPLORE_CELL
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_floor_and_truncate() {
        let pts = [
            [0.1, 0.1],
            [-0.1, 0.1],
            [0.4, 0.2],
            [0.6, 0.1],
            [-0.6, -0.6],
        ];
        // Floor: (0,0) (−1,0) (0,0) (1,0) (−2,−2) → 4 cells, 1 m².
        assert_eq!(visited_cells(&pts, false), 4);
        assert_eq!(explored_area(4), 1.0);
        // Truncation: (0,0) (0,0) (0,0) (1,0) (−1,−1) → 3 cells.
        assert_eq!(visited_cells(&pts, true), 3);
        assert_eq!(visited_cells(&[], false), 0);
    }
}
