//! Episodes from elsewhere (the published SAGE-Bench GVLN files, R2R-VLNCE splits, GN-Bench
//! Parquet splits) as one split of a dataset folder, so that `eval` and `data render` read them
//! like a built dataset.

use crate::formats::gnbench::{self, InstructionChoice, Rejected};
use crate::formats::{ReadEpisodes, gvln, jsonl, r2r};
use crate::slices::scene_assets_slice;
use crate::{Episode, build, folder};
use glam::Vec2;
use sage_core::{Error, MAX_COORDINATE, Result, ResultExt, within_bounds};
use sage_lang::StepSizes;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where the episodes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A GVLN file; files that do not state their frame are in the S frame with this offset.
    Gvln {
        /// The file.
        file: PathBuf,
        /// The S-frame offset (δx, δy) of files without a `frame` field.
        offset: Vec2,
    },
    /// The R2R-VLNCE split `split` in folder `dir` (`{split}/{split}.json.gz` and its `_gt`).
    R2r {
        /// The folder.
        dir: PathBuf,
        /// The split's name there.
        split: String,
    },
    /// A GN-Bench split (Parquet), checked against its scenes ([`gnbench::read`]).
    GnBench {
        /// The file.
        file: PathBuf,
        /// Which instruction text the agent gets.
        instruction: InstructionChoice,
    },
}

impl Source {
    /// The file the episodes come from (for R2R-VLNCE, the split's main file).
    pub fn path(&self) -> PathBuf {
        match self {
            Source::Gvln { file, .. } | Source::GnBench { file, .. } => file.clone(),
            Source::R2r { dir, split } => r2r::paths(dir, split).0,
        }
    }
}

/// The folder of a dataset where a GN-Bench import writes its report,
/// `import_reports/{split}.json`.
pub const REPORTS_DIR: &str = "import_reports";

/// What [`import`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The episodes written.
    pub episodes: Vec<Episode>,
    /// Rows of the source that were not imported, with their reasons (GN-Bench only).
    pub rejected: Vec<Rejected>,
    /// The report file listing them (GN-Bench only).
    pub report: Option<PathBuf>,
    /// Episodes whose asset slice is the `medium` placeholder: the source gave none (the
    /// published GVLN and R2R-VLNCE files do not) and no scenes folder was given to count
    /// their scenes' objects.
    pub assets_unknown: usize,
}

/// The command, as the run record of a dataset folder it made names it.
pub const COMMAND: &str = "data import";

/// The run-record field naming the split an import is writing, removed once it has written it.
pub const PENDING: &str = "importing";

/// The splits a run record names as being written by imports that have not finished: none,
/// one (as a text, as records before several were named wrote it) or a list.
fn pending_splits(record: Option<&serde_json::Value>) -> Vec<String> {
    match record.and_then(|r| r.get(PENDING)) {
        Some(serde_json::Value::String(split)) => vec![split.clone()],
        Some(serde_json::Value::Array(splits)) => splits
            .iter()
            .filter_map(|s| s.as_str().map(String::from))
            .collect(),
        _ => Vec::new(),
    }
}

/// What the run record says of an import: the source's format, its settings and the hashes
/// (FNV-1a 64) of the files read.
fn provenance(source: &Source) -> serde_json::Value {
    // Keyed by the paths as given (relative to nothing); an absent ground-truth file of an
    // R2R split is left out, as the reader leaves it.
    let hashed = |files: &[PathBuf]| sage_io::scenes::hash_files(Path::new(""), files);
    match source {
        Source::Gvln { file, offset } => serde_json::json!({
            "format": "gvln",
            "offset": [offset.x, offset.y],
            "inputs": hashed(std::slice::from_ref(file)),
        }),
        Source::R2r { dir, split } => {
            let (main, gt) = r2r::paths(dir, split);
            serde_json::json!({
                "format": "r2r",
                "split": split,
                "inputs": hashed(&[main, gt]),
            })
        }
        Source::GnBench {
            file, instruction, ..
        } => serde_json::json!({
            "format": "gn-bench",
            "instruction": instruction,
            "inputs": hashed(std::slice::from_ref(file)),
        }),
    }
}

