//! GN-Bench (GN0) episode splits: one Parquet file per split, one row per episode (research
//! notes, GN-Bench §A1; docs/dataset.md "GN-Bench episodes"), read into episodes and written
//! from them.
//!
//! **Columns** ([`COLUMNS`]): `scene`, `trajectory_id`, `instruction`, `grounded_instruction`,
//! `label_ins_id`, `label_label`, `label_goal_pixel_x/y`, `start_world_x/y`, `goal_world_x/y`,
//! `start_facing_unit_dx/dy`, `start_facing_heading_degrees`, `path_raster_world_x/y` (lists of
//! metres) and `path_raster_pixel_x/y` (lists of occupancy-map columns and rows). All are
//! required and non-null; the four path lists of a row have equal lengths.
//!
//! **Frame.** GN-Bench maps a point (x, y) of its world to the pixel of a scene's occupancy map
//! with `lower`/`upper` of `occupancy.json` and s = (upper − lower) / image size, per axis:
//! col = round((−x − lower_x)/s_x − 0.5), row = round((y + upper_y)/s_y − 0.5). InteriorGS (our
//! W) puts the centre of pixel (col, row) at W_x = upper_x − s_x·(col + ½), W_y = lower_y +
//! s_y·(row + ½) ([`sage_scene::occupancy`]). Putting that centre into GN's mapping gives col
//! exactly when −x − lower_x = upper_x − W_x, i.e. x = W_x − (lower_x + upper_x), and row exactly
//! when y + upper_y = W_y − lower_y, i.e. y = W_y − (lower_y + upper_y). So the GN world is W
//! translated by −(lower + upper) in x and y ([`GnFrame::to_world`], [`GnFrame::from_world`]):
//! no rotation or mirror, so headings (counter-clockwise from +X) are the same in both, and
//! the translation is exact for every point, not only for pixel centres. z: GN's agent stands
//! at 1.3 m, our episodes at the floor (0).
//!
//! **Check.** Every imported row's path pixels must lie within one pixel of its world points
//! under that mapping ([`GnFrame::pixel_offset`]); a row that does not is rejected, not
//! imported (its pixel and world lists describe different places, or the scene is not the
//! one the file was made for).

use crate::episode::{Episode, Goal, StartPose, Task};
use crate::formats::gvln::{goal_kind, planar};
use crate::slices::{Slices, assets_slice, path_slice, scene_objects};
use arrow_array::cast::AsArray;
use arrow_array::types::{Float32Type, Float64Type, Int16Type, Int32Type, Int64Type};
use arrow_array::{Array, ArrayRef, Float64Array, Int64Array, ListArray, RecordBatch, StringArray};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::arrow::ProjectionMask;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;
use sage_core::{Error, Result, ResultExt, wrap_angle};
use sage_lang::actions::{StepSizes, follow};
use sage_lang::{InstructionType, Source};
use sage_scene::occupancy::OccupancyMap;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The columns of a GN-Bench split, in the order this writer writes them.
pub const COLUMNS: [&str; 19] = [
    "scene",
    "trajectory_id",
    "instruction",
    "grounded_instruction",
    "label_ins_id",
    "label_label",
    "label_goal_pixel_x",
    "label_goal_pixel_y",
    "start_world_x",
    "start_world_y",
    "goal_world_x",
    "goal_world_y",
    "start_facing_unit_dx",
    "start_facing_unit_dy",
    "start_facing_heading_degrees",
    "path_raster_world_x",
    "path_raster_world_y",
    "path_raster_pixel_x",
    "path_raster_pixel_y",
];

/// Rows decoded at a time: memory stays bounded by a batch, whatever the file's size.
const BATCH_ROWS: usize = 1024;

/// Which of a row's two instruction texts an imported episode gives the agent; the other is
/// kept in [`Episode::instruction_texts`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InstructionChoice {
    /// `grounded_instruction`: what GN-Bench's instruction sensor gives its agents.
    #[default]
    Grounded,
    /// `instruction`.
    Plain,
}

impl InstructionChoice {
    /// The name: `grounded` or `plain`, also the key in [`Episode::instruction_texts`].
    pub fn name(self) -> &'static str {
        match self {
            InstructionChoice::Grounded => "grounded",
            InstructionChoice::Plain => "plain",
        }
    }
}

/// One row of a GN-Bench split as the file holds it (GN world frame, metres; pixels).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// `scene`: the scene folder's name.
    pub scene: String,
    /// `trajectory_id`, as text (a number column reads as its digits).
    pub trajectory_id: String,
    /// `instruction`.
    pub instruction: String,
    /// `grounded_instruction`.
    pub grounded_instruction: String,
    /// `label_ins_id`: the goal object's `ins_id`, as text.
    pub label_ins_id: String,
    /// `label_label`: the goal object's label.
    pub label_label: String,
    /// `label_goal_pixel_x/y`: the goal's (column, row).
    pub label_goal_pixel: [i64; 2],
    /// `start_world_x/y`.
    pub start_world: [f64; 2],
    /// `goal_world_x/y`.
    pub goal_world: [f64; 2],
    /// `start_facing_unit_dx/dy` (GN-Bench does not read them).
    pub start_facing_unit: [f64; 2],
    /// `start_facing_heading_degrees`: counter-clockwise from +X.
    pub start_facing_heading_degrees: f64,
    /// `path_raster_world_x/y` as points.
    pub path_world: Vec<[f64; 2]>,
    /// `path_raster_pixel_x/y` as (column, row).
    pub path_pixel: Vec<[i64; 2]>,
}

impl Row {
    /// GN-Bench's name of the episode's session and log, `<scene>_<trajectory_id>`: the id
    /// an imported episode gets.
    pub fn session(&self) -> String {
        format!("{}_{}", self.scene, self.trajectory_id)
    }
}

