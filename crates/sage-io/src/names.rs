//! Names read from data files or given as settings, on their way to becoming file names: the
//! one rule that keeps every such file inside its folder and every id in a file of its own.
//!
//! Two kinds of name meet the file system:
//! - names of things that already exist as files (a split's `episodes/{split}.jsonl`, a scene's
//!   folder) are **checked** ([`check_plain`]): a name that could point elsewhere (`..`, `/`,
//!   an absolute path, a leading dot, control characters) is refused, naming it;
//! - ids that only name outputs (an episode's map, a route's frames, a WebDataset key) are
//!   **mapped** ([`stem`]): kept as they are when already plain, otherwise their plain
//!   characters plus a hash of the whole id, so distinct ids get distinct files (checked for a
//!   whole set by [`distinct_stems`], which refuses the astronomically rare collision by naming
//!   both ids instead of mixing them).

use sage_core::{Error, Result};
use std::collections::BTreeMap;

/// The longest name [`check_plain`] accepts and the longest readable part of a [`stem`]: file
/// systems allow 255 bytes per name, and outputs add suffixes (`-000000.tar`, `.png`).
pub const MAX_NAME: usize = 128;

/// Hex digits of the hash a [`stem`] ends with when its id was not plain.
const HASH_DIGITS: usize = 16;

/// Refuses a name that cannot safely name an existing file or folder: `what` says what it
/// names (`split`, `scene`), for the message. Plain names are 1 to [`MAX_NAME`] characters of
/// ASCII letters, digits, `_`, `-` and `.`, not starting with `.`, so they never leave the
/// folder they are joined to, nor hide in it.
///
/// # Errors
///
/// An `invalid` error naming the kind and the name.
pub fn check_plain(what: &str, name: &str) -> Result<()> {
    let plain = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
    let problem = if name.is_empty() {
        Some("is empty".to_string())
    } else if name.len() > MAX_NAME {
        Some(format!("is longer than {MAX_NAME} characters"))
    } else if name.starts_with('.') {
        Some("starts with '.'".to_string())
    } else {
        name.chars()
            .find(|c| !plain(*c))
            .map(|c| format!("holds {c:?}; names use letters, digits, '_', '-' and '.'"))
    };
    match problem {
        Some(p) => Err(Error::invalid(format!(
            "{what} name '{}' {p}",
            name.chars()
                .take(MAX_NAME)
                .collect::<String>()
                .escape_debug()
        ))),
        None => Ok(()),
    }
}

/// Refuses a relative file path read from data (`meshes/1001.obj` in a scene's
/// `objects.json`) that could leave the folder it is relative to: absolute paths, `..`, and
/// any part that is not a plain name ([`check_plain`]); `what` names the field, for the message.
///
/// # Errors
///
/// An `invalid` error naming the field and the path.
pub fn check_relative(what: &str, path: &str) -> Result<()> {
    let parts: Vec<&str> = path.split(['/', '\\']).collect();
    if path.is_empty() || parts.iter().any(|p| check_plain(what, p).is_err()) {
        return Err(Error::invalid(format!(
            "{what} '{}' is not a path inside its folder (relative, plain names joined by '/')",
            path.chars()
                .take(MAX_NAME)
                .collect::<String>()
                .escape_debug()
        )));
    }
    Ok(())
}

/// The file-name stem for the id `id` (an episode, a route): `id` itself when it is 1 to
/// [`MAX_NAME`] characters of lowercase ASCII letters, digits, `_` and `-` and does not end
/// like a hashed stem; otherwise its first characters in lower case, every other character
/// as `_`,
/// then `-` and 16 hex digits of the id's hash, [`MAX_NAME`] characters at most. A stem holds no `.`, `/` or
/// upper case, so it stays in its folder, is a valid WebDataset key, and two ids that differ
/// only in case do not share a file on case-insensitive file systems.
pub fn stem(id: &str) -> String {
    let plain = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || matches!(c, '_' | '-');
    if !id.is_empty() && id.len() <= MAX_NAME && id.chars().all(plain) && !looks_hashed(id) {
        return id.to_string();
    }
    let readable: String = id
        .chars()
        .take(MAX_NAME - HASH_DIGITS - 1)
        .map(|c| match c.to_ascii_lowercase() {
            c if plain(c) => c,
            _ => '_',
        })
        .collect();
    let hash = crate::hash::fnv1a64(id.as_bytes());
    format!("{readable}-{hash:0width$x}", width = HASH_DIGITS)
}

/// True when `s` ends as a hashed [`stem`] does (`-` and 16 hex digits), so a plain id of that
/// shape is hashed too and can never equal another id's hashed stem.
fn looks_hashed(s: &str) -> bool {
    let b = s.as_bytes();
    b.len() > HASH_DIGITS
        && b[b.len() - HASH_DIGITS - 1] == b'-'
        && b[b.len() - HASH_DIGITS..]
            .iter()
            .all(|c| c.is_ascii_digit() || (b'a'..=b'f').contains(c))
}

