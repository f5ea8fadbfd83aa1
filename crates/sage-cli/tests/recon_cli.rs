//! `sage3d recon plan | render | export | project` end to end on a small synthetic scene.

mod common;

use common::{ok, s, sage3d, small_scene};
use std::path::Path;

fn plan(scene: &Path, out: &Path, policy: &str, budget: &str) -> String {
    ok(&[
        "recon",
        "plan",
        s(scene),
        "--policy",
        policy,
        "--budget",
        budget,
        "--seed",
        "3",
        "--out",
        s(out),
    ])
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn plan_render_export_resume_and_project() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    small_scene(&scene, "2", "1000");
    let dir = tmp.path().join("recon");
    // A budget that is not a multiple of 9 rounds down to whole placements.
    let printed = plan(&scene, &dir, "sweep", "40");
    let p = json(&dir.join("plan.json"));
    let (kept, dropped) = (
        p["views"].as_array().unwrap().len(),
        p["dropped"].as_array().unwrap().len(),
    );
    assert_eq!(kept + dropped, 36);
    assert!(
        printed.contains(&format!("sampled 36, kept {kept}, dropped {dropped}")),
        "{printed}"
    );
    assert!(dir.join("plan.png").is_file() && dir.join("sage3d_run.json").is_file());

    // Keep the debug render small: a handful of views.
    let mut small = p.clone();
    small["views"].as_array_mut().unwrap().truncate(9);
    std::fs::write(
        dir.join("plan.json"),
        serde_json::to_string(&small).unwrap(),
    )
    .unwrap();
    ok(&["recon", "render", s(&dir), "--size", "24x16"]);
    for k in 0..9 {
        assert!(dir.join(format!("views/rgb_{k:04}.png")).is_file());
        assert!(dir.join(format!("views/depth_{k:04}.png")).is_file());
    }
    // Resumable: a lost view is rendered again, the others are kept byte for byte.
    let before = std::fs::read(dir.join("views/rgb_0003.png")).unwrap();
    std::fs::remove_file(dir.join("views/depth_0005.png")).unwrap();
    let again = ok(&["recon", "render", s(&dir), "--size", "24x16"]);
    assert!(again.contains("rendered 1 of 9 views"), "{again}");
    assert_eq!(
        before,
        std::fs::read(dir.join("views/rgb_0003.png")).unwrap()
    );
    // Another size would mix images in one folder.
    let mixed = sage3d(&["recon", "render", s(&dir), "--size", "32x16"]);
    assert!(!mixed.status.success());
    assert!(String::from_utf8_lossy(&mixed.stderr).contains("already rendered at 24x16"));

    ok(&["recon", "export", s(&dir), "--points", "300"]);
    let t = json(&dir.join("transforms.json"));
    assert_eq!(t["ply_file_path"], "points3d.ply");
    let ply = std::fs::read(dir.join("points3d.ply")).unwrap();
    let header_end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    assert!(String::from_utf8_lossy(&ply[..header_end]).contains("element vertex 300"));
    assert_eq!(ply.len() - header_end, 300 * 15);
    assert_eq!(t["camera_model"], "OPENCV");
    assert_eq!((t["w"].as_u64(), t["h"].as_u64()), (Some(24), Some(16)));
    let frames = t["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 9);
    assert_eq!(frames[2]["file_path"], "views/rgb_0002.png");
    assert_eq!(
        t["val_filenames"],
        serde_json::json!(["views/rgb_0000.png", "views/rgb_0008.png"])
    );
    // An export without points removes the earlier one's, and says so; then they come back.
    let without = ok(&["recon", "export", s(&dir), "--points", "0"]);
    assert!(
        without.contains("removed") && without.contains("points3d.ply"),
        "{without}"
    );
    assert!(!dir.join("points3d.ply").exists());
    let again = ok(&["recon", "export", s(&dir), "--points", "300"]);
    assert!(!again.contains("removed"), "{again}");

    // The point 2 m ahead of view 4 lands on its principal point.
    let v = &small["views"][4];
    let (yaw, pitch) = (
        v["yaw_deg"].as_f64().unwrap().to_radians(),
        v["pitch_deg"].as_f64().unwrap().to_radians(),
    );
    let pos: Vec<f64> = v["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let ahead = [
        pos[0] + 2.0 * yaw.cos() * pitch.cos(),
        pos[1] + 2.0 * yaw.sin() * pitch.cos(),
        pos[2] + 2.0 * pitch.sin(),
    ];
    let point = format!("{},{},{}", ahead[0], ahead[1], ahead[2]);
    let lines = ok(&["recon", "project", s(&dir), "--point", &point]);
    let hit: serde_json::Value = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|j| j["view"] == 4)
        .expect("view 4 sees the point");
    assert!((hit["u"].as_f64().unwrap() - 12.0).abs() < 1e-3);
    assert!((hit["v"].as_f64().unwrap() - 8.0).abs() < 1e-3);
    assert!((hit["depth"].as_f64().unwrap() - 2.0).abs() < 1e-4);
    // A point that is nowhere is refused naming the flag, not answered with no view.
    for nowhere in ["nan,0,0", "inf,0,0", "1e30,0,0"] {
        let o = sage3d(&["recon", "project", s(&dir), &format!("--point={nowhere}")]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{nowhere}: {err}");
        assert!(
            err.contains("--point must be finite and within"),
            "{nowhere}: {err}"
        );
    }

    // A short fit: a scene folder with the fitted Gaussians and the original labels, and its
    // report (sage-train's own tests judge how well it fits).
    let fitted = tmp.path().join("fitted");
    let said = ok(&[
        "recon",
        "fit",
        s(&dir),
        "--iterations",
        "6",
        "--points",
        "1500",
        "--out",
        s(&fitted),
    ]);
    assert!(said.contains("7 views (2 held out)"), "{said}");
    let report = json(&fitted.join("fit_report.json"));
    assert_eq!(report["loss"].as_array().unwrap().len(), 6);
    assert_eq!(
        (
            report["train_views"].as_u64(),
            report["heldout_views"].as_u64()
        ),
        (Some(7), Some(2))
    );
    for key in [
        "initial_heldout_psnr",
        "final_heldout_psnr",
        "final_train_psnr",
    ] {
        assert!(report[key].as_f64().unwrap().is_finite(), "{key}");
    }
    let info = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&ok(&["scene", "info", s(dir), "--json"])).unwrap()
    };
    let (before, after) = (info(&scene), info(&fitted));
    assert_eq!(
        after["summary"]["gaussians"].as_u64(),
        report["gaussians"].as_u64()
    );
    assert_eq!(
        after["summary"]["categories"],
        before["summary"]["categories"]
    );
    assert_eq!(after["summary"]["rooms"], before["summary"]["rooms"]);

    // A new plan in the same folder never reuses the old plan's images.
    plan(&scene, &dir, "volume", "12");
    let stale = sage3d(&["recon", "render", s(&dir), "--size", "24x16"]);
    assert!(!stale.status.success());
    assert!(String::from_utf8_lossy(&stale.stderr).contains("rendered for another plan"));
    let stale = sage3d(&["recon", "export", s(&dir)]);
    assert!(String::from_utf8_lossy(&stale.stderr).contains("rendered for another plan"));
}

