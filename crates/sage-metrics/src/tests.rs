//! Whole-episode cases computed by hand, one per mode, plus the NoGoal case.

use super::distance::{LabelledBox, official_goal_box};
use super::*;
use std::f64::consts::FRAC_PI_2;

fn step(x: f32, y: f32, yaw: f64, motion: (f32, f32), touch: (bool, f32), geo: f32) -> StepRecord {
    let ((cmd, ach), (contact, c)) = (motion, touch);
    StepRecord {
        position: [x, y, 0.0],
        yaw: yaw as f32,
        time: 0.0,
        commanded: cmd,
        achieved: ach,
        contact,
        intensity: c,
        geodesic_to_goal_point: Some(geo),
    }
}

/// Forward 1 m, turn left, forward blocked after 0.25 m (c = 0.75, touching), turn right (still
/// touching), forward 1 m, STOP. Reference (0,0)→(2,0); goal: a 1 m square at x ∈ [2.5, 3.5].
fn vln_record(official_goal: OfficialGoal) -> EpisodeRecord {
    let h = (1.0f32).hypot(0.25);
    EpisodeRecord {
        episode_id: "e".into(),
        task: Task::Vln,
        start: [0.0, 0.0, 0.0],
        start_yaw: 0.0,
        steps: vec![
            step(1.0, 0.0, 0.0, (1.0, 1.0), (false, 0.0), 1.0),
            step(1.0, 0.0, FRAC_PI_2, (0.0, 0.0), (false, 0.0), 1.0),
            step(1.0, 0.25, FRAC_PI_2, (1.0, 0.25), (true, 0.75), h),
            step(1.0, 0.25, 0.0, (0.0, 0.0), (true, 0.0), h),
            step(2.0, 0.25, 0.0, (1.0, 1.0), (false, 0.0), 0.25),
            step(2.0, 0.25, 0.0, (0.0, 0.0), (false, 0.0), 0.25),
        ],
        stop_called: true,
        reference_path: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        goal: Some(GoalRegion {
            point: [2.0, 0.0],
            footprint: Some(vec![[2.5, -0.5], [3.5, -0.5], [3.5, 0.5], [2.5, 0.5]]),
            heading: None,
        }),
        geodesics: Geodesics {
            start_to_region: Some(2.5),
            final_to_region: Some(0.5),
            start_to_point: Some(2.0),
        },
        official_goal,
        gnbench: None,
    }
}

fn close(a: Option<f64>, b: f64) {
    let a = a.expect("metric defined");
    assert!((a - b).abs() < 1e-6, "{a} != {b}");
}

#[test]
fn sage_mode_by_hand() {
    let m = evaluate(&vln_record(OfficialGoal::NoMap), Mode::Sage).unwrap();
    close(m.tl, 2.25);
    // Final (2, 0.25) is 0.5 m from the square and STOP was called.
    close(m.sr, 1.0);
    close(m.osr, 1.0);
    close(m.ne, 0.5);
    // L* = 2.5 ≥ L = 2.25.
    close(m.spl, 1.0);
    // Contacts F F T T F F: one onset.
    close(m.cr, 1.0);
    close(m.icp, 0.75 / 6.0);
    // Every step within 1 m of the reference; only step 3 has c > 0.
    close(m.csr, 5.0 / 6.0);
    // Heading changes π/2, 0, π/2, 0, 0 → 1 − 1/5.
    close(m.ps, 0.8);
    // Reference resampled to 9 points; agent trace (0,0) (1,0) (1,.25) (2,.25); the optimal
    // alignment costs .25 + .5 + .25 + 0 + .25 + |(.5,.25)| + |(.25,.25)| + .25.
    let d = 1.5 + 0.5f64.hypot(0.25) + 0.25f64.hypot(0.25);
    close(m.ndtw, (-d / 27.0).exp());
    close(m.sdtw, (-d / 27.0).exp());
    assert_eq!(m.episode_time, None);
    close(m.steps, 6.0);
}

