//! `sage3d nav map` and `sage3d nav trajectories` end to end: outputs, byte-identical reruns
//! across thread counts, resume over a folder of scenes, and a clear error for a bad folder.

mod common;

use common::{ok, s, sage3d, small_scene, stderr};

use std::path::Path;

#[test]
fn map_writes_json_png_and_occupancy() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "1", "2000");
    let printed = ok(&["nav", "map", s(&scene)]);
    assert!(printed.contains("items"), "{printed}");
    let out = scene.join("nav");
    for f in [
        "semantic_map.json",
        "semantic_map.png",
        "occupancy.png",
        "occupancy.json",
        "sage3d_run.json",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let map: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("semantic_map.json")).unwrap()).unwrap();
    let first = &map["items"][0];
    for key in [
        "item_id",
        "category",
        "instance_id",
        "room",
        "polygon",
        "bbox_m",
        "min_z",
        "max_z",
    ] {
        assert!(first.get(key).is_some(), "{key} missing");
    }
}

/// The first object mesh of the scene in `scene`.
fn first_mesh(scene: &Path) -> std::path::PathBuf {
    let mut meshes: Vec<_> = std::fs::read_dir(scene.join("meshes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().is_some_and(|n| n != "structure.obj"))
        .collect();
    meshes.sort();
    meshes.remove(0)
}

#[test]
fn a_mesh_beyond_the_coordinate_bound_is_refused_and_one_at_it_is_mapped() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "1", "2000");
    let mesh = first_mesh(&scene);
    let tetra = |far: &str| {
        format!(
            "v 0 0 0\nv {far} 0 0\nv 0 {far} 0\nv 0 0 {far}\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
        )
    };
    std::fs::write(&mesh, tetra("1e30")).unwrap();
    let out = sage3d(&["nav", "map", s(&scene)]);
    let e = stderr(&out);
    assert!(!out.status.success(), "{e}");
    assert!(
        e.contains(&format!(
            "{}: line 2: vertex (1e30, 0.0, 0.0)",
            mesh.display()
        )) && e.contains("within ±10000 m"),
        "{e}"
    );
    assert!(
        !scene.join("nav").exists(),
        "a refused scene leaves no folder"
    );
    // At the bound the mesh's footprint is kilometres across; the maps cover the rooms only.
    std::fs::write(&mesh, tetra("1e4")).unwrap();
    ok(&["nav", "map", s(&scene)]);
    assert!(scene.join("nav/sage3d_run.json").is_file());
}

#[test]
fn a_map_that_fails_to_write_leaves_none_of_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "1", "2000");
    ok(&["nav", "map", s(&scene)]);
    let nav = scene.join("nav");
    // A folder where the picture goes makes its write fail, after the JSON map was written.
    std::fs::remove_file(nav.join("semantic_map.png")).unwrap();
    std::fs::create_dir(nav.join("semantic_map.png")).unwrap();
    let out = sage3d(&["nav", "map", s(&scene)]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("semantic_map.png"),
        "{}",
        stderr(&out)
    );
    for f in ["semantic_map.json", "occupancy.png", "occupancy.json"] {
        assert!(!nav.join(f).exists(), "{f} left beside a failed write");
    }
    // The folder is still the command's: once the obstacle is gone, a rerun makes the maps.
    std::fs::remove_dir(nav.join("semantic_map.png")).unwrap();
    ok(&["nav", "map", s(&scene)]);
    assert!(nav.join("semantic_map.json").is_file() && nav.join("semantic_map.png").is_file());
}

#[test]
fn trajectories_resume_over_a_folder_and_match_across_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    small_scene(&scenes.join("s1"), "1", "2000");
    small_scene(&scenes.join("s2"), "2", "2000");
    let out_a = dir.path().join("a");
    let out_b = dir.path().join("b");
    let args = |out: &Path, threads: &str| {
        vec![
            "--threads".to_string(),
            threads.to_string(),
            "nav".into(),
            "trajectories".into(),
            s(&scenes).into(),
            "--count".into(),
            "8".into(),
            "--seed".into(),
            "5".into(),
            "--out".into(),
            s(out).into(),
        ]
    };
    let run = |out: &Path, threads: &str| {
        let a = args(out, threads);
        ok(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let first = run(&out_a, "1");
    assert!(first.contains("2 done"), "{first}");
    run(&out_b, "2");
    for scene in ["s1", "s2"] {
        let a = std::fs::read(out_a.join(scene).join("trajectories.json")).unwrap();
        let b = std::fs::read(out_b.join(scene).join("trajectories.json")).unwrap();
        assert_eq!(a, b, "{scene} differs across thread counts");
        assert!(out_a.join(scene).join("trajectories.png").is_file());
    }
    // A crash that lost one scene's output: the rerun redoes that scene only, and records
    // what the folder holds, as the run that went through did.
    let recorded = std::fs::read(out_a.join("sage3d_run.json")).unwrap();
    std::fs::remove_file(out_a.join("s2").join("trajectories.json")).unwrap();
    let again = run(&out_a, "2");
    assert!(again.contains("1 done, 1 already complete"), "{again}");
    assert_eq!(
        String::from_utf8(std::fs::read(out_a.join("sage3d_run.json")).unwrap()).unwrap(),
        String::from_utf8(recorded).unwrap()
    );
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_a.join("sage3d_run.json")).unwrap()).unwrap();
    assert_eq!(record["seed"], 5);
    assert!(record["scenes"][0]["inputs"]["structure.json"].is_string());
}