/// The GN-Bench frame of one scene: its occupancy map's box and size (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnFrame {
    /// `lower` x, y of `occupancy.json`.
    pub lower: [f64; 2],
    /// `upper` x, y of `occupancy.json`.
    pub upper: [f64; 2],
    /// The image's (columns, rows).
    pub size: [usize; 2],
}

impl GnFrame {
    /// The frame of a scene's occupancy map.
    pub fn of_map(map: &OccupancyMap) -> Self {
        GnFrame {
            lower: [map.lower.x, map.lower.y].map(f64::from),
            upper: [map.upper.x, map.upper.y].map(f64::from),
            size: [map.width, map.height],
        }
    }

    /// Metres per pixel along x and y, as GN-Bench computes them: (upper − lower) / size.
    pub fn cell(&self) -> [f64; 2] {
        [0, 1].map(|k| (self.upper[k] - self.lower[k]) / self.size[k].max(1) as f64)
    }

    /// The W point of GN point `p`: `p + (lower + upper)`.
    pub fn to_world(&self, p: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|k| p[k] + self.lower[k] + self.upper[k])
    }

    /// The GN point of W point `w`: `w − (lower + upper)`.
    pub fn from_world(&self, w: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|k| w[k] - (self.lower[k] + self.upper[k]))
    }

    /// GN-Bench's pixel (column, row) of GN point `p`: rounded half to even, as Python rounds,
    /// then clamped into the image.
    pub fn pixel(&self, p: [f64; 2]) -> [i64; 2] {
        let s = self.cell();
        let at = [
            (-p[0] - self.lower[0]) / s[0] - 0.5,
            (p[1] + self.upper[1]) / s[1] - 0.5,
        ];
        [0, 1].map(|k| {
            let last = self.size[k].saturating_sub(1) as f64;
            at[k].round_ties_even().clamp(0.0, last) as i64
        })
    }

    /// The W centre of pixel (column, row): `(upper_x − s_x·(col + ½), lower_y + s_y·(row + ½))`.
    pub fn pixel_centre(&self, px: [i64; 2]) -> [f64; 2] {
        let s = self.cell();
        [
            self.upper[0] - s[0] * (px[0] as f64 + 0.5),
            self.lower[1] + s[1] * (px[1] as f64 + 0.5),
        ]
    }

    /// How far GN point `p` lies from the centre of pixel `px`, in pixels along x and y: at
    /// most ½ when `px` is `p`'s pixel, at most 1 for the import's check.
    pub fn pixel_offset(&self, p: [f64; 2], px: [i64; 2]) -> [f64; 2] {
        let (w, c, s) = (self.to_world(p), self.pixel_centre(px), self.cell());
        [0, 1].map(|k| (w[k] - c[k]).abs() / s[k])
    }
}

/// What a scene gives the import and the export: its frame and its objects.
#[derive(Debug, Clone)]
struct SceneInfo {
    frame: GnFrame,
    /// Per object of `labels.json` (in order): `ins_id`, item id (`sofa_2`) and label.
    objects: Vec<(String, String, String)>,
}

impl SceneInfo {
    /// Reads the occupancy map and the objects (`labels.json` with `objects.json`, whose
    /// categories the item ids are made of: [`sage_nav::semantic_map::item_ids`]) of a scene
    /// folder; the Gaussians are not read.
    fn load(dir: &Path) -> Result<Self> {
        if !(dir.join("occupancy.json").is_file() && dir.join("occupancy.png").is_file()) {
            return Err(Error::invalid(
                "the scene has no occupancy.json and occupancy.png, which GN-Bench's pixels refer to",
            )
            .in_file(dir));
        }
        let frame = GnFrame::of_map(&OccupancyMap::load(dir)?);
        // The objects the other importers count for the asset slice, so a scene gets the
        // same slice whichever file its episodes came from.
        let mut objects = scene_objects(dir)?;
        let categories = dir.join("objects.json");
        if categories.is_file() {
            let t = sage_io::files::read_text(&categories, &sage_io::limits::SCENE_JSON_MB)?;
            sage_scene::formats::objects_json::apply(&t, &mut objects).in_file(&categories)?;
        }
        let ids = sage_nav::semantic_map::item_ids(&objects);
        let objects = objects
            .into_iter()
            .zip(ids)
            .map(|(o, id)| (o.ins_id, id, o.label))
            .collect();
        Ok(SceneInfo { frame, objects })
    }
}

/// The scenes of a scenes folder, each read once when first asked for; a scene that is not
/// there, or cannot be read, is the reason its rows are rejected.
struct Scenes {
    dirs: BTreeMap<String, PathBuf>,
    root: PathBuf,
    loaded: HashMap<String, std::result::Result<Arc<SceneInfo>, String>>,
}

impl Scenes {
    fn new(root: &Path) -> Result<Self> {
        Ok(Scenes {
            dirs: sage_io::scenes::scene_dirs_by_name(root)?,
            root: root.to_path_buf(),
            loaded: HashMap::new(),
        })
    }

    fn get(&mut self, scene: &str) -> std::result::Result<Arc<SceneInfo>, String> {
        if let Some(r) = self.loaded.get(scene) {
            return r.clone();
        }
        let r = match self.dirs.get(scene) {
            Some(dir) => SceneInfo::load(dir)
                .map(Arc::new)
                .map_err(|e| e.to_string()),
            None => Err(format!(
                "scene '{}' is not in the scenes folder {}",
                scene.escape_debug(),
                self.root.display()
            )),
        };
        self.loaded.insert(scene.to_string(), r.clone());
        r
    }
}

// ---------------------------------------------------------------------------------------------
// Reading the file.

enum Num {
    Int(i64),
    Float(f64),
}

