//! Per-slice charts: one chart per slice axis, drawn as small multiples — a panel per metric
//! (SR, SPL, nDTW, NE, CR), each with its own axis, and in every panel one bar per slice value
//! — so no metric is read against another's scale.
//!
//! A metric has one scale in the whole report ([`scale_ends`]): SR, SPL and nDTW are ratios
//! on 0–1; NE (metres) and CR (collisions per episode) run from 0 to the smallest 1, 2 or
//! 5 × 10^k at or above the largest mean the summary holds for them (overall or any slice of
//! any axis), so a bar of the same length means the same value in every chart.
//!
//! A chart is laid out once as a list of pixel [`Mark`]s; the same marks become the page's
//! inline SVG and the PNG (drawn with the map canvas and its bitmap font), so both show the
//! same picture. Bars run horizontally so long slice names stay legible.

use crate::summary::Summary;
use glam::Vec2;
use sage_io::canvas::Canvas;
use sage_io::palette::OKABE_ITO;
use sage_metrics::Aggregate;
use std::collections::BTreeMap;
use std::fmt::Write;

/// A metric the charts show.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metric {
    /// Metric name as in `summary.json`.
    pub metric: &'static str,
    /// Panel heading.
    pub label: &'static str,
    /// What the axis counts, named under its ticks.
    pub unit: &'static str,
    /// Bar colour.
    pub colour: [u8; 3],
    /// A ratio on 0–1; otherwise the scale is fitted to the report's largest mean.
    pub ratio: bool,
}

/// The metrics the slice charts show, when the summary has them, in panel order.
pub const METRICS: [Metric; 5] = [
    Metric {
        metric: "sr",
        label: "SR",
        unit: "rate",
        colour: OKABE_ITO[3],
        ratio: true,
    },
    Metric {
        metric: "spl",
        label: "SPL",
        unit: "score",
        colour: OKABE_ITO[5],
        ratio: true,
    },
    Metric {
        metric: "ndtw",
        label: "nDTW",
        unit: "score",
        colour: OKABE_ITO[7],
        ratio: true,
    },
    Metric {
        metric: "ne",
        label: "NE",
        unit: "metres",
        colour: OKABE_ITO[1],
        ratio: false,
    },
    Metric {
        metric: "cr",
        label: "CR",
        unit: "collisions",
        colour: OKABE_ITO[6],
        ratio: false,
    },
];

/// One panel of a chart: a metric on its scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// The metric.
    pub metric: Metric,
    /// The value at the panel's full width (the report-wide scale end).
    pub end: f64,
}

/// A chart of one slice axis.
#[derive(Debug, Clone, PartialEq)]
pub struct BarChart {
    /// Title line.
    pub title: String,
    /// The panels, in order.
    pub panels: Vec<Panel>,
    /// Group label and one value per panel (`None`: the slice does not define it).
    pub groups: Vec<(String, Vec<Option<f64>>)>,
}

/// A drawing primitive in pixels (x right, y down).
#[derive(Debug, Clone, PartialEq)]
pub enum Mark {
    /// A filled rectangle.
    Rect {
        /// Left.
        x: i64,
        /// Top.
        y: i64,
        /// Width.
        w: i64,
        /// Height.
        h: i64,
        /// Fill.
        colour: [u8; 3],
    },
    /// A one-pixel line.
    Line {
        /// Start.
        from: (i64, i64),
        /// End.
        to: (i64, i64),
        /// Colour.
        colour: [u8; 3],
    },
    /// Text with its top-left corner at (x, y), in the 12-pixel-wide bitmap font.
    Text {
        /// Left.
        x: i64,
        /// Top.
        y: i64,
        /// The text.
        text: String,
        /// Colour.
        colour: [u8; 3],
    },
}

/// Pixel width of one character (the bitmap font at scale 2).
const CHAR_W: i64 = 12;
/// Pixel height of a text line.
const CHAR_H: i64 = 14;
/// Pixel height of a bar.
const BAR_H: i64 = 16;
/// Pixel gap between the bars of neighbouring slice values.
const BAR_GAP: i64 = 6;
/// Pixel width of a panel's full scale.
const PLOT_W: i64 = 120;
/// Pixel room after the full scale for a bar's value (`0.000`) and the gap to the next panel.
const VALUE_W: i64 = 6 * CHAR_W + 12;
const INK: [u8; 3] = [20, 20, 20];
const GRID: [u8; 3] = [220, 220, 220];

