//! The run record: how an output folder was made (SPEC §13).

use crate::files::{is_temporary, temporary_parts, write_json};
use crate::limits::JSON_MB;
use crate::lock::{FolderLock, LOCK_FILE};
use sage_core::{Error, Result, ResultExt};
use std::io::Read;
use std::path::{Path, PathBuf};

/// The file in which a command records how its output folder was made (SPEC §13).
pub const RUN_RECORD: &str = "sage3d_run.json";

/// Writes `dir/sage3d_run.json` (atomically): the tool, its version, the command and its seed,
/// plus the command's own `details` (an object: resolved settings, input hashes, outcomes).
pub fn write_run_record(
    dir: &Path,
    command: &str,
    seed: Option<u64>,
    details: serde_json::Value,
) -> Result<()> {
    let mut record = serde_json::json!({
        "tool": "sage3d",
        "version": env!("CARGO_PKG_VERSION"),
        "command": command,
        "seed": seed,
    });
    if let (Some(fields), serde_json::Value::Object(extra)) = (record.as_object_mut(), details) {
        fields.extend(extra);
    }
    write_json(&dir.join(RUN_RECORD), &record)
}

/// The `status` of a run record written before a command's first output and replaced by its
/// full record once it has written everything ([`mark_unfinished`]).
pub const UNFINISHED: &str = "unfinished";

/// The `status` of a run record whose command wrote everything. Most records carry no
/// `status`, which means the same; any other `status` (such as [`UNFINISHED`]) marks a folder
/// its command has not finished writing.
pub const FINISHED: &str = "finished";

/// Writes the run record of `command` into `dir` marked unfinished (`"status": "unfinished"`),
/// to do before the command writes its first output there and to be replaced by
/// [`write_run_record`] once it has written its last. A folder whose command was killed or
/// failed half-way then holds its outputs beside a record that names it: a rerun claims the
/// folder as its own and redoes the work ([`claim_folder`]), and a reader can tell the outputs
/// are not complete ([`unfinished_command`]).
///
/// # Errors
///
/// The record cannot be written.
pub fn mark_unfinished(dir: &Path, command: &str, seed: Option<u64>) -> Result<()> {
    write_run_record(
        dir,
        command,
        seed,
        serde_json::json!({ "status": UNFINISHED }),
    )
}

/// The run record in `dir`, if there is a readable one. A record that cannot be read (over
/// [`JSON_MB`], unreadable, not JSON) counts as none; [`load_record`] says why.
pub fn read_record(dir: &Path) -> Option<serde_json::Value> {
    load_record(dir).ok().flatten()
}

/// The run record in `dir`: `None` when there is none, or when it is not JSON text (a damaged
/// record names no command, as a missing one does).
///
/// # Errors
///
/// A record over [`JSON_MB`] (refused from its size before it is read, naming the file, the
/// limit and its variable), or one that cannot be read (a folder by that name, no permission).
pub fn load_record(dir: &Path) -> Result<Option<serde_json::Value>> {
    let path = dir.join(RUN_RECORD);
    let file = match std::fs::File::open(&path) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&path, e)),
    };
    let size = file.metadata().map_err(|e| Error::io(&path, e))?.len();
    JSON_MB.check(size, "file size").in_file(&path)?;
    // Bounded again while reading: the file may have grown since its size was looked at.
    let max = JSON_MB.get()?;
    let mut bytes = Vec::new();
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(&path, e))?;
    JSON_MB
        .check(bytes.len() as u64, "file size")
        .in_file(&path)?;
    let json = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(&bytes);
    Ok(serde_json::from_slice(json).ok())
}

/// The command named by the run record in `dir`, if there is a readable one.
pub fn recorded_command(dir: &Path) -> Option<String> {
    read_record(dir)?.get("command")?.as_str().map(String::from)
}

