//! One writer per output folder: a command holds an operating-system advisory lock on
//! `DIR/.sage3d.lock` for as long as it writes `DIR`, so a second command on the same folder
//! fails at once, told which command and process hold it. The operating system lets go of the
//! lock when its process ends, however it ends, so a crashed or killed holder never blocks a
//! rerun; the command and process id written in the file only serve the message.
//!
//! A folder inside one that another process is writing is refused the same way: once it holds
//! its own folder's lock, [`FolderLock::acquire`] looks at every folder above it (by its
//! canonical path, up to the root) and refuses when one of them is locked by another process,
//! naming that folder and its holder. While `sage3d demo --out D` runs, `sage3d data build …
//! --out D/dataset` or `sage3d eval … --out D/runs/oracle` from another process would change
//! what the demo's own steps write there. Folders locked by this same process do not count:
//! they are the outer command's own steps (the demo's dataset, training set and runs). A lock
//! file left above by a process that has ended does not count either.
//!
//! Holding the lock also makes every [temporary file](crate::files::is_temporary) in the folder
//! a leftover of an interrupted earlier run, which [`FolderLock::remove_temporary`] removes.
//!
//! A command that only reads a folder while other commands could write it (`recon fit` reading
//! the views `recon render` writes) holds a shared lock on the same file
//! ([`FolderLock::acquire_shared`]): readers run side by side, a writer is refused while one
//! reads (told which), and a reader is refused while a writer writes.

