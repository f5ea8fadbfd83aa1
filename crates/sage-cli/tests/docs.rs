//! The documents cannot rot: every example file in `docs/` is parsed by the reader sage3d uses
//! (or compared field by field with what its writer produces), the metric examples are
//! recomputed, and every `sage3d …` command line in the README parses.

mod common;

use common::ok;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The fenced blocks of `text` whose info string is `json example:KIND`, as (kind, body).
fn examples(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut current: Option<(String, String)> = None;
    for line in text.lines() {
        match &mut current {
            None => {
                if let Some(kind) = line.trim().strip_prefix("```json example:").map(str::trim) {
                    current = Some((kind.to_string(), String::new()));
                }
            }
            Some((kind, body)) => {
                if line.trim() == "```" {
                    out.push((kind.clone(), std::mem::take(body)));
                    current = None;
                } else {
                    body.push_str(line);
                    body.push('\n');
                }
            }
        }
    }
    out
}

/// Every example of every document under docs/, by kind.
fn all_examples() -> BTreeMap<String, Vec<(String, String)>> {
    let mut by_kind: BTreeMap<String, Vec<(String, String)>> = BTreeMap::new();
    for entry in std::fs::read_dir(repo().join("docs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "md") {
            let text = std::fs::read_to_string(&path).unwrap();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            for (kind, body) in examples(&text) {
                by_kind.entry(kind).or_default().push((name.clone(), body));
            }
        }
    }
    by_kind
}

/// True when every key of `example` exists in `real` with a value of the same JSON type
/// (arrays compared element-wise against the real array's first element; null matches all).
fn same_shape(example: &Value, real: &Value, at: &str) -> Result<(), String> {
    match (example, real) {
        (Value::Null, _) | (_, Value::Null) => Ok(()),
        (Value::Object(e), Value::Object(r)) => e.iter().try_for_each(|(k, v)| match r.get(k) {
            Some(rv) => same_shape(v, rv, &format!("{at}.{k}")),
            None => Err(format!("{at}.{k} is not written by sage3d")),
        }),
        (Value::Array(e), Value::Array(r)) => match r.first() {
            Some(first) => e
                .iter()
                .enumerate()
                .try_for_each(|(i, v)| same_shape(v, first, &format!("{at}[{i}]"))),
            None => Ok(()),
        },
        (Value::Number(_), Value::Number(_))
        | (Value::String(_), Value::String(_))
        | (Value::Bool(_), Value::Bool(_)) => Ok(()),
        _ => Err(format!("{at}: {example} where sage3d writes {real}")),
    }
}