/// The command whose work in `dir` is unfinished, as its run record says ([`mark_unfinished`]):
/// it was killed, or failed, before writing all of its outputs. `None` for a finished record or
/// none.
pub fn unfinished_command(dir: &Path) -> Option<String> {
    let record = read_record(dir).filter(|r| unfinished_status(r).is_some())?;
    record.get("command")?.as_str().map(String::from)
}

/// Whether `dir` holds a readable run record that is not marked unfinished: the command that
/// wrote the folder wrote all of it.
pub fn is_finished(dir: &Path) -> bool {
    read_record(dir).is_some_and(|record| unfinished_status(&record).is_none())
}

/// The `status` of a run record that marks its folder unfinished: a word other than
/// [`FINISHED`] (a record without one is finished).
pub fn unfinished_status(record: &serde_json::Value) -> Option<&str> {
    record
        .get("status")
        .and_then(serde_json::Value::as_str)
        .filter(|status| *status != FINISHED)
}

/// The names of the entries of folder `dir`, sorted, without its lock file
/// ([`LOCK_FILE`]) and temporary files ([`is_temporary`]): what the folder holds, as a claim
/// of it sees it.
///
/// # Errors
///
/// An unreadable folder, naming it.
pub fn entries(dir: &Path) -> Result<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| name != LOCK_FILE && !is_temporary(name))
        .collect();
    names.sort();
    Ok(names)
}

/// Claims `dir` for `commands[0]`, which writes its outputs (`names`: the files and folders it
/// writes at the top of `dir`) there, and returns the lock that `commands[0]` holds on it for
/// as long as it writes ([`FolderLock`]; the folder is made if missing). The folder must be new,
/// empty, or one whose run record names one of `commands` (a rerun, which resumes, or redoes
/// the work of a run that was killed after marking the folder its own with
/// [`mark_unfinished`]; the commands after the first are those whose folders it shares, such as
/// `nav map` and `nav trajectories` in `SCENE/nav`). Any other folder holds files it did not write: it is
/// refused unless `force`, and even then when it holds one of `names`, which would be
/// replaced. Once the folder is claimed, the temporary files of interrupted earlier runs are
/// removed from it ([`FolderLock::remove_temporary`]); a refused folder is left as it was.
///
/// # Errors
///
/// An `invalid` error naming the folder when another command holds it or when it holds files
/// `commands[0]` did not write (naming one); an unreadable folder or one that cannot be made.
pub fn claim_folder(
    dir: &Path,
    commands: &[&str],
    names: &[&str],
    force: bool,
) -> Result<FolderLock> {
    let command = commands.first().copied().unwrap_or("");
    let lock = FolderLock::acquire(dir, command)?;
    let held = entries(dir)?;
    let recorded = recorded_command(dir);
    if !held.is_empty() && !recorded.is_some_and(|r| commands.contains(&r.as_str())) {
        if let Some(clash) = held.iter().find(|h| names.contains(&h.as_str())) {
            return Err(Error::invalid(format!(
                "the output folder holds '{clash}', which `sage3d {command}` did not write and would replace; choose an empty or new folder"
            ))
            .in_file(dir));
        }
        if !force {
            return Err(Error::invalid(format!(
                "the output folder holds files `sage3d {command}` did not write ('{}'); choose an empty or new folder, or set `force` to write beside them",
                held[0]
            ))
            .in_file(dir));
        }
    }
    lock.remove_temporary();
    Ok(lock)
}

/// Checks that an output file may be written at `path`: one that does not exist yet, or any
/// with `force`. An existing file may be the user's, and a file carries no record of who
/// wrote it, so it is replaced only when asked. The temporary files that killed writes of
/// `path` left beside it are removed, where their process has ended.
///
/// # Errors
///
/// An `invalid` error naming the file when it exists and `force` is not given, or when `path`
/// is a folder.
pub fn claim_file(path: &Path, force: bool) -> Result<()> {
    if path.is_dir() {
        return Err(Error::invalid("the output is a folder; name a file to write").in_file(path));
    }
    if path.exists() && !force {
        return Err(Error::invalid(
            "the output file exists; choose another name, or set `force` to replace it",
        )
        .in_file(path));
    }
    remove_stale_temporaries(path);
    Ok(())
}

