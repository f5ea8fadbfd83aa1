//! The SAGE-Bench "GVLN" trajectory JSON (research notes §2.1), read and written.
//!
//! `{dataset_metadata: {name: "GVLN", frame, frame_offset}, scenes: [{scene_id, scene_name,
//! samples: [{trajectory_id, instructions: [{instruction_type, start, end,
//! generated_instruction, scene_id}], points: [{point, position, rotation, …}]}]}]}`.
//!
//! - **Frame**: written in W (`frame: "W"`) or in the SAGE S frame (`frame: "S"`, with
//!   `frame_offset: [δx, δy]`: x_S = −x_W + δx, y_S = −y_W + δy). A file without `frame` (the
//!   published ones) is read as S with the offset the caller gives.
//! - **rotation**: `[−sin(φ/2), 0, 0, cos(φ/2)]` with φ = ψ + π, ψ the heading in the file's frame
//!   toward the next point; the first point holds the start heading and the last the final
//!   heading (the published files force `[0, 0, 0, 1]` there, which the reader ignores at the
//!   last point only).
//! - **position** z: the agent's base above the floor, `base_z` in the metadata. The published
//!   files (no `frame`, no `base_z`) put it [`PUBLISHED_BASE_Z`] = 0.5 m up, and so does this
//!   writer in S, the frame those files' tools read; in W it writes the floor (`base_z: 0`).
//!   The reader takes `base_z` off (0.5 without `frame`, 0 in a file of ours that predates the
//!   key).
//! - **scene**: an instruction's `scene_id` (the published files' full folder key,
//!   `0033_839873`, the name of an InteriorGS scene folder), else the scene's `scene_name` (there
//!   the bare world id `839873`), else its `scene_id`; the writer writes the scene's name in all
//!   three.
//! - Each instruction carries extra keys of ours that other readers ignore: `episode_id`,
//!   `level`, `subtype`, `source`, `task`, and what the points cannot hold exactly —
//!   `start_yaw` and, for a pose goal, `goal_yaw` (headings in the file's frame, radians; in W
//!   as they are, unwrapped: a turn in place is one point with two headings), `goal_kind`,
//!   `path_length`, `geodesic_distance`, `slices` and the ground-truth `actions`. So a file in
//!   W reads back as exactly the episodes it was written from. A sample is a trajectory with
//!   all its instructions; Base-Action and no-goal episodes are samples of their own.
//! - Reading: one episode per (sample, instruction), each checked as the JSONL reader checks
//!   it ([`Episode::check`]); without our keys (the published files) the ground-truth actions
//!   are recomputed from the points (turning at the end to `goal_yaw` when only that key is
//!   there, else to the last point's heading), the headings come from the points, the goal's
//!   kind from its `end` name ([`goal_kind`]), both lengths are the path's and the asset slice
//!   is `medium` ([`read_episodes`] names those episodes, which an import with a scenes folder
//!   re-tags by their scene's object count); the type `Default` (the published generator's
//!   failure text) reads as Single-Goal.

use crate::episode::{Episode, Goal, StartPose, Task, check_point, check_unique_ids};
use crate::formats::ReadEpisodes;
use crate::slices::{Slices, path_slice};
use glam::{Vec2, Vec3};
use sage_core::frame::SageFrame;
use sage_core::{Error, Result, ResultExt, wrap_angle};
use sage_lang::actions::{StepSizes, follow};
use sage_lang::{InstructionType, Level, Source};
use serde_json::{Value, json};
use std::collections::HashMap;
use std::path::Path;

/// The height above the floor at which the published GVLN files (those without `frame`) put
/// every point: the agent's base in SAGE-Bench's generator (research notes §2.1).
pub const PUBLISHED_BASE_Z: f32 = 0.5;

/// The frame of a GVLN file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GvlnFrame {
    /// Our world frame W.
    World,
    /// The SAGE S frame with its per-scene offset.
    Sage(SageFrame),
}