fn check(kind: &str, body: &str) -> Result<(), String> {
    let err = |e: sage_core::Error| e.to_string();
    let dir = tempfile::tempdir().unwrap();
    match kind {
        "labels" => sage_scene::formats::labels::parse(body)
            .map_err(err)
            .and_then(|(objects, skipped)| {
                (skipped == 0 && !objects.is_empty())
                    .then_some(())
                    .ok_or(format!("{skipped} entries skipped"))
            }),
        "structure" => sage_scene::formats::structure::parse(body)
            .map(|_| ())
            .map_err(err),
        "occupancy" => sage_scene::occupancy::parse_placement(body)
            .map(|_| ())
            .map_err(err),
        "objects" => {
            let labels = &all_examples()["labels"][0].1;
            let (mut objects, _) = sage_scene::formats::labels::parse(labels).map_err(err)?;
            let applied =
                sage_scene::formats::objects_json::apply(body, &mut objects).map_err(err)?;
            (applied.unmatched == 0)
                .then_some(())
                .ok_or("entries match no label".into())
        }
        "camera" => sage_splat::CameraSpec::parse(body)
            .and_then(|c| c.camera())
            .map(|_| ())
            .map_err(err),
        "episode" => {
            let line: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            let file = dir.path().join("split.jsonl");
            std::fs::write(&file, format!("{line}\n")).unwrap();
            sage_dataset::formats::jsonl::read(&file)
                .map(|_| ())
                .map_err(err)
        }
        "replay" => {
            let file = dir.path().join("replay.jsonl");
            std::fs::write(&file, body).unwrap();
            sage_agents::replay::ReplayFile::read(&file)
                .map(|_| ())
                .map_err(err)
        }
        "eval-record" => serde_json::from_str::<sage_eval::EvalRecord>(body)
            .map(|_| ())
            .map_err(|e| e.to_string()),
        "navila-part" => {
            let part: Vec<sage_traindata::output::NavilaSample> =
                serde_json::from_str(body).map_err(|e| e.to_string())?;
            part.iter().try_for_each(|x| {
                let step: usize = x
                    .video_id
                    .rsplit('-')
                    .next()
                    .unwrap_or("")
                    .parse()
                    .map_err(|_| format!("{}: no step", x.video_id))?;
                (x.frames.len() == step + 1 && x.a.starts_with("The next action is "))
                    .then_some(())
                    .ok_or(format!("{}: frames or answer", x.video_id))
            })
        }
        "train-episode" => {
            let e: sage_traindata::sample::EpisodeSample =
                serde_json::from_str(body).map_err(|e| e.to_string())?;
            (e.files.len() == e.actions.len()
                && e.steps.len() == e.actions.len()
                && e.words.len() == e.actions.len())
            .then_some(())
            .ok_or("files, steps, words and actions differ in length".into())
        }
        "dataset-info" => {
            let preset = sage_traindata::ActionPreset::named("navila_small").map_err(err)?;
            sage_traindata::output::write_navila(dir.path(), &[], &preset, 10_000, 0, "x")
                .map_err(err)?;
            let real: Value =
                sage_io::files::read_json(&dir.path().join("dataset_info.json")).map_err(err)?;
            let example: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            same_shape(&example, &real, "info").and_then(|()| {
                real.as_object()
                    .unwrap()
                    .keys()
                    .all(|k| example.get(k).is_some())
                    .then_some(())
                    .ok_or("the example misses a field".into())
            })
        }
        "semantic-map" => {
            let scene = sage_synth::generate(&sage_synth::SynthConfig {
                rooms: 2,
                objects: 10,
                gaussians: 1000,
                ..Default::default()
            })
            .map_err(err)?;
            let real = serde_json::to_value(sage_nav::SemanticMap::build(&scene)).unwrap();
            let example: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            same_shape(&example, &real, "map")
        }
        "run-record" => {
            let example: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            let mut details = example.clone();
            let fields = details.as_object_mut().unwrap();
            let command = fields.remove("command").unwrap();
            let seed = fields.remove("seed").unwrap();
            for k in ["tool", "version"] {
                fields.remove(k);
            }
            sage_io::run::write_run_record(
                dir.path(),
                command.as_str().unwrap(),
                seed.as_u64(),
                details,
            )
            .map_err(err)?;
            let written: Value =
                sage_io::files::read_json(&dir.path().join(sage_io::run::RUN_RECORD))
                    .map_err(err)?;
            (written == example)
                .then_some(())
                .ok_or(format!("the writer gives {written}"))
        }
        "dtw" => {
            // {"reference": [[x, y]…], "query": […], "cost": "manhattan"|"euclidean",
            //  "threshold": d, "dtw": expected, "ndtw": expected}
            let v: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            let points =
                |k: &str| -> Vec<[f64; 2]> { serde_json::from_value(v[k].clone()).unwrap() };
            let (r, q) = (points("reference"), points("query"));
            let manhattan = |a: &[f64; 2], b: &[f64; 2]| (a[0] - b[0]).abs() + (a[1] - b[1]).abs();
            let cost = match v["cost"].as_str() {
                Some("manhattan") => sage_metrics::dtw::dtw(&r, &q, manhattan),
                _ => sage_metrics::dtw::dtw(&r, &q, sage_metrics::dtw::euclidean),
            };
            let ndtw =
                sage_metrics::dtw::ndtw_from(cost, r.len(), v["threshold"].as_f64().unwrap());
            let close = |a: f64, k: &str| (a - v[k].as_f64().unwrap()).abs() < 1e-9;
            (close(cost, "dtw") && close(ndtw, "ndtw"))
                .then_some(())
                .ok_or(format!("computed dtw {cost}, ndtw {ndtw}"))
        }
        "goal-box" => {
            // {"goal": [x, y], "entries": [LabelledBox…], "chosen": item_id}
            let v: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            let entries: Vec<sage_metrics::distance::LabelledBox> =
                serde_json::from_value(v["entries"].clone()).map_err(|e| e.to_string())?;
            let goal: [f64; 2] =
                serde_json::from_value(v["goal"].clone()).map_err(|e| e.to_string())?;
            let chosen = sage_metrics::distance::official_goal_box(&entries, goal)
                .map(|b| b.item_id)
                .unwrap_or_default();
            (chosen == v["chosen"].as_str().unwrap_or(""))
                .then_some(())
                .ok_or(format!("chosen '{chosen}'"))
        }
        "metrics" => {
            // {"mode": M, "record": EpisodeRecord, "expected": {metric: value}}
            let v: Value = serde_json::from_str(body).map_err(|e| e.to_string())?;
            let record: sage_metrics::EpisodeRecord =
                serde_json::from_value(v["record"].clone()).map_err(|e| e.to_string())?;
            let mode: sage_metrics::Mode =
                serde_json::from_value(v["mode"].clone()).map_err(|e| e.to_string())?;
            let m = sage_metrics::evaluate(&record, mode).map_err(err)?;
            let named: BTreeMap<&str, Option<f64>> = m.named().into_iter().collect();
            v["expected"]
                .as_object()
                .unwrap()
                .iter()
                .try_for_each(|(k, want)| {
                    let got = named.get(k.as_str()).copied().flatten();
                    match (got, want.as_f64()) {
                        (Some(g), Some(w)) if (g - w).abs() < 1e-4 => Ok(()),
                        (None, None) => Ok(()),
                        _ => Err(format!("{k}: computed {got:?}, documented {want}")),
                    }
                })
        }
        other => Err(format!("unknown example kind '{other}'")),
    }
}

