//! Mutation fuzzing of the benchmark's JSON and JSONL readers — dataset episodes (JSONL),
//! GVLN and R2R-VLNCE imports, evaluation records and replay files: damaged files give an `Err`
//! naming the file and the line or field — never a panic, never an endless walk — and the
//! writers' output reads back as what was written.
//! Run longer with `PROPTEST_CASES=10000 cargo test --release -p sage-eval --test json_fuzz`.

use glam::Vec2;
use proptest::prelude::*;
use sage_agents::replay::{ReplayFile, Sequence};
use sage_core::{Error, ErrorKind};
use sage_dataset::episode::MAX_COORDINATE;
use sage_dataset::formats::gvln::{self, GvlnFrame};
use sage_dataset::formats::{jsonl, r2r};
use sage_dataset::slices::Slices;
use sage_dataset::{Episode, Goal, StartPose, Task};
use sage_eval::EvalRecord;
use sage_eval::records::{self, Appender};
use sage_lang::actions::{StepSizes, follow};
use sage_lang::{InstructionType, Level, Source};
use sage_testkit::{Edit, edit, mutate, mutate_bytes};
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::Path;

/// A VLN episode of trajectory `trajectory` walking the polyline `corners` (floor points, W frame) from heading `yaw`,
/// with a reference path as dense as a built dataset's (a point every 0.25 m at most).
fn episode(trajectory: usize, corners: &[[f32; 2]], yaw: f32, instruction: &str) -> Episode {
    let mut flat = vec![Vec2::from(corners[0])];
    for w in corners.windows(2) {
        let (a, b) = (Vec2::from(w[0]), Vec2::from(w[1]));
        let n = (a.distance(b) / 0.25).ceil().max(1.0) as usize;
        flat.extend((1..=n).map(|i| a.lerp(b, i as f32 / n as f32)));
    }
    let length: f32 = flat.windows(2).map(|w| w[0].distance(w[1])).sum();
    let points: Vec<[f32; 3]> = flat.iter().map(|p| [p.x, p.y, 0.0]).collect();
    Episode {
        episode_id: format!("home1-t{trajectory}-0"),
        scene: "home1".into(),
        task: Task::Vln,
        trajectory_id: Some(trajectory),
        instruction: instruction.into(),
        instruction_texts: Default::default(),
        level: Some(Level::Low),
        instruction_type: InstructionType::SingleGoal,
        subtype: None,
        source: Source::Imported,
        start_ref: Some("door_1".into()),
        start: StartPose {
            position: points[0],
            yaw,
        },
        goal: Some(Goal {
            reference: "sofa_2".into(),
            kind: "object".into(),
            position: *points.last().unwrap(),
            yaw: None,
        }),
        actions: follow(&flat, yaw, None, &StepSizes::default()).unwrap(),
        reference_path: points,
        path_length: length,
        geodesic_distance: length,
        slices: Slices {
            assets: "medium".into(),
            path: "short".into(),
        },
    }
}

/// Three episodes, one per trajectory.
fn fixture_episodes() -> Vec<Episode> {
    vec![
        episode(
            0,
            &[[0.0, 0.0], [1.0, 0.0], [1.5, 1.0]],
            0.3,
            "walk to the sofa",
        ),
        episode(1, &[[2.0, 1.0], [2.0, 3.0]], -1.0, "go up"),
        episode(
            2,
            &[[-1.0, -1.0], [0.0, -2.5], [1.0, -2.5]],
            2.0,
            "then right",
        ),
    ]
}

/// Asserts that `e` names `file` and, for a format error, a place in it.
fn assert_names(e: &Error, file: &Path) {
    assert_eq!(e.file(), Some(file), "{e}");
    assert!(!e.message().is_empty(), "{e}");
    assert!(
        e.kind() != ErrorKind::Format || !e.location().is_empty(),
        "no line or field: {e}"
    );
}

