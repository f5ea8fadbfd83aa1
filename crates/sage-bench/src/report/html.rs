//! The report page: one HTML file with inline CSS, charts as inline SVG and maps as base64 PNG
//! data URIs, so it opens offline and can be mailed as one file. It needs no script.

use super::charts::BarChart;
use super::{MapFile, RunFiles, succeeded};
use crate::eval::summary::AXES;
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
}

/// Columns of the metric tables, in order, with their headings; those no aggregate holds are
/// left out. Text-table order first (`Summary::table`), then the other metrics.
const COLUMNS: [(&str, &str); 16] = [
    ("sr", "SR"),
    ("osr", "OSR"),
    ("spl", "SPL"),
    ("ne", "NE"),
    ("tl", "TL"),
    ("cr", "CR"),
    ("ndtw", "nDTW"),
    ("episode_time", "time"),
    ("explored_area", "area"),
    ("csr", "CSR"),
    ("icp", "ICP"),
    ("ps", "PS"),
    ("sdtw", "SDTW"),
    ("explored_cells", "cells"),
    ("coverage", "coverage"),
    ("steps", "steps"),
];

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em;color:#222;max-width:1400px}\
table{border-collapse:collapse;margin:.5em 0 1.5em}\
th,td{border:1px solid #ccc;padding:.2em .5em}\
td.num{text-align:right;font-family:ui-monospace,monospace}\
th{background:#f0f0f0}\
table.meta th{text-align:left}\
p.banner{background:#fff3cd;border:1px solid #c9a227;padding:.6em 1em}\
.charts svg{display:block;margin:.5em 0 1.5em;font-family:ui-monospace,monospace;font-size:14px}\
.gallery{display:flex;flex-wrap:wrap;gap:1em}\
figure{margin:0;border:1px solid #ddd;padding:.5em;max-width:640px}\
figure img{max-width:100%;height:auto}\
figcaption{font-size:.9em}\
.fail{color:#b71c1c}.ok{color:#1b5e20}";

/// Escapes text for HTML content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

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

/// The metric columns any of `aggs` holds.
fn columns<'a>(
    aggs: impl Iterator<Item = &'a Aggregate> + Clone,
) -> Vec<(&'static str, &'static str)> {
    COLUMNS
        .into_iter()
        .filter(|(m, _)| aggs.clone().any(|a| a.means.contains_key(*m)))
        .collect()
}

/// One metric table: a row per (name, aggregate).
fn metric_table(t: &mut String, first: &str, rows: &[(&str, &Aggregate)]) {
    let cols = columns(rows.iter().map(|(_, a)| *a));
    t.push_str("<table class=\"metrics\"><tr>");
    let _ = write!(t, "<th>{}</th><th>n</th>", escape(first));
    for (metric, head) in &cols {
        let _ = write!(t, "<th title=\"{metric}\">{head}</th>");
    }
    t.push_str("</tr>\n");
    for (name, a) in rows {
        let _ = write!(
            t,
            "<tr><td>{}</td><td class=\"num\">{}</td>",
            escape(name),
            a.episodes
        );
        for (metric, _) in &cols {
            let _ = write!(
                t,
                "<td class=\"num\">{}</td>",
                number(a.means.get(*metric).copied())
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

/// The metrics of an episode row: SR, NE, nDTW, CR, steps.
fn episode_numbers(m: Option<&EpisodeMetrics>) -> [String; 5] {
    let m = m.cloned().unwrap_or_default();
    [m.sr, m.ne, m.ndtw, m.cr, m.steps].map(number)
}

/// A serde enum's name (`-` when absent).
fn name_of(v: impl serde::Serialize) -> String {
    field(serde_json::to_value(v).ok().as_ref())
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
    let mut t = String::new();
    let title = format!("sage3d evaluation: {} on {}", s.agent, s.split);
    let _ = write!(
        t,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        escape(&title),
        escape(&title)
    );

    if !s.failed.is_empty() {
        let _ = writeln!(
            t,
            "<p class=\"banner\"><b>{} of {} episodes failed</b> and are not in the means ({}); \
             see <a href=\"#failed\">Failed episodes</a>.</p>",
            s.failed.len(),
            s.episodes,
            escape(&s.failure_counts())
        );
    }
    t.push_str("<h2>Run</h2>\n<table class=\"meta\">\n");
    let scored = s.episodes - s.failed.len();
    let rows = [
        ("metric mode", s.mode.to_string()),
        ("nDTW alignment", format!("{} DTW", s.dtw)),
        ("agent", s.agent.clone()),
        ("split", s.split.clone()),
        ("preset", setting("preset")),
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
        ("episodes failed", s.failed.len().to_string()),
        ("failures by kind", s.failure_counts()),
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
         The same numbers as <code>summary.json</code>.</p>\n<h3>overall</h3>\n",
        s.mode, s.dtw
    );
    metric_table(&mut t, "", &[("overall", &s.overall)]);
    for axis in AXES {
        let Some(slices) = s.slices.get(axis) else {
            continue;
        };
        let rows: Vec<(&str, &Aggregate)> = slices.iter().map(|(k, a)| (k.as_str(), a)).collect();
        let _ = writeln!(t, "<h3>per {axis}</h3>");
        metric_table(&mut t, axis, &rows);
    }

    t.push_str("<h2>Per-slice charts</h2>\n<div class=\"charts\">\n");
    for (axis, chart, png) in input.charts {
        let _ = writeln!(
            t,
            "<h3>per {axis}</h3>\n{}\n<p><a href=\"{}\">PNG</a></p>",
            chart.to_svg(),
            escape(png)
        );
    }
    t.push_str("</div>\n");

    t.push_str("<h2 id=\"failed\">Failed episodes</h2>\n");
    let failed: Vec<_> = files.records.iter().filter(|r| r.error.is_some()).collect();
    if failed.is_empty() {
        t.push_str("<p>None.</p>\n");
    } else {
        t.push_str("<table><tr><th>episode</th><th>scene</th><th>kind</th><th>error</th></tr>\n");
        for r in failed {
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
        "<h2>Episode maps</h2>\n<p>The semantic map of each episode's scene with the reference \
         path (blue), the agent's path (orange), the start (green), the goal and its region \
         (purple) and every step that ended in contact (red). Unsuccessful episodes first, then \
         by id; {} of {} embedded, the others linked.</p>\n<div class=\"gallery\">\n",
        input.embed,
        input.gallery.len()
    );
    for m in &input.gallery[..input.embed] {
        let [sr, ne, ndtw, ..] = episode_numbers(m.record.metrics.as_ref());
        let class = if succeeded(m.record) { "ok" } else { "fail" };
        let _ = writeln!(
            t,
            "<figure><a href=\"{path}\"><img alt=\"map of episode {id}\" src=\"{uri}\"></a>\
             <figcaption class=\"{class}\">{id}: SR {sr}, NE {ne}, nDTW {ndtw}</figcaption></figure>",
            path = escape(&m.rel_path),
            id = escape(&m.record.episode_id),
            uri = data_uri(&input.run_dir.join(&m.rel_path))?,
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

    t.push_str(
        "<h2>Episodes</h2>\n<table><tr><th>episode</th><th>scene</th><th>task</th>\
         <th>level</th><th>instruction type</th><th>assets</th><th>path</th>\
         <th>termination</th><th>SR</th><th>NE</th><th>nDTW</th><th>CR</th><th>steps</th>\
         <th>map</th></tr>\n",
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
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
            escape(&r.episode_id),
            escape(&r.scene),
            escape(&name_of(r.task)),
            escape(&name_of(r.level)),
            escape(&name_of(r.instruction_type)),
            escape(&r.slices.assets),
            escape(&r.slices.path),
            escape(&r.termination.map_or_else(|| "failed".to_string(), name_of)),
        );
        for v in episode_numbers(r.metrics.as_ref()) {
            let _ = write!(t, "<td class=\"num\">{v}</td>");
        }
        let _ = writeln!(t, "<td>{map}</td></tr>");
    }
    t.push_str("</table>\n</body>\n</html>\n");
    Ok(t)
}
