//! The output formats: NaVILA's annotation parts, WebDataset tar shards and a plain folder
//! tree, each written from the episode samples with atomic renames (the LeRobot layout has
//! its own module, [`crate::lerobot`]).

use crate::preset::{ActionPreset, action_from_name};
use crate::sample::{EpisodeSample, IMAGES_DIR};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use sage_core::{Error, Result};
use sage_io::files::{write_atomic, write_json};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The layout of a training set (`format` in the settings; named apart from
/// `sage_scene::splats::Format`, a 3DGS file format).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Layout {
    /// NaVILA's training format: `annotations_part_NNN.json` (one sample per step with the
    /// frame history), `dataset_info.json`, frames under `images/`.
    #[default]
    Navila,
    /// WebDataset tar shards `shards/{split}-NNNNNN.tar`, one sample per episode.
    Webdataset,
    /// The frames under `images/` and `episodes.jsonl`, for inspection.
    Frames,
    /// A LeRobot dataset, codebase version v3.0 ([`crate::lerobot`]): frames, poses and
    /// actions in Parquet files, with the metadata and statistics `LeRobotDataset` loads.
    Lerobot,
}

impl Layout {
    /// Every format's name.
    pub const NAMES: [&'static str; 4] = ["navila", "webdataset", "frames", "lerobot"];

    /// True when the format's files hold the frames themselves (WebDataset shards, LeRobot
    /// Parquet files): the frames folder is removed once they are written.
    pub fn packs_frames(self) -> bool {
        matches!(self, Layout::Webdataset | Layout::Lerobot)
    }

    /// The format's name.
    pub fn as_str(self) -> &'static str {
        match self {
            Layout::Navila => "navila",
            Layout::Webdataset => "webdataset",
            Layout::Frames => "frames",
            Layout::Lerobot => "lerobot",
        }
    }
}

impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Layout {
    type Err = Error;

    fn from_str(s: &str) -> Result<Layout> {
        match s.trim().to_ascii_lowercase().as_str() {
            "navila" => Ok(Layout::Navila),
            "webdataset" | "wds" => Ok(Layout::Webdataset),
            "frames" => Ok(Layout::Frames),
            "lerobot" => Ok(Layout::Lerobot),
            other => Err(Error::invalid(format!(
                "unknown format '{other}' (known: {})",
                Layout::NAMES.join(", ")
            ))),
        }
    }
}

/// The name of NaVILA part `k`.
pub fn navila_part_name(k: usize) -> String {
    format!("annotations_part_{k:03}.json")
}

/// The index file of a `frames` output.
pub const EPISODES_FILE: &str = "episodes.jsonl";

/// The folder of the WebDataset shards.
pub const SHARDS_DIR: &str = "shards";

/// One NaVILA training sample: the frames up to a step and the action taken there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavilaSample {
    /// `{episode_id}-{step}`.
    pub video_id: String,
    /// The instruction.
    pub q: String,
    /// `The next action is move forward 0.35 meter.` (or `… 35 cm.` in NaVILA's words).
    pub a: String,
    /// The RGB frames from the start to this step, relative to the images folder.
    pub frames: Vec<String>,
}

/// The NaVILA samples of `episodes` (one per step), shuffled with `seed` as the published
/// pipeline shuffles its samples before cutting them into parts.
pub fn navila_samples(
    episodes: &[EpisodeSample],
    preset: &ActionPreset,
    seed: u64,
) -> Vec<NavilaSample> {
    let mut samples: Vec<NavilaSample> = episodes
        .iter()
        .flat_map(|e| {
            let rgb: Vec<String> = e.files.iter().map(|f| f[0].clone()).collect();
            e.actions
                .iter()
                .enumerate()
                .map(move |(k, a)| NavilaSample {
                    video_id: format!("{}-{k}", e.episode_id),
                    q: e.instruction.clone(),
                    a: preset.answer(action_from_name(a)),
                    frames: rgb[..=k].to_vec(),
                })
        })
        .collect();
    samples.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    samples
}

