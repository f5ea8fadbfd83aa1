//! `sage3d data build` end to end: the dataset folder, the same bytes with 1 and 2 threads, the
//! summary, resume, its GVLN files imported back as the same episodes, and a clear error for a
//! bad folder.

mod common;

use common::{ok, s, sage3d, small_scene, stderr};
use sage_io::files::read_tree;
use std::collections::BTreeMap;
use std::path::Path;

#[test]
fn build_writes_the_dataset_deterministically_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    for seed in ["1", "2", "3"] {
        small_scene(&scenes.join(format!("home{seed}")), seed, "1000");
    }
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let args = |out: &Path, threads: &str| {
        vec![
            "--threads".to_string(),
            threads.into(),
            "data".into(),
            "build".into(),
            s(&scenes).into(),
            "--out".into(),
            s(out).into(),
            "--per-scene".into(),
            "4".into(),
            "--seed".into(),
            "5".into(),
            "--balanced".into(),
            "10".into(),
        ]
    };
    let run = |v: Vec<String>| ok(&v.iter().map(String::as_str).collect::<Vec<_>>());
    let printed = run(args(&a, "1"));
    assert!(
        printed.contains("3 scenes: 3 done") && printed.contains("validator|"),
        "{printed}"
    );
    run(args(&b, "2"));
    assert_eq!(read_tree(&a).unwrap(), read_tree(&b).unwrap());
    for f in [
        "summary.json",
        "summary.txt",
        "splits.json",
        "sage3d_run.json",
        "episodes/train.jsonl",
        "gvln/train.json",
        "r2r/train/train.json.gz",
        "r2r/train/train_gt.json.gz",
    ] {
        assert!(a.join(f).is_file(), "{f}");
    }
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("summary.json")).unwrap()).unwrap();
    assert!(summary["episodes"].as_u64().unwrap() > 10);
    assert!(summary["by_type"]["Single-Goal"].as_u64().unwrap() > 0);
    let again = run(args(&a, "2"));
    assert!(again.contains("3 already complete"), "{again}");
    assert_eq!(read_tree(&a).unwrap(), read_tree(&b).unwrap());
}

/// The GVLN files a build writes import back as the episodes they were written from, byte for
/// byte: Base-Action turns keep their goal heading and actions, every episode its geodesic
/// distance, lengths and slices (our keys beside the published fields), no-goal starts their
/// headings; and a negative zero is written as 0.0.
#[test]
fn gvln_files_of_a_build_import_as_the_same_episodes() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    small_scene(&scenes.join("home1"), "1", "1000");
    let data = dir.path().join("data");
    let build = [
        "data",
        "build",
        s(&scenes),
        "--out",
        s(&data),
        "--per-scene",
        "3",
        "--seed",
        "2",
        "--base-actions",
        "8",
        "--nogoal",
        "2",
    ];
    ok(&build);
    let lines = |file: &Path| -> BTreeMap<String, String> {
        std::fs::read_to_string(file)
            .unwrap()
            .lines()
            .map(|l| {
                let v: serde_json::Value = serde_json::from_str(l).unwrap();
                (v["episode_id"].as_str().unwrap().to_string(), l.to_string())
            })
            .collect()
    };
    let mut compared = 0;
    let mut turns = 0;
    for split in ["train", "val", "test_scene_unseen", "test_balanced"] {
        let gvln = data.join(format!("gvln/{split}.json"));
        let built = lines(&data.join(format!("episodes/{split}.jsonl")));
        if built.is_empty() {
            continue;
        }
        let name = format!("back_{split}");
        ok(&[
            "data",
            "import",
            s(&gvln),
            "--out",
            s(&data),
            "--split",
            &name,
        ]);
        let back = lines(&data.join(format!("episodes/{name}.jsonl")));
        assert_eq!(built, back, "{split}");
        compared += built.len();
        // Turns in place: one point, a goal heading, turns before STOP.
        turns += built
            .values()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|e| {
                e["reference_path"].as_array().unwrap().len() == 1
                    && e["goal"]["yaw"].is_number()
                    && e["actions"].as_array().unwrap().len() > 1
            })
            .count();
        assert!(built.values().all(|l| !l.contains(":-0.0")), "{split}");
    }
    assert!(compared > 10, "{compared}");
    assert!(turns > 0, "no turn in place among the episodes");
    // A rerun of the build keeps the imported splits listed, and their sources recorded.
    ok(&build);
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(data.join(name)).unwrap()).unwrap()
    };
    assert!(read("splits.json")["splits"]["back_train"].is_array());
    assert_eq!(
        read("sage3d_run.json")["imports"]["back_train"]["format"],
        "gvln"
    );
    ok(&[
        "eval",
        s(&data),
        "--split",
        "back_train",
        "--agent",
        "oracle",
        "--out",
        s(&dir.path().join("run")),
    ]);
}

