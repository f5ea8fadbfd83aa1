//! `sage3d physics drive`: one JSON report per step on a synthetic scene, and bad input refused
//! with a message naming the flag or command.

mod common;

use common::sage3d;

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