/// `text` (JSON lines) with one line's document edited and the bytes then edited.
fn mutate_line(text: &str, line: usize, edits: &[Edit]) -> Vec<u8> {
    let lines: Vec<&str> = text.lines().collect();
    let k = line % lines.len();
    // Node edits go to the chosen line; byte edits apply to the whole file afterwards.
    let (node, bytes): (Vec<Edit>, Vec<Edit>) = edits
        .iter()
        .cloned()
        .partition(|e| matches!(e, Edit::Replace { .. } | Edit::Remove { .. }));
    let mut out: Vec<u8> = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        if i == k {
            out.extend(mutate(l.as_bytes(), &node));
        } else {
            out.extend_from_slice(l.as_bytes());
        }
        out.push(b'\n');
    }
    mutate_bytes(out, &bytes)
}

fn jsonl_text() -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("e.jsonl");
    jsonl::write(&p, &fixture_episodes()).unwrap();
    std::fs::read_to_string(p).unwrap()
}

fn record(id: &str, agent: &str) -> EvalRecord {
    EvalRecord {
        episode_id: id.into(),
        scene: "home1".into(),
        task: Task::Vln,
        level: Some(Level::Low),
        instruction_type: InstructionType::SingleGoal,
        slices: Slices {
            assets: "few".into(),
            path: "short".into(),
        },
        agent: agent.into(),
        termination: None,
        metrics: None,
        error: Some("no path".into()),
        failure: None,
        faults: Vec::new(),
        notes: Vec::new(),
        record: None,
        bodies: Default::default(),
    }
}

const RECORD_IDS: [&str; 4] = ["a", "b", "c", "d"];

const REPLAY: &str = concat!(
    r#"{"episode_id": "a", "actions": ["move_forward", "TURN_LEFT", 1, {"type": "turn_right"}, "stop"]}"#,
    "\n",
    r#"{"episode_id": "b", "actions": [0]}"#,
    "\n",
);

