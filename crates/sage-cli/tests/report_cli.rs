//! `sage3d report` and the report `sage3d eval` writes: eval prints the report's path, a
//! regenerated report is the same bytes (also with the run's own scenes folder), faulted
//! episodes are listed under a banner, bad run folders give errors naming the file and a folder
//! that is not a run says so, `--videos N` writes N episode videos that the page shows (one
//! per episode when N is more), and `--mode M --out NEW` rescores a run into a new folder with
//! the numbers of an evaluation in mode M.

mod common;

use common::{eval, ok, s, sage3d, small_dataset};

#[test]
fn eval_writes_the_report_and_report_regenerates_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    let out = eval("2", &data, &scenes, &run, &["--agent", "random"]);
    let html_path = run.join("report.html");
    assert!(
        out.contains(&format!("report: {}", html_path.display())),
        "{out}"
    );
    let html = std::fs::read(&html_path).unwrap();
    let text = String::from_utf8(html.clone()).unwrap();
    assert!(text.contains("agent</th><td>random") && text.contains("data:image/png;base64,"));
    let maps = std::fs::read_dir(run.join("report/maps")).unwrap().count();
    assert!(maps >= 3, "{maps}");
    let before = sage_io::files::read_tree(&run.join("report")).unwrap();

    std::fs::remove_file(&html_path).unwrap();
    let out = ok(&["report", s(&run), "--scenes", s(&scenes)]);
    assert!(
        out.contains("report.html") && out.contains(&format!("{maps} maps")),
        "{out}"
    );
    assert_eq!(std::fs::read(&html_path).unwrap(), html);
    // Without --scenes the run's own scenes folder is used.
    ok(&["--threads", "1", "report", s(&run)]);
    assert_eq!(std::fs::read(&html_path).unwrap(), html);
    assert_eq!(
        sage_io::files::read_tree(&run.join("report")).unwrap(),
        before
    );
}

#[test]
fn faulted_episodes_are_listed_with_their_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    // The oracle cannot act on a no-goal episode: it is recorded with an error, never scored.
    eval("2", &data, &scenes, &run, &["--agent", "oracle"]);
    let records = std::fs::read_to_string(run.join("episodes.jsonl")).unwrap();
    let faulted: Vec<serde_json::Value> = records
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|r| r.get("error").is_some())
        .collect();
    assert!(!faulted.is_empty());
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(html.contains(&format!("episodes faulted</th><td>{}", faulted.len())));
    // A banner above everything says so and links the list.
    let banner = &html[..html.find("<h2>Run</h2>").unwrap()];
    assert!(
        banner.contains(&format!("{} of ", faulted.len()))
            && banner.contains("episodes faulted")
            && banner.contains("href=\"#faulted\""),
        "{banner}"
    );
    let section = &html[html
        .find("<h2 id=\"faulted\">Faulted episodes</h2>")
        .unwrap()
        + 4..];
    let section = &section[..section.find("<h2>").unwrap()];
    for r in faulted {
        let id = r["episode_id"].as_str().unwrap();
        let error = r["error"]
            .as_str()
            .unwrap()
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
            .replace('\'', "&#39;");
        assert!(section.contains(&format!("<tr><td>{id}</td>")), "{section}");
        assert!(
            section.contains(&format!("<td>{}</td>", r["failure"].as_str().unwrap())),
            "{section}"
        );
        assert!(section.contains(&error), "{error} {section}");
    }
}

#[test]
fn bad_run_folders_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path();
    let fails = |args: &[&str]| {
        let out = sage3d(args);
        assert!(!out.status.success(), "{args:?} succeeded");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // A run record that names no command: not a run of anything.
    std::fs::write(
        run.join("sage3d_run.json"),
        r#"{"tool": "sage3d", "settings": {"scenes": "nowhere"}}"#,
    )
    .unwrap();
    let e = fails(&["report", s(run), "--scenes", s(run)]);
    assert!(
        e.contains("sage3d_run.json") && e.contains("command"),
        "{e}"
    );
    std::fs::write(
        run.join("sage3d_run.json"),
        r#"{"tool": "sage3d", "command": "eval", "settings": {"scenes": "nowhere"}}"#,
    )
    .unwrap();
    let e = fails(&["report", s(run), "--scenes", s(run)]);
    assert!(
        e.contains("summary.json") && e.contains("sage3d eval"),
        "{e}"
    );
    std::fs::write(run.join("summary.json"), "{\"agent\": 1}").unwrap();
    let e = fails(&["report", s(run), "--scenes", s(run)]);
    assert!(e.contains("summary.json"), "{e}");
    // Without --scenes, a recorded scenes folder that is not there is named, with the advice.
    let e = fails(&["report", s(run)]);
    assert!(
        e.contains("settings.scenes: nowhere") && e.contains("(--scenes)"),
        "{e}"
    );
    std::fs::remove_file(run.join("sage3d_run.json")).unwrap();
    let e = fails(&["report", s(run)]);
    assert!(
        e.contains("not an evaluation run (it has no sage3d_run.json"),
        "{e}"
    );
    assert!(!run.join("report.html").exists());
}

