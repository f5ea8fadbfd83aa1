//! Hostile and unlucky inputs on the command line: names from data files never leave their
//! folder or share a file, a damaged dataset is refused before any work, and a build that could
//! not write what it was asked to says so in its exit status.

mod common;

use common::{eval, eval_output, ok, s, sage3d, small_build_args, small_dataset, stderr};
use serde_json::Value;
use std::path::Path;

/// The episodes of `data`'s train split, one JSON value per line.
fn train_episodes(data: &Path) -> Vec<Value> {
    std::fs::read_to_string(data.join("episodes").join("train.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Replaces the train split of `data` with `episodes`, listing their ids in splits.json as a
/// split made by hand must be.
fn write_train(data: &Path, episodes: &[Value]) {
    let text: String = episodes.iter().map(|e| format!("{e}\n")).collect();
    std::fs::write(data.join("episodes").join("train.jsonl"), text).unwrap();
    let ids: Vec<&Value> = episodes.iter().map(|e| &e["episode_id"]).collect();
    let listed = data.join("splits.json");
    let mut splits: Value = serde_json::from_slice(&std::fs::read(&listed).unwrap()).unwrap();
    splits["splits"]["train"] = serde_json::json!(ids);
    std::fs::write(&listed, splits.to_string()).unwrap();
}

/// The indices of two train episodes of different walks (start or path differ).
fn two_walks(episodes: &[Value]) -> (usize, usize) {
    let walk = |e: &Value| (e["start"].to_string(), e["reference_path"].to_string());
    let a = episodes
        .iter()
        .position(|e| e["task"] == "vln")
        .expect("a vln episode");
    let b = episodes
        .iter()
        .position(|e| e["task"] == "vln" && walk(e) != walk(&episodes[a]))
        .expect("a second walk");
    (a, b)
}

#[test]
fn a_split_name_never_leaves_the_dataset_or_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let victim = dir.path().join("victim.jsonl");
    std::fs::write(&victim, "mine\n").unwrap();
    // an import under a split name that climbs out of the dataset
    let gvln = data.join("gvln").join("train.json");
    let out = sage3d(&[
        "data",
        "import",
        s(&gvln),
        "--out",
        s(&data),
        "--split",
        "../../victim",
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("--split") && err.contains("split name"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "mine\n");
    // a render of such a split, named on the command line or listed in splits.json
    let render = dir.path().join("render");
    for split in ["../../x", "/tmp/x"] {
        let out = sage3d(&[
            "data",
            "render",
            s(&data),
            "--scenes",
            s(&scenes),
            "--split",
            split,
            "--format",
            "webdataset",
            "--out",
            s(&render),
        ]);
        assert!(!out.status.success(), "{split}");
        assert!(stderr(&out).contains("split name"), "{}", stderr(&out));
    }
    let listed = data.join("splits.json");
    let mut splits: Value = serde_json::from_slice(&std::fs::read(&listed).unwrap()).unwrap();
    splits["splits"]["../x"] = serde_json::json!([]);
    std::fs::write(&listed, splits.to_string()).unwrap();
    let out = eval_output(
        "1",
        &data,
        &scenes,
        &dir.path().join("run"),
        &["--agent", "forward"],
    );
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("split name '../x'"),
        "{}",
        stderr(&out)
    );
    assert!(!dir.path().join("x-000000.tar").exists() && !render.exists());
}

#[test]
fn ids_that_differ_keep_their_own_frames_and_maps() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let mut episodes = train_episodes(&data);
    let (a, b) = two_walks(&episodes);
    episodes[a]["episode_id"] = "r.1".into();
    episodes[b]["episode_id"] = "r_1".into();
    let long = "e".repeat(300);
    let c = (0..episodes.len()).find(|k| *k != a && *k != b).unwrap();
    episodes[c]["episode_id"] = long.as_str().into();
    write_train(&data, &episodes);
    let out = dir.path().join("frames");
    ok(&[
        "data",
        "render",
        s(&data),
        "--scenes",
        s(&scenes),
        "--out",
        s(&out),
        "--width",
        "32",
        "--height",
        "24",
        "--format",
        "frames",
    ]);
    // each episode's record names its own walk: as many frames as its actions, at its start
    let index: Vec<Value> = std::fs::read_to_string(out.join("episodes.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mut routes = std::collections::BTreeSet::new();
    for id in ["r.1", "r_1"] {
        let rec = index
            .iter()
            .find(|r| r["episode_id"] == id)
            .unwrap_or_else(|| panic!("{id} rendered"));
        let files = rec["files"].as_array().unwrap();
        let actions = rec["actions"].as_array().unwrap();
        assert_eq!(files.len(), actions.len(), "{id}");
        routes.insert(rec["route"].as_str().unwrap().to_string());
    }
    assert_eq!(routes.len(), 2, "two walks, two route folders: {routes:?}");
    // a 300-character id is scored and gets its map in the report
    let run = dir.path().join("run");
    eval("1", &data, &scenes, &run, &["--agent", "oracle"]);
    assert!(run.join("report.html").is_file());
    let maps: Vec<String> = std::fs::read_dir(run.join("report").join("maps"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        maps.iter().any(|m| m.starts_with("eeee") && m.len() < 160),
        "{maps:?}"
    );
}

#[test]
fn a_damaged_dataset_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let pristine = train_episodes(&data);
    let run = dir.path().join("run");

    let mut twice = pristine.clone();
    twice[1]["episode_id"] = twice[0]["episode_id"].clone();
    write_train(&data, &twice);
    let out = eval_output("1", &data, &scenes, &run, &["--agent", "forward"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("line 2") && err.contains("given twice (first at line 1)"),
        "{err}"
    );
    assert!(!run.exists(), "nothing is written for a refused dataset");

    // A split file cut short (its list in splits.json left as it was) is refused, not scored
    // as if it were the split.
    write_train(&data, &pristine);
    let file = data.join("episodes").join("train.jsonl");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.lines().next().unwrap()).unwrap();
    let out = eval_output("1", &data, &scenes, &run, &["--agent", "forward"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("train.jsonl")
            && err.contains(&format!(
                "holds 1 episodes where splits.json lists {} for split 'train' ({} missing: ",
                pristine.len(),
                pristine.len() - 1
            )),
        "{err}"
    );
    assert!(!run.exists(), "nothing is written for a refused dataset");

    let mut escaping = pristine.clone();
    escaping[0]["scene"] = "../home1".into();
    write_train(&data, &escaping);
    let out = eval_output("1", &data, &scenes, &run, &["--agent", "forward"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("line 1, scene: scene name '../home1'"),
        "{}",
        stderr(&out)
    );

    // a start far off the map fails its episode with the reason instead of being scored
    // (and, as every failed episode, fails a --strict run)
    let mut far = pristine.clone();
    far[0]["start"]["position"] = serde_json::json!([5000.0, 5000.0, 0.0]);
    write_train(&data, &far);
    let args = ["--agent", "oracle", "--strict"];
    let out = eval_output("1", &data, &scenes, &run, &args);
    assert!(!out.status.success());
    let records = std::fs::read_to_string(run.join("episodes.jsonl")).unwrap();
    let first: Value = records
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .find(|r| r["episode_id"] == far[0]["episode_id"])
        .unwrap();
    assert_eq!(first["failure"], "episode_error", "{first}");
    assert!(
        first["error"]
            .as_str()
            .unwrap()
            .contains("outside the scene's map"),
        "{first}"
    );
}

#[test]
fn a_build_that_cannot_write_a_scene_exits_non_zero_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    // the scene's episode file cannot be written: a folder of the user's stands in its way
    let file = data.join("scenes").join("home1.json");
    std::fs::remove_file(&file).unwrap();
    std::fs::create_dir_all(file.join("in-the-way")).unwrap();
    let args = small_build_args(&scenes, &data);
    let out = sage3d(&args);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("skipped home1") && err.contains("1 of 1 scenes were skipped"),
        "{err}"
    );
    std::fs::remove_dir_all(&file).unwrap();
    ok(&args);
    assert!(file.is_file());
}
