//! Mutation fuzzing of the camera file reader (`sage3d render --camera`): a damaged file gives
//! an `Err` — naming the line and column for bad JSON or the field for a bad value — or a
//! camera whose every number is finite, never a panic; a camera written out reads back the same.
//! Run longer with `PROPTEST_CASES=10000 cargo test --release -p sage-splat --test json_fuzz`.

use proptest::prelude::*;
use sage_splat::camera::CameraSpec;
use serde_json::Value;

/// Values put in place of a node: wrong types, numbers beyond f32 or beyond JSON's range,
/// number-like strings, empty containers.
const ODD: [&str; 16] = [
    "null",
    "true",
    "\"\"",
    "\"NaN\"",
    "\"inf\"",
    "\"x\"",
    "3.4e38",
    "1e39",
    "-1e300",
    "1e400",
    "-0",
    "-1",
    "18446744073709551616",
    "[]",
    "{}",
    "[[1, 2], [3]]",
];

/// Marks the node that [`ODD`] text replaces after serialising.
const MARK: &str = "@@odd@@";

/// One edit of a JSON document.
#[derive(Debug, Clone)]
enum Edit {
    /// Replace the n-th node (pre-order) by an odd value.
    Replace { node: usize, odd: usize },
    /// Remove the n-th node from its object or array.
    Remove { node: usize },
    /// Overwrite a byte of the text.
    Flip { at: usize, byte: u8 },
    /// Keep only a prefix of the text.
    Truncate { keep: usize },
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => (any::<usize>(), 0..ODD.len()).prop_map(|(node, odd)| Edit::Replace { node, odd }),
        2 => any::<usize>().prop_map(|node| Edit::Remove { node }),
        1 => (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Edit::Flip { at, byte }),
        1 => any::<usize>().prop_map(|keep| Edit::Truncate { keep }),
    ]
}

/// JSON pointers of every node below the root, in pre-order.
fn pointers(v: &Value, at: &str, out: &mut Vec<String>) {
    let children: Vec<(String, &Value)> = match v {
        Value::Object(o) => o
            .iter()
            .map(|(k, c)| (k.replace('~', "~0").replace('/', "~1"), c))
            .collect(),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .map(|(i, c)| (i.to_string(), c))
            .collect(),
        _ => Vec::new(),
    };
    for (key, child) in children {
        let p = format!("{at}/{key}");
        out.push(p.clone());
        pointers(child, &p, out);
    }
}

/// `text` with the edits applied: node edits on the parsed document, then byte edits on its
/// text. Only one odd value is placed per document, so the marker stays unique.
fn mutate(text: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut doc: Value = serde_json::from_slice(text).unwrap();
    let mut odd = None;
    for e in edits {
        let mut all = Vec::new();
        pointers(&doc, "", &mut all);
        match *e {
            Edit::Replace { node, odd: o } if !all.is_empty() && odd.is_none() => {
                *doc.pointer_mut(&all[node % all.len()]).unwrap() = Value::from(MARK);
                odd = Some(ODD[o]);
            }
            Edit::Remove { node } if !all.is_empty() => {
                let p = &all[node % all.len()];
                let (parent, key) = p.rsplit_once('/').unwrap();
                match doc.pointer_mut(parent).unwrap() {
                    Value::Object(o) => {
                        o.remove(&key.replace("~1", "/").replace("~0", "~"));
                    }
                    Value::Array(a) => {
                        a.remove(key.parse::<usize>().unwrap());
                    }
                    _ => unreachable!("a parent is a container"),
                }
            }
            _ => {}
        }
    }
    let mut out = serde_json::to_string(&doc).unwrap();
    if let Some(o) = odd {
        out = out.replacen(&format!("\"{MARK}\""), o, 1);
    }
    mutate_bytes(out.into_bytes(), edits)
}

/// The byte edits of `edits` applied to `out`.
fn mutate_bytes(mut out: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        match *e {
            Edit::Flip { at, byte } if !out.is_empty() => {
                let i = at % out.len();
                out[i] = byte;
            }
            Edit::Truncate { keep } => out.truncate(keep % (out.len() + 1)),
            _ => {}
        }
    }
    out
}

