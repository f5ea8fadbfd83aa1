//! A small RGB canvas for the map images: filled polygons, lines, discs and a 5×7 bitmap font
//! for the legend (upper-case letters, digits and a few signs), so the PNGs explain themselves
//! without a font library; [`printable`], [`clip`] and [`wrap`] fit text to that font and to
//! lines of a width.

use glam::Vec2;
use sage_core::Result;
use std::path::Path;

/// An RGB image with a world-to-pixel mapping (x right, y up; row 0 at the top).
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Rows top to bottom, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    origin: Vec2,
    top: f32,
    scale: f32,
}

impl Canvas {
    /// A canvas of `width × height` pixels filled with `background`, whose pixel (0, map_rows)
    /// bottom-left corner is world `origin` at `scale` metres per pixel over `map_rows` rows.
    pub fn new(
        width: usize,
        height: usize,
        background: [u8; 3],
        origin: Vec2,
        scale: f32,
        map_rows: usize,
    ) -> Canvas {
        Canvas {
            width,
            height,
            rgb: background.repeat(width * height),
            origin,
            top: origin.y + map_rows as f32 * scale,
            scale,
        }
    }

    /// The pixel coordinates (continuous) of world point `p`.
    pub fn to_pixel(&self, p: Vec2) -> Vec2 {
        Vec2::new(
            (p.x - self.origin.x) / self.scale,
            (self.top - p.y) / self.scale,
        )
    }

    /// The world point at pixel coordinates `q` (continuous): the inverse of [`Canvas::to_pixel`],
    /// so marks placed in pixels (a legend) can be drawn with the world-space primitives.
    pub fn to_world(&self, q: Vec2) -> Vec2 {
        Vec2::new(
            self.origin.x + q.x * self.scale,
            self.top - q.y * self.scale,
        )
    }