use crate::files::is_temporary;
use sage_core::{Error, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The lock file of a folder that a command is writing (removed when the command lets go).
pub const LOCK_FILE: &str = ".sage3d.lock";

/// How often [`FolderLock::acquire`] opens the lock file again when the holder before it
/// removed that file as it let go (each time means another command took and released it).
const ATTEMPTS: usize = 16;

/// How long a refused command waits for the holder to write who it is: a holder locks its
/// file before it writes its name there, so a command that loses a race by a hair finds it
/// empty for a moment.
const HOLDER_WAIT: Duration = Duration::from_millis(500);

/// How often the lock file is read again while waiting for its holder's name.
const HOLDER_POLL: Duration = Duration::from_millis(5);

/// The lock on a folder that a command writes, held until the guard is dropped; then the lock
/// file is removed, and so are the folders that [`FolderLock::acquire`] made when they are still
/// empty (a command that failed before writing leaves nothing behind).
#[derive(Debug)]
#[must_use = "the folder is unlocked as soon as the guard is dropped"]
pub struct FolderLock {
    /// The open, locked lock file: closing it releases the lock.
    file: File,
    /// The locked folder.
    dir: PathBuf,
    /// The folders made to hold the lock file, deepest first.
    made: Vec<PathBuf>,
    /// A reader's shared lock ([`FolderLock::acquire_shared`]) rather than a writer's.
    shared: bool,
}

impl FolderLock {
    /// Locks folder `dir` (made, with its parents, when missing) for `command`, as the run
    /// records name commands (`eval`, `data render`, …), writing that command, this process's
    /// id and its command line into the lock file; then checks that no folder above `dir` is
    /// locked by another process (see the module's documentation), letting go of `dir` again
    /// when one is.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the folder when it is a file, or when another command holds
    /// it or a folder above it, with that command, its process id and command line when they
    /// can be read; an I/O error when the folder or its lock file cannot be made or locked.
    pub fn acquire(dir: &Path, command: &str) -> Result<FolderLock> {
        if dir.exists() && !dir.is_dir() {
            return Err(Error::invalid(format!(
                "the output folder is a file; `sage3d {command}` writes a folder there, choose a new or empty one"
            ))
            .in_file(dir));
        }
        FolderLock::acquire_as(dir, command, false)
    }

    /// Locks the existing folder `dir` for `command`, which reads it: a shared lock, which
    /// other readers share, while a command writing `dir` ([`FolderLock::acquire`]) is refused
    /// until the last reader lets go, naming a reader. The folders above are checked as for
    /// [`FolderLock::acquire`]. The guard removes the lock file only when it is the last
    /// holder, and never removes the folder.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the folder when it does not exist, or when another command
    /// writes it or a folder above it, naming that command as [`FolderLock::acquire`] does; an
    /// I/O error when its lock file cannot be made or locked.
    pub fn acquire_shared(dir: &Path, command: &str) -> Result<FolderLock> {
        if !dir.is_dir() {
            return Err(Error::invalid("no such folder to read").in_file(dir));
        }
        FolderLock::acquire_as(dir, command, true)
    }

    /// [`FolderLock::acquire`] (`shared` false) or [`FolderLock::acquire_shared`].
    fn acquire_as(dir: &Path, command: &str, shared: bool) -> Result<FolderLock> {
        let lock = FolderLock::lock(dir, command, shared)?;
        // Only now: an outer command that starts later finds `dir` itself held when one of its
        // steps comes to write there.
        if let Err(e) = outer_writers(dir) {
            // Dropping the guard removes only the lock file and the folders it made.
            drop(lock);
            return Err(e);
        }
        Ok(lock)
    }

    /// Takes the lock of `dir` itself ([`FolderLock::acquire`] without the folders above),
    /// shared or exclusive.
    fn lock(dir: &Path, command: &str, shared: bool) -> Result<FolderLock> {
        let path = dir.join(LOCK_FILE);
        for _ in 0..ATTEMPTS {
            let made = missing_folders(dir);
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            let file = match OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
            {
                Ok(file) => file,
                // The folder went with the holder before us, which had made it: make it again.
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(Error::io(&path, e)),
            };
            let locked = if shared {
                file.try_lock_shared()
            } else {
                file.try_lock()
            };
            match locked {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => return Err(held(dir, &path)),
                Err(TryLockError::Error(e)) => return Err(Error::io(&path, e)),
            }
            if !still_at(&file, &path) {
                // The holder before us removed this file as it let go; lock the one now there.
                continue;
            }
            let lock = FolderLock {
                file,
                dir: dir.to_path_buf(),
                made,
                shared,
            };
            lock.write_holder(command)
                .map_err(|e| Error::io(&path, e))?;
            return Ok(lock);
        }
        Err(Error::invalid(
            "other commands keep taking and releasing this folder's lock; try again",
        )
        .in_file(dir))
    }

    /// Writes who holds the lock into the lock file, replacing an earlier holder's lines.
    fn write_holder(&self, command: &str) -> std::io::Result<()> {
        let mut holder = serde_json::json!({
            "command": command,
            "pid": std::process::id(),
            "process": std::env::args().collect::<Vec<_>>().join(" "),
        });
        if self.shared {
            // Only the message reads it: a writer refused is told the folder is being read.
            holder["reads"] = true.into();
        }
        self.file.set_len(0)?;
        (&self.file).write_all(format!("{holder}\n").as_bytes())
    }

    /// Whether this is the lock of folder `dir` (compared by canonical path, so `out/` and
    /// `./out` name the same folder): a caller handed a lock checks it is the right folder's
    /// before writing there under it.
    pub fn holds(&self, dir: &Path) -> bool {
        let canonical = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
        canonical(dir) == canonical(&self.dir)
    }

    /// Removes the temporary files ([`is_temporary`]) that interrupted earlier runs left in the
    /// folder and its sub-folders: while the lock is held no other command writes there, so
    /// they can only be stale. A sub-folder holding its own lock file (another command's folder)
    /// and symbolic links are left alone, and so is every other file. Best effort: a file or
    /// folder that cannot be read or removed is left as it is.
    pub fn remove_temporary(&self) {
        let mut stack = vec![self.dir.clone()];
        while let Some(dir) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else {
                continue;
            };
            for entry in entries.flatten() {
                let Ok(kind) = entry.file_type() else {
                    continue;
                };
                let path = entry.path();
                if kind.is_dir() {
                    if !path.join(LOCK_FILE).exists() {
                        stack.push(path);
                    }
                } else if kind.is_file() && is_temporary(&entry.file_name().to_string_lossy()) {
                    let _ = std::fs::remove_file(&path);
                }
            }
        }
    }
}

