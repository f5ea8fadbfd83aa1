//! Path length, distances to the goal and to the reference path, and the success tests of the
//! three modes (SPEC §10, §10.1).

use super::dtw::euclidean;
use super::smoothness::wrap;
use serde::{Deserialize, Serialize};

/// Success radius of mode `sage` (metres; the test is `≤`).
pub const SAGE_SUCCESS_DISTANCE: f64 = 1.0;
/// Success radius of mode `vlnce` (metres; the test is strict `<`, as VLN-CE codes it).
pub const VLNCE_SUCCESS_DISTANCE: f64 = 3.0;
/// Tolerance around the reference path for CSR in mode `sage` (metres).
pub const CSR_TOLERANCE: f64 = 1.0;
/// Success distance of a pose goal (a Base-Action motion's end) in mode `sage`, metres: less
/// than half the smallest motion an instruction asks for (one 0.25 m step), so staying put
/// never succeeds.
pub const POSE_SUCCESS_DISTANCE: f64 = 0.1;
/// Heading tolerance of a pose goal in mode `sage`, degrees: less than half the smallest turn
/// an instruction asks for (30°).
pub const POSE_SUCCESS_HEADING_DEG: f64 = 10.0;

/// Σ‖p_t − p_{t−1}‖ over consecutive points.
pub fn path_length(points: &[[f64; 2]]) -> f64 {
    points.windows(2).map(|w| euclidean(&w[0], &w[1])).sum()
}

/// Distance from `p` to the segment `a`–`b`.
pub fn point_segment(p: &[f64; 2], a: &[f64; 2], b: &[f64; 2]) -> f64 {
    let (abx, aby) = (b[0] - a[0], b[1] - a[1]);
    let len2 = abx * abx + aby * aby;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * abx + (p[1] - a[1]) * aby) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    euclidean(p, &[a[0] + abx * t, a[1] + aby * t])
}