#[test]
fn sage_mode_needs_stop_and_radius() {
    let mut r = vln_record(OfficialGoal::NoMap);
    r.stop_called = false;
    let m = evaluate(&r, Mode::Sage).unwrap();
    close(m.sr, 0.0);
    close(m.spl, 0.0);
    close(m.sdtw, 0.0);
    close(m.osr, 1.0);
    // Ending 1.0 m from the square succeeds (≤), 1.01 m does not.
    let mut r = vln_record(OfficialGoal::NoMap);
    r.steps.last_mut().unwrap().position = [1.5, 0.25, 0.0];
    close(evaluate(&r, Mode::Sage).unwrap().sr, 1.0);
    r.steps.last_mut().unwrap().position = [1.49, 0.25, 0.0];
    close(evaluate(&r, Mode::Sage).unwrap().sr, 0.0);
}

#[test]
fn vlnce_mode_by_hand() {
    let m = evaluate(&vln_record(OfficialGoal::NoMap), Mode::Vlnce).unwrap();
    close(m.ne, 0.25);
    close(m.sr, 1.0);
    close(m.osr, 1.0);
    // d0 = 2.0 (geodesic to the point), L = 2.25.
    close(m.spl, 2.0 / 2.25);
    // One blocked translation.
    close(m.cr, 1.0);
    // Dense reference as given (3 points): (0,0)(1,1)(1,2)(2,3) costs 0 + 0 + .25 + .25.
    close(m.ndtw, (-0.5f64 / 9.0).exp());
    // Success is strict: exactly 3.0 m fails. (The STOP step does not move, so the distance
    // is the one computed after step 5.)
    let mut r = vln_record(OfficialGoal::NoMap);
    for s in &mut r.steps[4..] {
        s.geodesic_to_goal_point = Some(3.0);
    }
    let m = evaluate(&r, Mode::Vlnce).unwrap();
    close(m.sr, 0.0);
    close(m.ne, 3.0);
    // Unreachable counts as infinitely far.
    r.steps[4].geodesic_to_goal_point = None;
    assert_eq!(evaluate(&r, Mode::Vlnce).unwrap().ne, Some(f64::INFINITY));
}

fn table_box() -> LabelledBox {
    LabelledBox {
        item_id: "table_1".into(),
        label: "Table".into(),
        min: [2.5, -0.5],
        max: [3.5, 0.5],
    }
}

#[test]
fn official_mode_by_hand() {
    let r = vln_record(OfficialGoal::Map {
        chosen: Some(table_box()),
    });
    // Step 5 ends 0.25 m from g = (2, 0): the published loop stops there, so step 6 (STOP)
    // never happens. 11 samples: reset, then before/after each of the 5 steps.
    assert_eq!(official_auto_stop(&r, Mode::SageOfficial), Some(5));
    let m = evaluate(&r, Mode::SageOfficial).unwrap();
    close(m.steps, 5.0);
    close(m.sr, 1.0);
    close(m.ne, 0.25);
    close(m.osr, 1.0);
    // L* is the straight line start → last reference point (2 m).
    close(m.spl, 2.0 / 2.25);
    // Box grown by 1.5 m starts at x = 1.0: the two samples at the start fail.
    close(m.csr, 9.0 / 11.0);
    // Step 3 achieves 25 % → counter 1 seen by samples 6–9; windows cover samples 6–10.
    close(m.icp, 5.0 / 11.0);
    // Non-zero displacements (1,0) (0,.25) (1,0): a = |(−1,.25)| twice.
    close(m.ps, 1.0 / (1.0 + 10.0 * 1.0f64.hypot(0.25)));
    assert_eq!(m.cr, None);
    assert_eq!(m.ndtw, None);
    // Without a map the 0.5 m radius applies (strict): 0.25 m passes, 0.5 m fails (and is
    // not close enough to stop the episode either).
    let mut r = vln_record(OfficialGoal::NoMap);
    close(evaluate(&r, Mode::SageOfficial).unwrap().sr, 1.0);
    for s in &mut r.steps[4..] {
        s.position = [2.0, 0.5, 0.0];
    }
    assert_eq!(official_auto_stop(&r, Mode::SageOfficial), None);
    close(evaluate(&r, Mode::SageOfficial).unwrap().sr, 0.0);
}

