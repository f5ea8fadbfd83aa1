//! What a dataset folder says about itself: the list of its splits (`splits.json`) and the
//! scenes folder it was built from (its run record, `sage3d_run.json`).
//!
//! **Splits.** A split is a name listed under `"splits"` in `splits.json` (which `data build`
//! writes and `data import` extends), its episodes in `episodes/{split}.jsonl`; any other
//! `*.jsonl` lying in `episodes/` is not a split. Folders written before the list existed (no
//! `splits.json`, and no build's run record: below) fall back to the old rule: every
//! `episodes/*.jsonl` is a split.
//!
//! **Unfinished builds.** `data build` records itself before it works (so that its rerun
//! resumes) with the `status` [`UNFINISHED`](sage_io::run::UNFINISHED), and again with
//! [`FINISHED`](sage_io::run::FINISHED) once `splits.json` and the summary are written. A folder whose record is a
//! build's with a `status` other than [`FINISHED`](sage_io::run::FINISHED), or a build's record (of any status,
//! records before the field included) beside no `splits.json`, is a build stopped halfway (or
//! still running): its episode files may be some of the splits, or another build's, so every
//! reader refuses it ([`check`]) rather than take its files for splits by the old rule.
//! Folders without a record (made by hand, or before the record existed) are read as before.
//!
//! **Scenes.** `data build` records the scenes folder it read twice: absolute, and relative to
//! the dataset folder. A command that needs the scenes and is not given them resolves the
//! relative path first (it still holds when the dataset and its scenes move together), then the
//! absolute one (it still holds when the dataset alone moves).

use crate::Episode;
use sage_core::{Error, Result, ResultExt};
use sage_io::files::{read_json, write_json};
use sage_io::run::RUN_RECORD;
use serde_json::{Map, Value, json};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

/// The file listing a dataset's splits and their episode ids.
pub const SPLITS_FILE: &str = "splits.json";

/// The command, as the run record of a built dataset names it.
pub const COMMAND: &str = "data build";

/// Checks that `dataset` is a dataset folder (it has `episodes/`) and not one a `data build`
/// left unfinished (see the module doc).
///
/// # Errors
///
/// An `invalid` error naming the folder: it does not exist, it is an unfinished build, or it
/// has no `episodes/`; an unreadable run record, naming it.
pub fn check(dataset: &Path) -> Result<()> {
    if !dataset.exists() {
        return Err(Error::invalid("no such dataset folder").in_file(dataset));
    }
    check_finished(dataset)?;
    if dataset.join("episodes").is_dir() {
        return Ok(());
    }
    Err(Error::invalid(
        "not a dataset folder (no episodes/ in it; make one with `sage3d data build`)",
    )
    .in_file(dataset))
}

/// Checks that `dataset` is not a folder a `data build` was stopped in before it finished:
/// its run record is a build's and has a `status` other than [`FINISHED`](sage_io::run::FINISHED) (a build records
/// [`UNFINISHED`](sage_io::run::UNFINISHED) before it works), or it has no `splits.json`
/// (which a build writes before it records [`FINISHED`](sage_io::run::FINISHED)). A folder without a run record
/// passes.
///
/// # Errors
///
/// An `invalid` error naming the folder and telling to rerun the build; an unreadable run
/// record, naming it.
pub(crate) fn check_finished(dataset: &Path) -> Result<()> {
    let path = dataset.join(RUN_RECORD);
    if !path.is_file() {
        return Ok(());
    }
    let record: Value = read_json(&path)?;
    let field = |name: &str| record.get(name).and_then(Value::as_str);
    if field("command") != Some(COMMAND) {
        return Ok(());
    }
    let why = if let Some(status) = sage_io::run::unfinished_status(&record) {
        format!("its {RUN_RECORD} has status '{status}'")
    } else if !dataset.join(SPLITS_FILE).is_file() {
        format!("no {SPLITS_FILE}")
    } else {
        return Ok(());
    };
    Err(Error::invalid(format!(
        "the `sage3d data build` of this folder has not finished ({why}: it was stopped, or is still running); rerun `sage3d data build` into this folder to finish it"
    ))
    .in_file(dataset))
}

