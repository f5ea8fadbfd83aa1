//! Finding scene folders, naming them, and fingerprinting the files a pipeline reads.

use crate::hash::fnv1a64_file_hex;
use sage_core::{Error, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// True when `dir` is a scene folder: it holds `structure.json` or `labels.json`, or it is an
/// imported capture (`capture.json`: Gaussians, a map and no annotations).
pub fn is_scene_dir(dir: &Path) -> bool {
    ["structure.json", "labels.json", "capture.json"]
        .iter()
        .any(|f| dir.join(f).is_file())
}

/// The scene folders of `root`: itself when it is a scene ([`is_scene_dir`]), else its
/// sub-folders that are, sorted by name.
///
/// # Errors
///
/// `root` does not exist or cannot be read, or neither it nor any sub-folder is a scene.
pub fn scene_dirs(root: &Path) -> Result<Vec<PathBuf>> {
    if is_scene_dir(root) {
        return Ok(vec![root.to_path_buf()]);
    }
    if !root.exists() {
        return Err(Error::invalid(format!("{} does not exist", root.display())));
    }
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root)
        .map_err(|e| Error::io(root, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir() && is_scene_dir(p))
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        return Err(Error::invalid(format!(
            "{} is neither a scene folder nor a folder of scenes (no structure.json, labels.json or capture.json)",
            root.display()
        )));
    }
    Ok(dirs)
}

/// The folder name of a scene folder (how episodes name their scene).
pub fn scene_name(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// [`scene_dirs`] keyed by [`scene_name`].
///
/// # Errors
///
/// As [`scene_dirs`].
pub fn scene_dirs_by_name(root: &Path) -> Result<BTreeMap<String, PathBuf>> {
    Ok(scene_dirs(root)?
        .into_iter()
        .map(|d| (scene_name(&d), d))
        .collect())
}

/// FNV-1a 64 hashes (hex) of the files navigation reads ([`input_files`]), keyed by their path
/// relative to `dir`: what run records store so a later reader can tell whether a scene
/// changed.
pub fn input_hashes(dir: &Path) -> BTreeMap<String, String> {
    hash_files(dir, &input_files(dir))
}

/// The paths of the files navigation reads in scene folder `dir` (labels, structure, objects,
/// occupancy, an imported capture's `capture.json`, whatever `meshes/` holds, and the mesh
/// files `objects.json` names elsewhere in the folder: [`named_mesh_files`]), whether or not
/// each exists. `capture.json` counts because loading a capture without `structure.json` takes
/// its ceiling height from it.
pub fn input_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = [
        "labels.json",
        "structure.json",
        "objects.json",
        "occupancy.json",
        "occupancy.png",
        "capture.json",
    ]
    .iter()
    .map(|f| dir.join(f))
    .collect();
    if let Ok(entries) = std::fs::read_dir(dir.join("meshes")) {
        let mut meshes: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        meshes.sort();
        files.extend(meshes);
    }
    // Named meshes already listed (those in `meshes/`) keep their one entry, so the hashes of
    // scenes whose meshes all live there are what they always were.
    for named in named_mesh_files(dir) {
        if !files.contains(&named) {
            files.push(named);
        }
    }
    files
}

/// The mesh files the entries of scene folder `dir`'s `objects.json` name (`objects[i].mesh`,
/// relative to `dir`), which the loader reads wherever in the folder they are. A file that is
/// missing, too large or not JSON, and a path that would leave the folder, name none here: the
/// loader refuses those itself, naming the field.
pub fn named_mesh_files(dir: &Path) -> Vec<PathBuf> {
    let path = dir.join("objects.json");
    let Ok(text) = crate::files::read_text(&path, &crate::limits::SCENE_JSON_MB) else {
        return Vec::new();
    };
    let Ok(root) = serde_json::from_str::<serde_json::Value>(&text) else {
        return Vec::new();
    };
    let Some(entries) = root.get("objects").and_then(serde_json::Value::as_array) else {
        return Vec::new();
    };
    let mut found: Vec<PathBuf> = entries
        .iter()
        .filter_map(|e| e.get("mesh")?.as_str())
        .filter(|rel| crate::names::check_relative("mesh", rel).is_ok())
        // Joined as the loader joins it; paths compare by component, so `meshes/7.obj` is the
        // entry `meshes/` lists.
        .map(|rel| dir.join(rel))
        .collect();
    found.sort();
    found.dedup();
    found
}

