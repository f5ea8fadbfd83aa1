//! Episode complexity slices with the paper's thresholds (SPEC §9): scene assets `many` > 376,
//! `few` < 184; path `long` > 29.0 m, `short` < 8.4 m; `medium` in between (bounds included).

use sage_core::{Result, ResultExt};
use sage_scene::Object;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// More assets than this: `many`.
pub const ASSETS_MANY: usize = 376;
/// Fewer assets than this: `few`.
pub const ASSETS_FEW: usize = 184;
/// Longer paths than this (metres): `long` (the upper of [`sage_nav::sampling::PATH_EDGES`]).
pub const PATH_LONG: f32 = sage_nav::sampling::PATH_EDGES[1];
/// Shorter paths than this (metres): `short` (the lower of [`sage_nav::sampling::PATH_EDGES`]).
pub const PATH_SHORT: f32 = sage_nav::sampling::PATH_EDGES[0];

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

/// The objects of scene folder `dir` as its `labels.json` lists them (none without the file):
/// the scene's assets, whose count is its asset slice ([`scene_assets_slice`]). Every reader
/// that tags an episode by its scene's folder counts them here, so all tag a scene alike.
///
/// # Errors
///
/// A `labels.json` that cannot be read or parsed, naming it.
pub fn scene_objects(dir: &Path) -> Result<Vec<Object>> {
    let path = dir.join("labels.json");
    if !path.is_file() {
        return Ok(Vec::new());
    }
    let text = sage_io::files::read_text(&path, &sage_io::limits::SCENE_JSON_MB)?;
    Ok(sage_scene::formats::labels::parse(&text).in_file(&path)?.0)
}

/// The asset slice of scene folder `dir`: [`assets_slice`] of its [`scene_objects`].
///
/// # Errors
///
/// Those of [`scene_objects`].
pub fn scene_assets_slice(dir: &Path) -> Result<&'static str> {
    Ok(assets_slice(scene_objects(dir)?.len()))
}

/// The path slice of a path `length` metres long: the length bin the trajectory sampler puts
/// it in ([`sage_nav::sampling::length_bin`] over the paper's edges), so a `--length-mix` share
/// of a bin is the share of that slice.
pub fn path_slice(length: f32) -> &'static str {
    match sage_nav::sampling::length_bin(&sage_nav::sampling::PATH_EDGES, length) {
        0 => "short",
        1 => "medium",
        _ => "long",
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
        // The sampler's bins agree at the edges: a trajectory counted as medium is tagged so.
        let sampling = sage_nav::sampling::SamplingParams::default();
        for (length, slice) in [
            (8.39, "short"),
            (8.4, "medium"),
            (29.0, "medium"),
            (29.01, "long"),
        ] {
            assert_eq!(path_slice(length), slice);
            assert_eq!(["short", "medium", "long"][sampling.bin_of(length)], slice);
        }
    }
}