#[test]
fn build_names_a_folder_without_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let out = sage3d(&[
        "data",
        "build",
        s(dir.path()),
        "--out",
        s(&dir.path().join("o")),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("neither a scene folder"), "{err}");
}

/// `--length-mix` reaches the sampler: all-short gives only short reference paths (each scene
/// records the mix it was built with), and a mix without a share per bin is refused before any
/// work.
#[test]
fn build_takes_a_length_mix() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "4", "1000");
    let out = dir.path().join("o");
    ok(&[
        "data",
        "build",
        s(&scene),
        "--out",
        s(&out),
        "--per-scene",
        "4",
        "--length-mix",
        "1,0,0",
    ]);
    let file: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("scenes/home.json")).unwrap()).unwrap();
    assert_eq!(
        file["settings"]["trajectories"]["sampling"]["length_mix"],
        serde_json::json!([1.0, 0.0, 0.0])
    );
    let paths: Vec<&str> = file["episodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["task"] == "vln" && e["instruction_type"] != "Base-Action")
        .map(|e| e["slices"]["path"].as_str().unwrap())
        .collect();
    assert!(
        !paths.is_empty() && paths.iter().all(|p| *p == "short"),
        "{paths:?}"
    );
    let bad = sage3d(&[
        "data",
        "build",
        s(&scene),
        "--out",
        s(&dir.path().join("bad")),
        "--length-mix",
        "0.4,0.6",
    ]);
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--length-mix needs 3 shares"), "{err}");
    assert!(!dir.path().join("bad").exists());
}

#[test]
fn build_plans_for_the_agent_profile_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = sage3d(&[
        "data",
        "build",
        s(dir.path()),
        "--out",
        s(&dir.path().join("o")),
        "--agent",
        "uav",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--agent") && err.contains("ground agents"),
        "{err}"
    );
    assert!(!dir.path().join("o").exists());
}

#[test]
fn build_refuses_counts_past_its_bounds_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    common::small_scene(&scenes.join("home1"), "1", "1000");
    let out = dir.path().join("o");
    for flag in [
        "--per-scene",
        "--nogoal",
        "--base-actions",
        "--high-per-type",
    ] {
        let o = sage3d(&[
            "data",
            "build",
            s(&scenes),
            "--out",
            s(&out),
            flag,
            "100001",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{flag}: {err}");
        assert!(
            err.contains(&format!("{flag} must be at most 100000 per scene")),
            "{flag}: {err}"
        );
        assert!(!out.exists(), "{flag}");
    }
}

#[test]
fn build_never_writes_over_files_it_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    common::small_scene(&scenes.join("home1"), "1", "1000");
    let out = dir.path().join("mine");
    std::fs::create_dir_all(out.join("episodes")).unwrap();
    std::fs::write(out.join("episodes").join("train.jsonl"), "my own file\n").unwrap();
    std::fs::write(out.join("notes.txt"), "mine\n").unwrap();
    let build = |force: bool| {
        let mut args = vec![
            "data",
            "build",
            s(&scenes),
            "--out",
            s(&out),
            "--per-scene",
            "2",
        ];
        if force {
            args.push("--force");
        }
        sage3d(&args)
    };
    for force in [false, true] {
        let run = build(force);
        assert!(!run.status.success());
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(err.contains("did not write"), "{err}");
    }
    assert_eq!(
        std::fs::read_to_string(out.join("episodes").join("train.jsonl")).unwrap(),
        "my own file\n"
    );
    // Beside files of the user's own names --force writes, and a rerun resumes.
    std::fs::remove_dir_all(out.join("episodes")).unwrap();
    assert!(!build(false).status.success());
    assert!(build(true).status.success());
    assert!(build(false).status.success());
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine\n"
    );
}

