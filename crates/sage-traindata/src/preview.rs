//! The preview: an animated GIF of a few episodes, so a person can check the data by eye.
//!
//! Each GIF frame is one step of an episode: on the left the RGB frame the sample holds (what
//! a model sees when it chooses the step's action), on the right the scene's top-down semantic
//! map with the reference path, the poses walked so far and the current pose with a heading
//! tick, and below both the episode, the instruction and the action in words. The episodes
//! follow one another, with a pause on each one's last frame. The colours are the evaluation
//! report's ([`sage_io::marks`]), so a preview reads like a report's episode map.

/// The preview's file name in the output folder.
pub const PREVIEW_FILE: &str = "preview.gif";

/// How long each step is shown, hundredths of a second.
pub const STEP_DELAY: u16 = 40;

/// How long an episode's last frame (its STOP) is shown, hundredths of a second: long enough
/// to see where the walk ended before the next episode starts.
pub const END_DELAY: u16 = 200;

/// The widest the preview gets, pixels: frame, map and margins together.
pub const MAX_WIDTH: usize = 900;

use crate::replay::Route;
use crate::sample::{EpisodeSample, IMAGES_DIR};
use glam::Vec2;
use sage_core::{Error, Result, ResultExt};
use sage_dataset::Episode;
use sage_env::SceneContext;
use sage_io::Canvas;
use sage_io::canvas::{clip, printable, wrap};
use sage_io::gif::GifWriter;
use sage_io::{marks, palette};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// The height the RGB frame is scaled towards (by a whole factor, so every pixel of the frame
/// stays a clean block): training frames are small, 224 pixels or less.
const FRAME_HEIGHT: usize = 256;
/// The tallest the frame and map panels get: a large render is scaled down to it.
const MAX_PANEL_HEIGHT: usize = 640;
/// The margin around and between the panels, pixels.
const PAD: usize = 8;
/// Lines of the instruction in the text band (longer ones end in `...`).
const INSTRUCTION_LINES: usize = 3;
/// Lines of the text band: the episode and step, the instruction, the action, the key.
const BAND_LINES: usize = INSTRUCTION_LINES + 3;
/// The page behind the panels and the text.
const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Text.
const INK: [u8; 3] = [20, 20, 20];

/// What the preview is drawn from besides the samples.
pub struct Sources<'a> {
    /// The render's routes by scene (each route's first episode: reference path and goal).
    pub routes: &'a BTreeMap<String, Vec<Route>>,
    /// Each scene's folder (for its map).
    pub scene_dirs: &'a BTreeMap<String, std::path::PathBuf>,
    /// The frames' size, (width, height).
    pub frame_size: (usize, usize),
}

/// Writes `out/preview.gif` showing the first `n` of `samples`, one step per GIF frame (see
/// the module's documentation). The RGB frames are read from `out/images` (so this runs
/// before a WebDataset render removes that folder); each scene shown is loaded once for its
/// map. Nothing is written when there is no sample to show. The same inputs give the same
/// bytes.
///
/// # Errors
///
/// A frame or scene that cannot be read, or a write error, naming the file.
pub fn write(from: &Sources<'_>, out: &Path, samples: &[EpisodeSample], n: usize) -> Result<()> {
    let shown: Vec<&EpisodeSample> = samples
        .iter()
        .take(n)
        .filter(|s| !s.steps.is_empty())
        .collect();
    if shown.is_empty() {
        return Ok(());
    }
    let episodes: Vec<Option<&Episode>> = shown.iter().map(|s| source_episode(from, s)).collect();
    let mut scenes: BTreeMap<&str, SceneMap> = BTreeMap::new();
    for s in &shown {
        if !scenes.contains_key(s.scene.as_str()) {
            // The goal objects of every shown episode of the scene, so the scene is loaded once.
            let goals: Vec<&str> = shown
                .iter()
                .zip(&episodes)
                .filter(|(x, _)| x.scene == s.scene)
                .filter_map(|(_, e)| object_goal(*e))
                .collect();
            scenes.insert(s.scene.as_str(), SceneMap::load(from, &s.scene, &goals)?);
        }
    }
    let layout = Layout::new(
        from.frame_size.0,
        from.frame_size.1,
        scenes.values().map(SceneMap::aspect).fold(0.0, f32::max),
    );
    let panels: BTreeMap<&str, Canvas> = scenes
        .iter()
        .map(|(name, map)| (*name, map.panel(layout.map_width, layout.panel_height)))
        .collect();
    let path = out.join(PREVIEW_FILE);
    let gif_error = |e: std::io::Error| Error::io(&path, e);
    // The GIF is made in memory (it is small) and written in one go: a frame that cannot be
    // read is reported as that frame's error, not as a failed write of the preview.
    let mut gif = GifWriter::new(Vec::new(), layout.width, layout.height).map_err(gif_error)?;
    for (sample, episode) in shown.iter().zip(&episodes) {
        let map = &scenes[sample.scene.as_str()];
        let base = episode_base(&panels[sample.scene.as_str()], map, *episode);
        let instruction = wrap(
            &printable(&sample.instruction),
            layout.chars_per_line(),
            INSTRUCTION_LINES,
        );
        for k in 0..sample.steps.len() {
            let image = compose(&layout, out, sample, k, &base, *episode, &instruction)?;
            let delay = if k + 1 == sample.steps.len() {
                END_DELAY
            } else {
                STEP_DELAY
            };
            gif.frame(&image.rgb, delay).map_err(gif_error)?;
        }
    }
    let bytes = gif.finish().map_err(gif_error)?;
    sage_io::files::write_atomic(&path, |w| w.write_all(&bytes))
}

