//! The dataset pipeline on small synthetic scenes: same bytes with 1 and 2 threads, resume,
//! split rules, the balanced selector, and round trips through JSONL, GVLN and R2R-VLNCE.

use glam::Vec2;
use sage_core::frame::SageFrame;
use sage_core::wrap_angle;
use sage_dataset::build::{self, AssembleParams, SceneParams};
use sage_dataset::formats::gvln::{self, GvlnFrame};
use sage_dataset::formats::{jsonl, r2r};
use sage_dataset::selector::{select_balanced, stratum};
use sage_dataset::split::{self, SplitParams};
use sage_dataset::{Episode, Task};
use sage_io::files::read_tree;
use sage_io::runner::Status;
use sage_lang::InstructionType;
use sage_lang::actions::{StepSizes, follow, replay};
use sage_synth::{SynthConfig, generate};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Five small scenes, written once per test process.
fn scenes() -> &'static (tempfile::TempDir, Vec<PathBuf>) {
    static S: OnceLock<(tempfile::TempDir, Vec<PathBuf>)> = OnceLock::new();
    S.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let dirs = (1..=5)
            .map(|seed| {
                let s = generate(&SynthConfig {
                    seed,
                    rooms: 4,
                    objects: 40,
                    gaussians: 1000,
                    ..SynthConfig::default()
                })
                .unwrap();
                let d = dir.path().join(format!("scene{seed}"));
                s.save(&d, sage_scene::SplatLayout::Compressed).unwrap();
                d
            })
            .collect();
        (dir, dirs)
    })
}

fn params() -> (SceneParams, AssembleParams) {
    (
        SceneParams::new(6, 11),
        AssembleParams {
            seed: 11,
            split: SplitParams::default(),
            balanced: 20,
        },
    )
}

fn build_with(threads: usize, out: &Path) -> Vec<build::SceneOutcome> {
    let (p, a) = params();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| build::build(&scenes().1, out, &p, &a, &|_| {}).unwrap().0)
}

fn all_episodes(out: &Path) -> Vec<Episode> {
    split::SPLITS
        .iter()
        .flat_map(|s| jsonl::read(&out.join("episodes").join(format!("{s}.jsonl"))).unwrap())
        .collect()
}

#[test]
fn same_bytes_with_one_and_two_threads_and_resume_redoes_only_missing_scenes() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    build_with(1, a.path());
    build_with(2, b.path());
    let (fa, fb) = (read_tree(a.path()).unwrap(), read_tree(b.path()).unwrap());
    assert!(fa.len() > 20);
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (k, v) in &fa {
        assert!(fb[k] == *v, "{k} differs between 1 and 2 threads");
    }
    // A crash that lost one scene: the rerun redoes that scene alone and ends with the same bytes.
    std::fs::remove_file(build::scene_file(b.path(), "scene3")).unwrap();
    std::fs::remove_file(b.path().join("summary.json")).unwrap();
    let outcomes = build_with(2, b.path());
    let status: Vec<Status> = outcomes.iter().map(|o| o.status).collect();
    use Status::{Done, Resumed};
    assert_eq!(status, [Resumed, Resumed, Done, Resumed, Resumed]);
    assert_eq!(read_tree(b.path()).unwrap(), fa);
    // Other settings redo every scene.
    let (mut p, a2) = params();
    p.nogoal = 2;
    let outcomes = build::build(&scenes().1, b.path(), &p, &a2, &|_| {})
        .unwrap()
        .0;
    assert!(outcomes.iter().all(|o| o.status == Status::Done));
}

/// A scene whose input files changed since its file was made is built again, the others kept:
/// its episodes must come from the scene as it is now.
#[test]
fn a_rebuild_redoes_a_scene_whose_input_files_changed() {
    let (out, own) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let dirs: Vec<PathBuf> = (1..=2)
        .map(|seed| {
            let d = own.path().join(format!("scene{seed}"));
            generate(&SynthConfig {
                seed,
                rooms: 3,
                objects: 20,
                gaussians: 1000,
                ..SynthConfig::default()
            })
            .unwrap()
            .save(&d, sage_scene::SplatLayout::Compressed)
            .unwrap();
            d
        })
        .collect();
    let (p, a) = params();
    let statuses = || -> Vec<Status> {
        build::build(&dirs, out.path(), &p, &a, &|_| {})
            .unwrap()
            .0
            .iter()
            .map(|o| o.status)
            .collect()
    };
    assert_eq!(statuses(), [Status::Done, Status::Done]);
    assert_eq!(statuses(), [Status::Resumed, Status::Resumed]);
    // Edited labels (here only a byte that changes nothing read, so the bytes can be compared).
    let labels = dirs[0].join("labels.json");
    let mut text = std::fs::read_to_string(&labels).unwrap();
    text.push('\n');
    std::fs::write(&labels, text).unwrap();
    assert_eq!(statuses(), [Status::Done, Status::Resumed]);
    let file: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(build::scene_file(out.path(), "scene1")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        file["inputs"],
        serde_json::to_value(sage_io::scenes::input_hashes(&dirs[0])).unwrap()
    );

    // LLM requests that failed (no server listens at the port): the scenes' files say so, and
    // the next run asks again instead of keeping the gap for good.
    let closed = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    let mut with_llm = p.clone();
    with_llm.llm = Some(sage_lang::llm::LlmConfig {
        base_url: format!("http://{closed}/v1"),
        max_retries: 0,
        timeout_s: 5,
        ..Default::default()
    });
    for _ in 0..2 {
        let (outcomes, summary) = build::build(&dirs, out.path(), &with_llm, &a, &|_| {}).unwrap();
        assert!(summary.llm_failures > 0);
        assert!(outcomes.iter().all(|o| o.status == Status::Done));
        let failures: u64 = ["scene1", "scene2"]
            .iter()
            .map(|name| {
                let file: serde_json::Value = serde_json::from_str(
                    &std::fs::read_to_string(build::scene_file(out.path(), name)).unwrap(),
                )
                .unwrap();
                file["report"]["llm_failures"].as_u64().unwrap()
            })
            .sum();
        assert_eq!(failures as usize, summary.llm_failures);
    }
}

