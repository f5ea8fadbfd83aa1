//! FastDTW (Salvador & Chan 2007) exactly as the Python `fastdtw` package (0.3.4, its pure-Python
//! path) computes it, which is what VLN-CE's nDTW calls: an approximation of DTW, not exact DTW.
//!
//! FastDTW solves DTW on sequences halved by averaging neighbours, widens the coarse path by
//! `radius` cells, projects it onto the finer grid and solves DTW only inside that window. The
//! result is the cost of some monotone path, so it is never below exact DTW
//! ([`crate::dtw::dtw`]) and often above it. Reproducing VLN-CE's numbers therefore needs the
//! package's every choice: how sequences are halved, how the window is built (including its
//! row scan) and how ties between equal-cost steps are broken, because the path picked at a
//! coarse level decides the window at the next finer one.

/// The package's default `radius`, the one VLN-CE uses (it never passes another).
pub const FASTDTW_RADIUS: usize = 1;

/// FastDTW cost between `x` (the query; VLN-CE passes the agent's positions) and `y` (the
/// reference path) under the Euclidean distance, as `fastdtw.fastdtw(x, y, radius=radius,
/// dist=euclidean)[0]` returns it.
///
/// Infinite when either sequence is empty (the package returns 0 for two empty sequences and
/// raises for one; an empty trace scores nDTW 0 either way). With `radius == 0` the window can
/// miss the last cell, where the package raises; this returns +inf there. With `radius >= 1` the
/// result is always finite for finite points.
pub fn fastdtw(x: &[[f64; 2]], y: &[[f64; 2]], radius: usize) -> f64 {
    if x.is_empty() || y.is_empty() {
        return f64::INFINITY;
    }
    solve(x, y, radius, false).0
}

/// The Euclidean distance as numpy computes it on the machines the goldens came from:
/// `numpy.linalg.norm(a - b)` is `sqrt(d.dot(d))`, and the BLAS dot product fuses the second
/// multiply-add (`fma(dy, dy, dx·dx)`). It agrees with `hypot` within an ulp or so, but matching
/// numpy's rounding keeps exact ties between costs where the package sees them.
fn distance(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    dy.mul_add(dy, dx * dx).sqrt()
}

/// One level of `__fastdtw`: full DTW below `radius + 2` points, else recurse on the halved
/// sequences and solve inside the window grown from the coarse path. Returns the cost and, when
/// `want_path`, the path (the top level needs only the cost).
fn solve(
    x: &[[f64; 2]],
    y: &[[f64; 2]],
    radius: usize,
    want_path: bool,
) -> (f64, Vec<(usize, usize)>) {
    let min_time_size = radius + 2;
    let window = if x.len() < min_time_size || y.len() < min_time_size {
        vec![(0, y.len()); x.len()]
    } else {
        let (_, coarse) = solve(&reduce_by_half(x), &reduce_by_half(y), radius, true);
        expand_window(&coarse, x.len(), y.len(), radius)
    };
    windowed_dtw(x, y, &window, want_path)
}

/// `__reduce_by_half`: the means of points (0, 1), (2, 3), …; an odd last point is dropped.
fn reduce_by_half(x: &[[f64; 2]]) -> Vec<[f64; 2]> {
    x.chunks_exact(2)
        .map(|p| [(p[0][0] + p[1][0]) / 2.0, (p[0][1] + p[1][1]) / 2.0])
        .collect()
}

