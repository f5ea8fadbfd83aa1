//! The LeRobot dataset layout, codebase version v3.0: what `lerobot`'s `LeRobotDataset` opens
//! from a local folder.
//!
//! ```text
//! meta/info.json                              written last: its presence marks a whole dataset
//! meta/stats.json                             every feature's min max mean std count q01 … q99
//! meta/tasks.parquet                          task_index, task (the pandas index)
//! meta/episodes/chunk-000/file-000.parquet    one row per episode
//! data/chunk-CCC/file-FFF.parquet             one row per frame, one row group per episode
//! ```
//!
//! One episode of the training set is one LeRobot episode; its frames are those of its walk,
//! one per action (the frame seen before the action), at [`FPS`] frames a second (one action
//! a simulated second, as the walk's action space). Frames go into the data files as PNG bytes
//! (`struct<bytes, path>`, LeRobot's image feature); depth, when rendered, as float32 metres;
//! the action as a float32 one-hot vector, its code beside it as an annotation (see [`ACTION`]).
//! Data files are cut at [`DATA_FILE_MB`] (never inside an episode) and grouped
//! [`CHUNK_SIZE`] to a chunk folder, as LeRobot's own writer does.
//!
//! Statistics are exact and independent of thread count: every value of every frame, order
//! statistics by sorting (numbers) or by counting (8-bit colour, millimetre depth), quantiles
//! by linear interpolation between order statistics (NumPy's default, [`quantile`]).

use crate::sample::{EpisodeSample, IMAGES_DIR};
use arrow_array::builder::{FixedSizeListBuilder, Float32Builder, ListBuilder, StringBuilder};
use arrow_array::{
    ArrayRef, BinaryArray, Float32Array, Int64Array, RecordBatch, StringArray, StructArray,
};
use arrow_schema::{DataType, Field, Fields, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;
use parquet::schema::types::ColumnPath;
use rayon::prelude::*;
use sage_core::{Error, Result, ResultExt, wrap_angle};
use sage_io::files::{write_atomic, write_json};
use sage_lang::DiscreteAction;
use sage_splat::{Camera, Intrinsics};
use serde_json::{Value, json};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;

/// The codebase version the files follow.
pub const CODEBASE_VERSION: &str = "v3.0";
/// Files per chunk folder (LeRobot's `chunks_size`).
pub const CHUNK_SIZE: usize = 1000;
/// A data file is closed before an episode would take it to this many MiB (LeRobot's
/// `data_files_size_in_mb`).
pub const DATA_FILE_MB: u64 = 100;
/// Frames per second: one action (one frame) per simulated second.
pub const FPS: u32 = 1;
/// The folder of the metadata.
pub const META_DIR: &str = "meta";
/// The folder of the data files.
pub const DATA_DIR: &str = "data";
/// The file written last.
pub const INFO_FILE: &str = "meta/info.json";
/// The statistics the loader normalises with.
pub const STATS_FILE: &str = "meta/stats.json";
/// The task table.
pub const TASKS_FILE: &str = "meta/tasks.parquet";
/// The quantiles of `stats.json`, by name.
pub const QUANTILES: [(&str, f64); 5] = [
    ("q01", 0.01),
    ("q10", 0.10),
    ("q50", 0.50),
    ("q90", 0.90),
    ("q99", 0.99),
];

/// The RGB frames' feature.
pub const RGB: &str = "observation.images.rgb";
/// Depth (float32 metres, `[H, W, 1]`), with `--sensors rgb,depth`.
pub const DEPTH: &str = "observation.depth";
/// The agent's pose `[x, y, z, yaw]` in W.
pub const STATE: &str = "observation.state";
/// The camera-to-world matrix (OpenCV axes), row-major 4×4.
pub const EXTRINSIC: &str = "observation.camera_extrinsic";
/// The action taken after the frame, one-hot over [`ACTION_NAMES`] (float32 `[4]`): what
/// LeRobot's policies predict and its normaliser scales. Not the code itself: the normaliser
/// casts a feature's statistics to the feature's dtype, so an int64 action's mean and standard
/// deviation would become integers (0.63 → 0) and its values be scaled by 10⁸; and a feature
/// of shape `[1]` loads as a scalar, which policies' action layers do not take.
pub const ACTION: &str = "action";
/// The elements of [`ACTION`], in code order.
pub const ACTION_NAMES: [&str; 4] = ["stop", "move_forward", "turn_left", "turn_right"];
/// The action's code ([`DiscreteAction`]: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT),
/// int64. Not under `action`, which LeRobot would take for a policy output.
pub const ACTION_ID: &str = "annotation.action_id";
/// The executed action's displacement in the agent's frame `[dx, dy, dyaw]`.
pub const NAV_DELTA: &str = "action.nav_delta";
/// The action in the preset's words. Not under `action`: LeRobot types every feature whose
/// name starts with `action` as a policy output.
pub const ACTION_TEXT: &str = "annotation.action_text";

/// What the data files are made from besides the samples.
#[derive(Debug, Clone)]
pub struct Spec {
    /// The render's split (the `splits` entry of info.json).
    pub split: String,
    /// The agent profile's name (info.json's `robot_type`).
    pub robot_type: String,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Depth frames were rendered (`{k:04}.depth.png` beside each RGB frame).
    pub depth: bool,
    /// The camera above the agent's pose, metres.
    pub eye_height: f32,
    /// The floor height (the start's z) of each episode, by episode id.
    pub floor: HashMap<String, f32>,
}

/// The data file of chunk `chunk`, file `file`, relative to the dataset.
pub fn data_file(chunk: usize, file: usize) -> String {
    format!("{DATA_DIR}/chunk-{chunk:03}/file-{file:03}.parquet")
}

/// The episodes metadata file of chunk `chunk`, file `file`, relative to the dataset.
pub fn episodes_file(chunk: usize, file: usize) -> String {
    format!("{META_DIR}/episodes/chunk-{chunk:03}/file-{file:03}.parquet")
}

/// Assigns episodes of `sizes` bytes to files in order: an episode goes to a new file when the
/// current one holds any and the two together would reach `limit` bytes (LeRobot's rule); the
/// `chunk_size`-th file of a chunk is followed by file 0 of the next chunk. Returns each
/// episode's `(chunk, file)`.
pub fn assign_files(sizes: &[u64], limit: u64, chunk_size: usize) -> Vec<(usize, usize)> {
    let (mut at, mut used, mut any) = ((0usize, 0usize), 0u64, false);
    sizes
        .iter()
        .map(|&size| {
            if any && used + size >= limit {
                at = if at.1 + 1 >= chunk_size.max(1) {
                    (at.0 + 1, 0)
                } else {
                    (at.0, at.1 + 1)
                };
                used = 0;
            }
            used += size;
            any = true;
            at
        })
        .collect()
}

/// The `q`-quantile (0–1) of `n` sorted values, `nth(k)` the k-th smallest: linear
/// interpolation between the order statistics around `(n − 1)·q` (NumPy's default method).
pub fn quantile(n: usize, nth: impl Fn(usize) -> f64, q: f64) -> f64 {
    let h = (n.saturating_sub(1)) as f64 * q;
    let lo = h.floor();
    let i = lo as usize;
    let a = nth(i);
    if i + 1 >= n || h == lo {
        return a;
    }
    a + (nth(i + 1) - a) * (h - lo)
}

/// The statistics of one channel of values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Mean.
    pub mean: f64,
    /// Population standard deviation.
    pub std: f64,
    /// The [`QUANTILES`], in order.
    pub q: [f64; 5],
}

