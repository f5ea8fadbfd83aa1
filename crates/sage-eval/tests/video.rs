//! Episode videos on a real evaluation (one small synthetic scene, the oracle agent): the GIF
//! has a frame for the start and one per step, at the layout's size; its first-person part is
//! a render through the agent's camera at the pose (compared with a direct render); the
//! agent's marker on the map is where the record puts it; the same inputs give the same
//! bytes, with any thread count; and the report writes the videos it is asked for and shows
//! them, through the camera of the environment the run recorded (its preset's for a run
//! recorded before the environment was), and removes those an earlier report wrote that it no
//! longer shows.

mod common;

use glam::{Vec2, Vec3};
use sage_core::Pose;
use sage_env::{EnvConfig, SceneContext};
use sage_eval::EvalRecord;
use sage_eval::report::video::{self, VideoLayout, VideoSize};
use sage_eval::report::{self, ReportOptions, maps};
use sage_io::canvas::Canvas;
use sage_io::palette::AGENT_PATH;
use sage_metrics::Mode;
use sage_splat::{Device, RenderOptions};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A scene, a finished oracle run (no report yet; its no-goal episodes fault) and the loaded
/// scene context.
struct Fixture {
    _dir: tempfile::TempDir,
    scenes: PathBuf,
    run: PathBuf,
    ctx: SceneContext,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, home, data) = common::small_dataset(dir.path(), 4);
        let run = dir.path().join("run");
        let settings = sage_eval::EvalSettings {
            dataset: data,
            scenes: scenes.clone(),
            split: "train".into(),
            agent: "oracle".parse().unwrap(),
            mode: Mode::Sage,
            dtw: Default::default(),
            seed: 0,
            preset: "sage".into(),
            device: Default::default(),
            splat_bodies: Default::default(),
        };
        sage_eval::run(&settings, &run, &|_, _| {}).unwrap();
        let ctx = SceneContext::load(&home, None).unwrap();
        Fixture {
            _dir: dir,
            scenes,
            run,
            ctx,
        }
    })
}

fn config() -> EnvConfig {
    EnvConfig::preset("sage").unwrap()
}

/// The run's episodes that have a record, most steps first (ties by id).
fn records() -> Vec<EvalRecord> {
    let mut recs: Vec<EvalRecord> = report::read_run(&fixture().run)
        .unwrap()
        .records
        .into_iter()
        .filter(|r| r.record.is_some())
        .collect();
    recs.sort_by_key(|r| std::cmp::Reverse(r.record.as_ref().unwrap().steps.len()));
    recs
}

/// The episode of the run that moved the farthest from its start (in map pixels, so the
/// marker test has room).
fn walker() -> EvalRecord {
    records()
        .into_iter()
        .max_by(|a, b| travel(a).total_cmp(&travel(b)))
        .unwrap()
}

fn travel(r: &EvalRecord) -> f32 {
    let rec = r.record.as_ref().unwrap();
    let start = Vec2::new(rec.start[0], rec.start[1]);
    rec.steps
        .iter()
        .map(|s| Vec2::new(s.position[0], s.position[1]).distance(start))
        .fold(0.0, f32::max)
}

const INSTRUCTION: &str = "Walk past the sofa, then stop by the door on your left.";

fn gif(rec: &EvalRecord) -> Vec<u8> {
    let f = fixture();
    video::episode_gif(
        &f.ctx,
        &config(),
        &f.ctx.semantic,
        &f.ctx.pathfinder.grid,
        rec,
        INSTRUCTION,
        VideoSize::default(),
    )
    .unwrap()
}

fn frames(rec: &EvalRecord) -> Vec<Canvas> {
    let f = fixture();
    video::episode_frames(
        &f.ctx,
        &config(),
        &f.ctx.semantic,
        &f.ctx.pathfinder.grid,
        rec,
        INSTRUCTION,
        VideoSize::default(),
    )
    .unwrap()
}