#[test]
fn every_documented_example_is_read_by_sage3d() {
    let by_kind = all_examples();
    for required in [
        "labels",
        "structure",
        "occupancy",
        "objects",
        "camera",
        "semantic-map",
        "episode",
        "eval-record",
        "replay",
        "run-record",
        "dtw",
        "metrics",
        "goal-box",
        "navila-part",
        "dataset-info",
        "train-episode",
    ] {
        assert!(
            by_kind.contains_key(required),
            "docs lost their {required} example"
        );
    }
    let failures: Vec<String> = by_kind
        .iter()
        .flat_map(|(kind, blocks)| blocks.iter().map(move |(doc, body)| (kind, doc, body)))
        .filter_map(|(kind, doc, body)| {
            check(kind, body)
                .err()
                .map(|e| format!("docs/{doc} example:{kind}: {e}"))
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The words after `sage3d` (or after `cargo run --release --`) of a command line, with the
/// usage brackets of the README's tables removed.
fn command_words(line: &str) -> Option<Vec<String>> {
    let words: Vec<String> = line
        .replace(['[', ']', '\\', '`'], " ")
        .replace(" | ", " ")
        .split_whitespace()
        .filter(|w| *w != "|")
        .map(str::to_string)
        .collect();
    let start = if words.first().is_some_and(|w| w == "cargo") {
        words.iter().position(|w| w == "--")
    } else {
        words.iter().position(|w| w == "sage3d")
    }?;
    let mut rest = &words[start + 1..];
    while rest
        .first()
        .is_some_and(|w| w == "--threads" || w == "--config")
    {
        rest = rest.get(2..).unwrap_or_default();
    }
    Some(rest.to_vec())
}

/// The `sage3d …` command lines of the README: in code blocks (continuation lines joined,
/// comments cut) and in inline code spans.
fn readme_commands() -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let mut commands = Vec::new();
    let mut in_block = false;
    let mut pending = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if in_block {
            let code = line.split(" #").next().unwrap_or("").trim();
            pending.push_str(code.trim_end_matches('\\'));
            pending.push(' ');
            if !code.ends_with('\\') {
                commands.extend(command_words(&pending));
                pending.clear();
            }
        } else {
            for (k, span) in line.split('`').enumerate() {
                if k % 2 == 1 && span.starts_with("sage3d ") {
                    commands.extend(command_words(span));
                }
            }
        }
    }
    commands.retain(|w| !w.is_empty());
    commands
}

#[test]
fn every_readme_command_names_real_subcommands_and_flags() {
    let commands = readme_commands();
    assert!(
        commands.len() >= 10,
        "the README shows too few commands: {commands:?}"
    );
    for words in commands {
        // The subcommand path: the leading lower-case words that are not values.
        let path: Vec<&str> = words
            .iter()
            .map(String::as_str)
            .take_while(|w| {
                !w.starts_with('-') && w.chars().all(|c| c.is_ascii_lowercase() || c == '-')
            })
            .collect();
        let mut args = path.clone();
        args.push("--help");
        let help = ok(&args);
        for flag in words.iter().filter(|w| w.starts_with("--")) {
            let flag = flag.split('=').next().unwrap();
            let known = help.match_indices(flag).any(|(i, _)| {
                !help[i + flag.len()..].starts_with(|c: char| c.is_ascii_alphanumeric() || c == '-')
            });
            assert!(
                flag == "--threads" || known,
                "README: `sage3d {}` uses {flag}, which `sage3d {} --help` does not know",
                words.join(" "),
                path.join(" ")
            );
        }
    }
}
