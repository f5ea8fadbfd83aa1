//! No silent overwrites: every command that writes a folder refuses one holding files it did
//! not write (naming the folder and a file, exiting non-zero, touching nothing), writes beside
//! them with `--force`, refuses even then a file it would replace, and resumes in its own
//! folder; a command that writes a file refuses an existing one without `--force`.

mod common;

use common::{ok, s, sage3d, small_dataset, small_scene, stderr};
use std::path::Path;
use std::process::Output;

const MINE: &[u8] = b"the user's own bytes";

/// Checks the folder rule of a command: `run(out, force)` runs it writing into `out`; `own` is
/// one of the names it writes at the top of its folder; `command` is what its run record names.
fn claims_its_folder(
    dir: &Path,
    name: &str,
    own: &str,
    command: &str,
    run: &dyn Fn(&Path, bool) -> Output,
) {
    // A folder of the user's files is refused, naming the folder and the file.
    let out = dir.join(name);
    std::fs::create_dir_all(&out).unwrap();
    let notes = out.join("notes.txt");
    std::fs::write(&notes, MINE).unwrap();
    let refused = run(&out, false);
    let e = stderr(&refused);
    assert!(!refused.status.success(), "{name}: {e}");
    assert!(
        e.contains(s(&out)) && e.contains("notes.txt") && e.contains("--force"),
        "{name}: {e}"
    );
    assert_eq!(std::fs::read(&notes).unwrap(), MINE, "{name}");
    assert_eq!(
        sage_io::run::entries(&out).unwrap(),
        ["notes.txt"],
        "{name}"
    );
    // With --force the command writes beside them, and records itself.
    let forced = run(&out, true);
    assert!(forced.status.success(), "{name}: {}", stderr(&forced));
    assert_eq!(std::fs::read(&notes).unwrap(), MINE, "{name}");
    assert_eq!(
        sage_io::run::recorded_command(&out).as_deref(),
        Some(command),
        "{name}"
    );
    // The folder is now the command's own: a rerun needs no --force.
    let again = run(&out, false);
    assert!(again.status.success(), "{name}: {}", stderr(&again));
    assert_eq!(std::fs::read(&notes).unwrap(), MINE, "{name}");
    // A file of the user's under one of the command's own names is refused even with --force.
    let clash = dir.join(format!("{name}_clash"));
    std::fs::create_dir_all(&clash).unwrap();
    let theirs = clash.join(own);
    std::fs::write(&theirs, MINE).unwrap();
    let refused = run(&clash, true);
    let e = stderr(&refused);
    assert!(!refused.status.success(), "{name}: {e}");
    assert!(e.contains(s(&clash)) && e.contains(own), "{name}: {e}");
    assert_eq!(std::fs::read(&theirs).unwrap(), MINE, "{name}");
    assert_eq!(sage_io::run::entries(&clash).unwrap(), [own], "{name}");
}

/// `args` followed by `--force` when `force`.
fn with_force<'a>(args: &[&'a str], force: bool) -> Vec<&'a str> {
    let mut v = args.to_vec();
    if force {
        v.push("--force");
    }
    v
}

