//! `scene import` end to end: a synthetic scene made into a tilted, Y-up, scaled capture file
//! (SPZ and standard PLY), imported into a scene folder that loads, maps and plans; and every
//! bad input refused with its reason and nothing written.

use glam::{Quat, Vec2, Vec3};
use sage_capture::Up;
use sage_capture::transform::{self, Similarity};
use sage_nav::{CostParams, GridParams, GridSource, NavGrid, PathFinder};
use sage_pipeline::capture::{
    CAPTURE_FILE, IMPORT_COMMAND, ImportSettings, OutputLayout, ScalePoints, import,
};
use sage_scene::splats::Format;
use sage_scene::{Gaussians, Scene, SplatLayout};
use sage_synth::{SceneKind, SynthConfig, generate};
use std::path::{Path, PathBuf};

/// W → capture: Y up, tilted 5°, half-metre units, moved.
fn to_capture() -> Similarity {
    Similarity {
        scale: 2.0,
        rotation: (Quat::from_rotation_z(0.2)
            * Quat::from_axis_angle(Vec3::new(1.0, 0.0, 1.0).normalize(), 5f32.to_radians())
            * Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2))
        .normalize(),
        translation: Vec3::new(-4.0, 1.0, 2.5),
    }
}

/// The capture of a small synthetic scene, written to `dir/name` in `format`.
fn write_capture(dir: &Path, name: &str, format: Format) -> PathBuf {
    write_cut_capture(dir, name, format, f32::INFINITY)
}

/// [`write_capture`] keeping only the Gaussians below `cut` metres (in the scene's frame):
/// a capture whose ceiling was cut away, as handheld captures often miss it.
fn write_cut_capture(dir: &Path, name: &str, format: Format, cut: f32) -> PathBuf {
    let scene = generate(&SynthConfig {
        seed: 11,
        kind: SceneKind::Home,
        rooms: 3,
        objects: 20,
        gaussians: 40_000,
        ..SynthConfig::default()
    })
    .unwrap();
    let g = &scene.gaussians;
    let keep: Vec<u32> = (0..g.len() as u32)
        .filter(|&i| g.positions[i as usize][2] < cut)
        .collect();
    let moved = transform::transform(g, &keep, &to_capture()).unwrap();
    let path = dir.join(name);
    sage_scene::splats::write_file(&path, &moved, format).unwrap();
    path
}

fn noop(_: sage_pipeline::capture::Stage) {}

