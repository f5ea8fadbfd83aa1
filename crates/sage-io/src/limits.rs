//! Limits on what an input file may hold or declare, checked before it is read or decoded in
//! full, so that a small hostile or damaged file (a PNG header claiming 20000 × 20000 pixels, a
//! `labels.json` of a million entries) fails at once with an error naming the file and the limit
//! instead of exhausting memory.
//!
//! Every limit is far above what any real scene needs and can be raised through its environment
//! variable (`SAGE3D_MAX_…`, a whole number in the limit's unit) for the rare input that needs
//! more. docs/scene-format.md ("Limits") lists them.

use sage_core::{Error, Result};

/// A limit: its default and the environment variable that overrides it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limit {
    /// The environment variable that overrides the default.
    pub variable: &'static str,
    /// The default, in `unit`s.
    pub default: u64,
    /// The unit the limit (and its variable) is given in: `MB`, `entries`, `megapixels`.
    pub unit: &'static str,
    /// How many of the counted things (bytes, entries, pixels) one unit is.
    pub scale: u64,
    /// What is limited, for messages.
    pub what: &'static str,
}

/// The size of a scene's JSON files (`labels.json`, `structure.json`, `objects.json`,
/// `occupancy.json`): real ones are a few megabytes at most, and their parsed form takes about
/// twenty times their size.
pub const SCENE_JSON_MB: Limit = Limit {
    variable: "SAGE3D_MAX_SCENE_JSON_MB",
    default: 64,
    unit: "MB",
    scale: 1 << 20,
    what: "a scene JSON file",
};

/// The size of any other JSON or JSON-lines file (datasets, records), decompressed.
pub const JSON_MB: Limit = Limit {
    variable: "SAGE3D_MAX_JSON_MB",
    default: 1024,
    unit: "MB",
    scale: 1 << 20,
    what: "a JSON file",
};

/// The entries of a `labels.json`: real scenes have hundreds, a few thousand at most.
pub const LABELS: Limit = Limit {
    variable: "SAGE3D_MAX_LABELS",
    default: 50_000,
    unit: "entries",
    scale: 1,
    what: "labels.json",
};

/// The pixels of an image decoded whole (the occupancy map): 64 megapixels is a 400 m square at
/// 5 cm per cell.
pub const IMAGE_MEGAPIXELS: Limit = Limit {
    variable: "SAGE3D_MAX_IMAGE_MEGAPIXELS",
    default: 64,
    unit: "megapixels",
    scale: 1_000_000,
    what: "an image",
};

/// The size of a mesh once decoded (vertices and triangles, every instance of a glTF mesh
/// counted), which a small glTF file can make far larger than itself by instancing.
pub const MESH_MB: Limit = Limit {
    variable: "SAGE3D_MAX_MESH_MB",
    default: 1024,
    unit: "MB",
    scale: 1 << 20,
    what: "a decoded mesh",
};

/// The size of a published collision file (`{scene}_collision.usd`, USDC or USDA) before it is
/// opened: SAGE-Bench's run to a few megabytes per scene.
pub const COLLISION_MB: Limit = Limit {
    variable: "SAGE3D_MAX_COLLISION_MB",
    default: 512,
    unit: "MB",
    scale: 1 << 20,
    what: "a collision file",
};

/// The size of a Parquet file (a GN-Bench episode split) before it is opened: the published
/// splits are a few megabytes.
pub const PARQUET_MB: Limit = Limit {
    variable: "SAGE3D_MAX_PARQUET_MB",
    default: 1024,
    unit: "MB",
    scale: 1 << 20,
    what: "a Parquet file",
};

/// The rows of a Parquet file, as its footer declares them, checked before any is decoded.
pub const PARQUET_ROWS: Limit = Limit {
    variable: "SAGE3D_MAX_PARQUET_ROWS",
    default: 1_000_000,
    unit: "rows",
    scale: 1,
    what: "a Parquet file",
};

/// The values of a Parquet file (every cell and every element of a list column), as its footer
/// declares them: a small file can encode far more values than its size suggests (runs of one
/// value), so the decoded size is bounded by this count, not by the file's size.
pub const PARQUET_VALUES: Limit = Limit {
    variable: "SAGE3D_MAX_PARQUET_VALUES",
    default: 100_000_000,
    unit: "values",
    scale: 1,
    what: "a Parquet file",
};