#[test]
fn scene_render_and_nav_commands_claim_their_folders() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "3", "1500");
    let synth = |out: &Path, force: bool| {
        let args = [
            "scene",
            "synth",
            "--rooms",
            "2",
            "--objects",
            "6",
            "--gaussians",
            "1000",
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "synth", "labels.json", "scene synth", &synth);
    let render = |out: &Path, force: bool| {
        let args = [
            "render",
            s(&scene),
            "--width",
            "32",
            "--height",
            "24",
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "render", "rgb.png", "render", &render);
    let map = |out: &Path, force: bool| {
        let args = ["nav", "map", s(&scene), "--cell", "0.1", "--out", s(out)];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "map", "semantic_map.json", "nav map", &map);
    let trajectories = |out: &Path, force: bool| {
        let args = [
            "nav",
            "trajectories",
            s(&scene),
            "--count",
            "2",
            "--cell",
            "0.1",
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(
        dir.path(),
        "trajectories",
        "trajectories.json",
        "nav trajectories",
        &trajectories,
    );
    // Both nav commands share their default folder, SCENE/nav, in either order and on reruns.
    for args in [
        &["nav", "map", s(&scene), "--cell", "0.1"][..],
        &[
            "nav",
            "trajectories",
            s(&scene),
            "--count",
            "2",
            "--cell",
            "0.1",
        ],
        &["nav", "map", s(&scene), "--cell", "0.1"],
    ] {
        ok(args);
    }
    assert!(scene.join("nav/semantic_map.json").is_file());
    assert!(scene.join("nav/trajectories.json").is_file());
}

#[test]
fn recon_plan_and_fit_claim_their_folders() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "4", "1000");
    let plan_args = |out: &Path| {
        vec![
            "recon".to_string(),
            "plan".into(),
            s(&scene).into(),
            "--policy".into(),
            "volume".into(),
            "--budget".into(),
            "20".into(),
            "--out".into(),
            s(out).into(),
        ]
    };
    let plan = |out: &Path, force: bool| {
        let args = plan_args(out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "plan", "plan.json", "recon plan", &plan);
    let recon = dir.path().join("recon");
    let args = plan_args(&recon);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    ok(&["recon", "render", s(&recon), "--size", "24x18"]);
    let fit = |out: &Path, force: bool| {
        let args = [
            "recon",
            "fit",
            s(&recon),
            "--iterations",
            "2",
            "--points",
            "200",
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "fit", "structure.json", "recon fit", &fit);
}

/// Checks that a command stopped while it writes its folder leaves one that is recognisably its
/// own unfinished work, which its rerun (no `--force`) redoes. `run(out)` runs the command into
/// `out`; `command` is what its run record names; `late` is one of its outputs written after
/// others; `scene` says whether the folder is a scene, which loads only once finished.
///
/// The stop is made without timing: with `late` turned into a folder, writing it fails there,
/// as a kill there would stop it, and the folder keeps what was written before; a kill's
/// leftover temporary file is added by hand. A first run killed the same way leaves the same
/// record beside fewer outputs, which is built by hand in a second folder.
fn a_stopped_run_is_redone(
    dir: &Path,
    name: &str,
    command: &str,
    late: &str,
    scene: bool,
    run: &dyn Fn(&Path) -> Output,
) {
    let out = dir.join(name);
    let done = run(&out);
    assert!(done.status.success(), "{name}: {}", stderr(&done));
    // A first run stopped after its first output: the record and that output alone.
    let first = dir.join(format!("{name}_first"));
    std::fs::create_dir(&first).unwrap();
    sage_io::run::mark_unfinished(&first, command, None).unwrap();
    let kept = sage_io::run::entries(&out)
        .unwrap()
        .into_iter()
        .find(|e| out.join(e).is_file() && e != sage_io::RUN_RECORD)
        .unwrap();
    std::fs::copy(out.join(&kept), first.join(&kept)).unwrap();
    std::fs::remove_file(out.join(late)).unwrap();
    std::fs::create_dir(out.join(late)).unwrap();
    let stopped = run(&out);
    assert!(!stopped.status.success(), "{name}");
    // The record was marked unfinished before the first output was written.
    assert_eq!(
        sage_io::run::unfinished_command(&out).as_deref(),
        Some(command),
        "{name}"
    );
    if scene {
        let info = sage3d(&["scene", "info", s(&out)]);
        let e = stderr(&info);
        assert!(!info.status.success(), "{name}: a stopped scene loads");
        assert!(
            e.contains(s(&out)) && e.contains("did not finish") && e.contains("rerun"),
            "{name}: {e}"
        );
    }
    std::fs::remove_dir(out.join(late)).unwrap();
    let stale = format!(".{late}.tmp-4242-0");
    for folder in [&out, &first] {
        std::fs::write(folder.join(&stale), "half").unwrap();
        let redone = run(folder);
        assert!(redone.status.success(), "{name}: {}", stderr(&redone));
        assert!(sage_io::run::is_finished(folder), "{name}");
        assert_eq!(
            sage_io::run::recorded_command(folder).as_deref(),
            Some(command),
            "{name}"
        );
        assert!(folder.join(late).is_file(), "{name}");
        assert!(
            !folder.join(&stale).exists(),
            "{name}: a stale temporary file is left"
        );
        if scene {
            ok(&["scene", "info", s(folder)]);
        }
    }
}

#[test]
fn commands_stopped_while_writing_their_folders_are_redone_by_their_reruns() {
    let dir = tempfile::tempdir().unwrap();
    let synth = |out: &Path| {
        sage3d(&[
            "scene",
            "synth",
            "--seed",
            "7",
            "--rooms",
            "2",
            "--objects",
            "6",
            "--gaussians",
            "1000",
            "--out",
            s(out),
        ])
    };
    a_stopped_run_is_redone(
        dir.path(),
        "synth",
        "scene synth",
        "objects.json",
        true,
        &synth,
    );
    // A stopped scene is no input: its scenes are skipped, naming it, until it is redone.
    let stopped = dir.path().join("stopped/home");
    std::fs::create_dir_all(&stopped).unwrap();
    sage_io::run::mark_unfinished(&stopped, "scene synth", None).unwrap();
    for f in ["3dgs_compressed.ply", "labels.json"] {
        std::fs::copy(dir.path().join("synth").join(f), stopped.join(f)).unwrap();
    }
    let data = dir.path().join("data");
    let build = sage3d(&["data", "build", s(&stopped), "--out", s(&data)]);
    let e = stderr(&build);
    assert!(!build.status.success(), "{e}");
    assert!(
        e.contains(s(&stopped)) && e.contains("did not finish"),
        "{e}"
    );
    let scene = dir.path().join("synth");
    let render = |out: &Path| {
        sage3d(&[
            "render",
            s(&scene),
            "--width",
            "32",
            "--height",
            "24",
            "--out",
            s(out),
        ])
    };
    a_stopped_run_is_redone(
        dir.path(),
        "render",
        "render",
        "render.json",
        false,
        &render,
    );
    let map = |out: &Path| sage3d(&["nav", "map", s(&scene), "--cell", "0.1", "--out", s(out)]);
    a_stopped_run_is_redone(
        dir.path(),
        "map",
        "nav map",
        "semantic_map.png",
        false,
        &map,
    );
    let recon = dir.path().join("recon");
    ok(&[
        "recon",
        "plan",
        s(&scene),
        "--policy",
        "volume",
        "--budget",
        "20",
        "--out",
        s(&recon),
    ]);
    ok(&["recon", "render", s(&recon), "--size", "24x18"]);
    let fit = |out: &Path| {
        sage3d(&[
            "recon",
            "fit",
            s(&recon),
            "--iterations",
            "2",
            "--points",
            "200",
            "--out",
            s(out),
        ])
    };
    a_stopped_run_is_redone(
        dir.path(),
        "fit",
        "recon fit",
        "fit_report.json",
        true,
        &fit,
    );
}

#[test]
fn data_import_and_eval_claim_their_folders() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let gvln = data.join("gvln/train.json");
    // Each import adds a split of its own name (an existing split is the other rule).
    let imports = std::cell::Cell::new(0);
    let import = |out: &Path, force: bool| {
        imports.set(imports.get() + 1);
        let split = format!("split{}", imports.get());
        let args = [
            "data",
            "import",
            s(&gvln),
            "--split",
            &split,
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "import", "splits.json", "data import", &import);
    // A dataset folder `data build` wrote takes a split, and keeps the build's record.
    ok(&[
        "data",
        "import",
        s(&gvln),
        "--split",
        "again",
        "--out",
        s(&data),
    ]);
    assert!(data.join("episodes/again.jsonl").is_file());
    assert_eq!(
        sage_io::run::recorded_command(&data).as_deref(),
        Some("data build")
    );
    let eval = |out: &Path, force: bool| {
        let args = [
            "eval",
            s(&data),
            "--scenes",
            s(&scenes),
            "--split",
            "train",
            "--agent",
            "forward",
            "--out",
            s(out),
        ];
        sage3d(&with_force(&args, force))
    };
    claims_its_folder(dir.path(), "run", "summary.json", "eval", &eval);
}

#[test]
fn the_demo_refuses_a_folder_of_other_files_before_it_writes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    std::fs::create_dir_all(&out).unwrap();
    let notes = out.join("notes.txt");
    std::fs::write(&notes, MINE).unwrap();
    let demo = |force: &[&str]| {
        let args = [
            "demo",
            "--out",
            s(&out),
            "--scenes",
            "1",
            "--split",
            "train",
        ];
        sage3d(&[&args[..], force].concat())
    };
    let refused = demo(&[]);
    let e = stderr(&refused);
    assert!(!refused.status.success() && e.contains("notes.txt") && e.contains(s(&out)));
    std::fs::create_dir_all(out.join("dataset")).unwrap();
    let refused = demo(&["--force"]);
    let e = stderr(&refused);
    assert!(!refused.status.success() && e.contains("'dataset'"), "{e}");
    assert_eq!(
        sage_io::run::entries(&out).unwrap(),
        ["dataset", "notes.txt"]
    );
    assert_eq!(std::fs::read(&notes).unwrap(), MINE);
}

#[test]
fn output_files_are_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    small_scene(&scene, "5", "1000");
    let file = |name: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, MINE).unwrap();
        p
    };
    let pending = file("pending.json");
    let usd = file("scene.usda");
    let preview = file("preview.png");
    let cases: [(Vec<&str>, &Path); 3] = [
        (
            vec!["physics", "pending", s(&scene), "--out", s(&pending)],
            &pending,
        ),
        (vec!["export", "usd", s(&scene), s(&usd)], &usd),
        (
            vec!["scene", "preview", s(&scene), "--out", s(&preview)],
            &preview,
        ),
    ];
    for (args, path) in &cases {
        let refused = sage3d(args);
        let e = stderr(&refused);
        assert!(!refused.status.success(), "{args:?}: {e}");
        assert!(
            e.contains(s(path)) && e.contains("--force"),
            "{args:?}: {e}"
        );
        assert_eq!(std::fs::read(path).unwrap(), MINE, "{args:?}");
        ok(&with_force(args, true));
        assert_ne!(std::fs::read(path).unwrap(), MINE, "{args:?}");
    }
}