impl GvlnFrame {
    fn point(&self, p: [f32; 3]) -> [f32; 3] {
        match self {
            GvlnFrame::World => p,
            GvlnFrame::Sage(s) => s.world_to_sage(Vec3::from(p)).into(),
        }
    }
    // The height of the agent's base above the floor at which this writer puts the points: in S
    // where the published files put it, so their tools stand the agent where they expect.
    fn base_z(&self) -> f32 {
        match self {
            GvlnFrame::World => 0.0,
            GvlnFrame::Sage(_) => PUBLISHED_BASE_Z,
        }
    }
    fn point_back(&self, p: [f32; 3]) -> [f32; 3] {
        match self {
            GvlnFrame::World => p,
            GvlnFrame::Sage(s) => s.sage_to_world(Vec3::from(p)).into(),
        }
    }
    // In W a heading is written as it is: wrapping it would round it (and a no-goal start of
    // 330° would come back as −30°), so a file in W would read back with other headings than
    // it was written from. `rotation` wraps its angle itself.
    fn heading(&self, yaw: f32) -> f32 {
        match self {
            GvlnFrame::World => yaw,
            GvlnFrame::Sage(s) => s.heading_to_sage(yaw),
        }
    }
    fn heading_back(&self, yaw: f32) -> f32 {
        match self {
            GvlnFrame::World => yaw,
            GvlnFrame::Sage(s) => s.heading_to_world(yaw),
        }
    }
}

/// The `rotation` of a heading ψ (see the module docs).
pub fn encode_rotation(psi: f32) -> [f32; 4] {
    let phi = wrap_angle(psi + std::f32::consts::PI);
    [-(phi / 2.0).sin(), 0.0, 0.0, (phi / 2.0).cos()]
}

/// The heading ψ of a `rotation`: 2·atan2(−q0, q3) − π.
pub fn decode_rotation(q: [f32; 4]) -> f32 {
    wrap_angle(2.0 * (-q[0]).atan2(q[3]) - std::f32::consts::PI)
}

/// Headings along a path: toward the next point; the last is `last`.
fn headings(path: &[[f32; 3]], last: f32) -> Vec<f32> {
    (0..path.len())
        .map(|i| match path.get(i + 1) {
            Some(n) if Vec2::new(n[0] - path[i][0], n[1] - path[i][1]).length() > 1e-6 => {
                (n[1] - path[i][1]).atan2(n[0] - path[i][0])
            }
            _ => last,
        })
        .collect()
}

/// A path read from a file as points in the floor plane, with its length (metres): what
/// the ground-truth actions follow ([`follow`]) and what the path slice and the geodesic
/// distance of an imported episode come from (the files hold no other distance).
pub(crate) fn planar(path: &[[f32; 3]]) -> (Vec<Vec2>, f32) {
    let flat: Vec<Vec2> = path.iter().map(|p| Vec2::new(p[0], p[1])).collect();
    // Folded from +0.0: an empty float sum is −0.0 (a path of one point).
    let length = flat
        .windows(2)
        .map(|w| w[0].distance(w[1]))
        .fold(0.0, |a, b| a + b);
    (flat, length)
}

/// A sample of a GVLN file as written: its trajectory id and its episodes.
type Sample<'a> = (String, Vec<&'a Episode>);

