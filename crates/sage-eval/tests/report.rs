//! The run report on a real evaluation (one small synthetic scene, the forward agent, which
//! walks into walls): the page holds every summary number as the text table writes it, in the
//! same columns, links nothing outside itself, embeds decodable PNGs; every metric has one
//! scale in all charts; the maps show the reference path, the agent's path and the collisions
//! where the records put them, in colours that stay apart for colour-blind readers, with a
//! legend of only what each map shows; the episode table holds the instructions; a faulted
//! episode gets a banner; same inputs give the same bytes; bad run folders give errors naming
//! the file, and folders that are not runs say so.

mod common;

use base64::Engine;
use sage_eval::report::{self, charts, maps};
use sage_eval::{EvalRecord, EvalSettings, Summary};
use sage_io::canvas::Canvas;
use sage_io::files::read_tree;
use sage_io::palette::{self, Cvd, delta_e, simulate};
use sage_metrics::Mode;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A scene folder, a dataset and a finished forward-agent run with its report, made once.
struct Fixture {
    _dir: tempfile::TempDir,
    scenes: PathBuf,
    data: PathBuf,
    run: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, _, data) = common::small_dataset(dir.path(), 4);
        let run = dir.path().join("run");
        sage_eval::run(&settings(&data, &scenes), &run, &|_, _| {}).unwrap();
        report::write(&run, &scenes).unwrap();
        Fixture {
            _dir: dir,
            scenes,
            data,
            run,
        }
    })
}

/// The fixture run's settings.
fn settings(data: &Path, scenes: &Path) -> EvalSettings {
    EvalSettings {
        dataset: data.to_path_buf(),
        scenes: scenes.to_path_buf(),
        split: "train".into(),
        agent: "forward".parse().unwrap(),
        mode: Mode::Sage,
        dtw: Default::default(),
        seed: 0,
        preset: "sage".into(),
        device: Default::default(),
        splat_bodies: Default::default(),
    }
}

fn html() -> String {
    std::fs::read_to_string(fixture().run.join(sage_eval::folder::REPORT_FILE)).unwrap()
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
        // The forward agent reads no images, so its environment renders none.
        "environment</th><td>wheeled; 224x224 no images at HFOV 90° (camera at the profile&#39;s height); 0.25 m / 15° steps; 500 steps",
        "sage3d version (run)",
        &format!("episodes recorded</th><td>{}", s.episodes),
        &format!("episodes faulted</th><td>{}", s.failed.len()),
    ] {
        assert!(html.contains(needle), "{needle}");
    }
    // The text table and the page's tables have the same metric columns, in the same order,
    // the continuous metrics and SDTW among them.
    let heads: Vec<&str> = s.columns().iter().map(|c| c.head).collect();
    for h in ["CSR", "ICP", "PS", "SDTW"] {
        assert!(heads.contains(&h), "{heads:?}");
    }
    let text_heads: Vec<&str> = table
        .lines()
        .find(|l| l.trim_start().starts_with("n "))
        .unwrap()
        .split_whitespace()
        .skip(1)
        .collect();
    assert_eq!(text_heads, heads);
    let overall = &html[html.find("<h3>overall</h3>").unwrap()..];
    let header = &overall[..overall.find("</tr>").unwrap()];
    let titles: Vec<&str> = header
        .split("<th title=\"")
        .skip(1)
        .map(|h| &h[..h.find('"').unwrap()])
        .collect();
    let metrics: Vec<&str> = s.columns().iter().map(|c| c.metric).collect();
    assert_eq!(titles, metrics);
}