#[test]
fn official_auto_stop_changes_the_result() {
    // The agent passes 0.3 m from g = (2, 0) at step 2, then walks on to (4, 0.3) and stops.
    let mut r = vln_record(OfficialGoal::NoMap);
    r.steps = vec![
        step(1.0, 0.3, 0.0, (1.0, 1.0), (false, 0.0), 1.0),
        step(2.0, 0.3, 0.0, (1.0, 1.0), (false, 0.0), 0.3),
        step(3.0, 0.3, 0.0, (1.0, 1.0), (false, 0.0), 1.0),
        step(4.0, 0.3, 0.0, (1.0, 1.0), (false, 0.0), 2.0),
        step(4.0, 0.3, 0.0, (0.0, 0.0), (false, 0.0), 2.0),
    ];
    let whole = evaluate(&r, Mode::Sage).unwrap();
    close(whole.steps, 5.0);
    let m = evaluate(&r, Mode::SageOfficial).unwrap();
    // Scored as if cut after step 2: success at 0.3 m, NE 0.3, TL to (2, 0.3).
    close(m.steps, 2.0);
    close(m.sr, 1.0);
    close(m.ne, 0.3);
    close(m.tl, 1.0f64.hypot(0.3) + 1.0);
    // Exactly 0.5 m does not stop (the test is strict).
    r.steps[1].position = [2.0, 0.5, 0.0];
    assert_eq!(official_auto_stop(&r, Mode::SageOfficial), None);
    close(evaluate(&r, Mode::SageOfficial).unwrap().sr, 0.0);
    // Other modes and NoGoal episodes are never cut.
    assert_eq!(official_auto_stop(&r, Mode::Vlnce), None);
}

#[test]
fn official_goal_box_choice_changes_the_result() {
    // Near g = (2, 0): a bookcase box 1.0 m away (priority 4 by its label) and a coffee table
    // 1.8 m away, which ranks with tables (2) because "table" is inside its id and label.
    let entries = [
        LabelledBox {
            item_id: "bookcase_1".into(),
            label: "Bookcase".into(),
            min: [1.8, 0.8],
            max: [2.2, 1.2],
        },
        LabelledBox {
            item_id: "coffee_table_1".into(),
            label: "Coffee Table".into(),
            min: [3.5, -0.3],
            max: [4.1, 0.3],
        },
    ];
    let chosen = official_goal_box(&entries, [2.0, 0.0]).unwrap();
    assert_eq!(chosen.item_id, "coffee_table_1");
    // The agent ends at (2, 1.5): inside the bookcase grown by 1 m, not the table.
    let mut r = vln_record(OfficialGoal::Map {
        chosen: Some(chosen),
    });
    r.steps = vec![step(2.0, 1.5, 0.0, (2.5, 2.5), (false, 0.0), 1.5)];
    close(evaluate(&r, Mode::SageOfficial).unwrap().sr, 0.0);
    r.official_goal = OfficialGoal::Map {
        chosen: Some(entries[0].clone()),
    };
    close(evaluate(&r, Mode::SageOfficial).unwrap().sr, 1.0);
}