/// Writes episodes as one GVLN file in `frame` (atomically), with
/// scenes and their samples (trajectories) in the order of their first episodes, so a split
/// reads back in its own order (a map keyed by the ids would put trajectory 10 before 3).
pub fn write(path: &Path, episodes: &[Episode], frame: GvlnFrame, space: &StepSizes) -> Result<()> {
    let mut scenes: Vec<(&str, Vec<Sample>)> = Vec::new();
    let mut scene_at: HashMap<&str, usize> = HashMap::new();
    let mut sample_at: HashMap<(usize, String), usize> = HashMap::new();
    for e in episodes {
        let key = match e.trajectory_id {
            Some(t) => format!("{t}"),
            None => e
                .episode_id
                .rsplit('-')
                .next()
                .unwrap_or_default()
                .to_string(),
        };
        let at = *scene_at.entry(&e.scene).or_insert_with(|| {
            scenes.push((&e.scene, Vec::new()));
            scenes.len() - 1
        });
        let samples = &mut scenes[at].1;
        let k = *sample_at.entry((at, key.clone())).or_insert_with(|| {
            samples.push((key, Vec::new()));
            samples.len() - 1
        });
        samples[k].1.push(e);
    }
    let scenes: Vec<Value> = scenes
        .into_iter()
        .map(|(scene, samples)| {
            let samples: Vec<Value> = samples
                .into_iter()
                .map(|(key, eps)| {
                    let first = eps[0];
                    let final_yaw = sage_lang::actions::replay(first.start.pose(), &first.actions, space)
                        .last()
                        .map_or(first.start.yaw, |p| p.yaw);
                    let mut hs = headings(&first.reference_path, final_yaw);
                    if let Some(h) = hs.first_mut() {
                        *h = first.start.yaw;
                    }
                    let points: Vec<Value> = first
                        .reference_path
                        .iter()
                        .zip(hs)
                        .enumerate()
                        .map(|(i, (p, h))| {
                            let [x, y, z] = frame.point(*p);
                            json!({
                                "point": i.to_string(), "position": [x, y, z + frame.base_z()],
                                "rotation": encode_rotation(frame.heading(h)),
                                "action": [], "camera_images": [], "focal_length": 7.0,
                                "horizontal_aperture": 20.955, "vertical_aperture": 20.955,
                                "focus_distance": 0.0, "clipping_range": [1.0, 1.0e6],
                            })
                        })
                        .collect();
                    let instructions: Vec<Value> = eps
                        .iter()
                        .map(|e| {
                            let e = e.without_negative_zeros();
                            let mut ins = json!({
                                "instruction_type": e.instruction_type.as_str(),
                                "start": e.start_ref.clone().unwrap_or_default(),
                                "end": e.goal.as_ref().map(|g| g.reference.clone()).unwrap_or_default(),
                                "generated_instruction": e.instruction, "scene_id": scene,
                                "episode_id": e.episode_id, "level": e.level, "subtype": e.subtype,
                                "source": e.source, "task": e.task,
                                "start_yaw": frame.heading(e.start.yaw),
                                "path_length": e.path_length,
                                "geodesic_distance": e.geodesic_distance,
                                "slices": e.slices,
                                "actions": e.actions,
                            });
                            if let Some(g) = &e.goal {
                                ins["goal_kind"] = json!(g.kind);
                                if let Some(yaw) = g.yaw {
                                    ins["goal_yaw"] = json!(frame.heading(yaw));
                                }
                            }
                            ins
                        })
                        .collect();
                    json!({"trajectory_id": key, "instructions": instructions, "points": points})
                })
                .collect();
            json!({"scene_id": scene, "scene_name": scene, "samples": samples})
        })
        .collect();
    let mut meta = json!({
        "name": "GVLN", "generator": format!("sage3d {}", env!("CARGO_PKG_VERSION")),
        "base_z": frame.base_z(),
    });
    match frame {
        GvlnFrame::World => meta["frame"] = json!("W"),
        GvlnFrame::Sage(s) => {
            meta["frame"] = json!("S");
            meta["frame_offset"] = json!([s.offset.x, s.offset.y]);
        }
    }
    sage_io::files::write_json(path, &json!({"dataset_metadata": meta, "scenes": scenes}))
}

/// The kind of a goal reference: `room_3` a room, `dining_area_1` an area, empty a pose.
pub fn goal_kind(reference: &str) -> &'static str {
    let numbered = |prefix: &str| {
        reference
            .strip_prefix(prefix)
            .is_some_and(|n| n.parse::<usize>().is_ok())
    };
    if reference.is_empty() {
        "pose"
    } else if numbered("room_") {
        "room"
    } else if reference
        .rsplit_once('_')
        .is_some_and(|(head, n)| head.ends_with("_area") && n.parse::<usize>().is_ok())
    {
        "area"
    } else {
        "object"
    }
}

fn field<'a>(v: &'a Value, key: &str) -> Result<&'a Value> {
    v.get(key).ok_or_else(|| Error::format(key, "missing"))
}