/// Every limit (what docs/scene-format.md lists).
pub const ALL: [Limit; 9] = [
    SCENE_JSON_MB,
    JSON_MB,
    LABELS,
    IMAGE_MEGAPIXELS,
    MESH_MB,
    COLLISION_MB,
    PARQUET_MB,
    PARQUET_ROWS,
    PARQUET_VALUES,
];

impl Limit {
    /// The limit in counted things (bytes, entries, pixels): the environment variable's value
    /// when it is set, else the default.
    ///
    /// # Errors
    ///
    /// The variable is set but is not a whole number.
    pub fn get(&self) -> Result<u64> {
        self.resolve(std::env::var(self.variable).ok().as_deref())
    }

    /// The limit given the variable's value (`None` when unset).
    fn resolve(&self, value: Option<&str>) -> Result<u64> {
        let units = match value.map(str::trim) {
            None | Some("") => self.default,
            Some(v) => v.parse::<u64>().map_err(|_| {
                Error::invalid(format!(
                    "the environment variable {} must be a whole number of {}, found '{v}'",
                    self.variable, self.unit
                ))
            })?,
        };
        Ok(units.saturating_mul(self.scale))
    }

    /// Checks `found` (bytes, entries or pixels) against the limit.
    ///
    /// # Errors
    ///
    /// `found` is over the limit (a format error at `location`, saying what was found, the
    /// limit and the variable that raises it), or the variable is not a number.
    pub fn check(&self, found: u64, location: &str) -> Result<()> {
        let max = self.get()?;
        if found > max {
            return Err(self.exceeded(location, &self.amount(found), max));
        }
        Ok(())
    }

    /// The error for `found` (already rendered, e.g. "more than 1024 MB") over the limit `max`.
    pub(crate) fn exceeded(&self, location: &str, found: &str, max: u64) -> Error {
        Error::format(
            location,
            format!(
                "{found}, over the limit of {} on {}; set the environment variable {} to \
                 raise it",
                self.amount(max),
                self.what,
                self.variable
            ),
        )
    }

    /// `n` counted things in the limit's unit: "300.5 MB", "1000000 entries". Fractions are
    /// rounded up, so that an amount just over the limit never reads as equal to it.
    pub(crate) fn amount(&self, n: u64) -> String {
        if n.is_multiple_of(self.scale) {
            format!("{} {}", n / self.scale, self.unit)
        } else {
            let tenths = (n as f64 * 10.0 / self.scale as f64).ceil();
            format!("{:.1} {}", tenths / 10.0, self.unit)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_variable_overrides_the_default_and_must_be_a_number() {
        assert_eq!(LABELS.resolve(None).unwrap(), 50_000);
        assert_eq!(LABELS.resolve(Some(" 7 ")).unwrap(), 7);
        assert_eq!(SCENE_JSON_MB.resolve(Some("2")).unwrap(), 2 << 20);
        let e = IMAGE_MEGAPIXELS.resolve(Some("lots")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the environment variable SAGE3D_MAX_IMAGE_MEGAPIXELS must be a whole number of \
             megapixels, found 'lots'"
        );
    }

    #[test]
    fn an_error_names_what_was_found_the_limit_and_the_variable() {
        let e = LABELS.check(1_000_000, "(top level)").unwrap_err();
        assert_eq!(
            e.to_string(),
            "(top level): 1000000 entries, over the limit of 50000 entries on labels.json; set \
             the environment variable SAGE3D_MAX_LABELS to raise it"
        );
        assert!(LABELS.check(50_000, "(top level)").is_ok());
        let e = SCENE_JSON_MB
            .check(300 << 20 | 1 << 19, "file size")
            .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("file size: 300.5 MB, over the limit of 64 MB on a scene JSON file")
        );
    }

    #[test]
    fn every_variable_is_distinct_and_documented() {
        let doc = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/scene-format.md"),
        )
        .unwrap();
        for (i, a) in ALL.iter().enumerate() {
            assert!(a.variable.starts_with("SAGE3D_MAX_"), "{}", a.variable);
            assert!(ALL[i + 1..].iter().all(|b| b.variable != a.variable));
            let row = format!("| `{}` | {} |", a.variable, a.default);
            assert!(
                doc.contains(&row),
                "docs/scene-format.md lacks the row {row}"
            );
        }
    }
}