#[test]
fn every_metric_has_one_scale_in_all_charts() {
    let html = html();
    let s = summary();
    let ends = charts::scale_ends(&s);
    let mut seen: std::collections::BTreeMap<&str, Vec<f64>> = Default::default();
    for axis in sage_eval::summary::AXES {
        let chart = charts::slice_chart(axis, &s.slices[axis], &ends);
        // The page shows exactly these charts.
        assert!(html.contains(&chart.to_svg()), "{axis}");
        for p in &chart.panels {
            seen.entry(p.metric.metric).or_default().push(p.end);
        }
    }
    assert!(
        seen.contains_key("cr") && seen.contains_key("sr"),
        "{seen:?}"
    );
    for (metric, scale) in &seen {
        assert!(scale.iter().all(|e| *e == scale[0]), "{metric}: {scale:?}");
    }
    // Ratios on 0-1; CR from 0 to a round number at or above every mean of the summary.
    for m in ["sr", "spl", "ndtw"] {
        assert!(seen.get(m).is_none_or(|e| e[0] == 1.0), "{m}");
    }
    let cr_max = std::iter::once(&s.overall)
        .chain(s.slices.values().flat_map(|v| v.values()))
        .filter_map(|a| a.means.get("cr").copied())
        .fold(0.0, f64::max);
    let cr_end = seen["cr"][0];
    assert!(
        cr_end >= cr_max && cr_end < 2.5 * cr_max.max(0.4),
        "{cr_end} {cr_max}"
    );
    assert!(html.contains(&format!("CR 0–{cr_end} collisions")));
}

/// The colours a report map draws under the overlays.
fn backgrounds() -> Vec<[u8; 3]> {
    let mut colours = vec![maps::WALL, maps::OCCUPIED_CELL, maps::OUTSIDE];
    colours.extend((0..100).map(maps::category_colour));
    colours.extend((0..40).map(maps::room_colour));
    colours
}

#[test]
fn overlay_colours_stay_apart_for_every_reader_and_from_the_map_under_them() {
    let marks = [
        ("agent", palette::AGENT_PATH),
        ("reference", palette::REFERENCE_PATH),
        ("start", palette::START),
        ("goal", palette::GOAL),
        ("collision", palette::COLLISION),
    ];
    let doors: Vec<(&str, [u8; 3])> = palette::DOOR_STATES.to_vec();
    let all: Vec<(&str, [u8; 3])> = marks.iter().copied().chain(doors.clone()).collect();
    for (i, (a, ca)) in all.iter().enumerate() {
        for (b, cb) in &all[i + 1..] {
            let d = delta_e(*ca, *cb);
            assert!(d >= 25.0, "{a} vs {b}: {d}");
            for cvd in Cvd::ALL {
                let d = delta_e(simulate(*ca, cvd), simulate(*cb, cvd));
                assert!(d >= 15.0, "{a} vs {b} for {cvd:?}: {d}");
            }
        }
    }
    // The paths and markers stand out on everything under them; doors in their walls.
    for (a, ca) in marks {
        for bg in backgrounds() {
            let d = delta_e(ca, bg);
            assert!(d >= 20.0, "{a} on {bg:?}: {d}");
        }
    }
    for (state, c) in doors {
        let d = delta_e(c, maps::WALL);
        assert!(d >= 20.0, "door {state} in a wall: {d}");
    }
}

