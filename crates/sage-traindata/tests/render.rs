//! Training-data renders on a small generated home: the formats' contents against the walks,
//! determinism over thread counts, resumption of a broken render, dropped walks leaving no
//! frames, NaVILA's wording of the answers, and bad input.

mod common;

use sage_traindata::encode::RgbCodec;
use sage_traindata::output::NavilaSample;
use sage_traindata::preset::Answers;
use sage_traindata::replay::Verdict;
use sage_traindata::sample::{EpisodeSample, RouteRecord};
use sage_traindata::{Layout, Settings};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A 3-room home and its dataset (every episode in `train`), built once: (scenes, dataset).
fn data() -> (&'static Path, &'static Path) {
    static DATA: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    let d = DATA.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (scenes, dataset) = common::home_dataset(dir.path(), 6);
        (dir, scenes, dataset)
    });
    (&d.1, &d.2)
}

fn settings(format: Layout) -> Settings {
    let (scenes, dataset) = data();
    Settings {
        width: 48,
        height: 36,
        format,
        keep_failed: true,
        shard_size: 7,
        ..Settings::new(dataset, scenes).unwrap()
    }
}

/// Every file under `root` (relative path → bytes), the run record aside (it names the
/// command, not the data).
fn tree(root: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut t = sage_io::files::read_tree(root).unwrap();
    t.remove("sage3d_run.json");
    t
}

fn render_with_threads(s: &Settings, out: &Path, threads: usize) -> sage_traindata::Manifest {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| sage_traindata::render(s, out, false, &|_| {}))
        .unwrap()
}

#[test]
fn navila_samples_match_the_walks_and_the_bytes_do_not_depend_on_threads() {
    let s = settings(Layout::Navila);
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let m = render_with_threads(&s, a.path(), 1);
    render_with_threads(&s, b.path(), 2);
    assert_eq!(tree(a.path()), tree(b.path()));
    assert!(m.counts.kept > 3 && m.counts.skipped == 0, "{:?}", m.counts);

    let info: serde_json::Value =
        sage_io::files::read_json(&a.path().join("dataset_info.json")).unwrap();
    let parts: Vec<String> = serde_json::from_value(info["part_files"].clone()).unwrap();
    assert_eq!(info["total_samples"], m.counts.samples);
    assert_eq!(parts.len(), m.counts.samples.div_ceil(7));
    assert_eq!(info["data_format"]["move_distance"], "0.35 meter");
    let mut samples = Vec::new();
    for p in &parts {
        let part: Vec<sage_traindata::output::NavilaSample> =
            sage_io::files::read_json(&a.path().join(p)).unwrap();
        assert!(part.len() <= 7);
        samples.extend(part);
    }
    assert_eq!(samples.len(), m.counts.samples);
    let allowed = [
        "The next action is move forward 0.35 meter.",
        "The next action is turn left 30 degree.",
        "The next action is turn right 30 degree.",
        "The next action is stop.",
    ];
    for x in &samples {
        assert!(allowed.contains(&x.a.as_str()), "{}", x.a);
        let step: usize = x.video_id.rsplit('-').next().unwrap().parse().unwrap();
        assert_eq!(x.frames.len(), step + 1, "{}", x.video_id);
        for (k, f) in x.frames.iter().enumerate() {
            assert!(f.ends_with(&format!("/{k:04}.jpg")), "{f}");
            let bytes = std::fs::read(a.path().join("images").join(f)).unwrap();
            let mut dec = zune_jpeg::JpegDecoder::new(bytes.as_slice());
            dec.decode_headers().unwrap();
            assert_eq!(dec.dimensions(), Some((48, 36)));
        }
        // Each episode's last sample is its STOP.
    }
    let stops = samples.iter().filter(|x| x.a.ends_with("stop.")).count();
    assert_eq!(stops, m.counts.kept);
}

