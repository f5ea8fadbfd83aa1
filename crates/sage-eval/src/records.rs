//! The per-episode records file (`RUN/episodes.jsonl`): appending flushed lines, reading it
//! back on resume, and putting it in episode-id order when the run ends.
//!
//! A crash can only cut the last line short (every line is written whole and flushed before
//! the next starts), so on resume an unfinished or unreadable last line is dropped and the file
//! rewritten without it; any other bad line, an id outside the split or an id recorded twice is
//! an error naming the line, because it means the file is not this run's.
//!
//! Every reader of a records file (resume, sort, the report, a rescoring, a merge of shards,
//! the viewer) reads a line through [`EvalRecord::from_line`], which checks what the record
//! holds of positions and numbers ([`EvalRecord::check`]) as the episode readers check
//! episodes: a record edited by hand or damaged is refused there, naming line and field,
//! rather than failing later in a drawing or a metric without saying where.

use sage_core::{Error, MAX_COORDINATE, Result, ResultExt};
use sage_dataset::Task;
use sage_dataset::episode::check_point;
use sage_dataset::slices::Slices;
use sage_env::Termination;
use sage_env::agents::Fault;
use sage_lang::{InstructionType, Level};
use sage_metrics::distance::OfficialGoal;
use sage_metrics::{EpisodeMetrics, EpisodeRecord};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// One finished episode: the line appended to `RUN/episodes.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalRecord {
    /// Episode id.
    pub episode_id: String,
    /// Scene name.
    pub scene: String,
    /// `vln` or `nogoal`.
    pub task: Task,
    /// Instruction level (absent for no-goal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<Level>,
    /// Instruction type.
    pub instruction_type: InstructionType,
    /// Complexity slices.
    pub slices: Slices,
    /// The agent's name.
    pub agent: String,
    /// Why the episode ended (absent when it failed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub termination: Option<Termination>,
    /// The metrics in the run's mode (absent when it failed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<EpisodeMetrics>,
    /// Why the episode failed (agent, reset or metric error); the run goes on without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// What kind of failure `error` is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<Failure>,
    /// Faults of a remote agent's server, each attempt that failed, recovered or not.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<Fault>,
    /// What a remote agent did with a reply that a reader should know (a reply cut to the
    /// `repeat` cap).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Everything the metrics need, so any mode can be recomputed and paths drawn later.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record: Option<EpisodeRecord>,
    /// Where the scene's object bodies came from: how many objects had each source
    /// (`published`, `mesh`, `gaussians`, `box`), so that results made with different physics
    /// are not compared unknowingly.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub bodies: BTreeMap<String, usize>,
}

impl EvalRecord {
    /// What kind of failure the record's error is; records written before failures had kinds
    /// count as [`Failure::EpisodeError`].
    pub fn failure_kind(&self) -> Failure {
        self.failure.unwrap_or(Failure::EpisodeError)
    }

    /// Reads one line of a records file as a record and checks it ([`EvalRecord::check`]);
    /// an error is placed at `at` (the line), the caller names the file.
    ///
    /// # Errors
    ///
    /// A line that is not a record, or the first bad field of one.
    pub fn from_line(line: &str, at: &str) -> Result<EvalRecord> {
        let rec: EvalRecord =
            serde_json::from_str(line).map_err(|e| Error::format(at, e.to_string()))?;
        rec.check().within(at)?;
        Ok(rec)
    }

    /// Checks a record read from a file: its metrics within their ranges
    /// ([`EpisodeMetrics::check`]), every position of its episode record (start, steps,
    /// reference path, goal point and footprint, the published goal box) finite and within
    /// ±[`MAX_COORDINATE`] m, every heading, time, length, intensity and distance of its f32
    /// fields finite (a number too large for f32 reads as infinity; JSON holds no other
    /// non-finite number).
    ///
    /// # Errors
    ///
    /// The first bad field, named (`record.steps[0].position`).
    pub fn check(&self) -> Result<()> {
        if let Some(m) = &self.metrics {
            m.check().within("metrics")?;
        }
        let Some(r) = &self.record else {
            return Ok(());
        };
        check_episode_record(r).within("record")
    }
}