#[test]
fn a_folder_that_is_not_a_run_is_named_for_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    // A dataset folder: its run record is from `data build`; said first, with and without
    // --scenes and when rescoring, and nothing is written into it.
    let before = sage_io::files::read_tree(&data).unwrap();
    for args in [
        vec!["report", s(&data)],
        vec!["report", s(&data), "--scenes", s(&scenes)],
        vec![
            "report",
            s(&data),
            "--mode",
            "vlnce",
            "--out",
            s(&dir.path().join("new")),
        ],
    ] {
        let out = sage3d(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(
            e.contains("not an evaluation run (its sage3d_run.json is from `data build`"),
            "{e}"
        );
    }
    assert_eq!(sage_io::files::read_tree(&data).unwrap(), before);
    assert!(!dir.path().join("new").exists());
}

/// The metric tables of a command's output: the lines from the first table header on (the
/// `agent … · mode …` line names the mode, so it is left out).
fn tables(out: &str) -> Vec<&str> {
    out.lines()
        .skip_while(|l| !l.starts_with("agent "))
        .skip(1)
        .take_while(|l| !l.contains(" episodes: ") && !l.starts_with("rescored "))
        .collect()
}

#[test]
fn report_mode_rescores_into_a_new_run_folder_with_an_evaluations_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let (sage, vlnce, rescored) = (
        dir.path().join("sage"),
        dir.path().join("vlnce"),
        dir.path().join("rescored"),
    );
    eval("2", &data, &scenes, &sage, &["--agent", "random"]);
    let evaluated = eval(
        "2",
        &data,
        &scenes,
        &vlnce,
        &["--agent", "random", "--mode", "vlnce"],
    );
    let run_before = sage_io::files::read_tree(&sage).unwrap();
    let out = ok(&["report", s(&sage), "--mode", "vlnce", "--out", s(&rescored)]);
    assert!(
        out.contains("from mode sage (exact DTW) to mode vlnce (exact DTW)")
            && out.contains(&format!(
                "report: {}",
                rescored.join("report.html").display()
            )),
        "{out}"
    );
    // The tables of the rescoring are those of the evaluation in mode vlnce.
    assert_eq!(tables(&out), tables(&evaluated));
    assert!(tables(&out).len() > 5, "{out}");
    assert_eq!(sage_io::files::read_tree(&sage).unwrap(), run_before);
    // The new folder is that evaluation's run: `eval` in mode vlnce resumes it, runs nothing.
    let resumed = eval(
        "2",
        &data,
        &scenes,
        &rescored,
        &["--agent", "random", "--mode", "vlnce"],
    );
    assert!(resumed.contains("already recorded, 0 run now"), "{resumed}");
    // Refused: over the run itself, over a run, gnbench from a run not scored in it, a mode
    // without --out (a usage error), --out without a mode.
    for (args, code, needle) in [
        (
            vec!["report", s(&sage), "--mode", "vlnce", "--out", s(&sage)],
            1,
            "a rescoring writes a new run folder",
        ),
        (
            vec!["report", s(&sage), "--mode", "vlnce", "--out", s(&vlnce)],
            1,
            "the folder holds a run already",
        ),
        (
            vec![
                "report",
                s(&sage),
                "--mode",
                "gnbench",
                "--out",
                s(&dir.path().join("gn")),
            ],
            1,
            "GN-Bench",
        ),
        (vec!["report", s(&sage), "--mode", "vlnce"], 2, "--out"),
        (
            vec!["report", s(&sage), "--out", s(&dir.path().join("x"))],
            1,
            "--mode",
        ),
    ] {
        let out = sage3d(&args);
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains(needle), "{args:?}: {e}");
    }
    assert!(!dir.path().join("gn").exists() && !dir.path().join("x").exists());
    assert_eq!(sage_io::files::read_tree(&sage).unwrap(), run_before);
}

#[test]
fn report_videos_writes_gifs_the_page_shows() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let run = dir.path().join("run");
    // The oracle's episodes are short (it walks the reference path and stops).
    eval("2", &data, &scenes, &run, &["--agent", "oracle"]);
    let videos = run.join("report/videos");
    // `eval` writes none.
    assert!(!videos.exists());
    let names = |dir: &std::path::Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    };

    let out = ok(&["report", s(&run), "--videos", "2"]);
    assert!(out.contains("videos: 2 in report/videos/"), "{out}");
    assert!(!out.contains("asked for"), "{out}");
    let gifs = names(&videos);
    assert_eq!(gifs.len(), 2);
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(html.contains("Episode videos"));
    for g in &gifs {
        assert!(g.ends_with(".gif"));
        assert!(html.contains(&format!("src=\"report/videos/{g}\"")), "{g}");
        let bytes = std::fs::read(videos.join(g)).unwrap();
        assert!(bytes.starts_with(b"GIF89a"));
    }

    // More than the run has: one per episode with a trajectory, and it says so.
    let maps = names(&run.join("report/maps")).len();
    let out = ok(&["report", s(&run), "--videos", "500"]);
    assert!(
        out.contains(&format!("videos: {maps} in report/videos/"))
            && out.contains(&format!(
                "(asked for 500; the run has {maps} episodes with a trajectory)"
            )),
        "{out}"
    );
    assert_eq!(names(&videos).len(), maps);
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert_eq!(html.matches("src=\"report/videos/").count(), maps);
}
