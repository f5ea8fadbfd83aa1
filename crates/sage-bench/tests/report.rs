//! The run report on a real evaluation (one small synthetic scene, the forward agent, which
//! walks into walls): the page holds every summary number as the text table writes it, links
//! nothing outside itself, embeds decodable PNGs; the maps show the reference path, the agent's
//! path and the collisions where the records put them; same inputs give the same bytes; bad run
//! folders give errors naming the file.

mod common;

use base64::Engine;
use sage_bench::eval::{self, EvalRecord, EvalSettings, Summary};
use sage_bench::report::{self, maps};
use sage_io::canvas::Canvas;
use sage_io::files::read_tree;
use sage_metrics::Mode;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A scene folder, a dataset and a finished forward-agent run with its report, made once.
struct Fixture {
    _dir: tempfile::TempDir,
    scenes: PathBuf,
    run: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, _, data) = common::small_dataset(dir.path(), 4);
        let run = dir.path().join("run");
        let settings = EvalSettings {
            dataset: data,
            scenes: scenes.clone(),
            split: "train".into(),
            agent: "forward".parse().unwrap(),
            mode: Mode::Sage,
            dtw: Default::default(),
            seed: 0,
            preset: "sage".into(),
        };
        eval::run(&settings, &run, &|_, _| {}).unwrap();
        report::write(&run, &scenes).unwrap();
        Fixture {
            _dir: dir,
            scenes,
            run,
        }
    })
}

fn html() -> String {
    std::fs::read_to_string(fixture().run.join(report::REPORT_FILE)).unwrap()
}

fn summary() -> Summary {
    serde_json::from_str(&std::fs::read_to_string(fixture().run.join("summary.json")).unwrap())
        .unwrap()
}

fn records() -> Vec<EvalRecord> {
    report::read_run(&fixture().run).unwrap().records
}

/// The cells of the first table row of `html` after `section` whose first cell is `name`.
fn row_cells(html: &str, section: &str, name: &str) -> Vec<String> {
    let from = html.find(section).unwrap_or_else(|| panic!("no {section}"));
    let rest = &html[from..];
    let start = rest
        .find(&format!("<tr><td>{name}</td>"))
        .unwrap_or_else(|| panic!("no row {name} after {section}"));
    let row = &rest[start..start + rest[start..].find("</tr>").unwrap()];
    row.split("<td")
        .skip(1)
        .map(|c| {
            let c = &c[c.find('>').unwrap() + 1..];
            c[..c.find("</td>").unwrap()].to_string()
        })
        .collect()
}

#[test]
fn page_holds_every_summary_number_as_the_text_table_writes_it() {
    let html = html();
    let s = summary();
    let table = s.table();
    let mut rows = vec![("<h3>overall</h3>".to_string(), "overall", &s.overall)];
    for (axis, slices) in &s.slices {
        for (name, a) in slices {
            rows.push((format!("<h3>per {axis}</h3>"), name.as_str(), a));
        }
    }
    assert!(rows.len() > 8, "{rows:?}");
    for (section, name, a) in rows {
        let cells = row_cells(&html, &section, name);
        assert_eq!(cells[1], a.episodes.to_string(), "{section} {name}");
        for (metric, v) in &a.means {
            let text = format!("{v:.3}");
            assert!(
                cells.contains(&text),
                "{section} {name}: {metric} = {text} missing from {cells:?}"
            );
        }
        // Every number of the text table's row is in the page's row.
        let line = table
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap();
        for tok in line.split_whitespace().skip(1).filter(|t| *t != "-") {
            assert!(cells.iter().any(|c| c == tok), "{name}: {tok} of {line:?}");
        }
    }
    for needle in [
        "metric mode</th><td>sage",
        "agent</th><td>forward",
        "split</th><td>train",
        "dataset hash",
        "sage3d version (run)",
        &format!("episodes recorded</th><td>{}", s.episodes),
        &format!("episodes failed</th><td>{}", s.failed.len()),
    ] {
        assert!(html.contains(needle), "{needle}");
    }
}

