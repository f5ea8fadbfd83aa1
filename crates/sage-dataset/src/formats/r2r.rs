//! R2R-VLNCE episode files (research notes peers §1.1), read and written, Habitat frame.
//!
//! `{split}/{split}.json.gz`: `{episodes: [...], instruction_vocab: {word_list, stoi, …}}`, each
//! episode with an integer `episode_id` (1…n in file order) and `trajectory_id`, `scene_id` (the
//! scene name), `start_position` `[x, y, z]` and `start_rotation` `[x, y, z, w]` in Habitat's Y-up
//! frame (agents face −Z; `sage_core::frame`), `info.geodesic_distance`, `goals: [{position,
//! radius: 3.0}]` (VLN-CE's success distance), `instruction: {instruction_text,
//! instruction_tokens}` (padded with 0 to 200) and the dense `reference_path`; plus a `sage3d`
//! object with our id, type, level, subtype, source, goal reference and slices.
//! `{split}/{split}_gt.json.gz`: `{episode_id: {locations, actions, forward_steps}}`, the
//! replayed positions after every action (start first) and the action ids.
//! No-goal episodes have no goal and are not written. gzip with a fixed header (no time stamp),
//! so the bytes depend only on the episodes.

use crate::episode::{Episode, Goal, StartPose, Task, check_point, check_unique_ids};
use crate::formats::ReadEpisodes;
use crate::slices::Slices;
use flate2::Compression;
use flate2::read::GzDecoder;
use glam::Vec3;
use sage_core::frame::{
    habitat_quat_to_heading, habitat_to_world, heading_to_habitat_quat, world_to_habitat,
};
use sage_core::{Error, Result, ResultExt};
use sage_lang::actions::{DiscreteAction, StepSizes, follow, replay};
use sage_lang::{InstructionType, Source};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Token ids: padding and unknown words.
pub const PAD: usize = 0;
/// Unknown word id.
pub const UNK: usize = 1;
/// Length instruction tokens are padded to (R2R).
pub const TOKENS: usize = 200;

/// Our extra fields in each R2R episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Extra {
    episode_id: String,
    scene: String,
    instruction_type: InstructionType,
    #[serde(default)]
    level: Option<sage_lang::Level>,
    #[serde(default)]
    subtype: Option<sage_lang::SingleGoalKind>,
    source: Source,
    #[serde(default)]
    start_ref: Option<String>,
    goal_ref: String,
    goal_kind: String,
    /// A pose goal's heading, W frame, radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    goal_yaw: Option<f32>,
    slices: Slices,
    path_length: f32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct R2rGoal {
    position: [f32; 3],
    radius: Option<f32>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct R2rInstruction {
    instruction_text: String,
    #[serde(default)]
    instruction_tokens: Vec<usize>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct R2rEpisode {
    episode_id: u64,
    trajectory_id: u64,
    scene_id: String,
    start_position: [f32; 3],
    start_rotation: [f32; 4],
    #[serde(default)]
    info: BTreeMap<String, f32>,
    goals: Vec<R2rGoal>,
    instruction: R2rInstruction,
    #[serde(default)]
    reference_path: Vec<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sage3d: Option<Extra>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Vocab {
    word_list: Vec<String>,
    #[serde(default)]
    stoi: BTreeMap<String, usize>,
    #[serde(default)]
    num_vocab: usize,
    #[serde(default, rename = "PAD_INDEX")]
    pad_index: usize,
    #[serde(default, rename = "UNK_INDEX")]
    unk_index: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct R2rFile {
    episodes: Vec<R2rEpisode>,
    instruction_vocab: Vocab,
}

/// One entry of the ground-truth file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct GtEntry {
    locations: Vec<[f32; 3]>,
    actions: Vec<u8>,
    forward_steps: usize,
}

/// Lower-case word tokens (R2R style: punctuation dropped).
pub fn tokenize(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_alphanumeric() || c == '\''))
        .filter(|w| !w.is_empty())
        .map(str::to_lowercase)
        .collect()
}

fn habitat(p: [f32; 3]) -> [f32; 3] {
    world_to_habitat(Vec3::from(p)).into()
}

fn world(p: [f32; 3]) -> [f32; 3] {
    habitat_to_world(Vec3::from(p)).into()
}

fn write_gz(path: &Path, value: &impl Serialize) -> Result<()> {
    sage_io::files::write_atomic(path, |w| {
        let mut gz = flate2::GzBuilder::new()
            .mtime(0)
            .write(w, Compression::new(6));
        serde_json::to_writer(&mut gz, value).map_err(std::io::Error::other)?;
        gz.finish()?.flush()
    })
}

/// Reads a gzipped JSON file; the decompressed text is capped at
/// [`JSON_MB`](sage_io::limits::JSON_MB), since a few kilobytes of gzip can inflate to gigabytes.
fn read_gz<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let text =
        sage_io::files::read_text_from(GzDecoder::new(file), path, &sage_io::limits::JSON_MB)?;
    sage_io::files::parse_json(&text, path)
}

