//! The 2-D semantic map as the published SAGE-3D map builder cuts it from a scene's occupancy
//! image and labels (research notes §3.1): the entries its evaluator chooses a goal box among
//! (metric mode `sage-official`).
//!
//! It differs from [`crate::semantic_map`] on purpose: object boxes are the pixel extents of the
//! footprint rasterised on the occupancy grid, walls are the 8-connected components of the
//! image's "wall" grey (its most frequent value strictly between 0 and 250) and unable areas
//! those of its 0 pixels (5 pixels or more), and every bound is stored with two decimals.
//!
//! The builder works in its own map frame M, a point reflection of the world W through the
//! grid's centre: column `w − 1 − j` and row `h − 1 − i` of M hold world cell `(j, i)` at
//! `x = x0 + (j + ½)·s`, `y = y0 + (i + ½)·s`. Boxes are computed and rounded there and
//! reflected back (`x_W = 2·x0 + w·s − x_M`), so distances and box tests are the builder's.

use glam::Vec2;
use sage_scene::Object;
use sage_scene::occupancy::OccupancyMap;
use std::collections::BTreeMap;

/// Unable-area components smaller than this (pixels) are dropped, as the builder drops them.
pub const MIN_UNABLE_PIXELS: usize = 5;

/// One entry of the published map: an object, a wall component or an unable area.
#[derive(Debug, Clone, PartialEq)]
pub struct PublishedEntry {
    /// `item_id`: the label in lower case with spaces as `_`, then `_{n}` counted per label.
    pub item_id: String,
    /// `category_label`: the object's label as written, `wall` or `Unable Area`.
    pub label: String,
    /// Lower corner of `bbox_m`, reflected into the world frame, metres.
    pub min: [f64; 2],
    /// Upper corner of `bbox_m`, reflected into the world frame, metres.
    pub max: [f64; 2],
    /// Pixels in the entry's mask.
    pub area: usize,
}

/// The published map of a scene: objects in `labels.json` order, then walls, then unable areas.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PublishedMap {
    /// The entries, in the builder's order.
    pub entries: Vec<PublishedEntry>,
}

/// The builder's grid: placement in f64 and the M-frame extent of a mask.
struct Grid {
    x0: f64,
    y0: f64,
    s: f64,
    w: usize,
    h: usize,
}

/// Column and row ranges of a mask in the M frame (inclusive).
#[derive(Clone, Copy)]
struct PixelBox {
    cols: (usize, usize),
    rows: (usize, usize),
}

impl PixelBox {
    fn at(col: usize, row: usize) -> PixelBox {
        PixelBox {
            cols: (col, col),
            rows: (row, row),
        }
    }

    fn grow(&mut self, col: usize, row: usize) {
        self.cols = (self.cols.0.min(col), self.cols.1.max(col));
        self.rows = (self.rows.0.min(row), self.rows.1.max(row));
    }
}

/// `f"{v:.2f}"` read back as a number: bounds are stored as two-decimal strings.
fn two_decimals(v: f64) -> f64 {
    format!("{v:.2}").parse().unwrap_or(v)
}

impl Grid {
    /// The world-frame box of an M-frame pixel box: pixel edges, rounded in M, reflected.
    fn world_box(&self, b: PixelBox) -> ([f64; 2], [f64; 2]) {
        let m = |origin: f64, k: usize| two_decimals(origin + k as f64 * self.s);
        let (left, right) = (m(self.x0, b.cols.0), m(self.x0, b.cols.1 + 1));
        let (bottom, top) = (m(self.y0, b.rows.0), m(self.y0, b.rows.1 + 1));
        let cx = 2.0 * self.x0 + self.w as f64 * self.s;
        let cy = 2.0 * self.y0 + self.h as f64 * self.s;
        ([cx - right, cy - top], [cx - left, cy - bottom])
    }
}

