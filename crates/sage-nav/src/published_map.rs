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
//! `x = x0 + (j + ½)·s`, `y = y0 + (i + ½)·s`. Boxes are computed and rounded there. The
//! published harness maps an agent position p (its stage is W turned 180° about Z, so p is
//! `−p_W`) into M as `p + (m + M)`, m and M the least and greatest coordinates of all mask
//! pixels in the file (research notes §1.6), which is the exact reflection only when the masks
//! reach the grid's edges. Boxes are reflected back into W the same way
//! (`x_W = (m_x + M_x) − x_M`), so box tests on W positions are the harness's.

use glam::Vec2;
use sage_scene::Object;
use sage_scene::occupancy::OccupancyMap;
use std::collections::BTreeMap;

/// Unable-area components smaller than this (pixels) are dropped, as the builder drops them.
pub const MIN_UNABLE_PIXELS: usize = 5;

/// The builder's fixed category ids (1–11, exact labels); other labels get 12, 13, … in order
/// of first appearance in `labels.json`, and unable areas −1.
pub const FIXED_CATEGORIES: [&str; 11] = [
    "door", "window", "chair", "table", "sofa", "bed", "wardrobe", "plant", "floor", "wall",
    "ceiling",
];

/// One object as the builder reads it from `labels.json`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledFootprint<'a> {
    /// `label`, as written.
    pub label: &'a str,
    /// `ins_id`.
    pub ins_id: &'a str,
    /// Corners 0–3 of `bounding_box`: the footprint polygon.
    pub corners: [Vec2; 4],
    /// Lowest and highest z of the eight corners.
    pub z: [f32; 2],
}

/// One entry of the published map: an object, a wall component or an unable area.
#[derive(Debug, Clone, PartialEq)]
pub struct PublishedEntry {
    /// `category_id` (see [`FIXED_CATEGORIES`]).
    pub category_id: i64,
    /// `category_label`: the object's label as written, `wall` or `Unable Area`.
    pub label: String,
    /// `instance_id`: the object's `ins_id`, `wall_{k}` or `unable_area_{k}` (k counts every
    /// component, kept or not).
    pub instance_id: String,
    /// `item_id`: the label in lower case with spaces as `_`, then `_{n}` counted per label
    /// over the kept entries.
    pub item_id: String,
    /// Lower corner of `bbox_m`, reflected into the world frame as the harness maps positions
    /// (through the extent of all mask coordinates), metres.
    pub min: [f64; 2],
    /// Upper corner of `bbox_m`, reflected into the world frame likewise, metres.
    pub max: [f64; 2],
    /// The mask's pixels `(column, row)` in the builder's frame, row by row.
    pub pixels: Vec<(usize, usize)>,
    /// `min_z_m`, `max_z_m`.
    pub z: [f64; 2],
}

/// The published map of a scene: objects in `labels.json` order, then walls, then unable areas.
#[derive(Debug, Clone, PartialEq)]
pub struct PublishedMap {
    /// The entries, in the builder's order.
    pub entries: Vec<PublishedEntry>,
    grid: Grid,
}

/// The file name the published harness looks for: `2D_Semantic_Map_{scene}_Complete.json`.
pub fn file_name(scene: &str) -> String {
    format!("2D_Semantic_Map_{scene}_Complete.json")
}

/// The builder's grid: the occupancy placement in f64 and the image size.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    x0: f64,
    y0: f64,
    s: f64,
    w: usize,
    h: usize,
}

/// `f"{v:.2f}"`: how the builder writes every metric value.
fn format2(v: f64) -> String {
    format!("{v:.2}")
}

/// `f"{v:.2f}"` read back as a number, as the evaluator reads the bounds.
fn two_decimals(v: f64) -> f64 {
    format2(v).parse().unwrap_or(v)
}

impl Grid {
    /// The grid of an occupancy map, placed in double precision as the builder reads
    /// `occupancy.json`.
    fn of(occupancy: &OccupancyMap) -> Grid {
        let [s, x0, y0] = occupancy.exact_placement;
        Grid {
            x0,
            y0,
            s,
            w: occupancy.width,
            h: occupancy.height,
        }
    }

