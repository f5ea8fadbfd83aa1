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
}
