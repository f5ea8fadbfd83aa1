//! `sage3d eval`: the oracle solves every VLN episode of a dataset; the summary and the records
//! file do not depend on the thread count; a run cut short (lines lost, last line half-written)
//! resumes to the same files with every episode recorded once; the scenes folder comes from the
//! dataset unless `--scenes` says otherwise; splits are those the dataset lists; bad input gives
//! clear errors.

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

    // Two threads: records finish in another order, the files are the same bytes (the records
    // end sorted by episode id).
    let two = dir.path().join("two");
    eval("2", &data, &scenes, &two, &["--agent", "oracle"]);
    assert_eq!(
        read(&two.join("summary.json")),
        read(&one.join("summary.json"))
    );
    assert_eq!(
        read(&two.join("episodes.jsonl")),
        read(&one.join("episodes.jsonl"))
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
        read(&two.join("episodes.jsonl")),
        read(&one.join("episodes.jsonl"))
    );
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

    // Nor on other scene files: the record holds the hash of every file of each scene, and a
    // file changed since is named.
    let inputs = run["scene_inputs"].as_object().unwrap();
    let (name, files) = inputs.iter().next().unwrap();
    assert!(
        files.get("labels.json").is_some()
            && files
                .as_object()
                .unwrap()
                .keys()
                .any(|f| f.starts_with("3dgs")),
        "{run}"
    );
    let labels = scenes.join(name).join("labels.json");
    let text = read(&labels);
    std::fs::write(&labels, format!("{text}\n")).unwrap();
    let changed = eval_output("1", &data, &scenes, &one, &["--agent", "oracle"]);
    let e = String::from_utf8_lossy(&changed.stderr);
    assert!(
        !changed.status.success() && e.contains(&format!("{name}/labels.json changed since")),
        "{e}"
    );
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
        e.contains("missing") && e.contains("no such dataset folder"),
        "{e}"
    );
    let e = err(&scenes, "train", "oracle");
    assert!(e.contains("not a dataset folder"), "{e}");
    let e = err(&data, "tset", "oracle");
    assert!(
        e.contains("unknown split 'tset'") && e.contains("train, val"),
        "{e}"
    );
    // An empty split (one scene: no validation scenes) is an error naming the splits that hold
    // episodes; no run folder is made.
    let e = err(&data, "val", "oracle");
    assert!(
        e.contains("split 'val' has no episodes (splits with episodes: train)"),
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
        stderr.contains("every episode of the run faulted") && stderr.contains("scene_load"),
        "{stderr}"
    );
    assert!(
        stdout.starts_with("FAULTED: "),
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
    assert!(out.starts_with(&format!("FAULTED: {failed} of ")), "{out}");
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

#[test]
fn eval_runs_in_the_scenes_the_dataset_records_unless_told_otherwise() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let eval_in = |scenes: Option<&Path>, split: &str, run: &Path| {
        let mut args = vec!["eval", s(&data), "--split", split, "--agent", "forward"];
        args.extend(["--out", s(run)]);
        if let Some(scenes) = scenes {
            args.extend(["--scenes", s(scenes)]);
        }
        sage3d(&args)
    };
    let stderr = |out: &std::process::Output| String::from_utf8_lossy(&out.stderr).into_owned();
    // Without --scenes: the recorded folder, the same run as with it.
    let (recorded, given) = (dir.path().join("recorded"), dir.path().join("given"));
    let out = eval_in(None, "train", &recorded);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(eval_in(Some(&scenes), "train", &given).status.success());
    for f in ["episodes.jsonl", "summary.json"] {
        assert_eq!(read(&recorded.join(f)), read(&given.join(f)), "{f}");
    }
    // --scenes overrides the record: a folder without the dataset's scene is refused.
    let others = dir.path().join("others");
    small_scene(&others.join("office9"), "3", "1000");
    let e = stderr(&eval_in(Some(&others), "train", &dir.path().join("o")));
    assert!(
        e.contains("scene 'home1'") && e.contains("not among the scenes"),
        "{e}"
    );

    // Splits are those splits.json lists: a stray *.jsonl is not one.
    let train = read(&data.join("episodes/train.jsonl"));
    let first = train.lines().next().unwrap();
    std::fs::write(data.join("episodes/notes.jsonl"), format!("{first}\n")).unwrap();
    let e = stderr(&eval_in(None, "notes", &dir.path().join("n")));
    assert!(
        e.contains("unknown split 'notes' (this dataset has: test_balanced, test_instruction_unseen, test_scene_unseen, test_trajectory_unseen, train, val)"),
        "{e}"
    );

    // The recorded folder gone: a clear error naming it.
    let moved = dir.path().join("scenes_moved");
    std::fs::rename(&scenes, &moved).unwrap();
    let e = stderr(&eval_in(None, "train", &dir.path().join("m")));
    assert!(
        e.contains("the recorded scenes folder")
            && e.contains("does not exist; name the scenes folder (--scenes)"),
        "{e}"
    );

    // A dataset written before the list and the record: every *.jsonl is a split, and the
    // scenes must be given.
    std::fs::remove_file(data.join("splits.json")).unwrap();
    std::fs::remove_file(data.join("sage3d_run.json")).unwrap();
    let e = stderr(&eval_in(None, "train", &dir.path().join("l")));
    assert!(
        e.contains("the dataset does not record its scenes folder; name it (--scenes)"),
        "{e}"
    );
    let legacy = dir.path().join("legacy");
    let out = eval_in(Some(&moved), "notes", &legacy);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(read(&legacy.join("episodes.jsonl")).lines().count(), 1);
}