/// A rebuild over fewer scenes and without a balanced selection leaves the folder as a fresh
/// build with those settings makes it: nothing of the earlier build's scenes or its
/// `test_balanced` stays behind for outside loaders to read.
#[test]
fn a_rebuild_with_other_settings_leaves_nothing_of_the_earlier_build() {
    let (again, fresh) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    build_with(2, again.path());
    assert!(again.path().join("r2r/test_balanced").is_dir());
    let (p, mut a) = params();
    a.balanced = 0;
    let fewer = &scenes().1[..3];
    build::build(fewer, again.path(), &p, &a, &|_| {}).unwrap();
    build::build(fewer, fresh.path(), &p, &a, &|_| {}).unwrap();
    let (got, want) = (
        read_tree(again.path()).unwrap(),
        read_tree(fresh.path()).unwrap(),
    );
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>()
    );
    assert!(got == want);
    assert!(!again.path().join("r2r/test_balanced").exists());
}

/// A scene built before with other settings that fails now leaves none of its old episodes in
/// the dataset: its file of those settings goes before it is built again.
#[test]
fn a_scene_that_fails_on_a_rebuild_brings_no_old_episodes() {
    let dir = tempfile::tempdir().unwrap();
    let copies: Vec<PathBuf> = scenes().1[..2]
        .iter()
        .map(|d| {
            let to = dir.path().join(d.file_name().unwrap());
            for (name, bytes) in read_tree(d).unwrap() {
                std::fs::create_dir_all(to.join(&name).parent().unwrap()).unwrap();
                std::fs::write(to.join(&name), bytes).unwrap();
            }
            to
        })
        .collect();
    let out = dir.path().join("out");
    let (mut p, a) = params();
    build::build(&copies, &out, &p, &a, &|_| {}).unwrap();
    assert!(all_episodes(&out).iter().any(|e| e.scene == "scene1"));
    std::fs::write(copies[0].join("labels.json"), "{").unwrap();
    p.nogoal = 2;
    let (outcomes, _) = build::build(&copies, &out, &p, &a, &|_| {}).unwrap();
    assert_eq!(outcomes[0].status, Status::Skipped);
    let episodes = all_episodes(&out);
    assert!(!episodes.is_empty());
    assert!(episodes.iter().all(|e| e.scene != "scene1"));
}

/// A scene folder whose name no reader takes as a scene name (`Episode::check`) is refused
/// before any work, naming the folder and the rule, instead of building episodes that no
/// split file could be read back with.
#[test]
fn a_scene_folder_without_a_plain_name_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let spaced = dir.path().join("My Home");
    for (name, bytes) in read_tree(&scenes().1[0]).unwrap() {
        std::fs::create_dir_all(spaced.join(&name).parent().unwrap()).unwrap();
        std::fs::write(spaced.join(&name), bytes).unwrap();
    }
    let out = dir.path().join("out");
    let (p, a) = params();
    let dirs = [scenes().1[1].clone(), spaced.clone()];
    let e = build::build(&dirs, &out, &p, &a, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains(&spaced.display().to_string()), "{e}");
    assert!(
        e.contains("'My Home'") && e.contains("rename the folder"),
        "{e}"
    );
    assert!(!out.exists(), "a refused build wrote into its folder");
    // One scene on its own (as a distributed build's task runs it) is skipped with the reason.
    let outcome = build::run_scene(&spaced, &out, &p, None);
    assert_eq!(outcome.status, Status::Skipped);
    assert!(outcome.reason.unwrap().contains("rename the folder"));
    assert!(!build::scene_file(&out, "My Home").exists());
}

#[test]
fn episodes_are_complete_and_their_actions_reach_the_goal() {
    let out = tempfile::tempdir().unwrap();
    build_with(2, out.path());
    let eps = all_episodes(out.path());
    let space = StepSizes::default();
    let kinds: BTreeSet<InstructionType> = eps.iter().map(|e| e.instruction_type).collect();
    for k in InstructionType::HIGH.into_iter().chain([
        InstructionType::BaseAction,
        InstructionType::SingleGoal,
        InstructionType::GoalLess,
    ]) {
        assert!(kinds.contains(&k), "no {k:?}");
    }
    let ids: BTreeSet<&str> = eps.iter().map(|e| e.episode_id.as_str()).collect();
    assert_eq!(ids.len(), eps.len());
    for e in &eps {
        assert!(e.slices.assets == "few", "40-object scenes are few");
        match e.task {
            Task::Nogoal => {
                assert!(e.goal.is_none() && e.actions.is_empty() && e.slices.path == "none")
            }
            Task::Vln => {
                let goal = e.goal.as_ref().unwrap();
                let end = *replay(e.start.pose(), &e.actions, &space).last().unwrap();
                let d = end
                    .position
                    .truncate()
                    .distance(Vec2::new(goal.position[0], goal.position[1]));
                assert!(d < 0.2, "{}: ends {d} m from its goal", e.episode_id);
                assert_eq!(e.level, e.instruction_type.level());
                assert!((e.slices.path == "short") == (e.path_length < 8.4));
            }
        }
    }
}

#[test]
fn splits_hold_out_scenes_trajectories_and_instructions() {
    let out = tempfile::tempdir().unwrap();
    build_with(2, out.path());
    let read =
        |s: &str| jsonl::read(&out.path().join("episodes").join(format!("{s}.jsonl"))).unwrap();
    let train = read("train");
    let scenes_of = |v: &[Episode]| v.iter().map(|e| e.scene.clone()).collect::<BTreeSet<_>>();
    let train_scenes = scenes_of(&train);
    let unseen = read("test_scene_unseen");
    assert!(!unseen.is_empty());
    assert!(scenes_of(&unseen).is_disjoint(&train_scenes));
    assert!(scenes_of(&read("val")).is_disjoint(&train_scenes));
    let train_trajs: BTreeSet<(String, usize)> = train
        .iter()
        .filter_map(|e| e.trajectory_id.map(|t| (e.scene.clone(), t)))
        .collect();
    let traj = read("test_trajectory_unseen");
    assert!(!traj.is_empty());
    for e in &traj {
        assert!(train_scenes.contains(&e.scene));
        assert!(!train_trajs.contains(&(e.scene.clone(), e.trajectory_id.unwrap())));
    }
    let instr = read("test_instruction_unseen");
    assert!(!instr.is_empty());
    for e in &instr {
        assert!(
            train_trajs.contains(&(e.scene.clone(), e.trajectory_id.unwrap())),
            "{}",
            e.episode_id
        );
        assert!(!train.iter().any(|t| t.episode_id == e.episode_id));
    }
    let total: usize = split::SPLITS.iter().map(|s| read(s).len()).sum();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["episodes"], total);
    assert!(
        std::fs::read_to_string(out.path().join("summary.txt"))
            .unwrap()
            .contains("validator|")
    );
}

