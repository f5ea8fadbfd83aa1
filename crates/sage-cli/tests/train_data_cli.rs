//! `sage3d data render`: a render killed with SIGKILL mid-run resumes to the bytes of an
//! uninterrupted one; skipped episodes are named and set the exit status.

mod common;

use common::{ok, s, sage3d, small_scene};
use std::path::Path;
use std::time::Duration;

/// Every file under `root`, the run record aside.
fn tree(root: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut t = sage_io::files::read_tree(root).unwrap();
    t.remove("sage3d_run.json");
    t
}

/// A one-scene dataset with every episode in `train` (8 trajectories); (scenes, dataset).
fn dataset(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
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
        "8",
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

fn render_args<'a>(data: &'a Path, scenes: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "--threads",
        "1",
        "data",
        "render",
        s(data),
        "--scenes",
        s(scenes),
        "--out",
        s(out),
        "--width",
        "160",
        "--height",
        "120",
        "--sensors",
        "rgb,depth",
        "--format",
        "webdataset",
        "--shard-size",
        "5",
        "--keep-failed",
    ]
}

#[cfg(unix)]
#[test]
fn a_render_killed_mid_run_resumes_to_the_bytes_of_an_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = dataset(dir.path());
    let whole = dir.path().join("whole");
    let printed = ok(&render_args(&data, &scenes, &whole));
    assert!(
        printed.contains("kept") && printed.contains("frames/s"),
        "{printed}"
    );

    let killed = dir.path().join("killed");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_sage3d"))
        .args(render_args(&data, &scenes, &killed))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Kill it as soon as the first walk is complete: later walks are then missing or half
    // written, and no shard or manifest exists yet.
    let images = killed.join("images").join("home1");
    let finished_early = loop {
        let done = std::fs::read_dir(&images).map_or(0, |d| {
            d.filter_map(Result::ok)
                .filter(|e| e.path().join("route.json").is_file())
                .count()
        });
        if done >= 1 {
            break false;
        }
        if child.try_wait().unwrap().is_some() {
            break true;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    assert!(
        !finished_early,
        "the render ended before it could be killed"
    );
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!killed.join("manifest.json").exists());

    let resumed = ok(&render_args(&data, &scenes, &killed));
    assert!(resumed.contains("kept"), "{resumed}");
    assert_eq!(tree(&whole), tree(&killed));
    // A finished render is not redone.
    let again = ok(&render_args(&data, &scenes, &killed));
    assert!(again.contains("already complete"), "{again}");
}

#[test]
fn skipped_episodes_are_named_and_the_exit_status_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = dataset(dir.path());
    let file = data.join("episodes").join("train.jsonl");
    let text = std::fs::read_to_string(&file).unwrap();
    let first = text
        .lines()
        .find(|l| l.contains("\"task\":\"vln\""))
        .unwrap();
    let id = serde_json::from_str::<serde_json::Value>(first).unwrap()["episode_id"]
        .as_str()
        .unwrap()
        .to_string();
    std::fs::write(
        &file,
        text.replacen(first, &first.replace("\"home1\"", "\"cellar\""), 1),
    )
    .unwrap();
    let out = dir.path().join("out");
    // Without --scenes: the scenes folder the dataset records.
    let run = sage3d(&[
        "data",
        "render",
        s(&data),
        "--out",
        s(&out),
        "--width",
        "32",
        "--height",
        "24",
        "--format",
        "frames",
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains(&format!("skipped {id}")) && err.contains("cellar"),
        "{err}"
    );
    assert!(err.contains("1 episodes were skipped"), "{err}");
    // The rest was written, and the manifest lists the skip.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["counts"]["skipped"], 1);
    assert!(out.join("episodes.jsonl").is_file());

    // Bad flags are named before any work; values out of range name the flag the user typed.
    let refused = dir.path().join("bad");
    for (flags, said) in [
        (&["--preset", "tiny"][..], "navila_small"),
        (&["--step", "0"], "--step: 0 m is outside (0, 5]"),
        (&["--turn", "0"], "--turn: 0 degrees is outside (0, 180]"),
        (
            &["--format", "webdataset", "--shard-size", "0"],
            "--shard-size: must be at least 1",
        ),
    ] {
        let mut args = vec![
            "data",
            "render",
            s(&data),
            "--scenes",
            s(&scenes),
            "--out",
            s(&refused),
        ];
        args.extend_from_slice(flags);
        let bad = sage3d(&args);
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains(said),
            "{flags:?}: {err}"
        );
        assert!(!refused.exists());
    }
}