#[test]
fn page_is_self_contained_and_its_images_decode_to_the_written_pngs() {
    let html = html();
    assert!(!html.contains("http://") && !html.contains("https://"));
    assert!(!html.contains("<script") && !html.contains("<link"));
    let run = &fixture().run;
    let mut embedded = Vec::new();
    for part in html.split("<a href=\"").skip(1) {
        let link = &part[..part.find('"').unwrap()];
        let rest = &part[link.len()..];
        if let Some(img) = rest.strip_prefix("\"><img alt=\"") {
            let uri = &img[img.find("src=\"").unwrap() + 5..];
            let b64 = uri[..uri.find('"').unwrap()]
                .strip_prefix("data:image/png;base64,")
                .unwrap();
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap();
            assert_eq!(bytes, std::fs::read(run.join(link)).unwrap(), "{link}");
            let mut dec = png::Decoder::new(std::io::Cursor::new(bytes))
                .read_info()
                .unwrap();
            let mut buf = vec![0; dec.output_buffer_size().unwrap()];
            dec.next_frame(&mut buf).unwrap();
            embedded.push(link.to_string());
        } else {
            assert!(run.join(link).is_file(), "{link}");
        }
    }
    // Every episode with a record has a map; unsuccessful episodes come first, then by id.
    let recs = records();
    let mut expected: Vec<&EvalRecord> = recs.iter().filter(|r| r.record.is_some()).collect();
    // Success: SR 1 for VLN; a no-goal episode succeeds unless it ended in a collision.
    let success = |r: &EvalRecord| match r.metrics.as_ref().and_then(|m| m.sr) {
        Some(sr) => sr == 1.0,
        None => r.termination != Some(sage_env::Termination::Collision),
    };
    expected.sort_by(|a, b| (success(a), &a.episode_id).cmp(&(success(b), &b.episode_id)));
    let names: Vec<String> = expected
        .iter()
        .take(report::EMBEDDED_MAPS)
        .map(|r| format!("report/maps/{}", report::map_file_name(&r.episode_id)))
        .collect();
    assert!(!names.is_empty());
    assert_eq!(embedded, names);
    for axis in sage_bench::eval::summary::AXES {
        assert!(run.join(format!("report/chart_{axis}.png")).is_file());
        assert!(html.contains(&format!("aria-label=\"per {axis}\"")));
    }
}

fn decode(path: &Path) -> (usize, usize, Vec<u8>) {
    let mut dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
        .read_info()
        .unwrap();
    let mut buf = vec![0; dec.output_buffer_size().unwrap()];
    let info = dec.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, buf)
}

fn pixel(c: &Canvas, p: glam::Vec2) -> [u8; 3] {
    let q = c.to_pixel(p);
    let k = (q.y as usize * c.width + q.x as usize) * 3;
    [c.rgb[k], c.rgb[k + 1], c.rgb[k + 2]]
}

/// Pixel distance from `q` to the segment a–b.
fn to_segment(q: glam::Vec2, a: glam::Vec2, b: glam::Vec2) -> f32 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.distance(a + ab * t)
}