/// A build killed while it assembled the dataset leaves its run record (written before the
/// work, unfinished), some split files and no `splits.json`: no command takes that folder
/// for a dataset (by the old rule, every `episodes/*.jsonl` a split), each names the folder
/// and says to rerun the build, and the rerun finishes it.
#[test]
fn a_killed_build_is_refused_until_rerun_finishes_it() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = common::small_dataset(dir.path());
    let finished = read_tree(&data).unwrap();
    // The state a kill in the assembly leaves: the record as the build writes it first, the
    // scene files, the split files written so far, nothing after them.
    let record_path = data.join("sage3d_run.json");
    let mut record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&record_path).unwrap()).unwrap();
    assert_eq!(record["status"], "finished");
    record["status"] = "unfinished".into();
    std::fs::write(&record_path, record.to_string()).unwrap();
    for f in ["splits.json", "summary.json", "summary.txt"] {
        std::fs::remove_file(data.join(f)).unwrap();
    }
    for split in ["test_balanced", "test_trajectory_unseen", "train", "val"] {
        std::fs::remove_file(data.join("episodes").join(format!("{split}.jsonl"))).unwrap();
    }
    let refused = |args: &[&str]| {
        let out = sage3d(args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let e = common::stderr(&out);
        assert!(
            e.contains(&format!(
                "{}: the `sage3d data build` of this folder has not finished",
                data.display()
            )) && e.contains("rerun `sage3d data build` into this folder to finish it"),
            "{args:?}: {e}"
        );
    };
    let run = dir.path().join("run");
    refused(&[
        "eval",
        s(&data),
        "--agent",
        "oracle",
        "--split",
        "test_scene_unseen",
        "--out",
        s(&run),
    ]);
    refused(&["eval", s(&data), "--agent", "oracle", "--out", s(&run)]);
    assert!(!run.exists());
    let train = dir.path().join("train");
    refused(&["data", "render", s(&data), "--out", s(&train)]);
    assert!(!train.exists());
    let parquet = dir.path().join("split.parquet");
    refused(&[
        "data",
        "export",
        s(&data),
        "--split",
        "test_scene_unseen",
        "--out",
        s(&parquet),
    ]);
    assert!(!parquet.exists());
    // The viewer refuses it before it listens: a taken port would fail it otherwise.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    refused(&["view", s(&data), "--port", &port]);
    // Rerunning the build finishes the folder: the same dataset as the build that was not
    // killed, and it evaluates.
    ok(&common::small_build_args(&scenes, &data));
    assert_eq!(read_tree(&data).unwrap(), finished);
    ok(&[
        "eval",
        s(&data),
        "--agent",
        "oracle",
        "--split",
        "train",
        "--out",
        s(&run),
    ]);
}

/// A GVLN file as SAGE-Bench publishes it (no `frame`, none of sage3d's instruction keys) holds
/// no asset counts: imported with `--scenes`, its episodes take their scene's asset slice
/// (`many`: more than 376 objects in `labels.json`); without, they stay `medium` and the import
/// says so.
#[test]
fn a_published_gvln_file_takes_its_scenes_asset_slice() {
    use sage_dataset::formats::gvln::encode_rotation;
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    ok(&[
        "scene",
        "synth",
        "--seed",
        "3",
        "--rooms",
        "24",
        "--objects",
        "450",
        "--gaussians",
        "1000",
        "--out",
        s(&scenes.join("big")),
    ]);
    // A walk along +x in S (offset 0), every point 0.5 m up as the published files put them.
    let points: Vec<serde_json::Value> = (0..5)
        .map(|i| {
            let rotation = if i == 4 {
                [0.0, 0.0, 0.0, 1.0]
            } else {
                encode_rotation(0.0)
            };
            let x = 1.0 + 0.25 * i as f32;
            serde_json::json!({"point": i.to_string(), "position": [x, 0.5, 0.5],
                "rotation": rotation, "action": [], "camera_images": []})
        })
        .collect();
    let file = dir.path().join("published.json");
    let published = serde_json::json!({"scenes": [{"scene_id": "big", "scene_name": "big",
        "samples": [{"trajectory_id": "0", "instructions": [{"instruction_type": "Scenario_Driven",
            "start": "sofa_1", "end": "table_1", "generated_instruction": "Walk to the table.",
            "scene_id": "big"}], "points": points}]}]});
    std::fs::write(&file, published.to_string()).unwrap();
    let assets = |data: &Path| -> Vec<String> {
        std::fs::read_to_string(data.join("episodes/train.jsonl"))
            .unwrap()
            .lines()
            .map(|l| {
                let e: serde_json::Value = serde_json::from_str(l).unwrap();
                e["slices"]["assets"].as_str().unwrap().to_string()
            })
            .collect()
    };
    let with = dir.path().join("with");
    let out = sage3d(&[
        "data",
        "import",
        s(&file),
        "--out",
        s(&with),
        "--scenes",
        s(&scenes),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("asset slice"), "{}", stderr(&out));
    assert_eq!(assets(&with), ["many"]);
    let without = dir.path().join("without");
    let out = sage3d(&["data", "import", s(&file), "--out", s(&without)]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("asset slice `medium` for 1 episodes")
            && stderr(&out).contains("no --scenes"),
        "{}",
        stderr(&out)
    );
    assert_eq!(assets(&without), ["medium"]);
}