#[test]
fn walks_record_commanded_and_achieved_poses_from_the_episode_start() {
    let s = settings(Layout::Frames);
    let out = tempfile::tempdir().unwrap();
    let m = render_with_threads(&s, out.path(), 2);
    let text = std::fs::read_to_string(out.path().join("episodes.jsonl")).unwrap();
    let episodes: Vec<sage_traindata::sample::EpisodeSample> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(episodes.len(), m.counts.kept);
    let (_, dataset) = data();
    let (_, source) = sage_dataset::folder::split_episodes(dataset, "train").unwrap();
    let by_id: BTreeMap<&str, &sage_dataset::Episode> =
        source.iter().map(|e| (e.episode_id.as_str(), e)).collect();
    let step = 0.35f32;
    let turn = 30f32.to_radians();
    let mut rotations = 0;
    for e in &episodes {
        let src = by_id[e.episode_id.as_str()];
        assert_eq!(e.instruction, src.instruction);
        assert_eq!(e.actions.last().map(String::as_str), Some("STOP"));
        assert_eq!(e.files.len(), e.actions.len());
        assert_eq!(e.steps.len(), e.actions.len());
        if src.reference_path.len() == 1 {
            // A rotation in place: whole preset turns one way, as far as the dataset's turns
            // go (15 degrees each), then STOP, without moving.
            let net: i32 = src
                .actions
                .iter()
                .map(|a| match a {
                    sage_lang::DiscreteAction::Left => 1,
                    sage_lang::DiscreteAction::Right => -1,
                    _ => 0,
                })
                .sum();
            let turns = sage_traindata::replay::turns_in_place(net as f32 * 15.0, &s.preset);
            assert!(turns != 0, "{}", e.episode_id);
            let name = if turns > 0 { "TURN_LEFT" } else { "TURN_RIGHT" };
            assert_eq!(e.actions.len(), turns.unsigned_abs() as usize + 1);
            assert!(e.actions[..e.actions.len() - 1].iter().all(|a| a == name));
            let (a, b) = (e.steps[0].pose, e.steps.last().unwrap().achieved);
            assert!((a[0] - b[0]).abs() < 1e-4 && (a[1] - b[1]).abs() < 1e-4);
            rotations += 1;
        }
        let first = e.steps[0].pose;
        assert!((first[0] - src.start.position[0]).abs() < 1e-5);
        assert!((first[1] - src.start.position[1]).abs() < 1e-5);
        assert!((first[2] - src.start.yaw).abs() < 1e-5);
        for w in e.steps.windows(2) {
            // Each frame is taken where the previous action left the agent.
            assert_eq!(w[1].pose, w[0].achieved);
        }
        for st in &e.steps {
            let moved = ((st.commanded[0] - st.pose[0]).powi(2)
                + (st.commanded[1] - st.pose[1]).powi(2))
            .sqrt();
            let turned = sage_core::wrap_angle(st.commanded[2] - st.pose[2]);
            match st.action.as_str() {
                "MOVE_FORWARD" => assert!((moved - step).abs() < 1e-4 && turned.abs() < 1e-5),
                "TURN_LEFT" => assert!(moved < 1e-6 && (turned - turn).abs() < 1e-4),
                "TURN_RIGHT" => assert!(moved < 1e-6 && (turned + turn).abs() < 1e-4),
                _ => assert!(moved < 1e-6 && turned.abs() < 1e-6),
            }
            if !st.contact && e.verdict == sage_traindata::replay::Verdict::Clean {
                // Free motion: physics achieves what was commanded.
                let err = ((st.achieved[0] - st.commanded[0]).powi(2)
                    + (st.achieved[1] - st.commanded[1]).powi(2))
                .sqrt();
                assert!(err < 0.02, "{} {:?}", e.episode_id, st);
            }
        }
        if e.verdict == sage_traindata::replay::Verdict::Clean {
            assert!(e.steps.iter().all(|s| !s.contact));
        }
    }
    assert!(
        rotations > 0,
        "the dataset's rotations in place are rendered"
    );
}