#[test]
fn maps_show_reference_agent_and_collisions_at_their_world_positions() {
    let f = fixture();
    let (grid, map) = report::scene_map(&f.scenes.join("home1")).unwrap();
    let xy = |p: &[f32; 3]| glam::Vec2::new(p[0], p[1]);
    let (mut checked_ref, mut checked_agent, mut checked_hits) = (0, 0, 0);
    for rec in records() {
        let Some(r) = &rec.record else { continue };
        let canvas = maps::episode_map(&map, &grid, &rec);
        let file = f
            .run
            .join("report/maps")
            .join(report::map_file_name(&rec.episode_id));
        assert_eq!(
            decode(&file),
            (canvas.width, canvas.height, canvas.rgb.clone())
        );
        let px = |p: glam::Vec2| canvas.to_pixel(p);
        let agent: Vec<glam::Vec2> = std::iter::once(&r.start)
            .chain(r.steps.iter().map(|s| &s.position))
            .map(|p| px(xy(p)))
            .collect();
        let hits: Vec<glam::Vec2> = r
            .steps
            .iter()
            .filter(|s| s.contact)
            .map(|s| px(xy(&s.position)))
            .collect();
        let mut markers = vec![px(xy(&r.start))];
        if let Some(g) = &r.goal {
            markers.push(px(glam::Vec2::new(g.point[0] as f32, g.point[1] as f32)));
        }
        let clear_of =
            |q: glam::Vec2, pts: &[glam::Vec2], d: f32| pts.iter().all(|p| p.distance(q) > d);
        for s in r.steps.iter().filter(|s| s.contact) {
            assert_eq!(
                pixel(&canvas, xy(&s.position)),
                maps::COLLISION,
                "{}",
                rec.episode_id
            );
            checked_hits += 1;
        }
        // A forward-only agent may walk out of the building and off the image.
        let on_image = |q: glam::Vec2| {
            q.x >= 0.0
                && q.y >= 0.0
                && (q.x as usize) < canvas.width
                && (q.y as usize) < canvas.height
        };
        for s in r.steps.iter().filter(|s| !s.contact) {
            let q = px(xy(&s.position));
            if on_image(q) && clear_of(q, &hits, 8.0) && clear_of(q, &markers, 10.0) {
                assert_eq!(
                    pixel(&canvas, xy(&s.position)),
                    maps::AGENT,
                    "{}",
                    rec.episode_id
                );
                checked_agent += 1;
            }
        }
        for p in &r.reference_path {
            let q = px(xy(p));
            let off_agent =
                agent.windows(2).all(|w| to_segment(q, w[0], w[1]) > 6.0) && agent.len() > 1;
            if off_agent && clear_of(q, &hits, 8.0) && clear_of(q, &markers, 10.0) {
                assert_eq!(pixel(&canvas, xy(p)), maps::REFERENCE, "{}", rec.episode_id);
                checked_ref += 1;
            }
        }
    }
    assert!(
        checked_ref > 10 && checked_agent > 10 && checked_hits > 0,
        "{checked_ref} {checked_agent} {checked_hits}"
    );
}

#[test]
fn same_inputs_give_the_same_bytes_with_any_thread_count() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("run");
    std::fs::create_dir_all(&copy).unwrap();
    for name in ["summary.json", "episodes.jsonl", "sage3d_run.json"] {
        std::fs::copy(f.run.join(name), copy.join(name)).unwrap();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let outcome = pool.install(|| report::write(&copy, &f.scenes)).unwrap();
    assert_eq!(
        outcome.maps,
        records().iter().filter(|r| r.record.is_some()).count()
    );
    let (a, b) = (read_tree(&f.run).unwrap(), read_tree(&copy).unwrap());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(b[k] == *v, "{k} differs");
    }
}

#[test]
fn bad_run_folders_are_errors_naming_the_file() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path();
    for name in ["summary.json", "episodes.jsonl", "sage3d_run.json"] {
        std::fs::copy(f.run.join(name), run.join(name)).unwrap();
    }
    let err = |run: &Path| report::write(run, &f.scenes).unwrap_err().to_string();
    let lines = std::fs::read_to_string(run.join("episodes.jsonl")).unwrap();
    let mut damaged: Vec<&str> = lines.lines().collect();
    damaged[1] = "{\"episode_id\": 3";
    std::fs::write(run.join("episodes.jsonl"), damaged.join("\n")).unwrap();
    let e = err(run);
    assert!(e.contains("episodes.jsonl") && e.contains("line 2"), "{e}");
    // A record missing: the summary does not count the records.
    std::fs::write(
        run.join("episodes.jsonl"),
        lines.lines().skip(1).collect::<Vec<_>>().join("\n"),
    )
    .unwrap();
    let e = err(run);
    assert!(
        e.contains("summary.json") && e.contains("unfinished"),
        "{e}"
    );
    std::fs::remove_file(run.join("summary.json")).unwrap();
    let e = err(run);
    assert!(e.contains("summary.json"), "{e}");
    let e = report::write(&f.run.join("nowhere"), &f.scenes)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sage3d_run.json"), "{e}");
    // A scene of the records that is not among the scenes.
    let e = report::write(&f.run, dir.path()).unwrap_err().to_string();
    assert!(e.contains("scene"), "{e}");
    assert!(!run.join(report::REPORT_FILE).exists());
}