#[test]
fn no_output_file_replaces_a_file_of_its_input_scene_or_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(dir.path());
    let scene = scenes.join("home1");
    let labels = scene.join("labels.json");
    let ply = scene.join("3dgs_compressed.ply");
    let mesh = std::fs::read_dir(scene.join("meshes"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let splits = data.join("splits.json");
    let cases: [(Vec<&str>, &Path); 6] = [
        (
            vec!["export", "usd", s(&scene), s(&labels), "--force"],
            &labels,
        ),
        (
            vec![
                "physics",
                "pending",
                s(&scene),
                "--out",
                s(&mesh),
                "--force",
            ],
            &mesh,
        ),
        (
            vec!["scene", "preview", s(&scene), "--out", s(&ply), "--force"],
            &ply,
        ),
        (vec!["splat", "convert", s(&ply), s(&ply), "--force"], &ply),
        (
            vec![
                "data",
                "export",
                s(&data),
                "--split",
                "train",
                "--out",
                s(&splits),
                "--force",
            ],
            &splits,
        ),
        (
            vec![
                "data",
                "export",
                s(&data),
                "--split",
                "train",
                "--scenes",
                s(&scenes),
                "--out",
                s(&labels),
                "--force",
            ],
            &labels,
        ),
    ];
    for (args, path) in &cases {
        let before = std::fs::read(path).unwrap();
        let refused = sage3d(args);
        let e = stderr(&refused);
        assert!(!refused.status.success(), "{args:?}: {e}");
        assert!(
            e.contains(s(path)) && e.contains("the output is ") && e.contains("write to another"),
            "{args:?}: {e}"
        );
        assert_eq!(std::fs::read(path).unwrap(), before, "{args:?}");
    }
    // The scene still loads, and a new file beside its own is written.
    ok(&["scene", "info", s(&scene)]);
    let usd = scene.join("scene.usda");
    ok(&["export", "usd", s(&scene), s(&usd)]);
    ok(&["export", "usd", s(&scene), s(&usd), "--force"]);
}

#[test]
fn a_mesh_objects_json_names_outside_meshes_is_never_written_over() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home1");
    small_scene(&scene, "1", "3000");
    let with_mesh = || {
        let info = ok(&["scene", "info", s(&scene), "--json"]);
        serde_json::from_str::<serde_json::Value>(&info).unwrap()["summary"]["objects_with_mesh"]
            .clone()
    };
    let before_move = with_mesh();
    // One object's mesh moved out of `meshes/`, named by its entry in objects.json.
    let objects_path = scene.join("objects.json");
    let mut objects: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&objects_path).unwrap()).unwrap();
    let entry = objects["objects"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|e| e["mesh"].is_string())
        .expect("an object with a mesh");
    let old = scene.join(entry["mesh"].as_str().unwrap());
    std::fs::create_dir_all(scene.join("assets")).unwrap();
    let moved = scene.join("assets").join("chair.obj");
    std::fs::rename(&old, &moved).unwrap();
    entry["mesh"] = "assets/chair.obj".into();
    std::fs::write(&objects_path, objects.to_string()).unwrap();
    // The scene loads with the moved mesh …
    assert_eq!(with_mesh(), before_move);
    // … and a command's output file is never that mesh, not even with --force.
    let before = std::fs::read(&moved).unwrap();
    let refused = sage3d(&["export", "usd", s(&scene), s(&moved), "--force"]);
    let e = stderr(&refused);
    assert!(!refused.status.success(), "{e}");
    assert!(
        e.contains(s(&moved)) && e.contains("the output is ") && e.contains("write to another"),
        "{e}"
    );
    assert_eq!(std::fs::read(&moved).unwrap(), before);
}