const REPLAY_POSES: &str = concat!(
    r#"{"episode_id": "a", "poses": [[0, 0, 0.1], [0.5, 0.2, 0, 0.3]]}"#,
    "\n",
    r#"{"episode_id": "b", "actions": [{"type": "velocity", "vx": 0.3, "vy": 0, "wz": 0.1, "dt": 0.5}]}"#,
    "\n",
);

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn mutated_episode_files_never_panic(line in any::<usize>(), edits in prop::collection::vec(edit(), 1..4)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("train.jsonl");
        std::fs::write(&p, mutate_line(&jsonl_text(), line, &edits)).unwrap();
        match jsonl::read(&p) {
            Ok(eps) => {
                for e in &eps {
                    prop_assert!(e.check().is_ok());
                }
            }
            Err(e) => {
                assert_names(&e, &p);
                prop_assert!(e.kind() != ErrorKind::Format || e.location().starts_with("line ") || e.location() == "encoding", "{}", e);
            }
        }
    }

    #[test]
    fn episode_files_round_trip(
        paths in prop::collection::vec(
            (prop::collection::vec(prop::array::uniform2(-20.0f32..20.0), 2..6), -3.1f32..3.1, "\\PC{0,40}"),
            1..5,
        ),
    ) {
        let eps: Vec<Episode> = paths
            .iter()
            .enumerate()
            .map(|(i, (path, yaw, text))| episode(i, path, *yaw, text))
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("e.jsonl");
        jsonl::write(&p, &eps).unwrap();
        prop_assert_eq!(jsonl::read(&p).unwrap(), eps);
    }

    #[test]
    fn mutated_gvln_files_never_panic(world in any::<bool>(), edits in prop::collection::vec(edit(), 1..4)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("gvln.json");
        let frame = if world {
            GvlnFrame::World
        } else {
            GvlnFrame::Sage(sage_core::frame::SageFrame { offset: Vec2::new(3.5, -1.25) })
        };
        let space = StepSizes::default();
        gvln::write(&p, &fixture_episodes(), frame, &space).unwrap();
        let bytes = mutate(&std::fs::read(&p).unwrap(), &edits);
        std::fs::write(&p, bytes).unwrap();
        match gvln::read(&p, Vec2::ZERO, &space) {
            Ok(eps) => {
                for e in &eps {
                    prop_assert!(e.check().is_ok(), "{:?}", e.check());
                }
            }
            Err(e) => assert_names(&e, &p),
        }
    }

    #[test]
    fn mutated_r2r_files_never_panic(gt in any::<bool>(), edits in prop::collection::vec(edit(), 1..4)) {
        let dir = tempfile::tempdir().unwrap();
        let space = StepSizes::default();
        r2r::write(dir.path(), "train", &fixture_episodes(), &space).unwrap();
        let (main, gt_path) = r2r::paths(dir.path(), "train");
        // The episodes file or the ground-truth file, gzip-compressed again after the edit.
        let target = if gt { &gt_path } else { &main };
        let mut text = String::new();
        std::io::Read::read_to_string(
            &mut flate2::read::GzDecoder::new(std::fs::File::open(target).unwrap()),
            &mut text,
        )
        .unwrap();
        let bytes = mutate(text.as_bytes(), &edits);
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut gz, &bytes).unwrap();
        std::fs::write(target, gz.finish().unwrap()).unwrap();
        match r2r::read(dir.path(), "train", &space) {
            Ok(eps) => {
                for e in &eps {
                    prop_assert!(e.check().is_ok(), "{:?}", e.check());
                }
            }
            Err(e) => {
                prop_assert!(e.file() == Some(main.as_path()) || e.file() == Some(gt_path.as_path()), "{}", e);
                prop_assert!(e.kind() != ErrorKind::Format || !e.location().is_empty(), "{}", e);
            }
        }
    }

    #[test]
    fn mutated_records_never_panic_and_a_resumed_file_reads_whole(
        line in any::<usize>(),
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("episodes.jsonl");
        {
            let mut w = Appender::open(&p).unwrap();
            for id in ["c", "a", "d"] {
                w.append(&record(id, "oracle")).unwrap();
            }
        }
        let text = std::fs::read_to_string(&p).unwrap();
        let bytes = mutate_line(&text, line, &edits);
        let ids: BTreeSet<&str> = RECORD_IDS.into();
        // The strict reader (end of a run) and the lenient one (resume), each on its own copy.
        let strict = dir.path().join("strict.jsonl");
        std::fs::write(&strict, &bytes).unwrap();
        if let Err(e) = records::sort(&strict, &ids) {
            assert_names(&e, &strict);
            prop_assert!(e.kind() != ErrorKind::Format || e.location().starts_with("line "), "{}", e);
        }
        std::fs::write(&p, &bytes).unwrap();
        match records::resume(&p, &ids) {
            // What resume keeps is a whole records file: every line reads, each id once.
            Ok(done) => {
                let all = records::sort(&p, &ids).unwrap();
                let read_ids: BTreeSet<String> = all.iter().map(|r| r.episode_id.clone()).collect();
                prop_assert_eq!(read_ids, done);
            }
            Err(e) => {
                assert_names(&e, &p);
                prop_assert!(e.kind() != ErrorKind::Format || e.location().starts_with("line "), "{}", e);
            }
        }
    }

    #[test]
    fn records_round_trip(agents in prop::collection::vec("\\PC{0,12}", 1..4)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("episodes.jsonl");
        let written: Vec<EvalRecord> = agents.iter().zip(RECORD_IDS).map(|(a, id)| record(id, a)).collect();
        {
            let mut w = Appender::open(&p).unwrap();
            for r in written.iter().rev() {
                w.append(r).unwrap();
            }
        }
        let ids: BTreeSet<&str> = RECORD_IDS.into();
        prop_assert_eq!(records::sort(&p, &ids).unwrap(), written.clone());
        // Sorting rewrote the file in id order; it reads back the same.
        prop_assert_eq!(records::sort(&p, &ids).unwrap(), written);
    }

    #[test]
    fn mutated_replay_files_never_panic(
        poses in any::<bool>(),
        line in any::<usize>(),
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("replay.jsonl");
        let text = if poses { REPLAY_POSES } else { REPLAY };
        std::fs::write(&p, mutate_line(text, line, &edits)).unwrap();
        match ReplayFile::read(&p) {
            Ok(f) => {
                // Every sequence read holds finite numbers only.
                for id in RECORD_IDS {
                    if let Some(Sequence::Poses(ps)) = f.get(id) {
                        prop_assert!(ps.iter().flatten().all(|n| n.is_finite()));
                    }
                }
            }
            Err(e) => {
                assert_names(&e, &p);
                prop_assert!(e.kind() != ErrorKind::Format || e.location().starts_with("line "), "{}", e);
            }
        }
    }
}