/// The dataset episode `sample` was made from: its route's first episode, whose start,
/// reference path and goal every episode of the route shares.
fn source_episode<'a>(from: &'a Sources<'_>, sample: &EpisodeSample) -> Option<&'a Episode> {
    from.routes
        .get(&sample.scene)?
        .iter()
        .find(|r| r.name == sample.route)?
        .episodes
        .first()
}

/// The item id of an object goal (whose footprint is the goal region).
fn object_goal(episode: Option<&Episode>) -> Option<&str> {
    episode?
        .goal
        .as_ref()
        .filter(|g| g.kind == "object" && !g.reference.is_empty())
        .map(|g| g.reference.as_str())
}

/// A scene's semantic map without its legend (the preview has its own key), at the size it was
/// drawn, with the footprints of the goal objects shown.
struct SceneMap {
    /// `width × height` RGB.
    rgb: Vec<u8>,
    width: usize,
    height: usize,
    /// World (x, y) of the map's bottom-left corner.
    origin: Vec2,
    /// Metres per pixel.
    scale: f32,
    /// Goal footprints by item id.
    footprints: BTreeMap<String, Vec<Vec2>>,
}

impl SceneMap {
    /// Loads scene `name` and draws its map over its navigation grid.
    fn load(from: &Sources<'_>, name: &str, goals: &[&str]) -> Result<SceneMap> {
        let dir = from
            .scene_dirs
            .get(name)
            .ok_or_else(|| Error::invalid(format!("preview: scene '{name}' is not known")))?;
        let ctx = SceneContext::load(dir, None).within(format!("scene {name}"))?;
        let grid = &ctx.pathfinder.grid;
        let (canvas, map_width) = ctx.semantic.draw(grid, &[]);
        // The map part of the canvas: `draw` scales every cell by one whole zoom factor, puts
        // the map at the top-left and the legend to its right (which may be taller).
        let zoom = (map_width / grid.width.max(1)).max(1);
        let height = (grid.height * zoom).min(canvas.height);
        let width = map_width.min(canvas.width);
        let rgb = resize(&canvas.rgb, canvas.width, width, height, width, height);
        let footprints = goals
            .iter()
            .filter_map(|g| {
                // A goal object missing from the scene fails the walk, not the preview.
                let poly = ctx.footprint(g).ok()?;
                Some((g.to_string(), poly.points))
            })
            .collect();
        Ok(SceneMap {
            rgb,
            width,
            height,
            origin: grid.origin,
            scale: grid.cell / zoom as f32,
            footprints,
        })
    }

    /// Width over height.
    fn aspect(&self) -> f32 {
        self.width as f32 / self.height.max(1) as f32
    }