impl Drop for FolderLock {
    /// Removes the lock file while still holding the lock (a command that opens it afterwards
    /// makes a new one), then the folders [`FolderLock::acquire`] made if they are empty; the
    /// lock itself goes when the file is closed, right after.
    fn drop(&mut self) {
        // A reader removes the file only as the last holder: taking the lock for itself alone
        // proves no other reader shares it (this process lets go of it either way).
        if self.shared && self.file.try_lock().is_err() {
            return;
        }
        let _ = std::fs::remove_file(self.dir.join(LOCK_FILE));
        for dir in &self.made {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// Who is writing folder `dir` now, in words ("the `eval` run of process 41 (…)"), or `None`
/// when no command holds its lock as a writer. Only looks: nothing is made or locked for long
/// (a reader's lock is taken and let go at once, which no writer notices), so a command that
/// reads a folder it may not lock can tell a run still being written from an abandoned one.
pub fn writer_of(dir: &Path) -> Option<String> {
    let path = dir.join(LOCK_FILE);
    let file = File::open(&path).ok()?;
    match file.try_lock_shared() {
        Err(TryLockError::WouldBlock) => Some(describe(read_holder(&path).as_ref())),
        _ => None,
    }
}

/// `dir` and those of its parents that do not exist, deepest first.
fn missing_folders(dir: &Path) -> Vec<PathBuf> {
    dir.ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
        .map(Path::to_path_buf)
        .collect()
}

/// Whether the open `file` is still the one at `path` (a holder removes its lock file before
/// it lets go, so a file locked just after that may no longer be the folder's lock file).
#[cfg(unix)]
fn still_at(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
        _ => false,
    }
}

/// Whether the open `file` is still the one at `path`: where files have no inode numbers to
/// compare, whether the lock file is still there.
#[cfg(not(unix))]
fn still_at(_file: &File, path: &Path) -> bool {
    path.exists()
}

/// Refuses folder `dir` when a folder above it is locked by another process (a lock that
/// this process holds is its own outer command's; a lock file whose holder has ended is
/// stale). A lock file that cannot be opened or tested is passed over: the check is only as
/// good as the files it can read.
fn outer_writers(dir: &Path) -> Result<()> {
    // An empty path is the working folder, as it is to `dir.join(LOCK_FILE)`.
    let here = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let real = std::fs::canonicalize(here).map_err(|e| Error::io(dir, e))?;
    for outer in real.ancestors().skip(1) {
        let path = outer.join(LOCK_FILE);
        let Ok(file) = File::open(&path) else {
            continue;
        };
        // A shared lock only tests: two commands testing the same folder at once do not take
        // each other for its holder. It goes when `file` is closed, at the end of this turn.
        if !matches!(file.try_lock_shared(), Err(TryLockError::WouldBlock)) {
            continue;
        }
        let holder = read_holder(&path);
        let own = u64::from(std::process::id());
        if holder
            .as_ref()
            .and_then(|h| h.get("pid"))
            .and_then(serde_json::Value::as_u64)
            == Some(own)
        {
            continue;
        }
        return Err(Error::invalid(format!(
            "the folder is inside {}, which is being written by {}; wait for it to finish, or choose another folder",
            outer.display(),
            describe(holder.as_ref())
        ))
        .in_file(dir));
    }
    Ok(())
}

/// The holder named in lock file `path`, waiting up to [`HOLDER_WAIT`] for it to be written
/// (a holder locks the file before writing its name); `None` when it is not written by then,
/// or when the file is gone (its holder let go).
fn read_holder(path: &Path) -> Option<serde_json::Value> {
    let deadline = Instant::now() + HOLDER_WAIT;
    loop {
        // Bounded: a lock file is a few hundred bytes, and a stray huge one must not be read
        // whole.
        let text = crate::files::read_text(path, &crate::limits::JSON_MB).ok()?;
        let holder = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .filter(serde_json::Value::is_object);
        if holder.is_some() || Instant::now() >= deadline {
            return holder;
        }
        std::thread::sleep(HOLDER_POLL);
    }
}

/// Who a lock file's `holder` is, in words.
fn describe(holder: Option<&serde_json::Value>) -> String {
    let field = |key: &str| holder.and_then(|h| h.get(key)).cloned();
    match (field("command"), field("pid")) {
        (Some(serde_json::Value::String(command)), Some(pid)) => {
            let process = field("process")
                .and_then(|p| p.as_str().map(String::from))
                .filter(|p| !p.is_empty())
                .map_or_else(String::new, |p| format!(" ({p})"));
            // The run's kind, not the program: human play in the viewer writes an `eval` run,
            // and Python's functions take the same locks.
            format!("the `{command}` run of process {pid}{process}")
        }
        _ => "another command".to_string(),
    }
}

/// The error for folder `dir` held by another command, naming it from its lock file `path`.
fn held(dir: &Path, path: &Path) -> Error {
    let holder = read_holder(path);
    let reads = holder
        .as_ref()
        .and_then(|h| h.get("reads"))
        .and_then(serde_json::Value::as_bool)
        == Some(true);
    Error::invalid(format!(
        "the folder is being {} by {}; wait for it to finish, or choose another folder",
        if reads { "read" } else { "written" },
        describe(holder.as_ref())
    ))
    .in_file(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_where_the_folder_should_be_is_refused_and_left_as_it_is() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("run.log");
        std::fs::write(&file, "mine").unwrap();
        let e = FolderLock::acquire(&file, "data render")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("run.log")
                && e.contains("the output folder is a file; `sage3d data render`"),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
    }

    #[test]
    fn a_held_folder_is_refused_naming_its_holder_until_the_guard_is_dropped() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("a/b/run");
        let lock = FolderLock::acquire(&dir, "eval").unwrap();
        assert!(dir.join(LOCK_FILE).is_file());
        // The lock knows its folder however it is named, and no other.
        assert!(lock.holds(&dir) && lock.holds(&root.path().join("a/./b/../b/run")));
        assert!(!lock.holds(&root.path().join("a/b")));
        let e = FolderLock::acquire(&dir, "data render")
            .unwrap_err()
            .to_string();
        let pid = std::process::id().to_string();
        assert!(
            e.contains(&format!("the `eval` run of process {pid}")),
            "{e}"
        );
        assert!(e.contains("run") && e.contains("being written"), "{e}");
        drop(lock);
        // The lock file goes, and so do the folders made only to hold it.
        assert!(!root.path().join("a").exists());
        let again = FolderLock::acquire(&dir, "data render").unwrap();
        std::fs::write(dir.join("out.json"), "{}").unwrap();
        drop(again);
        assert!(!dir.join(LOCK_FILE).exists() && dir.join("out.json").is_file());
        // A folder that holds files is kept; one that existed before is kept even when empty.
        let empty = root.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        drop(FolderLock::acquire(&empty, "eval").unwrap());
        assert!(empty.is_dir() && std::fs::read_dir(&empty).unwrap().count() == 0);
    }

    #[test]
    fn the_writer_of_a_folder_is_named_while_it_writes_and_readers_are_not_writers() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("run");
        assert_eq!(writer_of(&dir), None);
        std::fs::create_dir(&dir).unwrap();
        let lock = FolderLock::acquire(&dir, "eval").unwrap();
        let pid = std::process::id().to_string();
        let writer = writer_of(&dir).expect("a writer holds it");
        assert!(
            writer.contains(&format!("the `eval` run of process {pid}")),
            "{writer}"
        );
        // Looking took nothing: the writer still holds the folder alone.
        assert!(FolderLock::acquire_shared(&dir, "report").is_err());
        drop(lock);
        assert_eq!(writer_of(&dir), None);
        let reader = FolderLock::acquire_shared(&dir, "report").unwrap();
        assert_eq!(writer_of(&dir), None);
        drop(reader);
        // A lock file its holder left behind when it was killed names no writer.
        std::fs::write(dir.join(LOCK_FILE), r#"{"command": "eval", "pid": 1}"#).unwrap();
        assert_eq!(writer_of(&dir), None);
    }

    #[test]
    fn a_stale_lock_file_of_a_crashed_holder_does_not_block() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(LOCK_FILE),
            r#"{"command": "eval", "pid": 1, "process": "sage3d eval"}"#,
        )
        .unwrap();
        let lock = FolderLock::acquire(dir.path(), "report").unwrap();
        let text = std::fs::read_to_string(dir.path().join(LOCK_FILE)).unwrap();
        let holder: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(holder["command"], "report");
        assert_eq!(holder["pid"], std::process::id());
        drop(lock);
    }

    #[test]
    fn a_refused_command_waits_briefly_for_the_holder_to_name_itself() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(LOCK_FILE);
        // A holder that has locked its file but not yet written its name, as a command that
        // won a race by a hair is for a moment.
        let holder = File::create(&path).unwrap();
        holder.try_lock().unwrap();
        let writer = {
            let path = path.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(20));
                let name = r#"{"command": "eval", "pid": 4242, "process": "sage3d eval"}"#;
                std::fs::write(path, name).unwrap();
            })
        };
        let e = FolderLock::acquire(dir.path(), "report")
            .unwrap_err()
            .to_string();
        writer.join().unwrap();
        assert!(
            e.contains("the `eval` run of process 4242 (sage3d eval)"),
            "{e}"
        );
        // A holder that never names itself is not waited for without end.
        std::fs::write(&path, "").unwrap();
        let e = FolderLock::acquire(dir.path(), "report")
            .unwrap_err()
            .to_string();
        assert!(e.contains("being written by another command"), "{e}");
        drop(holder);
        drop(FolderLock::acquire(dir.path(), "report").unwrap());
    }

    #[test]
    fn this_process_may_lock_a_folder_inside_one_it_holds_and_a_stale_outer_file_is_passed() {
        let root = tempfile::tempdir().unwrap();
        let demo = root.path().join("demo");
        let outer = FolderLock::acquire(&demo, "demo").unwrap();
        let inner = FolderLock::acquire(&demo.join("runs/oracle"), "eval").unwrap();
        // The inner folder is still one writer's: a second lock on it is refused.
        assert!(FolderLock::acquire(&demo.join("runs/oracle"), "eval").is_err());
        drop(inner);
        drop(outer);
        // A lock file whose holder has ended, even one naming another process.
        std::fs::create_dir_all(&demo).unwrap();
        std::fs::write(
            demo.join(LOCK_FILE),
            r#"{"command": "demo", "pid": 1, "process": "sage3d demo"}"#,
        )
        .unwrap();
        drop(FolderLock::acquire(&demo.join("dataset"), "data build").unwrap());
        assert!(
            demo.join(LOCK_FILE).is_file(),
            "another's lock file is left alone"
        );
        assert!(!demo.join("dataset").exists());
    }

    #[test]
    fn only_temporary_files_outside_other_locked_folders_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        let write = |rel: &str| {
            let p = root.join(rel);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, "x").unwrap();
        };
        let stale = [
            ".annotations_part_000.json.tmp-123-4",
            "report/.report.html.tmp-9-0",
            "report/maps/.a.png.tmp-9-12",
        ];
        let kept = [
            "notes.txt",
            "annotations_part_000.json",
            "summary.json.tmp-123-4",
            ".summary.json.tmp-123",
            "runs/other/.summary.json.tmp-5-5",
            "runs/other/.sage3d.lock",
        ];
        for rel in stale.iter().chain(&kept) {
            write(rel);
        }
        std::fs::create_dir(root.join(".dir.tmp-1-1")).unwrap();
        let lock = FolderLock::acquire(root, "eval").unwrap();
        lock.remove_temporary();
        for rel in stale {
            assert!(!root.join(rel).exists(), "{rel} left");
        }
        for rel in kept {
            assert!(root.join(rel).is_file(), "{rel} removed");
        }
        assert!(
            root.join(".dir.tmp-1-1").is_dir(),
            "a folder is never removed"
        );
        drop(lock);
    }

    #[test]
    fn readers_share_a_folder_that_a_writer_is_refused_until_the_last_reader_lets_go() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("recon");
        assert!(
            FolderLock::acquire_shared(&dir, "recon fit")
                .unwrap_err()
                .to_string()
                .contains("no such folder")
        );
        std::fs::create_dir(&dir).unwrap();
        let first = FolderLock::acquire_shared(&dir, "recon fit").unwrap();
        let second = FolderLock::acquire_shared(&dir, "recon fit").unwrap();
        let pid = std::process::id();
        let e = FolderLock::acquire(&dir, "recon render")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "being read by the `recon fit` run of process {pid}"
            )),
            "{e}"
        );
        // The first reader to let go leaves the file to the other.
        drop(first);
        assert!(dir.join(LOCK_FILE).is_file());
        assert!(FolderLock::acquire(&dir, "recon render").is_err());
        drop(second);
        assert!(dir.is_dir() && !dir.join(LOCK_FILE).exists());
        // A reader is refused while a writer holds the folder, and the writer is named.
        let writer = FolderLock::acquire(&dir, "recon render").unwrap();
        let e = FolderLock::acquire_shared(&dir, "recon fit")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "being written by the `recon render` run of process {pid}"
            )),
            "{e}"
        );
        drop(writer);
        // A folder inside one being read may be written (a fit's output inside its recon
        // folder): readers do not change what is under them.
        let reading = FolderLock::acquire_shared(&dir, "recon fit").unwrap();
        drop(FolderLock::acquire(&dir.join("fit"), "recon fit").unwrap());
        drop(reading);
    }
}