#[test]
fn eval_scores_as_gn_bench_with_its_preset() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("gn");
    let args = [
        "--agent", "oracle", "--mode", "gnbench", "--preset", "gnbench",
    ];
    let out = eval("1", &data, &scenes, &run, &args);
    assert!(out.contains("overall"), "{out}");
    let summary: serde_json::Value =
        serde_json::from_str(&read(&run.join("summary.json"))).unwrap();
    assert_eq!(summary["mode"], "gnbench");
    let settings: serde_json::Value =
        serde_json::from_str(&read(&run.join("sage3d_run.json"))).unwrap();
    assert_eq!(settings["settings"]["preset"], "gnbench");
    let mut vln = 0;
    for l in read(&run.join("episodes.jsonl")).lines() {
        let r: serde_json::Value = serde_json::from_str(l).unwrap();
        if r["task"] != "vln" {
            continue;
        }
        vln += 1;
        // A distance per position, from the occupancy image, and GN-Bench's metrics only.
        let d = &r["record"]["gnbench"];
        assert_eq!(
            d["steps"].as_array().unwrap().len(),
            r["record"]["steps"].as_array().unwrap().len(),
            "{l}"
        );
        let m = &r["metrics"];
        assert!(
            m["osr"].as_f64().is_some() && m["sr"].as_f64().is_some(),
            "{l}"
        );
        for absent in ["cr", "csr", "icp", "ps", "ndtw", "sdtw"] {
            assert!(m[absent].is_null(), "{absent}: {l}");
        }
    }
    assert!(vln >= 3);
    let bad = eval_output(
        "1",
        &data,
        &scenes,
        &dir.path().join("bad"),
        &["--agent", "oracle", "--mode", "gn"],
    );
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("gnbench"));
}

#[test]
fn a_run_finds_its_scenes_from_anywhere_and_notes_scenes_changed_since_the_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, _) = small_dataset(dir.path());
    // Folders named relative to where the evaluation runs.
    let in_dir = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_sage3d"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    let args = |out: &'static str| {
        [
            "--threads",
            "1",
            "eval",
            "data",
            "--scenes",
            "scenes",
            "--split",
            "train",
            "--agent",
            "forward",
            "--out",
            out,
        ]
    };
    let first = in_dir(&args("run"));
    assert!(first.status.success(), "{}", common::stderr(&first));
    assert!(!common::stderr(&first).contains("note: scene files changed"));
    // The report and the viewer's run, from another working directory, find the scenes.
    let run = dir.path().join("run");
    std::fs::remove_file(run.join("report.html")).unwrap();
    common::ok(&["report", s(&run)]);
    assert!(run.join("report.html").is_file());
    // A scene file the dataset was built from, changed since: the evaluation says so.
    let structure = scenes.join("home1").join("structure.json");
    let text = read(&structure);
    std::fs::write(&structure, format!("{text}\n")).unwrap();
    let second = in_dir(&args("run2"));
    assert!(second.status.success(), "{}", common::stderr(&second));
    assert!(
        common::stderr(&second).contains(
            "note: scene files changed since the dataset was built (home1/structure.json changed)"
        ),
        "{}",
        common::stderr(&second)
    );
}