/// The number at `i` of a number column (ints and floats of the widths pandas writes).
fn number(a: &dyn Array, i: usize) -> std::result::Result<Num, String> {
    if a.is_null(i) {
        return Err(
            "null: expected a finite number (pandas writes a NaN as null; GN-Bench's columns \
             are required and non-null)"
                .into(),
        );
    }
    Ok(match a.data_type() {
        DataType::Int64 => Num::Int(a.as_primitive::<Int64Type>().value(i)),
        DataType::Int32 => Num::Int(a.as_primitive::<Int32Type>().value(i).into()),
        DataType::Int16 => Num::Int(a.as_primitive::<Int16Type>().value(i).into()),
        DataType::Float64 => Num::Float(a.as_primitive::<Float64Type>().value(i)),
        DataType::Float32 => Num::Float(a.as_primitive::<Float32Type>().value(i).into()),
        other => return Err(format!("expected a number, found {other}")),
    })
}

fn float(n: Num) -> std::result::Result<f64, String> {
    let f = match n {
        Num::Int(i) => i as f64,
        Num::Float(f) => f,
    };
    if f.is_finite() {
        Ok(f)
    } else {
        Err(format!("{f}: expected a finite number"))
    }
}

/// An integer; a float column (pandas makes one of an int column that held a missing value)
/// is accepted where its value is whole.
fn int(n: Num) -> std::result::Result<i64, String> {
    match n {
        Num::Int(i) => Ok(i),
        Num::Float(f) if f.is_finite() && f.fract() == 0.0 && f.abs() < 9.0e15 => Ok(f as i64),
        Num::Float(f) => Err(format!("{f}: expected a whole number")),
    }
}

/// The text at `i` of a string column.
fn text(a: &dyn Array, i: usize) -> std::result::Result<String, String> {
    if a.is_null(i) {
        return Err("null (GN-Bench's columns are required and non-null)".into());
    }
    Ok(match a.data_type() {
        DataType::Utf8 => a.as_string::<i32>().value(i).to_string(),
        DataType::LargeUtf8 => a.as_string::<i64>().value(i).to_string(),
        DataType::Utf8View => a.as_string_view().value(i).to_string(),
        other => return Err(format!("expected a string, found {other}")),
    })
}

/// An id column (`trajectory_id`, `label_ins_id`) as text: a string, or a whole number written
/// as its digits.
fn id_text(a: &dyn Array, i: usize) -> std::result::Result<String, String> {
    match a.data_type() {
        DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View => text(a, i),
        _ => number(a, i)
            .and_then(int)
            .map(|n| n.to_string())
            .map_err(|e| format!("{e} (expected a string or a whole number)")),
    }
}

/// The list at `i` of a list column, each element through `each`.
fn list<T>(
    a: &dyn Array,
    i: usize,
    each: impl Fn(Num) -> std::result::Result<T, String>,
) -> std::result::Result<Vec<T>, String> {
    if a.is_null(i) {
        return Err("null (GN-Bench's columns are required and non-null)".into());
    }
    let values: ArrayRef = match a.data_type() {
        DataType::List(_) => a.as_list::<i32>().value(i),
        DataType::LargeList(_) => a.as_list::<i64>().value(i),
        other => return Err(format!("expected a list of numbers, found {other}")),
    };
    (0..values.len())
        .map(|k| {
            number(&*values, k)
                .and_then(&each)
                .map_err(|e| format!("element {k}: {e}"))
        })
        .collect()
}

/// Reads row `i` of a batch (columns by name; all of [`COLUMNS`] are there).
fn read_row(b: &RecordBatch, i: usize) -> Result<Row> {
    let col = |name: &str| -> Result<&ArrayRef> {
        b.column_by_name(name)
            .ok_or_else(|| Error::format(name, "missing column"))
    };
    let at = |name: &'static str, e: String| Error::format(name, e);
    let s = |name: &'static str| text(&**col(name)?, i).map_err(|e| at(name, e));
    let id = |name: &'static str| id_text(&**col(name)?, i).map_err(|e| at(name, e));
    let f = |name: &'static str| {
        number(&**col(name)?, i)
            .and_then(float)
            .map_err(|e| at(name, e))
    };
    let n = |name: &'static str| {
        number(&**col(name)?, i)
            .and_then(int)
            .map_err(|e| at(name, e))
    };
    let floats = |name: &'static str| list(&**col(name)?, i, float).map_err(|e| at(name, e));
    let ints = |name: &'static str| list(&**col(name)?, i, int).map_err(|e| at(name, e));
    let wx = floats("path_raster_world_x")?;
    let wy = floats("path_raster_world_y")?;
    let px = ints("path_raster_pixel_x")?;
    let py = ints("path_raster_pixel_y")?;
    if wx.is_empty() {
        return Err(Error::format(
            "path_raster_world_x",
            "an empty path (the raster path runs from the start to the goal)",
        ));
    }
    for (name, len) in [
        ("path_raster_world_y", wy.len()),
        ("path_raster_pixel_x", px.len()),
        ("path_raster_pixel_y", py.len()),
    ] {
        if len != wx.len() {
            return Err(Error::format(
                name,
                format!(
                    "{len} values, but path_raster_world_x has {}: the four path lists must have equal lengths",
                    wx.len()
                ),
            ));
        }
    }
    Ok(Row {
        scene: s("scene")?,
        trajectory_id: id("trajectory_id")?,
        instruction: s("instruction")?,
        grounded_instruction: s("grounded_instruction")?,
        label_ins_id: id("label_ins_id")?,
        label_label: s("label_label")?,
        label_goal_pixel: [n("label_goal_pixel_x")?, n("label_goal_pixel_y")?],
        start_world: [f("start_world_x")?, f("start_world_y")?],
        goal_world: [f("goal_world_x")?, f("goal_world_y")?],
        start_facing_unit: [f("start_facing_unit_dx")?, f("start_facing_unit_dy")?],
        start_facing_heading_degrees: f("start_facing_heading_degrees")?,
        path_world: wx.into_iter().zip(wy).map(|(x, y)| [x, y]).collect(),
        path_pixel: px.into_iter().zip(py).map(|(x, y)| [x, y]).collect(),
    })
}