/// Removes the temporary files ([`is_temporary`]) that writes of `path` by processes that have
/// ended left beside it (a command killed while writing its output file): a single output file
/// has no folder lock to say nothing else writes there, so only those whose process is gone
/// are removed. Best effort, and only where the system lists its processes (`/proc`):
/// elsewhere they are left.
fn remove_stale_temporaries(path: &Path) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let processes = Path::new("/proc");
    if !processes.join("self").exists() {
        return;
    }
    let name = name.to_string_lossy();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let ended = temporary_parts(&file)
            .is_some_and(|(base, pid)| base == name && !processes.join(pid).exists());
        if ended && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// [`claim_file`] for a command that reads `inputs`: files, and folders every file of which it
/// reads. `path` may never be one of them or a file inside one of those folders, however it is
/// spelled (a link, `..`, another name of the same file), not even with `force`: replacing it
/// would destroy what the command reads (a scene's `labels.json` written over with its own
/// export). `what` says what the inputs are, for the message (`the input`, `a file of the
/// input scene`).
///
/// # Errors
///
/// An `invalid` error naming `path` and the input it is, or those of [`claim_file`].
pub fn claim_output_file(path: &Path, inputs: &[PathBuf], what: &str, force: bool) -> Result<()> {
    if let Some(input) = input_at(path, inputs) {
        return Err(Error::invalid(format!(
            "the output is {what} ({}); write to another file",
            input.display()
        ))
        .in_file(path));
    }
    claim_file(path, force)
}

/// The first of `inputs` that the existing file `path` is, or is inside; `None` for a path
/// that does not exist (a new file replaces nothing).
fn input_at<'a>(path: &Path, inputs: &'a [PathBuf]) -> Option<&'a PathBuf> {
    let out = std::fs::canonicalize(path).ok()?;
    let out_meta = std::fs::metadata(&out).ok()?;
    inputs.iter().find(|input| {
        let Ok(input) = std::fs::canonicalize(input) else {
            return false;
        };
        if input.is_dir() {
            return out.starts_with(&input);
        }
        out == input || std::fs::metadata(&input).is_ok_and(|m| same_file(&m, &out_meta))
    })
}

/// Whether two files are one (hard links of one file have different paths).
#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