#[test]
fn balanced_selection_is_even_over_strata() {
    let out = tempfile::tempdir().unwrap();
    build_with(1, out.path());
    let eps = all_episodes(out.path());
    let refs: Vec<&Episode> = eps.iter().filter(|e| e.task == Task::Vln).collect();
    let mut sizes: BTreeMap<String, usize> = BTreeMap::new();
    for e in &refs {
        *sizes.entry(stratum(e)).or_default() += 1;
    }
    for n in [1, 7, 25, refs.len() + 5, usize::MAX] {
        let picked = select_balanced(&refs, n, 3);
        assert_eq!(picked.len(), n.min(refs.len()));
        assert_eq!(picked, select_balanced(&refs, n, 3));
        let mut got: BTreeMap<String, usize> = BTreeMap::new();
        for id in &picked {
            let e = refs.iter().find(|e| &e.episode_id == id).unwrap();
            *got.entry(stratum(e)).or_default() += 1;
        }
        let most = got.values().max().copied().unwrap_or(0);
        for (s, size) in &sizes {
            let c = got.get(s).copied().unwrap_or(0);
            assert!(
                c == *size || c + 1 >= most,
                "stratum {s}: {c} of {size}, another has {most}"
            );
        }
    }
}

fn same_episode(a: &Episode, b: &Episode, tol: f32) {
    assert_eq!(a.instruction, b.instruction);
    assert_eq!(a.instruction_type, b.instruction_type);
    assert_eq!(a.episode_id, b.episode_id);
    assert_eq!(a.reference_path.len(), b.reference_path.len());
    for (p, q) in a.reference_path.iter().zip(&b.reference_path) {
        assert!((0..3).all(|i| (p[i] - q[i]).abs() < tol), "{p:?} vs {q:?}");
    }
    assert!((a.start.position[0] - b.start.position[0]).abs() < tol);
    assert!(wrap_angle(a.start.yaw - b.start.yaw).abs() < 1e-3);
}

/// `b` (read back from a file) equals `a` once its floats are within `tol` of `a`'s (headings
/// compared wrapped): every other field, the lengths and the actions included, is exact.
fn same_but_rounding(a: &Episode, b: &Episode, tol: f32) {
    let close = |x: f32, y: f32| (x - y).abs() <= tol;
    let heading = |x: f32, y: f32| wrap_angle(x - y).abs() <= tol;
    let point = |p: &[f32; 3], q: &[f32; 3]| (0..3).all(|i| close(p[i], q[i]));
    let id = &a.episode_id;
    assert!(point(&a.start.position, &b.start.position), "{id}");
    assert!(heading(a.start.yaw, b.start.yaw), "{id}: start heading");
    assert_eq!(a.reference_path.len(), b.reference_path.len(), "{id}");
    assert!(
        a.reference_path
            .iter()
            .zip(&b.reference_path)
            .all(|(p, q)| point(p, q)),
        "{id}"
    );
    let mut b = b.clone();
    if let (Some(ga), Some(gb)) = (&a.goal, &mut b.goal) {
        assert!(point(&ga.position, &gb.position), "{id}");
        match (ga.yaw, gb.yaw) {
            (Some(x), Some(y)) => assert!(heading(x, y), "{id}: goal heading {x} vs {y}"),
            (x, y) => assert_eq!(x, y, "{id}: goal heading"),
        }
        gb.position = ga.position;
        gb.yaw = ga.yaw;
    }
    b.start = a.start;
    b.reference_path = a.reference_path.clone();
    assert_eq!(*a, b);
}

/// A Base-Action turn in place, as the demo's `office_2-b0`: one point, two headings.
fn turn_in_place() -> Episode {
    serde_json::from_str(
        r#"{"episode_id":"office_2-b0","scene":"office_2","task":"vln","instruction":"Turn 60 degrees to the left in place.","level":"low","instruction_type":"Base-Action","source":"template","start":{"position":[-8.825001,-5.625001,0.0],"yaw":-0.26180005},"goal":{"ref":"","kind":"pose","position":[-8.825001,-5.625001,0.0],"yaw":0.7853975},"reference_path":[[-8.825001,-5.625001,0.0]],"actions":[2,2,2,2,0],"path_length":0.0,"geodesic_distance":0.0,"slices":{"assets":"many","path":"short"}}"#,
    )
    .unwrap()
}

