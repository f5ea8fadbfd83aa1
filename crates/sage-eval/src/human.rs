//! Human play: a person plays a split's episodes one at a time (in `sage3d view`), and each
//! finished episode is recorded and scored exactly as an evaluation records an agent's.
//!
//! A human run is an evaluation run folder whose agent is `human`: the same run record
//! (settings and dataset hash; a folder resumes only the same split), the same
//! `episodes.jsonl` records scored by [`score_into`], the same `summary.json` over the episodes
//! played so far, so `sage3d report` and every tool that reads run folders read it. The person
//! moves the agent; the steps go through the same [`Env`](sage_env::Env) as an agent's, and the
//! trace it returns at the end is what is scored here. Each finished episode is appended as one
//! flushed line and the summary is rewritten at once, so a closed browser tab or a killed
//! server loses no finished episode, and a split can be played over several sittings. The run
//! record says unfinished only while no episode is played (or a kill came between a record and
//! its summary, which opening the run again mends).

use crate::evaluator::{Split, blank_record, claim, env_config, open_split, score_into};
use crate::folder::{RECORDS_FILE, SUMMARY_FILE, mark_finished};
use crate::records::{self, Appender, EvalRecord};
use crate::settings::EvalSettings;
use crate::summary::Summary;
use sage_agents::AgentKind;
use sage_core::{Error, Result};
use sage_dataset::Episode;
use sage_env::{EnvConfig, EpisodeTrace, SceneContext};
use sage_io::lock::FolderLock;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The note a record carries when the person had the top-down map open: the map shows what no
/// agent sees (the layout, the goal), so such an episode is not a blind human baseline.
pub const NOTE_MAP_SHOWN: &str = "map shown";

/// A human run folder, claimed (one writer) for as long as this value lives.
#[derive(Debug)]
pub struct HumanRun {
    out: PathBuf,
    settings: EvalSettings,
    episodes: Vec<Episode>,
    dirs: BTreeMap<String, PathBuf>,
    recorded: BTreeMap<String, EvalRecord>,
    _lock: FolderLock,
}

impl HumanRun {
    /// Opens (or resumes) the human run of `settings` in `out`: `out` new, empty or a human
    /// run of the same settings and dataset; with `force`, a folder of other files that none
    /// of the run's would replace. `settings.agent` must be `human`.
    ///
    /// # Errors
    ///
    /// Another agent, a folder another command writes or one holding another run, the split's
    /// errors as [`run`](crate::run) gives them, a corrupt records file.
    pub fn open(settings: EvalSettings, out: &Path, force: bool) -> Result<HumanRun> {
        if settings.agent != AgentKind::Human {
            return Err(Error::invalid(format!(
                "a human run records the agent `human`, not `{}`",
                settings.agent
            )));
        }
        let lock = claim(out, force)?;
        // The run record holds the environment the person plays in ([`HumanRun::env_config`]).
        let env = env_config(&settings, &settings.agent.maker()?)?;
        let Split { episodes, dirs, .. } = open_split(
            &settings,
            &settings.agent.to_string(),
            &env,
            None,
            out,
            "play",
        )?;
        let ids: BTreeSet<&str> = episodes.iter().map(|e| e.episode_id.as_str()).collect();
        let played = records::sort(&out.join(RECORDS_FILE), &ids)?;
        // Opening marked the run unfinished; with episodes played it is a finished run again
        // (its summary written anew, over what was played, in case a kill came before it).
        if !played.is_empty() {
            write_summary(out, &settings, &played)?;
        }
        let recorded = played
            .into_iter()
            .map(|r| (r.episode_id.clone(), r))
            .collect();
        Ok(HumanRun {
            out: out.to_path_buf(),
            settings,
            episodes,
            dirs,
            recorded,
            _lock: lock,
        })
    }

    /// The run folder.
    pub fn folder(&self) -> &Path {
        &self.out
    }

    /// The run's settings.
    pub fn settings(&self) -> &EvalSettings {
        &self.settings
    }

    /// The split's episodes, in file order.
    pub fn episodes(&self) -> &[Episode] {
        &self.episodes
    }

    /// The episode `id` of the split.
    pub fn episode(&self, id: &str) -> Option<&Episode> {
        self.episodes.iter().find(|e| e.episode_id == id)
    }

    /// The folder of scene `name`.
    pub fn scene_dir(&self, name: &str) -> Option<&Path> {
        self.dirs.get(name).map(PathBuf::as_path)
    }

    /// The record of episode `id`, once played.
    pub fn recorded(&self, id: &str) -> Option<&EvalRecord> {
        self.recorded.get(id)
    }

    /// How many of the split's episodes have been played.
    pub fn played(&self) -> usize {
        self.recorded.len()
    }

    /// The environment a person plays in: the preset, with the RGB view an agent that reads
    /// images gets (rendering never changes the motion, so the steps are an agent's).
    ///
    /// # Errors
    ///
    /// An unknown preset.
    pub fn env_config(&self) -> Result<EnvConfig> {
        env_config(&self.settings, &self.settings.agent.maker()?)
    }

    /// Scores the finished episode `id` from its `trace` in `ctx` (its scene), records it with
    /// `notes`, and rewrites the summary over every episode played so far.
    ///
    /// # Errors
    ///
    /// An episode outside the split or already played, a trace of another episode or one that
    /// has not ended, a metric error, a write error.
    pub fn record(
        &mut self,
        ctx: &SceneContext,
        id: &str,
        trace: &EpisodeTrace,
        notes: Vec<String>,
    ) -> Result<EvalRecord> {
        let e = self
            .episode(id)
            .ok_or_else(|| Error::invalid(format!("episode {id} is not in the split")))?;
        if self.recorded.contains_key(id) {
            return Err(Error::invalid(format!("episode {id} is already recorded")));
        }
        if trace.episode.id != id || trace.termination.is_none() {
            return Err(Error::invalid(format!(
                "episode {id}: the trace is not this episode's finished one"
            )));
        }
        let mut rec = blank_record(&self.settings.agent.to_string(), e);
        rec.bodies = ctx.body_sources.clone();
        rec.notes = notes;
        score_into(&mut rec, ctx, self.settings.scoring(), trace)?;
        let path = self.out.join(RECORDS_FILE);
        // Opened per record: the sort below replaces the file, which a kept handle would miss.
        Appender::open(&path)?.append(&rec)?;
        self.recorded.insert(id.to_string(), rec.clone());
        let ids: BTreeSet<&str> = self
            .episodes
            .iter()
            .map(|e| e.episode_id.as_str())
            .collect();
        let all = records::sort(&path, &ids)?;
        write_summary(&self.out, &self.settings, &all)?;
        Ok(rec)
    }
}

/// Writes the summary of the human run in `out` over the episodes played (`played`) and marks
/// the run finished: every episode played so far is recorded and counted.
fn write_summary(out: &Path, settings: &EvalSettings, played: &[EvalRecord]) -> Result<()> {
    sage_io::files::write_json(&out.join(SUMMARY_FILE), &Summary::of(settings, played))?;
    mark_finished(out)
}