#[test]
fn volume_plans_are_the_same_for_a_seed_and_export_needs_rendered_views() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    small_scene(&scene, "4", "1000");
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    plan(&scene, &a, "volume", "60");
    ok(&[
        "--threads",
        "1",
        "recon",
        "plan",
        s(&scene),
        "--policy",
        "volume",
        "--budget",
        "60",
        "--seed",
        "3",
        "--out",
        s(&b),
    ]);
    for file in ["plan.json", "plan.png"] {
        let same = std::fs::read(a.join(file)).unwrap() == std::fs::read(b.join(file)).unwrap();
        assert!(same, "{file} differs between 1 thread and all threads");
    }
    let pa = json(&a.join("plan.json"));
    assert_eq!(
        pa["views"].as_array().unwrap().len() + pa["dropped"].as_array().unwrap().len(),
        60
    );
    let out = sage3d(&["recon", "export", s(&a)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("recon render"));
    // Counts past what any machine holds are refused naming their flags, before any work.
    let huge = tmp.path().join("huge");
    let o = sage3d(&[
        "recon",
        "plan",
        s(&scene),
        "--budget",
        "100001",
        "--out",
        s(&huge),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--budget must be at most 100000"), "{err}");
    assert!(!huge.exists());
    let o = sage3d(&["recon", "export", s(&a), "--points", "999999999999"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--points must be at most"), "{err}");
    let bad = sage3d(&[
        "recon",
        "plan",
        s(&scene),
        "--policy",
        "spiral",
        "--out",
        s(&a),
    ]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("expected sweep or volume"));
    // No floorplan, no cameras: said, and nothing written.
    std::fs::remove_file(scene.join("structure.json")).unwrap();
    let c = tmp.path().join("c");
    let bad = sage3d(&["recon", "plan", s(&scene), "--out", s(&c)]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("no rooms in structure.json"));
    assert!(!c.exists());
    let bad = sage3d(&["recon", "render", s(&c)]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("plan.json"));
}
