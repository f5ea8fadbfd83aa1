//! The aggregate of a run: metric means overall and per slice of the three axes (task,
//! instruction level and type, scene assets and path length), and their text tables.
//!
//! Computed from the records sorted by episode id, so the sums (and the bytes of
//! `summary.json`) do not depend on the order episodes finished in.

use crate::records::{EvalRecord, Failure};
use crate::settings::EvalSettings;
use sage_env::agents::FaultKind;
use sage_metrics::{Aggregate, Dtw, Mode, Scoring, aggregate};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

/// The slice axes, in table order.
pub const AXES: [&str; 5] = ["task", "level", "instruction_type", "assets", "path"];

/// A metric column of the summary tables: the text tables and the report show the same ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column {
    /// The metric's name in the aggregates (`summary.json`).
    pub metric: &'static str,
    /// The column's heading.
    pub head: &'static str,
    /// The unit of the mean (empty for ratios, scores and counts).
    pub unit: &'static str,
}

/// Every metric column, in table order: VLN success and path, collisions, the continuous
/// metrics, path fidelity, then the no-goal metrics and the step count.
pub const COLUMNS: [Column; 16] = {
    const fn col(metric: &'static str, head: &'static str, unit: &'static str) -> Column {
        Column { metric, head, unit }
    }
    [
        col("sr", "SR", ""),
        col("osr", "OSR", ""),
        col("spl", "SPL", ""),
        col("ne", "NE", "m"),
        col("tl", "TL", "m"),
        col("cr", "CR", ""),
        col("csr", "CSR", ""),
        col("icp", "ICP", ""),
        col("ps", "PS", ""),
        col("ndtw", "nDTW", ""),
        col("sdtw", "SDTW", ""),
        col("episode_time", "time", "s"),
        col("explored_area", "area", "m²"),
        col("explored_cells", "cells", ""),
        col("coverage", "coverage", ""),
        col("steps", "steps", ""),
    ]
};

/// `RUN/summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The agent.
    pub agent: String,
    /// Dataset split.
    pub split: String,
    /// The metric mode the numbers are in.
    pub mode: Mode,
    /// The alignment nDTW and SDTW used.
    #[serde(default)]
    pub dtw: Dtw,
    /// Episodes recorded.
    pub episodes: usize,
    /// Ids of the faulted episodes: recorded with an error, never scored, left out of the means
    /// (the field keeps its first name for readers of older summaries).
    pub failed: Vec<String>,
    /// Faulted episodes per kind of failure (kinds that occurred).
    #[serde(default)]
    pub failures: BTreeMap<Failure, usize>,
    /// For each kind of failure, the first faulted episode (by id) and its error:
    /// `"home1-n0: agent oracle on episode home1-n0: …"`.
    #[serde(default)]
    pub failure_examples: BTreeMap<Failure, String>,
    /// Model-server faults per kind over every episode, recovered or not (kinds that occurred).
    #[serde(default)]
    pub faults: BTreeMap<FaultKind, usize>,
    /// Means over every scored episode.
    pub overall: Aggregate,
    /// Axis → slice value → means over the scored episodes of that slice.
    pub slices: BTreeMap<String, BTreeMap<String, Aggregate>>,
}

/// The value of `rec` on `axis` (`none` where it has none).
fn slice_of(rec: &EvalRecord, axis: &str) -> String {
    let name = |v: serde_json::Value| v.as_str().unwrap_or("none").to_string();
    match axis {
        "task" => name(serde_json::to_value(rec.task).unwrap_or_default()),
        "level" => name(serde_json::to_value(rec.level).unwrap_or_default()),
        "instruction_type" => name(serde_json::to_value(rec.instruction_type).unwrap_or_default()),
        "assets" => rec.slices.assets.clone(),
        _ => rec.slices.path.clone(),
    }
}

impl Summary {
    /// The summary of `records` (sorted by episode id) of a run with `settings`.
    pub fn of(settings: &EvalSettings, records: &[EvalRecord]) -> Summary {
        Summary::of_records(
            &settings.agent.to_string(),
            &settings.split,
            settings.scoring(),
            records,
        )
    }