impl Summary {
    /// The statistics of `values` (sorted in place). `None` when there are none.
    pub fn of_values(values: &mut [f64]) -> Option<Summary> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
        values.sort_by(f64::total_cmp);
        Some(Summary {
            min: values[0],
            max: values[n - 1],
            mean,
            std: var.sqrt(),
            q: QUANTILES.map(|(_, q)| quantile(n, |k| values[k], q)),
        })
    }

    /// The statistics of a histogram: `counts[b]` values equal to `value(b)`, `value`
    /// increasing. `None` when it is empty.
    pub fn of_histogram(counts: &[u64], value: impl Fn(usize) -> f64) -> Option<Summary> {
        let n: u64 = counts.iter().sum();
        if n == 0 {
            return None;
        }
        let mut upto = Vec::with_capacity(counts.len());
        let mut total = 0u64;
        for c in counts {
            total += c;
            upto.push(total);
        }
        // The k-th smallest value is in the first bin whose running count exceeds k.
        let nth = |k: usize| value(upto.partition_point(|&u| u <= k as u64));
        let used = || counts.iter().enumerate().filter(|(_, c)| **c > 0);
        let mean = used().map(|(b, &c)| c as f64 * value(b)).sum::<f64>() / n as f64;
        let var = used()
            .map(|(b, &c)| c as f64 * (value(b) - mean) * (value(b) - mean))
            .sum::<f64>()
            / n as f64;
        Some(Summary {
            min: nth(0),
            max: nth(n as usize - 1),
            mean,
            std: var.sqrt(),
            q: QUANTILES.map(|(_, q)| quantile(n as usize, nth, q)),
        })
    }
}

/// Depth in metres as stored: whole millimetres over 1000, in float32 (0 where nothing was hit).
fn depth_m(mm: u16) -> f32 {
    f32::from(mm) / 1000.0
}

/// The action's displacement in the agent's frame at `pose` (`[x, y, yaw]` in W) when it
/// ends at `achieved`: `[dx forward, dy left, dyaw counter-clockwise]`, metres and radians
/// (wrapped to (−π, π]).
pub fn nav_delta(pose: [f32; 3], achieved: [f32; 3]) -> [f32; 3] {
    let (s, c) = pose[2].sin_cos();
    let (dx, dy) = (achieved[0] - pose[0], achieved[1] - pose[1]);
    [
        c * dx + s * dy,
        -s * dx + c * dy,
        wrap_angle(achieved[2] - pose[2]),
    ]
}

/// The camera-to-world matrix of the renderer's camera (`intrinsics`) at `eye` facing `yaw`
/// (level: the walks never tilt it), in OpenCV axes (x right, y down, z forward), row-major.
fn extrinsic(intrinsics: Intrinsics, eye: glam::Vec3, yaw: f32) -> [f32; 16] {
    Camera::from_yaw_pitch(intrinsics, eye, yaw, 0.0)
        .c2w()
        .transpose()
        .to_cols_array()
}

