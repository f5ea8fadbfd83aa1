//! One writer per folder, for the reconstruction steps and for folders inside another
//! command's: while this test process holds a folder's lock (through the same
//! `sage_io::lock` API the commands use), `recon plan`, `recon render` and `recon export` on
//! that folder, and `data build` or `eval` into a folder inside it, exit 1 at once naming the
//! holder and write nothing; once it lets go they run.

mod common;

use common::{eval_output, ok, s, sage3d, small_build_args, small_dataset, small_scene, stderr};
use sage_io::lock::{FolderLock, LOCK_FILE};
use std::path::Path;
use std::process::Output;

/// Asserts that `out` is a refusal naming this process as the `command` run that holds the
/// folder (`inside`: a folder above the one the command writes).
fn refused(out: &Output, command: &str, inside: Option<&Path>) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!(
            "being written by the `{command}` run of process {}",
            std::process::id()
        )),
        "{err}"
    );
    if let Some(outer) = inside {
        let outer = std::fs::canonicalize(outer).unwrap();
        assert!(
            err.contains(&format!("the folder is inside {}", outer.display())),
            "{err}"
        );
    }
}

#[test]
fn recon_plan_render_and_export_refuse_a_held_folder_and_run_once_it_is_free() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    small_scene(&scene, "2", "1000");
    let dir = tmp.path().join("recon");
    let plan = [
        "recon",
        "plan",
        s(&scene),
        "--budget",
        "18",
        "--seed",
        "3",
        "--out",
        s(&dir),
    ];
    let render = ["recon", "render", s(&dir), "--size", "24x16"];
    let export = ["recon", "export", s(&dir), "--points", "50"];
    ok(&plan);
    let planned = std::fs::read(dir.join("plan.json")).unwrap();

    for holder in ["recon render", "recon plan", "recon export"] {
        let held = FolderLock::acquire(&dir, holder).unwrap();
        refused(&sage3d(&render), holder, None);
        refused(&sage3d(&export), holder, None);
        refused(&sage3d(&plan), holder, None);
        drop(held);
    }
    assert!(!dir.join("views").exists() && !dir.join("transforms.json").exists());
    assert_eq!(std::fs::read(dir.join("plan.json")).unwrap(), planned);

    ok(&render);
    ok(&export);
    assert!(dir.join("views/rgb_0000.png").is_file() && dir.join("transforms.json").is_file());
    assert!(!dir.join(LOCK_FILE).exists());
    // A render killed mid-write leaves a temporary view; the next step under the lock clears it.
    let stale = dir.join("views/.rgb_0000.png.tmp-4242-0");
    std::fs::write(&stale, "half").unwrap();
    ok(&render);
    assert!(!stale.exists());
}

#[test]
fn a_folder_inside_one_another_command_writes_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let (scenes, data) = small_dataset(tmp.path());
    let demo = tmp.path().join("demo");
    let dataset = demo.join("dataset");
    let run = demo.join("runs/oracle");

    let held = FolderLock::acquire(&demo, "demo").unwrap();
    refused(
        &sage3d(&small_build_args(&scenes, &dataset)),
        "demo",
        Some(&demo),
    );
    refused(
        &eval_output("1", &data, &scenes, &run, &["--agent", "oracle"]),
        "demo",
        Some(&demo),
    );
    // Nothing written, not even the folders the commands would have made.
    assert_eq!(sage_io::run::entries(&demo).unwrap(), Vec::<String>::new());
    drop(held);

    ok(&small_build_args(&scenes, &dataset));
    assert!(dataset.join("splits.json").is_file());
}

#[test]
fn a_fit_holds_the_recon_folder_it_reads_so_a_render_or_export_into_it_is_refused_naming_it() {
    use sage_pipeline::recon::{FitSettings, fit};
    use std::sync::Mutex;
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    small_scene(&scene, "2", "1000");
    let dir = tmp.path().join("recon");
    ok(&[
        "recon",
        "plan",
        s(&scene),
        "--budget",
        "18",
        "--seed",
        "3",
        "--out",
        s(&dir),
    ]);
    let render = ["recon", "render", s(&dir), "--size", "24x16"];
    let export = ["recon", "export", s(&dir), "--points", "50"];
    ok(&render);
    let views = sage_io::files::read_tree(&dir.join("views")).unwrap();
    // A second fit reading the same folder beside the first, into a folder beside it.
    let beside = tmp.path().join("beside");
    let fit_beside = [
        "recon",
        "fit",
        s(&dir),
        "--iterations",
        "2",
        "--points",
        "200",
        "--out",
        s(&beside),
    ];
    // While the fit runs (its first iteration), the steps that write its folder are run
    // beside it; the fit's output folder is inside the folder it reads.
    let during: Mutex<Option<[Output; 3]>> = Mutex::new(None);
    let settings = FitSettings {
        iterations: 2,
        points: 200,
        seed: None,
    };
    let out = dir.join("fit");
    fit(&dir, None, &settings, &out, false, &|_, _| {
        let mut during = during.lock().unwrap();
        if during.is_none() {
            *during = Some([sage3d(&render), sage3d(&export), sage3d(&fit_beside)]);
        }
    })
    .unwrap();
    let [rendered, exported, beside_fit] = during.into_inner().unwrap().expect("iterations ran");
    for refusal in [&rendered, &exported] {
        let err = stderr(refusal);
        assert_eq!(refusal.status.code(), Some(1), "{err}");
        assert!(
            err.contains(&format!(
                "being read by the `recon fit` run of process {}",
                std::process::id()
            )),
            "{err}"
        );
    }
    // Readers share the folder.
    assert!(beside_fit.status.success(), "{}", stderr(&beside_fit));
    assert!(beside.join("3dgs_compressed.ply").is_file());
    // Nothing of the recon folder changed, the fit wrote its scene, and the lock is gone.
    assert_eq!(
        sage_io::files::read_tree(&dir.join("views")).unwrap(),
        views
    );
    assert!(!dir.join("transforms.json").exists());
    assert!(out.join("3dgs_compressed.ply").is_file());
    assert!(!dir.join(LOCK_FILE).exists());
    ok(&export);
}