/// A GIF's size and its frames as (RGB, delay).
fn decode(bytes: &[u8]) -> (usize, usize, Vec<(Vec<u8>, u16)>) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let mut d = opts.read_info(bytes).unwrap();
    let (w, h) = (d.width() as usize, d.height() as usize);
    let mut out = Vec::new();
    while let Some(f) = d.read_next_frame().unwrap() {
        // Every frame covers the whole image.
        assert_eq!((f.left, f.top), (0, 0));
        assert_eq!((f.width as usize, f.height as usize), (w, h));
        let rgb = f
            .buffer
            .chunks(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        out.push((rgb, f.delay));
    }
    (w, h, out)
}

/// The `w × h` RGB block at (x, y) of an image `stride` pixels wide.
fn crop(rgb: &[u8], stride: usize, (x, y, w, h): (usize, usize, usize, usize)) -> Vec<u8> {
    (y..y + h)
        .flat_map(|row| rgb[(row * stride + x) * 3..(row * stride + x + w) * 3].to_vec())
        .collect()
}

fn mean_abs_error(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| f64::from(x.abs_diff(*y)))
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn the_gif_has_a_frame_per_step_and_the_first_person_view_is_a_render_at_the_pose() {
    let f = fixture();
    let rec = walker();
    let record = rec.record.as_ref().unwrap();
    let n = record.steps.len();
    assert!(n >= 2, "the walker took {n} steps");
    let (w, h, decoded) = decode(&gif(&rec));
    assert_eq!(decoded.len(), n + 1);
    let layout = VideoLayout::new(&f.ctx.pathfinder.grid, VideoSize::default(), INSTRUCTION);
    assert_eq!((w, h), (layout.width, layout.height));
    assert_eq!((layout.fpv.2, layout.fpv.3), (320, 240));
    // Every frame but the last shows a quarter second; the last is held.
    assert!(decoded[..n].iter().all(|(_, d)| *d == video::STEP_DELAY));
    assert_eq!(decoded[n].1, video::END_DELAY);

    // The first-person part of frames 0 and n: a direct render through the agent's camera.
    let config = config();
    let profile = config.profile().unwrap();
    let last = &record.steps[n - 1];
    let poses = [
        (0, Pose::new(Vec3::from(record.start), record.start_yaw)),
        (n, Pose::new(Vec3::from(last.position), last.yaw)),
    ];
    let mut renderer = f.ctx.renderer(Device::Cpu).unwrap();
    for (k, pose) in poses {
        let camera = config.camera(&profile, pose, 0.0, 320, 240).unwrap();
        let direct = renderer
            .render_batch(
                &f.ctx.scene.gaussians,
                &f.ctx.scene.instances.category_ids,
                &[camera],
                &RenderOptions::default(),
            )
            .unwrap()
            .remove(0);
        let shown = crop(&decoded[k].0, w, layout.fpv);
        let err = mean_abs_error(&shown, &direct.rgb);
        assert!(err < 8.0, "frame {k}: mean abs error {err}");
        // Not any image would do: another pose's view differs by more.
        let other = crop(&decoded[if k == 0 { n } else { 0 }].0, w, layout.fpv);
        let apart = mean_abs_error(&other, &direct.rgb);
        assert!(apart > err + 4.0, "frame {k}: {apart} vs {err}");
    }

    // The GIF is the frames, up to its palettes.
    let canvases = frames(&rec);
    assert_eq!(canvases.len(), n + 1);
    for (k, c) in canvases.iter().enumerate() {
        assert_eq!((c.width, c.height), (w, h));
        let err = mean_abs_error(&c.rgb, &decoded[k].0);
        assert!(err < 4.0, "frame {k}: {err}");
    }
}