#[test]
fn a_capture_becomes_a_scene_that_loads_maps_and_plans() {
    let dir = tempfile::tempdir().unwrap();
    for (name, format) in [
        ("cap.spz", Format::Spz),
        ("cap.ply", Format::Ply(SplatLayout::Standard)),
    ] {
        let input = write_capture(dir.path(), name, format);
        let out = dir.path().join(format!("scene_{name}"));
        // Two points 3 m apart on the floor, in the capture's coordinates.
        let c = to_capture();
        let (a, b) = (
            c.apply(Vec3::new(1.0, 1.0, 0.0)),
            c.apply(Vec3::new(1.0, 4.0, 0.0)),
        );
        let settings = ImportSettings {
            scale_points: Some(ScalePoints([a.to_array(), b.to_array()])),
            scale_distance: Some(3.0),
            ..ImportSettings::default()
        };
        let report = import(&input, &out, &settings, &noop).unwrap();
        assert!((report.scale - 0.5).abs() < 1e-3, "{}", report.scale);
        assert_eq!(report.floaters, 0);
        assert!(report.free_m2 > 5.0);
        for f in [
            "3dgs_compressed.ply",
            "occupancy.png",
            "occupancy.json",
            CAPTURE_FILE,
            sage_io::RUN_RECORD,
        ] {
            assert!(out.join(f).is_file(), "{name}: {f}");
        }
        assert!(!out.join("labels.json").exists());
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(CAPTURE_FILE)).unwrap())
                .unwrap();
        assert_eq!(record["frame"], "W");
        assert_eq!(record["scale"]["source"], "points");
        assert_eq!(record["floaters"]["removed"], 0);
        assert_eq!(record["transform"]["matrix"].as_array().unwrap().len(), 4);

        // The floor is at z = 0: the capture's map composed with the import's is level.
        let num = |v: &serde_json::Value| v.as_f64().unwrap() as f32;
        let q = &record["transform"]["rotation_wxyz"];
        let t = &record["transform"]["translation"];
        let imported = Similarity {
            scale: num(&record["transform"]["scale"]),
            rotation: Quat::from_xyzw(num(&q[1]), num(&q[2]), num(&q[3]), num(&q[0])),
            translation: Vec3::new(num(&t[0]), num(&t[1]), num(&t[2])),
        };
        let back = to_capture().then(&imported);
        for p in [Vec2::ZERO, Vec2::new(8.0, 0.0), Vec2::new(0.0, 8.0)] {
            let z = back.apply(p.extend(0.0)).z;
            assert!(z.abs() < 0.02, "{name}: floor point at z = {z}");
        }

        // The folder is a scene: it loads, its grid is its own map, and the planner works.
        let (scene, _) = Scene::load(&out).unwrap();
        assert!(scene.objects.is_empty());
        let (grid, source) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
        assert_eq!(source, GridSource::SceneOccupancy);
        assert!(grid.counts().0 > 1000);
        let (finder, _) =
            PathFinder::from_scene(&scene, &GridParams::default(), CostParams::default()).unwrap();
        let cells = finder.navigable_cells();
        let (a, b) = (
            finder.grid.center_of(cells[0] as usize),
            finder.grid.center_of(cells[cells.len() / 2] as usize),
        );
        if finder.island(a) == finder.island(b) {
            finder.find_path(a, b).unwrap();
        }

        // An existing, non-empty folder is refused: a rerun too.
        let e = import(&input, &out, &settings, &noop)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not empty"), "{e}");

        // An import killed while it wrote: its record marked unfinished, the Gaussians, a
        // temporary file. It is no scene, and the rerun replaces it.
        sage_io::run::mark_unfinished(&out, IMPORT_COMMAND, None).unwrap();
        for f in ["occupancy.png", "occupancy.json", CAPTURE_FILE] {
            std::fs::remove_file(out.join(f)).unwrap();
        }
        let stale = out.join(format!(".{CAPTURE_FILE}.tmp-4242-0"));
        std::fs::write(&stale, "half").unwrap();
        let e = Scene::load(&out).unwrap_err().to_string();
        assert!(e.contains("did not finish") && e.contains("rerun"), "{e}");
        import(&input, &out, &settings, &noop).unwrap();
        assert!(
            out.join(CAPTURE_FILE).is_file() && !stale.exists(),
            "{name}"
        );
        assert!(sage_io::run::is_finished(&out), "{name}");
        Scene::load(&out).unwrap();
    }
}

