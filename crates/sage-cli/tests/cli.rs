//! The `sage3d` binary end to end: synth, info, convert, demo and bad input.

mod common;

use common::{ok, s, sage3d, small_scene, stderr};

use std::path::PathBuf;

fn testdata(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name)
        .display()
        .to_string()
}

#[test]
fn synth_then_info_describes_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("office");
    let printed = ok(&[
        "scene",
        "synth",
        "--seed",
        "5",
        "--kind",
        "office",
        "--rooms",
        "4",
        "--objects",
        "30",
        "--gaussians",
        "30000",
        "--out",
        s(&out),
    ]);
    assert!(printed.contains("gaussians"), "{printed}");
    for f in [
        "3dgs_compressed.ply",
        "labels.json",
        "structure.json",
        "objects.json",
        "occupancy.png",
        "occupancy.json",
        "sage3d_run.json",
        "meshes/structure.obj",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let info = ok(&["scene", "info", s(&out)]);
    assert!(
        info.contains("SH degree 1")
            && info.contains("rooms")
            && info.contains("format      compressed-ply"),
        "{info}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&ok(&["scene", "info", s(&out), "--json"])).unwrap();
    assert!(json["summary"]["objects"].as_u64().unwrap() >= 20);
    assert!(json["missing"].as_array().unwrap().is_empty(), "{json}");
}

#[test]
fn standard_layout_loads_like_compressed() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let common = [
        "--seed",
        "2",
        "--rooms",
        "3",
        "--objects",
        "20",
        "--gaussians",
        "20000",
    ];
    ok(&[&["scene", "synth", "--out", s(&a)][..], &common[..]].concat());
    ok(&[
        &["scene", "synth", "--out", s(&b), "--layout", "standard"][..],
        &common[..],
    ]
    .concat());
    assert!(b.join("3dgs.ply").is_file());
    let ja: serde_json::Value =
        serde_json::from_str(&ok(&["scene", "info", s(&a), "--json"])).unwrap();
    let jb: serde_json::Value =
        serde_json::from_str(&ok(&["scene", "info", s(&b), "--json"])).unwrap();
    assert_eq!(ja["summary"]["gaussians"], jb["summary"]["gaussians"]);
    assert_eq!(ja["summary"]["categories"], jb["summary"]["categories"]);
}

