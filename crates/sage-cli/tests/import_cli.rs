//! `sage3d scene import` on the command line: every up axis the docs list is accepted (`-y`
//! too), out-of-range values are the parser's refusals, the summary says what was lost and
//! what is missing, and implausible results are warned about or refused.

mod common;

use common::{ok, s, sage3d, small_scene, stderr};
use std::path::{Path, PathBuf};

/// A small synthetic scene's Gaussians (Z up, metres) as a capture; with `cut`, only those
/// below it (a capture whose ceiling was cut away).
fn capture(dir: &Path, cut: Option<f32>) -> PathBuf {
    let scene = dir.join("synth");
    if !scene.exists() {
        small_scene(&scene, "4", "30000");
    }
    let source = scene.join("3dgs_compressed.ply");
    let Some(cut) = cut else { return source };
    let (g, _) = sage_scene::splats::read_gaussians_file(&source).unwrap();
    let mut kept = sage_scene::Gaussians::new(g.sh_degree()).unwrap();
    for i in (0..g.len()).filter(|&i| g.positions[i][2] < cut) {
        kept.push(&g.get(i));
    }
    let path = dir.join("cut.ply");
    sage_scene::ply::write_splats_file(&path, &kept, sage_scene::SplatLayout::Standard).unwrap();
    path
}

#[test]
fn negative_up_axes_are_values_and_upside_down_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let cap = capture(dir.path(), None);
    for (k, axis) in ["-x", "-y", "-z"].into_iter().enumerate() {
        let out = dir.path().join(format!("imp{k}"));
        let run = sage3d(&["scene", "import", s(&cap), "--out", s(&out), "--up", axis]);
        let err = stderr(&run);
        assert_ne!(
            run.status.code(),
            Some(2),
            "--up {axis} refused by the parser: {err}"
        );
        assert!(!err.contains("unexpected argument"), "{err}");
        if axis == "-z" {
            // The capture is Z up: named upside down, it is said so, with what to try.
            assert!(
                err.contains("upside down") && err.contains("--up=z"),
                "{err}"
            );
        }
    }
    let right = ok(&[
        "scene",
        "import",
        s(&cap),
        "--out",
        s(&dir.path().join("right")),
        "--up",
        "z",
    ]);
    assert!(
        right.contains("lossy") && right.contains("lost: "),
        "{right}"
    );
}

#[test]
fn out_of_range_values_are_the_parsers_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for args in [
        ["--scale", "0"],
        ["--scale", "-2"],
        ["--cell", "0"],
        ["--cell", "2"],
    ] {
        let mut all = vec!["scene", "import", "whatever.ply", "--out", s(&out)];
        all.extend(args);
        let run = sage3d(&all);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {}", stderr(&run));
        assert!(!out.exists());
    }
    let run = sage3d(&[
        "scene",
        "import",
        "whatever.ply",
        "--out",
        s(&out),
        "--agent-height",
        "0.02",
    ]);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr(&run).contains("--agent-height must be a finite height"),
        "{}",
        stderr(&run)
    );
}

#[test]
fn a_capture_without_ceiling_says_so_and_one_without_free_floor_fails() {
    let dir = tempfile::tempdir().unwrap();
    let cut = capture(dir.path(), Some(2.7));
    let said = ok(&[
        "scene",
        "import",
        s(&cut),
        "--out",
        s(&dir.path().join("noceil")),
        "--layout",
        "standard",
    ]);
    assert!(said.contains("ceiling none"), "{said}");
    assert!(said.contains("every value as computed"), "{said}");
    // The whole home scaled to 0.4: its 2.8 m ceiling within the agent's 1.2 m slab, no
    // free floor.
    let whole = capture(dir.path(), None);
    let out = dir.path().join("tiny");
    let run = sage3d(&[
        "scene",
        "import",
        s(&whole),
        "--out",
        s(&out),
        "--scale",
        "0.4",
    ]);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no free cell") && err.contains("--scale"),
        "{err}"
    );
    assert!(!out.exists());
}