    /// The summary of `records` (sorted by episode id) of agent `agent` over split `split`,
    /// scored with `scoring`: what [`Summary::of`] computes, for callers that hold no
    /// [`EvalSettings`] (a rescoring reads its run's from the run record).
    pub fn of_records(
        agent: &str,
        split: &str,
        scoring: Scoring,
        records: &[EvalRecord],
    ) -> Summary {
        let scored: Vec<&EvalRecord> = records.iter().filter(|r| r.metrics.is_some()).collect();
        let mode = scoring.mode;
        let means =
            |rs: &[&EvalRecord]| aggregate(mode, rs.iter().filter_map(|r| r.metrics.as_ref()));
        let slices = AXES
            .iter()
            .map(|axis| {
                let mut by: BTreeMap<String, Vec<&EvalRecord>> = BTreeMap::new();
                for r in &scored {
                    by.entry(slice_of(r, axis)).or_default().push(r);
                }
                let aggs = by.into_iter().map(|(k, rs)| (k, means(&rs))).collect();
                (axis.to_string(), aggs)
            })
            .collect();
        let mut failures = BTreeMap::new();
        let mut failure_examples = BTreeMap::new();
        for r in records.iter().filter(|r| r.metrics.is_none()) {
            let kind = r.failure_kind();
            *failures.entry(kind).or_insert(0) += 1;
            failure_examples.entry(kind).or_insert_with(|| {
                format!(
                    "{}: {}",
                    r.episode_id,
                    r.error.as_deref().unwrap_or("no error recorded")
                )
            });
        }
        let mut faults = BTreeMap::new();
        for f in records.iter().flat_map(|r| &r.faults) {
            *faults.entry(f.kind).or_insert(0) += 1;
        }
        Summary {
            agent: agent.to_string(),
            split: split.to_string(),
            mode,
            dtw: scoring.dtw,
            episodes: records.len(),
            failed: records
                .iter()
                .filter(|r| r.metrics.is_none())
                .map(|r| r.episode_id.clone())
                .collect(),
            failures,
            failure_examples,
            faults,
            overall: means(&scored),
            slices,
        }
    }

    /// The faulted episodes per kind, as text: `2 model_server, 1 scene` (`none`).
    pub fn failure_counts(&self) -> String {
        counts(self.failures.iter().map(|(k, n)| (k.as_str(), *n)))
    }

    /// The faults per kind, as text: `3 server_error, 1 substituted` (`none`).
    pub fn fault_counts(&self) -> String {
        counts(self.faults.iter().map(|(k, n)| (k.as_str(), *n)))
    }

    /// The metric columns of the tables (text and report) that any aggregate of the summary
    /// holds, in [`COLUMNS`] order; every table of a summary has the same columns.
    pub fn columns(&self) -> Vec<&'static Column> {
        let held: BTreeSet<&str> = std::iter::once(&self.overall)
            .chain(self.slices.values().flat_map(|s| s.values()))
            .flat_map(|a| a.means.keys().map(String::as_str))
            .collect();
        COLUMNS.iter().filter(|c| held.contains(c.metric)).collect()
    }

    /// Short text tables: first the faulted episodes and the faults (when any), then the
    /// overall row and one block per axis, with the report's metric columns
    /// ([`Summary::columns`]).
    pub fn table(&self) -> String {
        let cols = self.columns();
        let mut t = String::new();
        if !self.failed.is_empty() {
            let _ = writeln!(
                t,
                "FAULTED: {} of {} episodes were never scored ({}):",
                self.failed.len(),
                self.episodes,
                self.failure_counts()
            );
            for (kind, example) in &self.failure_examples {
                let _ = writeln!(t, "  {kind}, e.g. {example}");
            }
        }
        if !self.faults.is_empty() {
            let _ = writeln!(t, "model-server faults: {}", self.fault_counts());
        }
        let _ = writeln!(
            t,
            "agent {} · split {} · mode {} · {} DTW · {} episodes ({} faulted)",
            self.agent,
            self.split,
            self.mode,
            self.dtw,
            self.episodes,
            self.failed.len()
        );
        // The name column fits the longest slice value or axis name (and `overall`).
        let name_w = self
            .slices
            .iter()
            .flat_map(|(axis, s)| std::iter::once(axis).chain(s.keys()))
            .map(|n| n.chars().count())
            .fold("overall".len(), usize::max);
        let header = |t: &mut String, axis: &str| {
            let _ = write!(t, "{axis:<name_w$} {:>5}", "n");
            for c in &cols {
                let _ = write!(t, " {:>8}", c.head);
            }
            t.push('\n');
        };
        let row = |t: &mut String, name: &str, a: &Aggregate| {
            let _ = write!(t, "{name:<name_w$} {:>5}", a.episodes);
            for c in &cols {
                match a.means.get(c.metric) {
                    Some(v) => {
                        let _ = write!(t, " {v:>8.3}");
                    }
                    None => {
                        let _ = write!(t, " {:>8}", "-");
                    }
                }
            }
            t.push('\n');
        };
        header(&mut t, "");
        row(&mut t, "overall", &self.overall);
        for axis in AXES {
            t.push('\n');
            header(&mut t, axis);
            for (name, a) in self.slices.get(axis).into_iter().flatten() {
                row(&mut t, name, a);
            }
        }
        t
    }
}

/// `n kind` pairs joined by commas, or `none`.
fn counts<'a>(pairs: impl Iterator<Item = (&'a str, usize)>) -> String {
    let text: Vec<String> = pairs.map(|(k, n)| format!("{n} {k}")).collect();
    if text.is_empty() {
        "none".to_string()
    } else {
        text.join(", ")
    }
}