/// [`EvalRecord::check`] on the episode record itself.
fn check_episode_record(r: &EpisodeRecord) -> Result<()> {
    check_point(r.start, "start")?;
    finite(r.start_yaw, "start_yaw")?;
    for (i, s) in r.steps.iter().enumerate() {
        let at = |field: &str| format!("steps[{i}].{field}");
        check_point(s.position, &at("position"))?;
        for (field, v) in [
            ("yaw", s.yaw),
            ("time", s.time),
            ("commanded", s.commanded),
            ("achieved", s.achieved),
            ("intensity", s.intensity),
        ] {
            finite(v, &at(field))?;
        }
        if let Some(d) = s.geodesic_to_goal_point {
            finite(d, &at("geodesic_to_goal_point"))?;
        }
    }
    for (i, p) in r.reference_path.iter().enumerate() {
        check_point(*p, &format!("reference_path[{i}]"))?;
    }
    if let Some(g) = &r.goal {
        check_floor_point(g.point, "goal.point")?;
        for (i, p) in g.footprint.iter().flatten().enumerate() {
            check_floor_point(*p, &format!("goal.footprint[{i}]"))?;
        }
    }
    if let OfficialGoal::Map { chosen: Some(b) } = &r.official_goal {
        check_floor_point(b.min, "official_goal.chosen.min")?;
        check_floor_point(b.max, "official_goal.chosen.max")?;
    }
    for (field, d) in [
        ("start_to_region", r.geodesics.start_to_region),
        ("start_to_point", r.geodesics.start_to_point),
        ("final_to_region", r.geodesics.final_to_region),
    ] {
        if let Some(d) = d {
            finite(d, &format!("geodesics.{field}"))?;
        }
    }
    Ok(())
}

/// Checks a number read from a file: finite.
fn finite(v: f32, at: &str) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::format(at, format!("{v}: expected a finite number")))
    }
}

/// Checks a floor point `[x, y]` read from a file as [`check_point`] checks a point.
fn check_floor_point(p: [f64; 2], at: &str) -> Result<()> {
    if p.iter().all(|c| c.abs() <= f64::from(MAX_COORDINATE)) {
        Ok(())
    } else {
        Err(Error::format(
            at,
            format!("{p:?}: expected finite coordinates within ±{MAX_COORDINATE} m"),
        ))
    }
}

/// Why an episode was not scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Failure {
    /// Its scene could not be loaded.
    SceneLoad,
    /// The agent's model server gave no usable reply after every retry.
    ModelServer,
    /// The agent could not act on it, or the environment or the metrics failed.
    EpisodeError,
}

impl Failure {
    /// The failure's name as records store it.
    pub fn as_str(self) -> &'static str {
        match self {
            Failure::SceneLoad => "scene_load",
            Failure::ModelServer => "model_server",
            Failure::EpisodeError => "episode_error",
        }
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The records file opened for appending.
#[derive(Debug)]
pub struct Appender {
    path: PathBuf,
    file: File,
}

impl Appender {
    /// Opens (creating) `path` for appending.
    ///
    /// # Errors
    ///
    /// The file cannot be opened.
    pub fn open(path: &Path) -> Result<Appender> {
        let file = File::options()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(Appender {
            path: path.to_path_buf(),
            file,
        })
    }

