//! Hand-built grids where each of GN-Bench's rules changes the distance, and an independent
//! shortest-path reference for the A*.

use super::*;

const FREE: u8 = 255;
const WALL: u8 = 0;

/// A grid from rows of text: `#` blocked, anything else free; 1 m pixels, column 0 at
/// x = width (the image is mirrored in x), row 0 at y = 0.
fn grid(rows: &[&str], margins: &[usize]) -> GnBenchGrid {
    let (w, h) = (rows[0].len(), rows.len());
    let cells: Vec<u8> = rows
        .iter()
        .flat_map(|r| r.bytes().map(|b| if b == b'#' { WALL } else { FREE }))
        .collect();
    let frame = GnFrame {
        upper_x: w as f64,
        lower_y: 0.0,
        sx: 1.0,
        sy: 1.0,
    };
    GnBenchGrid::new(w, h, &cells, frame, margins)
}

/// The world point at the centre of pixel `(c, r)` of a [`grid`].
fn centre(g: &GnBenchGrid, (c, r): Pixel) -> [f64; 2] {
    [g.size().0 as f64 - c as f64 - 0.5, r as f64 + 0.5]
}

fn cost(path: &[Pixel]) -> f64 {
    path.windows(2)
        .map(|w| {
            let diag = w[0].0 != w[1].0 && w[0].1 != w[1].1;
            if diag { std::f64::consts::SQRT_2 } else { 1.0 }
        })
        .sum()
}

#[test]
fn pixels_round_half_to_even_and_clamp() {
    let g = grid(&["....."; 4], &[0]);
    // x = 3 lies on the edge of columns 1 and 2: (5 − 3) − ½ = 1.5 rounds to 2; x = 2, on the
    // edge of columns 2 and 3, gives 2.5, which rounds to 2 as well (a floor of (5 − x) would
    // give 2 and 3).
    assert_eq!(g.pixel([3.0, 0.5]), (2, 0));
    assert_eq!(g.pixel([2.0, 0.5]), (2, 0));
    assert_eq!(g.pixel([4.7, 1.2]), (0, 1));
    assert_eq!(g.pixel([-10.0, 99.0]), (4, 3));
    assert_eq!(g.pixel(centre(&g, (3, 2))), (3, 2));
}

#[test]
fn corners_are_never_cut_but_line_of_sight_shortens() {
    // (0, 0) and (1, 1) are blocked: the diagonal from (1, 0) to (0, 1) passes between them.
    let g = grid(&["#..", ".#.", "..."], &[0]);
    let (a, b) = ((1, 0), (0, 1));
    // The A* refuses the corner and goes round the blocked centre: six axis steps.
    let path = g.astar(0, a, b).unwrap();
    assert_eq!((path[0], *path.last().unwrap()), (a, b));
    assert_eq!(cost(&path), 6.0);
    // The Bresenham line (1, 0)-(0, 1) touches no blocked pixel, so the smoothing joins the
    // ends directly and the distance is √2: shorter than the path the A* found.
    assert_eq!(g.smooth(&path), vec![a, b]);
    assert_eq!(g.pixel_distance(a, b), std::f64::consts::SQRT_2);
    // Boxed in at the corners only: no path at all, the distance is infinite.
    let boxed = grid(&[".#.", "#..", "..."], &[0]);
    assert!(boxed.astar(0, (0, 0), (1, 1)).is_none());
    assert_eq!(boxed.pixel_distance((0, 0), (1, 1)), f64::INFINITY);
}

#[test]
fn smoothing_keeps_keypoints_where_sight_is_blocked() {
    let g = grid(
        &["........", "........", "..####..", "..####..", "........"],
        &[0],
    );
    let (a, b) = ((0, 4), (7, 0));
    let path = g.path(a, b).unwrap();
    let smooth = g.smooth(&path);
    assert_eq!((smooth[0], *smooth.last().unwrap()), (a, b));
    assert!(smooth.len() >= 3, "{smooth:?}");
    let at = |p: &Pixel| path.iter().position(|q| q == p).unwrap();
    for w in smooth.windows(2) {
        assert!(at(&w[1]) == at(&w[0]) + 1 || g.line_of_sight(w[0], w[1]));
    }
    assert!(g.pixel_distance(a, b) <= cost(&path) + 1e-12);
}

#[test]
fn margins_fall_back_from_seven_to_four_pixels() {
    // A wall across the map with a gap of 9 free columns: its middle column is 5 px from both
    // sides, so the gap is open when inflated by 4 px and closed by 5, 6 or 7.
    let w = 41;
    let mut rows: Vec<String> = (0..60).map(|_| ".".repeat(w)).collect();
    for row in &mut rows[28..32] {
        *row = format!("{}{}{}", "#".repeat(16), ".".repeat(9), "#".repeat(16));
    }
    let rows: Vec<&str> = rows.iter().map(String::as_str).collect();
    let g = grid(&rows, &MARGINS);
    let (a, b) = ((20, 5), (20, 55));
    for (k, margin) in MARGINS[..3].iter().enumerate() {
        assert!(g.astar(k, a, b).is_none(), "margin {margin}");
    }
    let path = g.astar(3, a, b).unwrap();
    assert_eq!(g.path(a, b).unwrap(), path);
    assert_eq!(g.pixel_distance(a, b), 50.0);
    // With only the larger margins there is no path: the distance is infinite.
    let strict = grid(&rows, &MARGINS[..3]);
    assert_eq!(strict.pixel_distance(a, b), f64::INFINITY);
    let positions = [centre(&strict, a)];
    assert_eq!(
        strict.trace_distances(&positions, centre(&strict, b)),
        vec![None]
    );
}