#[test]
fn the_legend_lists_only_what_the_map_shows() {
    let f = fixture();
    let (grid, mut map) = report::scene_map(&f.scenes.join("home1")).unwrap();
    let recs = records();
    let hit = recs
        .iter()
        .find(|r| {
            r.record
                .as_ref()
                .is_some_and(|r| r.steps.iter().any(|s| s.contact))
        })
        .unwrap();
    let labels = |map: &sage_nav::SemanticMap, rec: &EvalRecord| -> Vec<String> {
        maps::legend_keys(map, &grid, rec)
            .iter()
            .map(maps::Key::label)
            .collect()
    };
    let all = labels(&map, hit);
    assert!(all.contains(&"collision".to_string()), "{all:?}");
    let present: std::collections::BTreeSet<String> = map
        .items
        .iter()
        .filter(|i| i.state.is_none())
        .map(|i| i.category.clone())
        .collect();
    for c in &present {
        assert!(all.contains(c), "{c} {all:?}");
    }
    let states: std::collections::BTreeSet<&str> = map.doors.iter().map(|d| d.state).collect();
    for (s, _) in palette::DOOR_STATES {
        assert_eq!(
            all.contains(&format!("door {s}")),
            states.contains(s),
            "{s}"
        );
    }
    // One category left, every door open, no contact: the legend says just that.
    let keep = map
        .items
        .iter()
        .find(|i| i.state.is_none())
        .unwrap()
        .category
        .clone();
    map.items.retain(|i| i.category == keep);
    for d in &mut map.doors {
        d.state = "open";
    }
    let mut calm = hit.clone();
    for s in &mut calm.record.as_mut().unwrap().steps {
        s.contact = false;
    }
    let some = labels(&map, &calm);
    assert!(!some.contains(&"collision".to_string()), "{some:?}");
    for c in present.iter().filter(|c| **c != keep) {
        assert!(!some.contains(c), "{c} {some:?}");
    }
    assert!(some.contains(&keep));
    let door_keys: Vec<&String> = some.iter().filter(|l| l.starts_with("door ")).collect();
    assert!(
        door_keys.is_empty() == map.doors.is_empty() && door_keys.iter().all(|l| *l == "door open"),
        "{some:?}"
    );
    // The image draws that legend under the map: it is taller with more entries.
    let few = maps::episode_map(&map, &grid, &calm);
    let (_, full) = report::scene_map(&f.scenes.join("home1")).unwrap();
    let many = maps::episode_map(&full, &grid, hit);
    assert!(many.height > few.height, "{} {}", many.height, few.height);
}

#[test]
fn the_episode_table_holds_each_instruction() {
    let f = fixture();
    let html = html();
    let (_, episodes) = sage_dataset::folder::split_episodes(&f.data, "train").unwrap();
    let table = &html[html.find("<h2>Episodes</h2>").unwrap()..];
    assert!(table.contains("<th>instruction</th>"));
    let mut checked = 0;
    for r in records() {
        let e = episodes
            .iter()
            .find(|e| e.episode_id == r.episode_id)
            .unwrap();
        assert!(!e.instruction.is_empty());
        let cells = row_cells(table, "<h2>Episodes</h2>", &r.episode_id);
        assert_eq!(
            cells[3],
            report::escape::escape(&e.instruction),
            "{}",
            r.episode_id
        );
        checked += 1;
    }
    assert!(checked > 3);
    // A dataset changed since the run: no instruction is shown, and the page says why.
    let dir = tempfile::tempdir().unwrap();
    let mut run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(f.run.join("sage3d_run.json")).unwrap())
            .unwrap();
    run["dataset_hash"] = "0000000000000000".into();
    let e = report::read_instructions(&run, "train")
        .unwrap_err()
        .to_string();
    assert!(e.contains("changed since the run"), "{e}");
    run["settings"]["dataset"] = dir.path().join("none").to_string_lossy().into();
    assert!(report::read_instructions(&run, "train").is_err());
}