/// How many pixels within `r` of world point `p` on the frame's map panel have `colour`.
fn count_near(
    frame: &Canvas,
    panel: &Canvas,
    at: (usize, usize),
    p: Vec2,
    r: i64,
    c: [u8; 3],
) -> usize {
    let q = panel.to_pixel(p);
    let (cx, cy) = (at.0 as i64 + q.x as i64, at.1 as i64 + q.y as i64);
    let mut hits = 0;
    for dy in -r..=r {
        for dx in -r..=r {
            if dx * dx + dy * dy > r * r {
                continue;
            }
            let (x, y) = ((cx + dx) as usize, (cy + dy) as usize);
            let k = (y * frame.width + x) * 3;
            if frame.rgb[k..k + 3] == c {
                hits += 1;
            }
        }
    }
    hits
}

#[test]
fn the_agent_marker_moves_on_the_map_with_the_record() {
    let f = fixture();
    let rec = walker();
    let record = rec.record.as_ref().unwrap();
    let grid = &f.ctx.pathfinder.grid;
    let layout = VideoLayout::new(grid, VideoSize::default(), INSTRUCTION);
    let (mx, my, mw, mh) = layout.map;
    // A canvas with the panel's world-to-pixel mapping.
    let panel = maps::base_map_rows(&f.ctx.semantic, grid, mh, mw, mh);
    let canvases = frames(&rec);
    let start = Vec2::new(record.start[0], record.start[1]);
    // The frame whose pose is farthest from the start, in pixels.
    let (k, far) = record
        .steps
        .iter()
        .enumerate()
        .map(|(i, s)| (i + 1, Vec2::new(s.position[0], s.position[1])))
        .max_by(|a, b| {
            let d = |p: Vec2| panel.to_pixel(p).distance(panel.to_pixel(start));
            d(a.1).total_cmp(&d(b.1))
        })
        .unwrap();
    let apart = panel.to_pixel(far).distance(panel.to_pixel(start));
    assert!(apart > 14.0, "the walker moved {apart} pixels");
    // The marker: a disc of the agent's colour, radius 5, at the frame's pose.
    let at =
        |frame: usize, p: Vec2| count_near(&canvases[frame], &panel, (mx, my), p, 3, AGENT_PATH);
    // A radius-3 disc holds 29 pixels; the heading tick may cross a few of them.
    assert!(at(0, start) >= 20, "frame 0 at the start: {}", at(0, start));
    assert!(at(k, far) >= 20, "frame {k} at its pose: {}", at(k, far));
    // Before the walk the agent is not at the far pose: neither marker nor path is drawn there.
    assert!(
        at(0, far) <= 8,
        "frame 0 at frame {k}'s pose: {}",
        at(0, far)
    );
}

#[test]
fn the_same_inputs_give_the_same_bytes_with_any_thread_count() {
    let rec = walker();
    let a = gif(&rec);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = pool.install(|| gif(&rec));
    assert!(a == b, "two calls gave different GIFs");
}

#[test]
fn a_faulted_episode_or_bad_frames_are_errors() {
    let f = fixture();
    let mut rec = walker();
    rec.record = None;
    let e = video::episode_gif(
        &f.ctx,
        &config(),
        &f.ctx.semantic,
        &f.ctx.pathfinder.grid,
        &rec,
        "",
        VideoSize::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains(&rec.episode_id), "{e}");
    assert!(video::encode_gif(&[], 25).is_err());
    let a = Canvas::new(4, 4, [0; 3], Vec2::ZERO, 1.0, 4);
    let b = Canvas::new(4, 5, [0; 3], Vec2::ZERO, 1.0, 5);
    let e = video::encode_gif(&[a.clone(), b], 25).unwrap_err();
    assert!(e.to_string().contains("frame 1"), "{e}");
    let (_, _, decoded) = decode(&video::encode_gif(&[a.clone(), a], 10).unwrap());
    let delays: Vec<u16> = decoded.iter().map(|d| d.1).collect();
    assert_eq!(delays, [10, video::END_DELAY]);
}

