//! Episode files saved by other tools: a leading UTF-8 byte-order mark (which Windows editors
//! add) is accepted, and a UTF-16 file is named as such.

use sage_dataset::formats::jsonl;

/// One episode, as docs/formats.md shows it.
const EPISODE: &str = r#"{"episode_id": "home_0-t0-0", "scene": "home_0", "task": "vln", "trajectory_id": 0, "instruction": "Go from the TV to the armchair in the bedroom.", "level": "low", "instruction_type": "Single-Goal", "subtype": "object_to_object", "source": "template", "start_ref": "tv_1", "start": {"position": [-0.325, 1.15, 0.0], "yaw": 0.0928}, "goal": {"ref": "armchair_2", "kind": "object", "position": [0.675, 1.15, 0.0]}, "reference_path": [[-0.325, 1.15, 0.0], [-0.075, 1.15, 0.0], [0.175, 1.15, 0.0], [0.425, 1.15, 0.0], [0.675, 1.15, 0.0]], "actions": [1, 1, 1, 1, 0], "path_length": 1.0, "geodesic_distance": 1.0, "slices": {"assets": "few", "path": "short"}}"#;

#[test]
fn episodes_with_a_byte_order_mark_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let with_bom = dir.path().join("bom.jsonl");
    std::fs::write(&with_bom, format!("\u{feff}{EPISODE}\n")).unwrap();
    let episodes = jsonl::read(&with_bom).unwrap();
    assert_eq!(episodes.len(), 1);
    assert_eq!(episodes[0].episode_id, "home_0-t0-0");
}

#[test]
fn a_utf16_episode_file_is_named_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wide.jsonl");
    let mut bytes = vec![0xff, 0xfe];
    bytes.extend(EPISODE.encode_utf16().flat_map(u16::to_le_bytes));
    std::fs::write(&path, bytes).unwrap();
    let e = jsonl::read(&path).unwrap_err();
    assert_eq!(e.file(), Some(path.as_path()));
    assert_eq!(
        e.to_string(),
        format!(
            "{}: encoding: the file is UTF-16 (it begins with a UTF-16 byte-order mark); save it \
             as UTF-8",
            path.display()
        )
    );
}