    /// `bbox_m` of a mask in the builder's frame: the pixel edges `[left, bottom, right, top]`.
    fn bbox(&self, pixels: &[(usize, usize)]) -> [f64; 4] {
        let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
        for &(c, r) in pixels {
            (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
        }
        let at = |origin: f64, k: usize| origin + k as f64 * self.s;
        [
            at(self.x0, c0),
            at(self.y0, r0),
            at(self.x0, c1 + 1),
            at(self.y0, r1 + 1),
        ]
    }

    /// The centre the harness reflects through: per axis m + M, the least and greatest
    /// `mask_coords_m` value (pixel centres, two decimals) over every entry; the grid's exact
    /// centre `2·x0 + w·s` when there is no mask at all.
    fn harness_centre<'a>(
        &self,
        masks: impl IntoIterator<Item = &'a [(usize, usize)]>,
    ) -> [f64; 2] {
        let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
        for &(c, r) in masks.into_iter().flatten() {
            (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
        }
        if c0 > c1 {
            return [
                2.0 * self.x0 + self.w as f64 * self.s,
                2.0 * self.y0 + self.h as f64 * self.s,
            ];
        }
        // Rounding to two decimals keeps the order, so the extremes of the written values are
        // those of the extreme pixels.
        let at = |origin: f64, k: usize| two_decimals(origin + (k as f64 + 0.5) * self.s);
        [
            at(self.x0, c0) + at(self.x0, c1),
            at(self.y0, r0) + at(self.y0, r1),
        ]
    }

    /// A mask's box as the evaluator reads it (two decimals), reflected into the world frame
    /// through `centre` ([`Grid::harness_centre`]).
    fn world_box(&self, pixels: &[(usize, usize)], centre: [f64; 2]) -> ([f64; 2], [f64; 2]) {
        let [left, bottom, right, top] = self.bbox(pixels).map(two_decimals);
        let [cx, cy] = centre;
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

/// The 8-connected components of the builder-frame mask `on(col, row)`, numbered in raster
/// order of their first pixel (as `scipy.ndimage.label` numbers them), each as its pixels row
/// by row.
fn components(g: &Grid, on: impl Fn(usize, usize) -> bool) -> Vec<Vec<(usize, usize)>> {
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
            let mut pixels = Vec::new();
            while let Some((c, r)) = stack.pop() {
                pixels.push((c, r));
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
            pixels.sort_unstable_by_key(|&(c, r)| (r, c));
            out.push(pixels);
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
        let n = counts[usize::from(v)];
        if n > 0 && best.is_none_or(|b| n > counts[usize::from(b)]) {
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
        let footprints = objects.iter().map(|o| LabelledFootprint {
            label: &o.label,
            ins_id: &o.ins_id,
            corners: o.obb.footprint(),
            z: [o.obb.min_z(), o.obb.max_z()],
        });
        PublishedMap::from_footprints(footprints, occupancy)
    }

    /// The published map of the objects of `labels.json` over an occupancy image.
    pub fn from_footprints<'a>(
        objects: impl IntoIterator<Item = LabelledFootprint<'a>>,
        occupancy: &OccupancyMap,
    ) -> PublishedMap {
        let g = Grid::of(occupancy);
        let objects: Vec<LabelledFootprint> = objects.into_iter().collect();
        let mut category: BTreeMap<&str, i64> = FIXED_CATEGORIES
            .iter()
            .zip(1..)
            .map(|(c, k)| (*c, k))
            .collect();
        for o in &objects {
            let next = category.len() as i64 + 1;
            category.entry(o.label).or_insert(next);
        }
        let mut counters: BTreeMap<String, usize> = BTreeMap::new();
        let mut entry = |category_id: i64,
                         label: &str,
                         instance_id: String,
                         pixels: Vec<(usize, usize)>,
                         z: [f64; 2]| {
            let n = counters.entry(label.to_string()).or_insert(0);
            *n += 1;
            // Placed once every mask is known (`harness_centre` needs them all).
            let (min, max) = ([0.0; 2], [0.0; 2]);
            PublishedEntry {
                category_id,
                label: label.to_string(),
                instance_id,
                item_id: format!("{}_{n}", label.trim().to_lowercase().replace(' ', "_")),
                min,
                max,
                pixels,
                z,
            }
        };
        let mut entries = Vec::new();
        for o in &objects {
            if let Some(pixels) = rasterise(&g, &o.corners) {
                let z = o.z.map(f64::from);
                entries.push(entry(
                    category[o.label],
                    o.label,
                    o.ins_id.to_string(),
                    pixels,
                    z,
                ));
            }
        }
        // Builder row `row` is image row `h − 1 − row` (the builder flips the image upside down).
        let pixel = |col: usize, row: usize| occupancy.get(col, g.h - 1 - row);
        let wall = wall_value(&occupancy.cells);
        for (k, pixels) in components(&g, |c, r| pixel(c, r) == wall)
            .into_iter()
            .enumerate()
        {
            entries.push(entry(
                category["wall"],
                "wall",
                format!("wall_{}", k + 1),
                pixels,
                [0.0, 3.0],
            ));
        }
        for (k, pixels) in components(&g, |c, r| pixel(c, r) == 0)
            .into_iter()
            .enumerate()
        {
            if pixels.len() >= MIN_UNABLE_PIXELS {
                let id = format!("unable_area_{}", k + 1);
                entries.push(entry(-1, "Unable Area", id, pixels, [0.0, 0.0]));
            }
        }
        let centre = g.harness_centre(entries.iter().map(|e| e.pixels.as_slice()));
        for e in &mut entries {
            (e.min, e.max) = g.world_box(&e.pixels, centre);
        }
        PublishedMap { entries, grid: g }
    }

    /// The map as the published builder writes it (`2D_Semantic_Map_{scene}_Complete.json`):
    /// an array of entries in its own frame, every metric value a two-decimal string, masks as
    /// `[y, x]` pixel centres. The published harness reads this file unchanged.
    pub fn to_json(&self) -> serde_json::Value {
        let g = &self.grid;
        let entries: Vec<serde_json::Value> = self
            .entries
            .iter()
            .map(|e| {
                let [left, bottom, right, top] = g.bbox(&e.pixels);
                let mask: Vec<[String; 2]> = e
                    .pixels
                    .iter()
                    .map(|&(c, r)| {
                        [
                            format2(g.y0 + (r as f64 + 0.5) * g.s),
                            format2(g.x0 + (c as f64 + 0.5) * g.s),
                        ]
                    })
                    .collect();
                let bbox = [left, bottom, right, top].map(format2);
                let xywh = [left, bottom, right - left, top - bottom].map(format2);
                serde_json::json!({
                    "category_id": e.category_id,
                    "category_label": e.label,
                    "instance_id": e.instance_id,
                    "item_id": e.item_id,
                    "bbox_m": bbox,
                    "bbox_xywh_m": xywh,
                    "area": e.pixels.len(),
                    "height_m": format2(e.z[1] - e.z[0]),
                    "min_z_m": format2(e.z[0]),
                    "max_z_m": format2(e.z[1]),
                    "mask_coords_m": mask,
                })
            })
            .collect();
        serde_json::Value::Array(entries)
    }
}

/// The builder-frame pixels whose centres a footprint covers, row by row, or `None` when there
/// are none (the builder skips such objects).
fn rasterise(g: &Grid, footprint: &[Vec2; 4]) -> Option<Vec<(usize, usize)>> {
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
    let mut pixels = Vec::new();
    for j in index(lo_x, g.x0, g.w)..=index(hi_x, g.x0, g.w) {
        for i in index(lo_y, g.y0, g.h)..=index(hi_y, g.y0, g.h) {
            let centre = [g.x0 + (j as f64 + 0.5) * g.s, g.y0 + (i as f64 + 0.5) * g.s];
            if covers(&poly, centre) {
                pixels.push((g.w - 1 - j, g.h - 1 - i));
            }
        }
    }
    pixels.sort_unstable_by_key(|&(c, r)| (r, c));
    (!pixels.is_empty()).then_some(pixels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sage_scene::occupancy::{FREE, OCCUPIED, UNKNOWN};

    /// A 20 × 10 map at 0.1 m from (0, 0): unknown border, free inside, one occupied pillar.
    fn map() -> OccupancyMap {
        let mut m = OccupancyMap::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 3.0), 0.1).unwrap();
        // As `occupancy.json` would hold it ("scale": 0.1), not the f32 widened.
        m.exact_placement = [0.1, 0.0, 0.0];
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

    /// An axis-aligned footprint 0.8 m tall.
    fn object(label: &'static str, centre: [f32; 2], half: [f32; 2]) -> LabelledFootprint<'static> {
        let (c, h) = (Vec2::from(centre), Vec2::from(half));
        LabelledFootprint {
            label,
            ins_id: "7",
            corners: [
                c - h,
                c + Vec2::new(h.x, -h.y),
                c + h,
                c + Vec2::new(-h.x, h.y),
            ],
            z: [0.0, 0.8],
        }
    }

    #[test]
    fn entries_follow_the_builder() {
        let objects = [
            object("Coffee Table", [0.5, 0.5], [0.2, 0.1]),
            object("Coffee Table", [1.5, 0.5], [0.02, 0.02]),
            object("chair", [1.5, 0.5], [0.1, 0.1]),
        ];
        let map = PublishedMap::from_footprints(objects, &map());
        let ids: Vec<&str> = map.entries.iter().map(|e| e.item_id.as_str()).collect();
        // The tiny table covers no pixel centre and is skipped without using up a number;
        // the unknown border is the wall grey (one component); the block is an unable area and
        // the lone pixel is dropped, though it numbers component 1 (the builder's rows run
        // upward from the image's last row, so it comes first).
        assert_eq!(
            ids,
            ["coffee_table_1", "chair_1", "wall_1", "unable_area_1"]
        );
        let cats: Vec<i64> = map.entries.iter().map(|e| e.category_id).collect();
        assert_eq!(cats, [12, 3, 10, -1]);
        let table = &map.entries[0];
        // Pixel centres 0.35..0.65 × 0.45, 0.55 are covered: edges 0.3..0.7 × 0.4..0.6.
        for (got, want) in table.min.iter().chain(&table.max).zip([0.3, 0.4, 0.7, 0.6]) {
            assert!((got - want).abs() < 1e-9, "{:?} {:?}", table.min, table.max);
        }
        assert_eq!(table.pixels.len(), 8);
        let wall = &map.entries[2];
        assert_eq!(
            (wall.min, wall.max, wall.pixels.len()),
            ([0.0, 0.0], [2.0, 1.0], 56)
        );
        // Image columns 5–7 hold world x 1.2..1.5 (column 0 at max-x); rows 3–4 world y 0.3..0.5.
        let unable = &map.entries[3];
        assert_eq!(
            (unable.label.as_str(), unable.instance_id.as_str()),
            ("Unable Area", "unable_area_2")
        );
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
        // The file: the builder's frame is the world reflected through (2, 1).
        let json = map.to_json();
        let t = &json[0];
        assert_eq!(
            t["bbox_m"],
            serde_json::json!(["1.30", "0.40", "1.70", "0.60"])
        );
        assert_eq!(
            t["bbox_xywh_m"],
            serde_json::json!(["1.30", "0.40", "0.40", "0.20"])
        );
        assert_eq!(
            (t["area"].as_u64(), t["height_m"].as_str()),
            (Some(8), Some("0.80"))
        );
        assert_eq!(t["mask_coords_m"][0], serde_json::json!(["0.45", "1.35"]));
        assert_eq!(json[2]["instance_id"], "wall_1");
        assert_eq!(json[3]["category_label"], "Unable Area");
    }

    /// The harness's goal test from the written file alone: p (in W) mapped into the builder's
    /// frame through the extent of every `mask_coords_m` value, tested against `bbox_m`.
    fn harness_inside(json: &serde_json::Value, entry: usize, p: [f64; 2]) -> bool {
        let num = |v: &serde_json::Value| v.as_str().unwrap().parse::<f64>().unwrap();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for e in json.as_array().unwrap() {
            for yx in e["mask_coords_m"].as_array().unwrap() {
                // Pairs are [y, x].
                for (k, v) in [(1, num(&yx[0])), (0, num(&yx[1]))] {
                    lo[k] = lo[k].min(v);
                    hi[k] = hi[k].max(v);
                }
            }
        }
        let b: Vec<f64> = json[entry]["bbox_m"]
            .as_array()
            .unwrap()
            .iter()
            .map(num)
            .collect();
        let m = [lo[0] + hi[0] - p[0], lo[1] + hi[1] - p[1]];
        m[0] >= b[0] && m[0] <= b[2] && m[1] >= b[1] && m[1] <= b[3]
    }

    #[test]
    fn boxes_follow_the_harness_frame_when_masks_miss_the_edges() {
        // Free image column 0 (world max-x) and image row 0 (world min-y): the wall no longer
        // reaches those edges, so the masks span x 0.15..1.95 (m + M = 2.1, not 2.0) and
        // y 0.05..0.85 (0.9, not 1.0).
        let mut occ = map();
        for r in 0..occ.height {
            occ.cells[r * occ.width] = FREE;
        }
        for c in 0..occ.width {
            occ.cells[c] = FREE;
        }
        let objects = [object("Coffee Table", [0.5, 0.5], [0.2, 0.1])];
        let map = PublishedMap::from_footprints(objects, &occ);
        let table = &map.entries[0];
        // The file is the builder's and has not moved: bbox_m 1.30..1.70 × 0.40..0.60.
        let json = map.to_json();
        assert_eq!(
            json[0]["bbox_m"],
            serde_json::json!(["1.30", "0.40", "1.70", "0.60"])
        );
        // The box as the harness places it in W: shifted by (+0.1, −0.1) from the exact
        // reflection's 0.3..0.7 × 0.4..0.6.
        for (got, want) in table.min.iter().chain(&table.max).zip([0.4, 0.3, 0.8, 0.5]) {
            assert!((got - want).abs() < 1e-9, "{:?} {:?}", table.min, table.max);
        }
        // Points where the two mappings disagree: the box test on W agrees with the harness
        // run on the file.
        for p in [[0.75, 0.35], [0.35, 0.55], [0.5, 0.45], [0.85, 0.45]] {
            let ours = (0..2).all(|k| p[k] >= table.min[k] && p[k] <= table.max[k]);
            assert_eq!(ours, harness_inside(&json, 0, p), "{p:?}");
        }
        assert!(harness_inside(&json, 0, [0.75, 0.35]));
        assert!(!harness_inside(&json, 0, [0.35, 0.55]));
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
        assert_eq!(format2(0.125), "0.12");
        assert_eq!(two_decimals(1.23456), 1.23);
    }
}