/// The splits `splits.json` lists, sorted; `None` for a dataset without the file (written
/// before the list existed).
///
/// # Errors
///
/// An unreadable `splits.json`, one without a `"splits"` object, or one naming a split that
/// is not a plain name ([`sage_io::names::check_plain`]: it would name a file elsewhere).
pub fn listed_splits(dataset: &Path) -> Result<Option<Vec<String>>> {
    let path = dataset.join(SPLITS_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let value: Value = read_json(&path)?;
    let splits = value
        .get("splits")
        .and_then(Value::as_object)
        .ok_or_else(|| {
            Error::format("splits", "expected an object of split names").in_file(&path)
        })?;
    for name in splits.keys() {
        sage_io::names::check_plain("split", name).map_err(|e| e.in_file(&path))?;
    }
    let mut names: Vec<String> = splits.keys().cloned().collect();
    names.sort();
    Ok(Some(names))
}

/// The names of the `episodes/*.jsonl` files of `dataset`, sorted: the splits of a dataset
/// without a list.
fn globbed_splits(dataset: &Path) -> Result<Vec<String>> {
    let dir = dataset.join("episodes");
    let mut splits: Vec<String> = std::fs::read_dir(&dir)
        .map_err(|e| Error::io(&dir, e))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            e.file_name()
                .to_string_lossy()
                .strip_suffix(".jsonl")
                .map(str::to_string)
        })
        .collect();
    splits.sort();
    Ok(splits)
}

/// The splits of `dataset`, sorted: those `splits.json` lists, or for a dataset without the
/// file every `episodes/*.jsonl`.
///
/// # Errors
///
/// Not a dataset folder ([`check`]), an unreadable `splits.json` or `episodes/`.
pub fn splits(dataset: &Path) -> Result<Vec<String>> {
    check(dataset)?;
    match listed_splits(dataset)? {
        Some(listed) => Ok(listed),
        None => globbed_splits(dataset),
    }
}

/// The splits of `dataset` that hold at least one episode, sorted.
///
/// # Errors
///
/// As [`splits`].
pub fn non_empty_splits(dataset: &Path) -> Result<Vec<String>> {
    Ok(splits(dataset)?
        .into_iter()
        .filter(|s| {
            let file = dataset.join("episodes").join(format!("{s}.jsonl"));
            std::fs::read_to_string(file).is_ok_and(|t| t.lines().any(|l| !l.trim().is_empty()))
        })
        .collect())
}

/// The episodes file of `split` in `dataset`.
///
/// # Errors
///
/// A split that is not a plain name, an `invalid` error listing the dataset's splits when
/// `split` is not one of them, an
/// error naming the missing file of a listed split, the file's read error, or a file whose
/// episode ids are not those `splits.json` lists for the split (some missing or not listed).
pub fn split_episodes(dataset: &Path, split: &str) -> Result<(PathBuf, Vec<Episode>)> {
    sage_io::names::check_plain("split", split).within("`split`")?;
    let splits = splits(dataset)?;
    let file = dataset.join("episodes").join(format!("{split}.jsonl"));
    if !splits.iter().any(|s| s == split) {
        return Err(Error::invalid(format!(
            "unknown split '{split}' (this dataset has: {})",
            splits.join(", ")
        ))
        .in_file(dataset));
    }
    if !file.is_file() {
        return Err(Error::invalid(format!(
            "split '{split}' is listed in {} but has no episodes file",
            SPLITS_FILE
        ))
        .in_file(&file));
    }
    let episodes = crate::formats::jsonl::read(&file)?;
    check_listed_ids(dataset, split, &file, &episodes)?;
    Ok((file, episodes))
}

/// Checks the episodes of `split`'s file against the ids `splits.json` lists for it, where it
/// lists them: a file cut short (or edited without its list) would otherwise be evaluated,
/// rendered or exported as if it were the split.
fn check_listed_ids(dataset: &Path, split: &str, file: &Path, episodes: &[Episode]) -> Result<()> {
    let Ok(value) = read_json::<Value>(&dataset.join(SPLITS_FILE)) else {
        return Ok(());
    };
    let Some(listed) = value["splits"].get(split).and_then(Value::as_array) else {
        return Ok(());
    };
    let listed: BTreeSet<&str> = listed.iter().filter_map(Value::as_str).collect();
    let held: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    let some = |ids: Vec<&&str>| {
        let shown: Vec<&str> = ids.iter().take(3).map(|id| **id).collect();
        match ids.len() {
            n if n > 3 => format!("{} and {} more", shown.join(", "), n - 3),
            _ => shown.join(", "),
        }
    };
    let missing: Vec<&&str> = listed.difference(&held).collect();
    let unlisted: Vec<&&str> = held.difference(&listed).collect();
    let mut differences = Vec::new();
    if !missing.is_empty() {
        differences.push(format!("{} missing: {}", missing.len(), some(missing)));
    }
    if !unlisted.is_empty() {
        differences.push(format!("{} not listed: {}", unlisted.len(), some(unlisted)));
    }
    if differences.is_empty() {
        return Ok(());
    }
    Err(Error::invalid(format!(
        "holds {} episodes where {SPLITS_FILE} lists {} for split '{split}' ({}): the file was cut short or edited; build the dataset again, or list the split's episode ids in {SPLITS_FILE}",
        held.len(),
        listed.len(),
        differences.join("; ")
    ))
    .in_file(file))
}

