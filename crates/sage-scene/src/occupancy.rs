//! The InteriorGS occupancy map: an 8-bit top-down image (`occupancy.png`) with its placement
//! (`occupancy.json`).
//!
//! Values: 255 free, 0 occupied, 127 unknown. Placement follows the InteriorGS viewer convention
//! (research notes §1.5): column `c` covers world x from `upper.x − scale·(c+1)` to
//! `upper.x − scale·c` (column 0 at max-x, mirrored), row `r` covers world y from
//! `lower.y + scale·r` (row 0 at min-y). Cell centres sit half a cell inside.

use glam::{Vec2, Vec3};
use sage_core::{Error, Result, ResultExt};
use sage_io::limits::{IMAGE_MEGAPIXELS, SCENE_JSON_MB};
use serde_json::{Value, json};
use std::path::Path;

/// A free cell.
pub const FREE: u8 = 255;
/// An occupied cell.
pub const OCCUPIED: u8 = 0;
/// A cell of unknown state (outside the mapped area).
pub const UNKNOWN: u8 = 127;

/// A top-down occupancy grid in the InteriorGS convention.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyMap {
    /// Metres per cell.
    pub scale: f32,
    /// World lower corner (`min` / `lower`).
    pub lower: Vec3,
    /// World upper corner (`max` / `upper`).
    pub upper: Vec3,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Row-major cells, `height × width`.
    pub cells: Vec<u8>,
    /// `scale`, `min[0]` and `min[1]` at the precision `occupancy.json` holds them. Tools that
    /// compute in double precision from the file (the published SAGE-3D map builder) need them
    /// unrounded; a map built in memory holds its f32 values widened, which is what
    /// [`OccupancyMap::save`] writes.
    pub exact_placement: [f64; 3],
}

impl OccupancyMap {
    /// A map of `UNKNOWN` cells covering `lower`…`upper` at `scale` metres per cell.
    pub fn new(lower: Vec3, upper: Vec3, scale: f32) -> Result<Self> {
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(Error::invalid(format!(
                "occupancy scale must be > 0, got {scale}"
            )));
        }
        let size = (upper - lower).truncate();
        if !(size.x > 0.0 && size.y > 0.0) {
            return Err(Error::invalid("occupancy bounds are empty"));
        }
        let width = (size.x / scale).ceil() as usize;
        let height = (size.y / scale).ceil() as usize;
        Ok(OccupancyMap {
            scale,
            lower,
            upper,
            width,
            height,
            cells: vec![UNKNOWN; width * height],
            exact_placement: [scale, lower.x, lower.y].map(f64::from),
        })
    }

    /// The world (x, y) of the centre of cell (column `c`, row `r`).
    pub fn cell_center(&self, c: usize, r: usize) -> Vec2 {
        Vec2::new(
            self.upper.x - self.scale * (c as f32 + 0.5),
            self.lower.y + self.scale * (r as f32 + 0.5),
        )
    }

    /// The cell (column, row) holding world point `p`, if inside the map.
    pub fn cell_at(&self, p: Vec2) -> Option<(usize, usize)> {
        let c = ((self.upper.x - p.x) / self.scale).floor();
        let r = ((p.y - self.lower.y) / self.scale).floor();
        (c >= 0.0 && r >= 0.0 && (c as usize) < self.width && (r as usize) < self.height)
            .then_some((c as usize, r as usize))
    }

    /// The value of cell (column, row).
    pub fn get(&self, c: usize, r: usize) -> u8 {
        self.cells[r * self.width + c]
    }

    /// Counts of (free, occupied, unknown or other) cells.
    pub fn counts(&self) -> (usize, usize, usize) {
        let free = self.cells.iter().filter(|&&v| v == FREE).count();
        let occ = self.cells.iter().filter(|&&v| v == OCCUPIED).count();
        (free, occ, self.cells.len() - free - occ)
    }

    /// Reads `occupancy.png` and `occupancy.json` from a scene folder.
    ///
    /// The image's size is checked against what the box of `occupancy.json` needs (with a
    /// generous margin) and against [`IMAGE_MEGAPIXELS`] before the image is decoded, so a
    /// small PNG whose header claims a huge image is refused without allocating it.
    pub fn load(dir: &Path) -> Result<Self> {
        let json_path = dir.join("occupancy.json");
        let png_path = dir.join("occupancy.png");
        let text = sage_io::files::read_text(&json_path, &SCENE_JSON_MB)?;
        let (scale, lower, upper) = parse_placement(&text).in_file(&json_path)?;
        let [box_w, box_h] = cells_for(lower, upper, scale);
        IMAGE_MEGAPIXELS
            .check(
                // Both are finite (the bounds and scale are finite f32); `as` saturates.
                (box_w * box_h) as u64,
                &format!("the box at scale {scale} needs {box_w}×{box_h} cells"),
            )
            .in_file(&json_path)?;
        let (width, height, cells) = read_gray_png(&png_path, [box_w, box_h])?;
        Ok(OccupancyMap {
            scale: scale as f32,
            lower: Vec3::from_array(lower.map(|v| v as f32)),
            upper: Vec3::from_array(upper.map(|v| v as f32)),
            width,
            height,
            cells,
            exact_placement: [scale, lower[0], lower[1]],
        })
    }

    /// Writes `occupancy.png` and `occupancy.json` (with both key spellings) into `dir`.
    pub fn save(&self, dir: &Path) -> Result<()> {
        let placement = json!({
            "scale": self.scale,
            "min": self.lower.to_array(), "max": self.upper.to_array(),
            "lower": self.lower.to_array(), "upper": self.upper.to_array(),
        });
        let png_path = dir.join("occupancy.png");
        sage_io::files::write_png(
            &png_path,
            self.width,
            self.height,
            png::ColorType::Grayscale,
            png::BitDepth::Eight,
            &self.cells,
        )?;
        sage_io::files::write_json(&dir.join("occupancy.json"), &placement)
    }
}