fn parquet_error(path: &Path) -> impl Fn(parquet::errors::ParquetError) -> Error + '_ {
    move |e| Error::format("parquet", e.to_string()).in_file(path)
}

/// Reads every row of a GN-Bench split. The file's size, and the rows and values its footer
/// declares, are checked against [`sage_io::limits::PARQUET_MB`], `PARQUET_ROWS` and
/// `PARQUET_VALUES` before anything is decoded; rows are then decoded a batch at a time.
///
/// # Errors
///
/// A file over a limit, one that is not Parquet, a missing column (naming it), and a bad
/// value: of the wrong type, null, not finite, or path lists of unequal lengths, naming the
/// row (1-based, GN-Bench's `episode_id`) and the column.
pub fn read_rows(path: &Path) -> Result<Vec<Row>> {
    use sage_io::limits::{PARQUET_MB, PARQUET_ROWS, PARQUET_VALUES};
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    PARQUET_MB.check(size, "file size").in_file(path)?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(parquet_error(path))?;
    let meta = builder.metadata();
    let rows = u64::try_from(meta.file_metadata().num_rows()).unwrap_or(u64::MAX);
    PARQUET_ROWS.check(rows, "rows").in_file(path)?;
    let values: u64 = meta
        .row_groups()
        .iter()
        .flat_map(|g| g.columns())
        .map(|c| u64::try_from(c.num_values()).unwrap_or(u64::MAX))
        .fold(0, u64::saturating_add);
    PARQUET_VALUES.check(values, "values").in_file(path)?;
    let schema = builder.schema().clone();
    let mut roots = Vec::with_capacity(COLUMNS.len());
    for name in COLUMNS {
        let k = schema.index_of(name).map_err(|_| {
            Error::format(
                name,
                format!(
                    "missing column (a GN-Bench split has {})",
                    COLUMNS.join(", ")
                ),
            )
            .in_file(path)
        })?;
        roots.push(k);
    }
    let mask = ProjectionMask::roots(builder.parquet_schema(), roots);
    let reader = builder
        .with_projection(mask)
        .with_batch_size(BATCH_ROWS)
        .build()
        .map_err(parquet_error(path))?;
    let mut out = Vec::new();
    for batch in reader {
        let batch = batch.map_err(|e| Error::format("parquet", e.to_string()).in_file(path))?;
        for i in 0..batch.num_rows() {
            let row = out.len() + 1;
            out.push(
                read_row(&batch, i)
                    .within(format!("row {row}"))
                    .in_file(path)?,
            );
        }
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Rows to episodes.

/// A row that was not imported, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rejected {
    /// The row, 1-based (GN-Bench's `episode_id`).
    pub row: usize,
    /// The id the episode would have had (`<scene>_<trajectory_id>`).
    pub episode_id: String,
    /// The column at fault.
    pub column: String,
    /// Why.
    pub reason: String,
}

/// What reading a GN-Bench split against a scenes folder gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The rows in the file.
    pub rows: usize,
    /// The imported episodes, in row order.
    pub episodes: Vec<Episode>,
    /// The row (1-based) each imported episode came from.
    pub episode_rows: Vec<usize>,
    /// The rows not imported.
    pub rejected: Vec<Rejected>,
}

impl Imported {
    /// The error of an import that imported nothing: the first rejected row, named by row and
    /// column, and how many more there are.
    pub fn nothing_imported(&self, file: &Path) -> Error {
        match self.rejected.first() {
            Some(r) => Error::format(
                format!("row {}.{}", r.row, r.column),
                format!(
                    "{} (no row could be imported: {} of {} rejected)",
                    r.reason,
                    self.rejected.len(),
                    self.rows
                ),
            ),
            None => Error::format("(rows)", "the file holds no episodes"),
        }
        .in_file(file)
    }
}

/// The episode of one row in the scene `info`, or the column at fault and why not.
fn episode(
    row: &Row,
    info: &SceneInfo,
    choice: InstructionChoice,
    space: &StepSizes,
) -> std::result::Result<Episode, (&'static str, String)> {
    let frame = &info.frame;
    for (k, (w, px)) in row.path_world.iter().zip(&row.path_pixel).enumerate() {
        let off = frame.pixel_offset(*w, *px);
        // A hair over one pixel is still one: the frame's sums round in the last bits.
        if let Some(axis) = (0..2).find(|&a| off[a] > 1.0 + 1e-9) {
            return Err((
                ["path_raster_pixel_x", "path_raster_pixel_y"][axis],
                format!(
                    "point {k}: pixel ({}, {}) is {:.2} pixels from the world point ({}, {}) \
                     (expected within 1 under the scene's occupancy.json)",
                    px[0], px[1], off[axis], w[0], w[1]
                ),
            ));
        }
    }
    let world = |p: [f64; 2]| {
        let w = frame.to_world(p);
        [w[0] as f32, w[1] as f32, 0.0]
    };
    let yaw = wrap_angle(row.start_facing_heading_degrees.to_radians() as f32);
    let path: Vec<[f32; 3]> = row.path_world.iter().map(|p| world(*p)).collect();
    let (flat, length) = planar(&path);
    let actions = follow(&flat, yaw, None, space).ok_or((
        "path_raster_world_x",
        "the path cannot be followed with discrete actions".to_string(),
    ))?;
    let goal = match info.objects.iter().find(|o| o.0 == row.label_ins_id) {
        Some((_, item, _)) => Goal {
            reference: item.clone(),
            kind: "object".into(),
            position: world(row.goal_world),
            yaw: None,
        },
        // Not an object of the scene's labels.json: a room or an area where the id names one
        // as sage3d's export writes them (`room_2`, `sleeping_area_1`), else the goal's point;
        // the raw id is kept as the reference.
        None => Goal {
            reference: row.label_ins_id.clone(),
            kind: match goal_kind(&row.label_ins_id) {
                kind @ ("room" | "area") => kind,
                _ => "pose",
            }
            .into(),
            position: world(row.goal_world),
            yaw: None,
        },
    };
    let texts = BTreeMap::from([
        ("grounded".to_string(), row.grounded_instruction.clone()),
        ("plain".to_string(), row.instruction.clone()),
    ]);
    let e = Episode {
        episode_id: row.session(),
        scene: row.scene.clone(),
        task: Task::Vln,
        trajectory_id: row.trajectory_id.parse().ok(),
        instruction: texts[choice.name()].clone(),
        instruction_texts: texts,
        level: InstructionType::SingleGoal.level(),
        instruction_type: InstructionType::SingleGoal,
        subtype: None,
        source: Source::Imported,
        start_ref: None,
        start: StartPose {
            position: world(row.start_world),
            yaw,
        },
        goal: Some(goal),
        reference_path: path,
        actions,
        path_length: length,
        geodesic_distance: length,
        slices: Slices {
            assets: assets_slice(info.objects.len()).into(),
            path: path_slice(length).into(),
        },
    };
    e.check().map_err(|err| ("(episode)", err.to_string()))?;
    Ok(e)
}