#[test]
fn webdataset_shards_hold_every_frame_and_the_sample_json() {
    let mut s = settings(Layout::Webdataset);
    s.sensors = "rgb,depth,semantic".parse().unwrap();
    s.shard_size = 4;
    let out = tempfile::tempdir().unwrap();
    let m = render_with_threads(&s, out.path(), 2);
    assert!(
        !out.path().join("images").exists(),
        "the shards hold the frames"
    );
    let shards: Vec<_> = m.files.iter().map(|f| f.path.clone()).collect();
    assert_eq!(shards.len(), m.counts.kept.div_ceil(4));
    let mut seen = 0;
    for shard in &shards {
        let bytes = std::fs::read(out.path().join(shard)).unwrap();
        assert_eq!(
            sage_io::hash::fnv1a64_hex(&bytes),
            m.files.iter().find(|f| &f.path == shard).unwrap().fnv1a64
        );
        let mut files: BTreeMap<String, Vec<u8>> = BTreeMap::new();
        let mut archive = tar::Archive::new(std::io::Cursor::new(bytes));
        for entry in archive.entries().unwrap() {
            let mut entry = entry.unwrap();
            let name = entry.path().unwrap().to_string_lossy().into_owned();
            let mut data = Vec::new();
            std::io::Read::read_to_end(&mut entry, &mut data).unwrap();
            files.insert(name, data);
        }
        for (name, json) in files.iter().filter(|(n, _)| n.ends_with(".json")) {
            seen += 1;
            let key = name.trim_end_matches(".json");
            assert!(!key.contains('.'), "{key}");
            let e: sage_traindata::sample::EpisodeSample = serde_json::from_slice(json).unwrap();
            assert_eq!(e.files.len(), e.actions.len());
            for (k, frame) in e.files.iter().enumerate() {
                let want = [
                    format!("{k:04}.jpg"),
                    format!("{k:04}.depth.png"),
                    format!("{k:04}.semantic.png"),
                ];
                assert_eq!(frame.as_slice(), &want);
                for f in frame {
                    assert!(files.contains_key(&format!("{key}.{f}")), "{key}.{f}");
                }
                let depth = png::Decoder::new(std::io::Cursor::new(
                    files[&format!("{key}.{k:04}.depth.png")].clone(),
                ))
                .read_info()
                .unwrap();
                let info = depth.info();
                assert_eq!((info.width, info.height), (48, 36));
                assert_eq!(info.bit_depth, png::BitDepth::Sixteen);
            }
        }
    }
    assert_eq!(seen, m.counts.kept);
    // Stopped after its manifest, before it removed the route folders the shards were made
    // from: the rerun finds the render finished and removes them.
    let before = tree(out.path());
    let frames = tempfile::tempdir().unwrap();
    render_with_threads(&settings(Layout::Frames), frames.path(), 2);
    copy_tree(&frames.path().join("images"), &out.path().join("images"));
    let again = sage_traindata::render(&s, out.path(), false, &|_| {}).unwrap();
    assert_eq!(again, m);
    assert_eq!(tree(out.path()), before);
}

/// Copies folder `from` into `to` (made), file by file.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let target = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_tree(&p, &target);
        } else {
            std::fs::copy(&p, &target).unwrap();
        }
    }
}