/// Reads `source`, writes its episodes as `dataset/episodes/{split}.jsonl` and lists the split
/// in the dataset's `splits.json` ([`folder::add_split`]). `dataset` must
/// be new, empty, or a dataset folder written by `data build` (a finished one:
/// [`folder::check`]) or `data import`; with `force`, a
/// folder of other files is written into, provided none of them would be replaced
/// ([`sage_io::run::claim_folder`]), and an existing split file is replaced.
///
/// `scenes` (a scene folder or a folder of them) is the folder the episodes' scenes are in:
/// every episode's scene must be there, and a dataset that records no scenes folder yet records
/// it, so that `eval` and `data render` find it. Episodes whose source gives no asset slice
/// (the published GVLN and R2R-VLNCE files) take their scene's there
/// ([`crate::slices::scene_assets_slice`]); without `scenes` they keep the `medium`
/// placeholder, counted in [`Imported::assets_unknown`]. A GN-Bench import checks its rows
/// against those scenes and so needs one: `scenes`, else the one the dataset records
/// ([`folder::scenes_folder`]).
///
/// A GN-Bench import also writes `dataset/import_reports/{split}.json`: the source, the
/// instruction chosen, the row of each imported episode and each rejected row with its column
/// and reason.
///
/// # Errors
///
/// A split name that would name a file outside the dataset, a GVLN offset not finite or past
/// ±[`MAX_COORDINATE`] m, an output folder holding files a
/// dataset command did not write, a build that did not finish, a bad source file (naming
/// the file and field), a GN-Bench file none of whose rows could be imported (naming the first
/// row and column), a GN-Bench import without a scenes folder, an episode whose scene is not
/// in `scenes`, a scene whose `labels.json` cannot be read for an episode's asset slice, an
/// existing split without `force`, a write error.
pub fn import(
    source: &Source,
    dataset: &Path,
    split: &str,
    scenes: Option<&Path>,
    force: bool,
) -> Result<Imported> {
    sage_io::names::check_plain("split", split).within("`split`")?;
    if let Source::Gvln { offset, .. } = source
        && !within_bounds(offset.extend(0.0))
    {
        return Err(Error::invalid(format!(
            "`offset` must be finite and within ±{MAX_COORDINATE} m, got {}, {}",
            offset.x, offset.y
        )));
    }
    let names = [
        "episodes",
        folder::SPLITS_FILE,
        sage_io::RUN_RECORD,
        REPORTS_DIR,
    ];
    let _lock = sage_io::run::claim_folder(dataset, &[COMMAND, build::COMMAND], &names, force)?;
    // A folder a build left unfinished is no dataset yet to add a split to.
    folder::check_finished(dataset)?;
    let space = StepSizes::default();
    let mut gn = None;
    let ReadEpisodes {
        mut episodes,
        mut assets_unknown,
    } = match source {
        Source::Gvln { file, offset } => gvln::read_episodes(file, *offset, &space)?,
        Source::R2r { dir, split } => r2r::read_episodes(dir, split, &space)?,
        Source::GnBench { file, instruction } => {
            let scenes = match scenes {
                Some(s) => s.to_path_buf(),
                // A new folder records none (`scenes_folder` would call it no dataset).
                None if sage_io::run::recorded_command(dataset).is_none() => {
                    return Err(Error::invalid(
                        "a GN-Bench import checks its episodes against their scenes: name the scenes folder (`scenes`)",
                    ));
                }
                None => folder::scenes_folder(dataset, None)?,
            };
            let mut read = gnbench::read(file, &scenes, *instruction, &space)?;
            if read.episodes.is_empty() {
                return Err(read.nothing_imported(file));
            }
            let episodes = std::mem::take(&mut read.episodes);
            gn = Some((file, *instruction, read));
            // Tagged from their scenes as they were read.
            ReadEpisodes {
                episodes,
                assets_unknown: Vec::new(),
            }
        }
    };
    if episodes.is_empty() {
        // An empty split is no benchmark: refused before anything is written, as a GN-Bench
        // file without an importable row is above.
        return Err(
            Error::invalid("the source holds no episode; nothing was imported")
                .in_file(source.path()),
        );
    }
    if let Some(scenes) = scenes {
        let dirs = sage_io::scenes::scene_dirs_by_name(scenes)?;
        if let Some(e) = episodes.iter().find(|e| !dirs.contains_key(&e.scene)) {
            return Err(Error::invalid(format!(
                "scene '{}' of episode {} is not among the scenes (their folders: {})",
                e.scene,
                e.episode_id,
                dirs.keys().cloned().collect::<Vec<_>>().join(", ")
            ))
            .in_file(scenes));
        }
        // The source gave no asset slice for these (the published files hold no object
        // counts); their scenes, now at hand, do. Each scene is read once.
        let mut slices: HashMap<&str, &'static str> = HashMap::new();
        for &k in &assets_unknown {
            let e = &mut episodes[k];
            let slice = match slices.get(e.scene.as_str()) {
                Some(s) => *s,
                None => {
                    let (name, dir) = dirs.get_key_value(&e.scene).expect("checked above");
                    let s = scene_assets_slice(dir).within(format!(
                        "the asset slice of episode {} (scene '{}')",
                        e.episode_id, e.scene
                    ))?;
                    slices.insert(name.as_str(), s);
                    s
                }
            };
            e.slices.assets = slice.into();
        }
        assets_unknown.clear();
    }
    let dir = dataset.join("episodes");
    let file = dir.join(format!("{split}.jsonl"));
    // A split an import was writing when it was stopped is that import's, for its rerun to
    // write again; any other is refused without `force`.
    let record_path = dataset.join(sage_io::RUN_RECORD);
    let earlier = sage_io::run::read_record(dataset);
    let mut pending = pending_splits(earlier.as_ref());
    let stopped_here = pending.iter().any(|p| p == split);
    if file.exists() && !force && !stopped_here {
        return Err(Error::invalid(
            "this split exists already; choose another `split`, or set `force` to replace it",
        )
        .in_file(&file));
    }
    // The record says which split is being written before any of it is, so a folder left by a
    // stopped import is claimed by its rerun (a new folder's record is marked unfinished). The
    // splits other stopped imports left stay named, for their own reruns.
    if !stopped_here {
        pending.push(split.to_string());
    }
    match earlier {
        None => sage_io::run::write_run_record(
            dataset,
            COMMAND,
            None,
            serde_json::json!({ "status": sage_io::run::UNFINISHED, PENDING: pending }),
        )?,
        Some(mut record) => {
            record[PENDING] = pending.clone().into();
            sage_io::files::write_json(&record_path, &record)?;
        }
    }
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    jsonl::write(&file, &episodes)?;
    folder::add_split(dataset, split, &episodes)?;
    let mut out = Imported {
        episodes,
        rejected: Vec::new(),
        report: None,
        assets_unknown: assets_unknown.len(),
    };
    if let Some((source_file, instruction, read)) = gn {
        let reports = dataset.join(REPORTS_DIR);
        std::fs::create_dir_all(&reports).map_err(|e| Error::io(&reports, e))?;
        let path = reports.join(format!("{split}.json"));
        let rows: serde_json::Map<String, serde_json::Value> = out
            .episodes
            .iter()
            .zip(&read.episode_rows)
            .map(|(e, r)| (e.episode_id.clone(), (*r).into()))
            .collect();
        sage_io::files::write_json(
            &path,
            &serde_json::json!({
                "format": "gn-bench",
                "source": folder::absolute(source_file),
                "split": split,
                "instruction": instruction,
                "rows": read.rows,
                "imported": out.episodes.len(),
                "episode_rows": rows,
                "rejected": read.rejected,
            }),
        )?;
        out.rejected = read.rejected;
        out.report = Some(path);
    }
    // Last, once every file is written: a built dataset keeps its build's record (it names the
    // scenes folder `eval` reads); either record lists every import by split, with its source
    // and the source files' hashes.
    let imported = provenance(source);
    let mut record: serde_json::Value = sage_io::files::read_json(&record_path)?;
    pending.retain(|p| p != split);
    if !record["imports"].is_object() {
        record["imports"] = serde_json::json!({});
    }
    record["imports"][split] = imported;
    // The folder a dataset records stays; one that records none learns this one.
    if let (Some(s), None) = (scenes, record.get("scenes")) {
        record["scenes"] = folder::scenes_record(dataset, s);
    }
    let first = sage_io::run::unfinished_command(dataset).as_deref() == Some(COMMAND);
    if first && pending.is_empty() {
        // The folder's first imports are all written: its record as an import writes it.
        let mut settings = serde_json::json!({ "imports": record["imports"].take() });
        if let Some(s) = record.get_mut("scenes") {
            settings["scenes"] = s.take();
        }
        sage_io::run::write_run_record(dataset, COMMAND, None, settings)?;
    } else {
        if pending.is_empty() {
            if let Some(fields) = record.as_object_mut() {
                fields.remove(PENDING);
            }
        } else {
            record[PENDING] = pending.into();
        }
        sage_io::files::write_json(&record_path, &record)?;
    }
    Ok(out)
}