#[test]
fn zero_shortest_distance_spl() {
    // Start on the goal point (the reference path ends where it starts); the agent steps away
    // and back and stops there.
    let mut r = vln_record(OfficialGoal::NoMap);
    r.reference_path = vec![[0.0, 0.0, 0.0]];
    r.goal = Some(GoalRegion {
        point: [0.0, 0.0],
        footprint: None,
        heading: None,
    });
    r.geodesics = Geodesics {
        start_to_region: Some(0.0),
        final_to_region: Some(0.0),
        start_to_point: Some(0.0),
    };
    r.steps = vec![
        step(0.4, 0.0, 0.0, (0.4, 0.4), (false, 0.0), 0.4),
        step(0.0, 0.0, 0.0, (0.4, 0.4), (false, 0.0), 0.0),
        step(0.0, 0.0, 0.0, (0.0, 0.0), (false, 0.0), 0.0),
    ];
    // SAGE's published formula: SPL = SR when L* = 0 (its auto-stop ends the episode at once).
    let m = evaluate(&r, Mode::SageOfficial).unwrap();
    close(m.sr, 1.0);
    close(m.spl, 1.0);
    // habitat: SR · 0 / max(0, L) = 0 once the agent moved; mode sage does the same.
    close(evaluate(&r, Mode::Vlnce).unwrap().spl, 0.0);
    close(evaluate(&r, Mode::Sage).unwrap().spl, 0.0);
    // Not moving at all: habitat divides 0 by 0 (undefined, left out of the mean); mode sage
    // gives SR.
    r.steps = vec![step(0.0, 0.0, 0.0, (0.0, 0.0), (false, 0.0), 0.0)];
    assert_eq!(evaluate(&r, Mode::Vlnce).unwrap().spl, None);
    close(evaluate(&r, Mode::Sage).unwrap().spl, 1.0);
}

#[test]
fn vlnce_distance_is_cached_like_habitat() {
    // A 5e-5 m creep after step 1 keeps the distance computed there, even though the record
    // holds a (hypothetically) different value: habitat would not have asked the path finder.
    let mut r = vln_record(OfficialGoal::NoMap);
    r.steps = vec![
        step(1.0, 0.0, 0.0, (1.0, 1.0), (false, 0.0), 2.9),
        step(1.000_05, 0.0, 0.0, (1.0, 0.000_05), (true, 1.0), 3.1),
    ];
    r.stop_called = true;
    let m = evaluate(&r, Mode::Vlnce).unwrap();
    close(m.ne, 2.9);
    close(m.sr, 1.0);
    // Beyond the tolerance the new value counts.
    r.steps[1].position = [1.001, 0.0, 0.0];
    close(evaluate(&r, Mode::Vlnce).unwrap().ne, 3.1);
}

#[test]
fn fast_dtw_is_chosen_by_scoring() {
    let r = vln_record(OfficialGoal::NoMap);
    let exact = evaluate(&r, Mode::Vlnce).unwrap();
    let fast = evaluate(
        &r,
        Scoring {
            mode: Mode::Vlnce,
            dtw: Dtw::Fast,
        },
    )
    .unwrap();
    // Short paths fall back to full DTW inside FastDTW: the same number.
    close(fast.ndtw, exact.ndtw.unwrap());
    assert_eq!(fast.sr, exact.sr);
    for d in [Dtw::Exact, Dtw::Fast] {
        assert_eq!(d.as_str().parse::<Dtw>().unwrap(), d);
    }
    assert!("approx".parse::<Dtw>().is_err());
}

#[test]
fn nogoal_by_hand() {
    let mut steps = vec![
        step(0.35, 0.1, 0.0, (0.25, 0.25), (false, 0.0), 0.0),
        step(0.6, 0.1, 0.0, (0.25, 0.25), (false, 0.0), 0.0),
        step(0.6, 0.1, 1.0, (0.0, 0.0), (false, 0.0), 0.0),
        step(0.6, -0.2, 1.0, (0.3, 0.3), (true, 0.2), 0.0),
    ];
    for (k, s) in steps.iter_mut().enumerate() {
        s.time = k as f32 + 1.0;
        s.geodesic_to_goal_point = None;
    }
    let r = EpisodeRecord {
        episode_id: "n".into(),
        task: Task::Nogoal,
        start: [0.1, 0.1, 0.0],
        start_yaw: 0.0,
        steps,
        stop_called: false,
        reference_path: vec![[0.1, 0.1, 0.0]],
        goal: None,
        geodesics: Geodesics::default(),
        official_goal: OfficialGoal::NoMap,
        gnbench: None,
    };
    let m = evaluate(&r, Mode::Sage).unwrap();
    close(m.episode_time, 4.0);
    // Cells (0,0) (0,0) (1,0) (1,0) (1,−1).
    close(m.explored_cells, 3.0);
    close(m.explored_area, 0.75);
    close(m.cr, 1.0);
    assert_eq!(m.sr, None);
    assert_eq!(m.coverage, None);
    let m = evaluate(&r, Mode::SageOfficial).unwrap();
    // Truncation folds y = −0.2 into row 0.
    close(m.explored_cells, 2.0);
    close(m.coverage, 2.0 / 400.0);
}