/// Writes the NaVILA parts and `dataset_info.json`; returns the files written (relative).
///
/// # Errors
///
/// A write error, naming the file.
pub fn write_navila(
    out: &Path,
    episodes: &[EpisodeSample],
    preset: &ActionPreset,
    shard_size: usize,
    seed: u64,
    name: &str,
) -> Result<Vec<String>> {
    let samples = navila_samples(episodes, preset, seed);
    let mut parts = Vec::new();
    for (k, chunk) in samples.chunks(shard_size.max(1)).enumerate() {
        let part = navila_part_name(k);
        write_json(&out.join(&part), &chunk)?;
        parts.push(part);
    }
    let info = serde_json::json!({
        "dataset_name": name,
        "total_samples": samples.len(),
        "num_parts": parts.len(),
        "samples_per_part": shard_size,
        "part_files": parts,
        "data_format": {
            "move_distance": preset.distance_words(),
            "turn_angle": preset.angle_words(),
            "action_format": "The next action is {action}.",
        },
        "conversion_params": {
            "images_dir": IMAGES_DIR,
            "preset": preset.name,
            "max_actions": preset.max_actions,
            "answers": preset.answers,
            "seed": seed,
        },
    });
    write_json(&out.join("dataset_info.json"), &info)?;
    parts.push("dataset_info.json".into());
    Ok(parts)
}

/// The file name of WebDataset shard `k` of `split`.
pub fn shard_name(split: &str, k: usize) -> String {
    format!("{split}-{k:06}.tar")
}

/// Writes the WebDataset shards (`shard_size` episodes each, in order): per episode
/// `{key}.json` (the sample with its `files` named as in the tar) and `{key}.{k:04}.{suffix}`
/// per frame file, `key` the episode id's file-name stem ([`sage_io::names::stem`]). Returns the files written (relative).
///
/// # Errors
///
/// A frame file that cannot be read or a write error, naming the file.
pub fn write_webdataset(
    out: &Path,
    episodes: &[EpisodeSample],
    shard_size: usize,
    split: &str,
) -> Result<Vec<String>> {
    let dir = out.join(SHARDS_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let images = out.join(IMAGES_DIR);
    let mut written = Vec::new();
    for (k, chunk) in episodes.chunks(shard_size.max(1)).enumerate() {
        let name = shard_name(split, k);
        let path = dir.join(&name);
        // Read every frame first, so a missing one is named rather than half a tar written.
        let mut entries: Vec<(String, Vec<u8>)> = Vec::new();
        for e in chunk {
            let key = sage_io::names::stem(&e.episode_id);
            let mut sample = e.clone();
            for frame in &mut sample.files {
                for f in frame.iter_mut() {
                    let bytes = std::fs::read(images.join(&*f)).map_err(|err| {
                        Error::io(images.join(&*f), err).within(format!("episode {}", e.episode_id))
                    })?;
                    let field = f.rsplit('/').next().unwrap_or(f).to_string();
                    entries.push((format!("{key}.{field}"), bytes));
                    *f = field;
                }
            }
            let json = serde_json::to_vec(&sample)
                .map_err(|err| Error::invalid(format!("sample {}: {err}", e.episode_id)))?;
            entries.push((format!("{key}.json"), json));
        }
        write_atomic(&path, |w| {
            let mut tar = tar::Builder::new(&mut *w);
            for (name, bytes) in &entries {
                let mut header = tar::Header::new_gnu();
                header.set_size(bytes.len() as u64);
                header.set_mode(0o644);
                header.set_mtime(0);
                header.set_uid(0);
                header.set_gid(0);
                header.set_entry_type(tar::EntryType::Regular);
                tar.append_data(&mut header, name, bytes.as_slice())?;
            }
            tar.finish()
        })?;
        written.push(format!("{SHARDS_DIR}/{name}"));
    }
    Ok(written)
}

/// Writes `episodes.jsonl` (one sample per line); returns the file written (relative).
///
/// # Errors
///
/// A write error, naming the file.
pub fn write_frames_index(out: &Path, episodes: &[EpisodeSample]) -> Result<Vec<String>> {
    write_atomic(&out.join(EPISODES_FILE), |w| {
        for e in episodes {
            serde_json::to_writer(&mut *w, e).map_err(std::io::Error::other)?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })?;
    Ok(vec![EPISODES_FILE.to_string()])
}

sage_core::named_by_string!(Layout);