/// FNV-1a 64 hashes (hex) of those of `files` that are readable files, keyed by their path
/// relative to `dir`.
pub fn hash_files(dir: &Path, files: &[PathBuf]) -> BTreeMap<String, String> {
    files
        .iter()
        .filter(|p| p.is_file())
        .filter_map(|p| {
            let hash = fnv1a64_file_hex(p).ok()?;
            let name = p
                .strip_prefix(dir)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned();
            Some((name, hash))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hash::fnv1a64_hex;

    #[test]
    fn a_folder_of_scenes_lists_its_scenes_by_name_and_a_scene_lists_itself() {
        let root = tempfile::tempdir().unwrap();
        for (name, file) in [("b", "labels.json"), ("a", "structure.json")] {
            std::fs::create_dir_all(root.path().join(name)).unwrap();
            std::fs::write(root.path().join(name).join(file), "[]").unwrap();
        }
        std::fs::create_dir_all(root.path().join("notes")).unwrap();
        let named = scene_dirs_by_name(root.path()).unwrap();
        assert_eq!(named.keys().collect::<Vec<_>>(), ["a", "b"]);
        let a = root.path().join("a");
        assert_eq!(scene_dirs(&a).unwrap(), vec![a.clone()]);
        let hashes = input_hashes(&a);
        assert_eq!(hashes.keys().collect::<Vec<_>>(), ["structure.json"]);
        assert_eq!(hashes["structure.json"], fnv1a64_hex(b"[]"));
        let e = scene_dirs(&root.path().join("notes"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("neither a scene folder"), "{e}");
    }

    #[test]
    fn a_capture_s_capture_json_is_hashed_and_editing_it_changes_the_hashes() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path();
        std::fs::write(dir.join("occupancy.json"), "{}").unwrap();
        let without = input_hashes(dir);
        assert!(!without.contains_key("capture.json"), "{without:?}");
        // Loading a capture takes its ceiling height from capture.json.
        std::fs::write(dir.join("capture.json"), r#"{"floor": {"ceiling_m": 2.5}}"#).unwrap();
        let before = input_hashes(dir);
        assert_eq!(
            before.keys().collect::<Vec<_>>(),
            ["capture.json", "occupancy.json"]
        );
        std::fs::write(dir.join("capture.json"), r#"{"floor": {"ceiling_m": 3.5}}"#).unwrap();
        let after = input_hashes(dir);
        assert_ne!(before["capture.json"], after["capture.json"]);
        assert_eq!(before["occupancy.json"], after["occupancy.json"]);
    }

    #[test]
    fn meshes_objects_json_names_outside_meshes_are_inputs_and_those_inside_are_listed_once() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path();
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::create_dir_all(dir.join("assets/chairs")).unwrap();
        std::fs::write(dir.join("meshes/1.obj"), "v 0 0 0").unwrap();
        std::fs::write(dir.join("assets/chairs/2.obj"), "v 1 0 0").unwrap();
        std::fs::write(dir.join("3.ply"), "ply").unwrap();
        let objects = serde_json::json!({"objects": [
            {"ins_id": "1", "mesh": "meshes/1.obj"},
            {"ins_id": "2", "mesh": "assets/chairs/2.obj"},
            {"ins_id": "3", "mesh": "3.ply"},
            {"ins_id": "4", "mesh": "../outside.obj"},
            {"ins_id": "5"},
        ]});
        std::fs::write(dir.join("objects.json"), objects.to_string()).unwrap();
        let files = input_files(dir);
        for named in ["meshes/1.obj", "assets/chairs/2.obj", "3.ply"] {
            let n = files.iter().filter(|p| **p == dir.join(named)).count();
            assert_eq!(n, 1, "{named}: {files:?}");
        }
        assert!(
            !files.iter().any(|p| p.ends_with("outside.obj")),
            "{files:?}"
        );
        let hashes = input_hashes(dir);
        assert_eq!(
            hashes.keys().collect::<Vec<_>>(),
            [
                "3.ply",
                "assets/chairs/2.obj",
                "meshes/1.obj",
                "objects.json"
            ]
        );
        // A file the loader refuses names no mesh here (and is no panic).
        std::fs::write(dir.join("objects.json"), "{not json").unwrap();
        assert!(named_mesh_files(dir).is_empty());
    }
}