    /// The map scaled (nearest neighbour, aspect kept) to fit `width × height`, as a canvas
    /// that maps world points to its pixels.
    fn panel(&self, width: usize, height: usize) -> Canvas {
        let t = (width as f32 / self.width.max(1) as f32)
            .min(height as f32 / self.height.max(1) as f32);
        let pw = ((self.width as f32 * t).floor() as usize).clamp(1, width.max(1));
        let ph = ((self.height as f32 * t).floor() as usize).clamp(1, height.max(1));
        // The vertical ratio sets the scale, so the map's top edge stays where it was; the
        // horizontal one differs by under a pixel across the map.
        let scale = self.scale * self.height as f32 / ph as f32;
        let mut canvas = Canvas::new(pw, ph, BACKGROUND, self.origin, scale, ph);
        canvas.rgb = resize(&self.rgb, self.width, self.width, self.height, pw, ph);
        canvas
    }
}

/// Where everything goes in a preview frame: the frame panel at the left, the map box beside
/// it, the text band below.
struct Layout {
    /// The whole image.
    width: usize,
    height: usize,
    /// The RGB frame as shown.
    frame_width: usize,
    /// The height of both panels.
    panel_height: usize,
    /// The box the map is centred in.
    map_width: usize,
    /// The font's scale (5×7 glyphs in cells of 6×`scale` pixels).
    text_scale: usize,
}

impl Layout {
    /// The layout of frames of `frame_w × frame_h` beside maps of at most `aspect` width over
    /// height.
    fn new(frame_w: usize, frame_h: usize, aspect: f32) -> Layout {
        let (frame_w, frame_h) = (frame_w.max(1), frame_h.max(1));
        // A whole factor, so the frame's pixels stay square blocks of one size.
        let factor = ((FRAME_HEIGHT as f32 / frame_h as f32).round() as usize).max(1);
        let (mut fw, mut h) = (frame_w * factor, frame_h * factor);
        // A very wide or very tall floor plan gets a box of sensible proportions; it is fitted
        // into it.
        let aspect = if aspect.is_finite() {
            aspect.clamp(0.5, 2.0)
        } else {
            1.0
        };
        let mut mw = (aspect * h as f32).ceil() as usize;
        let shrink = ((MAX_WIDTH - 3 * PAD) as f32 / (fw + mw) as f32)
            .min(MAX_PANEL_HEIGHT as f32 / h as f32);
        if shrink < 1.0 {
            let scaled = |v: usize| ((v as f32 * shrink).floor() as usize).max(1);
            (fw, h, mw) = (scaled(fw), scaled(h), scaled(mw));
        }
        let width = 3 * PAD + fw + mw;
        // The larger font where a line still holds a sentence's worth of words.
        let text_scale = if width >= 640 { 2 } else { 1 };
        let height = 2 * PAD + h + BAND_LINES * line_height(text_scale) + PAD;
        Layout {
            width,
            height,
            frame_width: fw,
            panel_height: h,
            map_width: mw,
            text_scale,
        }
    }

    /// Characters of text that fit one line of the band.
    fn chars_per_line(&self) -> usize {
        ((self.width - 2 * PAD) / (6 * self.text_scale)).max(1)
    }

    /// The top of the text band's line `k`.
    fn line_y(&self, k: usize) -> i64 {
        (2 * PAD + self.panel_height + k * line_height(self.text_scale)) as i64
    }
}

/// Pixel height of a line of text: the glyph's 7 rows and 3 of spacing.
fn line_height(scale: usize) -> usize {
    10 * scale
}

/// The map panel of an episode before its walk: the goal region's outline and the reference
/// path over the scene's map (what every step of the episode draws on).
fn episode_base(panel: &Canvas, map: &SceneMap, episode: Option<&Episode>) -> Canvas {
    let mut canvas = panel.clone();
    let Some(e) = episode else {
        return canvas;
    };
    if let Some(poly) = object_goal(Some(e)).and_then(|g| map.footprints.get(g))
        && poly.len() >= 2
    {
        let closed: Vec<Vec2> = poly.iter().chain(poly.first()).copied().collect();
        marks::polyline(&mut canvas, &closed, palette::GOAL, 3);
    }
    let reference: Vec<Vec2> = e.reference_path.iter().map(|p| xy(p[0], p[1])).collect();
    marks::polyline(
        &mut canvas,
        &reference,
        palette::REFERENCE_PATH,
        marks::REFERENCE_WIDTH,
    );
    canvas
}