#[test]
fn vln_without_goal_is_an_error() {
    let mut r = vln_record(OfficialGoal::NoMap);
    r.goal = None;
    let e = evaluate(&r, Mode::Sage).unwrap_err();
    assert!(e.message().contains("episode e"));
    let mut r = vln_record(OfficialGoal::NoMap);
    r.steps.clear();
    let e = evaluate(&r, Mode::Vlnce).unwrap_err();
    assert!(e.message().contains("no step"));
}

#[test]
fn modes_parse_and_aggregate() {
    for m in [Mode::Sage, Mode::Vlnce, Mode::SageOfficial, Mode::GnBench] {
        assert_eq!(m.as_str().parse::<Mode>().unwrap(), m);
    }
    assert!("habitat".parse::<Mode>().is_err());
    let a = evaluate(&vln_record(OfficialGoal::NoMap), Mode::Sage).unwrap();
    let mut r = vln_record(OfficialGoal::NoMap);
    r.stop_called = false;
    let b = evaluate(&r, Mode::Sage).unwrap();
    let agg = aggregate(Mode::Sage, [&a, &b]);
    assert_eq!(agg.episodes, 2);
    assert_eq!(agg.means["sr"], 0.5);
    assert_eq!(agg.means["tl"], 2.25);
    assert!(!agg.means.contains_key("episode_time"));
}

#[test]
fn record_round_trips_as_json() {
    let r = vln_record(OfficialGoal::Map { chosen: None });
    let text = serde_json::to_string(&r).unwrap();
    let back: EpisodeRecord = serde_json::from_str(&text).unwrap();
    assert_eq!(back, r);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn record() -> impl Strategy<Value = EpisodeRecord> {
        let step = (
            (-8i32..8, -8i32..8, -6i32..7),
            (0u8..5, 0u8..5),
            (any::<bool>(), 0u8..5),
            proptest::option::of(0u8..20),
        )
            .prop_map(|((x, y, yaw), (cmd, ach), (contact, c), geo)| {
                let cmd = f32::from(cmd) * 0.1;
                StepRecord {
                    position: [x as f32 * 0.25, y as f32 * 0.25, 0.0],
                    yaw: yaw as f32 * 0.5,
                    time: 0.0,
                    commanded: cmd,
                    achieved: cmd.min(f32::from(ach) * 0.1),
                    contact,
                    intensity: f32::from(c) * 0.25,
                    geodesic_to_goal_point: geo.map(|g| f32::from(g) * 0.5),
                }
            });
        (
            proptest::collection::vec(step, 0..12),
            any::<bool>(),
            proptest::collection::vec((-8i32..8, -8i32..8), 1..6),
        )
            .prop_map(|(steps, stop_called, path)| {
                let reference_path: Vec<[f32; 3]> = path
                    .iter()
                    .map(|&(x, y)| [x as f32 * 0.5, y as f32 * 0.5, 0.0])
                    .collect();
                let end = reference_path[reference_path.len() - 1];
                EpisodeRecord {
                    episode_id: "p".into(),
                    task: Task::Vln,
                    start: [0.0, 0.0, 0.0],
                    start_yaw: 0.0,
                    steps,
                    stop_called,
                    reference_path,
                    goal: Some(GoalRegion {
                        point: [f64::from(end[0]), f64::from(end[1])],
                        footprint: None,
                        heading: None,
                    }),
                    geodesics: Geodesics {
                        start_to_region: Some(2.0),
                        final_to_region: Some(1.0),
                        start_to_point: Some(2.0),
                    },
                    official_goal: OfficialGoal::NoMap,
                    gnbench: None,
                }
            })
    }

    proptest! {
        #[test]
        fn metrics_stay_in_range(r in record()) {
            if r.stop_called && r.steps.is_empty() {
                prop_assert!(evaluate(&r, Mode::Sage).is_err());
                return Ok(());
            }
            for mode in [Mode::Sage, Mode::Vlnce, Mode::SageOfficial] {
                let m = evaluate(&r, mode).unwrap();
                let sr = m.sr.unwrap();
                prop_assert!(sr == 0.0 || sr == 1.0);
                prop_assert!(sr <= m.osr.unwrap());
                prop_assert!(m.spl.unwrap() <= sr && m.spl.unwrap() >= 0.0);
                for v in [m.csr, m.icp, m.ps, m.ndtw].into_iter().flatten() {
                    prop_assert!((0.0..=1.0).contains(&v), "{mode}: {v}");
                }
                if let (Some(s), Some(n)) = (m.sdtw, m.ndtw) {
                    prop_assert!(s <= n);
                }
                prop_assert!(m.tl.unwrap() >= 0.0);
                prop_assert!(m.cr.unwrap_or(0.0) <= r.steps.len() as f64);
            }
        }
    }
}