#[test]
fn gvln_keeps_a_turn_in_place_its_headings_and_lengths() {
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    let turn = turn_in_place();
    // A no-goal start facing −x (heading π, whose rotation is the published placeholder
    // `[0, 0, 0, 1]`), and a trajectory whose geodesic distance is shorter than its path.
    let mut explore = turn.clone();
    explore.episode_id = "office_2-n0".into();
    explore.task = Task::Nogoal;
    explore.instruction_type = InstructionType::GoalLess;
    explore.level = None;
    explore.goal = None;
    explore.actions = Vec::new();
    explore.start.yaw = std::f32::consts::PI;
    explore.slices.path = "none".into();
    let mut walk = turn.clone();
    walk.episode_id = "office_2-b1".into();
    walk.reference_path = vec![[0.0, 0.0, 0.0], [0.25, 0.0, 0.0], [0.5, 0.0, 0.0]];
    walk.start.position = [0.0, 0.0, 0.0];
    walk.start.yaw = 0.0;
    walk.goal = Some(sage_dataset::Goal {
        reference: String::new(),
        kind: "pose".into(),
        position: [0.5, 0.0, 0.0],
        yaw: Some(std::f32::consts::PI),
    });
    // Two steps, then the half turn to the goal's heading (π: the last point's rotation is
    // the published placeholder, so only our key holds it).
    let flat = [Vec2::ZERO, Vec2::new(0.25, 0.0), Vec2::new(0.5, 0.0)];
    walk.actions = follow(&flat, 0.0, Some(std::f32::consts::PI), &space).unwrap();
    assert!(walk.actions.len() > 3, "{:?}", walk.actions);
    walk.path_length = 0.5;
    walk.geodesic_distance = 0.4;
    let eps = vec![turn.clone(), explore, walk];
    for frame in [
        GvlnFrame::World,
        GvlnFrame::Sage(SageFrame {
            offset: Vec2::new(3.5, -1.25),
        }),
    ] {
        let p = dir.path().join("g.json");
        gvln::write(&p, &eps, frame, &space).unwrap();
        let back = gvln::read(&p, Vec2::ZERO, &space).unwrap();
        assert_eq!(back.len(), eps.len());
        for a in &eps {
            let b = back.iter().find(|b| b.episode_id == a.episode_id).unwrap();
            same_but_rounding(a, b, 1e-4);
        }
    }
    // Our keys taken out of a file, as a tool that rewrites it without them would.
    let p = dir.path().join("g.json");
    gvln::write(&p, &eps, GvlnFrame::World, &space).unwrap();
    let mut root: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    let mut strip = |keys: &[&str]| {
        for scene in root["scenes"].as_array_mut().unwrap() {
            for sample in scene["samples"].as_array_mut().unwrap() {
                for ins in sample["instructions"].as_array_mut().unwrap() {
                    let ins = ins.as_object_mut().unwrap();
                    keys.iter().for_each(|k| _ = ins.remove(*k));
                }
            }
        }
        std::fs::write(&p, root.to_string()).unwrap();
        gvln::read(&p, Vec2::ZERO, &space).unwrap()
    };
    // Without the actions, they are recomputed: to the goal's heading, so the turn in place
    // turns left four times, as the instruction asks.
    let recomputed = strip(&["actions"]);
    let b0 = recomputed
        .iter()
        .find(|b| b.episode_id == turn.episode_id)
        .unwrap();
    assert_eq!(b0.actions, turn.actions);
    // Without any of our keys (a published file) the headings come from the points and both
    // lengths are the path's: the file read that way loses what only the keys hold.
    let plain = strip(&[
        "start_yaw",
        "goal_yaw",
        "goal_kind",
        "path_length",
        "geodesic_distance",
        "slices",
    ]);
    let walk = plain
        .iter()
        .find(|e| e.episode_id == "office_2-b1")
        .unwrap();
    assert_eq!(walk.goal.as_ref().unwrap().yaw, None);
    assert_eq!(walk.geodesic_distance, walk.path_length);
    assert_eq!(walk.slices.assets, "medium");
    // The actions are then recomputed from the points: the turn's end heading is lost too.
    let turn_back = plain
        .iter()
        .find(|e| e.episode_id == "office_2-b0")
        .unwrap();
    assert_eq!(turn_back.actions, [sage_lang::DiscreteAction::Stop]);
    // A bad value under one of our keys is named.
    root["scenes"][0]["samples"][0]["instructions"][0]["goal_yaw"] = "left".into();
    std::fs::write(&p, root.to_string()).unwrap();
    let e = gvln::read(&p, Vec2::ZERO, &space).unwrap_err().to_string();
    assert!(
        e.contains("g.json")
            && e.contains("instructions[0]")
            && e.contains("goal_yaw")
            && e.contains("expected a finite number"),
        "{e}"
    );
}

/// In S, the frame of SAGE-Bench's tools, the points stand at the agent's base 0.5 m up as in
/// the published files, and `base_z` says so; a file of ours in S from before the key (points
/// at the floor) still reads at the floor, and a bad `base_z` is named.
#[test]
fn gvln_in_the_sage_frame_puts_the_points_at_the_published_base() {
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.json");
    let eps = [turn_in_place()];
    let frame = GvlnFrame::Sage(SageFrame {
        offset: Vec2::new(3.5, -1.25),
    });
    gvln::write(&p, &eps, frame, &space).unwrap();
    let mut root: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    assert_eq!(root["dataset_metadata"]["base_z"], 0.5);
    let z = &root["scenes"][0]["samples"][0]["points"][0]["position"][2];
    assert_eq!(z.as_f64(), Some(f64::from(gvln::PUBLISHED_BASE_Z)));
    let back = gvln::read(&p, Vec2::ZERO, &space).unwrap();
    assert_eq!(back[0].reference_path[0][2], 0.0);
    // An S file of ours from before `base_z`: its points were at the floor.
    let meta = root["dataset_metadata"].as_object_mut().unwrap();
    meta.remove("base_z");
    root["scenes"][0]["samples"][0]["points"][0]["position"][2] = 0.0.into();
    std::fs::write(&p, root.to_string()).unwrap();
    let back = gvln::read(&p, Vec2::ZERO, &space).unwrap();
    assert_eq!(back[0].reference_path[0][2], 0.0);
    root["dataset_metadata"]["base_z"] = "high".into();
    std::fs::write(&p, root.to_string()).unwrap();
    let e = gvln::read(&p, Vec2::ZERO, &space).unwrap_err().to_string();
    assert!(
        e.contains("s.json") && e.contains("dataset_metadata") && e.contains("base_z"),
        "{e}"
    );
}

/// A GVLN file as SAGE-Bench publishes it (research notes §2.1): no `frame`, the world id as
/// the scene's name, the folder key in each instruction, every point at z = 0.5 in the S frame.
#[test]
fn gvln_reads_a_published_file_at_the_floor_in_its_scene_folder() {
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    let offset = Vec2::new(3.0, -2.0);
    let s = SageFrame { offset };
    // A walk along +x in W from (1, 0.5) to (2, 0.5), facing +x.
    let w: Vec<[f32; 3]> = (0..5).map(|k| [1.0 + 0.25 * k as f32, 0.5, 0.0]).collect();
    let points: Vec<serde_json::Value> = w
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = s.world_to_sage(glam::Vec3::new(p[0], p[1], 0.5));
            let rotation = if i + 1 == w.len() {
                [0.0, 0.0, 0.0, 1.0]
            } else {
                gvln::encode_rotation(s.heading_to_sage(0.0))
            };
            serde_json::json!({"point": i.to_string(), "position": [q.x, q.y, q.z],
                "rotation": rotation, "action": [], "camera_images": []})
        })
        .collect();
    let file = |folder_key: &str| {
        serde_json::json!({"Data_2set_metaData_2": {}, "scenes": [{"scene_id": "839873",
            "scene_name": "839873", "samples": [{"trajectory_id": "0", "instructions": [
                {"instruction_type": "Scenario_Driven", "start": "sofa_1", "end": "table_1",
                 "generated_instruction": "Walk to the table.", "scene_id": folder_key}],
            "points": points}]}]})
    };
    let p = dir.path().join("published.json");
    std::fs::write(&p, file("0033_839873").to_string()).unwrap();
    let eps = gvln::read(&p, offset, &space).unwrap();
    assert_eq!(eps.len(), 1);
    let e = &eps[0];
    // The scene is the InteriorGS folder the instruction names, not the bare world id.
    assert_eq!(e.scene, "0033_839873");
    assert_eq!(e.episode_id, "0033_839873-t0-0");
    // Every point back in W at the floor: the published 0.5 is the agent's base.
    for (a, b) in e.reference_path.iter().zip(&w) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-5, "{a:?} against {b:?}");
        }
    }
    assert_eq!(e.start.position[2], 0.0);
    assert_eq!(e.goal.as_ref().unwrap().position[2], 0.0);
    assert!(wrap_angle(e.start.yaw).abs() < 1e-5, "{}", e.start.yaw);
    // A folder key that would leave the scenes folder is refused where it stands.
    std::fs::write(&p, file("../0033_839873").to_string()).unwrap();
    let err = gvln::read(&p, offset, &space).unwrap_err().to_string();
    assert!(
        err.contains("published.json")
            && err.contains("instructions[0].scene_id")
            && err.contains("'../0033_839873'"),
        "{err}"
    );
}