/// Lists `split` with the ids of `episodes` in `splits.json` (replacing its old ids), making
/// the file when the dataset has none and no other split file. A dataset without the list but
/// with other `episodes/*.jsonl` keeps the old rule (every file a split), which already counts
/// the new split: writing a list of one split there would hide the others.
///
/// # Errors
///
/// An unreadable `splits.json` (or one whose `"splits"` is not an object), or a write error.
pub fn add_split(dataset: &Path, split: &str, episodes: &[Episode]) -> Result<()> {
    let path = dataset.join(SPLITS_FILE);
    let mut value: Value = if path.is_file() {
        read_json(&path)?
    } else if globbed_splits(dataset)?.iter().any(|s| s != split) {
        return Ok(());
    } else {
        json!({"splits": {}})
    };
    let ids: Vec<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    value
        .as_object_mut()
        .and_then(|o| {
            o.entry("splits")
                .or_insert_with(|| Value::Object(Map::new()))
                .as_object_mut()
        })
        .ok_or_else(|| Error::format("splits", "expected an object of split names").in_file(&path))?
        .insert(split.to_string(), json!(ids));
    write_json(&path, &value)
}

/// The `imports` of `dataset`'s run record (the splits `data import` added, by name, with
/// their sources), if it has a readable record listing any.
pub fn imports(dataset: &Path) -> Option<Value> {
    sage_io::run::read_record(dataset)?
        .get("imports")
        .filter(|i| i.as_object().is_some_and(|o| !o.is_empty()))
        .cloned()
}

/// The entries of `splits.json` for the splits `data import` added to `dataset` (as its run
/// record lists them) whose episode files are there: what a rebuild of the dataset keeps.
///
/// # Errors
///
/// An unreadable `splits.json`.
pub(crate) fn imported_splits(dataset: &Path) -> Result<Vec<(String, Value)>> {
    let path = dataset.join(SPLITS_FILE);
    let Some(imports) = imports(dataset) else {
        return Ok(Vec::new());
    };
    if !path.is_file() {
        return Ok(Vec::new());
    }
    let listed: Value = read_json(&path)?;
    Ok(imports
        .as_object()
        .into_iter()
        .flat_map(|o| o.keys())
        // A name read from the record becomes a file name only when it is a plain one.
        .filter(|name| sage_io::names::check_plain("split", name).is_ok())
        .filter(|name| {
            dataset
                .join("episodes")
                .join(format!("{name}.jsonl"))
                .is_file()
        })
        .filter_map(|name| Some((name.clone(), listed["splits"].get(name)?.clone())))
        .collect())
}

