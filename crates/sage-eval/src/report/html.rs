//! The report page: one HTML file with inline CSS, charts as inline SVG and maps as base64 PNG
//! data URIs, so it opens offline and can be mailed as one file. It needs no script.

use super::charts::{BarChart, METRICS};
use super::escape::escape;
use super::{MapFile, RunFiles, succeeded};
use crate::records::EvalRecord;
use crate::summary::{AXES, Column};
use base64::Engine;
use sage_core::{Error, Result};
use sage_metrics::{Aggregate, EpisodeMetrics};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

/// Everything the page shows.
#[derive(Debug)]
pub struct PageInput<'a> {
    /// The run folder (the maps' PNGs are read from it to be embedded).
    pub run_dir: &'a Path,
    /// The run's files.
    pub files: &'a RunFiles,
    /// Per axis: the chart and its PNG path relative to the run folder.
    pub charts: &'a [(&'a str, BarChart, String)],
    /// The maps in gallery order.
    pub gallery: &'a [MapFile<'a>],
    /// How many of the gallery's first maps are embedded; the rest are linked.
    pub embed: usize,
    /// Each chart metric's scale end, the same in every chart.
    pub scale_ends: &'a BTreeMap<&'static str, f64>,
    /// The instruction of each episode by id, or why they could not be read.
    pub instructions: &'a Result<BTreeMap<String, String>>,
    /// The episode videos written, in gallery order (linked, not embedded: they are large).
    pub videos: &'a [MapFile<'a>],
}