#[test]
fn convert_round_trip_through_both_layouts() {
    let dir = tempfile::tempdir().unwrap();
    let packed = dir.path().join("x.compressed.ply");
    let plain = dir.path().join("x.ply");
    let printed = ok(&[
        "splat",
        "convert",
        &testdata("random_4k_sh3.ply"),
        s(&packed),
    ]);
    assert!(printed.contains("4096 Gaussians, SH degree 3"), "{printed}");
    ok(&["splat", "convert", s(&packed), s(&plain)]);
    let printed = ok(&["splat", "convert", s(&plain), s(&dir.path().join("y.ply"))]);
    assert!(printed.contains("(ply, 4096 Gaussians"), "{printed}");
    assert!(printed.contains("lossless"), "{printed}");
    // Any format in, SPZ out, with what SPZ cannot hold listed; SH bands dropped on request.
    let spz = dir.path().join("x.spz");
    let printed = ok(&["splat", "convert", &testdata("random_3k_sh0.sog"), s(&spz)]);
    assert!(
        printed.contains("(sog, 3000 Gaussians") && printed.contains("lost: positions"),
        "{printed}"
    );
    let printed = ok(&[
        "splat",
        "convert",
        &testdata("random_4k_sh3.glb"),
        s(&dir.path().join("sh1.compressed.ply")),
        "--sh-degree",
        "1",
    ]);
    assert!(
        printed.contains("(gltf, 4096 Gaussians, SH degree 3)")
            && printed.contains("SH degree 1")
            && printed.contains("lost: SH bands 2–3 dropped"),
        "{printed}"
    );
    // An existing output is never replaced unasked.
    let out = sage3d(&["splat", "convert", s(&plain), s(&spz)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--force"));
    ok(&["splat", "convert", s(&plain), s(&spz), "--force"]);
}

/// A reader that stops early (`sage3d … | head`) ends the command quietly: killed by SIGPIPE
/// as `cat` is, or done before it noticed; never a panic.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("home");
    small_scene(&scene, "2", "2000");
    for args in [vec!["scene", "info", s(&scene)], vec!["--help"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_sage3d"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            out.status.success() || out.status.signal() == Some(13),
            "{args:?}: {:?} {err}",
            out.status
        );
    }
}

#[test]
fn bad_input_is_a_clear_error_and_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.ply");
    std::fs::write(
        &bad,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nend_header\n",
    )
    .unwrap();
    let out_path = dir.path().join("out.compressed.ply");
    let out = sage3d(&["splat", "convert", s(&bad), s(&out_path)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("broken.ply") && err.contains("element 'vertex': file is truncated"),
        "{err}"
    );
    assert!(!out_path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary files left"
    );

    let scene = dir.path().join("scene");
    std::fs::create_dir(&scene).unwrap();
    std::fs::write(
        scene.join("labels.json"),
        r#"[{"ins_id":"1","label":"chair","bounding_box":[{"x":0,"y":0,"z":0}]}]"#,
    )
    .unwrap();
    let out = sage3d(&["scene", "info", s(&scene)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("labels.json: [0].bounding_box: expected 8 corners, found 1"),
        "{err}"
    );

    let out = sage3d(&[
        "splat",
        "convert",
        &testdata("random_3k_sh0.ply"),
        s(&dir.path().join("x.splat")),
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot tell the output format"));
}

#[test]
fn demo_runs_the_whole_pipeline_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let args = [
        "demo",
        "--out",
        s(&out),
        "--scenes",
        "1",
        "--per-scene",
        "3",
        "--gaussians",
        "20000",
        "--agents",
        "oracle,forward",
    ];
    // One scene lands in train: the default split would be empty, and the demo says what to
    // do before it makes anything.
    let empty = sage3d(&args);
    assert!(!empty.status.success());
    let e = String::from_utf8_lossy(&empty.stderr);
    assert!(
        e.contains("split gets no episode") && e.contains("--split train"),
        "{e}"
    );
    assert!(!out.exists());
    let printed = ok(&[&args[..], &["--split", "train"]].concat());
    assert!(sage_io::run::is_finished(&out));
    let rows: Vec<&str> = printed
        .lines()
        .filter(|l| l.starts_with("oracle") || l.starts_with("forward"))
        .collect();
    assert_eq!(rows.len(), 2, "{printed}");
    // The oracle reaches its goals; forward-only never calls STOP at one.
    let sr = |row: &str| {
        row.split_whitespace()
            .nth(2)
            .unwrap()
            .parse::<f64>()
            .unwrap()
    };
    assert!(sr(rows[0]) > 0.9 && sr(rows[1]) == 0.0, "{printed}");
    for f in [
        "overview.png",
        "scenes/home_0/nav/semantic_map.png",
        "dataset/episodes/train.jsonl",
        "runs/oracle/summary.json",
        "runs/forward/episodes.jsonl",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // A second run keeps everything: no episode is run twice.
    let records = std::fs::read_to_string(out.join("runs/oracle/episodes.jsonl")).unwrap();
    let again = ok(&[&args[..], &["--split", "train"]].concat());
    assert!(
        again.contains("already complete") && again.contains("rendered 0 frames"),
        "{again}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("runs/oracle/episodes.jsonl")).unwrap(),
        records
    );
    // The same pipeline on an InteriorGS folder: no meshes, no objects.json; boxes and the
    // structure become the physics layer.
    let real = dir.path().join("interiorgs").join("0001_839920");
    std::fs::create_dir_all(&real).unwrap();
    for f in [
        "3dgs_compressed.ply",
        "labels.json",
        "structure.json",
        "occupancy.png",
        "occupancy.json",
    ] {
        std::fs::copy(out.join("scenes/home_0").join(f), real.join(f)).unwrap();
    }
    let out2 = dir.path().join("demo_real");
    let printed = ok(&[
        "demo",
        "--from",
        s(real.parent().unwrap()),
        "--out",
        s(&out2),
        "--per-scene",
        "3",
        "--agents",
        "oracle",
        "--split",
        "train",
    ]);
    let row = printed.lines().find(|l| l.starts_with("oracle")).unwrap();
    assert!(sr(row) > 0.9, "{printed}");
    assert!(real.join("nav/semantic_map.json").is_file());
    assert!(out2.join("overview.png").is_file());
}

#[test]
fn render_writes_every_channel_and_a_turntable() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    ok(&[
        "scene",
        "synth",
        "--seed",
        "3",
        "--rooms",
        "2",
        "--objects",
        "12",
        "--gaussians",
        "20000",
        "--out",
        s(&scene),
    ]);
    let camera = dir.path().join("camera.json");
    let info: serde_json::Value =
        serde_json::from_str(&ok(&["scene", "info", s(&scene), "--json"])).unwrap();
    let (lo, hi) = (
        &info["summary"]["bounds_min"],
        &info["summary"]["bounds_max"],
    );
    let mid = |k: usize| (lo[k].as_f64().unwrap() + hi[k].as_f64().unwrap()) / 2.0;
    std::fs::write(&camera, format!(r#"{{"width": 40, "height": 30, "hfov_deg": 90, "position": [{}, {}, 1.2], "yaw_deg": 20, "pitch_deg": -10}}"#, mid(0), mid(1))).unwrap();
    let out = dir.path().join("render");
    ok(&[
        "render",
        s(&scene),
        "--camera",
        s(&camera),
        "--out",
        s(&out),
        "--turntable",
        "4",
    ]);
    for f in [
        "rgb.png",
        "depth.npy",
        "depth_median.npy",
        "alpha.npy",
        "depth.png",
        "instance.png",
        "semantic.png",
        "legend.json",
        "render.json",
        "turntable.gif",
        "turntable/rgb_003.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let npy = std::fs::read(out.join("depth.npy")).unwrap();
    assert!(npy.starts_with(b"\x93NUMPY\x01\x00"));
    let header_len = u16::from_le_bytes([npy[8], npy[9]]) as usize;
    assert_eq!((10 + header_len) % 64, 0);
    assert!(String::from_utf8_lossy(&npy[10..10 + header_len]).contains("'shape': (30, 40)"));
    assert_eq!(npy.len(), 10 + header_len + 30 * 40 * 4);
    let legend: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("legend.json")).unwrap()).unwrap();
    let pixels: u64 = legend["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["pixels"].as_u64().unwrap())
        .sum();
    assert_eq!(pixels, 30 * 40);
    assert!(
        legend["categories"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["name"] == "floor" || c["name"] == "wall")
    );

    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"width": 40, "height": 30, "position": [0, 0, 1]}"#,
    )
    .unwrap();
    let o = sage3d(&["render", s(&scene), "--camera", s(&bad), "--out", s(&out)]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("bad.json: hfov_deg/fx"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A camera file's fields are named as the file names them, not as flags.
    std::fs::write(
        &bad,
        r#"{"width": 40, "height": 30, "hfov_deg": 90, "position": [0, 0, 1], "bogus": 1}"#,
    )
    .unwrap();
    let o = sage3d(&["render", s(&scene), "--camera", s(&bad), "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("unknown field `bogus`") && err.contains("`position`") && !err.contains("--"),
        "{err}"
    );
    // A pose given by flags that makes no camera is refused naming the flag, nothing written.
    let fresh = dir.path().join("fresh");
    for (flag, value) in [
        ("--pitch", "400"),
        ("--pitch", "nan"),
        ("--yaw", "inf"),
        ("--position", "0,nan,1.2"),
    ] {
        let arg = format!("{flag}={value}");
        let o = sage3d(&["render", s(&scene), &arg, "--out", s(&fresh)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{arg}: {err}");
        assert!(err.contains(&format!("{flag} must be")), "{arg}: {err}");
        assert!(!fresh.exists(), "{arg}");
    }
}

#[test]
fn rendering_a_scene_without_its_gaussians_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    ok(&[
        "scene",
        "synth",
        "--seed",
        "3",
        "--rooms",
        "2",
        "--objects",
        "6",
        "--gaussians",
        "2000",
        "--out",
        s(&scene),
    ]);
    let ply = scene.join("3dgs_compressed.ply");
    let out = dir.path().join("render");
    let render = || {
        sage3d(&[
            "render",
            s(&scene),
            "--position",
            "0,0,1.2",
            "--width",
            "40",
            "--height",
            "30",
            "--out",
            s(&out),
        ])
    };
    std::fs::remove_file(&ply).unwrap();
    // Listed as missing where the Gaussians are not needed ...
    let info = ok(&["scene", "info", s(&scene)]);
    assert!(info.contains("3dgs_compressed.ply"), "{info}");
    // ... and an error where they are, leaving no output.
    for o in [
        render(),
        sage3d(&[
            "scene",
            "preview",
            s(&scene),
            "--out",
            s(&dir.path().join("p.png")),
        ]),
    ] {
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        assert!(
            e.contains(&format!("{}: missing", ply.display())) && e.contains("Gaussians"),
            "{e}"
        );
    }
    assert!(!out.exists());
    // A directory by its name is no file, and not a missing one either: every command says so.
    std::fs::create_dir(&ply).unwrap();
    for o in [render(), sage3d(&["scene", "info", s(&scene)])] {
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        assert!(
            e.contains(&format!("{}: a directory, not a file", ply.display())),
            "{e}"
        );
    }
}

#[test]
fn a_config_file_supplies_flags_and_the_command_line_wins() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("sage3d.toml");
    std::fs::write(
        &config,
        "[scene.synth]\nrooms = 2\nobjects = 8\ngaussians = 3000\nseed = 5\n",
    )
    .unwrap();
    let scene = dir.path().join("scene");
    ok(&[
        "--config",
        s(&config),
        "scene",
        "synth",
        "--seed",
        "6",
        "--out",
        s(&scene),
    ]);
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scene.join("sage3d_run.json")).unwrap())
            .unwrap();
    assert_eq!(record["seed"], 6, "{record}");
    assert_eq!(record["config"]["gaussians"], 3000, "{record}");
    // A misspelt key is the flag clap does not know; a broken file names its line.
    std::fs::write(&config, "[scene.synth]\nroomz = 2\n").unwrap();
    let out = sage3d(&["--config", s(&config), "scene", "synth", "--out", s(&scene)]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("--roomz"), "{e}");
    std::fs::write(&config, "[scene.synth]\nrooms = \n").unwrap();
    let out = sage3d(&["--config", s(&config), "scene", "synth", "--out", s(&scene)]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2) && e.contains("sage3d.toml") && e.contains("line 2"),
        "{e}"
    );
    // File flags go before a typed `--` (after it they would be positionals).
    std::fs::write(
        &config,
        "[scene.synth]\nrooms = 2\nobjects = 8\ngaussians = 3000\n",
    )
    .unwrap();
    let dashed = dir.path().join("dashed");
    ok(&[
        "--config",
        s(&config),
        "scene",
        "synth",
        "--out",
        s(&dashed),
        "--",
    ]);
    assert!(dashed.join("sage3d_run.json").is_file());
    // A library's refusal names the flag; one the file gave is told where it came from.
    std::fs::write(&config, "[nav.map]\ncell = 5.0\n").unwrap();
    let out = sage3d(&["--config", s(&config), "nav", "map", s(&dashed)]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && e.contains("--cell")
            && e.contains("note: --cell is [nav.map] cell in")
            && e.contains("sage3d.toml"),
        "{e}"
    );
    // Help needs no config file, even a missing one; a command does.
    let missing = dir.path().join("missing.toml");
    for help in [&["scene", "synth", "--help"][..], &["help"][..]] {
        let out = sage3d(&[&["--config", s(&missing)][..], help].concat());
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains("Usage"), "{text}");
    }
    let out = sage3d(&[
        "--config",
        s(&missing),
        "scene",
        "synth",
        "--out",
        s(&scene),
    ]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2) && e.contains("missing.toml"),
        "{e}"
    );
}

/// Values out of a flag's range are the parser's to refuse: exit status 2, naming the flag,
/// before any work (the library's own checks still stand behind them).
#[test]
fn values_out_of_a_flags_range_exit_2_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x");
    for (args, flag) in [
        (vec!["--threads", "0", "scene", "info", "x"], "--threads"),
        (
            vec!["--threads", "100000", "scene", "info", "x"],
            "--threads",
        ),
        (
            vec!["scene", "synth", "--rooms", "0", "--out", s(&out)],
            "--rooms",
        ),
        (
            vec!["scene", "synth", "--gaussians", "10", "--out", s(&out)],
            "--gaussians",
        ),
        (
            vec!["render", "x", "--hfov", "200", "--out", s(&out)],
            "--hfov",
        ),
        (
            vec![
                "data",
                "render",
                "x",
                "--jpeg-quality",
                "0",
                "--out",
                s(&out),
            ],
            "--jpeg-quality",
        ),
        (
            vec!["data", "render", "x", "--width", "9000", "--out", s(&out)],
            "--width",
        ),
        (
            vec![
                "data",
                "render",
                "x",
                "--max-actions",
                "0",
                "--out",
                s(&out),
            ],
            "--max-actions",
        ),
        (
            vec!["data", "render", "x", "--hfov", "0", "--out", s(&out)],
            "--hfov",
        ),
        (vec!["recon", "render", "x", "--size", "0x480"], "--size"),
        (
            vec!["bench", "render", "--sizes", "224x224,99999x9"],
            "--sizes",
        ),
    ] {
        let o = sage3d(&args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(flag), "{args:?}: {e}");
    }
    assert!(!out.exists());
}