/// Preview frame `k` of `sample`: the RGB frame, the map with the walk so far, the text.
fn compose(
    layout: &Layout,
    out: &Path,
    sample: &EpisodeSample,
    k: usize,
    base: &Canvas,
    episode: Option<&Episode>,
    instruction: &[String],
) -> Result<Canvas> {
    let mut image = Canvas::new(
        layout.width,
        layout.height,
        BACKGROUND,
        Vec2::ZERO,
        1.0,
        layout.height,
    );
    let file = sample.files.get(k).and_then(|f| f.first()).ok_or_else(|| {
        Error::invalid(format!(
            "preview: episode {} has no frame for step {k}",
            sample.episode_id
        ))
    })?;
    let (rgb, w, h) = read_rgb(&out.join(IMAGES_DIR).join(file))?;
    let frame = resize(&rgb, w, w, h, layout.frame_width, layout.panel_height);
    image.blit(&frame, layout.frame_width, layout.panel_height, PAD, PAD);
    let map = walk_map(base, sample, k, episode);
    let x = 2 * PAD + layout.frame_width + (layout.map_width.saturating_sub(map.width)) / 2;
    let y = PAD + (layout.panel_height.saturating_sub(map.height)) / 2;
    image.blit(&map.rgb, map.width, map.height, x, y);

    let ts = layout.text_scale as i64;
    let left = PAD as i64;
    let header = format!(
        "{}  step {}/{}",
        printable(&sample.episode_id),
        k + 1,
        sample.steps.len()
    );
    let cpl = layout.chars_per_line();
    image.text(left, layout.line_y(0), &clip(&header, cpl), INK, ts);
    for (n, line) in instruction.iter().enumerate() {
        image.text(left, layout.line_y(1 + n), line, INK, ts);
    }
    let words = sample.words.get(k).map_or("", String::as_str);
    let action = format!("next action: {}", printable(words));
    image.text(
        left,
        layout.line_y(1 + INSTRUCTION_LINES),
        &clip(&action, cpl),
        palette::AGENT_PATH,
        ts,
    );
    key(&mut image, layout, layout.line_y(2 + INSTRUCTION_LINES));
    Ok(image)
}

/// The map of step `k`: the path walked up to the frame's pose, the start and goal markers,
/// the contacts so far and the current pose with a tick along its heading.
fn walk_map(base: &Canvas, sample: &EpisodeSample, k: usize, episode: Option<&Episode>) -> Canvas {
    let mut canvas = base.clone();
    let steps = &sample.steps[..=k.min(sample.steps.len() - 1)];
    let walked: Vec<Vec2> = steps.iter().map(|s| xy(s.pose[0], s.pose[1])).collect();
    marks::polyline(
        &mut canvas,
        &walked,
        palette::AGENT_PATH,
        marks::AGENT_WIDTH,
    );
    if let Some(start) = walked.first() {
        marks::marker(&mut canvas, *start, marks::MARKER_RADIUS, palette::START);
    }
    let goal = episode.and_then(|e| {
        e.goal
            .as_ref()
            .map(|g| g.position)
            .or_else(|| e.reference_path.last().copied())
    });
    if let Some(g) = goal {
        marks::marker(
            &mut canvas,
            xy(g[0], g[1]),
            marks::MARKER_RADIUS,
            palette::GOAL,
        );
    }
    // A contact happens during an action: it is shown where the action left the agent, once
    // that action has been taken.
    let hits: Vec<Vec2> = steps[..steps.len() - 1]
        .iter()
        .filter(|s| s.contact)
        .map(|s| xy(s.achieved[0], s.achieved[1]))
        .collect();
    for p in &hits {
        canvas.disc(*p, marks::COLLISION_RADIUS + 1, marks::HALO);
    }
    for p in &hits {
        canvas.disc(*p, marks::COLLISION_RADIUS, palette::COLLISION);
    }
    let [x, y, yaw] = steps[steps.len() - 1].pose;
    marks::pose_marker(&mut canvas, xy(x, y), yaw, palette::AGENT_PATH);
    canvas
}

/// The colour key of the map in the band's last line: the report's legend, as far as it fits.
fn key(image: &mut Canvas, layout: &Layout, y: i64) {
    let ts = layout.text_scale as i64;
    let mut x = PAD as i64;
    for (colour, label) in marks::LEGEND {
        let end = x + 9 * ts + (label.len() as i64 + 2) * 6 * ts;
        if end > (layout.width - PAD) as i64 {
            break;
        }
        for dy in 0..7 * ts {
            for dx in 0..7 * ts {
                image.put(x + dx, y + dy, colour);
            }
        }
        image.text(x + 9 * ts, y, label, INK, ts);
        x = end;
    }
}

