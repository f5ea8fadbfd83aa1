//! The InteriorGS occupancy map: an 8-bit top-down image (`occupancy.png`) with its placement
//! (`occupancy.json`).
//!
//! Values: 255 free, 0 occupied, 127 unknown. Placement follows the InteriorGS viewer convention
//! (research notes §1.5): column `c` covers world x from `upper.x − scale·(c+1)` to
//! `upper.x − scale·c` (column 0 at max-x, mirrored), row `r` covers world y from
//! `lower.y + scale·r` (row 0 at min-y). Cell centres sit half a cell inside.

use glam::{Vec2, Vec3};
use sage_core::{Error, Result, ResultExt};
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
    pub fn load(dir: &Path) -> Result<Self> {
        let json_path = dir.join("occupancy.json");
        let png_path = dir.join("occupancy.png");
        let text = std::fs::read_to_string(&json_path).map_err(|e| Error::io(&json_path, e))?;
        let (scale, lower, upper) = parse_placement(&text).in_file(&json_path)?;
        let (width, height, cells) = read_gray_png(&png_path)?;
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

fn vec3_field(v: &Value, keys: [&str; 2]) -> Result<[f64; 3]> {
    let (key, value) = keys
        .iter()
        .find_map(|k| v.get(*k).map(|x| (*k, x)))
        .ok_or_else(|| {
            Error::format(keys.join("/"), "missing (expected a 2- or 3-number array)")
        })?;
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
    Ok(out)
}

/// Reads `scale` and the bounds (accepting `min`/`lower` and `max`/`upper`), at the file's
/// precision.
pub fn parse_placement(text: &str) -> Result<(f64, [f64; 3], [f64; 3])> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| Error::format(format!("line {}", e.line()), e.to_string()))?;
    let scale = v
        .get("scale")
        .and_then(Value::as_f64)
        .filter(|s| *s > 0.0 && (*s as f32) > 0.0 && (*s as f32).is_finite())
        .ok_or_else(|| Error::format("scale", "missing or not a positive number"))?;
    Ok((
        scale,
        vec3_field(&v, ["min", "lower"])?,
        vec3_field(&v, ["max", "upper"])?,
    ))
}

fn read_gray_png(path: &Path) -> Result<(usize, usize, Vec<u8>)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
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