/// The [`stem`] of each of `ids` (an id given twice counts once), refusing two ids that would
/// share a file: `what` says what the ids name (`episode`, `route`), for the message.
///
/// # Errors
///
/// An `invalid` error naming both ids.
pub fn distinct_stems<'a>(
    what: &str,
    ids: impl IntoIterator<Item = &'a str>,
) -> Result<BTreeMap<&'a str, String>> {
    distinct_by(what, ids, stem)
}

/// [`distinct_stems`] with the mapping `to_stem`.
fn distinct_by<'a>(
    what: &str,
    ids: impl IntoIterator<Item = &'a str>,
    to_stem: impl Fn(&str) -> String,
) -> Result<BTreeMap<&'a str, String>> {
    let mut stems: BTreeMap<&'a str, String> = BTreeMap::new();
    let mut owner: BTreeMap<String, &'a str> = BTreeMap::new();
    for id in ids {
        if stems.contains_key(id) {
            continue;
        }
        let s = to_stem(id);
        if let Some(other) = owner.insert(s.clone(), id) {
            return Err(Error::invalid(format!(
                "{what} ids '{}' and '{}' would share the file name '{s}'; rename one",
                other.escape_debug(),
                id.escape_debug()
            )));
        }
        stems.insert(id, s);
    }
    Ok(stems)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn plain_ids_keep_their_name_and_others_get_a_hash() {
        assert_eq!(stem("s1-t0-2"), "s1-t0-2");
        assert_eq!(stem("0001_839920-b3"), "0001_839920-b3");
        let dotted = stem("r.1");
        assert!(
            dotted.starts_with("r_1-") && dotted.len() == 4 + 16,
            "{dotted}"
        );
        assert_ne!(stem("r.1"), stem("r_1"));
        assert_ne!(stem("A"), stem("a"));
        assert!(
            stem("Route.1").starts_with("route_1-"),
            "{}",
            stem("Route.1")
        );
        assert_eq!(stem("a").to_lowercase(), "a");
        let long = "x".repeat(300);
        assert_eq!(stem(&long).len(), MAX_NAME);
        // a plain id shaped like a hashed stem is hashed, so it cannot take another id's file
        let shaped = stem("r.1");
        assert_ne!(stem(&shaped), shaped);
    }

    #[test]
    fn names_that_leave_or_hide_in_the_folder_are_refused() {
        for bad in [
            "", "..", "../x", "/abs", "a/b", "a\\b", ".hidden", "x\0y", "tab\t",
        ] {
            let e = check_plain("split", bad).unwrap_err().to_string();
            assert!(e.contains("split name"), "{bad:?}: {e}");
        }
        assert!(check_plain("split", &"s".repeat(MAX_NAME + 1)).is_err());
        for good in ["train", "val_unseen", "test-1", "scene.v2", "0001_839920"] {
            check_plain("split", good).unwrap();
        }
    }

    #[test]
    fn relative_paths_stay_inside_their_folder() {
        check_relative("mesh", "meshes/1001.obj").unwrap();
        for bad in [
            "",
            "/etc/passwd",
            "../../x.obj",
            "meshes/../../x",
            "a//b",
            "C:\\x",
            "./x",
        ] {
            let e = check_relative("mesh", bad).unwrap_err().to_string();
            assert!(e.contains("not a path inside"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn a_shared_stem_is_refused_naming_both_ids() {
        let stems = distinct_stems("episode", ["a", "b", "a", "r.1", "r_1"]).unwrap();
        assert_eq!(stems.len(), 4);
        // a hash collision (crafted ids can find one) is refused, never merged
        let folded = |id: &str| id.to_lowercase();
        let e = distinct_by("route", ["Ab", "x", "aB"], folded)
            .unwrap_err()
            .to_string();
        assert!(e.contains("'Ab' and 'aB'") && e.contains("'ab'"), "{e}");
    }

    proptest! {
        #[test]
        fn stems_stay_in_their_folder_and_apart(a in ".{0,300}", b in ".{0,300}") {
            for id in [&a, &b] {
                let s = stem(id);
                prop_assert!(!s.is_empty() && s.len() <= MAX_NAME);
                prop_assert!(s.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '-'));
                prop_assert!(check_plain("id", &s).is_ok());
            }
            if a != b {
                prop_assert_ne!(stem(&a).to_lowercase(), stem(&b).to_lowercase());
            }
        }

        #[test]
        fn plain_names_never_leave_the_folder(name in "\\PC{0,200}") {
            if check_plain("scene", &name).is_ok() {
                let joined = std::path::Path::new("base").join(&name);
                prop_assert_eq!(joined.parent(), Some(std::path::Path::new("base")));
                prop_assert!(name != "." && name != "..");
            }
        }
    }
}
