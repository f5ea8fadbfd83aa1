//! `sage3d physics drive`: one JSON report per step on a synthetic scene, and bad input refused
//! with a message naming the flag or command; `physics build` and `export usd` over a damaged
//! hull cache entry.

mod common;

use common::{s, sage3d, small_scene, stderr};

#[test]
fn drive_prints_a_report_per_step_and_refuses_bad_commands() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s");
    let scene = scene.to_str().unwrap();
    let out = sage3d(&[
        "scene",
        "synth",
        "--seed",
        "2",
        "--rooms",
        "2",
        "--objects",
        "6",
        "--gaussians",
        "2000",
        "--out",
        scene,
    ]);
    assert!(out.status.success());
    let cache = dir.path().join("hulls");
    let common = ["--resolution", "16", "--cache", cache.to_str().unwrap()];
    let mut args = vec!["physics", "drive", scene];
    args.extend(common);
    args.extend(["--agent", "uav", "--position", "0,0,1", "--commands"]);
    let out = sage3d(&[args.as_slice(), &["stop,uav:0:0:10:0:1,turn:90"]].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[1]["command"], "uav:0:0:10:0:1");
    // The climb is clamped to 1.5 m/s for 1 s.
    let dz = lines[1]["commanded"][2].as_f64().unwrap();
    assert!((dz - 1.5).abs() < 1e-4, "{dz}");
    let out = sage3d(&[args.as_slice(), &["forward:1,jump:2"]].concat());
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("command 'jump:2'"));
    let out = sage3d(&[args.as_slice(), &["vel:1:0:0:1"]].concat());
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not apply"));
    // Values no step could honour are refused before anything moves (at 1e20 m a shape cast
    // passes through walls), and so are starts that are not finite or off any scene.
    let mut ground = vec!["physics", "drive", scene];
    ground.extend(common);
    for (start, commands, said) in [
        ("0,0,0", "forward:1e20", "command 'forward:"),
        ("0,0,0", "vel:1:0:0:1e6", "dt 1000000.0 is out of range"),
        ("0,0,0", "forward:nan", "'nan' is not a finite number"),
        (
            "nan,0,0",
            "stop",
            "--position/--yaw: position [NaN, 0.0, 0.0]",
        ),
        (
            "0,2e4,0",
            "stop",
            "expected finite coordinates within ±10000 m",
        ),
    ] {
        let out = sage3d(
            &[
                ground.as_slice(),
                &["--position", start, "--commands", commands],
            ]
            .concat(),
        );
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{start} {commands}: {e}");
        assert!(e.contains(said), "{start} {commands}: {e}");
        assert!(out.stdout.is_empty(), "no step is reported");
    }
    let out = sage3d(
        &[
            ground.as_slice(),
            &["--position", "0,0,0", "--yaw", "inf", "--commands", "stop"],
        ]
        .concat(),
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("yaw"));
}

/// A hull cache folder that cannot be written (on Linux, one under `/proc`, refused even to
/// root, as on a read-only mount) does not fail `physics build`: it builds, says in a note that
/// the entries could not be kept and how to keep them, and `--json` lists them in `unstored`.
#[cfg(target_os = "linux")]
#[test]
fn a_hull_cache_that_cannot_be_written_is_noted_not_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s");
    small_scene(&scene, "3", "1000");
    let out = sage3d(&[
        "physics",
        "build",
        s(&scene),
        "--resolution",
        "16",
        "--cache",
        "/proc/self/sage3d-hulls",
        "--json",
    ]);
    let said = stderr(&out);
    assert!(out.status.success(), "{said}");
    assert!(
        said.contains("note: a hull cache entry could not be written")
            && said.contains("--cache")
            && said.contains("/proc/self/sage3d-hulls"),
        "{said}"
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(!report["unstored"].as_array().unwrap().is_empty());
    assert!(report["decomposed"].as_u64().unwrap() > 0);
}

/// A damaged hull cache entry is decomposed anew: `physics build` and `export usd` succeed,
/// name the file in a note on standard error, and `physics build --json` lists it in `remade`.
#[test]
fn a_damaged_hull_cache_entry_is_remade_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s");
    small_scene(&scene, "3", "1000");
    let scene = s(&scene);
    let cache = dir.path().join("hulls");
    let flags = ["--resolution", "16", "--cache", cache.to_str().unwrap()];
    let build = |json: bool| {
        let mut args = vec!["physics", "build", scene];
        args.extend(flags);
        if json {
            args.push("--json");
        }
        sage3d(&args)
    };
    assert!(build(false).status.success());
    let mut entries: Vec<_> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    let damage = |path: &std::path::Path| {
        let bytes = std::fs::read(path).unwrap();
        std::fs::write(path, &bytes[..bytes.len() - 3]).unwrap();
    };
    let note = |path: &std::path::Path| {
        format!(
            "note: a damaged hull cache entry was decomposed anew and replaced: {}: ",
            path.display()
        )
    };

    damage(&entries[0]);
    let out = build(true);
    let said = stderr(&out);
    assert!(out.status.success(), "{said}");
    assert!(said.contains(&note(&entries[0])), "{said}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let remade = report["remade"].as_array().unwrap();
    assert_eq!(remade.len(), 1);
    assert!(
        remade[0]
            .as_str()
            .unwrap()
            .starts_with(&entries[0].display().to_string())
    );
    // Replaced: the next build reads every entry and says nothing of damage.
    let out = build(true);
    assert!(!stderr(&out).contains("note:"));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(report.get("remade").is_none() && report["decomposed"] == 0);

    damage(&entries[1]);
    let usda = dir.path().join("scene.usda");
    let mut args = vec!["export", "usd", scene, usda.to_str().unwrap()];
    args.extend(flags);
    let out = sage3d(&args);
    let said = stderr(&out);
    assert!(out.status.success(), "{said}");
    assert!(said.contains(&note(&entries[1])), "{said}");
}
