//! Merging the records of an evaluation run in shards (one per node or scene group) into the
//! run folder one evaluation over the union would have written.

use crate::evaluator::{
    RecordedRun, env_config, env_record, mark_unfinished, recorded_settings, scene_inputs,
};
use crate::folder::{RECORDS_FILE, SUMMARY_FILE, mark_finished};
use crate::records::EvalRecord;
use crate::report::{ReportJob, ReportOutcome};
use crate::settings::EvalSettings;
use crate::summary::Summary;
use sage_core::{Error, Result};
use sage_dataset::folder::split_episodes;
use sage_env::EnvConfig;
use sage_io::files::{write_atomic, write_json};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::Path;

/// Merges the records of evaluation shards (the text of each shard's `episodes.jsonl`) into one
/// run folder `out`: `episodes.jsonl` sorted by episode id, `summary.json` and
/// `sage3d_run.json`, the same bytes as one evaluation over the union writes them (which also
/// ends with its records in episode-id order). Returns the summary. Callers hold the lock on
/// `out` ([`sage_io::lock::FolderLock`]) while it and the report are written.
///
/// The run record's environment (`env`) is `env`, the one the shards ran in (their runner's
/// [`crate::Runner::config`]); given none, it is the one `sage3d eval` runs `agent` in
/// ([`env_config`]) when `agent` is the settings' own agent, and none for another name (a
/// Python agent's): the records do not say which environment they ran in.
///
/// # Errors
///
/// A line that is not a record or holds a bad field ([`EvalRecord::from_line`]), an episode
/// not in the split or recorded by two shards (naming shard and line), or a write error.
pub fn merge_shards(
    settings: &EvalSettings,
    agent: &str,
    env: Option<&EnvConfig>,
    shards: &[String],
    out: &Path,
) -> Result<Summary> {
    let summary = merge_unfinished(settings, agent, env, shards, out)?;
    mark_finished(out)?;
    Ok(summary)
}

/// [`merge_shards`] that also writes the merged run's report (`report`) before it marks the
/// run finished, as one evaluation over the union does.
///
/// # Errors
///
/// As [`merge_shards`] and [`crate::report::write_with_options`].
pub fn merge_shards_with_report(
    settings: &EvalSettings,
    agent: &str,
    env: Option<&EnvConfig>,
    shards: &[String],
    out: &Path,
    report: &ReportJob,
) -> Result<(Summary, ReportOutcome)> {
    let summary = merge_unfinished(settings, agent, env, shards, out)?;
    Ok((summary, report.finish(out)?))
}

/// The environment `sage3d eval` runs `agent` in under `settings`, when `agent` is the
/// settings' own agent (a built-in one); `None` for any other name (a Python agent's), or an
/// agent that cannot be made here (a replay file missing where the shards are merged): the
/// merge cannot tell which environment those ran in.
fn plain_env(settings: &EvalSettings, agent: &str) -> Option<EnvConfig> {
    if agent != settings.agent.to_string() {
        return None;
    }
    let maker = settings.agent.maker().ok()?;
    env_config(settings, &maker).ok()
}

/// [`merge_shards`] up to its summary, recording `env` as the run's environment: the run
/// record, written first, stays marked unfinished.
fn merge_unfinished(
    settings: &EvalSettings,
    agent: &str,
    env: Option<&EnvConfig>,
    shards: &[String],
    out: &Path,
) -> Result<Summary> {
    let (file, episodes) = split_episodes(&settings.dataset, &settings.split)?;
    let ids: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
    // Lines are kept as the shards wrote them: parsing and printing again would move some
    // floats by an ulp (serde_json's parser is not exactly rounding), and the summary is
    // computed from the parsed records as `sage3d eval` computes it from its file.
    let mut all: BTreeMap<String, (&str, EvalRecord)> = BTreeMap::new();
    for (i, text) in shards.iter().enumerate() {
        for (line, l) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            let at = || format!("shard {i}, line {}", line + 1);
            let rec = EvalRecord::from_line(l, &at())?;
            if !ids.contains(rec.episode_id.as_str()) {
                return Err(Error::format(
                    at(),
                    format!(
                        "episode {} is not in split {}",
                        rec.episode_id, settings.split
                    ),
                ));
            }
            if all.insert(rec.episode_id.clone(), (l, rec)).is_some() {
                return Err(Error::format(at(), "episode recorded by two shards"));
            }
        }
    }
    let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
    let recorded = recorded_settings(settings, agent)?;
    // The scenes as they are where the shards are merged; without them there, none.
    let dirs = sage_io::scenes::scene_dirs_by_name(&settings.scenes).unwrap_or_default();
    let scenes = scene_inputs(&episodes, &dirs);
    let env = match env {
        Some(env) => Some(env_record(env)?),
        None => plain_env(settings, agent)
            .map(|e| env_record(&e))
            .transpose()?,
    };
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    mark_unfinished(
        out,
        &RecordedRun {
            settings: &recorded,
            env: env.as_ref(),
            dataset_hash: &sage_io::hash::fnv1a64_hex(&bytes).into(),
            scenes: &scenes,
            scenes_folder: Some(settings.scenes.as_path()).filter(|p| p.is_dir()),
        },
        None,
    )?;
    write_atomic(&out.join(RECORDS_FILE), |w| {
        for (line, _) in all.values() {
            w.write_all(line.trim_end().as_bytes())?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })?;
    let records: Vec<EvalRecord> = all.into_values().map(|(_, r)| r).collect();
    let summary = Summary {
        agent: agent.to_string(),
        ..Summary::of(settings, &records)
    };
    write_json(&out.join(SUMMARY_FILE), &summary)?;
    Ok(summary)
}
