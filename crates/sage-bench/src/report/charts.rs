//! Grouped bar charts of the per-slice means: one chart per slice axis, one group of bars per
//! slice value, one bar per metric (SR, SPL, nDTW on a 0–1 scale; CR, a count, on its own
//! scale named in the legend).
//!
//! A chart is laid out once as a list of pixel [`Mark`]s; the same marks become the page's
//! inline SVG and the PNG (drawn with the map canvas and its bitmap font), so both show the
//! same picture. Bars run horizontally so long slice names stay legible.

use glam::Vec2;
use sage_io::canvas::Canvas;
use sage_metrics::Aggregate;
use std::collections::BTreeMap;
use std::fmt::Write;

/// One bar per group: a metric, its colour, and whether it has its own scale (counts).
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Metric name as in `summary.json`.
    pub metric: &'static str,
    /// Legend label.
    pub label: &'static str,
    /// Bar colour.
    pub colour: [u8; 3],
    /// Scaled to the series' own maximum instead of 0–1.
    pub own_scale: bool,
}

/// The metrics the slice charts show, when the summary has them.
pub const SERIES: [Series; 4] = [
    Series {
        metric: "sr",
        label: "SR",
        colour: [46, 125, 50],
        own_scale: false,
    },
    Series {
        metric: "spl",
        label: "SPL",
        colour: [25, 118, 210],
        own_scale: false,
    },
    Series {
        metric: "ndtw",
        label: "nDTW",
        colour: [123, 31, 162],
        own_scale: false,
    },
    Series {
        metric: "cr",
        label: "CR",
        colour: [211, 47, 47],
        own_scale: true,
    },
];

/// A grouped bar chart.
#[derive(Debug, Clone, PartialEq)]
pub struct BarChart {
    /// Title line.
    pub title: String,
    /// The bars of each group, in order.
    pub series: Vec<Series>,
    /// Group label and one value per series (`None`: the slice does not define it).
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
/// Pixel gap between the bars of a group, so their value texts do not touch.
const BAR_GAP: i64 = 4;
/// Pixel width of the bars' full scale.
const PLOT_W: i64 = 400;
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

/// The chart of one slice axis of a summary: SR, SPL, nDTW and CR where any slice has them.
pub fn slice_chart(axis: &str, slices: &BTreeMap<String, Aggregate>) -> BarChart {
    let series: Vec<Series> = SERIES
        .iter()
        .filter(|s| slices.values().any(|a| a.means.contains_key(s.metric)))
        .cloned()
        .collect();
    let groups = slices
        .iter()
        .map(|(name, a)| {
            let values = series
                .iter()
                .map(|s| a.means.get(s.metric).copied())
                .collect();
            (format!("{name} (n {})", a.episodes), values)
        })
        .collect();
    BarChart {
        title: format!("per {axis}"),
        series,
        groups,
    }
}

impl BarChart {
    /// The end of each series' scale: 1 for ratios, a [`nice_ceiling`] of the largest value
    /// for counts.
    fn scale_ends(&self) -> Vec<f64> {
        self.series
            .iter()
            .enumerate()
            .map(|(k, s)| {
                if s.own_scale {
                    let max = self
                        .groups
                        .iter()
                        .filter_map(|(_, v)| v[k])
                        .fold(0.0, f64::max);
                    nice_ceiling(max)
                } else {
                    1.0
                }
            })
            .collect()
    }