/// True when `p` lies inside the closed polygon or on its boundary (shapely's `covers`).
fn covers(poly: &[[f64; 2]], p: [f64; 2]) -> bool {
    let n = poly.len();
    let mut inside = false;
    for k in 0..n {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let within = p[0] >= a[0].min(b[0])
            && p[0] <= a[0].max(b[0])
            && p[1] >= a[1].min(b[1])
            && p[1] <= a[1].max(b[1]);
        if cross == 0.0 && within {
            return true;
        }
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// The 8-connected components of the M-frame mask `on(col, row)`, numbered in raster order of
/// their first pixel (as `scipy.ndimage.label` numbers them), with their boxes and pixel counts.
fn components(g: &Grid, on: impl Fn(usize, usize) -> bool) -> Vec<(PixelBox, usize)> {
    let mut seen = vec![false; g.w * g.h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for row in 0..g.h {
        for col in 0..g.w {
            if seen[row * g.w + col] || !on(col, row) {
                continue;
            }
            seen[row * g.w + col] = true;
            stack.push((col, row));
            let (mut b, mut n) = (PixelBox::at(col, row), 0);
            while let Some((c, r)) = stack.pop() {
                b.grow(c, r);
                n += 1;
                for (dc, dr) in [
                    (-1, -1),
                    (0, -1),
                    (1, -1),
                    (-1, 0),
                    (1, 0),
                    (-1, 1),
                    (0, 1),
                    (1, 1),
                ] {
                    let (nc, nr) = (c as isize + dc, r as isize + dr);
                    if nc < 0 || nr < 0 || nc as usize >= g.w || nr as usize >= g.h {
                        continue;
                    }
                    let (nc, nr) = (nc as usize, nr as usize);
                    if !seen[nr * g.w + nc] && on(nc, nr) {
                        seen[nr * g.w + nc] = true;
                        stack.push((nc, nr));
                    }
                }
            }
            out.push((b, n));
        }
    }
    out
}

/// The image's wall grey: its most frequent value strictly between 0 and 250 (the lowest on a
/// tie), else its lowest value.
fn wall_value(cells: &[u8]) -> u8 {
    let mut counts = [0usize; 256];
    for &v in cells {
        counts[usize::from(v)] += 1;
    }
    let mut best: Option<u8> = None;
    for v in 1u8..250 {
        if counts[usize::from(v)] > 0
            && best.is_none_or(|b| counts[usize::from(v)] > counts[usize::from(b)])
        {
            best = Some(v);
        }
    }
    best.unwrap_or_else(|| {
        (0u8..=255)
            .find(|&v| counts[usize::from(v)] > 0)
            .unwrap_or(0)
    })
}

impl PublishedMap {
    /// The published map of a scene's objects over its occupancy image.
    pub fn build(objects: &[Object], occupancy: &OccupancyMap) -> PublishedMap {
        let footprints = objects
            .iter()
            .map(|o| (o.label.as_str(), o.obb.footprint()));
        PublishedMap::from_footprints(footprints, occupancy)
    }

    /// The published map of labelled footprints (each an object's `bounding_box` corners 0–3)
    /// over an occupancy image.
    pub fn from_footprints<'a>(
        objects: impl IntoIterator<Item = (&'a str, [Vec2; 4])>,
        occupancy: &OccupancyMap,
    ) -> PublishedMap {
        // The placement is kept in f32; its shortest decimal form is the number the JSON held
        // (to f32's seven digits), which the builder reads as f64.
        let wide = |v: f32| v.to_string().parse::<f64>().unwrap_or(f64::from(v));
        let g = Grid {
            x0: wide(occupancy.lower.x),
            y0: wide(occupancy.lower.y),
            s: wide(occupancy.scale),
            w: occupancy.width,
            h: occupancy.height,
        };
        let mut counters: BTreeMap<String, usize> = BTreeMap::new();
        let mut entry = |label: &str, b: PixelBox, area: usize| {
            let n = counters.entry(label.to_string()).or_insert(0);
            *n += 1;
            let (min, max) = g.world_box(b);
            PublishedEntry {
                item_id: format!("{}_{n}", label.trim().to_lowercase().replace(' ', "_")),
                label: label.to_string(),
                min,
                max,
                area,
            }
        };
        let mut entries = Vec::new();
        for (label, footprint) in objects {
            if let Some((b, area)) = rasterise(&g, &footprint) {
                entries.push(entry(label, b, area));
            }
        }
        // M row `row` is image row `h − 1 − row` (the builder flips the image upside down).
        let pixel = |col: usize, row: usize| occupancy.get(col, g.h - 1 - row);
        let wall = wall_value(&occupancy.cells);
        for (b, area) in components(&g, |c, r| pixel(c, r) == wall) {
            entries.push(entry("wall", b, area));
        }
        for (b, area) in components(&g, |c, r| pixel(c, r) == 0) {
            if area >= MIN_UNABLE_PIXELS {
                entries.push(entry("Unable Area", b, area));
            }
        }
        PublishedMap { entries }
    }
}

/// The M-frame pixel box and pixel count of a footprint rasterised at pixel centres, or `None`
/// when no pixel centre is covered (the builder skips such objects).
fn rasterise(g: &Grid, footprint: &[Vec2; 4]) -> Option<(PixelBox, usize)> {
    let poly: Vec<[f64; 2]> = footprint
        .iter()
        .map(|p| [f64::from(p.x), f64::from(p.y)])
        .collect();
    let index = |v: f64, origin: f64, n: usize| {
        ((v - origin) / g.s).floor().clamp(0.0, (n - 1) as f64) as usize
    };
    let (lo_x, hi_x) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p[0]), b.max(p[0]))
        });
    let (lo_y, hi_y) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p[1]), b.max(p[1]))
        });
    let mut found: Option<PixelBox> = None;
    let mut area = 0;
    for j in index(lo_x, g.x0, g.w)..=index(hi_x, g.x0, g.w) {
        for i in index(lo_y, g.y0, g.h)..=index(hi_y, g.y0, g.h) {
            let centre = [g.x0 + (j as f64 + 0.5) * g.s, g.y0 + (i as f64 + 0.5) * g.s];
            if covers(&poly, centre) {
                let (col, row) = (g.w - 1 - j, g.h - 1 - i);
                area += 1;
                match &mut found {
                    Some(b) => b.grow(col, row),
                    None => found = Some(PixelBox::at(col, row)),
                }
            }
        }
    }
    found.map(|b| (b, area))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sage_scene::occupancy::{FREE, OCCUPIED, UNKNOWN};

    /// A 20 × 10 map at 0.1 m from (0, 0): unknown border, free inside, one occupied pillar.
    fn map() -> OccupancyMap {
        let mut m = OccupancyMap::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 3.0), 0.1).unwrap();
        for r in 0..m.height {
            for c in 0..m.width {
                let border = r == 0 || c == 0 || r + 1 == m.height || c + 1 == m.width;
                m.cells[r * m.width + c] = if border { UNKNOWN } else { FREE };
            }
        }
        // A 3 × 2 occupied block and a lone occupied pixel (dropped: < 5 pixels).
        for (c, r) in [(5, 3), (6, 3), (7, 3), (5, 4), (6, 4), (7, 4), (15, 7)] {
            m.cells[r * m.width + c] = OCCUPIED;
        }
        m
    }

    /// An axis-aligned footprint.
    fn object(label: &str, centre: [f32; 2], half: [f32; 2]) -> (&str, [Vec2; 4]) {
        let (c, h) = (Vec2::from(centre), Vec2::from(half));
        let f = [
            c - h,
            c + Vec2::new(h.x, -h.y),
            c + h,
            c + Vec2::new(-h.x, h.y),
        ];
        (label, f)
    }

    #[test]
    fn entries_follow_the_builder() {
        let objects = [
            object("Coffee Table", [0.5, 0.5], [0.2, 0.1]),
            object("Coffee Table", [1.5, 0.5], [0.02, 0.02]),
            object("Chair", [1.5, 0.5], [0.1, 0.1]),
        ];
        let map = PublishedMap::from_footprints(objects, &map());
        let ids: Vec<&str> = map.entries.iter().map(|e| e.item_id.as_str()).collect();
        // The tiny table covers no pixel centre and is skipped without using up a number;
        // the unknown border is the wall grey (one component); the block is an unable area.
        assert_eq!(
            ids,
            ["coffee_table_1", "chair_1", "wall_1", "unable_area_1"]
        );
        let table = &map.entries[0];
        // Pixel centres 0.35..0.65 × 0.45, 0.55 are covered: edges 0.3..0.7 × 0.4..0.6.
        for (got, want) in table.min.iter().chain(&table.max).zip([0.3, 0.4, 0.7, 0.6]) {
            assert!((got - want).abs() < 1e-9, "{:?} {:?}", table.min, table.max);
        }
        assert_eq!(table.area, 8);
        let wall = &map.entries[2];
        assert_eq!(
            (wall.min, wall.max, wall.area),
            ([0.0, 0.0], [2.0, 1.0], 56)
        );
        // Image columns 5–7 hold world x 1.2..1.5 (column 0 at max-x); rows 3–4 world y 0.3..0.5.
        let unable = &map.entries[3];
        assert_eq!(unable.label, "Unable Area");
        for (got, want) in unable
            .min
            .iter()
            .chain(&unable.max)
            .zip([1.2, 0.3, 1.5, 0.5])
        {
            assert!(
                (got - want).abs() < 1e-9,
                "{:?} {:?}",
                unable.min,
                unable.max
            );
        }
    }

    #[test]
    fn wall_grey_and_cover() {
        assert_eq!(wall_value(&[0, 127, 127, 200, 255]), 127);
        assert_eq!(wall_value(&[0, 100, 200, 255]), 100);
        assert_eq!(wall_value(&[0, 0, 255]), 0);
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(covers(&sq, [0.5, 0.5]));
        assert!(covers(&sq, [1.0, 0.5]));
        assert!(covers(&sq, [0.0, 0.0]));
        assert!(!covers(&sq, [1.0001, 0.5]));
        assert_eq!(two_decimals(0.30000000000000004), 0.3);
        assert_eq!(two_decimals(1.23456), 1.23);
    }
}