    /// Appends `rec` as one line and flushes it, so a crash loses at most this line.
    ///
    /// # Errors
    ///
    /// The write fails.
    pub fn append(&mut self, rec: &EvalRecord) -> Result<()> {
        let mut line = serde_json::to_vec(rec).map_err(|e| Error::invalid(e.to_string()))?;
        line.push(b'\n');
        self.file
            .write_all(&line)
            .and_then(|()| self.file.flush())
            .map_err(|e| Error::io(&self.path, e))
    }
}

/// The records of `text` and the byte length of the lines they came from; `tolerate_tail`
/// drops an unfinished or unreadable last line, or one whose record fails its checks, instead
/// of failing on it (its episode runs again).
fn parse(
    path: &Path,
    text: &str,
    ids: &BTreeSet<&str>,
    tolerate_tail: bool,
) -> Result<(Vec<EvalRecord>, usize)> {
    let mut records = Vec::new();
    let mut seen = BTreeSet::new();
    let mut kept = 0;
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    for (k, line) in lines.iter().enumerate() {
        let last = k + 1 == lines.len();
        let whole = line.ends_with('\n');
        let where_ = format!("line {}", k + 1);
        let parsed = if whole {
            EvalRecord::from_line(line, &where_).in_file(path)
        } else {
            Err(Error::format(where_.clone(), "unfinished line").in_file(path))
        };
        let rec = match parsed {
            Ok(rec) => rec,
            Err(_) if last && tolerate_tail => break,
            Err(e) => return Err(e),
        };
        if !ids.contains(rec.episode_id.as_str()) {
            return Err(Error::format(
                where_,
                format!("episode {} is not in this split", rec.episode_id),
            )
            .in_file(path));
        }
        if !seen.insert(rec.episode_id.clone()) {
            return Err(Error::format(
                where_,
                format!("episode {} is recorded twice", rec.episode_id),
            )
            .in_file(path));
        }
        kept += line.len();
        records.push(rec);
    }
    Ok((records, kept))
}

fn read_text(path: &Path) -> Result<String> {
    match std::fs::read_to_string(path) {
        Ok(t) => Ok(t),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(String::new()),
        Err(e) => Err(Error::io(path, e)),
    }
}

/// Prepares `path` for a resumed run: drops a cut-short last line (rewriting the file without
/// it) and returns the ids already recorded.
///
/// # Errors
///
/// An unreadable file, a bad line other than the last, an id outside `ids` or recorded twice.
pub fn resume(path: &Path, ids: &BTreeSet<&str>) -> Result<BTreeSet<String>> {
    let text = read_text(path)?;
    let (records, kept) = parse(path, &text, ids, true)?;
    if kept < text.len() {
        sage_io::files::write_atomic(path, |w| w.write_all(&text.as_bytes()[..kept]))?;
    }
    Ok(records.into_iter().map(|r| r.episode_id).collect())
}

/// Every record of `path`, sorted by episode id, with the file rewritten in that order when
/// it is not (each line kept byte for byte: printing a parsed record again could move a float
/// by an ulp).
///
/// # Errors
///
/// As [`resume`], and a cut-short last line is an error here too; a write error.
pub fn sort(path: &Path, ids: &BTreeSet<&str>) -> Result<Vec<EvalRecord>> {
    let text = read_text(path)?;
    let (records, _) = parse(path, &text, ids, false)?;
    // Strict parsing read every line into a record, so lines and records pair up.
    let mut lines: Vec<(EvalRecord, &str)> = records
        .into_iter()
        .zip(text.split_inclusive('\n'))
        .collect();
    if !lines.is_sorted_by(|a, b| a.0.episode_id <= b.0.episode_id) {
        lines.sort_by(|a, b| a.0.episode_id.cmp(&b.0.episode_id));
        sage_io::files::write_atomic(path, |w| {
            lines
                .iter()
                .try_for_each(|(_, l)| w.write_all(l.as_bytes()))
        })?;
    }
    Ok(lines.into_iter().map(|(r, _)| r).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_dataset::Task;
    use sage_dataset::slices::Slices;
    use sage_lang::InstructionType;

    fn rec(id: &str) -> EvalRecord {
        EvalRecord {
            episode_id: id.into(),
            scene: "home1".into(),
            task: Task::Vln,
            level: None,
            instruction_type: InstructionType::SingleGoal,
            slices: Slices {
                assets: "few".into(),
                path: "short".into(),
            },
            agent: "oracle".into(),
            termination: None,
            metrics: None,
            error: Some("no path".into()),
            failure: None,
            faults: Vec::new(),
            notes: Vec::new(),
            record: None,
            bodies: Default::default(),
        }
    }

    /// `lines` with the first record's metrics replaced by `metrics` (JSON).
    fn with_metrics(lines: &str, metrics: &str) -> String {
        let first = lines.lines().next().unwrap();
        let mut rec: serde_json::Value = serde_json::from_str(first).unwrap();
        rec["metrics"] = serde_json::from_str(metrics).unwrap();
        lines.replacen(first, &rec.to_string(), 1)
    }

    #[test]
    fn a_cut_last_line_is_dropped_and_other_damage_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("episodes.jsonl");
        let ids: BTreeSet<&str> = ["a", "b", "c"].into();
        {
            let mut w = Appender::open(&path).unwrap();
            w.append(&rec("b")).unwrap();
            w.append(&rec("a")).unwrap();
        }
        let whole = std::fs::read_to_string(&path).unwrap();
        let cut = &whole[..whole.len() - 10];
        std::fs::write(&path, cut).unwrap();
        let done = resume(&path, &ids).unwrap();
        assert_eq!(done, BTreeSet::from(["b".to_string()]));
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            whole.lines().next().unwrap().to_string() + "\n"
        );
        Appender::open(&path).unwrap().append(&rec("a")).unwrap();
        let all = sort(&path, &ids).unwrap();
        assert_eq!(all, vec![rec("a"), rec("b")]);
        // The file now holds the same lines in id order.
        let mut lines: Vec<&str> = whole.lines().collect();
        lines.reverse();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            lines.join("\n") + "\n"
        );
        // A damaged line before the last, a duplicate, a foreign id: errors naming the line.
        for (text, needle) in [
            (format!("{{oops\n{whole}"), "line 1"),
            (
                format!("{whole}{}\n", whole.lines().next().unwrap()),
                "line 3: episode b is recorded twice",
            ),
            (whole.replace("\"a\"", "\"z\""), "not in this split"),
            (
                with_metrics(&whole, r#"{"sr":7.0}"#),
                "metrics.sr: 7: no episode scores this (expected within 0-1)",
            ),
            (
                with_metrics(&whole, r#"{"spl":1e30}"#),
                "metrics.spl: 1000000000000000000000000000000",
            ),
            (
                with_metrics(&whole, r#"{"ne":-4.0}"#),
                "metrics.ne: -4: no episode scores this (expected finite and at least 0)",
            ),
        ] {
            std::fs::write(&path, &text).unwrap();
            let e = resume(&path, &ids).map(|_| ()).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
        assert!(
            resume(&dir.path().join("none.jsonl"), &ids)
                .unwrap()
                .is_empty()
        );
    }
}