/// The smallest of 1, 2, 5 × 10^k at or above `v` (1 when `v` ≤ 0): a scale end that reads well.
pub fn nice_ceiling(v: f64) -> f64 {
    if !(v > 0.0 && v.is_finite()) {
        return 1.0;
    }
    let mut unit = 10f64.powf(v.log10().floor());
    loop {
        for m in [1.0, 2.0, 5.0, 10.0] {
            if m * unit >= v * (1.0 - 1e-12) {
                return m * unit;
            }
        }
        unit *= 10.0;
    }
}

/// The scale end of every chart metric for the whole report: 1 for ratios, a
/// [`nice_ceiling`] of the largest mean over the overall row and every slice of every axis
/// for the others.
pub fn scale_ends(summary: &Summary) -> BTreeMap<&'static str, f64> {
    let aggregates: Vec<&Aggregate> = std::iter::once(&summary.overall)
        .chain(summary.slices.values().flat_map(|s| s.values()))
        .collect();
    METRICS
        .iter()
        .map(|m| {
            let end = if m.ratio {
                1.0
            } else {
                let max = aggregates
                    .iter()
                    .filter_map(|a| a.means.get(m.metric).copied())
                    .fold(0.0, f64::max);
                nice_ceiling(max)
            };
            (m.metric, end)
        })
        .collect()
}

/// The chart of one slice axis: a panel for each of [`METRICS`] that any slice has, on the
/// report-wide scale `ends` ([`scale_ends`]).
pub fn slice_chart(
    axis: &str,
    slices: &BTreeMap<String, Aggregate>,
    ends: &BTreeMap<&'static str, f64>,
) -> BarChart {
    let panels: Vec<Panel> = METRICS
        .iter()
        .filter(|m| slices.values().any(|a| a.means.contains_key(m.metric)))
        .map(|m| Panel {
            metric: *m,
            end: ends.get(m.metric).copied().unwrap_or(1.0),
        })
        .collect();
    let groups = slices
        .iter()
        .map(|(name, a)| {
            let values = panels
                .iter()
                .map(|p| a.means.get(p.metric.metric).copied())
                .collect();
            (format!("{name} (n {})", a.episodes), values)
        })
        .collect();
    BarChart {
        title: format!("per {axis}"),
        panels,
        groups,
    }
}