/// The two ways to give a camera: a pose by position and angles with a field of view, and a
/// 4×4 camera-to-world matrix with focal lengths.
const FIXTURES: [&str; 2] = [
    r#"{"width": 64, "height": 48, "hfov_deg": 90, "position": [1, 2, 1.2], "yaw_deg": 30, "pitch_deg": -10, "near": 0.2, "far": 50}"#,
    r#"{"width": 64, "height": 48, "fx": 40, "fy": 41, "cx": 32, "cy": 24, "c2w": [[0, 0, 1, 1], [-1, 0, 0, 2], [0, -1, 0, 1.2], [0, 0, 0, 1]]}"#,
];

/// Reads `text` as a camera file: `Ok` only with a fully finite camera.
fn read(text: &[u8]) -> Result<(), TestCaseError> {
    let Ok(text) = std::str::from_utf8(text) else {
        return Ok(());
    };
    let spec = match CameraSpec::parse(text) {
        Ok(spec) => spec,
        Err(e) => {
            prop_assert!(e.location().starts_with("line "), "{}", e);
            return Ok(());
        }
    };
    match spec.camera() {
        Ok(c) => {
            let i = c.intrinsics;
            prop_assert!(
                [i.fx, i.fy, i.cx, i.cy, c.near, c.far]
                    .iter()
                    .all(|v| v.is_finite())
                    && c.position.is_finite()
                    && c.rotation.is_finite(),
                "{:?}",
                c
            );
        }
        Err(e) => prop_assert!(!e.to_string().is_empty()),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn mutated_camera_files_never_panic(which in 0..FIXTURES.len(), edits in prop::collection::vec(edit(), 1..4)) {
        read(&mutate(FIXTURES[which].as_bytes(), &edits))?;
    }

    #[test]
    fn arbitrary_text_never_panics(text in ".{0,120}") {
        read(text.as_bytes())?;
    }

    #[test]
    fn cameras_round_trip(
        size in (1u32..4000, 1u32..4000),
        hfov in prop::option::of(1.0f32..170.0),
        focal in (1.0f32..5000.0, prop::option::of(1.0f32..5000.0), prop::option::of(-100.0f32..5000.0)),
        position in prop::array::uniform3(-100.0f32..100.0),
        angles in (-360.0f32..360.0, -89.0f32..89.0),
        clip in prop::option::of((0.01f32..1.0, 2.0f32..1000.0)),
    ) {
        let (fx, fy, cx) = focal;
        let spec = CameraSpec {
            width: size.0,
            height: size.1,
            hfov_deg: hfov,
            fx: hfov.is_none().then_some(fx),
            fy: hfov.is_none().then_some(fy).flatten(),
            cx: hfov.is_none().then_some(cx).flatten(),
            cy: None,
            position: Some(position),
            yaw_deg: Some(angles.0),
            pitch_deg: Some(angles.1),
            c2w: None,
            near: clip.map(|c| c.0),
            far: clip.map(|c| c.1),
        };
        let back = CameraSpec::parse(&serde_json::to_string(&spec).unwrap()).unwrap();
        prop_assert_eq!(&back, &spec);
        prop_assert_eq!(back.camera().unwrap(), spec.camera().unwrap());
    }
}

#[test]
fn the_fixtures_are_cameras_and_bad_values_name_the_field() {
    for f in FIXTURES {
        CameraSpec::parse(f).unwrap().camera().unwrap();
    }
    let with = |key: &str, value: &str| {
        let mut doc: Value = serde_json::from_str(FIXTURES[1]).unwrap();
        doc[key] = Value::from("@");
        let text = doc.to_string().replace("\"@\"", value);
        CameraSpec::parse(&text)
            .and_then(|s| s.camera())
            .unwrap_err()
            .to_string()
    };
    // A number beyond f32 reads as infinity: the principal point and far plane must be finite.
    assert!(
        with("cx", "1e39").contains("principal point"),
        "{}",
        with("cx", "1e39")
    );
    assert!(with("far", "1e39").contains("both finite"));
    assert!(with("fx", "-1").contains("focal lengths"));
    let e = with("width", "\"wide\"");
    assert!(
        e.starts_with("line 1 column") && e.contains("invalid type"),
        "{e}"
    );
    let e = with("zoom", "2");
    assert!(e.contains("unknown field `zoom`"), "{e}");
}