fn floats<const N: usize>(v: &Value, key: &str) -> Result<[f32; N]> {
    let a = field(v, key)?
        .as_array()
        .ok_or_else(|| Error::format(key, "expected an array"))?;
    if a.len() != N {
        return Err(Error::format(
            key,
            format!("expected {N} numbers, found {}", a.len()),
        ));
    }
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        // Finite in single precision: 1e300 is a finite f64 but an infinite f32.
        *o = x
            .as_f64()
            .map(|f| f as f32)
            .filter(|f| f.is_finite())
            .ok_or_else(|| Error::format(key, "expected finite numbers"))?;
    }
    Ok(out)
}

/// An optional number of an instruction (one of the keys of ours): `None` when absent or null.
///
/// # Errors
///
/// A value that is not a number finite in single precision, naming `key`.
fn optional_number(v: &Value, key: &str) -> Result<Option<f32>> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => x
            .as_f64()
            .map(|f| f as f32)
            .filter(|f| f.is_finite())
            .map(Some)
            .ok_or_else(|| Error::format(key, format!("{x}: expected a finite number"))),
    }
}

fn text(v: &Value, key: &str) -> String {
    match v.get(key) {
        Some(Value::String(s)) => s.clone(),
        Some(Value::Number(n)) => n.to_string(),
        _ => String::new(),
    }
}

/// Reads a GVLN file; `sage_offset` is the S-frame offset for files that do not state their frame.
/// Files without our `slices` key (the published ones) hold no asset count: their asset slices
/// read as `medium` unless the caller re-tags them ([`read_episodes`] says which).
///
/// # Errors
///
/// Those of [`read_episodes`].
pub fn read(path: &Path, sage_offset: Vec2, space: &StepSizes) -> Result<Vec<Episode>> {
    read_episodes(path, sage_offset, space).map(|r| r.episodes)
}

