//! Mutation fuzzing of the camera file reader (`sage3d render --camera`): a damaged file gives
//! an `Err` — naming the line and column for bad JSON or the field for a bad value — or a
//! camera whose every number is finite, never a panic; a camera written out reads back the same.
//! Run longer with `PROPTEST_CASES=10000 cargo test --release -p sage-splat --test json_fuzz`.

use proptest::prelude::*;
use sage_splat::camera::CameraSpec;
use sage_testkit::{edit, mutate};
use serde_json::Value;

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
