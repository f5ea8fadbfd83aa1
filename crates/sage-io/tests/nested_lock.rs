//! A folder inside one that another process is writing is refused, naming that folder and its
//! holder, and taken once the holder has ended. The other process is this test executable run
//! again in the mode of [`hold_the_folder_named_by_the_environment`]: it locks the folder, says
//! so on its standard output and keeps the lock until its standard input is closed.

use sage_io::lock::{FolderLock, LOCK_FILE};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};

/// The variable naming the folder a helper process locks.
const HOLD: &str = "SAGE3D_TEST_HOLD_FOLDER";

/// The line a helper process prints once it holds its folder.
const HOLDING: &str = "sage3d-test: holding";

/// The helper's mode: run alone with [`HOLD`] set, it locks that folder as `demo` until its
/// standard input ends. As an ordinary test (no [`HOLD`]) it does nothing.
#[test]
fn hold_the_folder_named_by_the_environment() {
    let Some(dir) = std::env::var_os(HOLD) else {
        return;
    };
    let lock = FolderLock::acquire(Path::new(&dir), "demo").unwrap();
    println!("{HOLDING}");
    let _ = std::io::stdin().read_to_end(&mut Vec::new());
    drop(lock);
}

/// A helper process that holds a folder's lock, with the rest of its standard output (read
/// to the end before it is waited for, so it never blocks on a full pipe).
struct Helper {
    child: Child,
    out: BufReader<ChildStdout>,
}

impl Helper {
    /// Starts a helper process holding `dir` and returns it once it holds the lock.
    fn hold(dir: &Path) -> Helper {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args([
                "hold_the_folder_named_by_the_environment",
                "--exact",
                "--nocapture",
            ])
            .env(HOLD, dir)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let out = BufReader::new(child.stdout.take().unwrap());
        let mut helper = Helper { child, out };
        let mut line = String::new();
        loop {
            line.clear();
            if helper.out.read_line(&mut line).unwrap() == 0 {
                let status = helper.child.wait().unwrap();
                panic!(
                    "the helper ended ({status}) before it held {}",
                    dir.display()
                );
            }
            if line.trim_end() == HOLDING {
                return helper;
            }
        }
    }

    /// The helper's process id.
    fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Lets the folder go and waits for the helper to end.
    fn release(mut self) {
        drop(self.child.stdin.take());
        let _ = self.out.read_to_end(&mut Vec::new());
        assert!(self.child.wait().unwrap().success());
    }
}

#[test]
fn a_folder_inside_one_another_process_writes_is_refused_until_that_process_ends() {
    let root = tempfile::tempdir().unwrap();
    let demo = root.path().join("demo");
    let helper = Helper::hold(&demo);
    let pid = helper.pid();
    let real = std::fs::canonicalize(&demo).unwrap();
    for inner in ["dataset", "runs/oracle"] {
        let dir = demo.join(inner);
        let e = FolderLock::acquire(&dir, "data build")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!(
                "{}: the folder is inside {}, ",
                dir.display(),
                real.display()
            )) && e.contains(&format!(
                "being written by the `demo` run of process {pid} ("
            )) && e.contains("wait for it to finish, or choose another folder"),
            "{e}"
        );
        // The refused command leaves nothing: no lock file, no folder made for it.
        assert!(!demo.join("dataset").exists() && !demo.join("runs").exists());
    }
    // An existing folder inside is refused the same way, and kept.
    std::fs::create_dir(demo.join("dataset")).unwrap();
    assert!(FolderLock::acquire(&demo.join("dataset"), "data build").is_err());
    assert!(demo.join("dataset").is_dir() && !demo.join("dataset").join(LOCK_FILE).exists());
    // The folder itself, as before.
    let e = FolderLock::acquire(&demo, "demo").unwrap_err().to_string();
    assert!(
        e.contains(&format!("the `demo` run of process {pid}")),
        "{e}"
    );
    // Named through a link, it is the same folder.
    #[cfg(unix)]
    {
        let link = root.path().join("link");
        std::os::unix::fs::symlink(&demo, &link).unwrap();
        let e = FolderLock::acquire(&link.join("runs/oracle"), "eval")
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("process {pid}")), "{e}");
    }

    helper.release();
    assert!(!demo.join(LOCK_FILE).exists());
    let inner = FolderLock::acquire(&demo.join("dataset"), "data build").unwrap();
    assert!(demo.join("dataset").join(LOCK_FILE).is_file());
    drop(inner);
}

#[test]
fn a_helper_holding_an_inner_folder_does_not_stop_the_outer_one() {
    // The rule looks up, never down: an outer command that starts while an inner folder is
    // held is refused only when one of its own steps comes to write there.
    let root = tempfile::tempdir().unwrap();
    let demo = root.path().join("demo");
    let helper = Helper::hold(&demo.join("dataset"));
    let outer = FolderLock::acquire(&demo, "demo").unwrap();
    let e = FolderLock::acquire(&demo.join("dataset"), "data build")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("the `demo` run of process {}", helper.pid())),
        "{e}"
    );
    drop(outer);
    helper.release();
}
