//! Each benchmark on a tiny setting: it runs, and its report holds what it measured.

use sage_perf::load::{self, LoadSettings};
use sage_perf::nav::{self, NavSettings};
use sage_perf::physics::{self, PhysicsSettings};
use sage_perf::render::{self, RenderSettings};

/// Generated inputs go to the fresh-process step with the input set; here that step measures
/// in this process. One test for both, as they share this process's scratch folder.
#[test]
fn load_and_render_hand_generated_inputs_to_the_fresh_step() {
    let settings = LoadSettings {
        gaussians: 3000,
        repeat: 2,
        ..LoadSettings::default()
    };
    let report = load::run(&settings, &|s| {
        let file = s.input.as_ref().expect("the generated file");
        assert!(file.is_file());
        load::run(s, &|_| unreachable!("a given file is measured in process"))
    })
    .unwrap();
    assert_eq!(report.format, "compressed-ply");
    assert_eq!(report.decode_s.len(), 2);
    assert!(report.gaussians > 0 && report.sh_degree == 1);
    assert!(!report.file.exists(), "the scratch folder is removed");
    assert_eq!(
        report.to_string().lines().count(),
        5 + report.resident_growth_bytes.iter().count()
    );
    // Every writable format can be generated and measured; the read-only ones come as files.
    for format in ["ply", "spz"] {
        let settings = LoadSettings {
            format: format.parse().unwrap(),
            ..settings.clone()
        };
        let report = load::run(&settings, &|s| load::run(s, &|_| unreachable!())).unwrap();
        assert_eq!(report.format, format);
    }
    let sog = LoadSettings {
        format: "sog".parse().unwrap(),
        ..settings.clone()
    };
    let e = load::run(&sog, &|_| unreachable!())
        .unwrap_err()
        .to_string();
    assert!(e.contains("`input`"), "{e}");

    let settings = RenderSettings {
        gaussians: 3000,
        frames: 2,
        sizes: Some(vec![(16, 12), (24, 16)]),
        sh3: true,
        ..RenderSettings::default()
    };
    let report = render::run(&settings, &|s| {
        assert!(s.scene.as_ref().is_some_and(|d| d.is_dir()) && !s.sh3);
        render::run(s, &|_| unreachable!("a given scene is measured in process"))
    })
    .unwrap();
    assert_eq!(report.sh_degree, 3);
    let sizes: Vec<_> = report.sizes.iter().map(|t| (t.width, t.height)).collect();
    assert_eq!(Some(sizes), settings.sizes);
    let text = report.to_string();
    assert!(
        text.contains("\n16x12         median ") && text.contains("\n24x16         median "),
        "{text}"
    );
    // The mean beside the median: what a user rendering every heading pays per frame.
    assert!(text.contains(" ms/frame (mean "), "{text}");
    // The CPU renders: its stage breakdown and index are reported, no batches (the CPU renders
    // a batch one camera after the other), and the JSON keeps the fields it always had.
    assert!(report.renderer.starts_with("cpu"), "{}", report.renderer);
    assert!(text.contains(&format!("renderer         {}", report.renderer)));
    assert!(report.sizes.iter().all(|t| t.breakdown.is_some()));
    assert!(report.index_bytes.is_some() && report.batches.is_empty());
    let json = serde_json::to_value(&report).unwrap();
    let size = &json["sizes"][0];
    for key in [
        "median_ms",
        "worst_ms",
        "mean_ms",
        "cull_ms",
        "raster_ms",
        "splats",
    ] {
        assert!(size.get(key).is_some(), "{key}: {size}");
    }
    assert!(json["index_bytes"].is_u64() && json.get("batches").is_none());
    // No CPU renderer beside the CPU renderer.
    assert!(size.get("cpu_median_ms").is_none() && !text.contains("in the same rounds"));
    let back: render::RenderReport = serde_json::from_value(json).unwrap();
    assert_eq!(back, report);
}

#[test]
fn render_refuses_an_empty_batch_or_no_pitch_before_any_work() {
    let settings = RenderSettings {
        batches: vec![16, 0],
        ..RenderSettings::default()
    };
    let e = render::run(&settings, &|_| unreachable!("nothing is measured"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 1 camera"), "{e}");
    // A pitch past straight up or down (or none at all) is no camera either.
    for pitch in [90.5, -120.0, f32::NAN] {
        let settings = RenderSettings {
            pitch,
            ..RenderSettings::default()
        };
        let e = render::run(&settings, &|_| unreachable!("nothing is measured"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`pitch` must be -90 to 90 degrees"),
            "{pitch}: {e}"
        );
    }
}

#[test]
fn nav_plans_in_a_small_home() {
    let report = nav::run(&NavSettings {
        count: 8,
        rooms: 3,
        ..NavSettings::default()
    })
    .unwrap();
    assert_eq!(report.rooms, 3);
    assert!(report.trajectories > 0 && report.trajectories <= 8);
    assert!(report.planned >= report.trajectories);
    assert_eq!(report.to_string().lines().count(), 5);
}

#[test]
fn physics_steps_an_agent() {
    let cache = tempfile::tempdir().unwrap();
    let settings = PhysicsSettings {
        objects: 14,
        cache: Some(cache.path().to_path_buf()),
        steps: 200,
        repeat: 2,
        ..PhysicsSettings::default()
    };
    let report = physics::run(&settings).unwrap();
    assert_eq!((report.agent.as_str(), report.steps), ("wheeled", 200));
    assert_eq!(report.steps_per_s.len(), 2);
    assert!(report.touching <= 200 && report.parts > 0);
    assert!(report.to_string().contains("steps/s          median "));
    let unknown = PhysicsSettings {
        agent: "nope".into(),
        ..settings
    };
    assert!(physics::run(&unknown).is_err());
}

#[test]
fn env_steps_a_vector_environment_over_the_scenes_renderers() {
    use sage_perf::env::{self, EnvSettings};
    let cache = tempfile::tempdir().unwrap();
    let settings = EnvSettings {
        objects: 56,
        gaussians: 20_000,
        steps: 100,
        render_steps: 6,
        sizes: vec![(32, 24)],
        cache: Some(cache.path().to_path_buf()),
        envs: 6,
        ..EnvSettings::default()
    };
    let report = env::run(&settings).unwrap();
    assert_eq!(report.rendered.len(), 1);
    let v = report.vector.as_ref().unwrap();
    assert_eq!((v.envs, v.width, v.height), (6, 32, 24));
    // The environments borrow renderers from the scene's pool: at least one, never one each
    // beyond what rendered at once (the single environments of the rates before were one
    // at a time).
    assert!(v.cpu_renderers >= 1 && v.cpu_renderers <= 6, "{v:?}");
    let text = report.to_string();
    assert!(
        text.contains("CPU renderers between the scene's environments"),
        "{text}"
    );
    if cfg!(target_os = "linux") {
        assert!(v.resident_bytes.is_some_and(|b| b > 0));
        assert!(text.contains("MB: the whole process after the vector environment"));
    }
}