/// One episode read back from its frames: the columns of its rows.
struct Loaded {
    png: Vec<Vec<u8>>,
    /// Per channel, how many pixels have each value.
    colours: Box<[[u64; 256]; 3]>,
    depth_mm: Vec<u16>,
    state: Vec<[f32; 4]>,
    extrinsic: Vec<[f32; 16]>,
    action: Vec<DiscreteAction>,
    nav: Vec<[f32; 3]>,
}

/// Reads `episode`'s frames (checking their size) and computes its per-frame values.
fn load(images: &Path, episode: &EpisodeSample, spec: &Spec) -> Result<Loaded> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let z = spec.floor.get(&episode.episode_id).copied().unwrap_or(0.0);
    let intrinsics = Intrinsics::from_hfov(spec.width, spec.height, spec.hfov_deg)?;
    let mut out = Loaded {
        png: Vec::with_capacity(episode.files.len()),
        colours: Box::new([[0; 256]; 3]),
        depth_mm: Vec::new(),
        state: Vec::new(),
        extrinsic: Vec::new(),
        action: Vec::new(),
        nav: Vec::new(),
    };
    for (files, step) in episode.files.iter().zip(&episode.steps) {
        let path = images.join(&files[0]);
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let (rgb, fw, fh) = crate::preview::decode_rgb(&bytes, &path)?;
        if (fw, fh) != (w, h) {
            return Err(Error::invalid(format!(
                "the frame is {fw}×{fh} pixels, the render's size is {w}×{h}"
            ))
            .in_file(&path));
        }
        for px in rgb.chunks_exact(3) {
            for (c, &v) in px.iter().enumerate() {
                out.colours[c][usize::from(v)] += 1;
            }
        }
        out.png.push(bytes);
        if spec.depth {
            let path = images.join(files.get(1).ok_or_else(|| {
                Error::invalid(format!("episode {}: no depth frame", episode.episode_id))
            })?);
            out.depth_mm.extend(read_depth_mm(&path, w, h)?);
        }
        let [x, y, yaw] = step.pose;
        out.state.push([x, y, z, yaw]);
        out.extrinsic.push(extrinsic(
            intrinsics,
            glam::Vec3::new(x, y, z + spec.eye_height),
            yaw,
        ));
        out.action.push(action_code(&step.action));
        out.nav.push(nav_delta(step.pose, step.achieved));
    }
    Ok(out)
}

/// The one-hot row of `action` ([`ACTION`]).
fn one_hot(action: DiscreteAction) -> [f32; 4] {
    let mut row = [0.0; 4];
    row[usize::from(u8::from(action))] = 1.0;
    row
}

/// The code of `action` ([`ACTION_ID`]).
fn code(action: DiscreteAction) -> i64 {
    i64::from(u8::from(action))
}

/// The dataset code of a published action name.
fn action_code(name: &str) -> DiscreteAction {
    match name {
        "MOVE_FORWARD" => DiscreteAction::Forward,
        "TURN_LEFT" => DiscreteAction::Left,
        "TURN_RIGHT" => DiscreteAction::Right,
        _ => DiscreteAction::Stop,
    }
}

/// A 16-bit grey PNG of `w × h` millimetres.
fn read_depth_mm(path: &Path, w: usize, h: usize) -> Result<Vec<u16>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let bad = |why: String| Error::invalid(format!("cannot decode the depth frame: {why}"));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(e.to_string()).in_file(path))?;
    let info = reader.info();
    if (info.width as usize, info.height as usize) != (w, h)
        || info.color_type != png::ColorType::Grayscale
        || info.bit_depth != png::BitDepth::Sixteen
    {
        return Err(bad(format!(
            "expected a {w}×{h} 16-bit grey PNG, found {}×{} {:?} {:?}",
            info.width, info.height, info.color_type, info.bit_depth
        ))
        .in_file(path));
    }
    let mut buf = vec![0; w * h * 2];
    reader
        .next_frame(&mut buf)
        .map_err(|e| bad(e.to_string()).in_file(path))?;
    Ok(buf
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect())
}

/// A feature of info.json.
struct Feature {
    name: &'static str,
    dtype: &'static str,
    shape: Vec<usize>,
    names: Value,
}

/// The features of a dataset with `spec`, in column order.
fn features(spec: &Spec) -> Vec<Feature> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let f = |name, dtype, shape: &[usize], names| Feature {
        name,
        dtype,
        shape: shape.to_vec(),
        names,
    };
    let hwc = json!(["height", "width", "channel"]);
    let mut out = vec![f(RGB, "image", &[h, w, 3], hwc.clone())];
    if spec.depth {
        out.push(f(DEPTH, "float32", &[h, w, 1], hwc));
    }
    out.extend([
        f(STATE, "float32", &[4], json!(["x", "y", "z", "yaw"])),
        f(EXTRINSIC, "float32", &[4, 4], Value::Null),
        f(ACTION, "float32", &[4], json!(ACTION_NAMES)),
        f(NAV_DELTA, "float32", &[3], json!(["dx", "dy", "dyaw"])),
        f(ACTION_ID, "int64", &[1], Value::Null),
        f(ACTION_TEXT, "string", &[1], Value::Null),
        f("timestamp", "float32", &[1], Value::Null),
        f("frame_index", "int64", &[1], Value::Null),
        f("episode_index", "int64", &[1], Value::Null),
        f("index", "int64", &[1], Value::Null),
        f("task_index", "int64", &[1], Value::Null),
    ]);
    out
}

