//! InteriorGS `labels.json`: an array of `{ins_id, label, bounding_box: [8 × {x, y, z}]}`.
//!
//! Also accepted: an object with the array under `labels`, numeric `ins_id`s, `id` in place of
//! `ins_id`. Entries without a `bounding_box` (InteriorGS walls) are skipped and counted.
//!
//! An object's `ins_id` names its mesh file (`meshes/{ins_id}.obj`), so it must be a plain file
//! name ([`ins_id_problem`]): an id read from a data file never becomes a path unchecked.

use super::json::{array, field, parse_text, point3, string};
use crate::object::{Attributes, Object, PhysicsRole, RigidBody, normalize_category};
use sage_core::{Error, InstanceId, Obb, Result, ResultExt};
use sage_io::files::strip_bom;
use sage_io::limits::LABELS;
use serde::de::{DeserializeSeed, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde_json::{Value, json};
use std::borrow::Cow;
use std::collections::BTreeMap;

/// Corner tolerance (metres) when reading boxes: rounding in files stays within it.
const BOX_TOLERANCE: f32 = 0.01;

/// The longest `ins_id` an object may have, in bytes: it names the object's mesh file, and file
/// systems allow 255 bytes a name, extension included.
pub const MAX_INS_ID: usize = sage_io::names::MAX_NAME;

/// The stem of the structure mesh's file (`meshes/structure.obj`), which no object's mesh may
/// take: the structure would load as that object's mesh, and a save would write both to one file.
pub const STRUCTURE_STEM: &str = "structure";

/// Why `ins_id` cannot name an object's files (`meshes/{ins_id}.obj`), or `None` when it can.
///
/// The rule is that of a single path component that stays in its folder: not empty, at most
/// [`MAX_INS_ID`] bytes, no `/` or `\` (a separator on some system) nor `:` (`C:x` leaves its
/// folder on Windows), no control character (NUL included), not starting with `.` (which
/// refuses `.` and `..` and hidden files), and not the structure mesh's [`STRUCTURE_STEM`] in
/// any case. It is looser than [`sage_io::names::check_plain`] on
/// purpose: a space or a non-ASCII letter is harmless in a file name, and refusing it would
/// refuse scenes that load today.
pub fn ins_id_problem(ins_id: &str) -> Option<String> {
    if ins_id.is_empty() {
        Some("is empty".to_string())
    } else if ins_id.len() > MAX_INS_ID {
        Some(format!("is longer than {MAX_INS_ID} bytes"))
    } else if let Some(c) = ins_id
        .chars()
        .find(|c| matches!(c, '/' | '\\' | ':') || c.is_control())
    {
        Some(format!("holds {c:?}"))
    } else if ins_id.starts_with('.') {
        Some("starts with '.'".to_string())
    } else if ins_id.eq_ignore_ascii_case(STRUCTURE_STEM) {
        Some(format!(
            "is the structure mesh's name (meshes/{STRUCTURE_STEM}.obj)"
        ))
    } else {
        None
    }
}

/// The message for an `ins_id` that cannot name a file, given [`ins_id_problem`]'s `problem`.
pub fn ins_id_message(ins_id: &str, problem: &str) -> String {
    let shown: String = ins_id.chars().take(MAX_INS_ID).collect();
    format!(
        "'{}' {problem}: an object's ins_id names its mesh file (meshes/{{ins_id}}.obj), so it \
         must be one file name: no '/', '\\', ':' or control characters, not starting with '.', \
         not '{STRUCTURE_STEM}', at most {MAX_INS_ID} bytes",
        shown.escape_debug()
    )
}

/// Parses `labels.json` into objects (ids unset) and the count of skipped entries.
///
/// The entries are counted first, without building them, and checked against [`LABELS`]: a
/// parsed entry takes about twenty times its text, so a file of a million small entries would
/// otherwise take gigabytes before any of them is looked at.
pub fn parse(text: &str) -> Result<(Vec<Object>, usize)> {
    if let Some(n) = count_entries(text) {
        LABELS.check(n, "(top level)")?;
    }
    let root = parse_text(text)?;
    let entries = match &root {
        Value::Object(o) if o.contains_key("labels") => array(&root["labels"], "labels")?,
        other => array(other, "(top level)")?,
    };
    let mut objects = Vec::with_capacity(entries.len());
    let mut skipped = 0;
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    for (i, e) in entries.iter().enumerate() {
        let parsed = parse_entry(e).within(format!("[{i}]"))?;
        let Some(object) = parsed else {
            skipped += 1;
            continue;
        };
        if let Some(first) = seen.insert(object.ins_id.clone(), i) {
            return Err(Error::format(
                format!("[{i}].ins_id"),
                format!(
                    "duplicate ins_id '{}' (first used by entry {first})",
                    object.ins_id
                ),
            ));
        }
        objects.push(object);
    }
    Ok((objects, skipped))
}

/// The number of entries of a `labels.json` text in either form (an array, or an object with
/// the array under `labels`), read without building them; `None` when the text is not one of
/// those forms, which the full parse then reports.
fn count_entries(text: &str) -> Option<u64> {
    let mut de = serde_json::Deserializer::from_str(strip_bom(text));
    Entries { nested: false }.deserialize(&mut de).ok()
}

/// Counts the elements of an array with [`IgnoredAny`] (which keeps nothing); at the top level
/// (`nested: false`) it also looks inside an object's `labels` key.
struct Entries {
    nested: bool,
}

impl<'de> DeserializeSeed<'de> for Entries {
    type Value = u64;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> std::result::Result<u64, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Entries {
    type Value = u64;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("an array of labels")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<u64, A::Error> {
        let mut n = 0;
        while seq.next_element::<IgnoredAny>()?.is_some() {
            n += 1;
        }
        Ok(n)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> std::result::Result<u64, A::Error> {
        if self.nested {
            return Err(serde::de::Error::custom("expected an array"));
        }
        let mut n = 0;
        while let Some(key) = map.next_key::<Cow<str>>()? {
            if key == "labels" {
                n = map.next_value_seed(Entries { nested: true })?;
            } else {
                map.next_value::<IgnoredAny>()?;
            }
        }
        Ok(n)
    }
}

fn parse_entry(e: &Value) -> Result<Option<Object>> {
    if !e.is_object() {
        return Err(Error::format("(entry)", "expected an object"));
    }
    let id_value = e
        .get("ins_id")
        .or_else(|| e.get("id"))
        .ok_or_else(|| Error::format("ins_id", "missing"))?;
    let ins_id = string(id_value, "ins_id")?;
    let label = string(field(e, "label")?, "label")?;
    let Some(bb) = e.get("bounding_box").filter(|b| !b.is_null()) else {
        return Ok(None);
    };
    // Only objects (entries with a box) get files named after them; a wall's id names none.
    if let Some(problem) = ins_id_problem(&ins_id) {
        return Err(Error::format("ins_id", ins_id_message(&ins_id, &problem)));
    }
    let corners = array(bb, "bounding_box")?
        .iter()
        .enumerate()
        .map(|(k, c)| point3(c, &format!("bounding_box[{k}]")))
        .collect::<Result<Vec<_>>>()?;
    let obb = Obb::from_corners(&corners, BOX_TOLERANCE)?;
    Ok(Some(Object {
        id: InstanceId::NONE,
        category: normalize_category(&label),
        ins_id,
        label,
        obb,
        room: None,
        attributes: Attributes::default(),
        role: PhysicsRole::Static,
        rigid_body: RigidBody::default(),
        mesh: None,
        body: None,
    }))
}

/// The objects as `labels.json`.
pub fn to_json(objects: &[Object]) -> Value {
    Value::Array(
        objects
            .iter()
            .map(|o| {
                let corners: Vec<Value> = o
                    .obb
                    .corners()
                    .iter()
                    .map(|c| json!({"x": c.x, "y": c.y, "z": c.z}))
                    .collect();
                json!({"ins_id": o.ins_id, "label": o.label, "bounding_box": corners})
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn one(corners: &str) -> String {
        format!(r#"[{{"ins_id":"7","label":"Dining Chair","bounding_box":{corners}}}]"#)
    }

    #[test]
    fn round_trip() {
        let obb = Obb {
            center: Vec3::new(1.0, 2.0, 0.5),
            half_extents: Vec3::new(0.3, 0.2, 0.5),
            yaw: 0.4,
        };
        let (objects, skipped) = parse(&one(&obb_json(&obb).to_string())).unwrap();
        assert_eq!(skipped, 0);
        let (back, _) = parse(&to_json(&objects).to_string()).unwrap();
        assert_eq!(
            (back[0].ins_id.as_str(), back[0].label.as_str()),
            ("7", "Dining Chair")
        );
        assert_eq!(back[0].category, "dining_chair");
        assert!((back[0].obb.center - obb.center).length() < 1e-4);
        assert!(
            (back[0].obb.half_extents - obb.half_extents)
                .abs()
                .max_element()
                < 1e-4
        );
    }

    fn obb_json(o: &Obb) -> Value {
        Value::Array(
            o.corners()
                .iter()
                .map(|c| json!({"x": c.x, "y": c.y, "z": c.z}))
                .collect(),
        )
    }

    #[test]
    fn errors_name_entry_and_field() {
        let b = Obb {
            center: Vec3::ZERO,
            half_extents: Vec3::ONE,
            yaw: 0.0,
        };
        let mut corners = obb_json(&b);
        corners.as_array_mut().unwrap().pop();
        let e = parse(&one(&corners.to_string())).unwrap_err();
        assert_eq!(
            e.to_string(),
            "[0].bounding_box: expected 8 corners, found 7"
        );
        let e = parse(r#"[{"ins_id":"1","label":"x","bounding_box":[{"x":"a","y":0,"z":0}]}]"#)
            .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("[0].bounding_box[0].x: expected a finite number"),
            "{e}"
        );
        let e = parse(r#"[{"label":"x"}]"#).unwrap_err();
        assert_eq!(e.to_string(), "[0].ins_id: missing");
        let e = parse("[{").unwrap_err();
        assert!(e.to_string().starts_with("line 1 column"), "{e}");
    }

    #[test]
    fn entries_without_box_are_skipped_and_dict_form_accepted() {
        let (o, skipped) = parse(r#"{"labels":[{"ins_id":3,"label":"wall"}]}"#).unwrap();
        assert!(o.is_empty());
        assert_eq!(skipped, 1);
    }

    #[test]
    fn more_entries_than_the_limit_are_refused_before_they_are_built() {
        // Entries that are not even objects: the count is checked before any entry is parsed.
        let n = LABELS.default as usize + 1;
        let many = format!("[{}0]", "0,".repeat(n - 1));
        let e = parse(&many).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "(top level): {n} entries, over the limit of {} entries on labels.json; set the \
                 environment variable SAGE3D_MAX_LABELS to raise it",
                LABELS.default
            )
        );
        let e = parse(&format!("{{\"version\": 2, \"labels\": {many}}}")).unwrap_err();
        assert!(e.to_string().contains("SAGE3D_MAX_LABELS"), "{e}");
        // At the limit, the entries are parsed (and the first bad one reported).
        let e = parse(&format!("[{}0]", "0,".repeat(n - 2))).unwrap_err();
        assert_eq!(e.to_string(), "[0].(entry): expected an object");
    }

    #[test]
    fn counting_keeps_the_errors_of_the_full_parse() {
        assert_eq!(count_entries("\u{feff}[1, 2]"), Some(2));
        assert_eq!(
            count_entries(r#"{"labels": [1], "other": [1, 2, 3]}"#),
            Some(1)
        );
        assert_eq!(count_entries(r#"{"labels": {"labels": [1]}}"#), None);
        let e = parse(r#"{"labels": 3}"#).unwrap_err();
        assert_eq!(e.to_string(), "labels: expected an array, found 3");
    }

    #[test]
    fn duplicate_ids_are_an_error() {
        let b = obb_json(&Obb {
            center: Vec3::ZERO,
            half_extents: Vec3::ONE,
            yaw: 0.0,
        })
        .to_string();
        let text = format!(
            r#"[{{"ins_id":"1","label":"a","bounding_box":{b}}},{{"ins_id":"1","label":"b","bounding_box":{b}}}]"#
        );
        assert!(
            parse(&text)
                .unwrap_err()
                .to_string()
                .contains("duplicate ins_id '1'")
        );
    }
}
