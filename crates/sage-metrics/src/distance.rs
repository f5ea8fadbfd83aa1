//! Path length, distances to the goal and to the reference path, and the success tests of the
//! three modes (SPEC §10, §10.1).

use super::dtw::euclidean;
use serde::{Deserialize, Serialize};

/// Success radius of mode `sage` (metres; the test is `≤`).
pub const SAGE_SUCCESS_DISTANCE: f64 = 1.0;
/// Success radius of mode `vlnce` (metres; the test is strict `<`, as VLN-CE codes it).
pub const VLNCE_SUCCESS_DISTANCE: f64 = 3.0;
/// Tolerance around the reference path for CSR in mode `sage` (metres).
pub const CSR_TOLERANCE: f64 = 1.0;

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
}

impl GoalRegion {
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

/// An axis-aligned box of the published semantic map (`bbox_m`, here in the W frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LabelledBox {
    /// The map entry's label (`table`, `wall`, `unable`, …).
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
    /// No semantic map loaded: plain distance to the goal point against the goal radius 0.5 m.
    NoMap,
    /// A map is loaded: its "smart position" entry (see [`official_goal_box`]), or `None` when
    /// no entry lies within 2 m of the goal point (then distance to the goal point is used).
    Map {
        /// The chosen entry.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        chosen: Option<LabelledBox>,
    },
}

/// Priority of a semantic-map label in the published "smart position" fallback (lower first).
fn official_priority(label: &str) -> u32 {
    let l = label.to_ascii_lowercase();
    match l.as_str() {
        "screen" | "projector" => 1,
        "table" | "desk" => 2,
        "chair" => 3,
        "unable" => 10,
        _ if ["furniture", "cabinet", "shelf", "bookcase"]
            .iter()
            .any(|w| l.contains(w)) =>
        {
            4
        }
        _ => 5,
    }
}

/// The published code's choice of goal box: among entries whose box centre is ≤ 2.0 m from the
/// goal point (walls and unable areas included), the lowest priority, then the nearest; ties
/// keep map order.
pub fn official_goal_box(entries: &[LabelledBox], goal: [f64; 2]) -> Option<LabelledBox> {
    entries
        .iter()
        .filter(|e| euclidean(&e.centre(), &goal) <= 2.0)
        .min_by(|a, b| {
            official_priority(&a.label)
                .cmp(&official_priority(&b.label))
                .then(euclidean(&a.centre(), &goal).total_cmp(&euclidean(&b.centre(), &goal)))
        })
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
                OfficialTest::Success => d < 0.5,
                OfficialTest::Oracle => d < 1.5,
                OfficialTest::Continuous => d <= 2.0,
            },
            OfficialGoal::Map { chosen: Some(b) } => b.contains_expanded(p, e),
            OfficialGoal::Map { chosen: None } => d <= e,
        }
    }
}

/// SPL = SR · L* / max(L*, L); SR itself when L* = 0 (both paths empty).
pub fn spl(success: bool, shortest: f64, taken: f64) -> f64 {
    if !success {
        return 0.0;
    }
    let denom = shortest.max(taken);
    if denom <= 0.0 { 1.0 } else { shortest / denom }
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
        };
        assert_eq!(g.distance(&[1.0, 1.0]), 0.0);
        assert_eq!(g.distance(&[3.0, 1.0]), 1.0);
        // The closing edge counts.
        assert_eq!(g.distance(&[-0.5, 1.0]), 0.5);
        assert_eq!(g.distance(&[5.0, 6.0]), 5.0);
        let p = GoalRegion {
            point: [1.0, 1.0],
            footprint: None,
        };
        assert_eq!(p.distance(&[4.0, 5.0]), 5.0);
    }

    #[test]
    fn spl_cases() {
        assert_eq!(spl(true, 4.0, 5.0), 0.8);
        assert_eq!(spl(true, 4.0, 3.0), 1.0);
        assert_eq!(spl(false, 4.0, 4.0), 0.0);
        assert_eq!(spl(true, 0.0, 0.0), 1.0);
    }

    #[test]
    fn official_box_choice_and_tests() {
        let b = |label: &str, min: [f64; 2], max: [f64; 2]| LabelledBox {
            label: label.into(),
            min,
            max,
        };
        let entries = vec![
            b("wall", [-10.0, -10.0], [10.0, 10.0]),
            b("chair", [0.5, 0.5], [1.5, 1.5]),
            b("table", [2.0, 0.0], [3.0, 1.0]),
            b("desk", [4.5, 4.5], [5.5, 5.5]),
            b("bookcase_big", [0.0, -1.0], [0.2, -0.8]),
        ];
        // Table (priority 2, centre 1.58 m away) beats chair (3) and the wall (5); the desk is
        // more than 2 m away.
        let chosen = official_goal_box(&entries, [1.0, 0.0]).unwrap();
        assert_eq!(chosen.label, "table");
        assert!(official_goal_box(&entries[3..4], [0.0, 0.0]).is_none());
        // Priority: furniture-like labels rank 4, before the default 5 and `unable` 10.
        assert_eq!(official_priority("Bookcase_big"), 4);
        assert_eq!(official_priority("unable"), 10);
        assert_eq!(official_priority("sofa"), 5);
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