/// Whether two files are one: elsewhere, only their canonical paths tell.
#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// The keys whose values differ between `old` (recorded) and `new` (asked), each as `key: OLD
/// recorded, NEW asked` (a string without its quotes, a missing value as `none`), in key
/// order: how a command says why a folder holds another run than the one asked.
pub fn differences(
    old: &std::collections::BTreeMap<String, serde_json::Value>,
    new: &std::collections::BTreeMap<String, serde_json::Value>,
) -> Vec<String> {
    let shown = |v: Option<&serde_json::Value>| match v {
        None => "none".to_string(),
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(v) => v.to_string(),
    };
    let keys: std::collections::BTreeSet<&String> = old.keys().chain(new.keys()).collect();
    keys.into_iter()
        .filter(|k| old.get(*k) != new.get(*k))
        .map(|k| {
            format!(
                "{k}: {} recorded, {} asked",
                shown(old.get(k)),
                shown(new.get(k))
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_is_claimed_only_when_new_empty_or_the_same_commands() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let claim = |commands: &[&str], force| claim_folder(&out, commands, &["episodes"], force);
        drop(claim(&["data build"], false).unwrap());
        assert!(
            !out.exists(),
            "a claimed folder left empty goes with the lock"
        );
        std::fs::create_dir(&out).unwrap();
        drop(claim(&["data build"], false).unwrap());
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let e = claim(&["data build"], false).unwrap_err();
        assert!(e.to_string().contains("notes.txt") && e.to_string().contains("`force`"));
        drop(claim(&["data build"], true).unwrap());
        std::fs::create_dir(out.join("episodes")).unwrap();
        let e = claim(&["data build"], true).unwrap_err();
        assert!(e.to_string().contains("'episodes'"), "{e}");
        write_run_record(&out, "data build", None, serde_json::json!({})).unwrap();
        drop(claim(&["data build"], false).unwrap());
        let e = claim(&["nav trajectories"], true).unwrap_err();
        assert!(e.to_string().contains("episodes"), "{e}");
        drop(claim(&["data import", "data build"], false).unwrap());
        std::fs::write(dir.path().join("file"), "x").unwrap();
        assert!(claim_folder(&dir.path().join("file"), &["render"], &[], true).is_err());
    }

    #[test]
    fn an_oversized_run_record_is_refused_from_its_size_naming_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(load_record(dir.path()).unwrap(), None, "no record");
        // A damaged record names no command, as before.
        let path = dir.path().join(RUN_RECORD);
        std::fs::write(&path, "{\"command\": ").unwrap();
        assert_eq!(load_record(dir.path()).unwrap(), None);
        // With a byte-order mark, as some editors save it.
        std::fs::write(&path, "\u{feff}{\"command\": \"render\"}").unwrap();
        assert_eq!(recorded_command(dir.path()).as_deref(), Some("render"));
        // One byte over the default limit, sparse (nothing is written), so the default applies
        // and no environment variable is shared with other tests.
        std::fs::File::create(&path)
            .unwrap()
            .set_len((1024 << 20) + 1)
            .unwrap();
        let e = load_record(dir.path()).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "{}: file size: 1024.1 MB, over the limit of 1024 MB on a JSON file; set the \
                 environment variable SAGE3D_MAX_JSON_MB to raise it",
                path.display()
            )
        );
        // The readers that take an unreadable record for none do so here too.
        assert_eq!(read_record(dir.path()), None);
        assert!(!is_finished(dir.path()) && unfinished_command(dir.path()).is_none());
    }

    #[test]
    fn a_folder_left_unfinished_is_its_command_s_own_and_says_so_until_finished() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        assert!(!is_finished(out) && unfinished_command(out).is_none());
        // What a kill leaves: the record marked unfinished, some outputs, a temporary file.
        mark_unfinished(out, "scene synth", Some(7)).unwrap();
        std::fs::write(out.join("labels.json"), "[]").unwrap();
        let stale = out.join(".structure.json.tmp-4242-0");
        std::fs::write(&stale, "half").unwrap();
        assert_eq!(unfinished_command(out).as_deref(), Some("scene synth"));
        assert_eq!(recorded_command(out).as_deref(), Some("scene synth"));
        assert!(!is_finished(out));
        let names = ["labels.json", "structure.json", RUN_RECORD];
        // Another command may not take it over, even with `force`.
        assert!(claim_folder(out, &["recon fit"], &names, true).is_err());
        assert!(stale.is_file());
        // The command's rerun takes it without `force`, and the stale file goes.
        drop(claim_folder(out, &["scene synth"], &names, false).unwrap());
        assert!(!stale.exists() && out.join("labels.json").is_file());
        write_run_record(out, "scene synth", Some(7), serde_json::json!({})).unwrap();
        assert!(is_finished(out) && unfinished_command(out).is_none());
        // A command's own words for its state read the same way.
        for (status, finished) in [(FINISHED, true), ("building", false)] {
            let details = serde_json::json!({ "status": status });
            write_run_record(out, "data build", None, details).unwrap();
            assert_eq!(is_finished(out), finished, "{status}");
            assert_eq!(unfinished_command(out).is_some(), !finished, "{status}");
        }
    }

    #[test]
    fn a_claimed_folder_is_locked_until_the_claim_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let held = claim_folder(dir.path(), &["eval"], &[], false).unwrap();
        let e = claim_folder(dir.path(), &["eval"], &[], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("being written by the `eval` run"), "{e}");
        drop(held);
        drop(claim_folder(dir.path(), &["eval"], &[], false).unwrap());
    }

    #[test]
    fn temporary_and_lock_files_are_not_foreign_and_go_once_the_folder_is_claimed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let stale = out.join(".summary.json.tmp-4242-3");
        std::fs::write(&stale, "half").unwrap();
        std::fs::write(out.join(LOCK_FILE), "").unwrap();
        assert!(entries(out).unwrap().is_empty());
        drop(claim_folder(out, &["eval"], &["summary.json"], false).unwrap());
        assert!(!stale.exists() && !out.join(LOCK_FILE).exists());
        // A refused folder keeps everything, temporary files included.
        std::fs::write(&stale, "half").unwrap();
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        assert!(claim_folder(out, &["eval"], &["summary.json"], false).is_err());
        assert!(stale.is_file());
        drop(claim_folder(out, &["eval"], &["summary.json"], true).unwrap());
        assert!(!stale.exists() && out.join("notes.txt").is_file());
    }

    #[test]
    fn an_input_is_never_an_output_however_it_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        std::fs::create_dir_all(scene.join("meshes")).unwrap();
        let labels = scene.join("labels.json");
        std::fs::write(&labels, "[]").unwrap();
        std::fs::write(scene.join("meshes/1.obj"), "").unwrap();
        let inputs = [labels.clone()];
        let what = "a file of the input scene";
        let e = claim_output_file(&labels, &inputs, what, true)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            format!(
                "{}: the output is a file of the input scene ({}); write to another file",
                labels.display(),
                labels.display()
            )
        );
        // Another spelling of the same file.
        let dotted = scene.join("meshes/../labels.json");
        assert!(claim_output_file(&dotted, &inputs, what, true).is_err());
        #[cfg(unix)]
        {
            let link = dir.path().join("link.json");
            std::os::unix::fs::symlink(&labels, &link).unwrap();
            assert!(claim_output_file(&link, &inputs, what, true).is_err());
            let hard = dir.path().join("hard.json");
            std::fs::hard_link(&labels, &hard).unwrap();
            assert!(claim_output_file(&hard, &inputs, what, true).is_err());
        }
        // A folder input covers every file inside it, and nothing beside it.
        let folder = [scene.clone()];
        let e = claim_output_file(
            &scene.join("meshes/1.obj"),
            &folder,
            "inside the input",
            true,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("the output is inside the input ("), "{e}");
        // New files, and existing files that are no input, follow `claim_file`.
        claim_output_file(&scene.join("export.usda"), &inputs, what, false).unwrap();
        let other = dir.path().join("other.json");
        std::fs::write(&other, "{}").unwrap();
        assert!(claim_output_file(&other, &folder, what, false).is_err());
        claim_output_file(&other, &folder, what, true).unwrap();
    }

    #[test]
    fn an_existing_file_is_replaced_only_with_force() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("out.json");
        claim_file(&file, false).unwrap();
        std::fs::write(&file, "mine").unwrap();
        let e = claim_file(&file, false).unwrap_err().to_string();
        assert!(e.contains("out.json") && e.contains("`force`"), "{e}");
        claim_file(&file, true).unwrap();
        assert!(claim_file(dir.path(), true).is_err());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn temporaries_of_an_output_file_whose_writer_ended_are_removed_when_it_is_claimed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("scene.ply");
        // Above the largest process id Linux hands out: a writer that has ended.
        let ended = 4_194_305;
        let live = std::process::id();
        let names = [
            format!(".scene.ply.tmp-{ended}-0"),
            format!(".scene.ply.tmp-{live}-3"),
            format!(".other.ply.tmp-{ended}-0"),
            format!(".scene.ply.tmp-{ended}-x"),
            "scene.ply.bak".to_string(),
        ];
        for name in &names {
            std::fs::write(dir.path().join(name), "part").unwrap();
        }
        claim_file(&out, false).unwrap();
        let left: Vec<bool> = names.iter().map(|n| dir.path().join(n).exists()).collect();
        assert_eq!(left, [false, true, true, true, true]);
    }
}