/// What a case of [`readers_refuse_episodes_their_task_cannot_score`] changes in a good episode.
type Spoil = Box<dyn Fn(&mut Episode)>;

#[test]
fn readers_refuse_episodes_their_task_cannot_score() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("e.jsonl");
    let base = turn_in_place();
    let mut object = base.clone();
    object.episode_id = "office_2-t0-0".into();
    object.instruction_type = InstructionType::SingleGoal;
    object.goal = Some(sage_dataset::Goal {
        reference: "sofa_2".into(),
        kind: "object".into(),
        position: [1.0, 0.0, 0.0],
        yaw: None,
    });
    let cases: Vec<(&str, Spoil, &str)> = vec![
        ("no goal", Box::new(|e| e.goal = None), "goal: missing"),
        (
            "empty reference path",
            Box::new(|e| e.reference_path.clear()),
            "reference_path: empty",
        ),
        (
            "unknown goal kind",
            Box::new(|e| e.goal.as_mut().unwrap().kind = "objet".into()),
            "goal.kind: 'objet': expected one of object, room, area, pose",
        ),
        (
            "object goal without its object",
            Box::new(|e| {
                let g = e.goal.as_mut().unwrap();
                g.kind = "object".into();
                g.reference.clear();
                g.yaw = None;
            }),
            "goal.ref: empty",
        ),
        (
            "heading on a room goal",
            Box::new(|e| {
                let g = e.goal.as_mut().unwrap();
                g.kind = "room".into();
                g.reference = "room_2".into();
            }),
            "goal.yaw: only a pose goal has a heading",
        ),
        (
            "no-goal episode with a goal",
            Box::new(|e| {
                e.task = Task::Nogoal;
                e.instruction_type = InstructionType::GoalLess;
            }),
            "goal: a nogoal episode has no goal",
        ),
        (
            "Goal-less type on a vln episode",
            Box::new(|e| e.instruction_type = InstructionType::GoalLess),
            "instruction_type: 'Goal-less' with task 'vln'",
        ),
    ];
    for (what, spoil, needle) in cases {
        let mut bad = base.clone();
        spoil(&mut bad);
        // The bad episode second: the error names its line.
        jsonl::write(&p, &[object.clone(), bad]).unwrap();
        let e = jsonl::read(&p).unwrap_err().to_string();
        assert!(
            e.contains("e.jsonl") && e.contains("line 2") && e.contains(needle),
            "{what}: {e}"
        );
    }
    // The unspoilt pair reads, and a no-goal episode needs no reference path to be scored.
    jsonl::write(&p, &[object.clone(), base.clone()]).unwrap();
    assert_eq!(jsonl::read(&p).unwrap().len(), 2);
    let mut explore = base;
    explore.task = Task::Nogoal;
    explore.instruction_type = InstructionType::GoalLess;
    explore.goal = None;
    explore.reference_path.clear();
    jsonl::write(&p, &[explore]).unwrap();
    assert_eq!(jsonl::read(&p).unwrap().len(), 1);
}

#[test]
fn negative_zeros_are_written_as_zeros() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("e.jsonl");
    let mut e = turn_in_place();
    e.path_length = -0.0;
    e.geodesic_distance = -0.0;
    e.start.position[2] = -0.0;
    jsonl::write(&p, &[e]).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(!text.contains("-0.0"), "{text}");
    assert!(text.contains("\"path_length\":0.0"), "{text}");
    let back = &jsonl::read(&p).unwrap()[0];
    assert!(back.path_length.is_sign_positive() && back.geodesic_distance.is_sign_positive());
}

#[test]
fn formats_round_trip() {
    let out = tempfile::tempdir().unwrap();
    build_with(2, out.path());
    let eps = all_episodes(out.path());
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    // JSONL: exact.
    jsonl::write(&dir.path().join("e.jsonl"), &eps).unwrap();
    assert_eq!(jsonl::read(&dir.path().join("e.jsonl")).unwrap(), eps);
    // GVLN in W and in S.
    for frame in [
        GvlnFrame::World,
        GvlnFrame::Sage(SageFrame {
            offset: Vec2::new(3.5, -1.25),
        }),
    ] {
        let p = dir.path().join("g.json");
        gvln::write(&p, &eps, frame, &space).unwrap();
        let back = gvln::read(&p, Vec2::ZERO, &space).unwrap();
        for a in &eps {
            let b = back.iter().find(|b| b.episode_id == a.episode_id).unwrap();
            // Everything comes back (our keys hold what the points cannot): in W exactly, in
            // S with floats within rounding.
            if frame == GvlnFrame::World {
                assert_eq!(a, b);
            }
            same_but_rounding(a, b, 1e-4);
            // GVLN carries no actions: the reader recomputes them, and they must reach the goal.
            if let Some(g) = &b.goal {
                let end = *replay(b.start.pose(), &b.actions, &space).last().unwrap();
                assert!(
                    end.position
                        .truncate()
                        .distance(Vec2::new(g.position[0], g.position[1]))
                        < 0.2,
                    "{}",
                    a.episode_id
                );
            }
        }
    }
    // A split reads back in its own order, trajectory 10 after 9 (not after 1).
    let first = eps.iter().find(|e| e.trajectory_id.is_some()).unwrap();
    let many: Vec<Episode> = (0..12)
        .map(|t| {
            let mut e = first.clone();
            e.trajectory_id = Some(t);
            e.episode_id = format!("{}-t{t}-0", e.scene);
            e
        })
        .collect();
    let p = dir.path().join("many.json");
    gvln::write(&p, &many, GvlnFrame::World, &space).unwrap();
    assert_eq!(gvln::read(&p, Vec2::ZERO, &space).unwrap(), many);
    // R2R in the Habitat frame (no-goal episodes are left out).
    let n = r2r::write(dir.path(), "train", &eps, &space).unwrap();
    let vln: Vec<&Episode> = eps.iter().filter(|e| e.task == Task::Vln).collect();
    assert_eq!(n, vln.len());
    let back = r2r::read(dir.path(), "train", &space).unwrap();
    assert_eq!(back.len(), vln.len());
    for (a, b) in vln.iter().zip(&back) {
        same_episode(a, b, 1e-5);
        assert_eq!(a.actions, b.actions);
        assert_eq!(a.slices, b.slices);
    }
}