    /// Sets pixel (x, y) when inside the image.
    pub fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let k = (y as usize * self.width + x as usize) * 3;
            self.rgb[k..k + 3].copy_from_slice(&c);
        }
    }

    /// Fills a world polygon (even-odd rule over pixel centres).
    pub fn fill_polygon(&mut self, poly: &[Vec2], c: [u8; 3]) {
        if poly.len() < 3 {
            for w in poly.windows(2) {
                self.line(w[0], w[1], c, 1);
            }
            return;
        }
        let px: Vec<Vec2> = poly.iter().map(|p| self.to_pixel(*p)).collect();
        let lo = px.iter().fold(f32::INFINITY, |m, p| m.min(p.y)).max(0.0) as usize;
        let hi =
            (px.iter().fold(f32::NEG_INFINITY, |m, p| m.max(p.y)).ceil() as usize).min(self.height);
        let mut xs = Vec::new();
        for y in lo..hi {
            let yc = y as f32 + 0.5;
            xs.clear();
            for e in 0..px.len() {
                let (a, b) = (px[e], px[(e + 1) % px.len()]);
                if (a.y > yc) != (b.y > yc) {
                    xs.push(a.x + (yc - a.y) / (b.y - a.y) * (b.x - a.x));
                }
            }
            xs.sort_by(f32::total_cmp);
            // Clipped to the image: a polygon reaching far outside it (a broken mesh's hull)
            // must cost the pixels it covers here, not the ones it would cover out there.
            let last = self.width as i64 - 1;
            for pair in xs.chunks_exact(2) {
                let x0 = (pair[0] - 0.5).ceil().max(0.0) as i64;
                let x1 = ((pair[1] - 0.5).floor() as i64).min(last);
                for x in x0..=x1 {
                    self.put(x, y as i64, c);
                }
            }
        }
        // Thin shapes still show: their outline is drawn too.
        for e in 0..poly.len() {
            self.line(poly[e], poly[(e + 1) % poly.len()], c, 1);
        }
    }

    /// Draws a world segment `thickness` pixels wide.
    pub fn line(&mut self, a: Vec2, b: Vec2, c: [u8; 3], thickness: i64) {
        let r = thickness / 2;
        // Stepped only over its part near the image, so the cost is bounded by the image
        // whatever the segment's length.
        let margin = Vec2::splat(r as f32 + 1.0);
        let size = Vec2::new(self.width as f32, self.height as f32);
        let Some((pa, pb)) =
            clip_segment(self.to_pixel(a), self.to_pixel(b), -margin, size + margin)
        else {
            return;
        };
        let steps = (pa.distance(pb).ceil() as usize).max(1);
        for s in 0..=steps {
            let p = pa.lerp(pb, s as f32 / steps as f32);
            for dy in -r..=r {
                for dx in -r..=r {
                    self.put(p.x as i64 + dx, p.y as i64 + dy, c);
                }
            }
        }
    }

    /// Draws a filled disc of `radius` pixels at world point `p`.
    pub fn disc(&mut self, p: Vec2, radius: i64, c: [u8; 3]) {
        let q = self.to_pixel(p);
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                if dx * dx + dy * dy <= radius * radius {
                    self.put(q.x as i64 + dx, q.y as i64 + dy, c);
                }
            }
        }
    }

    /// Writes `text` (upper-cased) with its top-left at pixel (x, y), glyphs scaled by `scale`.
    pub fn text(&mut self, x: i64, y: i64, text: &str, c: [u8; 3], scale: i64) {
        for (n, ch) in text.chars().enumerate() {
            let rows = glyph(ch.to_ascii_uppercase());
            let gx = x + n as i64 * 6 * scale;
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for sy in 0..scale {
                            for sx in 0..scale {
                                self.put(gx + col * scale + sx, y + r as i64 * scale + sy, c);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Draws a legend column at pixel x = `x`: a swatch and a label per entry.
    pub fn legend(&mut self, x: i64, title: &str, entries: &[([u8; 3], String)]) {
        let ink = [20, 20, 20];
        self.text(x, 8, title, ink, 2);
        for (n, (c, label)) in entries.iter().enumerate() {
            let y = 34 + n as i64 * LEGEND_ROW;
            for dy in 0..12 {
                for dx in 0..12 {
                    self.put(x + dx, y + dy, *c);
                }
            }
            self.text(x + 18, y - 1, label, ink, 2);
        }
    }

    /// Copies `src` (`w × h` RGB, rows top to bottom) into the canvas with its top-left at
    /// pixel (x0, y0), clipped to the canvas.
    pub fn blit(&mut self, src: &[u8], w: usize, h: usize, x0: usize, y0: usize) {
        if x0 >= self.width {
            return;
        }
        let cols = w.min(self.width - x0);
        for y in 0..h.min(self.height.saturating_sub(y0)) {
            let d = ((y0 + y) * self.width + x0) * 3;
            let s = y * w * 3;
            if let (Some(dst), Some(src)) =
                (self.rgb.get_mut(d..d + cols * 3), src.get(s..s + cols * 3))
            {
                dst.copy_from_slice(src);
            }
        }
    }

    /// Saves the canvas as an RGB PNG (atomically).
    pub fn save_png(&self, path: &Path) -> Result<()> {
        crate::files::write_rgb_png(path, self.width, self.height, &self.rgb)
    }
}

/// Pixel height of one legend row.
pub const LEGEND_ROW: i64 = 18;

/// The part of segment `a`–`b` inside the rectangle `lo`…`hi` (Cohen–Sutherland); `None` when
/// none is, or when an end is not finite. An end moved to the rectangle is put exactly on the
/// side it crosses, and clamped into the rectangle: f32 cannot place a cut made at 1e30 within
/// the rectangle's size, and the cost of drawing is then bounded by the rectangle whatever
/// the ends.
fn clip_segment(mut a: Vec2, mut b: Vec2, lo: Vec2, hi: Vec2) -> Option<(Vec2, Vec2)> {
    if !(a.is_finite() && b.is_finite()) {
        return None;
    }
    let code = |p: Vec2| {
        u8::from(p.x < lo.x)
            | u8::from(p.x > hi.x) << 1
            | u8::from(p.y < lo.y) << 2
            | u8::from(p.y > hi.y) << 3
    };
    // Each pass puts one end on one more side: four sides, two ends.
    for _ in 0..8 {
        let (ca, cb) = (code(a), code(b));
        if ca | cb == 0 {
            break;
        }
        if ca & cb != 0 {
            return None;
        }
        let (out, other, c) = if ca != 0 { (a, b, ca) } else { (b, a, cb) };
        // The other end is on the inner side of the side crossed, so the divisor is not zero.
        let d = other - out;
        let moved = if c & 1 != 0 {
            Vec2::new(lo.x, out.y + d.y * (lo.x - out.x) / d.x)
        } else if c & 2 != 0 {
            Vec2::new(hi.x, out.y + d.y * (hi.x - out.x) / d.x)
        } else if c & 4 != 0 {
            Vec2::new(out.x + d.x * (lo.y - out.y) / d.y, lo.y)
        } else {
            Vec2::new(out.x + d.x * (hi.y - out.y) / d.y, hi.y)
        };
        if ca != 0 {
            a = moved;
        } else {
            b = moved;
        }
    }
    Some((a.clamp(lo, hi), b.clamp(lo, hi)))
}

/// Pixel width the legend needs for labels of up to `chars` characters.
pub fn legend_width(chars: usize) -> usize {
    30 + chars * 12
}

/// Pixel height the legend needs for `rows` entries.
pub fn legend_height(rows: usize) -> usize {
    40 + rows * LEGEND_ROW as usize
}

/// A distinct, stable colour per index.
pub fn palette(index: usize) -> [u8; 3] {
    crate::palette::distinct_color(index as u32 + 1)
}

/// `text` in the characters the bitmap font has: marks it lacks that only separate words
/// (commas, quotes, …) are left out, white space becomes one space; anything else the font
/// draws as its unknown-character sign.
pub fn printable(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            ',' | ';' | '!' | '\'' | '"' | '`' | '\u{2018}' | '\u{2019}' | '\u{201C}'
            | '\u{201D}' => {}
            c if c.is_whitespace() => {
                if !out.ends_with(' ') {
                    out.push(' ');
                }
            }
            c => out.push(c),
        }
    }
    out.trim().to_string()
}

/// `text` cut to `n` characters, ending in `...` when cut.
pub fn clip(text: &str, n: usize) -> String {
    if text.chars().count() <= n {
        return text.to_string();
    }
    let kept: String = text.chars().take(n.saturating_sub(3)).collect();
    format!("{kept}...")
}

/// `text` word-wrapped to lines of at most `width` characters, at most `lines` of them (the
/// last ending in `...` when the text goes on); a word longer than a line is broken.
pub fn wrap(text: &str, width: usize, lines: usize) -> Vec<String> {
    let width = width.max(4);
    let mut out: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let mut word: Vec<char> = word.chars().collect();
        loop {
            let used = line.chars().count();
            let room = if used == 0 { width } else { width - used - 1 };
            if word.len() <= room {
                if used > 0 {
                    line.push(' ');
                }
                line.extend(word.iter());
                break;
            }
            if used == 0 {
                // Longer than a whole line: break it.
                line.extend(word.drain(..width));
            }
            out.push(std::mem::take(&mut line));
        }
        if line.chars().count() >= width {
            out.push(std::mem::take(&mut line));
        }
    }
    if !line.is_empty() {
        out.push(line);
    }
    if out.len() > lines {
        out.truncate(lines);
        if let Some(last) = out.last_mut() {
            let kept: String = last.chars().take(width - 3).collect();
            *last = format!("{}...", kept.trim_end());
        }
    }
    out
}