/// Reads a GN-Bench split and turns each row into an episode in W, checked against its scene
/// in `scenes` (a scene folder or a folder of them) as the module docs say. A row whose scene
/// is not there (or has no occupancy map), whose pixels do not match its world points, whose
/// path cannot be followed, or whose `<scene>_<trajectory_id>` repeats an earlier row's is
/// rejected with its row and column; the others are imported.
///
/// The episode: id `<scene>_<trajectory_id>` (GN-Bench's session and log name), the numeric
/// `trajectory_id` when it is one, `choice`'s instruction with both texts in
/// [`Episode::instruction_texts`], a Single-Goal episode whose goal is the object
/// `label_ins_id` names (its item id, kind `object`) or, when the scene has no such object,
/// the goal point (kind `pose` without a heading, the raw id as its reference), the start
/// heading from `start_facing_heading_degrees`, the raster path as the reference path
/// (its points as they are), its ground-truth actions, its length as path length and
/// geodesic distance, the asset slice of the scene's object count.
///
/// # Errors
///
/// Those of [`read_rows`], and a scenes folder without scenes.
pub fn read(
    path: &Path,
    scenes: &Path,
    choice: InstructionChoice,
    space: &StepSizes,
) -> Result<Imported> {
    let rows = read_rows(path)?;
    let mut scenes = Scenes::new(scenes)?;
    let mut out = Imported {
        rows: rows.len(),
        episodes: Vec::new(),
        episode_rows: Vec::new(),
        rejected: Vec::new(),
    };
    let mut seen: HashMap<String, usize> = HashMap::new();
    for (k, row) in rows.iter().enumerate() {
        let at = k + 1;
        let id = row.session();
        let result = if let Some(first) = seen.get(&id) {
            Err((
                "trajectory_id",
                format!("the episode id '{id}' is already row {first}'s"),
            ))
        } else if let Err(reason) = sage_io::names::check_plain("scene", &row.scene) {
            Err(("scene", reason.to_string()))
        } else {
            match scenes.get(&row.scene) {
                Ok(info) => episode(row, &info, choice, space),
                Err(reason) => Err(("scene", reason)),
            }
        };
        match result {
            Ok(e) => {
                seen.insert(id, at);
                out.episodes.push(e);
                out.episode_rows.push(at);
            }
            Err((column, reason)) => out.rejected.push(Rejected {
                row: at,
                episode_id: id,
                column: column.into(),
                reason,
            }),
        }
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Episodes to rows, and the file.

/// An episode that a GN-Bench file cannot hold, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LeftOut {
    /// The episode.
    pub episode_id: String,
    /// Why.
    pub reason: String,
}

/// The row of an episode in the scene `info`: the inverse of the import (module docs).
fn row(e: &Episode, info: &SceneInfo) -> std::result::Result<Row, String> {
    let goal = e
        .goal
        .as_ref()
        .ok_or("a no-goal episode: GN-Bench episodes have a goal")?;
    if goal.yaw.is_some() {
        // GN-Bench scores the distance to the goal point alone: a turn in place would be
        // solved by stopping at the start.
        return Err("a goal heading: GN-Bench scores only the distance to the goal point".into());
    }
    let frame = &info.frame;
    let gn = |p: [f32; 3]| frame.from_world([f64::from(p[0]), f64::from(p[1])]);
    let object = (goal.kind == "object")
        .then(|| info.objects.iter().find(|o| o.1 == goal.reference))
        .flatten();
    let (ins_id, label) = match object {
        Some((ins, _, label)) => (ins.clone(), label.clone()),
        None => (goal.reference.clone(), String::new()),
    };
    let text = |name: &str| {
        e.instruction_texts
            .get(name)
            .unwrap_or(&e.instruction)
            .clone()
    };
    let yaw = f64::from(e.start.yaw);
    let path_world: Vec<[f64; 2]> = e.reference_path.iter().map(|p| gn(*p)).collect();
    let goal_world = gn(goal.position);
    Ok(Row {
        trajectory_id: e
            .episode_id
            .strip_prefix(&format!("{}_", e.scene))
            .unwrap_or(&e.episode_id)
            .to_string(),
        scene: e.scene.clone(),
        instruction: text(InstructionChoice::Plain.name()),
        grounded_instruction: text(InstructionChoice::Grounded.name()),
        label_ins_id: ins_id,
        label_label: label,
        label_goal_pixel: frame.pixel(goal_world),
        start_world: gn(e.start.position),
        goal_world,
        start_facing_unit: [yaw.cos(), yaw.sin()],
        start_facing_heading_degrees: yaw.to_degrees(),
        path_pixel: path_world.iter().map(|p| frame.pixel(*p)).collect(),
        path_world,
    })
}

/// The rows of `episodes` in the scenes of `scenes` (a scene folder or a folder of them),
/// in the episodes' order, and the episodes left out: no-goal episodes, and those of scenes
/// not there or without an occupancy map.
///
/// # Errors
///
/// A scenes folder without scenes.
pub fn rows(episodes: &[Episode], scenes: &Path) -> Result<(Vec<Row>, Vec<LeftOut>)> {
    let mut scenes = Scenes::new(scenes)?;
    let mut rows = Vec::with_capacity(episodes.len());
    let mut left_out = Vec::new();
    for e in episodes {
        match scenes.get(&e.scene).and_then(|info| row(e, &info)) {
            Ok(r) => rows.push(r),
            Err(reason) => left_out.push(LeftOut {
                episode_id: e.episode_id.clone(),
                reason,
            }),
        }
    }
    Ok((rows, left_out))
}

/// The Arrow schema of a GN-Bench split as this writer writes it: the types pandas writes
/// (string, int64, double, list of double, list of int64), every column nullable as
/// pandas declares them.
pub fn schema() -> Schema {
    let list = |t: DataType| DataType::List(Arc::new(Field::new_list_field(t, true)));
    let kind = |name: &str| match name {
        "scene"
        | "trajectory_id"
        | "instruction"
        | "grounded_instruction"
        | "label_ins_id"
        | "label_label" => DataType::Utf8,
        "label_goal_pixel_x" | "label_goal_pixel_y" => DataType::Int64,
        "path_raster_world_x" | "path_raster_world_y" => list(DataType::Float64),
        "path_raster_pixel_x" | "path_raster_pixel_y" => list(DataType::Int64),
        _ => DataType::Float64,
    };
    Schema::new(
        COLUMNS
            .iter()
            .map(|c| Field::new(*c, kind(c), true))
            .collect::<Vec<_>>(),
    )
}

/// The record batch of `rows`, columns as [`schema`] says.
fn batch(rows: &[Row]) -> std::result::Result<RecordBatch, arrow_schema::ArrowError> {
    let strings = |f: fn(&Row) -> &str| -> ArrayRef {
        Arc::new(StringArray::from_iter_values(rows.iter().map(f)))
    };
    let ints = |f: fn(&Row) -> i64| -> ArrayRef {
        Arc::new(Int64Array::from_iter_values(rows.iter().map(f)))
    };
    let floats = |f: fn(&Row) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(rows.iter().map(f)))
    };
    let world = |k: usize| -> ArrayRef {
        Arc::new(ListArray::from_iter_primitive::<Float64Type, _, _>(
            rows.iter()
                .map(|r| Some(r.path_world.iter().map(|p| Some(p[k])))),
        ))
    };
    let pixel = |k: usize| -> ArrayRef {
        Arc::new(ListArray::from_iter_primitive::<Int64Type, _, _>(
            rows.iter()
                .map(|r| Some(r.path_pixel.iter().map(|p| Some(p[k])))),
        ))
    };
    RecordBatch::try_new(
        Arc::new(schema()),
        vec![
            strings(|r| &r.scene),
            strings(|r| &r.trajectory_id),
            strings(|r| &r.instruction),
            strings(|r| &r.grounded_instruction),
            strings(|r| &r.label_ins_id),
            strings(|r| &r.label_label),
            ints(|r| r.label_goal_pixel[0]),
            ints(|r| r.label_goal_pixel[1]),
            floats(|r| r.start_world[0]),
            floats(|r| r.start_world[1]),
            floats(|r| r.goal_world[0]),
            floats(|r| r.goal_world[1]),
            floats(|r| r.start_facing_unit[0]),
            floats(|r| r.start_facing_unit[1]),
            floats(|r| r.start_facing_heading_degrees),
            world(0),
            world(1),
            pixel(0),
            pixel(1),
        ],
    )
}