/// A corner given as a 2- or 3-number array under `key` (a missing z reads as 0), with the
/// number of values the file gave.
fn corner_at(key: &str, value: &Value) -> Result<([f64; 3], usize)> {
    let arr = value
        .as_array()
        .filter(|a| a.len() == 2 || a.len() == 3)
        .ok_or_else(|| Error::format(key, "expected an array of 2 or 3 numbers"))?;
    let mut out = [0.0; 3];
    for (i, x) in arr.iter().enumerate() {
        // The map holds the bounds as f32: a value beyond its range is not finite there.
        out[i] = x
            .as_f64()
            .filter(|f| (*f as f32).is_finite())
            .ok_or_else(|| Error::format(format!("{key}[{i}]"), "expected a finite number"))?;
    }
    Ok((out, arr.len()))
}

/// A corner of the box, under either of its two spellings `keys` (`min`/`lower`,
/// `max`/`upper`), with the key it was read from and the number of values it has. Where the
/// file gives both they must agree (at the single precision the map holds them at, on the axes
/// both give): a file whose two spellings disagree has no one box, and taking either would
/// place the map silently wrong.
///
/// # Errors
///
/// Neither key, a value that is not 2 or 3 finite numbers, or two that disagree, naming both.
fn corner(v: &Value, keys: [&'static str; 2]) -> Result<(&'static str, [f64; 3], usize)> {
    let mut found = Vec::new();
    for key in keys {
        if let Some(value) = v.get(key) {
            found.push((key, corner_at(key, value)?));
        }
    }
    match found[..] {
        [] => Err(Error::format(
            keys.join("/"),
            "missing (expected a 2- or 3-number array)",
        )),
        [(key, (p, n))] => Ok((key, p, n)),
        [(a, (p, n)), (b, (q, m)), ..] => {
            if let Some(i) = (0..n.min(m)).find(|&i| p[i] as f32 != q[i] as f32) {
                return Err(Error::format(
                    format!("{a}[{i}]/{b}[{i}]"),
                    format!(
                        "{a}[{i}] is {} but {b}[{i}] is {}: the two spellings of one corner \
                         disagree (keep one, or make them equal)",
                        p[i], q[i]
                    ),
                ));
            }
            Ok((a, p, n))
        }
    }
}

/// Reads `scale` and the bounds (accepting `min`/`lower` and `max`/`upper`), at the file's
/// precision.
///
/// # Errors
///
/// Beyond those of its fields: a lower corner above the upper one on an axis both give (the
/// cells of an inverted box would lie outside the box the file names, from `upper.x` down and
/// from `lower.y` up), and two spellings of one corner that disagree.
pub fn parse_placement(text: &str) -> Result<(f64, [f64; 3], [f64; 3])> {
    let v: Value = serde_json::from_str(sage_io::files::strip_bom(text))
        .map_err(|e| Error::format(format!("line {}", e.line()), e.to_string()))?;
    let scale = v
        .get("scale")
        .and_then(Value::as_f64)
        .filter(|s| *s > 0.0 && (*s as f32) > 0.0 && (*s as f32).is_finite())
        .ok_or_else(|| Error::format("scale", "missing or not a positive number"))?;
    let (lo_key, lower, lo_n) = corner(&v, ["min", "lower"])?;
    let (hi_key, upper, hi_n) = corner(&v, ["max", "upper"])?;
    // A z the file does not give is no bound to compare.
    if let Some(k) = (0..lo_n.min(hi_n)).find(|&k| lower[k] > upper[k]) {
        return Err(Error::format(
            format!("{lo_key}[{k}]/{hi_key}[{k}]"),
            format!(
                "{lo_key}[{k}] is {} but {hi_key}[{k}] is {}: the box is inverted ({lo_key} is \
                 its lower corner, {hi_key} its upper)",
                lower[k], upper[k]
            ),
        ));
    }
    Ok((scale, lower, upper))
}

/// The cells (columns, rows) that the box `lower`…`upper` needs at `scale` metres per cell; the
/// box is ordered ([`parse_placement`] refuses one that is not).
fn cells_for(lower: [f64; 3], upper: [f64; 3], scale: f64) -> [f64; 2] {
    [0, 1].map(|k| ((upper[k] - lower[k]) / scale).ceil())
}

/// How much larger than its box an occupancy image may be, per side: twice the box plus this
/// many cells. The images sage3d writes match their box to the cell; the margin keeps other
/// tools' rounding or padding from being refused while still bounding the image by its box.
const BOX_MARGIN_CELLS: f64 = 16.0;

/// Reads an 8-bit grey image whose box needs `box_cells` (columns, rows); its header is checked
/// against them, and against the pixel limit, before anything the size of the image is
/// allocated.
fn read_gray_png(path: &Path, box_cells: [f64; 2]) -> Result<(usize, usize, Vec<u8>)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let header = decoder
        .read_header_info()
        .map_err(|e| Error::format("png", e.to_string()).in_file(path))?;
    let (w, h) = (header.width, header.height);
    let [box_w, box_h] = box_cells;
    let most = |cells: f64| 2.0 * cells + BOX_MARGIN_CELLS;
    if f64::from(w) > most(box_w) || f64::from(h) > most(box_h) {
        return Err(Error::format(
            "png",
            format!(
                "the {w}×{h} image is far larger than the box of occupancy.json needs \
                 ({box_w}×{box_h} cells; at most {}×{} accepted)",
                most(box_w),
                most(box_h)
            ),
        )
        .in_file(path));
    }
    IMAGE_MEGAPIXELS
        .check(u64::from(w) * u64::from(h), &format!("the {w}×{h} image"))
        .in_file(path)?;
    let mut reader = decoder
        .read_info()
        .map_err(|e| Error::format("png", e.to_string()).in_file(path))?;
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| Error::format("png", e.to_string()).in_file(path))?;
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    // Colour or grey+alpha images keep their first channel (the grey level).
    let cells = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .map(|px| px[0])
        .collect();
    Ok((w, h, cells))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_spellings_are_accepted() {
        let a = parse_placement(r#"{"scale":0.05,"min":[0,1,0],"max":[4,5,3]}"#).unwrap();
        let b = parse_placement(r#"{"scale":0.05,"lower":[0,1,0],"upper":[4,5,3]}"#).unwrap();
        assert_eq!(a, b);
        let e = parse_placement(r#"{"scale":0.05,"min":[0,1,0]}"#).unwrap_err();
        assert!(e.to_string().contains("max/upper"));
    }

    #[test]
    fn cell_mapping_is_mirrored_in_x_and_round_trips() {
        let m = OccupancyMap::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 3.0), 0.1).unwrap();
        assert_eq!((m.width, m.height), (20, 10));
        let c0 = m.cell_center(0, 0);
        assert!((c0 - Vec2::new(1.95, 0.05)).length() < 1e-5);
        for (c, r) in [(0, 0), (19, 9), (7, 3)] {
            assert_eq!(m.cell_at(m.cell_center(c, r)), Some((c, r)));
        }
        assert_eq!(m.cell_at(Vec2::new(-0.1, 0.5)), None);
    }

    /// A scene folder whose `occupancy.json` covers 1 m × 0.5 m at 0.1 m (10 × 5 cells).
    fn small_box() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let json = r#"{"scale": 0.1, "min": [0, 0, 0], "max": [1, 0.5, 2]}"#;
        std::fs::write(dir.path().join("occupancy.json"), json).unwrap();
        dir
    }

    fn write_gray(path: &Path, width: usize, height: usize) {
        let cells = vec![FREE; width * height];
        let (color, depth) = (png::ColorType::Grayscale, png::BitDepth::Eight);
        sage_io::files::write_png(path, width, height, color, depth, &cells).unwrap();
    }

    #[test]
    fn a_png_header_claiming_a_huge_image_is_refused_before_decoding() {
        let dir = small_box();
        let path = dir.path().join("occupancy.png");
        std::fs::write(&path, header_only_png(20_000, 20_000)).unwrap();
        let e = OccupancyMap::load(dir.path()).unwrap_err();
        assert_eq!(e.file(), Some(path.as_path()));
        assert_eq!(
            e.to_string(),
            format!(
                "{}: png: the 20000×20000 image is far larger than the box of occupancy.json \
                 needs (10×5 cells; at most 36×26 accepted)",
                path.display()
            )
        );
    }

    /// A PNG of signature, a header declaring `width × height` grey pixels and the end: no
    /// image data at all, so only a check of the header can refuse it before decoding.
    fn header_only_png(width: u32, height: u32) -> Vec<u8> {
        let mut file = Vec::new();
        let mut png = png::Encoder::new(&mut file, width, height);
        png.set_color(png::ColorType::Grayscale);
        drop(png.write_header().unwrap());
        assert!(file.len() < 100);
        file
    }

    #[test]
    fn an_image_within_its_box_but_over_the_pixel_limit_is_refused_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        // 62.5 m at 2^-7 m per cell: 8000 × 8000 cells, exactly the default 64 megapixels.
        let json = r#"{"scale": 0.0078125, "min": [0, 0, 0], "max": [62.5, 62.5, 3]}"#;
        std::fs::write(dir.path().join("occupancy.json"), json).unwrap();
        let path = dir.path().join("occupancy.png");
        std::fs::write(&path, header_only_png(9000, 9000)).unwrap();
        let e = OccupancyMap::load(dir.path()).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "{}: the 9000×9000 image: 81 megapixels, over the limit of 64 megapixels on an \
                 image; set the environment variable SAGE3D_MAX_IMAGE_MEGAPIXELS to raise it",
                path.display()
            )
        );
    }

    #[test]
    fn an_image_much_larger_than_its_box_is_refused_and_one_within_the_margin_read() {
        let dir = small_box();
        let path = dir.path().join("occupancy.png");
        write_gray(&path, 37, 5);
        let e = OccupancyMap::load(dir.path()).unwrap_err();
        assert!(
            e.to_string().contains("the 37×5 image is far larger"),
            "{e}"
        );
        write_gray(&path, 36, 26);
        let m = OccupancyMap::load(dir.path()).unwrap();
        assert_eq!((m.width, m.height, m.cells.len()), (36, 26, 36 * 26));
    }

    #[test]
    fn a_box_needing_too_many_cells_is_refused_before_the_image_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let json_path = dir.path().join("occupancy.json");
        // 2^17 m at 2^-7 m per cell: 2^24 cells a side, 2^48 in all (exact in binary).
        let json = r#"{"scale": 0.0078125, "min": [0, 0, 0], "max": [131072, 131072, 3]}"#;
        std::fs::write(&json_path, json).unwrap();
        write_gray(&dir.path().join("occupancy.png"), 4, 4);
        let e = OccupancyMap::load(dir.path()).unwrap_err();
        assert_eq!(e.file(), Some(json_path.as_path()));
        assert_eq!(
            e.location(),
            "the box at scale 0.0078125 needs 16777216×16777216 cells"
        );
        assert_eq!(
            e.message(),
            "281474976.8 megapixels, over the limit of 64 megapixels on an image; set the \
             environment variable SAGE3D_MAX_IMAGE_MEGAPIXELS to raise it"
        );
    }

    #[test]
    fn placement_with_a_byte_order_mark_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let m = OccupancyMap::new(Vec3::ZERO, Vec3::new(1.0, 0.5, 2.0), 0.1).unwrap();
        m.save(dir.path()).unwrap();
        let json_path = dir.path().join("occupancy.json");
        let text = std::fs::read_to_string(&json_path).unwrap();
        std::fs::write(&json_path, format!("\u{feff}{text}")).unwrap();
        assert_eq!(OccupancyMap::load(dir.path()).unwrap(), m);
    }

    #[test]
    fn png_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = OccupancyMap::new(Vec3::ZERO, Vec3::new(1.0, 0.5, 2.0), 0.1).unwrap();
        m.cells[3] = FREE;
        m.cells[7] = OCCUPIED;
        m.save(dir.path()).unwrap();
        let r = OccupancyMap::load(dir.path()).unwrap();
        assert_eq!(r, m);
    }
}