/// `__expand_window`: the fine-grid window, as one half-open column range per row of `x`
/// (empty where the row has no cell).
///
/// The package takes every cell within `radius` (Chebyshev) of the coarse path, maps each to
/// its 2×2 block of fine cells, and then scans rows in order: row `i` keeps only the first run
/// of consecutive window cells at or after the column where row `i − 1`'s kept run started.
/// Each coarse path cell thus contributes one rectangle of fine cells; the union per row is kept
/// as merged intervals, which gives the same set without materialising it.
fn expand_window(
    path: &[(usize, usize)],
    len_x: usize,
    len_y: usize,
    radius: usize,
) -> Vec<(usize, usize)> {
    let mut window = vec![(0, 0); len_x];
    if len_y == 0 {
        return window;
    }
    // Signed arithmetic: the package's neighbourhoods reach below index 0 and past the ends;
    // its row scan never looks at such cells, so they are clipped here.
    let r = radius as i64;
    let (rows, cols) = (len_x as i64, len_y as i64);
    let mut spans: Vec<Vec<(usize, usize)>> = vec![Vec::new(); len_x];
    for &(i, j) in path {
        let (i, j) = (i as i64, j as i64);
        let col_lo = (2 * (j - r)).max(0);
        let col_hi = (2 * (j + r) + 1).min(cols - 1);
        if col_lo > col_hi {
            continue;
        }
        for row in (2 * (i - r)).max(0)..=(2 * (i + r) + 1).min(rows - 1) {
            spans[row as usize].push((col_lo as usize, col_hi as usize));
        }
    }
    let mut start_j = 0;
    for (row, row_spans) in spans.iter_mut().enumerate() {
        row_spans.sort_unstable();
        // Merge overlapping or adjacent intervals: a "run" in the scan is a maximal interval.
        let mut merged: Vec<(usize, usize)> = Vec::with_capacity(row_spans.len());
        for &(lo, hi) in row_spans.iter() {
            match merged.last_mut() {
                Some(last) if lo <= last.1 + 1 => last.1 = last.1.max(hi),
                _ => merged.push((lo, hi)),
            }
        }
        match merged.iter().find(|&&(_, hi)| hi >= start_j) {
            Some(&(lo, hi)) => {
                let first = lo.max(start_j);
                window[row] = (first, hi + 1);
                start_j = first;
            }
            // The package sets `start_j = None` here and raises on the next row (only
            // possible with radius 0); no later row gets a cell, so the cost becomes +inf.
            None => break,
        }
    }
    window
}

/// Which predecessor a cell's cost came from, in the order the package lists them to `min`.
#[derive(Clone, Copy)]
enum Step {
    /// From `(i − 1, j)`.
    Up,
    /// From `(i, j − 1)`.
    Left,
    /// From `(i − 1, j − 1)`.
    Diagonal,
}