#[test]
fn pose_goal_needs_the_pose_in_sage_mode() {
    // "Turn 90 degrees to the left in place": the goal is the start point facing +y.
    let mut r = vln_record(OfficialGoal::NoMap);
    r.reference_path = vec![[0.0, 0.0, 0.0]];
    r.goal = Some(GoalRegion {
        point: [0.0, 0.0],
        footprint: None,
        heading: Some(FRAC_PI_2),
    });
    r.geodesics = Geodesics {
        start_to_region: Some(0.0),
        final_to_region: Some(0.0),
        start_to_point: Some(0.0),
    };
    let stop = |yaw: f64| vec![step(0.0, 0.0, yaw, (0.0, 0.0), (false, 0.0), 0.0)];
    // STOP at once: in place, facing the start heading: not the pose asked for.
    r.steps = stop(0.0);
    let m = evaluate(&r, Mode::Sage).unwrap();
    close(m.sr, 0.0);
    close(m.osr, 0.0);
    close(m.spl, 0.0);
    close(m.sdtw, 0.0);
    // Turned as asked (within 10°, across the ±π seam too).
    r.steps = stop(FRAC_PI_2 + 0.1);
    close(evaluate(&r, Mode::Sage).unwrap().sr, 1.0);
    r.goal.as_mut().unwrap().heading = Some(std::f64::consts::PI);
    r.steps = stop(-std::f64::consts::PI + 0.05);
    close(evaluate(&r, Mode::Sage).unwrap().sr, 1.0);
    // Facing right but 0.15 m off the point: more than the pose distance.
    r.steps = vec![step(
        0.15,
        0.0,
        std::f64::consts::PI,
        (0.15, 0.15),
        (false, 0.0),
        0.15,
    )];
    close(evaluate(&r, Mode::Sage).unwrap().sr, 0.0);
}

/// A VLN record for mode `gnbench`: the agent walks along x in 0.25 m steps (turns where `x`
/// repeats), with GN-Bench's raw distance at the start and after each step.
fn gn_record(xs: &[f32], start: Option<f64>, dists: &[Option<f64>], stop: bool) -> EpisodeRecord {
    let mut r = vln_record(OfficialGoal::NoMap);
    let mut prev = 0.0f32;
    r.steps = xs
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            let d = x - prev;
            prev = x;
            let mut s = step(x, 0.0, 0.0, (d, d), (false, 0.0), 1.0);
            s.time = k as f32 + 1.0;
            s
        })
        .collect();
    r.stop_called = stop;
    r.gnbench = Some(GnBenchDistances {
        start,
        steps: dists.to_vec(),
    });
    r
}