/// Writes `rows` as a GN-Bench split (Snappy-compressed Parquet, one row group, atomically:
/// a failed write leaves no file and an existing one as it was).
///
/// # Errors
///
/// A write error, naming the file.
pub fn write_rows(path: &Path, rows: &[Row]) -> Result<()> {
    let batch = batch(rows).map_err(|e| Error::format("parquet", e.to_string()).in_file(path))?;
    let props = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .build();
    sage_io::files::write_atomic(path, |w| {
        let mut writer =
            ArrowWriter::try_new(w, batch.schema(), Some(props)).map_err(std::io::Error::other)?;
        writer.write(&batch).map_err(std::io::Error::other)?;
        writer.close().map_err(std::io::Error::other)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A 4 m × 3 m map at 0.05 m (80 × 60 pixels) away from the origin.
    fn frame() -> GnFrame {
        GnFrame {
            lower: [-1.5, 2.0],
            upper: [2.5, 5.0],
            size: [80, 60],
        }
    }

    #[test]
    fn the_research_mapping_puts_pixel_centres_on_their_pixels() {
        let f = frame();
        assert_eq!(f.cell(), [0.05, 0.05]);
        // Pixel (0, 0) is at max-x, min-y in W.
        let c = f.pixel_centre([0, 0]);
        assert!((c[0] - 2.475).abs() < 1e-12 && (c[1] - 2.025).abs() < 1e-12);
        for px in [[0, 0], [79, 59], [13, 41]] {
            let w = f.pixel_centre(px);
            let gn = f.from_world(w);
            assert_eq!(f.pixel(gn), px);
            assert!(f.pixel_offset(gn, px).iter().all(|o| *o < 1e-9));
        }
        // The translation by hand: GN = W − (lower + upper) = W − (1.0, 7.0).
        assert_eq!(f.from_world([2.0, 3.0]), [1.0, -4.0]);
        // Outside the image the pixel is clamped, and the offset says how far it is.
        let far = f.from_world([-3.0, 9.0]);
        assert_eq!(f.pixel(far), [79, 59]);
        assert!(f.pixel_offset(far, [79, 59])[0] > 1.0);
    }

    proptest! {
        #[test]
        fn world_and_gn_convert_both_ways(x in -50.0f64..50.0, y in -50.0f64..50.0) {
            let f = frame();
            let back = f.to_world(f.from_world([x, y]));
            prop_assert!((back[0] - x).abs() < 1e-12 && (back[1] - y).abs() < 1e-12);
            let fwd = f.from_world(f.to_world([x, y]));
            prop_assert!((fwd[0] - x).abs() < 1e-12 && (fwd[1] - y).abs() < 1e-12);
        }

        #[test]
        fn a_point_inside_lies_within_half_a_pixel_of_its_pixel(
            wx in -1.49f64..2.49, wy in 2.01f64..4.99,
        ) {
            let f = frame();
            let gn = f.from_world([wx, wy]);
            let px = f.pixel(gn);
            let off = f.pixel_offset(gn, px);
            prop_assert!(off[0] <= 0.5 + 1e-9 && off[1] <= 0.5 + 1e-9, "{off:?}");
            // The neighbour across x is more than half a pixel off; two over, more than one.
            let two = [px[0] + 2, px[1]];
            prop_assert!(f.pixel_offset(gn, two)[0] > 1.0);
        }

        #[test]
        fn the_translation_keeps_headings(a in -3.1f64..3.1, x in -5.0f64..5.0, y in -5.0f64..5.0) {
            // A step along heading a in W is a step along a in GN: no rotation or mirror.
            let f = frame();
            let (p, q) = ([x, y], [x + a.cos(), y + a.sin()]);
            let (gp, gq) = (f.from_world(p), f.from_world(q));
            let h = (gq[1] - gp[1]).atan2(gq[0] - gp[0]);
            prop_assert!((h - a).abs() < 1e-9);
        }
    }

    /// A row walking 1 m along +x in W from pixel (60, 30) of [`frame`], its pixels computed
    /// with GN-Bench's mapping.
    fn walk() -> Row {
        let f = frame();
        let w: Vec<[f64; 2]> = (0..=20).map(|k| f.pixel_centre([60 - k, 30])).collect();
        let gn: Vec<[f64; 2]> = w.iter().map(|p| f.from_world(*p)).collect();
        Row {
            scene: "s".into(),
            trajectory_id: "7".into(),
            instruction: "go".into(),
            grounded_instruction: "go to the sofa".into(),
            label_ins_id: "1001".into(),
            label_label: "Sofa".into(),
            label_goal_pixel: f.pixel(gn[20]),
            start_world: gn[0],
            goal_world: gn[20],
            start_facing_unit: [0.0, 1.0],
            start_facing_heading_degrees: 90.0,
            path_pixel: gn.iter().map(|p| f.pixel(*p)).collect(),
            path_world: gn,
        }
    }

    fn info() -> SceneInfo {
        SceneInfo {
            frame: frame(),
            objects: vec![("1001".into(), "sofa_1".into(), "Sofa".into())],
        }
    }

    #[test]
    fn a_row_becomes_an_episode_in_w_and_back() {
        let space = StepSizes::default();
        let e = episode(&walk(), &info(), InstructionChoice::Grounded, &space).unwrap();
        let start = frame().pixel_centre([60, 30]);
        assert!((e.start.position[0] - start[0] as f32).abs() < 1e-5);
        assert!((e.start.position[1] - start[1] as f32).abs() < 1e-5);
        assert!((e.start.yaw - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((e.path_length - 1.0).abs() < 1e-4);
        assert_eq!(e.episode_id, "s_7");
        assert_eq!(e.trajectory_id, Some(7));
        assert_eq!(e.instruction, "go to the sofa");
        assert_eq!(e.instruction_texts["plain"], "go");
        let g = e.goal.as_ref().unwrap();
        assert_eq!(
            (g.reference.as_str(), g.kind.as_str()),
            ("sofa_1", "object")
        );
        // Facing +y, the path along +x starts with right turns, then walks, then stops.
        assert_eq!(e.actions[0], sage_lang::DiscreteAction::Right);
        assert_eq!(e.actions.last(), Some(&sage_lang::DiscreteAction::Stop));
        let plain = episode(&walk(), &info(), InstructionChoice::Plain, &space).unwrap();
        assert_eq!(plain.instruction, "go");
        // And back: the row again, to the precision of f32 positions.
        let r = row(&e, &info()).unwrap();
        let w = walk();
        assert_eq!(r.path_pixel, w.path_pixel);
        assert_eq!(r.label_goal_pixel, w.label_goal_pixel);
        assert_eq!(
            (r.label_ins_id.as_str(), r.label_label.as_str()),
            ("1001", "Sofa")
        );
        assert_eq!(r.session(), w.session());
        assert!((r.start_facing_heading_degrees - 90.0).abs() < 1e-4);
        for (a, b) in r.path_world.iter().zip(&w.path_world) {
            assert!((a[0] - b[0]).abs() < 1e-5 && (a[1] - b[1]).abs() < 1e-5);
        }
        assert_eq!(
            episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap(),
            e
        );
    }

    #[test]
    fn pixels_more_than_a_pixel_off_are_rejected_and_unknown_objects_are_points() {
        let space = StepSizes::default();
        // One pixel off in x still passes (the check allows the rounding of another tool).
        let mut r = walk();
        r.path_pixel[3][0] += 1;
        assert!(episode(&r, &info(), InstructionChoice::Grounded, &space).is_ok());
        r.path_pixel[3][0] += 1;
        let (column, reason) =
            episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap_err();
        assert_eq!(column, "path_raster_pixel_x");
        assert!(
            reason.starts_with("point 3: pixel (59, 30) is 2.00 pixels"),
            "{reason}"
        );
        let mut r = walk();
        r.path_pixel[5][1] -= 2;
        let (column, _) = episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap_err();
        assert_eq!(column, "path_raster_pixel_y");
        let mut r = walk();
        r.label_ins_id = "42".into();
        let e = episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap();
        let g = e.goal.unwrap();
        assert_eq!((g.reference.as_str(), g.kind.as_str()), ("42", "pose"));
        assert_eq!(g.yaw, None);
        // A room or an area as sage3d's export names them comes back as one.
        for (id, kind) in [("room_2", "room"), ("sleeping_area_1", "area")] {
            let mut r = walk();
            r.label_ins_id = id.into();
            let e = episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap();
            let g = e.goal.unwrap();
            assert_eq!((g.reference.as_str(), g.kind.as_str()), (id, kind));
            // And goes out under the same id.
            let mut e = episode(&r, &info(), InstructionChoice::Grounded, &space).unwrap();
            assert_eq!(row(&e, &info()).unwrap().label_ins_id, id);
            // A goal heading (a turn in place) has no column: the episode is left out.
            e.goal.as_mut().unwrap().yaw = Some(1.0);
            assert!(row(&e, &info()).unwrap_err().contains("goal heading"));
        }
    }

    /// A one-row batch holding every column, with `edit` changing it first.
    fn file_with(edit: impl FnOnce(&mut Vec<(String, ArrayRef)>)) -> (tempfile::TempDir, PathBuf) {
        let r = Row {
            scene: "s".into(),
            trajectory_id: "7".into(),
            instruction: "go".into(),
            grounded_instruction: "go to the sofa".into(),
            label_ins_id: "12".into(),
            label_label: "Sofa".into(),
            label_goal_pixel: [3, 4],
            start_world: [0.0, 0.0],
            goal_world: [1.0, 0.0],
            start_facing_unit: [1.0, 0.0],
            start_facing_heading_degrees: 0.0,
            path_world: vec![[0.0, 0.0], [1.0, 0.0]],
            path_pixel: vec![[1, 1], [2, 1]],
        };
        let b = batch(&[r]).unwrap();
        let mut cols: Vec<(String, ArrayRef)> = b
            .schema()
            .fields()
            .iter()
            .zip(b.columns())
            .map(|(f, c)| (f.name().clone(), c.clone()))
            .collect();
        edit(&mut cols);
        let b = RecordBatch::try_from_iter(cols).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.parquet");
        let file = std::fs::File::create(&path).unwrap();
        let mut w = ArrowWriter::try_new(file, b.schema(), None).unwrap();
        w.write(&b).unwrap();
        w.close().unwrap();
        (dir, path)
    }

    fn set(cols: &mut [(String, ArrayRef)], name: &str, a: ArrayRef) {
        cols.iter_mut().find(|c| c.0 == name).unwrap().1 = a;
    }

    #[test]
    fn rows_round_trip_and_other_widths_read() {
        let (_d, path) = file_with(|_| {});
        let rows = read_rows(&path).unwrap();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].path_pixel, vec![[1, 1], [2, 1]]);
        assert_eq!(rows[0].trajectory_id, "7");
        // int32 pixels, float32 coordinates, a large string and an int64 id read the same.
        let (_d, path) = file_with(|c| {
            set(
                c,
                "label_goal_pixel_x",
                Arc::new(arrow_array::Int32Array::from(vec![3])),
            );
            set(
                c,
                "start_world_x",
                Arc::new(arrow_array::Float32Array::from(vec![0.0f32])),
            );
            set(
                c,
                "scene",
                Arc::new(arrow_array::LargeStringArray::from(vec!["s"])),
            );
            set(c, "trajectory_id", Arc::new(Int64Array::from(vec![7])));
        });
        assert_eq!(read_rows(&path).unwrap(), rows);
    }

    /// An edit of a test file's columns.
    type Edit = Box<dyn FnOnce(&mut Vec<(String, ArrayRef)>)>;

    #[test]
    fn bad_rows_name_the_row_and_the_column() {
        let message = |edit: Edit| {
            let (_d, path) = file_with(edit);
            read_rows(&path).unwrap_err().to_string()
        };
        let e = message(Box::new(|c| c.retain(|x| x.0 != "goal_world_y")));
        assert!(e.contains("goal_world_y: missing column"), "{e}");
        let e = message(Box::new(|c| {
            set(
                c,
                "start_world_y",
                Arc::new(Float64Array::from(vec![f64::NAN])),
            )
        }));
        assert!(
            e.contains("row 1.start_world_y: NaN: expected a finite number"),
            "{e}"
        );
        let e = message(Box::new(|c| {
            set(
                c,
                "instruction",
                Arc::new(StringArray::from(vec![None::<&str>])),
            )
        }));
        assert!(e.contains("row 1.instruction: null"), "{e}");
        let e = message(Box::new(|c| {
            let short = ListArray::from_iter_primitive::<Int64Type, _, _>([Some([Some(1)])]);
            set(c, "path_raster_pixel_y", Arc::new(short))
        }));
        assert!(
            e.contains("row 1.path_raster_pixel_y: 1 values, but path_raster_world_x has 2"),
            "{e}"
        );
        let e = message(Box::new(|c| {
            set(c, "scene", Arc::new(Float64Array::from(vec![1.0])))
        }));
        assert!(
            e.contains("row 1.scene: expected a string, found Float64"),
            "{e}"
        );
        let e = message(Box::new(|c| {
            set(
                c,
                "label_goal_pixel_y",
                Arc::new(Float64Array::from(vec![2.5])),
            )
        }));
        assert!(
            e.contains("row 1.label_goal_pixel_y: 2.5: expected a whole number"),
            "{e}"
        );
    }

    #[test]
    fn a_file_that_is_not_parquet_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let garbage = dir.path().join("g.parquet");
        std::fs::write(&garbage, b"not parquet at all").unwrap();
        let e = read_rows(&garbage).unwrap_err().to_string();
        assert!(e.contains("g.parquet: parquet:"), "{e}");
    }
}