#[test]
fn gvln_and_r2r_files_import_as_a_split_that_renders() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = dataset(dir.path());
    let built = std::fs::read_to_string(data.join("episodes/train.jsonl")).unwrap();
    let imported = dir.path().join("imported");
    let gvln = data.join("gvln/train.json");
    let said = ok(&["data", "import", s(&gvln), "--out", s(&imported)]);
    assert!(said.contains("episodes of 1 scenes"), "{said}");
    let read = std::fs::read_to_string(imported.join("episodes/train.jsonl")).unwrap();
    let ids = |text: &str| -> Vec<String> {
        text.lines()
            .map(|l| {
                serde_json::from_str::<serde_json::Value>(l).unwrap()["episode_id"].to_string()
            })
            .collect()
    };
    assert_eq!(ids(&read), ids(&built));
    // An existing split is not replaced without --force.
    let again = sage3d(&["data", "import", s(&gvln), "--out", s(&imported)]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    ok(&["data", "import", s(&gvln), "--out", s(&imported), "--force"]);
    ok(&[
        "data",
        "import",
        s(&data.join("r2r")),
        "--r2r-split",
        "train",
        "--split",
        "from_r2r",
        "--out",
        s(&imported),
    ]);
    // Both imports are listed as splits; the imported dataset records no scenes folder.
    let listed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(imported.join("splits.json")).unwrap())
            .unwrap();
    let names: Vec<&String> = listed["splits"].as_object().unwrap().keys().collect();
    assert_eq!(names, ["from_r2r", "train"]);
    // The run record lists each import with its source files' hashes.
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(imported.join("sage3d_run.json")).unwrap())
            .unwrap();
    let gvln_hash = sage_io::hash::fnv1a64_hex(&std::fs::read(&gvln).unwrap());
    assert_eq!(record["imports"]["train"]["format"], "gvln", "{record}");
    assert_eq!(
        record["imports"]["train"]["inputs"][gvln.display().to_string()],
        gvln_hash.as_str(),
        "{record}"
    );
    let r2r = &record["imports"]["from_r2r"];
    assert_eq!(r2r["format"], "r2r", "{record}");
    assert!(
        r2r["inputs"]
            .as_object()
            .is_some_and(|f| f.keys().any(|k| k.ends_with("train.json.gz"))),
        "{record}"
    );
    let unplaced = sage3d(&[
        "data",
        "render",
        s(&imported),
        "--split",
        "from_r2r",
        "--out",
        s(&dir.path().join("unplaced")),
    ]);
    let err = String::from_utf8_lossy(&unplaced.stderr);
    assert!(
        !unplaced.status.success()
            && err.contains("the dataset does not record its scenes folder; name it (--scenes)"),
        "{err}"
    );
    // An import naming a scenes folder that lacks the episodes' scene is refused, and writes
    // nothing; one naming theirs is recorded, so a render needs no --scenes.
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir_all(elsewhere.join("other")).unwrap();
    let wrong = sage3d(&[
        "data",
        "import",
        s(&gvln),
        "--out",
        s(&imported),
        "--split",
        "placed",
        "--scenes",
        s(&elsewhere),
    ]);
    assert!(!wrong.status.success());
    assert!(!imported.join("episodes/placed.jsonl").exists());
    ok(&[
        "data",
        "import",
        s(&gvln),
        "--out",
        s(&imported),
        "--split",
        "placed",
        "--scenes",
        s(&scenes),
    ]);
    let out = dir.path().join("out");
    let printed = ok(&[
        "data",
        "render",
        s(&imported),
        "--split",
        "from_r2r",
        "--out",
        s(&out),
        "--limit",
        "4",
        "--width",
        "32",
        "--height",
        "24",
    ]);
    assert!(printed.contains("4 episodes"), "{printed}");
    assert!(out.join("dataset_info.json").is_file());
}

#[test]
fn the_choice_of_splat_bodies_reaches_the_run_record_and_a_resume_must_keep_it() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = dataset(dir.path());
    let render = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "--threads",
            "1",
            "data",
            "render",
            s(&data),
            "--scenes",
            s(&scenes),
            "--out",
            s(out),
            "--width",
            "32",
            "--height",
            "24",
            "--format",
            "frames",
            "--limit",
            "1",
            "--keep-failed",
        ];
        args.extend_from_slice(extra);
        sage3d(&args)
    };
    let settings = |out: &Path| {
        let record: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("sage3d_run.json")).unwrap()).unwrap();
        record["settings"].clone()
    };
    let default = dir.path().join("default");
    assert!(render(&default, &[]).status.success());
    // The default is not written: the records of earlier renders stay as they were.
    assert!(settings(&default).get("splat_bodies").is_none());
    let never = dir.path().join("never");
    let run = render(&never, &["--splat-bodies", "never"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(settings(&never)["splat_bodies"], "never");
    // A rerun with other bodies is another render, not a resume of this one.
    let other = render(&never, &[]);
    assert!(!other.status.success());
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(err.contains("other settings"), "{err}");
    let bad = render(&dir.path().join("bad"), &["--splat-bodies", "sometimes"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("sometimes"));
    // NaVILA's words cannot say 22.5 degrees: refused before anything is written, in flags.
    let halves = dir.path().join("halves");
    let run = render(&halves, &["--answers", "navila", "--turn", "22.5"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{err}");
    assert!(
        err.contains("--answers navila words the turn in whole degrees")
            && err.contains("(--turn)"),
        "{err}"
    );
    assert!(!halves.exists());
}