/// Distance from `p` to a polyline (to its only point when it has one; infinite when empty).
pub fn point_polyline(p: &[f64; 2], line: &[[f64; 2]]) -> f64 {
    match line {
        [] => f64::INFINITY,
        [a] => euclidean(p, a),
        _ => line
            .windows(2)
            .map(|w| point_segment(p, &w[0], &w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

/// The pose test of a pose goal: `distance` (metres) from its point within
/// [`POSE_SUCCESS_DISTANCE`] and the heading difference `dyaw` (radians, any winding) within
/// [`POSE_SUCCESS_HEADING_DEG`].
pub fn pose_reached(distance: f64, dyaw: f64) -> bool {
    distance <= POSE_SUCCESS_DISTANCE && wrap(dyaw).abs().to_degrees() <= POSE_SUCCESS_HEADING_DEG
}

/// True when `p` lies inside the polygon (even-odd rule).
pub fn polygon_contains(poly: &[[f64; 2]], p: &[f64; 2]) -> bool {
    let mut inside = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// The goal region of a VLN episode: the end object's footprint when the episode names one,
/// else the goal point alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GoalRegion {
    /// The goal point `[x, y]` (the reference path's end).
    pub point: [f64; 2],
    /// The end object's footprint polygon, when there is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub footprint: Option<Vec<[f64; 2]>>,
    /// The heading a pose goal asks for (radians): set for Base-Action motions, whose success
    /// in mode `sage` is the pose test ([`GoalRegion::reached`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading: Option<f64>,
}

impl GoalRegion {
    /// The success test of mode `sage` at position `p` and heading `yaw`: a pose goal is
    /// reached within [`POSE_SUCCESS_DISTANCE`] of its point and [`POSE_SUCCESS_HEADING_DEG`]
    /// of its heading; any other goal within `radius` of the region (`≤`).
    pub fn reached(&self, p: &[f64; 2], yaw: f64, radius: f64) -> bool {
        match self.heading {
            Some(h) => pose_reached(euclidean(p, &self.point), yaw - h),
            None => self.distance(p) <= radius,
        }
    }

    /// Euclidean distance from `p` to the region (0 inside the footprint).
    pub fn distance(&self, p: &[f64; 2]) -> f64 {
        match &self.footprint {
            Some(poly) if poly.len() >= 3 => {
                if polygon_contains(poly, p) {
                    0.0
                } else {
                    let mut closed = poly.clone();
                    closed.push(poly[0]);
                    point_polyline(p, &closed)
                }
            }
            _ => euclidean(p, &self.point),
        }
    }
}

/// An entry of the published semantic map (`bbox_m`, here in the W frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LabelledBox {
    /// The entry's `item_id` (`coffee_table_1`, `wall_2`, `unable_area_1`, …).
    #[serde(default)]
    pub item_id: String,
    /// The entry's `category_label` (`Coffee Table`, `wall`, `Unable Area`, …).
    pub label: String,
    /// Lower corner `[x, y]`.
    pub min: [f64; 2],
    /// Upper corner `[x, y]`.
    pub max: [f64; 2],
}

impl LabelledBox {
    fn centre(&self) -> [f64; 2] {
        [
            (self.min[0] + self.max[0]) * 0.5,
            (self.min[1] + self.max[1]) * 0.5,
        ]
    }

    /// True when `p` lies in the box grown by `e` on every side.
    pub fn contains_expanded(&self, p: &[f64; 2], e: f64) -> bool {
        (0..2).all(|k| p[k] >= self.min[k] - e && p[k] <= self.max[k] + e)
    }
}

/// The goal test of the published code (mode `sage-official`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum OfficialGoal {
    /// No semantic map loaded: plain distance to the goal point: < 0.5 m for SR, < 1.5 m for
    /// OSR, ≤ 2.0 m for CSR.
    NoMap,
    /// A map is loaded: its "smart position" entry (see [`official_goal_box`]), or `None` when
    /// no entry lies within 2 m of the goal point (then distance to the goal point is used).
    Map {
        /// The chosen entry.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        chosen: Option<LabelledBox>,
    },
}

/// The published goal radius: its loop stops an episode once the agent is closer than this to
/// the goal point, and without a semantic map success is being closer than this (metres).
pub const OFFICIAL_GOAL_RADIUS: f64 = 0.5;

/// How far from the goal point the published code looks for goal boxes (box centres, metres).
pub const OFFICIAL_SEARCH_RADIUS: f64 = 2.0;

/// Priority of a map entry in the published "smart position" fallback (lower first). As the
/// published code has it, keywords match as substrings of the lower-cased item id or category
/// label (`coffee_table_1` ranks with tables, `office_chair` with chairs), except the
/// furniture group, which it looks for in the category label only.
pub fn official_priority(item_id: &str, label: &str) -> u32 {
    let (id, label) = (item_id.to_lowercase(), label.to_lowercase());
    let either = |kw: &str| id.contains(kw) || label.contains(kw);
    if either("screen") || either("projector") {
        1
    } else if either("table") || either("desk") {
        2
    } else if either("chair") {
        3
    } else if ["furniture", "cabinet", "shelf", "bookcase"]
        .iter()
        .any(|kw| label.contains(kw))
    {
        4
    } else if either("unable") {
        10
    } else {
        5
    }
}

/// The box the published code tests against: among entries whose box centre is ≤ 2.0 m from
/// the goal point (walls and unable areas included), the lowest priority, then the nearest,
/// ties in map order. It then looks the winner up by item id in a table where a later entry
/// with the same id replaced an earlier one, so the box returned is the last entry carrying
/// the winner's id (the same entry unless ids repeat).
pub fn official_goal_box(entries: &[LabelledBox], goal: [f64; 2]) -> Option<LabelledBox> {
    let winner = entries
        .iter()
        .map(|e| (e, euclidean(&e.centre(), &goal)))
        .filter(|(_, d)| *d <= OFFICIAL_SEARCH_RADIUS)
        .min_by(|(a, da), (b, db)| {
            official_priority(&a.item_id, &a.label)
                .cmp(&official_priority(&b.item_id, &b.label))
                .then(da.total_cmp(db))
        })?
        .0;
    entries
        .iter()
        .rev()
        .find(|e| e.item_id == winner.item_id)
        .cloned()
}

/// Which of the published code's three tests is evaluated (they differ only in their margins).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OfficialTest {
    /// Success: box margin 1.0 m, no-map radius 0.5 m (strict).
    Success,
    /// Oracle success: box margin 1.2 m, no-map radius 1.5 m (strict).
    Oracle,
    /// Continuous success: box margin 1.5 m, no-map radius 2.0 m (`≤`).
    Continuous,
}

impl OfficialGoal {
    /// The published test at position `p`, with `goal` the last reference point.
    pub fn passes(&self, test: OfficialTest, p: &[f64; 2], goal: &[f64; 2]) -> bool {
        let e = match test {
            OfficialTest::Success => 1.0,
            OfficialTest::Oracle => 1.2,
            OfficialTest::Continuous => 1.5,
        };
        let d = euclidean(p, goal);
        match self {
            OfficialGoal::NoMap => match test {
                OfficialTest::Success => d < OFFICIAL_GOAL_RADIUS,
                OfficialTest::Oracle => d < 1.5,
                OfficialTest::Continuous => d <= 2.0,
            },
            OfficialGoal::Map { chosen: Some(b) } => b.contains_expanded(p, e),
            OfficialGoal::Map { chosen: None } => d <= e,
        }
    }
}

/// SPL = SR · L* / max(L*, L) (modes `sage` and `vlnce`); `None` when L* = L = 0, where the
/// formula divides zero by zero (habitat's SPL raises there); with L* = 0 < L it is 0.
pub fn spl(success: bool, shortest: f64, taken: f64) -> Option<f64> {
    let denom = shortest.max(taken);
    if denom <= 0.0 {
        return None;
    }
    Some(if success { shortest / denom } else { 0.0 })
}

/// SPL as the published SAGE-3D code computes it: SR · L* / max(L*, L) when L* > 0, else SR.
pub fn official_spl(success: bool, shortest: f64, taken: f64) -> f64 {
    match (success, shortest > 0.0) {
        (false, _) => 0.0,
        (true, true) => shortest / shortest.max(taken),
        (true, false) => 1.0,
    }
}

/// The per-step distances habitat's `DistanceToGoal` reports: it recomputes the distance only
/// when the position moved beyond `np.allclose(previous, current, atol=1e-4)` (per coordinate
/// |a − b| ≤ 1e-4 + 1e-5·|b|) from the position of its last computation, and otherwise repeats
/// the last value. `positions[k]` and `distances[k]` are the start (k = 0) and each step's.
pub fn habitat_cached_distances(
    positions: &[[f64; 3]],
    distances: &[Option<f64>],
) -> Vec<Option<f64>> {
    let close = |a: &[f64; 3], b: &[f64; 3]| {
        (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-4 + 1e-5 * b[k].abs())
    };
    let mut last: Option<([f64; 3], Option<f64>)> = None;
    positions
        .iter()
        .zip(distances)
        .map(|(p, d)| match last {
            Some((q, v)) if close(&q, p) => v,
            _ => {
                last = Some((*p, *d));
                *d
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_and_polyline_distance() {
        let pts = [[0.0, 0.0], [3.0, 4.0], [3.0, 4.0], [3.0, 0.0]];
        assert_eq!(path_length(&pts), 9.0);
        let line = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]];
        assert_eq!(point_polyline(&[2.0, 1.5], &line), 1.5);
        assert_eq!(point_polyline(&[5.0, 2.0], &line), 1.0);
        assert_eq!(point_polyline(&[-3.0, 4.0], &line), 5.0);
        assert_eq!(point_polyline(&[1.0, 1.0], &[[1.0, 2.0]]), 1.0);
        assert!(point_polyline(&[1.0, 1.0], &[]).is_infinite());
    }

    #[test]
    fn goal_region_distance() {
        let sq = vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        let g = GoalRegion {
            point: [1.0, -1.0],
            footprint: Some(sq),
            heading: None,
        };
        assert_eq!(g.distance(&[1.0, 1.0]), 0.0);
        assert_eq!(g.distance(&[3.0, 1.0]), 1.0);
        // The closing edge counts.
        assert_eq!(g.distance(&[-0.5, 1.0]), 0.5);
        assert_eq!(g.distance(&[5.0, 6.0]), 5.0);
        let p = GoalRegion {
            point: [1.0, 1.0],
            footprint: None,
            heading: None,
        };
        assert_eq!(p.distance(&[4.0, 5.0]), 5.0);
    }

    #[test]
    fn spl_cases() {
        assert_eq!(spl(true, 4.0, 5.0), Some(0.8));
        assert_eq!(spl(true, 4.0, 3.0), Some(1.0));
        assert_eq!(spl(false, 4.0, 4.0), Some(0.0));
        // Zero shortest distance: undefined when nothing moved, else 0; the published SAGE
        // formula gives SR in both cases.
        assert_eq!(spl(true, 0.0, 0.0), None);
        assert_eq!(spl(true, 0.0, 1.0), Some(0.0));
        assert_eq!(official_spl(true, 0.0, 1.0), 1.0);
        assert_eq!(official_spl(false, 0.0, 0.0), 0.0);
        assert_eq!(official_spl(true, 4.0, 5.0), 0.8);
    }

    #[test]
    fn habitat_distance_cache() {
        let p = |x: f64| [x, 0.0, 0.0];
        let d = |v: f64| Some(v);
        // Moves of 5e-5 stay within the tolerance of the last computed position (0.0) until
        // the total exceeds 1e-4 (+ 1e-5·|x|); then the value is recomputed.
        let got = habitat_cached_distances(
            &[p(0.0), p(5e-5), p(1e-4), p(1.5e-4), p(1.5e-4)],
            &[d(3.0), d(2.99995), d(2.9999), d(2.99985), d(2.99985)],
        );
        assert_eq!(got, [d(3.0), d(3.0), d(3.0), d(2.99985), d(2.99985)]);
        // Relative part: at x = 100 the tolerance is 1e-4 + 1e-3.
        let got = habitat_cached_distances(&[p(100.0), p(100.001)], &[d(1.0), d(2.0)]);
        assert_eq!(got, [d(1.0), d(1.0)]);
    }

    fn entry(item_id: &str, label: &str, min: [f64; 2], max: [f64; 2]) -> LabelledBox {
        LabelledBox {
            item_id: item_id.into(),
            label: label.into(),
            min,
            max,
        }
    }

    #[test]
    fn official_priority_matches_substrings() {
        // Keywords match inside the item id or the label, in any case.
        assert_eq!(official_priority("coffee_table_1", "Coffee Table"), 2);
        assert_eq!(official_priority("table_lamp_1", "Table Lamp"), 2);
        assert_eq!(official_priority("reception_desk_2", "Reception Desk"), 2);
        assert_eq!(official_priority("armchair_1", "Armchair"), 3);
        assert_eq!(official_priority("office_chair_3", "Office Chair"), 3);
        assert_eq!(official_priority("tv_screen_1", "TV Screen"), 1);
        // The first group that matches wins: a desk chair ranks with desks.
        assert_eq!(official_priority("desk_chair_1", "Desk Chair"), 2);
        // The furniture group is looked for in the label only.
        assert_eq!(official_priority("big_bookcase_1", "Bookcase"), 4);
        assert_eq!(official_priority("shelf_1", "Rack"), 5);
        assert_eq!(official_priority("unable_area_1", "Unable Area"), 10);
        assert_eq!(official_priority("wall_2", "wall"), 5);
        assert_eq!(official_priority("sofa_1", "Sofa"), 5);
    }

    #[test]
    fn official_box_choice_and_tests() {
        let entries = vec![
            entry("wall_1", "wall", [-10.0, -10.0], [10.0, 10.0]),
            entry("armchair_1", "Armchair", [0.5, 0.5], [1.5, 1.5]),
            entry("coffee_table_1", "Coffee Table", [2.0, 0.0], [3.0, 1.0]),
            entry("desk_1", "Desk", [4.5, 4.5], [5.5, 5.5]),
            entry("bookcase_1", "Bookcase", [0.0, -1.0], [0.2, -0.8]),
        ];
        // The coffee table (priority 2, centre 1.58 m away) beats the armchair (3, 1.12 m) and
        // the wall (5); the desk is more than 2 m away. An exact-category rule would have
        // taken the bookcase (4, 1.27 m).
        let chosen = official_goal_box(&entries, [1.0, 0.0]).unwrap();
        assert_eq!(chosen.item_id, "coffee_table_1");
        assert!(official_goal_box(&entries[3..4], [0.0, 0.0]).is_none());
        // Equal priority: the nearer centre; equal distance too: map order.
        let twins = [
            entry("chair_1", "Chair", [0.0, 0.0], [1.0, 1.0]),
            entry("chair_2", "Chair", [0.0, 0.0], [1.0, 1.0]),
            entry("chair_3", "Chair", [0.2, 0.2], [0.6, 0.6]),
        ];
        let near = official_goal_box(&twins, [0.4, 0.4]).unwrap();
        assert_eq!(near.item_id, "chair_3");
        assert_eq!(
            official_goal_box(&twins[..2], [0.4, 0.4]).unwrap().item_id,
            "chair_1"
        );
        // A repeated item id: the winner is looked up by id, and the last entry holding it wins.
        let repeated = [
            entry("chair_1", "Chair", [0.0, 0.0], [0.4, 0.4]),
            entry("chair_1", "chair", [5.0, 5.0], [6.0, 6.0]),
        ];
        assert_eq!(
            official_goal_box(&repeated, [0.2, 0.2]).unwrap().min,
            [5.0, 5.0]
        );
        let goal = OfficialGoal::Map {
            chosen: Some(chosen),
        };
        let g = [1.0, 0.0];
        assert!(goal.passes(OfficialTest::Success, &[1.0, 0.5], &g));
        assert!(goal.passes(OfficialTest::Success, &[4.0, 2.0], &g));
        assert!(!goal.passes(OfficialTest::Success, &[4.1, 2.0], &g));
        assert!(goal.passes(OfficialTest::Oracle, &[4.1, 2.0], &g));
        let none = OfficialGoal::Map { chosen: None };
        assert!(none.passes(OfficialTest::Success, &[2.0, 0.0], &g));
        assert!(!none.passes(OfficialTest::Success, &[2.01, 0.0], &g));
        let nomap = OfficialGoal::NoMap;
        assert!(!nomap.passes(OfficialTest::Success, &[1.5, 0.0], &g));
        assert!(nomap.passes(OfficialTest::Success, &[1.49, 0.0], &g));
        assert!(!nomap.passes(OfficialTest::Oracle, &[2.5, 0.0], &g));
        assert!(nomap.passes(OfficialTest::Continuous, &[3.0, 0.0], &g));
    }
}
