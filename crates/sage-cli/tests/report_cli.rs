//! `sage3d report` and the report `sage3d eval` writes: eval prints the report's path, a
//! regenerated report is the same bytes (also with the run's own scenes folder), faulted
//! episodes are listed under a banner, bad run folders give errors naming the file, and
//! `--videos N` writes N episode videos that the page shows (one per episode when N is more).

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
    std::fs::write(
        run.join("sage3d_run.json"),
        r#"{"tool": "sage3d", "settings": {"scenes": "nowhere"}}"#,
    )
    .unwrap();
    let fails = |args: &[&str]| {
        let out = sage3d(args);
        assert!(!out.status.success(), "{args:?} succeeded");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = fails(&["report", s(run), "--scenes", s(run)]);
    assert!(
        e.contains("summary.json") && e.contains("sage3d eval"),
        "{e}"
    );
    std::fs::write(run.join("summary.json"), "{\"agent\": 1}").unwrap();
    let e = fails(&["report", s(run)]);
    assert!(e.contains("summary.json"), "{e}");
    std::fs::remove_file(run.join("sage3d_run.json")).unwrap();
    let e = fails(&["report", s(run)]);
    assert!(e.contains("sage3d_run.json"), "{e}");
    assert!(!run.join("report.html").exists());
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