/// The page's style: readable at a desktop width, and on paper (A4 or Letter) without cut
/// tables or maps split across pages.
const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em auto;padding:0 2em;color:#222;max-width:1400px}\
table{border-collapse:collapse;margin:.5em 0 1.5em}\
th,td{border:1px solid #ccc;padding:.2em .5em;vertical-align:top}\
td.num{text-align:right;font-family:ui-monospace,monospace;white-space:nowrap}\
th{background:#f0f0f0}\
th small{font-weight:normal;color:#555}\
table.meta th{text-align:left}\
table.episodes{width:100%}table.episodes td:first-child{white-space:nowrap}\
td.instr{min-width:14em;overflow-wrap:anywhere}\
.banner{background:#fff3cd;border:1px solid #c9a227;border-left:.4em solid #c9a227;padding:.6em 1em;margin:.6em 0}\
.banner.faulted{background:#fde2e1;border-color:#b3261e}\
.charts svg{display:block;max-width:100%;height:auto;margin:.5em 0 1em;font-family:ui-monospace,monospace;font-size:14px}\
.gallery{display:grid;grid-template-columns:repeat(auto-fill,minmax(30em,1fr));gap:1em}\
figure{margin:0;border:1px solid #ddd;padding:.5em;break-inside:avoid}\
figure img{display:block;width:100%;height:auto}\
figcaption{font-size:.9em;margin-top:.3em}\
figcaption .instr{display:block;color:#444;margin-top:.2em}\
.faulted,.fail{color:#b3261e}.ok{color:#1b5e20}\
@page{margin:12mm}\
@media print{body{margin:0;padding:0;max-width:none;font-size:9pt}\
.gallery{grid-template-columns:repeat(2,1fr)}\
tr,figure,.charts svg{break-inside:avoid}h2,h3{break-after:avoid}a{color:inherit}}";

/// A metric as the tables write it: three decimals, `-` where undefined.
pub fn number(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3}"))
}

/// A field of the run record as text (`-` when absent).
fn field(v: Option<&serde_json::Value>) -> String {
    match v {
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(serde_json::Value::Null) | None => "-".into(),
        Some(v) => v.to_string(),
    }
}

/// A column heading, with its unit when it has one.
fn heading(c: &Column) -> String {
    if c.unit.is_empty() {
        c.head.to_string()
    } else {
        format!("{} <small>({})</small>", c.head, escape(c.unit))
    }
}

/// One metric table: a row per (name, aggregate), in the summary's columns.
fn metric_table(t: &mut String, cols: &[&Column], first: &str, rows: &[(&str, &Aggregate)]) {
    t.push_str("<table class=\"metrics\"><tr>");
    let _ = write!(t, "<th>{}</th><th>n</th>", escape(first));
    for c in cols {
        let _ = write!(t, "<th title=\"{}\">{}</th>", c.metric, heading(c));
    }
    t.push_str("</tr>\n");
    for (name, a) in rows {
        let _ = write!(
            t,
            "<tr><td>{}</td><td class=\"num\">{}</td>",
            escape(name),
            a.episodes
        );
        for c in cols {
            let _ = write!(
                t,
                "<td class=\"num\">{}</td>",
                number(a.means.get(c.metric).copied())
            );
        }
        t.push_str("</tr>\n");
    }
    t.push_str("</table>\n");
}

/// `data:image/png;base64,…` of a PNG file.
fn data_uri(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    ))
}

/// The metrics of an episode row: SR, NE, nDTW, and the counts CR and steps as whole numbers.
fn episode_numbers(m: Option<&EpisodeMetrics>) -> [String; 5] {
    let m = m.cloned().unwrap_or_default();
    let count = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.0}"));
    [
        number(m.sr),
        number(m.ne),
        number(m.ndtw),
        count(m.cr),
        count(m.steps),
    ]
}

/// What an episode asks: its task, instruction level (when it has one) and instruction type.
fn task_of(r: &EvalRecord) -> String {
    let mut parts = vec![name_of(r.task)];
    if r.level.is_some() {
        parts.push(name_of(r.level));
    }
    parts.push(name_of(r.instruction_type));
    parts.join(", ")
}

/// A serde enum's name (`-` when absent).
fn name_of(v: impl serde::Serialize) -> String {
    field(serde_json::to_value(v).ok().as_ref())
}

/// How an episode ended, as its record names it (`faulted` when it was never scored): any
/// termination the record holds shows, including ones added after this page was written.
fn ending(r: &EvalRecord) -> String {
    r.termination.map_or_else(|| "faulted".to_string(), name_of)
}

/// The environment the run recorded (`env`) in a line ([`sage_env::EnvConfig::summary`]); for a
/// run recorded before that field, that its preset's is assumed.
fn environment(run: &serde_json::Value) -> String {
    match run.get("env") {
        Some(env) => serde_json::from_value::<sage_env::EnvConfig>(env.clone())
            .map_or_else(|e| format!("unreadable ({e})"), |c| c.summary()),
        None => "not recorded (a run of an earlier version): the preset's".to_string(),
    }
}

/// The scored episodes per termination, as text: `3 collision, 1 max_steps` (`none`).
fn termination_counts(records: &[EvalRecord]) -> String {
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    for r in records.iter().filter(|r| r.termination.is_some()) {
        *counts.entry(ending(r)).or_insert(0) += 1;
    }
    if counts.is_empty() {
        return "none".into();
    }
    let parts: Vec<String> = counts.iter().map(|(k, n)| format!("{n} {k}")).collect();
    parts.join(", ")
}

/// The banners above everything: faulted episodes, and model-server faults the run recovered
/// from (their episodes were scored, but a reader should know the server misbehaved).
fn banners(t: &mut String, files: &RunFiles) {
    let s = &files.summary;
    if !s.failed.is_empty() {
        let _ = writeln!(
            t,
            "<p class=\"banner faulted\"><b>{} of {} episodes faulted</b>: they were never scored \
             and are not in the means ({}); see <a href=\"#faulted\">Faulted episodes</a>.</p>",
            s.failed.len(),
            s.episodes,
            escape(&s.failure_counts())
        );
    }
    let faults: Vec<_> = files.records.iter().flat_map(|r| &r.faults).collect();
    if !faults.is_empty() {
        let recovered = faults.iter().filter(|f| f.recovered).count();
        let episodes = files
            .records
            .iter()
            .filter(|r| !r.faults.is_empty())
            .count();
        let _ = writeln!(
            t,
            "<p class=\"banner\"><b>Model-server faults: {}</b> ({}) in {episodes} of {} \
             episodes; {recovered} recovered by a retry, {} did not.</p>",
            faults.len(),
            escape(&s.fault_counts()),
            s.episodes,
            faults.len() - recovered
        );
    }
}

/// The "Episode videos" section, when there are videos: each GIF (by its path under the
/// report folder, as they are too large to embed) with its episode and instruction.
fn videos<'i>(t: &mut String, input: &PageInput, instruction: &dyn Fn(&str) -> &'i str) {
    if input.videos.is_empty() {
        return;
    }
    let _ = write!(
        t,
        "<h2 id=\"videos\">Episode videos</h2>\n<p>{} episodes, the first of the maps' order, as \
         animated GIFs in <code>report/videos/</code> (beside this page, not embedded): one frame \
         for the start and one per step, the agent's first-person view (level: the records hold \
         no camera pitch) beside the map with the reference path, the agent's path and contacts \
         so far and its pose, and above them the instruction and the step's action, collision \
         intensity c(t) and distance to the goal.</p>\n<div class=\"gallery\">\n",
        input.videos.len()
    );
    for v in input.videos {
        let class = if succeeded(v.record) { "ok" } else { "fail" };
        let _ = writeln!(
            t,
            "<figure><a href=\"{path}\"><img alt=\"video of episode {id}\" src=\"{path}\" \
             loading=\"lazy\"></a><figcaption><b class=\"{class}\">{id}</b>\
             <span class=\"instr\">{instr}</span></figcaption></figure>",
            path = escape(&v.rel_path),
            id = escape(&v.record.episode_id),
            instr = escape(instruction(&v.record.episode_id)),
        );
    }
    t.push_str("</div>\n");
}

/// The whole page.
///
/// # Errors
///
/// An embedded map's PNG cannot be read.
pub fn page(input: &PageInput) -> Result<String> {
    let files = input.files;
    let s = &files.summary;
    let run = &files.run;
    let settings = run.get("settings");
    let setting = |k: &str| field(settings.and_then(|v| v.get(k)));
    let instructions = input.instructions.as_ref().ok();
    let instruction = |id: &str| {
        instructions
            .and_then(|i| i.get(id))
            .map_or("-", String::as_str)
    };
    let mut t = String::new();
    let title = format!("sage3d evaluation: {} on {}", s.agent, s.split);
    let _ = write!(
        t,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        escape(&title),
        escape(&title)
    );
    banners(&mut t, files);

    t.push_str("<h2>Run</h2>\n<table class=\"meta\">\n");
    let scored = s.episodes - s.failed.len();
    let rows = [
        ("metric mode", s.mode.to_string()),
        ("nDTW alignment", format!("{} DTW", s.dtw)),
        ("agent", s.agent.clone()),
        ("split", s.split.clone()),
        ("preset", setting("preset")),
        ("environment", environment(run)),
        ("seed", setting("seed")),
        ("dataset", setting("dataset")),
        ("scenes", setting("scenes")),
        ("dataset hash", field(run.get("dataset_hash"))),
        ("sage3d version (run)", field(run.get("version"))),
        (
            "sage3d version (report)",
            env!("CARGO_PKG_VERSION").to_string(),
        ),
        ("episodes recorded", s.episodes.to_string()),
        ("episodes scored", scored.to_string()),
        ("episodes faulted", s.failed.len().to_string()),
        ("faulted episodes by kind", s.failure_counts()),
        (
            "scored episodes by termination",
            termination_counts(&files.records),
        ),
        ("model-server faults by kind", s.fault_counts()),
    ];
    for (k, v) in rows {
        let _ = writeln!(t, "<tr><th>{k}</th><td>{}</td></tr>", escape(&v));
    }
    t.push_str("</table>\n");

    let _ = write!(
        t,
        "<h2>Metrics</h2>\n<p>Means over the scored episodes, in metric mode <b>{}</b> \
         with {} DTW for nDTW (each metric over the episodes that define it; <code>-</code>: none does). \
         The same numbers and columns as <code>summary.json</code> and the text tables.</p>\n<h3>overall</h3>\n",
        s.mode, s.dtw
    );
    let cols = s.columns();
    metric_table(&mut t, &cols, "", &[("overall", &s.overall)]);
    for axis in AXES {
        let Some(slices) = s.slices.get(axis) else {
            continue;
        };
        let rows: Vec<(&str, &Aggregate)> = slices.iter().map(|(k, a)| (k.as_str(), a)).collect();
        let _ = writeln!(t, "<h3>per {axis}</h3>");
        metric_table(&mut t, &cols, axis, &rows);
    }

    let ratios: Vec<&str> = METRICS
        .iter()
        .filter(|m| m.ratio)
        .map(|m| m.label)
        .collect();
    let fitted: Vec<String> = METRICS
        .iter()
        .filter(|m| !m.ratio)
        .map(|m| {
            let end = input.scale_ends.get(m.metric).copied().unwrap_or(1.0);
            format!("{} 0–{end} {}", m.label, m.unit)
        })
        .collect();
    let _ = writeln!(
        t,
        "<h2>Per-slice charts</h2>\n<p>One panel per metric, one bar per slice value. Each metric \
         has the same scale in every chart: {} 0–1; {} (to a round number at or above the \
         largest mean of this run).</p>\n<div class=\"charts\">",
        ratios.join(", "),
        fitted.join("; ")
    );
    for (axis, chart, png) in input.charts {
        let _ = writeln!(
            t,
            "<h3>per {axis}</h3>\n{}\n<p><a href=\"{}\">PNG</a></p>",
            chart.to_svg(),
            escape(png)
        );
    }
    t.push_str("</div>\n");

    t.push_str("<h2 id=\"faulted\">Faulted episodes</h2>\n");
    let faulted: Vec<_> = files.records.iter().filter(|r| r.error.is_some()).collect();
    if faulted.is_empty() {
        t.push_str("<p>None: every episode was scored.</p>\n");
    } else {
        t.push_str(
            "<p>Recorded with an error and never scored; not in the means.</p>\n\
             <table><tr><th>episode</th><th>scene</th><th>kind</th><th>error</th></tr>\n",
        );
        for r in faulted {
            let _ = writeln!(
                t,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                escape(&r.episode_id),
                escape(&r.scene),
                r.failure_kind().as_str(),
                escape(r.error.as_deref().unwrap_or_default())
            );
        }
        t.push_str("</table>\n");
    }

    let _ = write!(
        t,
        "<h2>Episode maps</h2>\n<p>The semantic map of each episode's scene, in muted tints, with \
         the reference path (blue, dashed), the agent's path (vermillion), the start (green \
         square), the goal (purple diamond outline) and its region's outline, and a black cross \
         at every step that ended in contact; doors are sky blue when open, yellow when \
         half-open and orange when closed. The colours are Okabe and Ito's colour-blind-safe set, and each \
         map's legend lists what that map shows. Unsuccessful episodes first, then by id; {} of \
         {} embedded, the others linked.</p>\n<div class=\"gallery\">\n",
        input.embed,
        input.gallery.len()
    );
    for m in &input.gallery[..input.embed] {
        let [sr, ne, ndtw, ..] = episode_numbers(m.record.metrics.as_ref());
        let class = if succeeded(m.record) { "ok" } else { "fail" };
        let _ = writeln!(
            t,
            "<figure><a href=\"{path}\"><img alt=\"map of episode {id}\" src=\"{uri}\"></a>\
             <figcaption><b class=\"{class}\">{id}</b>: SR {sr}, NE {ne}, nDTW {ndtw}\
             <span class=\"instr\">{instr}</span></figcaption></figure>",
            path = escape(&m.rel_path),
            id = escape(&m.record.episode_id),
            uri = data_uri(&input.run_dir.join(&m.rel_path))?,
            instr = escape(instruction(&m.record.episode_id)),
        );
    }
    t.push_str("</div>\n");
    if input.gallery.len() > input.embed {
        t.push_str("<p>Other maps:</p>\n<ul>\n");
        for m in &input.gallery[input.embed..] {
            let _ = writeln!(
                t,
                "<li><a href=\"{}\">{}</a></li>",
                escape(&m.rel_path),
                escape(&m.record.episode_id)
            );
        }
        t.push_str("</ul>\n");
    }

    videos(&mut t, input, &instruction);

    t.push_str("<h2>Episodes</h2>\n");
    if let Err(e) = input.instructions {
        let _ = writeln!(
            t,
            "<p>The instructions are not shown: {}.</p>",
            escape(&e.to_string())
        );
    }
    t.push_str(
        "<table class=\"episodes\"><thead><tr><th>episode</th><th>scene</th>\
         <th>task <small>(level, type)</small></th><th>instruction</th>\
         <th>slices <small>(assets, path)</small></th><th>termination</th><th>SR</th>\
         <th>NE <small>(m)</small></th><th>nDTW</th><th>CR</th><th>steps</th><th>map</th></tr>\
         </thead>\n<tbody>\n",
    );
    let links: BTreeMap<&str, &str> = input
        .gallery
        .iter()
        .map(|m| (m.record.episode_id.as_str(), m.rel_path.as_str()))
        .collect();
    for r in &files.records {
        let map = links.get(r.episode_id.as_str()).map_or_else(
            || "-".to_string(),
            |path| format!("<a href=\"{}\">map</a>", escape(path)),
        );
        let end = if r.termination.is_some() {
            escape(&ending(r))
        } else {
            format!("<span class=\"faulted\">{}</span>", ending(r))
        };
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"instr\">{}</td><td>{}, {}</td><td>{end}</td>",
            escape(&r.episode_id),
            escape(&r.scene),
            escape(&task_of(r)),
            escape(instruction(&r.episode_id)),
            escape(&r.slices.assets),
            escape(&r.slices.path),
        );
        for v in episode_numbers(r.metrics.as_ref()) {
            let _ = write!(t, "<td class=\"num\">{v}</td>");
        }
        let _ = writeln!(t, "<td>{map}</td></tr>");
    }
    t.push_str("</tbody></table>\n</body>\n</html>\n");
    Ok(t)
}
