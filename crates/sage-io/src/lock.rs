//! One writer per output folder: a command holds an operating-system advisory lock on
//! `DIR/.sage3d.lock` for as long as it writes `DIR`, so a second command on the same folder
//! fails at once, told which command and process hold it. The operating system lets go of the
//! lock when its process ends, however it ends, so a crashed or killed holder never blocks a
//! rerun; the command and process id written in the file only serve the message.
//!
//! Holding the lock also makes every [temporary file](crate::files::is_temporary) in the folder
//! a leftover of an interrupted earlier run, which [`FolderLock::remove_temporary`] removes.

use crate::files::is_temporary;
use sage_core::{Error, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The lock file of a folder that a command is writing (removed when the command lets go).
pub const LOCK_FILE: &str = ".sage3d.lock";

/// How often [`FolderLock::acquire`] opens the lock file again when the holder before it
/// removed that file as it let go (each time means another command took and released it).
const ATTEMPTS: usize = 16;

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
}

impl FolderLock {
    /// Locks folder `dir` (made, with its parents, when missing) for `command`, as the run
    /// records name commands (`eval`, `data render`, …), writing that command, this process's
    /// id and its command line into the lock file.
    ///
    /// # Errors
    ///
    /// An `invalid` error naming the folder when another command holds it, with that command,
    /// its process id and command line when they can be read; an I/O error when the folder or
    /// its lock file cannot be made or locked.
    pub fn acquire(dir: &Path, command: &str) -> Result<FolderLock> {
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
            match file.try_lock() {
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
        let holder = serde_json::json!({
            "command": command,
            "pid": std::process::id(),
            "process": std::env::args().collect::<Vec<_>>().join(" "),
        });
        self.file.set_len(0)?;
        (&self.file).write_all(format!("{holder}\n").as_bytes())
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
        let _ = std::fs::remove_file(self.dir.join(LOCK_FILE));
        for dir in &self.made {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
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

/// The error for folder `dir` held by another command, naming it from its lock file `path`.
fn held(dir: &Path, path: &Path) -> Error {
    let holder: Option<serde_json::Value> = std::fs::read_to_string(path)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok());
    let field = |key: &str| holder.as_ref().and_then(|h| h.get(key)).cloned();
    let who = match (field("command"), field("pid")) {
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
    };
    Error::invalid(format!(
        "the folder is being written by {who}; wait for it to finish, or choose another folder"
    ))
    .in_file(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_folder_is_refused_naming_its_holder_until_the_guard_is_dropped() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("a/b/run");
        let lock = FolderLock::acquire(&dir, "eval").unwrap();
        assert!(dir.join(LOCK_FILE).is_file());
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
}