/// The two files of `split` under `dir`.
pub fn paths(dir: &Path, split: &str) -> (PathBuf, PathBuf) {
    let d = dir.join(split);
    (
        d.join(format!("{split}.json.gz")),
        d.join(format!("{split}_gt.json.gz")),
    )
}

/// Writes the VLN episodes of `episodes` as split `split` under `dir`; returns how many were
/// written (no-goal episodes are left out).
pub fn write(dir: &Path, split: &str, episodes: &[Episode], space: &StepSizes) -> Result<usize> {
    sage_io::names::check_plain("split", split)?;
    let vln: Vec<(&Episode, &Goal)> = episodes
        .iter()
        .filter(|e| e.task == Task::Vln)
        .filter_map(|e| e.goal.as_ref().map(|g| (e, g)))
        .collect();
    let mut words: Vec<String> = vln
        .iter()
        .flat_map(|(e, _)| tokenize(&e.instruction))
        .collect();
    words.sort();
    words.dedup();
    let mut word_list = vec!["<PAD>".to_string(), "<UNK>".to_string()];
    word_list.extend(words);
    let stoi: BTreeMap<String, usize> = word_list
        .iter()
        .enumerate()
        .map(|(i, w)| (w.clone(), i))
        .collect();
    let mut trajectories: BTreeMap<(String, String), u64> = BTreeMap::new();
    let mut out = Vec::with_capacity(vln.len());
    let mut gt: BTreeMap<String, GtEntry> = BTreeMap::new();
    for (i, (e, goal)) in vln.iter().enumerate() {
        let id = i as u64 + 1;
        let tkey = (
            e.scene.clone(),
            e.trajectory_id
                .map_or_else(|| e.episode_id.clone(), |t| t.to_string()),
        );
        let next = trajectories.len() as u64 + 1;
        let trajectory_id = *trajectories.entry(tkey).or_insert(next);
        let mut tokens: Vec<usize> = tokenize(&e.instruction)
            .iter()
            .map(|w| stoi.get(w).copied().unwrap_or(UNK))
            .take(TOKENS)
            .collect();
        tokens.resize(TOKENS, PAD);
        out.push(R2rEpisode {
            episode_id: id,
            trajectory_id,
            scene_id: e.scene.clone(),
            start_position: habitat(e.start.position),
            start_rotation: heading_to_habitat_quat(e.start.yaw),
            info: [("geodesic_distance".to_string(), e.geodesic_distance)].into(),
            goals: vec![R2rGoal {
                position: habitat(goal.position),
                radius: Some(3.0),
            }],
            instruction: R2rInstruction {
                instruction_text: e.instruction.clone(),
                instruction_tokens: tokens,
            },
            reference_path: e.reference_path.iter().map(|p| habitat(*p)).collect(),
            sage3d: Some(Extra {
                episode_id: e.episode_id.clone(),
                scene: e.scene.clone(),
                instruction_type: e.instruction_type,
                level: e.level,
                subtype: e.subtype,
                source: e.source,
                start_ref: e.start_ref.clone(),
                goal_ref: goal.reference.clone(),
                goal_kind: goal.kind.clone(),
                goal_yaw: goal.yaw,
                slices: e.slices.clone(),
                path_length: e.path_length,
            }),
        });
        let poses = replay(e.start.pose(), &e.actions, space);
        gt.insert(
            id.to_string(),
            GtEntry {
                locations: poses.iter().map(|p| habitat(p.position.into())).collect(),
                actions: e.actions.iter().map(|a| *a as u8).collect(),
                forward_steps: e
                    .actions
                    .iter()
                    .filter(|a| **a == DiscreteAction::Forward)
                    .count(),
            },
        );
    }
    let (main, gt_path) = paths(dir, split);
    let d = main.parent().unwrap_or(dir);
    std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    let num_vocab = word_list.len();
    write_gz(
        &main,
        &R2rFile {
            episodes: out,
            instruction_vocab: Vocab {
                word_list,
                stoi,
                num_vocab,
                pad_index: PAD,
                unk_index: UNK,
            },
        },
    )?;
    write_gz(&gt_path, &gt)?;
    Ok(vln.len())
}

/// Reads split `split` under `dir` back into episodes (W frame). Actions come from the
/// ground-truth file when it is there, else from following the reference path. Episodes without
/// our `sage3d` object (other R2R files) read as imported Single-Goal episodes, their asset
/// slice `medium` unless the caller re-tags them ([`read_episodes`] says which).
///
/// # Errors
///
/// Those of [`read_episodes`].
pub fn read(dir: &Path, split: &str, space: &StepSizes) -> Result<Vec<Episode>> {
    read_episodes(dir, split, space).map(|r| r.episodes)
}