    /// The chart's size in pixels and its marks.
    pub fn layout(&self) -> (usize, usize, Vec<Mark>) {
        let ends = self.scale_ends();
        let label_chars = self
            .groups
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0) as i64;
        let x0 = 10 + label_chars * CHAR_W + 10;
        let mut legend_x = 10;
        let mut marks = vec![Mark::Text {
            x: 10,
            y: 8,
            text: self.title.clone(),
            colour: INK,
        }];
        for (s, end) in self.series.iter().zip(&ends) {
            let label = if s.own_scale {
                format!("{} (0-{end})", s.label)
            } else {
                s.label.to_string()
            };
            marks.push(Mark::Rect {
                x: legend_x,
                y: 32,
                w: 12,
                h: 12,
                colour: s.colour,
            });
            marks.push(Mark::Text {
                x: legend_x + 18,
                y: 31,
                text: label.clone(),
                colour: INK,
            });
            legend_x += 18 + label.chars().count() as i64 * CHAR_W + 20;
        }
        let top = 60;
        let block = self.series.len().max(1) as i64 * (BAR_H + BAR_GAP) + 12;
        let bottom = top + self.groups.len() as i64 * block;
        let ticks = [0.0, 0.25, 0.5, 0.75, 1.0];
        for t in ticks {
            let x = x0 + (t * PLOT_W as f64).round() as i64;
            marks.push(Mark::Line {
                from: (x, top - 4),
                to: (x, bottom),
                colour: GRID,
            });
            let text = format!("{t}");
            marks.push(Mark::Text {
                x: x - text.len() as i64 * CHAR_W / 2,
                y: bottom + 8,
                text,
                colour: INK,
            });
        }
        marks.push(Mark::Line {
            from: (x0, top - 4),
            to: (x0, bottom),
            colour: INK,
        });
        for (g, (label, values)) in self.groups.iter().enumerate() {
            let gy = top + g as i64 * block;
            let bars_h = block - 12;
            marks.push(Mark::Text {
                x: 10,
                y: gy + (bars_h - CHAR_H) / 2,
                text: label.clone(),
                colour: INK,
            });
            for (k, (s, v)) in self.series.iter().zip(values).enumerate() {
                let y = gy + k as i64 * (BAR_H + BAR_GAP);
                let (w, text) = match v {
                    Some(v) => {
                        let frac = (v / ends[k]).clamp(0.0, 1.0);
                        ((frac * PLOT_W as f64).round() as i64, format!("{v:.3}"))
                    }
                    None => (0, "-".to_string()),
                };
                if w > 0 {
                    marks.push(Mark::Rect {
                        x: x0,
                        y,
                        w,
                        h: BAR_H,
                        colour: s.colour,
                    });
                }
                marks.push(Mark::Text {
                    x: x0 + w + 6,
                    y: y + 1,
                    text,
                    colour: INK,
                });
            }
        }
        let width = (x0 + PLOT_W + 6 + 7 * CHAR_W + 10).max(legend_x) as usize;
        let height = (bottom + 8 + CHAR_H + 10) as usize;
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
            super::html::escape(&self.title)
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
                        super::html::escape(text)
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
    }

    fn agg(n: usize, means: &[(&str, f64)]) -> Aggregate {
        Aggregate {
            episodes: n,
            mode: Mode::Sage,
            means: means.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
        }
    }

    #[test]
    fn bars_are_as_long_as_their_values_and_the_png_matches_the_marks() {
        let slices: BTreeMap<String, Aggregate> = [
            (
                "vln".to_string(),
                agg(3, &[("sr", 0.5), ("spl", 0.25), ("cr", 3.0)]),
            ),
            ("nogoal".to_string(), agg(1, &[("cr", 1.0)])),
        ]
        .into();
        let chart = slice_chart("task", &slices);
        // nDTW is in no slice: no series for it.
        let names: Vec<&str> = chart.series.iter().map(|s| s.metric).collect();
        assert_eq!(names, ["sr", "spl", "cr"]);
        let (w, h, marks) = chart.layout();
        let bars: Vec<(i64, [u8; 3])> = marks
            .iter()
            .filter_map(|m| match m {
                Mark::Rect { w, h, colour, .. } if *h == BAR_H => Some((*w, *colour)),
                _ => None,
            })
            .collect();
        // nogoal: CR 1 of a 0-5 scale; vln: SR 0.5, SPL 0.25 of 1, CR 3 of 5.
        assert_eq!(
            bars,
            [
                (80, SERIES[3].colour),
                (200, SERIES[0].colour),
                (100, SERIES[1].colour),
                (240, SERIES[3].colour),
            ]
        );
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
            svg.contains("width=\"240\"") && svg.contains(">0.250<"),
            "{svg}"
        );
        assert!(svg.contains("CR (0-5)") && !svg.contains("http"));
    }
}