/// The files navigation reads ([`sage_io::scenes::input_hashes`]) of the scenes `names` that
/// differ from what `data build` read when it built `dataset` (the `inputs` of its run
/// record), as `scene/file changed`, `added` or `removed`, in order. The dataset's goals and
/// reference paths were planned on those files: after such a change, metrics against them
/// (SPL, nDTW, the goal tests) and training data along them follow an episode the scene no
/// longer holds.
///
/// `dirs` holds the scene folders by name. A dataset without a build's record (imported, made
/// by hand or before the record held hashes), or a scene it does not list or `dirs` does not
/// hold, has nothing to compare: none.
pub fn scene_changes<'a>(
    dataset: &Path,
    names: impl IntoIterator<Item = &'a str>,
    dirs: &BTreeMap<String, PathBuf>,
) -> Vec<String> {
    let Some(record) = sage_io::run::read_record(dataset) else {
        return Vec::new();
    };
    if record.get("command").and_then(Value::as_str) != Some(COMMAND) {
        return Vec::new();
    }
    let Some(built) = record.get("inputs").and_then(Value::as_object) else {
        return Vec::new();
    };
    let names: BTreeSet<&str> = names.into_iter().collect();
    let mut changes = Vec::new();
    for scene in names {
        let (Some(then), Some(dir)) =
            (built.get(scene).and_then(Value::as_object), dirs.get(scene))
        else {
            continue;
        };
        let now = sage_io::scenes::input_hashes(dir);
        let files: BTreeSet<&String> = then.keys().chain(now.keys()).collect();
        for file in files {
            let what = match (then.get(file).and_then(Value::as_str), now.get(file)) {
                (Some(old), Some(new)) if old == new => continue,
                (Some(_), Some(_)) => "changed",
                (None, _) => "added",
                (Some(_), None) => "removed",
            };
            changes.push(format!("{scene}/{file} {what}"));
        }
    }
    changes
}

/// `path` made absolute: resolved through links when it exists, else joined to the working
/// directory.
pub(crate) fn absolute(path: &Path) -> PathBuf {
    std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_path_buf())
}

/// The relative path from folder `base` to `target` (both absolute, without `.` or `..`);
/// `None` when they share no root (another drive).
fn relative_to(target: &Path, base: &Path) -> Option<PathBuf> {
    let (t, b): (Vec<Component>, Vec<Component>) =
        (target.components().collect(), base.components().collect());
    if t.first() != b.first() {
        return None;
    }
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut rel: PathBuf = b[common..].iter().map(|_| Component::ParentDir).collect();
    rel.extend(&t[common..]);
    Some(if rel.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        rel
    })
}

/// How a dataset's run record stores the scenes folder `scenes` of dataset `dataset`:
/// `{"absolute": …, "relative": …}` (`relative` from the dataset folder, absent when there is
/// no relative path).
pub fn scenes_record(dataset: &Path, scenes: &Path) -> Value {
    let abs = absolute(scenes);
    let mut record = json!({"absolute": abs});
    if let Some(rel) = relative_to(&abs, &absolute(dataset)) {
        record["relative"] = json!(rel);
    }
    record
}

/// The scenes folder of an evaluation or render of `dataset`: `given` when there is one, else
/// the folder the dataset's run record names (relative to the dataset first, then absolute).
///
/// # Errors
///
/// Without `given`: not a dataset folder, a dataset that records no scenes folder (imported, or
/// built before the record existed) or one whose recorded folder exists neither way, each
/// telling to pass `--scenes`.
pub fn scenes_folder(dataset: &Path, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(scenes) = given {
        return Ok(scenes.to_path_buf());
    }
    check(dataset)?;
    let path = dataset.join(RUN_RECORD);
    let record: Option<Value> = if path.is_file() {
        Some(read_json(&path)?)
    } else {
        None
    };
    let Some(scenes) = record.as_ref().and_then(|r| r.get("scenes")) else {
        return Err(Error::invalid(
            "the dataset does not record its scenes folder; name it (`scenes`)",
        )
        .in_file(dataset));
    };
    resolve_scenes_record(dataset, scenes, "scenes").in_file(&path)
}