/// A nullable list field named `item` (Arrow's and pyarrow's default) of `inner`.
fn item(inner: DataType) -> Arc<Field> {
    Arc::new(Field::new("item", inner, true))
}

/// The Arrow type of a feature: a scalar for shape `[1]`, a fixed-size list for `[n]`,
/// nested lists for more dimensions (how `datasets` stores `Array2D`/`Array3D`), LeRobot's
/// image struct for images.
fn arrow_type(f: &Feature) -> DataType {
    let scalar = match f.dtype {
        "float32" => DataType::Float32,
        "int64" => DataType::Int64,
        "string" => DataType::Utf8,
        _ => {
            return DataType::Struct(Fields::from(vec![
                Field::new("bytes", DataType::Binary, true),
                Field::new("path", DataType::Utf8, true),
            ]));
        }
    };
    match f.shape.as_slice() {
        [1] => scalar,
        [n] => DataType::FixedSizeList(item(scalar), *n as i32),
        dims => dims.iter().fold(scalar, |t, _| DataType::List(item(t))),
    }
}

/// The data files' schema.
fn schema(features: &[Feature]) -> Arc<Schema> {
    Arc::new(Schema::new(
        features
            .iter()
            .map(|f| Field::new(f.name, arrow_type(f), true))
            .collect::<Vec<_>>(),
    ))
}

/// Snappy, no size limit on row groups (each episode is flushed as one), and no dictionary
/// for the image bytes (they never repeat).
fn properties() -> WriterProperties {
    WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_max_row_group_row_count(None)
        .set_max_row_group_bytes(None)
        .set_column_dictionary_enabled(
            ColumnPath::new(vec![RGB.to_string(), "bytes".to_string()]),
            false,
        )
        .set_column_dictionary_enabled(
            ColumnPath::new(vec![
                DEPTH.to_string(),
                "item".into(),
                "item".into(),
                "item".into(),
            ]),
            false,
        )
        .build()
}

fn fixed_list<const N: usize>(rows: &[[f32; N]]) -> ArrayRef {
    let mut b = FixedSizeListBuilder::new(Float32Builder::new(), N as i32);
    for r in rows {
        b.values().append_slice(r);
        b.append(true);
    }
    Arc::new(b.finish())
}

/// One episode's rows as a record batch of `schema`.
fn batch(
    schema: &Arc<Schema>,
    e: &Loaded,
    episode: &EpisodeSample,
    spec: &Spec,
    episode_index: i64,
    first_index: i64,
    task_index: i64,
) -> Result<RecordBatch> {
    let n = e.png.len();
    let (w, h) = (spec.width as usize, spec.height as usize);
    let frames = 0..n as i64;
    let image = StructArray::new(
        Fields::from(vec![
            Field::new("bytes", DataType::Binary, true),
            Field::new("path", DataType::Utf8, true),
        ]),
        vec![
            Arc::new(BinaryArray::from_iter_values(e.png.iter())),
            Arc::new(StringArray::from_iter_values(
                frames.clone().map(|k| format!("frame-{k:06}.png")),
            )),
        ],
        None,
    );
    let mut columns: Vec<ArrayRef> = vec![Arc::new(image)];
    if spec.depth {
        let mut b = ListBuilder::new(ListBuilder::new(ListBuilder::new(Float32Builder::new())));
        for frame in e.depth_mm.chunks_exact(w * h) {
            for row in frame.chunks_exact(w) {
                for &mm in row {
                    b.values().values().values().append_value(depth_m(mm));
                    b.values().values().append(true);
                }
                b.values().append(true);
            }
            b.append(true);
        }
        columns.push(Arc::new(b.finish()));
    }
    let mut extr = ListBuilder::new(ListBuilder::new(Float32Builder::new()));
    for m in &e.extrinsic {
        for row in m.chunks_exact(4) {
            extr.values().values().append_slice(row);
            extr.values().append(true);
        }
        extr.append(true);
    }
    let mut text = StringBuilder::new();
    for words in &episode.words {
        text.append_value(words);
    }
    columns.extend([
        fixed_list(&e.state),
        Arc::new(extr.finish()) as ArrayRef,
        fixed_list(&e.action.iter().copied().map(one_hot).collect::<Vec<_>>()),
        fixed_list(&e.nav),
        Arc::new(Int64Array::from_iter_values(
            e.action.iter().copied().map(code),
        )),
        Arc::new(text.finish()),
        Arc::new(Float32Array::from_iter_values(
            frames.clone().map(|k| k as f32 / FPS as f32),
        )),
        Arc::new(Int64Array::from_iter_values(frames.clone())),
        Arc::new(Int64Array::from_iter_values(
            frames.clone().map(|_| episode_index),
        )),
        Arc::new(Int64Array::from_iter_values(
            frames.clone().map(|k| first_index + k),
        )),
        Arc::new(Int64Array::from_iter_values(frames.map(|_| task_index))),
    ]);
    RecordBatch::try_new(schema.clone(), columns)
        .map_err(|err| Error::invalid(format!("episode {}: {err}", episode.episode_id)))
}

