//! Helpers shared by the CLI tests: run the built `sage3d` binary.

#![allow(dead_code)] // each test file uses its own subset

use std::path::Path;
use std::process::{Command, Output};

/// Runs `sage3d ARGS…` and returns its output, whatever the exit status.
pub fn sage3d(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sage3d"))
        .args(args)
        .output()
        .expect("sage3d runs")
}

/// Runs `sage3d ARGS…`, asserts success and returns standard output.
pub fn ok(args: &[&str]) -> String {
    let out = sage3d(args);
    assert!(
        out.status.success(),
        "sage3d {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A command's standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A temporary path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// Writes a small synthetic scene (3 rooms, 30 objects, `gaussians` Gaussians) into `dir`.
pub fn small_scene(dir: &Path, seed: &str, gaussians: &str) {
    ok(&[
        "scene",
        "synth",
        "--seed",
        seed,
        "--rooms",
        "3",
        "--objects",
        "30",
        "--gaussians",
        gaussians,
        "--out",
        s(dir),
    ]);
}

/// A one-scene dataset under `dir` (`scenes/home1` and `data/`, 3 trajectories, seed 2);
/// returns (scenes folder, dataset folder).
pub fn small_dataset(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let scenes = dir.join("scenes");
    small_scene(&scenes.join("home1"), "1", "1000");
    let data = dir.join("data");
    ok(&small_build_args(&scenes, &data));
    (scenes, data)
}

/// The `sage3d data build` command of [`small_dataset`] (3 trajectories, seed 2): rerunning it
/// resumes that dataset.
pub fn small_build_args<'a>(scenes: &'a Path, data: &'a Path) -> [&'a str; 9] {
    [
        "data",
        "build",
        s(scenes),
        "--out",
        s(data),
        "--per-scene",
        "3",
        "--seed",
        "2",
    ]
}

/// `sage3d --threads N eval DATA --scenes SCENES --split train --out RUN` and `extra`: asserts
/// success and returns standard output.
pub fn eval(threads: &str, data: &Path, scenes: &Path, run: &Path, extra: &[&str]) -> String {
    ok(&eval_args(threads, data, scenes, run, extra))
}

/// [`eval`]'s command, whatever its outcome.
pub fn eval_output(
    threads: &str,
    data: &Path,
    scenes: &Path,
    run: &Path,
    extra: &[&str],
) -> Output {
    sage3d(&eval_args(threads, data, scenes, run, extra))
}

/// The arguments of [`eval`].
fn eval_args<'a>(
    threads: &'a str,
    data: &'a Path,
    scenes: &'a Path,
    run: &'a Path,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let base = [
        "--threads",
        threads,
        "eval",
        s(data),
        "--scenes",
        s(scenes),
        "--split",
        "train",
        "--out",
        s(run),
    ];
    [&base[..], extra].concat()
}
