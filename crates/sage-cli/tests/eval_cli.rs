//! `sage3d eval`: the oracle solves every VLN episode of a dataset; the summary does not depend
//! on the thread count; a run cut short (lines lost, last line half-written) resumes to the same
//! summary with every episode recorded once; bad input gives clear errors.

mod common;

use common::{eval, eval_output, s, sage3d, small_dataset, small_scene};
use std::path::Path;

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

fn ids(run: &Path) -> Vec<String> {
    let mut ids: Vec<String> = read(&run.join("episodes.jsonl"))
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["episode_id"].as_str().unwrap().to_string()
        })
        .collect();
    ids.sort();
    ids
}

#[test]
fn oracle_solves_the_vln_episodes_independent_of_threads_and_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let n_episodes = read(&data.join("episodes/train.jsonl")).lines().count();
    let one = dir.path().join("one");
    let out = eval("1", &data, &scenes, &one, &["--agent", "oracle"]);
    assert!(
        out.contains("overall") && out.contains("instruction_type"),
        "{out}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&read(&one.join("summary.json"))).unwrap();
    assert_eq!(summary["mode"], "sage");
    assert_eq!(summary["episodes"], n_episodes);
    assert_eq!(
        summary["slices"]["task"]["vln"]["means"]["sr"], 1.0,
        "{summary}"
    );
    let mut vln = 0;
    for l in read(&one.join("episodes.jsonl")).lines() {
        let r: serde_json::Value = serde_json::from_str(l).unwrap();
        if r["task"] == "vln" {
            vln += 1;
            assert_eq!(r["metrics"]["sr"], 1.0, "{l}");
            assert_eq!(r["termination"], "stop");
        }
    }
    assert!(vln >= 3);
    assert_eq!(ids(&one).len(), n_episodes);
    let run: serde_json::Value = serde_json::from_str(&read(&one.join("sage3d_run.json"))).unwrap();
    assert_eq!(run["settings"]["agent"], "oracle");
    assert!(run["dataset_hash"].as_str().is_some());

    // Two threads: records finish in another order, the summary is the same bytes.
    let two = dir.path().join("two");
    eval("2", &data, &scenes, &two, &["--agent", "oracle"]);
    assert_eq!(
        read(&two.join("summary.json")),
        read(&one.join("summary.json"))
    );
    assert_eq!(ids(&two), ids(&one));

    // A crash: two whole lines lost and the last one cut in half; the rerun finishes the rest.
    let records = two.join("episodes.jsonl");
    let text = read(&records);
    let lines: Vec<&str> = text.lines().collect();
    let last = lines[lines.len() - 1];
    let cut = format!(
        "{}\n{}\n{}",
        lines[0],
        lines[3..lines.len() - 1].join("\n"),
        &last[..last.len() / 2]
    );
    std::fs::write(&records, cut).unwrap();
    std::fs::remove_file(two.join("summary.json")).unwrap();
    let out = eval("2", &data, &scenes, &two, &["--agent", "oracle"]);
    assert!(out.contains("3 run now"), "{out}");
    assert_eq!(ids(&two), ids(&one));
    assert_eq!(
        read(&two.join("summary.json")),
        read(&one.join("summary.json"))
    );
    // Nothing left to do: a rerun runs nothing and writes the same summary.
    let out = eval("1", &data, &scenes, &two, &["--agent", "oracle"]);
    assert!(out.contains("0 run now"), "{out}");
    assert_eq!(
        read(&two.join("summary.json")),
        read(&one.join("summary.json"))
    );

    // The seeded random agent: same summary with 1 and 2 threads.
    let (r1, r2) = (dir.path().join("r1"), dir.path().join("r2"));
    let random = ["--agent", "random", "--seed", "7", "--mode", "vlnce"];
    eval("1", &data, &scenes, &r1, &random);
    eval("2", &data, &scenes, &r2, &random);
    assert_eq!(
        read(&r1.join("summary.json")),
        read(&r2.join("summary.json"))
    );
    assert!(read(&r1.join("summary.json")).contains("\"mode\": \"vlnce\""));

    // A run folder resumes only the same run.
    let other = eval_output("1", &data, &scenes, &one, &["--agent", "forward"]);
    assert!(!other.status.success());
    assert!(String::from_utf8_lossy(&other.stderr).contains("other settings"));
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    let err = |dataset: &Path, split: &str, agent: &str| {
        let out = sage3d(&[
            "eval",
            s(dataset),
            "--scenes",
            s(&scenes),
            "--split",
            split,
            "--agent",
            agent,
            "--out",
            s(&run),
        ]);
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = err(&dir.path().join("missing"), "train", "oracle");
    assert!(
        e.contains("missing") && e.contains("not a dataset folder"),
        "{e}"
    );
    let e = err(&data, "tset", "oracle");
    assert!(
        e.contains("unknown split 'tset'") && e.contains("train, val"),
        "{e}"
    );
    // An empty split is an error naming the splits that hold episodes; no run folder is made.
    std::fs::write(data.join("episodes/empty.jsonl"), "").unwrap();
    let e = err(&data, "empty", "oracle");
    assert!(
        e.contains("split 'empty' has no episodes") && e.contains("train") && !e.contains("empty,"),
        "{e}"
    );
    assert!(!run.exists(), "no run folder for an empty split");
    let e = err(&data, "train", "genius");
    assert!(
        e.contains("--agent 'genius'") && e.contains("random, forward, oracle"),
        "{e}"
    );
    // The episodes' scene is not among the scenes given.
    let others = dir.path().join("others");
    small_scene(&others.join("office9"), "3", "1000");
    let out = sage3d(&[
        "eval",
        s(&data),
        "--scenes",
        s(&others),
        "--split",
        "train",
        "--agent",
        "oracle",
        "--out",
        s(&run),
    ]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && e.contains("scene 'home1'") && e.contains("not among the scenes"),
        "{e}"
    );
    assert!(!run.exists(), "no run folder for bad input");
}

#[test]
fn a_scene_that_cannot_be_loaded_fails_its_episodes_and_the_run_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    std::fs::write(scenes.join("home1/structure.json"), "{\"rooms\": 3}").unwrap();
    let run = dir.path().join("run");
    // Nothing could be scored: the run is written, and says so in its exit status.
    let out = eval_output("2", &data, &scenes, &run, &["--agent", "forward"]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!out.status.success(), "{stdout}");
    assert!(
        stderr.contains("every episode of the run failed") && stderr.contains("scene_load"),
        "{stderr}"
    );
    assert!(
        stdout.starts_with("FAILED: "),
        "the failures come first: {stdout}"
    );
    let records: Vec<serde_json::Value> = read(&run.join("episodes.jsonl"))
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(!records.is_empty());
    for r in &records {
        let e = r["error"].as_str().unwrap();
        assert!(
            e.contains("structure.json") && e.contains("scene home1"),
            "{e}"
        );
        assert!(r.get("metrics").is_none());
    }
    let summary: serde_json::Value =
        serde_json::from_str(&read(&run.join("summary.json"))).unwrap();
    assert_eq!(summary["failed"].as_array().unwrap().len(), records.len());
    assert_eq!(
        summary["failures"],
        serde_json::json!({"scene_load": records.len()})
    );
    assert!(records.iter().all(|r| r["failure"] == "scene_load"));
}

#[test]
fn strict_fails_a_run_with_any_failed_episode() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    // The oracle cannot act on no-goal episodes (they have no goal): some fail, most are scored.
    let lenient = dir.path().join("lenient");
    let out = eval("2", &data, &scenes, &lenient, &["--agent", "oracle"]);
    let summary: serde_json::Value =
        serde_json::from_str(&read(&lenient.join("summary.json"))).unwrap();
    let failed = summary["failed"].as_array().unwrap().len();
    assert!(failed > 0 && failed < summary["episodes"].as_u64().unwrap() as usize);
    assert_eq!(
        summary["failures"],
        serde_json::json!({"episode_error": failed})
    );
    assert!(out.starts_with(&format!("FAILED: {failed} of ")), "{out}");
    let strict = dir.path().join("strict");
    let run = eval_output(
        "2",
        &data,
        &scenes,
        &strict,
        &["--agent", "oracle", "--strict"],
    );
    let e = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && e.contains(&format!("{failed} of")) && e.contains("--strict"),
        "{e}"
    );
    // The run folder is complete all the same: the same summary as the lenient run.
    assert_eq!(
        read(&strict.join("summary.json")),
        read(&lenient.join("summary.json"))
    );
}