/// Every value of the numeric features, per element, in frame order; the colour and depth
/// histograms.
struct Collected {
    /// Per feature name, per element (row-major), the values of every frame.
    values: BTreeMap<&'static str, Vec<Vec<f64>>>,
    colours: Box<[[u64; 256]; 3]>,
    depth: Vec<u64>,
    frames: usize,
}

impl Collected {
    fn new(depth: bool) -> Collected {
        Collected {
            values: BTreeMap::new(),
            colours: Box::new([[0; 256]; 3]),
            depth: if depth { vec![0; 1 << 16] } else { Vec::new() },
            frames: 0,
        }
    }

    fn push(&mut self, name: &'static str, row: &[f32]) {
        let cols = self
            .values
            .entry(name)
            .or_insert_with(|| vec![Vec::new(); row.len()]);
        for (c, &v) in cols.iter_mut().zip(row) {
            c.push(f64::from(v));
        }
    }

    fn push_int(&mut self, name: &'static str, v: i64) {
        self.values.entry(name).or_insert_with(|| vec![Vec::new()])[0].push(v as f64);
    }

    /// Adds an episode's rows (`first_index` the global index of its first frame).
    fn add(&mut self, e: &Loaded, episode_index: i64, first_index: i64, task_index: i64) {
        for c in 0..3 {
            for (a, b) in self.colours[c].iter_mut().zip(&e.colours[c]) {
                *a += b;
            }
        }
        for &mm in &e.depth_mm {
            self.depth[usize::from(mm)] += 1;
        }
        for k in 0..e.png.len() {
            self.push(STATE, &e.state[k]);
            self.push(EXTRINSIC, &e.extrinsic[k]);
            self.push(ACTION, &one_hot(e.action[k]));
            self.push(NAV_DELTA, &e.nav[k]);
            self.push_int(ACTION_ID, code(e.action[k]));
            self.push("timestamp", &[k as f32 / FPS as f32]);
            self.push_int("frame_index", k as i64);
            self.push_int("episode_index", episode_index);
            self.push_int("index", first_index + k as i64);
            self.push_int("task_index", task_index);
        }
        self.frames += e.png.len();
    }

    /// stats.json: per feature, each statistic in the feature's shape (images and depth per
    /// channel, `[C][1][1]`, colours scaled to [0, 1]); `count` the frames. Strings have none.
    fn stats(mut self, features: &[Feature]) -> Value {
        let mut out = serde_json::Map::new();
        for f in features {
            let (summaries, shape): (Vec<Summary>, Vec<usize>) = match f.name {
                RGB => (
                    self.colours
                        .iter()
                        .filter_map(|h| Summary::of_histogram(h, |b| b as f64 / 255.0))
                        .collect(),
                    vec![3, 1, 1],
                ),
                DEPTH => (
                    Summary::of_histogram(&self.depth, |mm| f64::from(depth_m(mm as u16)))
                        .into_iter()
                        .collect(),
                    vec![1, 1, 1],
                ),
                name => match self.values.get_mut(name) {
                    Some(cols) => (
                        cols.iter_mut()
                            .filter_map(|c| Summary::of_values(c))
                            .collect(),
                        f.shape.clone(),
                    ),
                    None => continue,
                },
            };
            if summaries.is_empty() {
                continue;
            }
            let mut stat = serde_json::Map::new();
            let mut put = |name: &str, pick: &dyn Fn(&Summary) -> f64| {
                let flat: Vec<f64> = summaries.iter().map(pick).collect();
                stat.insert(name.into(), shaped(&flat, &shape));
            };
            put("min", &|s| s.min);
            put("max", &|s| s.max);
            put("mean", &|s| s.mean);
            put("std", &|s| s.std);
            for (k, (name, _)) in QUANTILES.iter().enumerate() {
                put(name, &|s| s.q[k]);
            }
            stat.insert("count".into(), json!([self.frames]));
            out.insert(f.name.into(), Value::Object(stat));
        }
        Value::Object(out)
    }
}

/// `flat` (row-major) nested into `shape`; a shape `[1]` is a list of one.
fn shaped(flat: &[f64], shape: &[usize]) -> Value {
    match shape {
        [] | [_] => json!(flat),
        [_, rest @ ..] => {
            let inner: usize = rest.iter().product();
            Value::Array(flat.chunks(inner.max(1)).map(|c| shaped(c, rest)).collect())
        }
    }
}

