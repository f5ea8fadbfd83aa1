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
use sage_lang::actions::{StepSizes, replay};
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
    for n in [1, 7, 25, refs.len() + 5] {
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
        assert_eq!(back.len(), eps.len());
        for a in &eps {
            let b = back.iter().find(|b| b.episode_id == a.episode_id).unwrap();
            same_episode(a, b, 1e-4);
            assert_eq!(
                a.goal.as_ref().map(|g| &g.kind),
                b.goal.as_ref().map(|g| &g.kind)
            );
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
