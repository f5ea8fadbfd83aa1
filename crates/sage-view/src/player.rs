//! The episodes the page lists (a dataset's, a run's, a human run's) and, for the player, an
//! evaluated episode step by step.

use crate::subject::Subject;
use sage_dataset::Episode;
use sage_eval::EvalRecord;
use sage_eval::report::video::{StepMove, step_move};
use serde_json::{Value, json};

/// The episodes of `subject` for the page's list: id, scene, instruction and tags; for a run
/// the outcome (termination, SR, NE, CR, the error of a faulted one); for human play whether
/// each was played and its outcome.
pub fn episode_list(subject: &Subject) -> Vec<Value> {
    match subject {
        Subject::Scenes => Vec::new(),
        Subject::Dataset { episodes, .. } => episodes.iter().map(|e| listed(e, None)).collect(),
        Subject::Play { run } => run
            .episodes()
            .iter()
            .map(|e| listed(e, run.recorded(&e.episode_id)))
            .collect(),
        Subject::Run {
            records,
            instructions,
            ..
        } => records
            .iter()
            .map(|r| {
                let mut v = outcome(r);
                v["id"] = json!(r.episode_id);
                v["scene"] = json!(r.scene);
                v["task"] = json!(r.task);
                v["instruction"] = json!(instructions.get(&r.episode_id));
                v
            })
            .collect(),
    }
}

/// An episode of a split for the list, with its record once played.
fn listed(e: &Episode, rec: Option<&EvalRecord>) -> Value {
    let mut v = rec.map_or_else(|| json!({}), outcome);
    v["id"] = json!(e.episode_id);
    v["scene"] = json!(e.scene);
    v["task"] = json!(e.task);
    v["instruction"] = json!(e.instruction);
    v["instruction_type"] = json!(e.instruction_type);
    v["played"] = json!(rec.is_some());
    v
}

/// A record's outcome: termination, SR, NE, CR, SPL, nDTW, the error of a faulted episode and
/// the record's notes.
fn outcome(r: &EvalRecord) -> Value {
    let m = r.metrics.clone().unwrap_or_default();
    json!({
        "termination": r.termination,
        "sr": m.sr,
        "ne": m.ne,
        "cr": m.cr,
        "spl": m.spl,
        "ndtw": m.ndtw,
        "error": r.error,
        "notes": r.notes,
    })
}

/// One evaluated episode for the player: its outcome and metrics, instruction, start, goal,
/// reference path, and every step with its pose, the action taken (as the record implies it:
/// [`step_actions`]), the contact with its intensity c(t) and the geodesic distance to the goal.
pub fn episode_detail(rec: &EvalRecord, instruction: Option<&str>) -> Value {
    let mut v = outcome(rec);
    v["id"] = json!(rec.episode_id);
    v["scene"] = json!(rec.scene);
    v["agent"] = json!(rec.agent);
    v["instruction"] = json!(instruction);
    v["metrics"] = json!(rec.metrics);
    let Some(r) = &rec.record else {
        v["steps"] = json!([]);
        return v;
    };
    let actions = step_actions(r);
    v["start"] = json!({"x": r.start[0], "y": r.start[1], "z": r.start[2], "yaw": r.start_yaw});
    v["reference_path"] = json!(
        r.reference_path
            .iter()
            .map(|p| [p[0], p[1]])
            .collect::<Vec<_>>()
    );
    v["goal"] = json!(r.goal);
    v["steps"] = r
        .steps
        .iter()
        .zip(&actions)
        .map(|(s, a)| {
            json!({
                "x": num(s.position[0]), "y": num(s.position[1]), "z": num(s.position[2]),
                "yaw": num(s.yaw),
                "time": num(s.time),
                "action": a,
                "contact": s.contact,
                "intensity": num(s.intensity),
                "geodesic_to_goal": s.geodesic_to_goal_point.map(num),
            })
        })
        .collect();
    v
}

/// `v` as the JSON number the records print for it: the shortest decimal that reads back as
/// this `f32` (a plain widening to `f64` would print its binary expansion instead).
pub fn num(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}

/// The action of each step of `r` by the viewer's key names, as the record implies it
/// ([`step_move`]): `stop`, `forward`, `left`, `right`, or `-` (a camera tilt, or a step that
/// did nothing).
pub fn step_actions(r: &sage_metrics::EpisodeRecord) -> Vec<&'static str> {
    (0..r.steps.len())
        .map(|k| match step_move(r, k) {
            StepMove::Stop => "stop",
            StepMove::Forward(_) => "forward",
            StepMove::Turn(t) if t > 0.0 => "left",
            StepMove::Turn(_) => "right",
            StepMove::Nothing => "-",
        })
        .collect()
}
