//! Episode complexity slices with the paper's thresholds (SPEC §9): scene assets `many` > 376,
//! `few` < 184; path `long` > 29.0 m, `short` < 8.4 m; `medium` in between (bounds included).

use serde::{Deserialize, Serialize};

/// More assets than this: `many`.
pub const ASSETS_MANY: usize = 376;
/// Fewer assets than this: `few`.
pub const ASSETS_FEW: usize = 184;
/// Longer paths than this (metres): `long`.
pub const PATH_LONG: f32 = 29.0;
/// Shorter paths than this (metres): `short`.
pub const PATH_SHORT: f32 = 8.4;

/// The slice tags of an episode.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Slices {
    /// `many`, `medium` or `few` (scene assets).
    pub assets: String,
    /// `long`, `medium` or `short` (reference path length); `none` for no-goal episodes.
    pub path: String,
}

/// The asset slice of a scene with `assets` objects.
pub fn assets_slice(assets: usize) -> &'static str {
    if assets > ASSETS_MANY {
        "many"
    } else if assets < ASSETS_FEW {
        "few"
    } else {
        "medium"
    }
}

/// The path slice of a path `length` metres long.
pub fn path_slice(length: f32) -> &'static str {
    if length > PATH_LONG {
        "long"
    } else if length < PATH_SHORT {
        "short"
    } else {
        "medium"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_are_strict_at_the_paper_values() {
        assert_eq!(assets_slice(377), "many");
        assert_eq!(assets_slice(376), "medium");
        assert_eq!(assets_slice(184), "medium");
        assert_eq!(assets_slice(183), "few");
        assert_eq!(path_slice(29.01), "long");
        assert_eq!(path_slice(29.0), "medium");
        assert_eq!(path_slice(8.4), "medium");
        assert_eq!(path_slice(8.39), "short");
    }
}