#[test]
fn a_folder_without_scenes_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = sage3d(&["nav", "trajectories", s(dir.path()), "--count", "2"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("neither a scene folder"), "{err}");
}

#[test]
fn a_skipped_scene_is_named_and_the_exit_status_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    small_scene(&scenes.join("good"), "1", "2000");
    small_scene(&scenes.join("broken"), "2", "2000");
    let labels = scenes.join("broken").join("labels.json");
    let intact = std::fs::read(&labels).unwrap();
    std::fs::write(&labels, "{").unwrap();
    let out_dir = dir.path().join("out");
    let args = [
        "nav",
        "trajectories",
        s(&scenes),
        "--count",
        "4",
        "--out",
        s(&out_dir),
    ];
    let out = sage3d(&args);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("broken") && err.contains("labels.json"),
        "{err}"
    );
    assert!(err.contains("1 of 2 scenes were skipped"), "{err}");
    // The good scene is complete; the broken one has nothing, and a rerun after the fix does
    // it alone.
    assert!(out_dir.join("good").join("trajectories.json").is_file());
    assert!(!out_dir.join("broken").join("trajectories.json").exists());
    std::fs::write(&labels, intact).unwrap();
    let again = ok(&args);
    assert!(again.contains("1 done, 1 already complete"), "{again}");
}

#[test]
fn a_scene_with_fewer_trajectories_than_asked_is_noted_and_none_at_all_fails() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "1", "2000");
    let trajectories = |out: &str, count: &str, min_distance: &str| {
        let out = dir.path().join(out);
        sage3d(&[
            "nav",
            "trajectories",
            s(&scene),
            "--count",
            count,
            "--min-distance",
            min_distance,
            "--out",
            s(&out),
        ])
    };
    // No two stand points of a small home are 500 m apart: every candidate is rejected.
    let far = trajectories("far", "3", "500");
    assert_eq!(far.status.code(), Some(1));
    let err = stderr(&far);
    assert!(err.contains("0 of 3 trajectories"), "{err}");
    assert!(err.contains("no trajectory was made"), "{err}");
    // Few pairs 5 m apart: some trajectories, fewer than asked, noted; the command succeeds.
    let some = trajectories("some", "20", "5");
    let err = stderr(&some);
    assert!(some.status.success(), "{err}");
    let made: usize = err
        .split_once(" of 20 trajectories;")
        .and_then(|(before, _)| before.rsplit(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no note: {err}"));
    assert!((1..20).contains(&made), "{err}");
    // The default distance fills the count: no note.
    let near = trajectories("near", "3", "2");
    let err = stderr(&near);
    assert!(
        near.status.success() && !err.contains("trajectories;"),
        "{err}"
    );
}

#[test]
fn a_min_distance_that_is_no_distance_is_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "1", "2000");
    let out = dir.path().join("out");
    for v in ["-1", "nan", "inf"] {
        let flag = format!("--min-distance={v}");
        let o = sage3d(&["nav", "trajectories", s(&scene), &flag, "--out", s(&out)]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{v}: {err}");
        assert!(
            err.contains("--min-distance must be a finite distance >= 0 m"),
            "{v}: {err}"
        );
        assert!(!out.exists(), "{v}");
    }
    // The planner's settings out of range are refused naming their flags, nothing written.
    for (flag, shown) in [
        ("--radius=-1", "--radius (0-10 m)"),
        ("--radius=nan", "--radius (0-10 m)"),
        ("--narrow-weight=-2", "--narrow-weight (>= 0)"),
        ("--step=0", "--step"),
        ("--step=0.6", "--step must be > 0 and at most 0.5 m"),
        ("--step=1e30", "--step must be > 0 and at most 0.5 m"),
        ("--count=100001", "--count must be at most 100000"),
    ] {
        let o = sage3d(&["nav", "trajectories", s(&scene), flag, "--out", s(&out)]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{flag}: {err}");
        assert!(err.contains(shown) && !err.contains('`'), "{flag}: {err}");
        assert!(!out.exists(), "{flag}");
    }
    // The robot radius is a setting of the trajectories' planner; the map has none.
    let o = sage3d(&["nav", "map", s(&scene), "--radius", "0.3"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