/// [`read`], also naming the episodes without our `sage3d` object: their asset slice is the
/// `medium` placeholder, for the caller to re-tag from their scenes.
///
/// # Errors
///
/// A split name that leaves `dir`, a file that cannot be read or is not R2R-VLNCE, or an
/// episode that fails [`Episode::check`], naming the file and the episode.
pub fn read_episodes(dir: &Path, split: &str, space: &StepSizes) -> Result<ReadEpisodes> {
    sage_io::names::check_plain("split", split)?;
    let (main, gt_path) = paths(dir, split);
    let file: R2rFile = read_gz(&main)?;
    let gt: BTreeMap<String, GtEntry> = if gt_path.is_file() {
        read_gz(&gt_path)?
    } else {
        BTreeMap::new()
    };
    // One episode per file entry, in order, so the entries' indices are the episodes'.
    let assets_unknown = (file.episodes.iter().enumerate())
        .filter(|(_, r)| r.sage3d.is_none())
        .map(|(i, _)| i)
        .collect();
    let episodes = file
        .episodes
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            let ctx = format!("episodes[{i}]");
            let goal = r
                .goals
                .first()
                .ok_or_else(|| Error::format("goals", "no goal"))
                .within(&ctx)
                .in_file(&main)?;
            let path: Vec<[f32; 3]> = if r.reference_path.is_empty() {
                vec![r.start_position, goal.position]
            } else {
                r.reference_path.clone()
            };
            let path: Vec<[f32; 3]> = path.into_iter().map(world).collect();
            let yaw = habitat_quat_to_heading(r.start_rotation);
            // Checked before the path is followed: an infinite or far-off point would make
            // the walk along it endless.
            let checked = check_point(world(r.start_position), "start_position")
                .and_then(|()| check_point(world(goal.position), "goals[0].position"))
                .and_then(|()| {
                    path.iter()
                        .enumerate()
                        .try_for_each(|(k, p)| check_point(*p, &format!("reference_path[{k}]")))
                })
                .and_then(|()| {
                    if yaw.is_finite() {
                        Ok(())
                    } else {
                        Err(Error::format("start_rotation", "expected finite numbers"))
                    }
                });
            checked.within(&ctx).in_file(&main)?;
            let actions = match gt.get(&r.episode_id.to_string()) {
                Some(g) => g
                    .actions
                    .iter()
                    .map(|a| {
                        DiscreteAction::try_from(*a).map_err(|m| {
                            Error::format(format!("{}.actions", r.episode_id), m).in_file(&gt_path)
                        })
                    })
                    .collect::<Result<Vec<_>>>()?,
                None => {
                    let flat: Vec<glam::Vec2> =
                        path.iter().map(|p| glam::Vec2::new(p[0], p[1])).collect();
                    follow(&flat, yaw, None, space)
                        .ok_or_else(|| Error::format("reference_path", "cannot be followed"))
                        .within(&ctx)
                        .in_file(&main)?
                }
            };
            let length: f32 = path
                .windows(2)
                .map(|w| Vec3::from(w[0]).distance(Vec3::from(w[1])))
                // Folded from +0.0: an empty float sum is −0.0 (a path of one point).
                .fold(0.0, |a, b| a + b);
            let x = r.sage3d.clone();
            let episode = Episode {
                episode_id: x
                    .as_ref()
                    .map_or_else(|| r.episode_id.to_string(), |x| x.episode_id.clone()),
                scene: x
                    .as_ref()
                    .map_or_else(|| r.scene_id.clone(), |x| x.scene.clone()),
                task: Task::Vln,
                trajectory_id: x
                    .as_ref()
                    .filter(|x| x.instruction_type != InstructionType::BaseAction)
                    .map(|_| r.trajectory_id as usize),
                instruction: r.instruction.instruction_text.clone(),
                instruction_texts: Default::default(),
                level: x.as_ref().map_or(Some(sage_lang::Level::Low), |x| x.level),
                instruction_type: x
                    .as_ref()
                    .map_or(InstructionType::SingleGoal, |x| x.instruction_type),
                subtype: x.as_ref().and_then(|x| x.subtype),
                source: x.as_ref().map_or(Source::Imported, |x| x.source),
                start_ref: x.as_ref().and_then(|x| x.start_ref.clone()),
                start: StartPose {
                    position: world(r.start_position),
                    yaw,
                },
                goal: Some(Goal {
                    reference: x.as_ref().map_or_else(String::new, |x| x.goal_ref.clone()),
                    kind: x
                        .as_ref()
                        .map_or_else(|| "pose".into(), |x| x.goal_kind.clone()),
                    position: world(goal.position),
                    yaw: x.as_ref().and_then(|x| x.goal_yaw),
                }),
                reference_path: path,
                actions,
                path_length: x.as_ref().map_or(length, |x| x.path_length),
                geodesic_distance: r.info.get("geodesic_distance").copied().unwrap_or(length),
                slices: x.map_or_else(
                    || Slices {
                        assets: "medium".into(),
                        path: crate::slices::path_slice(length).into(),
                    },
                    |x| x.slices,
                ),
            };
            // The lengths and heading come from the file too.
            episode.check().within(&ctx).in_file(&main)?;
            Ok(episode)
        })
        .collect::<Result<Vec<_>>>()?;
    check_unique_ids(&episodes, |k| format!("episodes[{k}]")).in_file(&main)?;
    Ok(ReadEpisodes {
        episodes,
        assets_unknown,
    })
}
