//! `sage3d eval` killed with SIGKILL mid-run: its run record says unfinished, which `report`
//! refuses; the rerun of the same command finishes the split with every episode recorded once,
//! each record the line an uninterrupted run writes, the same records file and the same summary
//! and run record bytes.

mod common;

use common::{ok, s, small_scene};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// A one-scene dataset with every episode in `train` (`per_scene` trajectories); (scenes,
/// dataset).
fn dataset(dir: &Path, per_scene: &str) -> (PathBuf, PathBuf) {
    let scenes = dir.join("scenes");
    small_scene(&scenes.join("home1"), "1", "3000");
    let data = dir.join("data");
    ok(&[
        "data",
        "build",
        s(&scenes),
        "--out",
        s(&data),
        "--per-scene",
        per_scene,
        "--seed",
        "2",
        "--scene-unseen",
        "0",
        "--val",
        "0",
        "--balanced",
        "0",
    ]);
    (scenes, data)
}

/// One thread, so records are appended one episode at a time; the seeded random agent walks
/// until the step limit on most episodes, which keeps the run long enough to be caught.
fn eval_args<'a>(data: &'a Path, scenes: &'a Path, run: &'a Path) -> Vec<&'a str> {
    vec![
        "--threads",
        "1",
        "eval",
        s(data),
        "--scenes",
        s(scenes),
        "--split",
        "train",
        "--out",
        s(run),
        "--agent",
        "random",
        "--seed",
        "7",
    ]
}

/// The whole lines of a records file (a cut-short last line is not one).
fn whole_lines(path: &Path) -> usize {
    std::fs::read(path).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count())
}

/// Each record's line by episode id; fails on an id recorded twice.
fn records_by_id(run: &Path) -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(run.join("episodes.jsonl")).unwrap();
    let mut out = BTreeMap::new();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let id = v["episode_id"].as_str().unwrap().to_string();
        assert!(
            out.insert(id.clone(), line.to_string()).is_none(),
            "episode {id} is recorded twice"
        );
    }
    out
}

/// Starts the evaluation into `run` and kills it with SIGKILL once at least one record is
/// written. Returns the whole records it left, or `None` when the run finished before it could
/// be killed.
fn kill_mid_run(data: &Path, scenes: &Path, run: &Path, episodes: usize) -> Option<usize> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_sage3d"))
        .args(eval_args(data, scenes, run))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let records = run.join("episodes.jsonl");
    // Polling, not timing: the loop ends when a record appears or the process exits.
    let finished = loop {
        if whole_lines(&records) >= 1 {
            break false;
        }
        if child.try_wait().unwrap().is_some() {
            break true;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    let left = whole_lines(&records);
    // Caught mid-run only if the summary was never written and episodes are missing.
    (!finished && !run.join("summary.json").exists() && left < episodes).then_some(left)
}

#[cfg(unix)]
#[test]
fn an_eval_killed_mid_run_resumes_to_the_records_and_summary_of_an_uninterrupted_one() {
    // A run that ends before the kill lands is retried bigger, never skipped.
    for (attempt, per_scene) in ["8", "24", "64"].into_iter().enumerate() {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, data) = dataset(dir.path(), per_scene);
        let episodes = std::fs::read_to_string(data.join("episodes/train.jsonl"))
            .unwrap()
            .lines()
            .count();
        let killed = dir.path().join("killed");
        let Some(left) = kill_mid_run(&data, &scenes, &killed, episodes) else {
            eprintln!("attempt {attempt}: {episodes} episodes ended before the kill");
            continue;
        };
        assert!(left >= 1, "the kill came before any record");
        // The folder says it was not finished, and the report says what to do.
        let record = |run: &Path| std::fs::read(run.join("sage3d_run.json")).unwrap();
        let status = |run: &Path| {
            serde_json::from_slice::<serde_json::Value>(&record(run)).unwrap()["status"].clone()
        };
        assert_eq!(status(&killed), "unfinished");
        let report = common::sage3d(&["report", s(&killed)]);
        assert!(
            common::stderr(&report)
                .contains("not finished (its sage3d_run.json has status 'unfinished'): rerun the same `sage3d eval` into it to finish it"),
            "{}",
            common::stderr(&report)
        );

        let resumed = ok(&eval_args(&data, &scenes, &killed));
        assert!(
            resumed.contains(&format!(
                "{episodes} episodes: {left} already recorded, {} run now",
                episodes - left
            )),
            "{resumed}"
        );
        let whole = dir.path().join("whole");
        ok(&eval_args(&data, &scenes, &whole));

        let (a, b) = (records_by_id(&killed), records_by_id(&whole));
        assert_eq!(a.len(), episodes);
        assert_eq!(a, b);
        // The evaluator leaves the records in episode-id order, so the files are the same bytes.
        assert_eq!(
            std::fs::read(killed.join("episodes.jsonl")).unwrap(),
            std::fs::read(whole.join("episodes.jsonl")).unwrap()
        );
        // The summary has no timing field: its bytes must match, as the run records' do.
        assert_eq!(
            std::fs::read(killed.join("summary.json")).unwrap(),
            std::fs::read(whole.join("summary.json")).unwrap()
        );
        assert_eq!(status(&killed), "finished");
        assert_eq!(record(&killed), record(&whole));
        return;
    }
    panic!("every evaluation ended before it could be killed");
}