#[test]
fn gnbench_success_needs_stop_and_0_lt_d_lt_3() {
    let run = |d: f64, stop: bool| {
        evaluate(
            &gn_record(&[1.0], Some(5.0), &[Some(d)], stop),
            Mode::GnBench,
        )
        .unwrap()
    };
    let m = run(2.99, true);
    assert_eq!((m.sr, m.osr, m.ne), (Some(1.0), Some(1.0), Some(2.99)));
    // SPL = d0 / max(d0, L) = 5 / max(5, 1).
    assert_eq!(m.spl, Some(1.0));
    // Without STOP: no success, the oracle still counts.
    let m = run(2.99, false);
    assert_eq!((m.sr, m.osr, m.spl), (Some(0.0), Some(1.0), Some(0.0)));
    // 3.0 is not below the threshold.
    let m = run(3.0, true);
    assert_eq!((m.sr, m.osr), (Some(0.0), Some(0.0)));
    // Exactly 0 (on the goal's pixel) fails; the oracle counts it.
    let m = run(0.0, true);
    assert_eq!((m.sr, m.osr), (Some(0.0), Some(1.0)));
    // GN-Bench measures no collisions, smoothness or path alignment.
    assert_eq!(
        (m.cr, m.csr, m.icp, m.ps, m.ndtw, m.sdtw),
        (None, None, None, None, None, None)
    );
    assert_eq!(m.tl, Some(1.0));
}

#[test]
fn gnbench_oracle_counts_the_reset_position() {
    let r = gn_record(&[1.0, 2.0], Some(2.5), &[Some(3.5), Some(4.5)], true);
    let m = evaluate(&r, Mode::GnBench).unwrap();
    assert_eq!((m.sr, m.osr, m.ne), (Some(0.0), Some(1.0), Some(4.5)));
    let r = gn_record(&[1.0, 2.0], Some(3.2), &[Some(3.5), Some(4.5)], true);
    assert_eq!(evaluate(&r, Mode::GnBench).unwrap().osr, Some(0.0));
}

#[test]
fn gnbench_spl_against_the_path_taken() {
    // d0 = 4, L = 2 (shorter than d0: the grid distance exceeds the straight line): SPL 1.
    let r = gn_record(&[1.0, 2.0], Some(4.0), &[Some(3.0), Some(2.0)], true);
    close(evaluate(&r, Mode::GnBench).unwrap().spl, 1.0);
    // d0 = 1.5, L = 3 (a detour): SPL = 1.5 / 3.
    let r = gn_record(
        &[1.0, 2.0, 3.0],
        Some(1.5),
        &[Some(2.5), Some(2.6), Some(2.0)],
        true,
    );
    close(evaluate(&r, Mode::GnBench).unwrap().spl, 0.5);
}

#[test]
fn gnbench_distance_is_kept_for_moves_within_1e_4() {
    // The second step moves 5e-5: GN-Bench does not recompute, so the 2.5 recorded there is
    // not read; the start's 3.5 repeats up to the third step's real move.
    let r = gn_record(
        &[0.00005, 0.00005, 1.0],
        Some(3.5),
        &[Some(2.5), Some(2.5), Some(3.2)],
        true,
    );
    let m = evaluate(&r, Mode::GnBench).unwrap();
    assert_eq!((m.osr, m.sr, m.ne), (Some(0.0), Some(0.0), Some(3.2)));
    // A real move (1 m) is measured.
    let r = gn_record(
        &[1.0, 1.0, 2.0],
        Some(3.5),
        &[Some(2.5), Some(2.5), Some(3.2)],
        true,
    );
    assert_eq!(evaluate(&r, Mode::GnBench).unwrap().osr, Some(1.0));
}