#[test]
fn the_replay_fixtures_read() {
    for text in [REPLAY, REPLAY_POSES] {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("replay.jsonl");
        std::fs::write(&p, text).unwrap();
        let f = ReplayFile::read(&p).unwrap();
        assert!(f.get("a").is_some() && f.get("b").is_some());
    }
}

#[test]
fn huge_and_infinite_numbers_are_errors_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let space = StepSizes::default();
    // A coordinate far beyond any scene: reading it must fail, not walk toward it for ever.
    let p = dir.path().join("e.jsonl");
    std::fs::write(
        &p,
        jsonl_text().replacen("[0.0,0.0,0.0]", "[0.0,1e39,0.0]", 1),
    )
    .unwrap();
    let e = jsonl::read(&p).unwrap_err();
    assert_names(&e, &p);
    assert!(e.to_string().contains("line 1, start.position"), "{e}");

    let g = dir.path().join("g.json");
    gvln::write(&g, &fixture_episodes(), GvlnFrame::World, &space).unwrap();
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&g).unwrap()).unwrap();
    doc["scenes"][0]["samples"][1]["points"][1]["position"][0] = serde_json::json!(1e9);
    std::fs::write(&g, doc.to_string()).unwrap();
    let e = gvln::read(&g, Vec2::ZERO, &space).unwrap_err();
    assert_names(&e, &g);
    assert!(
        e.to_string()
            .contains("scenes[0].samples[1].points[1].position")
            && e.to_string().contains(&format!("{MAX_COORDINATE}")),
        "{e}"
    );

    // R2R without its ground truth: the reader follows the path itself.
    r2r::write(dir.path(), "x", &fixture_episodes(), &space).unwrap();
    let (main, gt) = r2r::paths(dir.path(), "x");
    std::fs::remove_file(gt).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(
        &mut flate2::read::GzDecoder::new(std::fs::File::open(&main).unwrap()),
        &mut text,
    )
    .unwrap();
    let mut doc: Value = serde_json::from_str(&text).unwrap();
    doc["episodes"][2]["reference_path"][1][2] = serde_json::json!(1e39);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut gz, doc.to_string().as_bytes()).unwrap();
    std::fs::write(&main, gz.finish().unwrap()).unwrap();
    let e = r2r::read(dir.path(), "x", &space).unwrap_err();
    assert_names(&e, &main);
    assert!(
        e.to_string().contains("episodes[2].reference_path[1]"),
        "{e}"
    );

    let r = dir.path().join("replay.jsonl");
    std::fs::write(
        &r,
        r#"{"episode_id": "a", "actions": [{"type": "velocity", "vx": 1e39, "vy": 0, "wz": 0, "dt": 1}]}"#,
    )
    .unwrap();
    let e = ReplayFile::read(&r).unwrap_err();
    assert_names(&e, &r);
    assert!(
        e.to_string().contains("line 1, actions[0]") && e.to_string().contains("finite"),
        "{e}"
    );

    // A finite pose far outside any scene is refused as it is read, naming the pose; it used
    // to fail mid-episode as a velocity command the robot could not have.
    std::fs::write(
        &r,
        "{\"episode_id\": \"a\", \"actions\": [\"stop\"]}\n{\"episode_id\": \"b\", \"poses\": [[0, 0, 0], [1e9, 0, 0]]}",
    )
    .unwrap();
    let e = ReplayFile::read(&r).unwrap_err();
    assert_names(&e, &r);
    assert!(
        e.to_string().contains("line 2, poses[1]") && e.to_string().contains("10000"),
        "{e}"
    );
}