/// `__dtw` restricted to `window` (one half-open column range per row of `x`), cells visited
/// row by row as the package does. Returns the cost of the last cell and, when `want_path`,
/// the path traced back from it. An unreachable last cell gives (+inf, no path).
fn windowed_dtw(
    x: &[[f64; 2]],
    y: &[[f64; 2]],
    window: &[(usize, usize)],
    want_path: bool,
) -> (f64, Vec<(usize, usize)>) {
    // Dense storage per row: row `i`'s cells `lo..hi` live at `offset[i]..offset[i] + hi - lo`.
    let mut offset = Vec::with_capacity(window.len());
    let mut total = 0;
    for &(lo, hi) in window {
        offset.push(total);
        total += hi - lo;
    }
    let mut cells: Vec<(f64, Step)> = Vec::with_capacity(total);
    // The package's D is indexed from (1, 1) with D[0, 0] = 0 and every other missing entry
    // +inf; `cost(i, j)` reads that table, where cell (i, j) of the grid is D[i + 1, j + 1].
    let cost = |cells: &[(f64, Step)], i: usize, j: usize| -> f64 {
        if i == 0 || j == 0 {
            return if i == 0 && j == 0 { 0.0 } else { f64::INFINITY };
        }
        let (lo, hi) = window[i - 1];
        if (lo..hi).contains(&(j - 1)) {
            cells[offset[i - 1] + (j - 1 - lo)].0
        } else {
            f64::INFINITY
        }
    };
    for (i, (xi, &(lo, hi))) in x.iter().zip(window).enumerate() {
        for (j, yj) in (lo..hi).zip(&y[lo..hi]) {
            let dt = distance(xi, yj);
            let (di, dj) = (i + 1, j + 1);
            // Python's `min(..., key=cost)` keeps the first of equal costs and replaces it
            // only on a strictly smaller one; the order is up, left, diagonal.
            let mut best = (cost(&cells, di - 1, dj) + dt, Step::Up);
            for candidate in [
                (cost(&cells, di, dj - 1) + dt, Step::Left),
                (cost(&cells, di - 1, dj - 1) + dt, Step::Diagonal),
            ] {
                if candidate.0 < best.0 {
                    best = candidate;
                }
            }
            cells.push(best);
        }
    }
    let total_cost = cost(&cells, x.len(), y.len());
    if !want_path || !total_cost.is_finite() {
        return (total_cost, Vec::new());
    }
    let mut path = Vec::with_capacity(x.len() + y.len());
    let (mut i, mut j) = (x.len(), y.len());
    while !(i == 0 && j == 0) {
        path.push((i - 1, j - 1));
        let (lo, _) = window[i - 1];
        match cells[offset[i - 1] + (j - 1 - lo)].1 {
            Step::Up => i -= 1,
            Step::Left => j -= 1,
            Step::Diagonal => {
                i -= 1;
                j -= 1;
            }
        }
    }
    path.reverse();
    (total_cost, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dtw::{dtw, euclidean};

    /// How a test sequence moves (see [`sequence`]).
    #[derive(Clone, Copy)]
    enum Kind {
        /// Free random walk, steps in [−1, 1] m per axis at 0.01 m.
        Walk,
        /// Steps of −1, 0 or 1 lattice cells per axis on a 0.25 m lattice (exact distances
        /// repeat, so equal-cost ties are common).
        Lattice,
        /// One 4-neighbour lattice step or none (two times in six): repeated points, as an agent
        /// that stands still leaves them.
        Still,
    }

    /// The deterministic test sequences, written identically in the generator below: a 64-bit
    /// LCG (Knuth's MMIX constants) whose top 31 bits drive each step.
    fn sequence(seed: u64, n: usize, kind: Kind) -> Vec<[f64; 2]> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            s >> 33
        };
        let (mut x, mut y, mut ix, mut iy) = (0.0f64, 0.0f64, 0i64, 0i64);
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            match kind {
                Kind::Walk => {
                    x += ((next() % 201) as f64 - 100.0) / 100.0;
                    y += ((next() % 201) as f64 - 100.0) / 100.0;
                    out.push([x, y]);
                }
                Kind::Lattice => {
                    ix += (next() % 3) as i64 - 1;
                    iy += (next() % 3) as i64 - 1;
                    out.push([ix as f64 * 0.25, iy as f64 * 0.25]);
                }
                Kind::Still => {
                    let r = next() % 6;
                    ix += i64::from(r == 1) - i64::from(r == 3);
                    iy += i64::from(r == 2) - i64::from(r == 4);
                    out.push([ix as f64 * 0.25, iy as f64 * 0.25]);
                }
            }
        }
        out
    }

    // Goldens from fastdtw 0.3.4 (pure Python) with numpy 2.4 on x86-64, made by this script:
    //
    //     import numpy, fastdtw
    //     M = 2**64
    //     def seq(seed, n, kind):
    //         s = seed
    //         def nxt():
    //             nonlocal s
    //             s = (s * 6364136223846793005 + 1442695040888963407) % M
    //             return s >> 33
    //         out, x, y, ix, iy = [], 0.0, 0.0, 0, 0
    //         for _ in range(n):
    //             if kind == "walk":
    //                 x += (nxt() % 201 - 100) / 100.0
    //                 y += (nxt() % 201 - 100) / 100.0
    //                 out.append([x, y])
    //             elif kind == "lattice":
    //                 ix += nxt() % 3 - 1
    //                 iy += nxt() % 3 - 1
    //                 out.append([ix * 0.25, iy * 0.25])
    //             else:  # "still"
    //                 r = nxt() % 6
    //                 ix += (r == 1) - (r == 3)
    //                 iy += (r == 2) - (r == 4)
    //                 out.append([ix * 0.25, iy * 0.25])
    //         return out
    //     dist = lambda a, b: numpy.linalg.norm(numpy.array(a) - numpy.array(b))
    //     for sx, nx, sy, ny, kind, r in CASES:
    //         x, y = seq(sx, nx, kind), seq(sy, ny, kind)
    //         print(fastdtw.fastdtw(x, y, radius=r, dist=dist)[0],
    //               fastdtw.dtw(x, y, dist=dist)[0])
    //
    // A Python callable `dist` keeps the package on its pure-Python path even where the C
    // extension is installed, as in VLN-CE. The "still" cases were picked because they are
    // tie-sensitive: listing `min`'s candidates in any other order changes the package's own
    // FastDTW result on them (checked by patching `__dtw`).

    /// (seed x, len x, seed y, len y, kind, radius, fastdtw, exact DTW) from the package.
    type Case = (u64, usize, u64, usize, Kind, usize, f64, f64);

    /// The package's results on the generated sequences.
    const GOLDEN: [Case; 12] = [
        // Below `radius + 2` points: full DTW.
        (
            1,
            2,
            2,
            5,
            Kind::Walk,
            1,
            11.449308350403825,
            11.449308350403825,
        ),
        // Exactly `radius + 2`: one coarse level of a single point each.
        (
            3,
            3,
            4,
            3,
            Kind::Walk,
            1,
            3.64235492846494,
            3.64235492846494,
        ),
        (
            5,
            17,
            6,
            9,
            Kind::Walk,
            1,
            33.961318226792855,
            33.961318226792855,
        ),
        (
            7,
            60,
            8,
            41,
            Kind::Walk,
            1,
            350.0946257484864,
            350.0946257484864,
        ),
        (
            9,
            23,
            10,
            31,
            Kind::Lattice,
            1,
            27.100080499646435,
            27.100080499646435,
        ),
        // Tie-sensitive: here the package's order finds the exact DTW, others do not.
        (
            1116,
            14,
            1117,
            28,
            Kind::Still,
            1,
            18.343998631046887,
            18.343998631046887,
        ),
        // Tie-sensitive and above exact DTW.
        (
            1117,
            15,
            1118,
            35,
            Kind::Still,
            1,
            8.36967716615477,
            7.987711154904664,
        ),
        (
            1359,
            35,
            1360,
            7,
            Kind::Still,
            1,
            20.053968071350184,
            20.053968071350184,
        ),
        // The approximation far above exact DTW (by 42.7).
        (
            262,
            47,
            263,
            47,
            Kind::Walk,
            1,
            346.8819098727072,
            304.13689625758565,
        ),
        (
            13,
            200,
            14,
            150,
            Kind::Walk,
            1,
            1635.178914929015,
            1632.355765508371,
        ),
        (
            15,
            201,
            16,
            199,
            Kind::Lattice,
            1,
            572.2698612534874,
            572.2698612534874,
        ),
        (
            17,
            50,
            18,
            37,
            Kind::Walk,
            2,
            342.5849457573987,
            342.5849457573987,
        ),
    ];

    #[test]
    fn fastdtw_matches_python_package() {
        let mut above_exact = 0;
        for (sx, nx, sy, ny, kind, radius, fast, exact) in GOLDEN {
            let (x, y) = (sequence(sx, nx, kind), sequence(sy, ny, kind));
            let got = fastdtw(&x, &y, radius);
            assert!((got - fast).abs() < 1e-9, "case {sx}: {got} vs {fast}");
            // The exact DTW agrees too, which shows the inputs are the generator's.
            let d = dtw(&y, &x, euclidean);
            assert!((d - exact).abs() < 1e-9, "case {sx}: exact {d} vs {exact}");
            if fast - exact > 1e-6 {
                // The approximation is reproduced, not replaced by exact DTW.
                assert!(got - d > 1e-6, "case {sx}");
                above_exact += 1;
            }
        }
        assert_eq!(above_exact, 3);
    }

    #[test]
    fn fastdtw_default_radius_and_short_sequences() {
        assert_eq!(FASTDTW_RADIUS, 1);
        let x = sequence(1117, 15, Kind::Still);
        let y = sequence(1118, 35, Kind::Still);
        assert_eq!(fastdtw(&x, &y, FASTDTW_RADIUS), fastdtw(&x, &y, 1));
        // A radius as long as the sequences makes it full DTW (the package's own remark).
        assert!((fastdtw(&x, &y, 35) - dtw(&y, &x, euclidean)).abs() < 1e-12);
        // Empty sequences: no alignment.
        assert_eq!(fastdtw(&[], &y, 1), f64::INFINITY);
        assert_eq!(fastdtw(&x, &[], 1), f64::INFINITY);
        assert_eq!(fastdtw(&[], &[], 1), f64::INFINITY);
        // One point against many: the sum of distances to it.
        let p = [[0.0, 0.0]];
        let line = [[3.0, 4.0], [0.0, 1.0], [6.0, 8.0]];
        assert_eq!(fastdtw(&p, &line, 1), 16.0);
        assert_eq!(fastdtw(&line, &p, 1), 16.0);
    }

    #[test]
    fn fastdtw_reduce_by_half_drops_odd_point() {
        let x = [[0.0, 2.0], [1.0, 4.0], [2.0, 0.0], [4.0, 1.0], [9.0, 9.0]];
        assert_eq!(reduce_by_half(&x), vec![[0.5, 3.0], [3.0, 0.5]]);
        assert!(reduce_by_half(&x[..1]).is_empty());
    }

    /// The window as the package lists it: (row, column) cells in row order.
    fn cells(window: &[(usize, usize)]) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for (i, &(lo, hi)) in window.iter().enumerate() {
            out.extend((lo..hi).map(|j| (i, j)));
        }
        out
    }

    #[test]
    fn fastdtw_expand_window_matches_python_package() {
        // `__expand_window(path, len_x, len_y, radius)` outputs from the package.
        let w = expand_window(&[(0, 0), (1, 1), (1, 2), (2, 3)], 6, 9, 1);
        let mut want: Vec<(usize, usize)> =
            (0..2).flat_map(|i| (0..8).map(move |j| (i, j))).collect();
        want.extend((2..6).flat_map(|i| (0..9).map(move |j| (i, j))));
        assert_eq!(cells(&w), want);
        // Not DTW paths (DTW never makes them), for the row scan: cells left of where the
        // previous row started are skipped, a gap ends the row, and a row with nothing at or
        // after that column ends the window.
        let w = expand_window(&[(0, 3), (1, 0), (1, 5), (2, 2)], 5, 12, 0);
        let want = [
            (0, 6),
            (0, 7),
            (1, 6),
            (1, 7),
            (2, 10),
            (2, 11),
            (3, 10),
            (3, 11),
        ];
        assert_eq!(cells(&w), want);
        let w = expand_window(&[(0, 1), (1, 0), (1, 3), (1, 6), (2, 4)], 6, 13, 0);
        let want = [
            (0, 2),
            (0, 3),
            (1, 2),
            (1, 3),
            (2, 6),
            (2, 7),
            (3, 6),
            (3, 7),
            (4, 8),
            (4, 9),
            (5, 8),
            (5, 9),
        ];
        assert_eq!(cells(&w), want);
    }

    #[test]
    fn fastdtw_distance_agrees_with_hypot() {
        for (sx, nx, sy, ny, kind, ..) in GOLDEN {
            let (x, y) = (sequence(sx, nx, kind), sequence(sy, ny, kind));
            for a in &x {
                for b in &y {
                    let (d, h) = (distance(a, b), euclidean(a, b));
                    assert!((d - h).abs() <= 1e-12 * h.max(1.0), "{d} vs {h}");
                }
            }
        }
    }
}