#[test]
fn gnbench_forced_stop_cuts_after_26_unchanged_readings() {
    // The agent turns on the spot 2.0 m from the goal and never calls STOP.
    let spin = |n: usize| gn_record(&vec![0.0; n], Some(2.0), &vec![Some(2.0); n], false);
    // 25 turns: readings 0..=24 before steps 1..=25 never exceed 25 repeats: no cut, no STOP.
    let r = spin(25);
    assert_eq!(gnbench_forced_stop(&r, Mode::GnBench).unwrap(), None);
    let m = evaluate(&r, Mode::GnBench).unwrap();
    assert_eq!((m.sr, m.steps), (Some(0.0), Some(25.0)));
    // 26 turns: still none (the reading after the last step forces nothing).
    assert_eq!(gnbench_forced_stop(&spin(26), Mode::GnBench).unwrap(), None);
    // 40 turns: the reading before step 27 is the 26th repeat, so step 27 is a forced STOP,
    // which succeeds 2.0 m from the goal.
    let r = spin(40);
    assert_eq!(gnbench_forced_stop(&r, Mode::GnBench).unwrap(), Some(26));
    let m = evaluate(&r, Mode::GnBench).unwrap();
    assert_eq!((m.sr, m.steps, m.ne), (Some(1.0), Some(27.0), Some(2.0)));
    // Other modes never cut.
    assert_eq!(gnbench_forced_stop(&r, Mode::Vlnce).unwrap(), None);
    assert_eq!(evaluate(&r, Mode::Vlnce).unwrap().steps, Some(40.0));
    // A move that changes the distance resets the count.
    let mut xs = vec![0.0; 20];
    xs.extend(vec![1.0; 20]);
    let mut ds = vec![Some(2.0); 20];
    ds.extend(vec![Some(1.5); 20]);
    let r = gn_record(&xs, Some(2.0), &ds, false);
    assert_eq!(gnbench_forced_stop(&r, Mode::GnBench).unwrap(), None);
}

#[test]
fn gnbench_unreachable_goal_is_infinite_and_averages_as_zero() {
    let r = gn_record(&[1.0], None, &[None], true);
    let m = evaluate(&r, Mode::GnBench).unwrap();
    assert_eq!((m.sr, m.osr), (Some(0.0), Some(0.0)));
    assert_eq!(m.ne, Some(f64::INFINITY));
    assert!(m.spl.unwrap().is_nan());
    let ok = evaluate(
        &gn_record(&[1.0], Some(2.0), &[Some(1.0)], true),
        Mode::GnBench,
    )
    .unwrap();
    // Through JSON (where ∞ and NaN become null) and back, the means are the same: NE and SPL
    // of the unreachable episode count as 0 over both episodes.
    let back: EpisodeMetrics = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
    for bad in [&m, &back] {
        let agg = aggregate(Mode::GnBench, [bad, &ok]);
        assert_eq!(agg.means["ne"], 0.5);
        assert_eq!(agg.means["spl"], 0.5);
        assert_eq!(agg.means["sr"], 0.5);
        assert_eq!(agg.means["tl"], 1.0);
    }
    // Mode vlnce leaves a missing value out of its mean.
    let agg = aggregate(Mode::Vlnce, [&back, &ok]);
    assert_eq!(agg.means["ne"], 1.0);
}

#[test]
fn gnbench_needs_its_distances() {
    let mut r = gn_record(&[1.0], Some(2.0), &[Some(1.0)], true);
    r.gnbench = None;
    let e = evaluate(&r, Mode::GnBench).unwrap_err();
    assert!(e.message().contains("GN-Bench distances"), "{e}");
    r.gnbench = Some(GnBenchDistances {
        start: Some(2.0),
        steps: vec![],
    });
    let e = evaluate(&r, Mode::GnBench).unwrap_err();
    assert!(e.message().contains("gnbench.steps"), "{e}");
    // Other modes do not need them.
    r.gnbench = None;
    evaluate(&r, Mode::Sage).unwrap();
}
