//! Dynamic time warping and its normalised forms (SPEC §10: nDTW, SDTW; Ilharco et al. 2019).

/// The VLN distance threshold d_th that normalises DTW (metres).
pub const DTW_THRESHOLD: f64 = 3.0;

/// Exact DTW cost between a reference `r` and a query `q` under `cost`: the cheapest monotone
/// alignment that starts at both first points and ends at both last points. Infinite when either
/// sequence is empty.
pub fn dtw<P>(r: &[P], q: &[P], cost: impl Fn(&P, &P) -> f64) -> f64 {
    if r.is_empty() || q.is_empty() {
        return f64::INFINITY;
    }
    // One row per query point; `prev[j]` is the best cost aligning q[..i] with r[..=j].
    let mut prev = vec![f64::INFINITY; r.len()];
    let mut row = vec![0.0; r.len()];
    for (i, qi) in q.iter().enumerate() {
        for (j, rj) in r.iter().enumerate() {
            let best = match (i, j) {
                (0, 0) => 0.0,
                (0, _) => row[j - 1],
                (_, 0) => prev[0],
                _ => prev[j].min(prev[j - 1]).min(row[j - 1]),
            };
            row[j] = best + cost(qi, rj);
        }
        std::mem::swap(&mut prev, &mut row);
    }
    prev[r.len() - 1]
}

/// nDTW = exp(−DTW / (|R| · d_th)) from a DTW cost and the number of reference points.
pub fn ndtw_from(dtw_cost: f64, reference_points: usize, threshold: f64) -> f64 {
    if reference_points == 0 || !dtw_cost.is_finite() {
        return 0.0;
    }
    (-dtw_cost / (reference_points as f64 * threshold)).exp()
}

/// Euclidean distance of two floor points.
pub fn euclidean(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Consecutive duplicates removed (a turn in place adds no point to an agent trace).
pub fn dedup_trace(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(points.len());
    for p in points {
        if out.last().is_none_or(|l| euclidean(l, p) > 1e-9) {
            out.push(*p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shortest-path distance on a unit grid graph (4-connected, no obstacles).
    fn grid(a: &[f64; 2], b: &[f64; 2]) -> f64 {
        (a[0] - b[0]).abs() + (a[1] - b[1]).abs()
    }

    const PRED: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
    const REF: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0], [3.0, 2.0]];

    #[test]
    fn published_reference_case() {
        // The doctest of the reference DTW implementation (3×4 grid graph, unit edges).
        let d = dtw(&REF, &PRED, grid);
        assert_eq!(d, 3.0);
        let n = ndtw_from(d, REF.len(), DTW_THRESHOLD);
        assert!((n - 0.778_800_783_071_404_9).abs() < 1e-15);
        assert!((n - (-0.25f64).exp()).abs() < 1e-15);
        // Euclidean cost gives the same alignment and cost on this case.
        assert_eq!(dtw(&REF, &PRED, euclidean), 3.0);
    }

    #[test]
    fn alignment_may_repeat_points() {
        // q = [0, 0, 2] against r = [0, 1, 2] on a line: best pairs (0,0) (0,1) (2,2) → 1,
        // or (0,0) (0,0) (2,1) (2,2) → 1; both cost 1.
        let p = |x: f64| [x, 0.0];
        let r = [p(0.0), p(1.0), p(2.0)];
        let q = [p(0.0), p(0.0), p(2.0)];
        assert_eq!(dtw(&r, &q, euclidean), 1.0);
        // Identical sequences cost 0; an empty one is infinite and scores 0.
        assert_eq!(dtw(&r, &r, euclidean), 0.0);
        assert_eq!(dtw(&r, &[], euclidean), f64::INFINITY);
        assert_eq!(ndtw_from(f64::INFINITY, 3, DTW_THRESHOLD), 0.0);
        // Ends are pinned: a query far at the end pays for it.
        let q2 = [p(0.0), p(1.0), p(2.0), p(5.0)];
        assert_eq!(dtw(&r, &q2, euclidean), 3.0);
    }

    #[test]
    fn dedup_drops_only_repeats() {
        let t = [[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 0.0]];
        assert_eq!(dedup_trace(&t), vec![[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]);
    }
}

#[cfg(test)]
mod properties {
    use super::*;
    use proptest::prelude::*;

    /// DTW by enumerating every monotone alignment path (small inputs only).
    fn brute(r: &[[f64; 2]], q: &[[f64; 2]], i: usize, j: usize) -> f64 {
        let c = euclidean(&q[i], &r[j]);
        if i + 1 == q.len() && j + 1 == r.len() {
            return c;
        }
        let mut best = f64::INFINITY;
        if i + 1 < q.len() {
            best = best.min(brute(r, q, i + 1, j));
        }
        if j + 1 < r.len() {
            best = best.min(brute(r, q, i, j + 1));
        }
        if i + 1 < q.len() && j + 1 < r.len() {
            best = best.min(brute(r, q, i + 1, j + 1));
        }
        c + best
    }

    fn points(n: usize) -> impl Strategy<Value = Vec<[f64; 2]>> {
        proptest::collection::vec((-5i32..5, -5i32..5), 1..n).prop_map(|v| {
            v.into_iter()
                .map(|(x, y)| [f64::from(x) * 0.5, f64::from(y) * 0.5])
                .collect()
        })
    }

    proptest! {
        #[test]
        fn dynamic_programme_matches_enumeration(r in points(6), q in points(6)) {
            let d = dtw(&r, &q, euclidean);
            prop_assert!((d - brute(&r, &q, 0, 0)).abs() < 1e-9);
            // Symmetric cost: swapping the sequences changes nothing.
            prop_assert!((d - dtw(&q, &r, euclidean)).abs() < 1e-9);
            let n = ndtw_from(d, r.len(), DTW_THRESHOLD);
            prop_assert!(n > 0.0 && n <= 1.0);
            prop_assert_eq!(n == 1.0, d == 0.0);
        }
    }
}