/// Writes `table` to `path` (relative to `out`) as one Parquet file, one row group per batch.
fn write_parquet(
    out: &Path,
    path: &str,
    schema: &Arc<Schema>,
    batches: impl FnOnce(&mut dyn FnMut(&RecordBatch) -> Result<()>) -> Result<()>,
) -> Result<()> {
    let full = out.join(path);
    if let Some(dir) = full.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let mut failure = None;
    write_atomic(&full, |w| {
        let mut writer = ArrowWriter::try_new(&mut *w, schema.clone(), Some(properties()))
            .map_err(std::io::Error::other)?;
        let mut add = |b: &RecordBatch| -> Result<()> {
            writer
                .write(b)
                .and_then(|_| writer.flush())
                .map_err(|e| Error::invalid(format!("Parquet: {e}")).in_file(&full))
        };
        if let Err(e) = batches(&mut add) {
            let msg = e.to_string();
            failure = Some(e);
            return Err(std::io::Error::other(msg));
        }
        writer.close().map_err(std::io::Error::other)?;
        Ok(())
    })
    .map_err(|e| failure.take().unwrap_or(e))
}

/// Writes the LeRobot dataset of `episodes` (in order: episode `i` is `episodes[i]`) into
/// `out`, reading the frames under `out/images`: the data files, the episodes metadata, the
/// task table, the statistics and info.json last (after the `data` and `meta` folders of an
/// earlier attempt are removed, so a dataset cut short never has an info.json). Returns the
/// files written (relative, info.json last).
///
/// # Errors
///
/// A frame that is missing, of another size or not a PNG (naming it), a write error.
pub fn write(out: &Path, episodes: &[EpisodeSample], spec: &Spec) -> Result<Vec<String>> {
    for dir in [META_DIR, DATA_DIR] {
        let p = out.join(dir);
        if p.exists() {
            std::fs::remove_dir_all(&p).map_err(|e| Error::io(&p, e))?;
        }
    }
    let images = out.join(IMAGES_DIR);
    let features = features(spec);
    let schema = schema(&features);
    // Tasks by first appearance: identical instructions share one.
    let mut tasks: Vec<&str> = Vec::new();
    let mut task_of: HashMap<&str, i64> = HashMap::new();
    let task_index: Vec<i64> = episodes
        .iter()
        .map(|e| {
            *task_of.entry(e.instruction.as_str()).or_insert_with(|| {
                tasks.push(e.instruction.as_str());
                tasks.len() as i64 - 1
            })
        })
        .collect();
    // Which file each episode goes to, from the bytes it will take (its PNGs, its depth).
    let per_frame_depth = if spec.depth {
        4 * u64::from(spec.width) * u64::from(spec.height)
    } else {
        0
    };
    let sizes = episodes
        .iter()
        .map(|e| {
            let mut bytes = 0;
            for f in &e.files {
                let p = images.join(&f[0]);
                bytes += std::fs::metadata(&p)
                    .map_err(|err| Error::io(&p, err))?
                    .len();
                bytes += per_frame_depth + 128;
            }
            Ok(bytes)
        })
        .collect::<Result<Vec<u64>>>()?;
    let placed = assign_files(&sizes, DATA_FILE_MB << 20, CHUNK_SIZE);
    let mut first_index = Vec::with_capacity(episodes.len());
    let mut total = 0i64;
    for e in episodes {
        first_index.push(total);
        total += e.steps.len() as i64;
    }
    let mut collected = Collected::new(spec.depth);
    let mut written = Vec::new();
    let mut start = 0;
    while start < episodes.len() {
        let at = placed[start];
        let end = start + placed[start..].iter().take_while(|p| **p == at).count();
        let loaded = episodes[start..end]
            .par_iter()
            .map(|e| load(&images, e, spec).within(format!("episode {}", e.episode_id)))
            .collect::<Result<Vec<_>>>()?;
        let path = data_file(at.0, at.1);
        write_parquet(out, &path, &schema, |add| {
            for (k, e) in loaded.iter().enumerate() {
                let i = start + k;
                add(&batch(
                    &schema,
                    e,
                    &episodes[i],
                    spec,
                    i as i64,
                    first_index[i],
                    task_index[i],
                )?)?;
            }
            Ok(())
        })?;
        for (k, e) in loaded.iter().enumerate() {
            let i = start + k;
            collected.add(e, i as i64, first_index[i], task_index[i]);
        }
        written.push(path);
        start = end;
    }
    written.push(write_episodes(out, episodes, &placed, &first_index)?);
    written.push(write_tasks(out, &tasks)?);
    write_json(&out.join(STATS_FILE), &collected.stats(&features))?;
    written.push(STATS_FILE.into());
    let info = json!({
        "codebase_version": CODEBASE_VERSION,
        "robot_type": spec.robot_type,
        "total_episodes": episodes.len(),
        "total_frames": total,
        "total_tasks": tasks.len(),
        "chunks_size": CHUNK_SIZE,
        "data_files_size_in_mb": DATA_FILE_MB,
        "video_files_size_in_mb": 200,
        "fps": FPS,
        "splits": { spec.split.as_str(): format!("0:{}", episodes.len()) },
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": Value::Null,
        "features": features.iter().map(|f| (f.name.to_string(), json!({
            "dtype": f.dtype,
            "shape": f.shape,
            "names": f.names,
        }))).collect::<serde_json::Map<_, _>>(),
    });
    write_json(&out.join(INFO_FILE), &info)?;
    written.push(INFO_FILE.into());
    Ok(written)
}