#[test]
fn bad_input_is_refused_with_its_reason_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_capture(dir.path(), "cap.spz", Format::Spz);
    let out = dir.path().join("out");
    let refused = |settings: ImportSettings, input: &Path, want: &str| {
        let e = import(input, &out, &settings, &noop)
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "wanted '{want}' in: {e}");
        assert!(!out.exists(), "{want}: the output folder was made");
    };
    for bad in [0.0, -2.0, f32::NAN] {
        refused(
            ImportSettings {
                scale: Some(bad),
                ..ImportSettings::default()
            },
            &input,
            "`scale` must be a finite number > 0",
        );
    }
    let same = ScalePoints([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]]);
    refused(
        ImportSettings {
            scale_points: Some(same),
            scale_distance: Some(2.5),
            ..ImportSettings::default()
        },
        &input,
        "same point",
    );
    let apart = ScalePoints([[0.0; 3], [1.0, 0.0, 0.0]]);
    refused(
        ImportSettings {
            scale_points: Some(apart),
            scale_distance: Some(0.0),
            ..ImportSettings::default()
        },
        &input,
        "`scale_distance` must be",
    );
    refused(
        ImportSettings {
            scale_points: Some(apart),
            ..ImportSettings::default()
        },
        &input,
        "need `scale_distance`",
    );
    refused(
        ImportSettings {
            scale: Some(2.0),
            scale_points: Some(apart),
            scale_distance: Some(1.0),
            ..ImportSettings::default()
        },
        &input,
        "not both",
    );
    assert!("1,2:3,4,5".parse::<ScalePoints>().is_err());
    assert_eq!(
        "1,2,3:4,5,6".parse::<ScalePoints>().unwrap(),
        ScalePoints([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    );

    let empty = dir.path().join("empty.ply");
    std::fs::write(&empty, b"").unwrap();
    refused(ImportSettings::default(), &empty, "empty");
    refused(
        ImportSettings::default(),
        &dir.path().join("missing.ply"),
        "missing.ply",
    );

    // A ball of round Gaussians: no surface, no floor; the message says so and names the file.
    let mut ball = Gaussians::new(0).unwrap();
    for i in 0..3000u32 {
        let f =
            |k: u32| ((i.wrapping_mul(2_654_435_761).rotate_left(k) % 1000) as f32) / 250.0 - 2.0;
        ball.push(&sage_scene::gaussians::Gaussian {
            position: Vec3::new(f(0), f(11), f(22)),
            log_scale: Vec3::splat(-3.0),
            opacity_logit: 3.0,
            ..Default::default()
        });
    }
    let ball_path = dir.path().join("ball.ply");
    sage_scene::ply::write_splats_file(&ball_path, &ball, SplatLayout::Standard).unwrap();
    refused(ImportSettings::default(), &ball_path, "no floor found");
    let e = import(&ball_path, &out, &ImportSettings::default(), &noop)
        .unwrap_err()
        .to_string();
    assert!(e.contains("ball.ply"), "{e}");

    // A folder holding anything is refused and left as it was.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let e = import(&input, &out, &ImportSettings::default(), &noop)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not empty") && e.contains("notes.txt"), "{e}");
    assert_eq!(sage_io::run::entries(&out).unwrap(), vec!["notes.txt"]);
}

#[test]
fn an_imported_capture_keeps_the_ceiling_height_its_import_measured() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_capture(dir.path(), "cap.spz", Format::Spz);
    // Capture units are half metres; a scale of 0.4 makes the synthetic home's 2.8 m rooms
    // 2.24 m high, away from the 2.8 m a scene without walls would otherwise be given.
    let out = dir.path().join("low");
    let settings = ImportSettings {
        scale: Some(0.4),
        ..ImportSettings::default()
    };
    let report = import(&input, &out, &settings, &noop).unwrap();
    assert!((report.ceiling - 2.24).abs() < 0.05, "{}", report.ceiling);
    let (scene, loaded) = Scene::load(&out).unwrap();
    assert!(loaded.files.iter().any(|f| f == CAPTURE_FILE));
    // capture.json keeps six decimals.
    let ceiling = scene.floorplan.ceiling.expect("the measured ceiling");
    assert!((ceiling - report.ceiling).abs() < 1e-5, "{ceiling}");
    assert_eq!(scene.floorplan.ceiling_height(), ceiling);

    // A ceiling that is not a height is refused, naming the file and the field.
    let path = out.join(CAPTURE_FILE);
    let mut record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    for bad in [
        serde_json::json!(-1.0),
        serde_json::json!("high"),
        serde_json::json!(1e9),
    ] {
        record["floor"]["ceiling_m"] = bad;
        std::fs::write(&path, record.to_string()).unwrap();
        let e = Scene::load(&out).unwrap_err().to_string();
        assert!(
            e.contains(CAPTURE_FILE) && e.contains("floor.ceiling_m"),
            "{e}"
        );
    }
    // None found (0): the scene has no measured ceiling.
    record["floor"]["ceiling_m"] = serde_json::json!(0.0);
    std::fs::write(&path, record.to_string()).unwrap();
    assert_eq!(Scene::load(&out).unwrap().0.floorplan.ceiling, None);
}

/// Capture units are half metres.
fn metric() -> ImportSettings {
    ImportSettings {
        scale: Some(0.5),
        ..ImportSettings::default()
    }
}

#[test]
fn a_capture_without_its_ceiling_keeps_its_floor_and_gets_no_ceiling_slab_at_furniture_height() {
    let dir = tempfile::tempdir().unwrap();
    let whole = write_capture(dir.path(), "whole.spz", Format::Spz);
    let cut = write_cut_capture(dir.path(), "cut.spz", Format::Spz, 2.7);
    let with = import(&whole, &dir.path().join("with"), &metric(), &noop).unwrap();
    assert!((with.ceiling - 2.8).abs() < 0.05, "{}", with.ceiling);
    for up in [Up::Auto, Up::Y] {
        let out = dir.path().join(format!("without_{up}"));
        let settings = ImportSettings { up, ..metric() };
        let without = import(&cut, &out, &settings, &noop).unwrap();
        let same_up = Vec3::from_array(without.up).angle_between(Vec3::from_array(with.up));
        assert!(
            same_up.to_degrees() < 0.5,
            "{up}: up {:?} vs {:?}",
            without.up,
            with.up
        );
        assert_eq!(without.ceiling, 0.0, "{up}");
        assert!(without.warnings.is_empty(), "{up}: {:?}", without.warnings);
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(CAPTURE_FILE)).unwrap())
                .unwrap();
        assert_eq!(record["floor"]["ceiling_m"], 0.0);
        assert_eq!(record["floor"]["floor_side"], "extreme");
        // The same floor: the two imports agree on the scene's height, up to the cut.
        let (scene, _) = Scene::load(&out).unwrap();
        assert_eq!(scene.floorplan.ceiling, None);
        let top = scene.gaussians.bounds().max.z;
        assert!(
            (top - 2.7).abs() < 0.05,
            "{up}: top of the Gaussians at {top}"
        );
        let cache = tempfile::tempdir().unwrap();
        let (bodies, _) = sage_physics::SceneBodies::build(
            &scene,
            &sage_physics::Decomposer::default(),
            &sage_physics::HullCache::new(cache.path()),
        )
        .unwrap();
        // No slab at a table top's height: it caps the Gaussians.
        assert!(
            bodies.ceiling_height >= top,
            "{up}: ceiling slab at {}",
            bodies.ceiling_height
        );
    }
}

