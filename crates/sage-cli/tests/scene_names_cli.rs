//! Scene folders are named by their folder: `data build` and `nav trajectories` refuse a scene
//! folder whose name is not a plain name before anything is written, naming the folder and the
//! rule, instead of writing episodes every reader then refuses.

mod common;

use common::{s, sage3d, small_scene, stderr};

#[test]
fn data_build_and_nav_trajectories_refuse_a_scene_folder_without_a_plain_name() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    small_scene(&scenes.join("home1"), "1", "1000");
    small_scene(&scenes.join("My Home"), "2", "1000");
    let checks: [(&str, Vec<&str>); 2] = [
        ("data", vec!["build", s(&scenes), "--per-scene", "2"]),
        ("nav", vec!["trajectories", s(&scenes), "--count", "2"]),
    ];
    for (command, args) in checks {
        let out_dir = dir.path().join(format!("out_{command}"));
        let mut all = vec![command];
        all.extend(&args);
        all.extend(["--out", s(&out_dir)]);
        let out = sage3d(&all);
        assert!(!out.status.success(), "{all:?} succeeded");
        let err = stderr(&out);
        assert!(err.contains("My Home"), "{all:?}: {err}");
        assert!(err.contains("holds ' '"), "{all:?}: {err}");
        assert!(err.contains("rename the folder"), "{all:?}: {err}");
        assert!(
            !out_dir.exists(),
            "{all:?} wrote into {}",
            out_dir.display()
        );
    }
    // Renamed, the same folder builds, and its episodes read back.
    std::fs::rename(scenes.join("My Home"), scenes.join("My_Home")).unwrap();
    let data = dir.path().join("data");
    let out = sage3d(&[
        "data",
        "build",
        s(&scenes),
        "--per-scene",
        "2",
        "--out",
        s(&data),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text: String = std::fs::read_dir(data.join("episodes"))
        .unwrap()
        .map(|e| std::fs::read_to_string(e.unwrap().path()).unwrap())
        .collect();
    assert!(text.contains("My_Home-n0"), "{text}");
}