/// `meta/episodes/chunk-000/file-000.parquet`: per episode its index, task, length, data
/// file and global index range, and where it came from (scene, episode id, route, verdict).
fn write_episodes(
    out: &Path,
    episodes: &[EpisodeSample],
    placed: &[(usize, usize)],
    first_index: &[i64],
) -> Result<String> {
    let int = |name: &str| Field::new(name, DataType::Int64, true);
    let text = |name: &str| Field::new(name, DataType::Utf8, true);
    let schema = Arc::new(Schema::new(vec![
        int("episode_index"),
        Field::new("tasks", DataType::List(item(DataType::Utf8)), true),
        int("length"),
        int("data/chunk_index"),
        int("data/file_index"),
        int("dataset_from_index"),
        int("dataset_to_index"),
        int("meta/episodes/chunk_index"),
        int("meta/episodes/file_index"),
        text("scene"),
        text("episode_id"),
        text("route"),
        text("verdict"),
    ]));
    let ints = |f: &dyn Fn(usize) -> i64| -> ArrayRef {
        Arc::new(Int64Array::from_iter_values((0..episodes.len()).map(f)))
    };
    let texts = |f: &dyn Fn(&EpisodeSample) -> String| -> ArrayRef {
        Arc::new(StringArray::from_iter_values(episodes.iter().map(f)))
    };
    let mut tasks = ListBuilder::new(StringBuilder::new());
    for e in episodes {
        tasks.values().append_value(&e.instruction);
        tasks.append(true);
    }
    let len = |i: usize| episodes[i].steps.len() as i64;
    let columns: Vec<ArrayRef> = vec![
        ints(&|i| i as i64),
        Arc::new(tasks.finish()),
        ints(&len),
        ints(&|i| placed[i].0 as i64),
        ints(&|i| placed[i].1 as i64),
        ints(&|i| first_index[i]),
        ints(&|i| first_index[i] + len(i)),
        ints(&|_| 0),
        ints(&|_| 0),
        texts(&|e| e.scene.clone()),
        texts(&|e| e.episode_id.clone()),
        texts(&|e| e.route.clone()),
        texts(&|e| {
            serde_json::to_value(e.verdict)
                .ok()
                .and_then(|v| v.as_str().map(String::from))
                .unwrap_or_default()
        }),
    ];
    let path = episodes_file(0, 0);
    let batch = RecordBatch::try_new(schema.clone(), columns)
        .map_err(|e| Error::invalid(format!("episodes metadata: {e}")))?;
    write_parquet(out, &path, &schema, |add| add(&batch))?;
    Ok(path)
}