#[test]
fn bad_files_name_file_and_place() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.jsonl");
    std::fs::write(&p, "{\"episode_id\": 3}\n").unwrap();
    let e = jsonl::read(&p).unwrap_err().to_string();
    assert!(e.contains("bad.jsonl") && e.contains("line 1"), "{e}");
    let g = dir.path().join("bad.json");
    std::fs::write(&g, r#"{"scenes":[{"scene_name":"x","samples":[{"trajectory_id":"0","instructions":[],"points":[{"position":[0,0],"rotation":[0,0,0,1]}]}]}]}"#).unwrap();
    let e = gvln::read(&g, Vec2::ZERO, &StepSizes::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.json") && e.contains("scenes[0].samples[0].points[0].position"),
        "{e}"
    );
    std::fs::create_dir_all(dir.path().join("x")).unwrap();
    std::fs::write(dir.path().join("x/x.json.gz"), b"not gzip").unwrap();
    assert!(
        r2r::read(dir.path(), "x", &StepSizes::default())
            .unwrap_err()
            .to_string()
            .contains("x.json.gz")
    );
}

#[test]
fn every_reader_refuses_ids_twice_and_names_that_leave_a_folder() {
    let out = tempfile::tempdir().unwrap();
    build_with(1, out.path());
    let mut eps: Vec<Episode> = all_episodes(out.path())
        .into_iter()
        .filter(|e| e.task == Task::Vln)
        .take(3)
        .collect();
    eps[2].episode_id = eps[0].episode_id.clone();
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    let j = dir.path().join("e.jsonl");
    jsonl::write(&j, &eps).unwrap();
    let e = jsonl::read(&j).unwrap_err().to_string();
    assert!(
        e.contains("e.jsonl: line 3") && e.contains("given twice (first at line 1)"),
        "{e}"
    );
    let g = dir.path().join("g.json");
    gvln::write(&g, &eps, GvlnFrame::World, &space).unwrap();
    let e = gvln::read(&g, Vec2::ZERO, &space).unwrap_err().to_string();
    assert!(e.contains("g.json") && e.contains("given twice"), "{e}");
    r2r::write(dir.path(), "twice", &eps, &space).unwrap();
    let e = r2r::read(dir.path(), "twice", &space)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("episodes[2]") && e.contains("given twice (first at episodes[0])"),
        "{e}"
    );
    assert!(r2r::read(dir.path(), "../twice", &space).is_err());

    // a GVLN trajectory index that is not a number, and a scene name that climbs out
    let text = std::fs::read_to_string(&g).unwrap();
    let mut root: serde_json::Value = serde_json::from_str(&text).unwrap();
    root["scenes"][0]["samples"][0]["trajectory_id"] = "seven".into();
    std::fs::write(&g, root.to_string()).unwrap();
    let e = gvln::read(&g, Vec2::ZERO, &space).unwrap_err().to_string();
    assert!(e.contains("trajectory_id") && e.contains("'seven'"), "{e}");
    let mut root: serde_json::Value = serde_json::from_str(&text).unwrap();
    root["scenes"][0]["scene_name"] = "../../etc".into();
    std::fs::write(&g, root.to_string()).unwrap();
    let e = gvln::read(&g, Vec2::ZERO, &space).unwrap_err().to_string();
    assert!(
        e.contains("scenes[0].scene_name") && e.contains("scene name '../../etc'"),
        "{e}"
    );
}

#[test]
fn a_build_stopped_before_it_finished_is_no_dataset_until_rerun() {
    use sage_dataset::folder;
    let dir = tempfile::tempdir().unwrap();
    let (data, scenes) = (dir.path().join("data"), dir.path().join("scenes"));
    std::fs::create_dir_all(data.join("episodes")).unwrap();
    std::fs::create_dir_all(&scenes).unwrap();
    let (p, a) = params();
    let record = |finished| build::write_run_record(&data, &scenes, &[], &p, &a, finished);
    // What a build killed in its assembly leaves: its record written before the work, some
    // split files, no splits.json.
    record(false).unwrap();
    for split in ["test_instruction_unseen", "train"] {
        let file = data.join("episodes").join(format!("{split}.jsonl"));
        jsonl::write(&file, &[turn_in_place()]).unwrap();
    }
    let refused = |what: &str, e: sage_core::Error| {
        let e = e.to_string();
        assert!(
            e.starts_with(&format!("{}: ", data.display()))
                && e.contains("has not finished")
                && e.contains("rerun `sage3d data build` into this folder to finish it"),
            "{what}: {e}"
        );
    };
    refused("splits", folder::splits(&data).unwrap_err());
    refused("non-empty", folder::non_empty_splits(&data).unwrap_err());
    refused("split", folder::split_episodes(&data, "train").unwrap_err());
    refused("scenes", folder::scenes_folder(&data, None).unwrap_err());
    let gvln_file = dir.path().join("g.json");
    gvln::write(
        &gvln_file,
        &[turn_in_place()],
        GvlnFrame::World,
        &StepSizes::default(),
    )
    .unwrap();
    let source = sage_dataset::import::Source::Gvln {
        file: gvln_file,
        offset: Vec2::ZERO,
    };
    refused(
        "import",
        sage_dataset::import::import(&source, &data, "mine", None, false).unwrap_err(),
    );
    assert!(!data.join("episodes/mine.jsonl").exists());
    // Its record says why: unfinished.
    let e = folder::splits(&data).unwrap_err().to_string();
    assert!(e.contains("status 'unfinished'"), "{e}");
    // A build's record beside no splits.json, of any status (one written before the status
    // existed too), is no finished build either.
    record(true).unwrap();
    let e = folder::splits(&data).unwrap_err().to_string();
    assert!(e.contains("no splits.json"), "{e}");
    // A rerun killed after an earlier build had finished: the old splits.json is still there.
    let ids: Vec<String> = jsonl::read(&data.join("episodes/train.jsonl"))
        .unwrap()
        .into_iter()
        .map(|e| e.episode_id)
        .collect();
    std::fs::write(
        data.join(folder::SPLITS_FILE),
        serde_json::json!({"splits": {"train": ids}}).to_string(),
    )
    .unwrap();
    record(false).unwrap();
    refused("rerun", folder::splits(&data).unwrap_err());
    // Finished: the listed splits, and the recorded scenes.
    record(true).unwrap();
    assert_eq!(folder::splits(&data).unwrap(), ["train"]);
    assert_eq!(folder::split_episodes(&data, "train").unwrap().1.len(), 1);
    assert!(folder::scenes_folder(&data, None).unwrap().is_dir());
    // A folder without a run record (made by hand, or before records) keeps the old rule.
    std::fs::remove_file(data.join(sage_io::RUN_RECORD)).unwrap();
    std::fs::remove_file(data.join(folder::SPLITS_FILE)).unwrap();
    assert_eq!(
        folder::splits(&data).unwrap(),
        ["test_instruction_unseen", "train"]
    );
}