/// The 5×7 bitmap of a character (rows top to bottom, bit 4 = leftmost column).
fn glyph(c: char) -> [u8; 7] {
    match c {
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1E],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '=' => [0, 0, 0x1F, 0, 0x1F, 0, 0],
        '\u{B7}' => [0, 0, 0, 0x0C, 0x0C, 0, 0],
        ' ' => [0; 7],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0, 0x04],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_far_outside_the_image_cost_only_the_pixels_inside() {
        let mut c = Canvas::new(40, 30, [0; 3], Vec2::ZERO, 0.05, 30);
        // Kilometres and beyond at 5 cm a pixel: stepping the whole shapes would take
        // billions of steps (or forever, past the range of the pixel coordinates).
        let far = 1e30;
        c.fill_polygon(
            &[
                Vec2::new(0.5, 0.5),
                Vec2::new(far, 0.5),
                Vec2::new(0.5, far),
            ],
            [255; 3],
        );
        c.line(Vec2::new(-far, 1.0), Vec2::new(far, 1.0), [7; 3], 3);
        c.line(Vec2::new(0.1, -1e5), Vec2::new(0.1, 1e5), [9; 3], 1);
        c.line(Vec2::new(-far, -far), Vec2::new(-far, far), [5; 3], 1);
        let px = |x: usize, y: usize| {
            let k = (y * c.width + x) * 3;
            c.rgb[k]
        };
        // The triangle covers the image's upper right from (0.5, 0.5) m on, the row at 1 m
        // carries the horizontal line, the column at 0.1 m the vertical one.
        assert_eq!(px(39, 0), 255);
        assert_eq!(px(39, 10), 7);
        assert_eq!(px(2, 5), 9);
        assert_eq!(
            px(0, 29),
            0,
            "the corner below and left of the triangle stays clear"
        );
        assert_eq!(
            clip_segment(
                Vec2::ZERO,
                Vec2::new(3.0, 4.0),
                Vec2::splat(-1.0),
                Vec2::splat(9.0)
            ),
            Some((Vec2::ZERO, Vec2::new(3.0, 4.0)))
        );
        assert_eq!(
            clip_segment(
                Vec2::new(20.0, 0.0),
                Vec2::new(20.0, 5.0),
                Vec2::ZERO,
                Vec2::splat(9.0)
            ),
            None
        );
    }

    #[test]
    fn polygon_fill_covers_its_area() {
        let mut c = Canvas::new(20, 20, [0; 3], Vec2::ZERO, 0.1, 20);
        c.fill_polygon(
            &[
                Vec2::new(0.5, 0.5),
                Vec2::new(1.5, 0.5),
                Vec2::new(1.5, 1.5),
                Vec2::new(0.5, 1.5),
            ],
            [255, 0, 0],
        );
        let red = c.rgb.chunks_exact(3).filter(|p| p[0] == 255).count();
        // 10×10 pixels inside, plus the outline drawn on the boundary pixels.
        assert!((100..=121).contains(&red), "{red}");
        // World y up = image row down: (1.0, 1.0) is at row 10, column 10.
        assert_eq!(c.to_pixel(Vec2::new(1.0, 1.0)), Vec2::new(10.0, 10.0));
        assert_eq!(c.to_world(Vec2::new(10.0, 10.0)), Vec2::new(1.0, 1.0));
    }

    #[test]
    fn wrap_breaks_at_words_and_marks_what_is_left_out() {
        let lines = wrap("walk past the sofa and stop at the door", 12, 3);
        assert_eq!(lines, ["walk past", "the sofa and", "stop at t..."]);
        assert_eq!(wrap("short", 12, 3), ["short"]);
        assert_eq!(wrap("abcdefghijklmnop", 6, 3), ["abcdef", "ghijkl", "mnop"]);
        assert!(wrap("", 10, 3).is_empty());
        for l in wrap(&"word ".repeat(50), 17, 3) {
            assert!(l.chars().count() <= 17, "{l}");
        }
    }

    #[test]
    fn printable_drops_marks_the_font_lacks() {
        assert_eq!(
            printable("Go to the sofa,  then don't\tstop!"),
            "Go to the sofa then dont stop"
        );
    }
}