/// `meta/tasks.parquet`: `task_index` and `task`, in task order, with the pandas metadata
/// that makes `task` the index (without it LeRobot reads a task as its number).
fn write_tasks(out: &Path, tasks: &[&str]) -> Result<String> {
    let pandas = json!({
        "index_columns": ["task"],
        "column_indexes": [{
            "name": null, "field_name": null, "pandas_type": "unicode",
            "numpy_type": "object", "metadata": {"encoding": "UTF-8"},
        }],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": null},
            {"name": "task", "field_name": "task", "pandas_type": "unicode",
             "numpy_type": "object", "metadata": null},
        ],
        "creator": {"library": "sage3d", "version": env!("CARGO_PKG_VERSION")},
        "pandas_version": "2.2.3",
    });
    let schema = Arc::new(Schema::new_with_metadata(
        vec![
            Field::new("task_index", DataType::Int64, true),
            Field::new("task", DataType::Utf8, true),
        ],
        HashMap::from([("pandas".to_string(), pandas.to_string())]),
    ));
    let batch = RecordBatch::try_new(
        schema.clone(),
        vec![
            Arc::new(Int64Array::from_iter_values(0..tasks.len() as i64)),
            Arc::new(StringArray::from_iter_values(tasks.iter())),
        ],
    )
    .map_err(|e| Error::invalid(format!("task table: {e}")))?;
    write_parquet(out, TASKS_FILE, &schema, |add| add(&batch))?;
    Ok(TASKS_FILE.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_a_sort_and_numpys_linear_rule() {
        // Brute force: the same rule on a sorted copy, for many lengths and quantiles.
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % 1000) as f64 / 10.0
        };
        for n in [1usize, 2, 3, 10, 99, 100, 101, 1000] {
            let values: Vec<f64> = (0..n).map(|_| next()).collect();
            let mut sorted = values.clone();
            sorted.sort_by(f64::total_cmp);
            let mut work = values.clone();
            let s = Summary::of_values(&mut work).unwrap();
            for (k, (_, q)) in QUANTILES.iter().enumerate() {
                let h = (n - 1) as f64 * q;
                let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
                let want = sorted[lo] + (sorted[hi] - sorted[lo]) * (h - h.floor());
                assert!((s.q[k] - want).abs() < 1e-12, "n {n} q {q}");
            }
            assert_eq!((s.min, s.max), (sorted[0], sorted[n - 1]));
            // The same values as a histogram (bins of 0.1) give the same statistics.
            let mut counts = vec![0u64; 1000];
            for v in &values {
                counts[(v * 10.0).round() as usize] += 1;
            }
            let h = Summary::of_histogram(&counts, |b| b as f64 / 10.0).unwrap();
            assert_eq!((h.min, h.max), (s.min, s.max));
            for k in 0..5 {
                assert!((h.q[k] - s.q[k]).abs() < 1e-9, "n {n}: {h:?} vs {s:?}");
            }
            assert!((h.mean - s.mean).abs() < 1e-9 && (h.std - s.std).abs() < 1e-9);
        }
        // Hand-made: 1..=5, q50 = 3, q10 at 0.4 between 1 and 2, population std √2.
        let s = Summary::of_values(&mut [5.0, 1.0, 4.0, 2.0, 3.0]).unwrap();
        assert_eq!(s.q[2], 3.0);
        assert!((s.q[1] - 1.4).abs() < 1e-12);
        assert!((s.std - 2f64.sqrt()).abs() < 1e-12);
        assert!(Summary::of_values(&mut []).is_none());
        assert!(Summary::of_histogram(&[0, 0], |b| b as f64).is_none());
    }

    #[test]
    fn files_roll_over_at_the_size_limit_and_chunks_at_the_file_count() {
        // An episode never spans two files; a file is closed before one would reach the limit.
        assert_eq!(
            assign_files(&[40, 50, 20, 100, 5], 100, 1000),
            [(0, 0), (0, 0), (0, 1), (0, 2), (0, 3)]
        );
        // One episode larger than the limit still gets a file of its own.
        assert_eq!(assign_files(&[300], 100, 1000), [(0, 0)]);
        // Three files a chunk: the fourth file is file 0 of chunk 1.
        let placed = assign_files(&[60; 5], 100, 3);
        assert_eq!(placed, [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1)]);
        assert_eq!(data_file(1, 0), "data/chunk-001/file-000.parquet");
        assert_eq!(
            episodes_file(0, 12),
            "meta/episodes/chunk-000/file-012.parquet"
        );
    }

    #[test]
    fn nav_delta_is_the_step_in_the_agents_frame() {
        let yaw = std::f32::consts::FRAC_PI_2;
        // Facing +Y, a move to +Y is forward; to -X is left.
        let d = nav_delta([1.0, 2.0, yaw], [1.0, 2.35, yaw]);
        assert!((d[0] - 0.35).abs() < 1e-6 && d[1].abs() < 1e-6 && d[2] == 0.0);
        let d = nav_delta([1.0, 2.0, yaw], [0.5, 2.0, yaw]);
        assert!(d[0].abs() < 1e-6 && (d[1] - 0.5).abs() < 1e-6);
        // A left turn across ±π is a small positive turn.
        let d = nav_delta([0.0, 0.0, 3.0], [0.0, 0.0, -3.0]);
        assert!((d[2] - (std::f32::consts::TAU - 6.0)).abs() < 1e-5);
    }

    #[test]
    fn the_extrinsic_is_the_renderers_camera() {
        let intrinsics = Intrinsics::from_hfov(64, 48, 90.0).unwrap();
        let m = extrinsic(intrinsics, glam::Vec3::new(1.0, 2.0, 1.2), 0.0);
        // Row-major: translation in the last column; facing +X, the camera's z (forward)
        // is W's +X, its x (right) W's −Y, its y (down) W's −Z.
        assert_eq!([m[3], m[7], m[11], m[15]], [1.0, 2.0, 1.2, 1.0]);
        let col = |c: usize| [m[c], m[4 + c], m[8 + c]];
        let near = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(near(col(2), [1.0, 0.0, 0.0]), "{m:?}");
        assert!(near(col(0), [0.0, -1.0, 0.0]), "{m:?}");
        assert!(near(col(1), [0.0, 0.0, -1.0]), "{m:?}");
    }

    #[test]
    fn policy_features_are_float_vectors() {
        // LeRobot casts statistics to a feature's dtype and loads shape [1] as a scalar: what
        // its policies take (names under `observation` and `action`) must be float vectors.
        let spec = Spec {
            split: "train".into(),
            robot_type: "wheeled".into(),
            width: 8,
            height: 6,
            hfov_deg: 90.0,
            depth: true,
            eye_height: 1.2,
            floor: HashMap::new(),
        };
        for f in features(&spec) {
            if f.name.starts_with("observation") || f.name.starts_with("action") {
                assert!(matches!(f.dtype, "float32" | "image"), "{}", f.name);
                assert_ne!(f.shape, [1], "{}", f.name);
            }
        }
        for (k, a) in [
            DiscreteAction::Stop,
            DiscreteAction::Forward,
            DiscreteAction::Left,
            DiscreteAction::Right,
        ]
        .into_iter()
        .enumerate()
        {
            let row = one_hot(a);
            assert_eq!(code(a), k as i64);
            assert!(row.iter().enumerate().all(|(i, &v)| v == f32::from(i == k)));
        }
    }

    #[test]
    fn stats_are_shaped_like_their_feature() {
        assert_eq!(shaped(&[1.0], &[1]), json!([1.0]));
        assert_eq!(
            shaped(&[1.0, 2.0, 3.0], &[3, 1, 1]),
            json!([[[1.0]], [[2.0]], [[3.0]]])
        );
        assert_eq!(
            shaped(&[1.0, 2.0, 3.0, 4.0], &[2, 2]),
            json!([[1.0, 2.0], [3.0, 4.0]])
        );
    }
}
