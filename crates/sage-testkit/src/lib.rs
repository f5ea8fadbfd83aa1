//! What sage3d's test suites share: mutations of JSON documents for the fuzz tests of every
//! JSON and JSONL reader (scene files, dataset and record files, camera files) — a test draws
//! [`Edit`]s with [`edit`] and applies them with [`mutate`]: node replacements by odd values
//! ([`ODD`]), node removals, byte flips and truncations — and random Gaussians for the
//! renderers' tests ([`splats`]).

pub mod splats;

use proptest::prelude::*;
use serde_json::Value;

/// Values put in place of a node: wrong types, numbers beyond f32 or beyond JSON's range,
/// number-like strings, empty containers.
pub const ODD: [&str; 16] = [
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
pub enum Edit {
    /// Replace the n-th node (pre-order) by an odd value.
    Replace { node: usize, odd: usize },
    /// Remove the n-th node from its object or array.
    Remove { node: usize },
    /// Overwrite a byte of the text.
    Flip { at: usize, byte: u8 },
    /// Keep only a prefix of the text.
    Truncate { keep: usize },
}

/// One random [`Edit`] (node edits drawn more often than byte edits).
pub fn edit() -> impl Strategy<Value = Edit> {
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
///
/// # Panics
///
/// When `text` is not JSON (the fixtures mutated are valid documents).
pub fn mutate(text: &[u8], edits: &[Edit]) -> Vec<u8> {
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
pub fn mutate_bytes(mut out: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
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