/// [`read`], also naming the episodes whose instruction has no `slices` key of ours: their
/// asset slice is the `medium` placeholder, for the caller to re-tag from their scenes.
///
/// # Errors
///
/// A file that cannot be read or is not GVLN, or an episode that fails [`Episode::check`],
/// naming the file and the place in it.
pub fn read_episodes(path: &Path, sage_offset: Vec2, space: &StepSizes) -> Result<ReadEpisodes> {
    let text_in = sage_io::files::read_text(path, &sage_io::limits::JSON_MB)?;
    let root: Value = sage_io::files::parse_json(&text_in, path)?;
    let meta = root.get("dataset_metadata").cloned().unwrap_or(Value::Null);
    let stated = meta.get("frame").and_then(Value::as_str);
    // The points stand at the agent's base: where the file says, else where the published
    // files put it (no `frame`), else at the floor (our files before `base_z`).
    let stated_base = optional_number(&meta, "base_z")
        .within("dataset_metadata")
        .in_file(path)?;
    let base_z = match stated_base {
        Some(z) => z,
        None if stated.is_none() => PUBLISHED_BASE_Z,
        None => 0.0,
    };
    let frame = match stated {
        Some("W") => GvlnFrame::World,
        Some("S") => {
            let o: [f32; 2] = floats(&meta, "frame_offset")
                .within("dataset_metadata")
                .in_file(path)?;
            GvlnFrame::Sage(SageFrame {
                offset: Vec2::from(o),
            })
        }
        None => GvlnFrame::Sage(SageFrame {
            offset: sage_offset,
        }),
        Some(other) => {
            return Err(Error::format(
                "dataset_metadata.frame",
                format!("expected W or S, got {other}"),
            )
            .in_file(path));
        }
    };
    let scenes = field(&root, "scenes")
        .and_then(|s| {
            s.as_array()
                .ok_or_else(|| Error::format("scenes", "expected an array"))
        })
        .in_file(path)?;
    let mut out = Vec::new();
    let mut places = Vec::new();
    let mut assets_unknown = Vec::new();
    for (si, scene) in scenes.iter().enumerate() {
        let ctx = format!("scenes[{si}]");
        // The scene's own name, for instructions without a `scene_id` of their own.
        let name = match text(scene, "scene_name") {
            n if n.is_empty() => text(scene, "scene_id"),
            n => n,
        };
        if !name.is_empty() {
            sage_io::names::check_plain("scene", &name)
                .within(format!("{ctx}.scene_name"))
                .in_file(path)?;
        }
        let samples = field(scene, "samples")
            .ok()
            .and_then(Value::as_array)
            .ok_or_else(|| Error::format("samples", "expected an array"))
            .within(&ctx)
            .in_file(path)?;
        for (ti, sample) in samples.iter().enumerate() {
            let ctx = format!("{ctx}.samples[{ti}]");
            // Each episode with whether its file gave its asset slice.
            let read_sample = || -> Result<Vec<(Episode, bool)>> {
                let pts = field(sample, "points")?
                    .as_array()
                    .ok_or_else(|| Error::format("points", "expected an array"))?;
                if pts.is_empty() {
                    return Err(Error::format("points", "no points"));
                }
                let mut positions = Vec::with_capacity(pts.len());
                let mut yaws = Vec::with_capacity(pts.len());
                for (pi, p) in pts.iter().enumerate() {
                    let pos: [f32; 3] = floats(p, "position").within(format!("points[{pi}]"))?;
                    let rot: [f32; 4] = floats(p, "rotation").within(format!("points[{pi}]"))?;
                    let [x, y, z] = frame.point_back(pos);
                    let pos = [x, y, z - base_z];
                    check_point(pos, "position").within(format!("points[{pi}]"))?;
                    positions.push(pos);
                    // Only the last point's `[0, 0, 0, 1]` is the published files' placeholder;
                    // elsewhere it is the heading π like any other rotation.
                    let placeholder = pi + 1 == pts.len() && rot == [0.0, 0.0, 0.0, 1.0];
                    yaws.push((!placeholder).then(|| frame.heading_back(decode_rotation(rot))));
                }
                let path_start_yaw = yaws[0].unwrap_or(0.0);
                let path_final_yaw = yaws.last().copied().flatten();
                let (flat, length) = planar(&positions);
                let tid = text(sample, "trajectory_id");
                // A goal-directed trajectory's id is its index, which the published files
                // spell as a string ("0"): anything else there is a damaged file, not a
                // trajectory without an index. Base-Action and no-goal samples have no index
                // (this writer names them by their ids' ends, "b0").
                let index = |kind: InstructionType, task: Task| -> Result<Option<usize>> {
                    if kind == InstructionType::BaseAction || task != Task::Vln || tid.is_empty() {
                        return Ok(None);
                    }
                    tid.parse().map(Some).map_err(|_| {
                        Error::format(
                            "trajectory_id",
                            format!("'{tid}' is not a trajectory index"),
                        )
                    })
                };
                let instructions = field(sample, "instructions")?
                    .as_array()
                    .ok_or_else(|| Error::format("instructions", "expected an array"))?;
                let mut eps = Vec::new();
                for (ii, ins) in instructions.iter().enumerate() {
                    let kind_name = text(ins, "instruction_type");
                    let kind = if kind_name == "Default" {
                        InstructionType::SingleGoal
                    } else {
                        InstructionType::parse(&kind_name).ok_or_else(|| {
                            Error::format(
                                format!("instructions[{ii}].instruction_type"),
                                format!("unknown type '{kind_name}'"),
                            )
                        })?
                    };
                    let task = if kind == InstructionType::GoalLess {
                        Task::Nogoal
                    } else {
                        Task::Vln
                    };
                    // Our own keys (other readers ignore them) carry what the points cannot:
                    // the headings exactly (a turn in place has one point for two headings),
                    // the goal's kind and heading, the lengths and the slices.
                    let ours =
                        |key: &str| optional_number(ins, key).within(format!("instructions[{ii}]"));
                    let start_yaw =
                        ours("start_yaw")?.map_or(path_start_yaw, |y| frame.heading_back(y));
                    let goal_yaw = ours("goal_yaw")?.map(|y| frame.heading_back(y));
                    let final_yaw = goal_yaw.or(path_final_yaw);
                    let actions =
                        match (ins.get("actions"), task) {
                            // Ours, as written: recomputing them from rounded points could pick
                            // another, equivalent sequence.
                            (Some(a), _) if !a.is_null() => serde_json::from_value(a.clone())
                                .map_err(|e| {
                                    Error::format(
                                        format!("instructions[{ii}].actions"),
                                        format!("expected action ids 0-3: {e}"),
                                    )
                                })?,
                            (_, Task::Nogoal) => Vec::new(),
                            (_, Task::Vln) => follow(&flat, start_yaw, final_yaw, space)
                                .ok_or_else(|| {
                                    Error::format(
                                        "points",
                                        "the path cannot be followed with discrete actions",
                                    )
                                })?,
                        };
                    let scene = match text(ins, "scene_id") {
                        s if s.is_empty() => name.clone(),
                        s => s,
                    };
                    sage_io::names::check_plain("scene", &scene)
                        .within(format!("instructions[{ii}].scene_id"))?;
                    let id = text(ins, "episode_id");
                    let start_ref = text(ins, "start");
                    let end = text(ins, "end");
                    let end_kind = match ins.get("goal_kind") {
                        None | Some(Value::Null) => goal_kind(&end).to_string(),
                        Some(Value::String(k)) => k.clone(),
                        Some(other) => {
                            return Err(Error::format(
                                format!("instructions[{ii}].goal_kind"),
                                format!("{other}: expected a string"),
                            ));
                        }
                    };
                    let tagged = !matches!(ins.get("slices"), None | Some(Value::Null));
                    let slices = match ins.get("slices") {
                        None | Some(Value::Null) => Slices {
                            assets: "medium".into(),
                            path: if task == Task::Nogoal {
                                "none".into()
                            } else {
                                path_slice(length).into()
                            },
                        },
                        Some(v) => serde_json::from_value(v.clone()).map_err(|e| {
                            Error::format(format!("instructions[{ii}].slices"), e.to_string())
                        })?,
                    };
                    let episode = Episode {
                        episode_id: if id.is_empty() {
                            format!("{scene}-t{tid}-{ii}")
                        } else {
                            id
                        },
                        scene,
                        task,
                        trajectory_id: index(kind, task)?,
                        instruction: text(ins, "generated_instruction"),
                        instruction_texts: Default::default(),
                        level: ins
                            .get("level")
                            .and_then(|l| serde_json::from_value::<Level>(l.clone()).ok())
                            .or(kind.level()),
                        instruction_type: kind,
                        subtype: ins
                            .get("subtype")
                            .and_then(|s| serde_json::from_value(s.clone()).ok()),
                        source: ins
                            .get("source")
                            .and_then(|s| serde_json::from_value(s.clone()).ok())
                            .unwrap_or(Source::Imported),
                        start_ref: (!start_ref.is_empty()).then_some(start_ref),
                        start: StartPose {
                            position: positions[0],
                            yaw: start_yaw,
                        },
                        goal: (task == Task::Vln).then(|| Goal {
                            kind: end_kind,
                            reference: end,
                            position: *positions.last().unwrap_or(&positions[0]),
                            yaw: goal_yaw,
                        }),
                        reference_path: positions.clone(),
                        actions,
                        path_length: ours("path_length")?.unwrap_or(length),
                        geodesic_distance: ours("geodesic_distance")?.unwrap_or(length),
                        slices,
                    };
                    // The same check as our JSONL reader's, so an import writes no episode
                    // that `eval` would refuse.
                    episode.check().within(format!("instructions[{ii}]"))?;
                    eps.push((episode, tagged));
                }
                Ok(eps)
            };
            let read = read_sample().within(&ctx).in_file(path)?;
            places.extend((0..read.len()).map(|k| format!("{ctx}.instructions[{k}]")));
            for (episode, tagged) in read {
                if !tagged {
                    assets_unknown.push(out.len());
                }
                out.push(episode);
            }
        }
    }
    check_unique_ids(&out, |k| places[k].clone()).in_file(path)?;
    Ok(ReadEpisodes {
        episodes: out,
        assets_unknown,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn rotation_round_trip(psi in -3.1f32..3.1) {
            prop_assert!(wrap_angle(decode_rotation(encode_rotation(psi)) - psi).abs() < 1e-4);
            let q = encode_rotation(psi);
            prop_assert!((q[0] * q[0] + q[3] * q[3] - 1.0).abs() < 1e-5);
        }
    }
}