/// A copy of the fixture's run folder (no report yet).
fn copy_run(to: &Path) -> PathBuf {
    let copy = to.join("run");
    std::fs::create_dir_all(&copy).unwrap();
    for name in ["summary.json", "episodes.jsonl", "sage3d_run.json"] {
        std::fs::copy(fixture().run.join(name), copy.join(name)).unwrap();
    }
    copy
}

fn write_report(run: &Path, videos: usize) -> report::ReportOutcome {
    let options = ReportOptions {
        videos,
        ..ReportOptions::default()
    };
    let seen = std::sync::Mutex::new(Vec::new());
    let outcome = report::write_with_options(
        run,
        &fixture().scenes,
        &options,
        &|_, _| {},
        &|id, total| {
            seen.lock().unwrap().push((id.to_string(), total));
        },
    )
    .unwrap();
    let seen = seen.into_inner().unwrap();
    assert_eq!(seen.len(), outcome.videos);
    assert!(seen.iter().all(|(_, t)| *t == outcome.videos));
    outcome
}

/// The scored records of a run as the report's gallery takes them.
fn scored_maps(records: &[EvalRecord]) -> Vec<report::MapFile<'_>> {
    records
        .iter()
        .filter(|r| r.record.is_some())
        .map(|r| report::MapFile {
            record: r,
            rel_path: String::new(),
        })
        .collect()
}

#[test]
fn the_report_writes_the_videos_asked_for_in_gallery_order_and_shows_them() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_run(dir.path());
    let videos_dir = run.join("report").join(video::VIDEOS_DIR);

    let outcome = write_report(&run, 0);
    assert_eq!(outcome.videos, 0);
    assert!(!videos_dir.exists());
    let html = std::fs::read_to_string(&outcome.html).unwrap();
    assert!(!html.contains("Episode videos"));

    let outcome = write_report(&run, 2);
    assert_eq!(outcome.videos, 2);
    let html = std::fs::read_to_string(&outcome.html).unwrap();
    let files = report::read_run(&run).unwrap();
    let maps = scored_maps(&files.records);
    let order = report::gallery_order(&maps);
    let section = &html[html.find("<h2 id=\"videos\">Episode videos</h2>").unwrap()..];
    let section = &section[..section.find("<h2>").unwrap()];
    let mut written: Vec<String> = std::fs::read_dir(&videos_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    written.sort();
    let mut expected: Vec<String> = order[..2]
        .iter()
        .map(|m| report::video_file_name(&m.record.episode_id))
        .collect();
    // The page shows them in gallery order.
    let first = section
        .find(&format!("report/videos/{}", expected[0]))
        .unwrap();
    let second = section
        .find(&format!("report/videos/{}", expected[1]))
        .unwrap();
    assert!(first < second);
    expected.sort();
    assert_eq!(written, expected);
    for name in &written {
        let bytes = std::fs::read(videos_dir.join(name)).unwrap();
        let (_, _, frames) = decode(&bytes);
        let rec = order
            .iter()
            .find(|m| report::video_file_name(&m.record.episode_id) == *name)
            .unwrap()
            .record;
        assert_eq!(frames.len(), rec.record.as_ref().unwrap().steps.len() + 1);
        assert!(section.contains(&format!("src=\"report/videos/{name}\"")));
    }

    // More than there are: one per episode with a record.
    let outcome = write_report(&run, 1000);
    assert_eq!(outcome.videos, maps.len());
    assert_eq!(std::fs::read_dir(&videos_dir).unwrap().count(), maps.len());
}

