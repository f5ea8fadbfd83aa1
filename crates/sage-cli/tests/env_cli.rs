//! `sage3d env run`: a dataset episode driven by the oracle, one JSON line per step and the
//! metrics at the end; clear errors for a bad agent or episode.

mod common;

use common::{ok, s, sage3d, small_dataset};

#[test]
fn oracle_runs_a_dataset_episode_and_scores_it() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let scene = scenes.join("home1");
    let episodes = data.join("episodes/train.jsonl");
    let first: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(&episodes)
            .unwrap()
            .lines()
            .find(|l| l.contains("\"task\":\"vln\"") && l.contains("\"kind\":\"object\""))
            .expect("an object-goal episode"),
    )
    .unwrap();
    let id = first["episode_id"].as_str().unwrap();
    // `sage3d env run SCENE --episodes FILE` followed by `extra`.
    let base = ["env", "run", s(&scene), "--episodes", s(&episodes)];
    let run = |extra: &[&str]| sage3d(&[&base[..], extra].concat());
    let run_ok = |extra: &[&str]| ok(&[&base[..], extra].concat());
    let out = run_ok(&["--episode", id, "--agent", "oracle"]);
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (last, steps) = lines.split_last().unwrap();
    assert!(!steps.is_empty());
    assert_eq!(steps.last().unwrap()["termination"], "stop");
    assert_eq!(last["episode"], id);
    assert_eq!(last["mode"], "sage");
    let m = &last["metrics"];
    assert_eq!(m["sr"], 1.0, "{out}");
    assert_eq!(m["steps"].as_f64().unwrap() as usize, steps.len());
    assert!(m["spl"].as_f64().unwrap() > 0.5);
    // Rendering the observations does not change the motion.
    let rendered = run_ok(&["--episode", id, "--render"]);
    assert_eq!(rendered, out);
    // The same run scored as VLN-CE and as the published code.
    for mode in ["vlnce", "sage-official"] {
        let out = run_ok(&["--episode", id, "--mode", mode]);
        let last: serde_json::Value = serde_json::from_str(out.lines().last().unwrap()).unwrap();
        assert_eq!(last["mode"], mode);
        assert!(last["metrics"]["ne"].as_f64().unwrap() < 1.5, "{out}");
    }
    // GN-Bench's camera (480×360 RGB rendered at every step) and its metrics.
    let out = run_ok(&[
        "--episode",
        id,
        "--mode",
        "gnbench",
        "--preset",
        "gnbench",
        "--render",
    ]);
    let last: serde_json::Value = serde_json::from_str(out.lines().last().unwrap()).unwrap();
    assert_eq!(last["mode"], "gnbench");
    assert!(last["metrics"]["osr"].as_f64().is_some(), "{out}");
    assert!(last["metrics"]["cr"].is_null(), "{out}");
    // The bodies a user chose with `physics build --splat-bodies`: the scene's objects have
    // meshes, so `never` (boxes only where nothing better exists) walks the same way.
    assert_eq!(
        run_ok(&["--episode", id, "--splat-bodies", "never"]),
        rendered
    );
    let bad = run(&["--splat-bodies", "sometimes"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("sometimes"));
    let bad = run(&["--agent", "genius"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--agent 'genius'"));
    let bad = run(&["--episode", "nope"]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("no episode 'nope'"));
}

#[test]
fn bench_env_reports_each_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let out = ok(&[
        "bench",
        "env",
        "--objects",
        "30",
        "--gaussians",
        "2000",
        "--steps",
        "300",
        "--render-steps",
        "3",
        "--sizes",
        "16x12",
        "--cache",
        s(dir.path()),
    ]);
    assert!(out.contains("machine"), "{out}");
    assert!(
        out.contains("no rendering") && out.contains("steps/s"),
        "{out}"
    );
    assert!(out.contains("16x12"), "{out}");
}