#[test]
fn same_pixel_is_zero_and_goal_snaps_to_passable() {
    let g = grid(&["....#", "....#", "....#"], &[0]);
    assert_eq!(g.pixel_distance((1, 1), (1, 1)), 0.0);
    // A goal on the wall snaps to the nearest passable pixel by the ring search: row above
    // first (top edge of the ring), left to right.
    assert_eq!(g.nearest_passable((4, 1)), Some((3, 0)));
    let d = g.trace_distances(&[centre(&g, (3, 0))], centre(&g, (4, 1)));
    assert_eq!(d, vec![Some(0.0)]);
}

#[test]
fn off_grid_positions_use_the_last_passable_one() {
    let g = grid(&["......", "......", "...###", "......"], &[0]);
    let goal = centre(&g, (0, 0));
    let start = centre(&g, (0, 3));
    let inside_wall = centre(&g, (4, 2));
    // In the wall, the distance is the last passable position's (the start), not that of
    // the wall's nearest free pixel (3, 1).
    let d = g.trace_distances(&[start, inside_wall], goal);
    assert_eq!(d[0], d[1]);
    assert_eq!(d[0], Some(3.0));
    // With no passable position before it, the nearest passable pixel stands in.
    let first = g.trace_distances(&[inside_wall], goal);
    assert_eq!(g.nearest_passable((4, 2)), Some((3, 1)));
    assert!((first[0].unwrap() - (2.0 + std::f64::consts::SQRT_2)).abs() < 1e-12);
    assert_ne!(first[0], d[1]);
}

#[test]
fn lengths_count_pixel_steps_in_metres() {
    let frame = GnFrame {
        upper_x: 4.0,
        lower_y: 0.0,
        sx: 0.05,
        sy: 0.1,
    };
    let g = GnBenchGrid::new(4, 3, &[FREE; 12], frame, &[0]);
    // Along a row: 3 columns of 5 cm; then one diagonal step of (5 cm, 10 cm).
    let d = g.chain_length(&[(0, 0), (3, 0), (2, 1)]);
    assert!((d - (0.15 + 0.05f64.hypot(0.1))).abs() < 1e-12, "{d}");
}

/// Shortest 8-connected path cost without corner cutting, by repeated relaxation (no
/// priority queue, no heuristic).
fn reference(rows: &[Vec<bool>], a: Pixel, b: Pixel) -> Option<f64> {
    let (h, w) = (rows.len(), rows[0].len());
    let free = |x: isize, y: isize| {
        x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h && rows[y as usize][x as usize]
    };
    let mut d = vec![vec![f64::INFINITY; w]; h];
    d[a.1][a.0] = 0.0;
    loop {
        let mut changed = false;
        for y in 0..h as isize {
            for x in 0..w as isize {
                let here = d[y as usize][x as usize];
                if !here.is_finite() {
                    continue;
                }
                for (dx, dy) in NEIGHBOURS {
                    let (nx, ny) = (x + dx, y + dy);
                    if !free(nx, ny) || (dx != 0 && dy != 0 && !(free(nx, y) && free(x, ny))) {
                        continue;
                    }
                    let c = here + if dx != 0 && dy != 0 { 2f64.sqrt() } else { 1.0 };
                    if c < d[ny as usize][nx as usize] - 1e-12 {
                        d[ny as usize][nx as usize] = c;
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
    let v = d[b.1][b.0];
    v.is_finite().then_some(v)
}

#[test]
fn astar_lengths_match_a_brute_force_reference() {
    let mut state = 0x2545_f491_u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize
    };
    for _ in 0..60 {
        let (w, h) = (3 + next() % 7, 3 + next() % 7);
        let rows: Vec<Vec<bool>> = (0..h)
            .map(|_| (0..w).map(|_| next() % 100 >= 30).collect())
            .collect();
        let text: Vec<String> = rows
            .iter()
            .map(|r| r.iter().map(|&f| if f { '.' } else { '#' }).collect())
            .collect();
        let text: Vec<&str> = text.iter().map(String::as_str).collect();
        let g = grid(&text, &[0]);
        for _ in 0..8 {
            let a = (next() % w, next() % h);
            let b = (next() % w, next() % h);
            if !rows[a.1][a.0] || !rows[b.1][b.0] {
                continue;
            }
            let got = g.astar(0, a, b).map(|p| cost(&p));
            let want = reference(&rows, a, b);
            match (got, want) {
                (Some(x), Some(y)) => {
                    assert!((x - y).abs() < 1e-9, "{text:?} {a:?}→{b:?}: {x} vs {y}")
                }
                (None, None) => {}
                other => panic!("{text:?} {a:?}→{b:?}: {other:?}"),
            }
        }
    }
}
