//! A run folder a command was killed in is still that command's own: `eval` records itself
//! unfinished until its summary and report are written, and `report` refuses such a run,
//! saying to rerun the evaluation; a rescoring killed part-way (`report RUN --mode M --out
//! NEW`) is redone by the same command, `--force` or not, and refused once finished; runs
//! recorded before the status existed read as finished; an `eval` into a run folder of other
//! settings names the run record and the settings that differ.

mod common;

use common::{eval, eval_output, ok, s, sage3d, small_dataset, stderr};
use std::path::Path;

/// The run record of `run`.
fn record(run: &Path) -> serde_json::Value {
    sage_io::files::read_json(&run.join("sage3d_run.json")).unwrap()
}

/// Writes the run record of `from` into `to` with the status `status` (`None`: none, as before
/// the status existed).
fn write_record(from: &Path, to: &Path, status: Option<&str>) {
    let mut r = record(from);
    match status {
        Some(status) => r["status"] = status.into(),
        None => {
            r.as_object_mut().unwrap().remove("status");
        }
    }
    std::fs::create_dir_all(to).unwrap();
    sage_io::files::write_json(&to.join("sage3d_run.json"), &r).unwrap();
}

/// The bytes of the files a run folder holds at its top (records, summary, run record, page).
fn outputs(run: &Path) -> Vec<Vec<u8>> {
    [
        "episodes.jsonl",
        "summary.json",
        "sage3d_run.json",
        "report.html",
    ]
    .iter()
    .map(|name| std::fs::read(run.join(name)).unwrap())
    .collect()
}

#[test]
fn a_rescoring_killed_part_way_is_redone_by_the_same_command_and_refused_once_finished() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    eval("2", &data, &scenes, &run, &["--agent", "random"]);
    let rescore = |out: &Path, force: bool| {
        let mut args = vec!["report", s(&run), "--mode", "vlnce", "--out", s(out)];
        if force {
            args.push("--force");
        }
        sage3d(&args)
    };
    let whole = dir.path().join("whole");
    assert!(rescore(&whole, false).status.success());
    assert_eq!(record(&whole)["status"], "finished");

    // Killed after its records and summary, before its page; killed after its records alone.
    for (name, files, force) in [
        (
            "after_summary",
            &["episodes.jsonl", "summary.json"][..],
            false,
        ),
        ("after_records", &["episodes.jsonl"][..], true),
    ] {
        let killed = dir.path().join(name);
        write_record(&whole, &killed, Some("unfinished"));
        for file in files {
            std::fs::copy(whole.join(file), killed.join(file)).unwrap();
        }
        let read = sage3d(&["report", s(&killed)]);
        assert_eq!(read.status.code(), Some(1));
        assert!(
            stderr(&read).contains(&format!(
                "{}: the rescoring in this folder was not finished (its sage3d_run.json has status 'unfinished'): rerun the same rescoring (`sage3d report ",
                killed.display()
            )),
            "{}",
            stderr(&read)
        );
        let rerun = rescore(&killed, force);
        assert!(rerun.status.success(), "{name}: {}", stderr(&rerun));
        assert_eq!(outputs(&killed), outputs(&whole), "{name}");
        // Finished, it is a run of its own: the same command is refused, `--force` too.
        for force in [false, true] {
            let again = rescore(&killed, force);
            assert_eq!(again.status.code(), Some(1));
            assert!(
                stderr(&again).contains("the folder holds a run already"),
                "{}",
                stderr(&again)
            );
        }
    }
}

#[test]
fn eval_records_its_status_and_report_refuses_a_run_it_did_not_finish() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    eval("2", &data, &scenes, &run, &["--agent", "oracle"]);
    assert_eq!(record(&run)["status"], "finished");
    let whole = outputs(&run);

    // What a kill before the summary leaves: the run record marked unfinished, some records.
    let killed = dir.path().join("killed");
    write_record(&run, &killed, Some("unfinished"));
    let text = std::fs::read_to_string(run.join("episodes.jsonl")).unwrap();
    let first = text.lines().next().unwrap();
    std::fs::write(killed.join("episodes.jsonl"), format!("{first}\n")).unwrap();
    let expected = format!(
        "{}: the evaluation in this folder was not finished (its sage3d_run.json has status 'unfinished'): rerun the same `sage3d eval` into it to finish it",
        killed.display()
    );
    for args in [
        vec!["report", s(&killed)],
        vec![
            "report",
            s(&killed),
            "--mode",
            "vlnce",
            "--out",
            s(&dir.path().join("rescored")),
        ],
    ] {
        let out = sage3d(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        assert!(stderr(&out).contains(&expected), "{}", stderr(&out));
    }
    assert!(!dir.path().join("rescored").exists());
    let resumed = eval("1", &data, &scenes, &killed, &["--agent", "oracle"]);
    assert!(resumed.contains("1 already recorded"), "{resumed}");
    assert_eq!(outputs(&killed), whole);

    // A run recorded before the status existed is a finished one.
    write_record(&run, &run, None);
    ok(&["report", s(&run)]);
}

#[test]
fn eval_into_a_run_of_other_settings_names_the_record_and_what_differs() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    eval("2", &data, &scenes, &run, &["--agent", "oracle"]);
    let other = eval_output("2", &data, &scenes, &run, &["--agent", "random"]);
    assert_eq!(other.status.code(), Some(1));
    assert!(
        stderr(&other).contains(&format!(
            "{}: this run folder holds a run with other settings (agent: oracle recorded, random asked); use a new run folder (--out)",
            run.join("sage3d_run.json").display()
        )),
        "{}",
        stderr(&other)
    );
}
