//! GN-Bench's measures (metric mode `gnbench`; research notes gn_bench.md §A2, §A4): success
//! within 3.0 m of its grid distance to goal, oracle success from the reset on, SPL over that
//! distance, the forced STOP after 25 unchanged distances, and its means.
//!
//! The distances themselves (GN-Bench's A* on the occupancy image, `sage_nav::gnbench`) come
//! with the record ([`GnBenchDistances`]); everything here is arithmetic on them.

use serde::{Deserialize, Serialize};

/// GN-Bench's success (and oracle success) threshold, metres, strict `<`.
pub const SUCCESS_DISTANCE: f64 = 3.0;

/// GN-Bench's runner forces STOP once the distance to goal has stayed the same (bit for bit)
/// for more than this many loop iterations in a row.
pub const EARLY_STOP_UNCHANGED: usize = 25;

/// GN-Bench's distance to goal at the start and after every step, as the environment computed
/// it on the scene's occupancy image (`None`: no path, GN-Bench's ∞). Raw values: the metrics
/// apply GN-Bench's rule that the distance is only recomputed after a move.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GnBenchDistances {
    /// At the start position.
    #[serde(default)]
    pub start: Option<f64>,
    /// After each step, one per step.
    #[serde(default)]
    pub steps: Vec<Option<f64>>,
}

/// `None` (no path) as ∞.
pub fn value(d: Option<f64>) -> f64 {
    d.unwrap_or(f64::INFINITY)
}

/// The number of steps GN-Bench's runner lets the agent choose before it forces STOP, given
/// the distances it reads before each of them (`distances[k]`: the start for k = 0, else after
/// step k): before step k + 1 it counts how many times in a row the distance has equalled the
/// previous reading (the reading before the first is ∞, so an unreachable start counts once),
/// and STOP is forced when the count exceeds [`EARLY_STOP_UNCHANGED`]. `None` when that never
/// happens within the readings given.
pub fn forced_stop(distances: &[Option<f64>]) -> Option<usize> {
    let mut last = f64::INFINITY;
    let mut unchanged = 0;
    for (k, d) in distances.iter().enumerate() {
        let d = value(*d);
        unchanged = if d == last { unchanged + 1 } else { 0 };
        last = d;
        if unchanged > EARLY_STOP_UNCHANGED {
            return Some(k);
        }
    }
    None
}

/// GN-Bench's success: STOP and 0 < d < 3.0 (a distance of exactly 0, the agent on the goal's
/// pixel, fails: GN-Bench tests the distance for truth first).
pub fn success(stop_called: bool, d: f64) -> bool {
    stop_called && d != 0.0 && d < SUCCESS_DISTANCE
}

/// GN-Bench's SPL: success · d0 / max(d0, L), computed as it is, so an unreachable start
/// (d0 = ∞) or d0 = L = 0 gives NaN.
pub fn spl(success: bool, d0: f64, taken: f64) -> f64 {
    let s = if success { 1.0 } else { 0.0 };
    s * (d0 / d0.max(taken))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_forced_stop_comes_after_26_unchanged_readings() {
        let d = |v: f64, n: usize| vec![Some(v); n];
        // Readings 0..=25 equal: 25 repeats, not yet more than 25.
        assert_eq!(forced_stop(&d(4.0, 26)), None);
        // The 27th equal reading (k = 26) is the 26th repeat: STOP replaces step 27.
        assert_eq!(forced_stop(&d(4.0, 27)), Some(26));
        // A change resets the count.
        let mut v = d(4.0, 20);
        v.extend(d(3.5, 26));
        assert_eq!(forced_stop(&v), None);
        v.push(Some(3.5));
        assert_eq!(forced_stop(&v), Some(46));
        // An unreachable start already equals the ∞ read before it.
        assert_eq!(forced_stop(&vec![None; 26]), Some(25));
    }

    #[test]
    fn success_and_spl_follow_gn_bench() {
        assert!(success(true, 2.99));
        assert!(!success(true, 3.0));
        assert!(!success(true, 0.0));
        assert!(!success(false, 1.0));
        assert!(!success(true, f64::INFINITY));
        assert_eq!(spl(true, 4.0, 5.0), 0.8);
        assert_eq!(spl(true, 4.0, 3.0), 1.0);
        assert_eq!(spl(false, 4.0, 5.0), 0.0);
        assert!(spl(false, f64::INFINITY, 5.0).is_nan());
        assert!(spl(true, 0.0, 0.0).is_nan());
        assert_eq!(spl(true, 0.0, 1.0), 0.0);
    }
}