/// A tick value as text: `0`, `0.5`, `2.5`, `10`.
fn tick_text(v: f64) -> String {
    let t = format!("{:.3}", v);
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl BarChart {
    /// The chart's size in pixels and its marks.
    pub fn layout(&self) -> (usize, usize, Vec<Mark>) {
        let label_chars = self
            .groups
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0) as i64;
        let x0 = 10 + label_chars * CHAR_W + 16;
        let panel_w = PLOT_W + VALUE_W;
        let mut marks = vec![Mark::Text {
            x: 10,
            y: 8,
            text: self.title.clone(),
            colour: INK,
        }];
        let head = 34;
        let top = head + CHAR_H + 10;
        let bottom = top + self.groups.len() as i64 * (BAR_H + BAR_GAP);
        for (k, p) in self.panels.iter().enumerate() {
            let px = x0 + k as i64 * panel_w;
            marks.push(Mark::Text {
                x: px,
                y: head,
                text: p.metric.label.to_string(),
                colour: INK,
            });
            for q in 0..=4 {
                let x = px + PLOT_W * q / 4;
                marks.push(Mark::Line {
                    from: (x, top - 4),
                    to: (x, bottom),
                    colour: if q == 0 { INK } else { GRID },
                });
                // Labels at both ends and the middle; quarters are gridlines only.
                if q % 2 == 0 {
                    let text = tick_text(p.end * q as f64 / 4.0);
                    let w = text.chars().count() as i64 * CHAR_W;
                    marks.push(Mark::Text {
                        x: (x - w / 2).max(px - CHAR_W / 2),
                        y: bottom + 6,
                        text,
                        colour: INK,
                    });
                }
            }
            marks.push(Mark::Text {
                x: px,
                y: bottom + 6 + CHAR_H + 6,
                text: p.metric.unit.to_string(),
                colour: INK,
            });
        }
        for (g, (label, values)) in self.groups.iter().enumerate() {
            let y = top + g as i64 * (BAR_H + BAR_GAP);
            marks.push(Mark::Text {
                x: 10,
                y: y + (BAR_H - CHAR_H) / 2,
                text: label.clone(),
                colour: INK,
            });
            for (k, (p, v)) in self.panels.iter().zip(values).enumerate() {
                let px = x0 + k as i64 * panel_w;
                let (w, text) = match v {
                    Some(v) => {
                        let frac = (v / p.end).clamp(0.0, 1.0);
                        ((frac * PLOT_W as f64).round() as i64, format!("{v:.3}"))
                    }
                    None => (0, "-".to_string()),
                };
                if w > 0 {
                    marks.push(Mark::Rect {
                        x: px,
                        y,
                        w,
                        h: BAR_H,
                        colour: p.metric.colour,
                    });
                }
                marks.push(Mark::Text {
                    x: px + w + 6,
                    y: y + 1,
                    text,
                    colour: INK,
                });
            }
        }
        let title_w = 10 + self.title.chars().count() as i64 * CHAR_W + 10;
        let width = (x0 + self.panels.len() as i64 * panel_w).max(title_w) as usize;
        let height = (bottom + 6 + 2 * CHAR_H + 6 + 10) as usize;
        (width, height, marks)
    }

    /// The chart as an inline SVG element (no external reference).
    pub fn to_svg(&self) -> String {
        let (w, h, marks) = self.layout();
        let rgb = |c: &[u8; 3]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
        let mut s = String::new();
        let _ = write!(
            s,
            "<svg class=\"chart\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" role=\"img\" aria-label=\"{}\">",
            super::escape::escape(&self.title)
        );
        let _ = write!(
            s,
            "<rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>"
        );
        for m in &marks {
            match m {
                Mark::Rect { x, y, w, h, colour } => {
                    let _ = write!(
                        s,
                        "<rect x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" fill=\"{}\"/>",
                        rgb(colour)
                    );
                }
                Mark::Line { from, to, colour } => {
                    let _ = write!(
                        s,
                        "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\"/>",
                        from.0 as f64 + 0.5,
                        from.1 as f64 + 0.5,
                        to.0 as f64 + 0.5,
                        to.1 as f64 + 0.5,
                        rgb(colour)
                    );
                }
                Mark::Text { x, y, text, colour } => {
                    let _ = write!(
                        s,
                        "<text x=\"{x}\" y=\"{}\" fill=\"{}\">{}</text>",
                        y + CHAR_H - 2,
                        rgb(colour),
                        super::escape::escape(text)
                    );
                }
            }
        }
        s.push_str("</svg>");
        s
    }

    /// The chart drawn on a canvas (for the PNG).
    pub fn to_canvas(&self) -> Canvas {
        let (w, h, marks) = self.layout();
        // One world unit per pixel, world y up: pixel row r is world y = h - r.
        let mut c = Canvas::new(w, h, [255, 255, 255], Vec2::ZERO, 1.0, h);
        let world = |(x, y): (i64, i64)| Vec2::new(x as f32 + 0.5, (h as i64 - y) as f32 - 0.5);
        for m in &marks {
            match m {
                Mark::Rect { x, y, w, h, colour } => {
                    for py in *y..y + h {
                        for px in *x..x + w {
                            c.put(px, py, *colour);
                        }
                    }
                }
                Mark::Line { from, to, colour } => c.line(world(*from), world(*to), *colour, 1),
                Mark::Text { x, y, text, colour } => c.text(*x, *y, text, *colour, 2),
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_metrics::Mode;

    #[test]
    fn nice_ceilings() {
        for (v, e) in [
            (0.0, 1.0),
            (0.3, 0.5),
            (1.0, 1.0),
            (1.2, 2.0),
            (3.0, 5.0),
            (7.5, 10.0),
            (20.0, 20.0),
            (f64::NAN, 1.0),
        ] {
            assert_eq!(nice_ceiling(v), e, "{v}");
        }
        assert_eq!(
            [0.0, 0.25, 0.5, 2.5, 10.0].map(tick_text),
            ["0", "0.25", "0.5", "2.5", "10"]
        );
    }

    fn agg(n: usize, means: &[(&str, f64)]) -> Aggregate {
        Aggregate {
            episodes: n,
            mode: Mode::Sage,
            means: means.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
        }
    }

    #[test]
    fn bars_are_as_long_as_their_values_on_their_metric_scale_and_the_png_matches_the_marks() {
        let slices: BTreeMap<String, Aggregate> = [
            (
                "vln".to_string(),
                agg(3, &[("sr", 0.5), ("spl", 0.25), ("cr", 3.0)]),
            ),
            ("nogoal".to_string(), agg(1, &[("cr", 1.0)])),
        ]
        .into();
        // CR's report-wide scale ends at 5 (say another axis has a mean of 4.2).
        let ends: BTreeMap<&str, f64> = [("sr", 1.0), ("spl", 1.0), ("ndtw", 1.0), ("cr", 5.0)]
            .into_iter()
            .collect();
        let chart = slice_chart("task", &slices, &ends);
        // nDTW and NE are in no slice: no panel for them.
        let names: Vec<(&str, f64)> = chart
            .panels
            .iter()
            .map(|p| (p.metric.metric, p.end))
            .collect();
        assert_eq!(names, [("sr", 1.0), ("spl", 1.0), ("cr", 5.0)]);
        let (w, h, marks) = chart.layout();
        let bars: Vec<(i64, [u8; 3])> = marks
            .iter()
            .filter_map(|m| match m {
                Mark::Rect { w, h, colour, .. } if *h == BAR_H => Some((*w, *colour)),
                _ => None,
            })
            .collect();
        // nogoal: CR 1 of 0-5; vln: SR 0.5, SPL 0.25 of 1, CR 3 of 5.
        let (sr, spl, cr) = (METRICS[0].colour, METRICS[1].colour, METRICS[4].colour);
        assert_eq!(bars, [(24, cr), (60, sr), (30, spl), (72, cr)]);
        let canvas = chart.to_canvas();
        assert_eq!((canvas.width, canvas.height), (w, h));
        for m in &marks {
            if let Mark::Rect { x, y, w, h, colour } = m {
                let at = |px: i64, py: i64| {
                    let k = (py as usize * canvas.width + px as usize) * 3;
                    [canvas.rgb[k], canvas.rgb[k + 1], canvas.rgb[k + 2]]
                };
                assert_eq!(at(*x, *y), *colour);
                assert_eq!(at(x + w - 1, y + h - 1), *colour);
            }
        }
        let svg = chart.to_svg();
        assert!(
            svg.contains("width=\"72\"") && svg.contains(">0.250<"),
            "{svg}"
        );
        // Each panel is labelled with its ticks and unit: CR's axis reads 0, 2.5, 5 collisions.
        for text in [">CR<", ">2.5<", ">5<", ">collisions<", ">rate<"] {
            assert!(svg.contains(text), "{text}");
        }
        assert!(!svg.contains("http"));
    }

    #[test]
    fn fitted_scales_cover_the_largest_mean_of_the_whole_summary() {
        let settings = crate::settings::EvalSettings {
            dataset: "d".into(),
            scenes: "s".into(),
            split: "train".into(),
            agent: "forward".parse().unwrap(),
            mode: Mode::Sage,
            dtw: Default::default(),
            seed: 0,
            preset: "sage".into(),
            device: Default::default(),
            splat_bodies: Default::default(),
        };
        let mut s = Summary::of(&settings, &[]);
        s.overall = agg(4, &[("cr", 0.4), ("ne", 2.0), ("sr", 0.5)]);
        s.slices.insert(
            "task".into(),
            [("vln".to_string(), agg(2, &[("cr", 0.3), ("ne", 3.1)]))].into(),
        );
        s.slices.insert(
            "path".into(),
            [("long".to_string(), agg(1, &[("cr", 1.4)]))].into(),
        );
        let ends = scale_ends(&s);
        assert_eq!(ends["cr"], 2.0);
        assert_eq!(ends["ne"], 5.0);
        assert_eq!((ends["sr"], ends["spl"], ends["ndtw"]), (1.0, 1.0, 1.0));
    }
}