#[test]
fn implausible_results_warn_and_an_import_without_free_floor_fails() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_capture(dir.path(), "cap.spz", Format::Spz);
    // Upside down: the up axis given is the capture's down.
    let report = import(
        &input,
        &dir.path().join("down"),
        &ImportSettings {
            up: Up::NegY,
            ..metric()
        },
        &noop,
    )
    .unwrap();
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("upside down") && w.contains("--up=y")),
        "{:?}",
        report.warnings
    );
    // The right way up: no warning.
    let right = ImportSettings {
        up: Up::Y,
        ..metric()
    };
    let report = import(&input, &dir.path().join("up"), &right, &noop).unwrap();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    // Scaled too small: the 2.8 m ceiling stands 1.68 m high, too low for a ceiling.
    let low = ImportSettings {
        scale: Some(0.3),
        ..ImportSettings::default()
    };
    let report = import(&input, &dir.path().join("low"), &low, &noop).unwrap();
    assert_eq!(report.ceiling, 0.0);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("1.68 m above the floor") && w.contains("--scale")),
        "{:?}",
        report.warnings
    );
    // Scaled too large: a 14 m ceiling.
    let high = ImportSettings {
        scale: Some(2.5),
        ..ImportSettings::default()
    };
    let report = import(&input, &dir.path().join("high"), &high, &noop).unwrap();
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("higher than rooms") && w.contains("--scale")),
        "{:?}",
        report.warnings
    );
    // Scaled so small that the whole home fits in the agent's slab: no free cell. Refused,
    // and nothing written.
    let out = dir.path().join("tiny");
    let tiny = ImportSettings {
        scale: Some(0.2),
        ..ImportSettings::default()
    };
    let e = import(&input, &out, &tiny, &noop).unwrap_err().to_string();
    assert!(
        e.contains("no free cell") && e.contains("--scale") && e.contains("cap.spz"),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn a_rerun_with_the_other_layout_removes_the_killed_imports_gaussians() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_capture(dir.path(), "cap.spz", Format::Spz);
    let out = dir.path().join("scene");
    import(&input, &out, &metric(), &noop).unwrap();
    // Killed: its run record marked unfinished, its compressed Gaussians left.
    sage_io::run::mark_unfinished(&out, IMPORT_COMMAND, None).unwrap();
    let notes = out.join("notes.txt");
    std::fs::write(&notes, "mine").unwrap();
    let standard = ImportSettings {
        layout: OutputLayout::Standard,
        // Another scale: other Gaussians, to tell which file the scene is read from.
        scale: Some(0.55),
        ..ImportSettings::default()
    };
    let report = import(&input, &out, &standard, &noop).unwrap();
    assert!(report.losses.is_empty());
    assert!(out.join("3dgs.ply").is_file());
    assert!(!out.join("3dgs_compressed.ply").exists());
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "mine");
    let (scene, loaded) = Scene::load(&out).unwrap();
    assert_eq!(
        loaded.splat_format,
        Some(Format::Ply(SplatLayout::Standard))
    );
    let top = scene.gaussians.bounds().max.z;
    assert!(
        (top - report.ceiling).abs() < 0.1,
        "{top} vs {}",
        report.ceiling
    );
    // And back: the standard file goes when the compressed one is written.
    sage_io::run::mark_unfinished(&out, IMPORT_COMMAND, None).unwrap();
    let report = import(&input, &out, &metric(), &noop).unwrap();
    assert!(!report.losses.is_empty());
    assert!(!out.join("3dgs.ply").exists() && out.join("3dgs_compressed.ply").is_file());
}