/// The folder a [`scenes_record`] of folder `base` names: relative to `base` first (it still
/// holds when `base` and the scenes move together), then absolute (when `base` alone moves).
/// `field` is the record's name in its file, for the errors.
///
/// # Errors
///
/// A record naming a folder that exists neither way (telling to name the scenes folder), or
/// one without its absolute path.
pub fn resolve_scenes_record(base: &Path, scenes: &Value, field: &str) -> Result<PathBuf> {
    let path = |name: &str| scenes.get(name).and_then(Value::as_str).map(PathBuf::from);
    if let Some(rel) = path("relative") {
        let dir = base.join(rel);
        if dir.is_dir() {
            return Ok(dir);
        }
    }
    match path("absolute") {
        Some(abs) if abs.is_dir() => Ok(abs),
        Some(abs) => Err(Error::invalid(format!(
            "the recorded scenes folder {} does not exist; name the scenes folder (`scenes`)",
            abs.display()
        ))),
        None => Err(Error::format(
            format!("{field}.absolute"),
            "expected the scenes folder's path",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_changes_name_each_navigation_file_changed_added_or_removed_since_the_build() {
        let root = tempfile::tempdir().unwrap();
        let (dataset, scene) = (root.path().join("data"), root.path().join("home"));
        std::fs::create_dir_all(&dataset).unwrap();
        std::fs::create_dir_all(&scene).unwrap();
        for file in ["labels.json", "structure.json", "3dgs_compressed.ply"] {
            std::fs::write(scene.join(file), file).unwrap();
        }
        let dirs = BTreeMap::from([("home".to_string(), scene.clone())]);
        let record = |command: &str| {
            sage_io::run::write_run_record(
                &dataset,
                command,
                None,
                json!({"inputs": {"home": sage_io::scenes::input_hashes(&scene)}}),
            )
            .unwrap()
        };
        record(COMMAND);
        assert!(scene_changes(&dataset, ["home"], &dirs).is_empty());
        // The Gaussians are no file navigation reads.
        std::fs::write(scene.join("3dgs_compressed.ply"), "other").unwrap();
        assert!(scene_changes(&dataset, ["home"], &dirs).is_empty());
        std::fs::write(scene.join("labels.json"), "edited").unwrap();
        std::fs::write(scene.join("objects.json"), "{}").unwrap();
        std::fs::remove_file(scene.join("structure.json")).unwrap();
        assert_eq!(
            scene_changes(&dataset, ["home", "home"], &dirs),
            [
                "home/labels.json changed",
                "home/objects.json added",
                "home/structure.json removed"
            ]
        );
        // A scene the build did not read, or a dataset no build recorded, has nothing to compare.
        assert!(scene_changes(&dataset, ["other"], &dirs).is_empty());
        record("data import");
        assert!(scene_changes(&dataset, ["home"], &dirs).is_empty());
    }

    #[test]
    fn relative_paths_climb_to_the_common_folder() {
        let rel = |t: &str, b: &str| relative_to(Path::new(t), Path::new(b)).unwrap();
        assert_eq!(rel("/w/scenes", "/w/data"), PathBuf::from("../scenes"));
        assert_eq!(rel("/w/data/scenes", "/w/data"), PathBuf::from("scenes"));
        assert_eq!(rel("/w", "/w/a/b"), PathBuf::from("../.."));
        assert_eq!(rel("/w", "/w"), PathBuf::from("."));
    }

    #[test]
    fn the_recorded_scenes_resolve_relative_first_then_absolute() {
        let dir = tempfile::tempdir().unwrap();
        let (data, scenes) = (dir.path().join("data"), dir.path().join("scenes"));
        std::fs::create_dir_all(data.join("episodes")).unwrap();
        std::fs::create_dir_all(&scenes).unwrap();
        let e = scenes_folder(&data, None).unwrap_err().to_string();
        assert!(
            e.contains("does not record its scenes folder; name it (`scenes`)"),
            "{e}"
        );
        let record = json!({"command": "data build", "scenes": scenes_record(&data, &scenes)});
        write_json(&data.join(RUN_RECORD), &record).unwrap();
        write_json(&data.join(SPLITS_FILE), &json!({"splits": {}})).unwrap();
        assert_eq!(record["scenes"]["relative"], "../scenes");
        assert_eq!(scenes_folder(&data, None).unwrap(), data.join("../scenes"));
        // Moved together: the relative path holds.
        let moved = dir.path().join("moved");
        std::fs::create_dir(&moved).unwrap();
        std::fs::rename(&data, moved.join("data")).unwrap();
        std::fs::rename(&scenes, moved.join("scenes")).unwrap();
        let data = moved.join("data");
        assert_eq!(scenes_folder(&data, None).unwrap(), data.join("../scenes"));
        // The scenes back where they were: the absolute path holds, until they are gone.
        std::fs::create_dir_all(&scenes).unwrap();
        std::fs::remove_dir(moved.join("scenes")).unwrap();
        assert_eq!(scenes_folder(&data, None).unwrap(), absolute(&scenes));
        std::fs::remove_dir(&scenes).unwrap();
        let e = scenes_folder(&data, None).unwrap_err().to_string();
        assert!(
            e.contains("the recorded scenes folder")
                && e.contains("does not exist; name the scenes folder (`scenes`)"),
            "{e}"
        );
        // Given scenes override the record.
        assert_eq!(
            scenes_folder(&data, Some(Path::new("elsewhere"))).unwrap(),
            PathBuf::from("elsewhere")
        );
    }
}