/// A walk of 1 m along +x in `scene` whose file says its asset slice is `assets`.
fn walk_in(scene: &str, assets: &str) -> Episode {
    let path = [[1.0, 0.5, 0.0], [1.5, 0.5, 0.0], [2.0, 0.5, 0.0]];
    let flat: Vec<Vec2> = path.iter().map(|p| Vec2::new(p[0], p[1])).collect();
    let actions = follow(&flat, 0.0, None, &StepSizes::default()).unwrap();
    let mut e: Episode = serde_json::from_value(serde_json::json!({
        "episode_id": format!("{scene}-t0-0"), "scene": scene, "task": "vln", "trajectory_id": 0,
        "instruction": "Walk to the table.", "level": "low", "instruction_type": "Single-Goal",
        "source": "template",
        "start": {"position": path[0], "yaw": 0.0},
        "goal": {"ref": "table_1", "kind": "object", "position": path[2]},
        "reference_path": path, "actions": [], "path_length": 1.0, "geodesic_distance": 1.0,
        "slices": {"assets": assets, "path": "short"}}))
    .unwrap();
    e.actions = actions;
    e
}

/// The asset slice of each scene's episodes in split `split` of `data`, as written.
fn assets_by_scene(data: &Path, split: &str) -> BTreeMap<String, String> {
    jsonl::read(&data.join(format!("episodes/{split}.jsonl")))
        .unwrap()
        .into_iter()
        .map(|e| (e.scene, e.slices.assets))
        .collect()
}

/// The published GVLN and R2R-VLNCE files hold none of sage3d's keys, so no asset counts: an
/// import given the scenes tags each such episode with its scene's slice (`many` above 376
/// objects of `labels.json`, `few` below 184), one without them leaves `medium` and counts
/// those episodes; a file sage3d wrote keeps the slices it holds either way.
#[test]
fn imports_tag_published_episodes_with_their_scenes_asset_slice() {
    use sage_dataset::import::{Source, import};
    let space = StepSizes::default();
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    for (name, rooms, objects) in [("big", 24, 450), ("small", 2, 20)] {
        generate(&SynthConfig {
            seed: 3,
            rooms,
            objects,
            gaussians: 1000,
            ..SynthConfig::default()
        })
        .unwrap()
        .save(&scenes.join(name), sage_scene::SplatLayout::Compressed)
        .unwrap();
    }
    let count = |name: &str| sage_dataset::slices::scene_objects(&scenes.join(name)).unwrap();
    assert!(count("big").len() > 376, "{}", count("big").len());
    assert!(count("small").len() < 184, "{}", count("small").len());
    // What the files of ours say is the other way round, so that keeping it shows.
    let ours = [walk_in("big", "few"), walk_in("small", "many")];
    let tagged = BTreeMap::from([
        ("big".into(), "many".into()),
        ("small".into(), "few".into()),
    ]);
    let kept = BTreeMap::from([
        ("big".into(), "few".into()),
        ("small".into(), "many".into()),
    ]);
    let medium = BTreeMap::from([
        ("big".into(), "medium".into()),
        ("small".into(), "medium".into()),
    ]);
    // A published GVLN file: in S, no `frame`, `base_z` or instruction keys of ours.
    let ours_gvln = dir.path().join("ours.json");
    gvln::write(&ours_gvln, &ours, GvlnFrame::World, &space).unwrap();
    let published_gvln = dir.path().join("published.json");
    let s = GvlnFrame::Sage(SageFrame { offset: Vec2::ZERO });
    gvln::write(&published_gvln, &ours, s, &space).unwrap();
    let mut root: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&published_gvln).unwrap()).unwrap();
    root["dataset_metadata"] = serde_json::json!({"name": "GVLN"});
    for scene in root["scenes"].as_array_mut().unwrap() {
        for sample in scene["samples"].as_array_mut().unwrap() {
            for ins in sample["instructions"].as_array_mut().unwrap() {
                let ins = ins.as_object_mut().unwrap();
                for key in [
                    "episode_id",
                    "level",
                    "subtype",
                    "source",
                    "task",
                    "start_yaw",
                    "goal_yaw",
                    "goal_kind",
                    "path_length",
                    "geodesic_distance",
                    "slices",
                    "actions",
                ] {
                    ins.remove(key);
                }
            }
        }
    }
    std::fs::write(&published_gvln, root.to_string()).unwrap();
    // A published R2R-VLNCE split: no `sage3d` object.
    let (ours_r2r, published_r2r) = (dir.path().join("r2r_ours"), dir.path().join("r2r"));
    r2r::write(&ours_r2r, "val", &ours, &space).unwrap();
    r2r::write(&published_r2r, "val", &ours, &space).unwrap();
    let main = r2r::paths(&published_r2r, "val").0;
    let mut text = String::new();
    std::io::Read::read_to_string(
        &mut flate2::read::GzDecoder::new(std::fs::File::open(&main).unwrap()),
        &mut text,
    )
    .unwrap();
    let mut root: serde_json::Value = serde_json::from_str(&text).unwrap();
    for e in root["episodes"].as_array_mut().unwrap() {
        assert!(e.as_object_mut().unwrap().remove("sage3d").is_some());
    }
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut gz, root.to_string().as_bytes()).unwrap();
    std::fs::write(&main, gz.finish().unwrap()).unwrap();

    let gvln_source = |file: &Path| Source::Gvln {
        file: file.to_path_buf(),
        offset: Vec2::ZERO,
    };
    let r2r_source = |dir: &Path| Source::R2r {
        dir: dir.to_path_buf(),
        split: "val".into(),
    };
    for (name, source, published) in [
        ("gvln", gvln_source(&published_gvln), true),
        ("gvln_ours", gvln_source(&ours_gvln), false),
        ("r2r", r2r_source(&published_r2r), true),
        ("r2r_ours", r2r_source(&ours_r2r), false),
    ] {
        let with = dir.path().join(format!("{name}_with_scenes"));
        let imported = import(&source, &with, "s", Some(&scenes), false).unwrap();
        assert_eq!(imported.assets_unknown, 0, "{name}");
        let want = if published { &tagged } else { &kept };
        assert_eq!(&assets_by_scene(&with, "s"), want, "{name} with scenes");
        let without = dir.path().join(format!("{name}_without_scenes"));
        let imported = import(&source, &without, "s", None, false).unwrap();
        let (want, unknown) = if published { (&medium, 2) } else { (&kept, 0) };
        assert_eq!(imported.assets_unknown, unknown, "{name}");
        assert_eq!(
            &assets_by_scene(&without, "s"),
            want,
            "{name} without scenes"
        );
    }
    // An offset that is no place is refused, whether or not the file states its frame.
    for file in [&published_gvln, &ours_gvln] {
        for offset in [Vec2::new(f32::NAN, 0.0), Vec2::new(0.0, 1e9)] {
            let out = dir.path().join("nowhere");
            let source = Source::Gvln {
                file: file.clone(),
                offset,
            };
            let e = import(&source, &out, "s", Some(&scenes), false).unwrap_err();
            assert!(
                e.to_string().contains("`offset` must be finite and within"),
                "{e}"
            );
            assert!(!out.exists());
        }
    }
    // A scene whose labels cannot be read is named, with the episode it was read for.
    std::fs::write(scenes.join("small/labels.json"), "{").unwrap();
    let e = import(
        &gvln_source(&published_gvln),
        &dir.path().join("broken"),
        "s",
        Some(&scenes),
        false,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("labels.json") && e.contains("small-t0-0") && e.contains("asset slice"),
        "{e}"
    );
}