#[test]
fn a_rewritten_report_removes_the_videos_it_no_longer_shows_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_run(dir.path());
    let videos_dir = run.join("report").join(video::VIDEOS_DIR);
    let gifs = || {
        let mut names: Vec<String> = std::fs::read_dir(&videos_dir)
            .map(|d| {
                d.map(|e| e.unwrap().file_name().into_string().unwrap())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    };
    let shown = |outcome: &report::ReportOutcome| {
        let html = std::fs::read_to_string(&outcome.html).unwrap();
        let mut names: Vec<String> = html
            .match_indices("src=\"report/videos/")
            .map(|(at, m)| {
                let rest = &html[at + m.len()..];
                rest[..rest.find('"').unwrap()].to_string()
            })
            .collect();
        names.sort();
        names
    };
    let three = write_report(&run, 3);
    assert_eq!(three.videos, 3.min(records().len()));
    assert_eq!(gifs(), shown(&three));
    // Files of the user's beside them: another GIF, another kind of file.
    std::fs::write(videos_dir.join("mine.gif"), "GIF89a").unwrap();
    std::fs::write(videos_dir.join("notes.txt"), "keep").unwrap();
    let one = write_report(&run, 1);
    let mut expected = shown(&one);
    assert_eq!(expected.len(), 1);
    expected.extend(["mine.gif".to_string(), "notes.txt".to_string()]);
    expected.sort();
    assert_eq!(gifs(), expected);
    let none = write_report(&run, 0);
    assert!(shown(&none).is_empty());
    assert_eq!(gifs(), ["mine.gif", "notes.txt"]);
    // Without files of the user's, the folder goes with the last video.
    std::fs::remove_file(videos_dir.join("mine.gif")).unwrap();
    std::fs::remove_file(videos_dir.join("notes.txt")).unwrap();
    write_report(&run, 1);
    write_report(&run, 0);
    assert!(!videos_dir.exists());
}

#[test]
fn the_videos_show_the_camera_the_run_recorded_and_the_presets_for_older_runs() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_run(dir.path());
    let record_path = run.join("sage3d_run.json");
    let mut record: serde_json::Value = sage_io::files::read_json(&record_path).unwrap();
    // A run in an environment of its own (a Python run's overrides): a lower, narrower camera,
    // recorded as rendered on the GPU, which the report does not use.
    let own = EnvConfig {
        sensors: sage_env::SensorConfig {
            hfov_deg: 60.0,
            camera_height: Some(0.5),
            ..config().sensors
        },
        device: Device::Gpu,
        ..config()
    };
    record["env"] = serde_json::to_value(&own).unwrap();
    sage_io::files::write_json(&record_path, &record).unwrap();
    write_report(&run, 1);
    let files = report::read_run(&run).unwrap();
    let maps = scored_maps(&files.records);
    let first = report::gallery_order(&maps)[0].record;
    let instructions = report::read_instructions(&files.run, &files.summary.split).unwrap();
    let gif_in = |config: &EnvConfig| {
        let f = fixture();
        video::episode_gif(
            &f.ctx,
            config,
            &f.ctx.semantic,
            &f.ctx.pathfinder.grid,
            first,
            &instructions[&first.episode_id],
            VideoSize::default(),
        )
        .unwrap()
    };
    let written = || {
        std::fs::read(
            run.join("report")
                .join(video::VIDEOS_DIR)
                .join(report::video_file_name(&first.episode_id)),
        )
        .unwrap()
    };
    let on_cpu = EnvConfig {
        device: Device::Cpu,
        ..own
    };
    let recorded = written();
    assert_eq!(recorded, gif_in(&on_cpu));
    assert_ne!(recorded, gif_in(&config()));

    // A run recorded before the environment was: the preset its settings name.
    record.as_object_mut().unwrap().remove("env");
    sage_io::files::write_json(&record_path, &record).unwrap();
    write_report(&run, 1);
    assert_eq!(written(), gif_in(&config()));

    // An environment the record holds but no config reads is named.
    record["env"] = serde_json::json!({"agent": "wheeled", "lens": 3});
    sage_io::files::write_json(&record_path, &record).unwrap();
    let e = report::write_with_options(
        &run,
        &fixture().scenes,
        &ReportOptions {
            videos: 1,
            ..ReportOptions::default()
        },
        &|_, _| {},
        &|_, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("sage3d_run.json: env") && e.contains("lens"),
        "{e}"
    );
}