#[cfg(test)]
mod properties {
    use super::*;
    use crate::dtw::{dtw, euclidean};
    use proptest::prelude::*;

    /// Points on a 0.5 m lattice (many exact ties) or anywhere in a 10 m square.
    fn points(n: usize) -> impl Strategy<Value = Vec<[f64; 2]>> {
        prop_oneof![
            proptest::collection::vec((-5i32..5, -5i32..5), 1..n).prop_map(|v| {
                v.into_iter()
                    .map(|(x, y)| [f64::from(x) * 0.5, f64::from(y) * 0.5])
                    .collect()
            }),
            proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0), 1..n)
                .prop_map(|v| v.into_iter().map(|(x, y)| [x, y]).collect()),
        ]
    }

    proptest! {
        #[test]
        fn fastdtw_bounds_exact_dtw(x in points(40), y in points(40), radius in 0usize..4) {
            let fast = fastdtw(&x, &y, radius);
            let exact = dtw(&y, &x, euclidean);
            // The cost of a path inside a window: never below the best path overall. Only
            // radius 0 can lose the last cell (+inf, where the package raises).
            prop_assert!(radius == 0 || fast.is_finite());
            prop_assert!(fast >= exact - 1e-9, "{} < {}", fast, exact);
            if x.len() < radius + 2 || y.len() < radius + 2 {
                prop_assert!((fast - exact).abs() < 1e-9);
            }
        }
    }
}