/// World point (x, y).
fn xy(x: f32, y: f32) -> Vec2 {
    Vec2::new(x, y)
}

/// The top-left `sw × sh` pixels of `src` (RGB rows of `stride` pixels) resampled to
/// `dw × dh` by nearest neighbour, sampling at pixel centres in whole numbers (an upscale by a
/// whole factor repeats every pixel the same number of times).
fn resize(src: &[u8], stride: usize, sw: usize, sh: usize, dw: usize, dh: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(dw * dh * 3);
    let cols: Vec<usize> = (0..dw)
        .map(|x| ((2 * x + 1) * sw / (2 * dw)).min(sw.saturating_sub(1)))
        .collect();
    for y in 0..dh {
        let sy = ((2 * y + 1) * sh / (2 * dh)).min(sh.saturating_sub(1));
        for &sx in &cols {
            let k = (sy * stride + sx) * 3;
            out.extend_from_slice(src.get(k..k + 3).unwrap_or(&BACKGROUND));
        }
    }
    out
}

/// An RGB frame file (JPEG or PNG, told by its first bytes) as `(rgb, width, height)`.
fn read_rgb(path: &Path) -> Result<(Vec<u8>, usize, usize)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode_rgb(&bytes, path)
}

/// The bytes of an RGB frame file `path` (JPEG or PNG, told by its first bytes) as
/// `(rgb, width, height)`.
pub(crate) fn decode_rgb(bytes: &[u8], path: &Path) -> Result<(Vec<u8>, usize, usize)> {
    let bad = |why: String| Error::invalid(format!("cannot decode the frame: {why}")).in_file(path);
    let (pixels, w, h) = if bytes.starts_with(&[0xFF, 0xD8]) {
        let mut dec = zune_jpeg::JpegDecoder::new(bytes);
        dec.decode_headers().map_err(|e| bad(format!("{e:?}")))?;
        let (w, h) = dec
            .dimensions()
            .ok_or_else(|| bad("no image size".into()))?;
        (dec.decode().map_err(|e| bad(format!("{e:?}")))?, w, h)
    } else if bytes.starts_with(b"\x89PNG") {
        let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
        dec.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = dec.read_info().map_err(|e| bad(e.to_string()))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| bad("the image is too large".into()))?;
        let mut buf = vec![0; size];
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| bad(e.to_string()))?;
        buf.truncate(info.buffer_size());
        (buf, info.width as usize, info.height as usize)
    } else {
        return Err(bad("neither a JPEG nor a PNG".into()));
    };
    let n = w * h;
    if n == 0 || pixels.len() < n || pixels.len() % n != 0 {
        return Err(bad(format!("{} bytes for {w}×{h} pixels", pixels.len())));
    }
    // Grey, grey + alpha, RGB or RGBA: the colour channels as RGB.
    let rgb = match pixels.len() / n {
        1 => pixels.iter().flat_map(|&g| [g, g, g]).collect(),
        2 => pixels.chunks_exact(2).flat_map(|p| [p[0]; 3]).collect(),
        3 => pixels,
        4 => pixels
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect(),
        c => return Err(bad(format!("{c} channels"))),
    };
    Ok((rgb, w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resize_by_a_whole_factor_repeats_every_pixel() {
        let src = [1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4];
        let out = resize(&src, 2, 2, 2, 4, 4);
        let firsts: Vec<u8> = out.chunks_exact(3).map(|p| p[0]).collect();
        assert_eq!(firsts, [1, 1, 2, 2, 1, 1, 2, 2, 3, 3, 4, 4, 3, 3, 4, 4]);
    }

    #[test]
    fn the_layout_keeps_within_the_width_cap() {
        for (w, h, aspect) in [
            (64, 48, 1.0),
            (224, 224, 3.0),
            (1024, 1024, 0.2),
            (1, 1, 1.0),
        ] {
            let l = Layout::new(w, h, aspect);
            assert!(l.width <= MAX_WIDTH, "{w}×{h}: {}", l.width);
            assert!(l.panel_height <= MAX_PANEL_HEIGHT);
            assert!(l.frame_width >= 1 && l.map_width >= 1);
        }
        // Small frames are scaled up by a whole factor towards the target height.
        assert_eq!(Layout::new(64, 48, 1.0).panel_height % 48, 0);
    }
}