#[test]
fn a_faulted_episode_gets_a_banner_and_is_called_faulted() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::copy(f.run.join("sage3d_run.json"), run.join("sage3d_run.json")).unwrap();
    // The first episode faults (never scored); the second has a fault it recovered from.
    let mut recs = records();
    let faulted = recs[0].episode_id.clone();
    recs[0].termination = None;
    recs[0].metrics = None;
    recs[0].record = None;
    recs[0].error = Some("agent forward on episode: <no reply>".into());
    recs[0].failure = Some(sage_eval::Failure::ModelServer);
    recs[1].faults = vec![sage_env::agents::Fault {
        step: 2,
        attempt: 1,
        kind: sage_env::agents::FaultKind::Transport,
        message: "timeout".into(),
        recovered: true,
    }];
    let lines: Vec<String> = recs
        .iter()
        .map(|r| serde_json::to_string(r).unwrap())
        .collect();
    std::fs::write(run.join("episodes.jsonl"), lines.join("\n") + "\n").unwrap();
    let s = Summary::of(&settings(&f.data, &f.scenes), &recs);
    std::fs::write(run.join("summary.json"), serde_json::to_string(&s).unwrap()).unwrap();
    report::write(&run, &f.scenes).unwrap();
    let html = std::fs::read_to_string(run.join(sage_eval::folder::REPORT_FILE)).unwrap();
    let top = &html[..html.find("<h2>Run</h2>").unwrap()];
    assert!(
        top.contains(&format!("1 of {} episodes faulted", recs.len()))
            && top.contains("href=\"#faulted\"")
            && top.contains("1 model_server")
            && top.contains("1 recovered"),
        "{top}"
    );
    assert!(html.contains("<h2 id=\"faulted\">Faulted episodes</h2>"));
    assert!(html.contains("&lt;no reply&gt;"));
    let row = row_cells(&html, "<h2>Episodes</h2>", &faulted);
    assert!(row[5].contains("faulted"), "{row:?}");
    assert!(
        !html.to_lowercase().contains("failed"),
        "no episode is called failed"
    );
    // The terminal says the same.
    let table = s.table();
    assert!(
        table.starts_with(&format!("FAULTED: 1 of {} ", recs.len()))
            && table.contains("(1 faulted)")
            && table.contains("model-server faults: 1 transport"),
        "{table}"
    );
    // A run without faults has no banner.
    let clean = self::html();
    assert!(!clean[..clean.find("<h2>Run</h2>").unwrap()].contains("class=\"banner"));
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
    for axis in sage_eval::summary::AXES {
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
    let (mut checked_ref, mut gaps, mut checked_agent, mut checked_hits) = (0, 0, 0, 0);
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
                palette::COLLISION,
                "{}",
                rec.episode_id
            );
            checked_hits += 1;
        }
        // A forward-only agent may walk out of the building and off the map, whose bottom
        // edge is the grid's origin (caption and legend lie below it).
        let map_bottom = px(grid.origin).y;
        let on_image = |q: glam::Vec2| {
            q.x >= 0.0 && q.y >= 0.0 && (q.x as usize) < canvas.width && q.y < map_bottom - 1.0
        };
        for s in r.steps.iter().filter(|s| !s.contact) {
            let q = px(xy(&s.position));
            if on_image(q) && clear_of(q, &hits, 8.0) && clear_of(q, &markers, 13.0) {
                assert_eq!(
                    pixel(&canvas, xy(&s.position)),
                    palette::AGENT_PATH,
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
            if off_agent && clear_of(q, &hits, 8.0) && clear_of(q, &markers, 13.0) {
                // Dashed: a dash or the white halo of a gap.
                let c = pixel(&canvas, xy(p));
                assert!(
                    c == palette::REFERENCE_PATH || c == sage_io::marks::HALO,
                    "{}: {c:?}",
                    rec.episode_id
                );
                checked_ref += usize::from(c == palette::REFERENCE_PATH);
                gaps += usize::from(c == sage_io::marks::HALO);
            }
        }
    }
    // Dashes are 14 pixels and gaps 8: most reference points fall on a dash, some in a gap.
    assert!(
        checked_ref > 10
            && checked_ref > gaps
            && gaps > 0
            && checked_agent > 10
            && checked_hits > 0,
        "{checked_ref} {gaps} {checked_agent} {checked_hits}"
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
fn positions_out_of_bounds_in_records_are_refused_naming_line_and_field() {
    let f = fixture();
    let lines = std::fs::read_to_string(f.run.join("episodes.jsonl")).unwrap();
    let first: serde_json::Value = serde_json::from_str(lines.lines().next().unwrap()).unwrap();
    let owned: Vec<String> = lines
        .lines()
        .map(|l| serde_json::from_str::<EvalRecord>(l).unwrap().episode_id)
        .collect();
    let ids: std::collections::BTreeSet<&str> = owned.iter().map(String::as_str).collect();
    let huge = serde_json::json!(1e300);
    for (pointer, value, field) in [
        (
            "/record/steps/0/position",
            serde_json::json!([1e300, 0, 0]),
            "record.steps[0].position",
        ),
        ("/record/steps/0/yaw", huge.clone(), "record.steps[0].yaw"),
        ("/record/steps/0/time", huge.clone(), "record.steps[0].time"),
        (
            "/record/start",
            serde_json::json!([20000.0, 0, 0]),
            "record.start",
        ),
        ("/record/start_yaw", huge.clone(), "record.start_yaw"),
        (
            "/record/reference_path/0",
            serde_json::json!([0, 1e300, 0]),
            "record.reference_path[0]",
        ),
        (
            "/record/goal/point",
            serde_json::json!([1e300, 0]),
            "record.goal.point",
        ),
    ] {
        let mut rec = first.clone();
        *rec.pointer_mut(pointer)
            .unwrap_or_else(|| panic!("{pointer}")) = value;
        let mut hostile: Vec<String> = lines.lines().map(str::to_string).collect();
        hostile[0] = rec.to_string();
        let text = hostile.join("\n") + "\n";
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        std::fs::create_dir(&run).unwrap();
        for name in ["summary.json", "sage3d_run.json"] {
            std::fs::copy(f.run.join(name), run.join(name)).unwrap();
        }
        let records = run.join("episodes.jsonl");
        std::fs::write(&records, &text).unwrap();
        let named = |what: &str, e: String| {
            assert!(
                e.contains(&format!("{}: line 1, {field}: ", records.display()))
                    && e.contains("finite"),
                "{what}, {pointer}: {e}"
            );
        };
        // The report (maps and videos), a rescoring, the viewer (all through `read_run`),
        // and the evaluator's own reader of its file.
        named("read", report::read_run(&run).unwrap_err().to_string());
        let options = report::ReportOptions {
            videos: 3,
            ..Default::default()
        };
        let e = report::write_with_options(&run, &f.scenes, &options, &|_, _| {}, &|_, _| {});
        named("report", e.unwrap_err().to_string());
        let e = sage_eval::rescore(&run, Some(Mode::Vlnce), None, &dir.path().join("re"));
        named("rescore", e.unwrap_err().to_string());
        let e = sage_eval::records::sort(&records, &ids)
            .unwrap_err()
            .to_string();
        named("sort", e);
        assert!(!run.join(sage_eval::folder::REPORT_FILE).exists());
        // Shards are text, not files: the merge names shard, line and field.
        let e = sage_eval::merge_shards(
            &settings(&f.data, &f.scenes),
            "forward",
            None,
            &[text],
            &dir.path().join("merged"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains(&format!("shard 0, line 1, {field}: ")), "{e}");
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
    assert!(e.contains("nowhere: no such run folder"), "{e}");
    // Folders that are not evaluation runs are named for what they are, before any file of a
    // run is looked for: one without a run record, and a dataset (another command's record).
    let bare = tempfile::tempdir().unwrap();
    let e = report::write(bare.path(), &f.scenes)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not an evaluation run (it has no sage3d_run.json"),
        "{e}"
    );
    let data = bare.path().join("data");
    std::fs::create_dir_all(data.join("episodes")).unwrap();
    sage_io::run::write_run_record(&data, "data build", Some(0), serde_json::json!({})).unwrap();
    let e = report::write(&data, &f.scenes).unwrap_err().to_string();
    assert!(
        e.contains("data: not an evaluation run (its sage3d_run.json is from `data build`"),
        "{e}"
    );
    assert!(!data.join(sage_eval::folder::REPORT_FILE).exists());
    // A scene of the records that is not among the scenes.
    let e = report::write(&f.run, dir.path()).unwrap_err().to_string();
    assert!(e.contains("scene"), "{e}");
    assert!(!run.join(sage_eval::folder::REPORT_FILE).exists());
}