#[test]
fn a_broken_render_resumes_to_the_same_bytes_and_a_finished_one_is_left_alone() {
    let s = settings(Layout::Navila);
    let (whole, broken) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    render_with_threads(&s, whole.path(), 2);
    render_with_threads(&s, broken.path(), 2);
    // A crash mid-route: one route's record is gone and a frame cut short; the parts and the
    // manifest were never written.
    let images = broken.path().join("images").join("home1");
    let route = std::fs::read_dir(&images)
        .unwrap()
        .map(|e| e.unwrap().path())
        .min()
        .unwrap();
    std::fs::remove_file(route.join("route.json")).unwrap();
    std::fs::write(route.join("0001.jpg"), b"\xff\xd8").unwrap();
    for f in [
        "manifest.json",
        "dataset_info.json",
        "annotations_part_000.json",
    ] {
        std::fs::remove_file(broken.path().join(f)).unwrap();
    }
    let rendered = std::sync::atomic::AtomicUsize::new(0);
    sage_traindata::render(&s, broken.path(), false, &|p| {
        if let sage_traindata::Progress::Route(_) = p {
            rendered.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    })
    .unwrap();
    assert_eq!(
        rendered.into_inner(),
        1,
        "only the broken route is walked again"
    );
    assert_eq!(tree(whole.path()), tree(broken.path()));
    // Finished: nothing is walked again.
    let again = std::sync::atomic::AtomicUsize::new(0);
    sage_traindata::render(&s, broken.path(), false, &|p| {
        if let sage_traindata::Progress::Route(_) = p {
            again.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    })
    .unwrap();
    assert_eq!(again.into_inner(), 0);
}

#[test]
fn other_settings_or_foreign_files_in_the_output_are_refused() {
    let s = settings(Layout::Frames);
    let out = tempfile::tempdir().unwrap();
    render_with_threads(&s, out.path(), 2);
    let other = Settings {
        seed: 9,
        ..s.clone()
    };
    let err = sage_traindata::render(&other, out.path(), false, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("other settings") && err.contains("`force`"),
        "{err}"
    );
    // With force the old render's files are replaced.
    sage_traindata::render(&other, out.path(), true, &|_| {}).unwrap();

    let foreign = tempfile::tempdir().unwrap();
    std::fs::write(foreign.path().join("notes.txt"), "mine").unwrap();
    for force in [false, true] {
        let err = sage_traindata::render(&s, foreign.path(), force, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(err.contains("notes.txt"), "{err}");
    }
    assert_eq!(
        std::fs::read_to_string(foreign.path().join("notes.txt")).unwrap(),
        "mine"
    );
    // Nor is a file of the user's inside a render's own folders, which `force` would remove
    // with the folder: the frames, a route's, the WebDataset shards, LeRobot's data and meta.
    let rendered = tempfile::tempdir().unwrap();
    render_with_threads(&s, rendered.path(), 2);
    let route = std::fs::read_dir(rendered.path().join("images"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let route = std::fs::read_dir(route)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let route = route
        .strip_prefix(rendered.path())
        .unwrap()
        .to_str()
        .unwrap()
        .to_string();
    for mine in [
        "images/notes.txt".to_string(),
        "images/mine/keep.txt".to_string(),
        format!("{route}/notes.json"),
        format!("{route}/0000.jpg.bak"),
        format!("{route}/deeper/0000.jpg"),
        "shards/readme.md".to_string(),
        "meta/extra.json".to_string(),
        "data/chunk-000/mine.parquet".to_string(),
    ] {
        let path = rendered.path().join(&mine);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, "mine").unwrap();
        for force in [false, true] {
            let err = sage_traindata::render(&other, rendered.path(), force, &|_| {})
                .unwrap_err()
                .to_string();
            assert!(err.contains(&format!("'{mine}'")), "{mine}: {err}");
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "mine", "{mine}");
        std::fs::remove_file(&path).unwrap();
    }
    // Without them, the same folder is the render's again.
    sage_traindata::render(&other, rendered.path(), true, &|_| {}).unwrap();

    // Files with a render's names in another command's folder are not a render's either.
    let eval = tempfile::tempdir().unwrap();
    sage_io::run::write_run_record(eval.path(), "eval", Some(0), serde_json::json!({})).unwrap();
    std::fs::write(eval.path().join("episodes.jsonl"), "{}\n").unwrap();
    for force in [false, true] {
        let err = sage_traindata::render(&s, eval.path(), force, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a training-data render"), "{err}");
    }
    assert_eq!(
        std::fs::read_to_string(eval.path().join("episodes.jsonl")).unwrap(),
        "{}\n"
    );
}

/// Every file a render writes, in any layout and with every image, is one `force` may replace:
/// a render with other settings takes the folder over.
#[test]
fn force_replaces_a_render_of_any_layout() {
    let every_image = sage_traindata::Sensors {
        rgb: true,
        depth: true,
        semantic: true,
        instance: true,
    };
    for (format, sensors, codec) in [
        (Layout::Frames, every_image, RgbCodec::Png),
        (
            Layout::Webdataset,
            every_image,
            RgbCodec::Jpeg { quality: 80 },
        ),
        (Layout::Lerobot, Default::default(), RgbCodec::Png),
    ] {
        let s = Settings {
            sensors,
            rgb_codec: codec,
            limit: Some(4),
            ..settings(format)
        };
        let out = tempfile::tempdir().unwrap();
        render_with_threads(&s, out.path(), 2);
        let other = Settings { seed: 5, ..s };
        let replaced = sage_traindata::render(&other, out.path(), true, &|_| {});
        assert!(replaced.is_ok(), "{format:?}: {:?}", replaced.err());
    }
}

#[test]
fn failed_walks_are_counted_dropped_or_kept_and_a_render_keeping_none_writes_no_layout() {
    // Only episodes that must walk a metre or more, and one motion each: no walk reaches its
    // goal, and failed walks are not kept.
    let (scenes, dataset) = data();
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("data");
    std::fs::create_dir_all(copy.join("episodes")).unwrap();
    let text = std::fs::read_to_string(dataset.join("episodes/train.jsonl")).unwrap();
    let far: Vec<&str> = text
        .lines()
        .filter(|l| {
            let e: serde_json::Value = serde_json::from_str(l).unwrap();
            e["goal"].is_object() && e["geodesic_distance"].as_f64().unwrap() > 1.0
        })
        .collect();
    assert!(!far.is_empty());
    std::fs::write(copy.join("episodes/train.jsonl"), far.join("\n")).unwrap();
    let mut s = Settings {
        width: 32,
        height: 24,
        format: Layout::Lerobot,
        ..Settings::new(&copy, scenes).unwrap()
    };
    s.preset.max_actions = 1;
    let out = dir.path().join("out");
    let e = sage_traindata::render(&s, &out, false, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no episode was kept") && e.contains("dropped"),
        "{e}"
    );
    for made in ["meta", "data", "manifest.json"] {
        assert!(!out.join(made).exists(), "{made}");
    }
    // Kept on request, the same walks are counted by their verdict all the same.
    s.keep_failed = true;
    let out = dir.path().join("kept");
    let m = sage_traindata::render(&s, &out, false, &|_| {}).unwrap();
    assert!(m.counts.dropped.is_empty(), "{:?}", m.counts);
    assert_eq!(
        m.counts.kept_failed.values().sum::<usize>(),
        m.counts.kept,
        "{:?}",
        m.counts
    );
    assert!(
        m.counts.kept_failed.contains_key("far_from_goal"),
        "{:?}",
        m.counts
    );
}

#[test]
fn episodes_of_a_missing_scene_are_skipped_with_the_reason_and_the_rest_rendered() {
    let (scenes, dataset) = data();
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("data");
    std::fs::create_dir_all(copy.join("episodes")).unwrap();
    let text = std::fs::read_to_string(dataset.join("episodes/train.jsonl")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let lost = lines
        .iter()
        .position(|l| l.contains("\"task\":\"vln\"") && l.contains("reference_path"))
        .unwrap();
    lines[lost] = lines[lost].replace("\"scene\":\"home1\"", "\"scene\":\"attic9\"");
    std::fs::write(copy.join("episodes/train.jsonl"), lines.join("\n")).unwrap();
    let s = Settings {
        width: 32,
        height: 24,
        format: Layout::Frames,
        rgb_codec: RgbCodec::Png,
        ..Settings::new(&copy, scenes).unwrap()
    };
    let out = dir.path().join("out");
    let m = sage_traindata::render(&s, &out, false, &|_| {}).unwrap();
    assert_eq!(m.counts.skipped, 1);
    assert!(m.skipped_any());
    assert!(m.skipped[0].reason.contains("attic9"), "{:?}", m.skipped);
    assert!(m.counts.kept + m.counts.dropped.values().sum::<usize>() > 0);
    let first = std::fs::read_to_string(out.join("episodes.jsonl")).unwrap();
    assert!(first.contains(".png"));
}

#[test]
fn a_limit_counts_as_ignored_only_the_episodes_it_reads() {
    use sage_traindata::run::Plan;
    // The split: an episode with nothing to walk, two goal-directed ones, another with
    // nothing to walk.
    let (scenes, dataset) = data();
    let text = std::fs::read_to_string(dataset.join("episodes/train.jsonl")).unwrap();
    let goal: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|e| e["goal"].is_object() && e["reference_path"].as_array().unwrap().len() >= 2)
        .take(2)
        .collect();
    let still = |id: &str| {
        let mut e = goal[0].clone();
        e["episode_id"] = id.into();
        e["reference_path"] = serde_json::json!([e["reference_path"][0]]);
        e["actions"] = serde_json::json!([0]);
        e
    };
    let lines: Vec<String> = [
        still("still_a"),
        goal[0].clone(),
        goal[1].clone(),
        still("still_b"),
    ]
    .iter()
    .map(|e| e.to_string())
    .collect();
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("data");
    std::fs::create_dir_all(copy.join("episodes")).unwrap();
    std::fs::write(copy.join("episodes/train.jsonl"), lines.join("\n")).unwrap();
    let plan = |limit: Option<usize>| {
        let s = Settings {
            limit,
            ..Settings::new(&copy, scenes).unwrap()
        };
        let plan = Plan::new(&s).unwrap();
        let episodes: usize = plan
            .routes
            .values()
            .flatten()
            .map(|r| r.episodes.len())
            .sum();
        (
            episodes,
            plan.ignored.get("no_motion").copied().unwrap_or(0),
        )
    };
    assert_eq!(plan(None), (2, 2));
    assert_eq!(plan(Some(2)), (2, 1));
    assert_eq!(plan(Some(1)), (1, 1));
}

#[test]
fn a_gpu_render_walks_in_lockstep_and_each_walk_is_what_it_gives_alone() {
    use sage_splat::Device;
    use sage_traindata::replay::{self, Walk};
    use sage_traindata::run::{Plan, route_dir};
    let s = Settings {
        device: Device::Gpu,
        ..settings(Layout::Navila)
    };
    let out = tempfile::tempdir().unwrap();
    let manifest = match sage_traindata::render(&s, out.path(), false, &|_| {}) {
        Ok(m) => m,
        Err(e) if std::env::var_os("SAGE3D_REQUIRE_GPU").is_none() => {
            eprintln!("no GPU renderer here, GPU test not run: {e}");
            return;
        }
        Err(e) => panic!("SAGE3D_REQUIRE_GPU is set and the GPU render failed: {e}"),
    };
    assert_eq!(manifest.counts.skipped, 0, "{:?}", manifest.counts);
    // The walks are physics alone: the same as the CPU render's.
    let cpu = tempfile::tempdir().unwrap();
    let cpu_manifest = render_with_threads(&settings(Layout::Navila), cpu.path(), 2);
    assert_eq!(manifest.counts, cpu_manifest.counts);
    // Every route walked alone on the GPU writes the frames the lockstep render wrote.
    let plan = Plan::new(&s).unwrap();
    // Routes of one scene are shared between the two cohorts of the lockstep render.
    assert!(
        plan.routes.values().any(|r| r.len() >= 2),
        "{:?}",
        plan.routes.keys()
    );
    let mut frames = 0;
    for (scene, routes) in &plan.routes {
        let ctx = std::sync::Arc::new(
            sage_env::SceneContext::load(&plan.scene_dirs[scene], None).unwrap(),
        );
        let mut env = sage_env::Env::new(ctx, plan.env.clone()).unwrap();
        assert!(env.renders_in_scene_batches());
        for route in routes {
            let dir = route_dir(out.path(), route);
            let walk = replay::walk(
                &mut env,
                route,
                &s.preset,
                plan.dataset_turn_deg,
                |k, img| {
                    for (suffix, bytes) in sage_traindata::encode::encode(img, s.rgb_codec)? {
                        let written = std::fs::read(dir.join(format!("{k:04}.{suffix}"))).unwrap();
                        assert!(written == bytes, "{}: frame {k} differs", route.name);
                        frames += 1;
                    }
                    Ok(())
                },
            )
            .unwrap();
            let record: serde_json::Value =
                sage_io::files::read_json(&dir.join(sage_traindata::sample::ROUTE_FILE)).unwrap();
            let lockstep: Walk = serde_json::from_value(record["walk"].clone()).unwrap();
            assert_eq!(lockstep, walk, "{}", route.name);
        }
    }
    assert!(frames > 20, "{frames} frames compared");
}

/// The frame files under `out/images` (every file but the routes' records).
fn frame_files(out: &Path) -> BTreeSet<String> {
    tree(&out.join("images"))
        .into_keys()
        .filter(|k| !k.ends_with("/route.json"))
        .collect()
}

/// The frame files the annotations of `out` name: the NaVILA parts' frames, or every file of
/// `episodes.jsonl`.
fn named_frames(out: &Path, format: Layout) -> BTreeSet<String> {
    match format {
        Layout::Navila => {
            let info: serde_json::Value =
                sage_io::files::read_json(&out.join("dataset_info.json")).unwrap();
            let parts: Vec<String> = serde_json::from_value(info["part_files"].clone()).unwrap();
            parts
                .iter()
                .flat_map(|p| sage_io::files::read_json::<Vec<NavilaSample>>(&out.join(p)).unwrap())
                .flat_map(|x| x.frames)
                .collect()
        }
        _ => std::fs::read_to_string(out.join("episodes.jsonl"))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<EpisodeSample>(l).unwrap())
            .flat_map(|e| e.files.into_iter().flatten())
            .collect(),
    }
}

#[test]
fn a_dropped_walk_leaves_no_frame_that_no_annotation_names() {
    // Six motions at most: most walks stop far from their goal and are dropped.
    for format in [Layout::Navila, Layout::Frames] {
        let mut s = Settings {
            keep_failed: false,
            ..settings(format)
        };
        s.preset.max_actions = 6;
        let out = tempfile::tempdir().unwrap();
        let rendered = std::sync::atomic::AtomicUsize::new(0);
        let m = sage_traindata::render(&s, out.path(), false, &|p| {
            if let sage_traindata::Progress::Route(r) = p {
                rendered.fetch_add(r.frames, std::sync::atomic::Ordering::Relaxed);
            }
        })
        .unwrap();
        let dropped: usize = m.counts.dropped.values().sum();
        assert!(m.counts.kept > 0 && dropped > 0, "{:?}", m.counts);
        // The frames reported are the frames kept: a dropped walk is known from physics alone,
        // before any frame of it is rendered.
        let kept_frames = frame_files(out.path())
            .iter()
            .filter(|f| f.ends_with(".jpg"))
            .count();
        assert_eq!(rendered.into_inner(), kept_frames, "{format}");
        assert_eq!(
            frame_files(out.path()),
            named_frames(out.path(), format),
            "{format}"
        );
        // A dropped route keeps its record: it is done, and says why its episodes are left out.
        let records: Vec<PathBuf> = tree(&out.path().join("images"))
            .into_keys()
            .filter(|k| k.ends_with("/route.json"))
            .map(|k| out.path().join("images").join(k))
            .collect();
        let failed: Vec<&PathBuf> = records
            .iter()
            .filter(|p| {
                let r: RouteRecord = sage_io::files::read_json(p).unwrap();
                r.walk.unwrap().verdict != Verdict::Clean
            })
            .collect();
        assert!(!failed.is_empty());
        // Those walks are the walks a render that keeps failed walks records after rendering
        // their frames.
        let all = tempfile::tempdir().unwrap();
        let keep = Settings {
            keep_failed: true,
            ..s.clone()
        };
        render_with_threads(&keep, all.path(), 2);
        for record in &records {
            let twin = all.path().join(record.strip_prefix(out.path()).unwrap());
            let (a, b): (RouteRecord, RouteRecord) = (
                sage_io::files::read_json(record).unwrap(),
                sage_io::files::read_json(&twin).unwrap(),
            );
            assert_eq!(a.walk, b.walk, "{}", record.display());
        }
        for record in &failed {
            let folder: Vec<_> = std::fs::read_dir(record.parent().unwrap())
                .unwrap()
                .collect();
            assert_eq!(folder.len(), 1, "{}", record.display());
        }
        let whole = tree(out.path());

        // A crash before the layout was written, in a folder whose dropped route still has a
        // frame (rendered before dropped walks left none): the resume walks nothing again and
        // removes the frame.
        let stray = failed[0].with_file_name("0000.jpg");
        std::fs::write(&stray, b"\xff\xd8").unwrap();
        std::fs::remove_file(out.path().join("manifest.json")).unwrap();
        let walked = std::sync::atomic::AtomicUsize::new(0);
        sage_traindata::render(&s, out.path(), false, &|p| {
            if let sage_traindata::Progress::Route(_) = p {
                walked.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        })
        .unwrap();
        assert_eq!(walked.into_inner(), 0);
        assert!(!stray.exists());
        assert_eq!(tree(out.path()), whole);
    }
}

#[test]
fn navila_answers_speak_centimetres_and_a_resume_must_keep_the_wording() {
    let mut s = Settings {
        limit: Some(4),
        ..settings(Layout::Navila)
    };
    s.preset = s.preset.worded(Answers::Navila).unwrap();
    let out = tempfile::tempdir().unwrap();
    let m = render_with_threads(&s, out.path(), 2);
    assert!(m.counts.samples > 0, "{:?}", m.counts);
    let info: serde_json::Value =
        sage_io::files::read_json(&out.path().join("dataset_info.json")).unwrap();
    assert_eq!(info["data_format"]["move_distance"], "35 cm");
    assert_eq!(info["data_format"]["turn_angle"], "30 degree");
    assert_eq!(info["conversion_params"]["answers"], "navila");
    assert_eq!(m.settings["preset"]["answers"], "navila");
    let allowed = [
        "The next action is move forward 35 cm.",
        "The next action is turn left 30 degree.",
        "The next action is turn right 30 degree.",
        "The next action is stop.",
    ];
    let parts: Vec<String> = serde_json::from_value(info["part_files"].clone()).unwrap();
    for p in &parts {
        for x in sage_io::files::read_json::<Vec<NavilaSample>>(&out.path().join(p)).unwrap() {
            assert!(allowed.contains(&x.a.as_str()), "{}", x.a);
        }
    }
    // The same folder with SAGE-3D's wording is another render, not a resume.
    let sage = Settings {
        preset: s.preset.clone().worded(Answers::Sage).unwrap(),
        ..s.clone()
    };
    let e = sage_traindata::render(&sage, out.path(), false, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("other settings"), "{e}");
    // A turn NaVILA's words cannot say is refused before the folder is touched.
    let mut half = s.clone();
    half.preset.turn_deg = 22.5;
    let fresh = tempfile::tempdir().unwrap();
    let e = sage_traindata::render(&half, &fresh.path().join("out"), false, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("`answers`") && e.contains("22.5"), "{e}");
    assert!(!fresh.path().join("out").exists());
}

/// An environment over `scene` of `plan` with `plan`'s configuration changed by `change`.
fn plan_env(
    plan: &sage_traindata::Plan,
    scene: &str,
    change: impl FnOnce(&mut sage_env::EnvConfig),
) -> sage_env::Env {
    let ctx = sage_env::SceneContext::load_with_bodies(
        &plan.scene_dirs[scene],
        None,
        &sage_scene::LoadOptions::default(),
        plan.env.splat_bodies,
    )
    .unwrap();
    let mut config = plan.env.clone();
    change(&mut config);
    sage_env::Env::new(std::sync::Arc::new(ctx), config).unwrap()
}

#[test]
fn a_rotation_in_place_turns_at_most_the_motion_cap_and_a_capped_one_is_not_clean() {
    use sage_traindata::replay::{self, net_turns, turns_in_place};
    let (scenes, dataset) = data();
    let mut s = Settings::new(dataset, scenes).unwrap();
    s.preset.max_actions = 1;
    let plan = sage_traindata::Plan::new(&s).unwrap();
    let (mut capped, mut whole) = (0, 0);
    for (scene, routes) in &plan.routes {
        let mut env = plan_env(&plan, scene, |c| c.sensors = c.sensors.without_images());
        for route in routes
            .iter()
            .filter(|r| r.episodes[0].reference_path.len() == 1)
        {
            let asked = turns_in_place(
                net_turns(&route.episodes[0]) as f32 * plan.dataset_turn_deg,
                &s.preset,
            )
            .unsigned_abs() as usize;
            let walk = replay::walk(&mut env, route, &s.preset, plan.dataset_turn_deg, |_, _| {
                Ok(())
            })
            .unwrap();
            let turns = &walk.steps[..walk.steps.len() - 1];
            assert_eq!(walk.steps.last().unwrap().action, "STOP");
            assert!(turns.iter().all(|t| t.action.starts_with("TURN_")));
            // One turn at most: the cap bounds the turns of a rotation as any other motion.
            assert_eq!(turns.len(), asked.min(1), "{}", route.name);
            if asked > 1 {
                // Short of the heading it was asked for: not a clean walk, whatever the distance.
                assert_eq!(walk.ending, "capped");
                assert_ne!(walk.verdict, Verdict::Clean);
                capped += 1;
            } else {
                assert_eq!(walk.ending, "reached");
                whole += 1;
            }
        }
    }
    assert!(
        capped > 0,
        "no rotation of more than one turn ({whole} of one)"
    );
}

#[test]
fn a_walk_whose_episode_the_environment_ends_stops_there_without_an_error() {
    use sage_traindata::replay;
    let (scenes, dataset) = data();
    let s = Settings {
        width: 32,
        height: 24,
        ..Settings::new(dataset, scenes).unwrap()
    };
    let plan = sage_traindata::Plan::new(&s).unwrap();
    let (scene, routes) = plan.routes.iter().next().unwrap();
    // A walk of more than three motions, in an environment whose episodes end at three steps.
    let mut free = plan_env(&plan, scene, |c| c.sensors = c.sensors.without_images());
    let route = routes
        .iter()
        .find(|r| {
            replay::walk(
                &mut free,
                r,
                &s.preset,
                plan.dataset_turn_deg,
                |_, _| Ok(()),
            )
            .unwrap()
            .steps
            .len()
                > 4
        })
        .expect("a walk of more than three motions");
    let mut env = plan_env(&plan, scene, |c| c.task.max_steps = 3);
    let mut frames = 0;
    let walk = replay::walk(&mut env, route, &s.preset, plan.dataset_turn_deg, |k, _| {
        assert_eq!(k, frames);
        frames += 1;
        Ok(())
    })
    .unwrap();
    // The third motion ended the episode; the walk calls STOP where that left the agent, as at
    // the motion cap, seen in a frame of its own.
    assert_eq!(walk.steps.len(), 4, "{:?}", walk.steps);
    assert_eq!(frames, walk.steps.len());
    assert!(walk.steps[..3].iter().all(|st| st.action != "STOP"));
    let stop = &walk.steps[3];
    assert_eq!(stop.action, "STOP");
    assert_eq!(stop.pose, walk.steps[2].achieved);
    assert_eq!((stop.commanded, stop.achieved), (stop.pose, stop.pose));
    assert!(!stop.contact);
    assert_eq!(walk.ending, "capped");
    let clean = walk.contact_steps == 0 && walk.final_distance.is_some_and(|d| d <= 1.0);
    assert_eq!(walk.verdict == Verdict::Clean, clean, "{walk:?}");
}