/// A source without an episode is refused by name before any file of the dataset is written:
/// an empty split is no benchmark.
#[test]
fn an_import_of_no_episode_is_refused_and_writes_no_split() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("empty.json");
    gvln::write(&file, &[], GvlnFrame::World, &StepSizes::default()).unwrap();
    let source = sage_dataset::import::Source::Gvln {
        file: file.clone(),
        offset: Vec2::ZERO,
    };
    let data = dir.path().join("data");
    let err = sage_dataset::import::import(&source, &data, "mine", None, false).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: the source holds no episode; nothing was imported",
            file.display()
        )
    );
    assert!(!data.join("episodes").exists());
    assert!(!data.join(sage_dataset::folder::SPLITS_FILE).exists());
    assert!(!data.join(sage_io::RUN_RECORD).exists());
}

#[test]
fn an_import_stopped_before_its_record_is_redone_by_its_rerun() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("walks.json");
    let walks = [walk_in("home_a", "few"), walk_in("home_b", "many")];
    gvln::write(&file, &walks, GvlnFrame::World, &StepSizes::default()).unwrap();
    let source = sage_dataset::import::Source::Gvln {
        file,
        offset: Vec2::ZERO,
    };
    let import =
        |data: &Path, split: &str| sage_dataset::import::import(&source, data, split, None, false);
    let whole = dir.path().join("whole");
    import(&whole, "a").unwrap();
    import(&whole, "b").unwrap();
    // What an import stopped after its split file leaves: the record naming the split it was
    // writing (a new folder's marked unfinished), the split, no finished record.
    let record = |data: &Path| sage_io::run::read_record(data).unwrap();
    let stopped = dir.path().join("stopped");
    import(&stopped, "a").unwrap();
    let first = record(&stopped);
    std::fs::remove_file(stopped.join(sage_io::RUN_RECORD)).unwrap();
    sage_io::run::write_run_record(
        &stopped,
        sage_dataset::import::COMMAND,
        None,
        serde_json::json!({"status": "unfinished", "importing": "a"}),
    )
    .unwrap();
    assert!(sage_io::run::unfinished_command(&stopped).is_some());
    import(&stopped, "a").unwrap();
    assert_eq!(record(&stopped), first);
    // Stopped adding a second split to a finished folder: the rerun writes it again, once.
    let mut adding = first.clone();
    adding["importing"] = "b".into();
    sage_io::files::write_json(&stopped.join(sage_io::RUN_RECORD), &adding).unwrap();
    std::fs::copy(
        whole.join("episodes/b.jsonl"),
        stopped.join("episodes/b.jsonl"),
    )
    .unwrap();
    import(&stopped, "b").unwrap();
    assert_eq!(record(&stopped), record(&whole));
    for f in [
        "episodes/a.jsonl",
        "episodes/b.jsonl",
        sage_dataset::folder::SPLITS_FILE,
    ] {
        assert_eq!(
            std::fs::read(stopped.join(f)).unwrap(),
            std::fs::read(whole.join(f)).unwrap(),
            "{f}"
        );
    }
    // A split no stopped import was writing is still the user's to keep.
    let e = import(&stopped, "b").unwrap_err();
    assert!(e.to_string().contains("this split exists already"), "{e}");
    // The first import of a new folder stopped, then another split imported before its rerun:
    // both splits end recorded, in the bytes of imports never stopped.
    let other = dir.path().join("other");
    import(&other, "a").unwrap();
    sage_io::run::write_run_record(
        &other,
        sage_dataset::import::COMMAND,
        None,
        serde_json::json!({"status": "unfinished", "importing": "a"}),
    )
    .unwrap();
    import(&other, "b").unwrap();
    let between = record(&other);
    assert_eq!(between["status"], "unfinished");
    assert_eq!(between["importing"], serde_json::json!(["a"]));
    assert!(between["imports"]["b"].is_object());
    import(&other, "a").unwrap();
    assert_eq!(record(&other), record(&whole));
}
