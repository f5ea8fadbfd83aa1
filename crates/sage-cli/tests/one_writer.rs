//! One writer per folder: a command refuses at once, naming the holder and exiting 1, a folder
//! that another process holds the lock on (here the test process itself, through the same
//! `sage_io::lock` API), and runs once it is released; temporary files that an interrupted
//! earlier run left in its folder never stop a rerun, with or without `--force`, and are gone
//! after it.

mod common;

use common::{eval, eval_output, ok, s, sage3d, small_build_args, small_dataset, stderr};
use sage_io::lock::{FolderLock, LOCK_FILE};
use std::path::Path;
use std::process::Output;

/// Asserts that `out` is the refusal of a folder held by this process as `command`.
fn refused_by_holder(out: &Output, command: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("being written by the `{command}` run"))
            && err.contains(&format!("process {}", std::process::id())),
        "{err}"
    );
}

/// Writes the temporary files an interrupted write would leave at `rels` under `root`.
fn leave_temporary(root: &Path, rels: &[&str]) {
    for rel in rels {
        let p = root.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, "half-written").unwrap();
    }
}

#[test]
fn eval_report_and_build_refuse_a_held_folder_and_reruns_remove_leftover_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    let oracle = ["--agent", "oracle"];

    let held = FolderLock::acquire(&run, "eval").unwrap();
    refused_by_holder(&eval_output("1", &data, &scenes, &run, &oracle), "eval");
    assert!(!run.join("episodes.jsonl").exists() && !run.join("sage3d_run.json").exists());
    drop(held);
    eval("1", &data, &scenes, &run, &oracle);
    assert!(run.join("summary.json").is_file() && !run.join(LOCK_FILE).exists());

    let held = FolderLock::acquire(&run, "eval").unwrap();
    refused_by_holder(&sage3d(&["report", s(&run)]), "eval");
    drop(held);

    let stale = [
        ".summary.json.tmp-4242-7",
        ".report.html.tmp-4242-8",
        "report/maps/.home1-t0-0.png.tmp-4242-9",
    ];
    for force in [false, true] {
        leave_temporary(&run, &stale);
        let extra: &[&str] = if force {
            &["--agent", "oracle", "--force"]
        } else {
            &oracle
        };
        let out = eval_output("1", &data, &scenes, &run, extra);
        assert!(out.status.success(), "{}", stderr(&out));
        for rel in stale {
            assert!(!run.join(rel).exists(), "{rel} left (force: {force})");
        }
    }
    leave_temporary(&run, &stale);
    ok(&["report", s(&run)]);
    for rel in stale {
        assert!(!run.join(rel).exists(), "{rel} left by report");
    }
    assert!(!run.join(LOCK_FILE).exists());

    let held = FolderLock::acquire(&data, "data build").unwrap();
    let out = sage3d(&small_build_args(&scenes, &data));
    refused_by_holder(&out, "data build");
    drop(held);
}

#[test]
fn data_render_refuses_a_held_folder_and_reruns_over_leftover_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let out = dir.path().join("train");
    let render = |force: bool| {
        let mut args = vec![
            "--threads",
            "1",
            "data",
            "render",
            s(&data),
            "--scenes",
            s(&scenes),
            "--out",
            s(&out),
            "--split",
            "train",
            "--width",
            "64",
            "--height",
            "48",
            "--sensors",
            "rgb",
            "--limit",
            "2",
        ];
        if force {
            args.push("--force");
        }
        sage3d(&args)
    };

    let held = FolderLock::acquire(&out, "data render").unwrap();
    refused_by_holder(&render(false), "data render");
    assert!(!out.join("sage3d_run.json").exists());
    drop(held);
    let first = render(false);
    assert!(first.status.success(), "{}", stderr(&first));
    assert!(out.join("manifest.json").is_file() && !out.join(LOCK_FILE).exists());

    // What a SIGINT during the final writes leaves behind.
    let stale = [
        ".annotations_part_000.json.tmp-4242-7",
        ".manifest.json.tmp-4242-8",
    ];
    for force in [false, true] {
        leave_temporary(&out, &stale);
        let again = render(force);
        assert!(again.status.success(), "force {force}: {}", stderr(&again));
        assert!(
            String::from_utf8_lossy(&again.stdout).contains("already complete"),
            "{}",
            String::from_utf8_lossy(&again.stdout)
        );
        for rel in stale {
            assert!(!out.join(rel).exists(), "{rel} left (force: {force})");
        }
    }
}
