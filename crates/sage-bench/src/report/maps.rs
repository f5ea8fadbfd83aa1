//! Per-episode top-down maps: the scene's semantic map with the reference path, the agent's
//! path, start and goal, the goal region and the collision points (the paper's figure of ground
//! truth against agent trajectories).
//!
//! [`overlay`] draws one episode record over any semantic-map canvas, so other commands can put
//! paths on their own maps; [`episode_map`] is the report's whole image, with a legend and a
//! caption naming the episode and its SR, NE and nDTW.

use crate::eval::EvalRecord;
use glam::Vec2;
use sage_io::canvas::Canvas;
use sage_metrics::EpisodeRecord;
use sage_nav::{NavGrid, SemanticMap};

/// The folder of the maps, under the report folder.
pub const MAPS_DIR: &str = "maps";
/// The reference (ground-truth) path.
pub const REFERENCE: [u8; 3] = [20, 90, 220];
/// The agent's path.
pub const AGENT: [u8; 3] = [255, 140, 0];
/// The start marker.
pub const START: [u8; 3] = [0, 160, 0];
/// The goal marker and the goal region's outline.
pub const GOAL: [u8; 3] = [150, 0, 200];
/// Steps that end in contact.
pub const COLLISION: [u8; 3] = [255, 0, 0];
/// Pixel width of the reference path: wider than the agent's, so it shows beside it.
pub const REFERENCE_WIDTH: i64 = 5;
/// Pixel width of the agent's path.
pub const AGENT_WIDTH: i64 = 3;
/// Pixel radius of the start and goal markers.
pub const MARKER_RADIUS: i64 = 6;
/// Pixel radius of a collision point.
pub const COLLISION_RADIUS: i64 = 4;

/// The legend entries of the overlay, in drawing order.
pub fn legend() -> Vec<([u8; 3], String)> {
    [
        (REFERENCE, "reference path"),
        (AGENT, "agent path"),
        (START, "start"),
        (GOAL, "goal / region"),
        (COLLISION, "collision"),
    ]
    .into_iter()
    .map(|(c, l)| (c, l.to_string()))
    .collect()
}

fn xy(p: &[f32; 3]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

/// White under the paths and markers, so they stand out on any category colour.
pub const HALO: [u8; 3] = [255, 255, 255];

/// A path `width` pixels wide over a white halo one pixel wider on each side.
pub fn polyline(canvas: &mut Canvas, points: &[Vec2], c: [u8; 3], width: i64) {
    for w in points.windows(2) {
        canvas.line(w[0], w[1], HALO, width + 2);
    }
    for w in points.windows(2) {
        canvas.line(w[0], w[1], c, width);
    }
}

/// A disc over a white ring.
pub fn marker(canvas: &mut Canvas, p: Vec2, radius: i64, c: [u8; 3]) {
    canvas.disc(p, radius + 1, HALO);
    canvas.disc(p, radius, c);
}

/// Draws `rec` over `canvas`: the goal region's outline, the reference path, the agent's path
/// (start, then every step's position), start and goal markers, and a red point at every step
/// that ended in contact — drawn last, so no collision is hidden.
pub fn overlay(canvas: &mut Canvas, rec: &EpisodeRecord) {
    if let Some(goal) = &rec.goal
        && let Some(poly) = goal.footprint.as_ref().filter(|p| p.len() >= 2)
    {
        let pts: Vec<Vec2> = poly
            .iter()
            .chain(poly.first())
            .map(|p| Vec2::new(p[0] as f32, p[1] as f32))
            .collect();
        polyline(canvas, &pts, GOAL, 3);
    }
    let reference: Vec<Vec2> = rec.reference_path.iter().map(xy).collect();
    polyline(canvas, &reference, REFERENCE, REFERENCE_WIDTH);
    let agent: Vec<Vec2> = std::iter::once(&rec.start)
        .chain(rec.steps.iter().map(|s| &s.position))
        .map(xy)
        .collect();
    polyline(canvas, &agent, AGENT, AGENT_WIDTH);
    marker(canvas, xy(&rec.start), MARKER_RADIUS, START);
    if let Some(goal) = &rec.goal {
        let g = Vec2::new(goal.point[0] as f32, goal.point[1] as f32);
        marker(canvas, g, MARKER_RADIUS, GOAL);
    }
    // All rings before all discs: a ring never covers a neighbouring collision point.
    let hits: Vec<Vec2> = rec
        .steps
        .iter()
        .filter(|s| s.contact)
        .map(|s| xy(&s.position))
        .collect();
    for p in &hits {
        canvas.disc(*p, COLLISION_RADIUS + 1, HALO);
    }
    for p in &hits {
        canvas.disc(*p, COLLISION_RADIUS, COLLISION);
    }
}

/// A metric for a caption: three decimals, `-` where undefined.
fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3}"))
}

/// The caption lines of an episode's map.
pub fn caption(rec: &EvalRecord) -> [String; 2] {
    let m = rec.metrics.clone().unwrap_or_default();
    let contacts = rec
        .record
        .as_ref()
        .map_or(0, |r| r.steps.iter().filter(|s| s.contact).count());
    [
        format!("episode {} (scene {})", rec.episode_id, rec.scene),
        format!(
            "sr {}  ne {}  ndtw {}  contact steps {contacts}",
            fmt(m.sr),
            fmt(m.ne),
            fmt(m.ndtw)
        ),
    ]
}

/// Pixel height of one caption line (bitmap font at scale 2) with its spacing.
const CAPTION_LINE: usize = 20;

/// The map image of one episode: `map` drawn over `grid` with the legend, the episode's
/// [`overlay`] and its [`caption`] in a band under the image. An episode without a record
/// (it failed) gets the plain map and its caption.
pub fn episode_map(map: &SemanticMap, grid: &NavGrid, rec: &EvalRecord) -> Canvas {
    let (mut canvas, _) = map.draw(grid, &legend());
    if let Some(r) = &rec.record {
        overlay(&mut canvas, r);
    }
    // The band is added below the image, so the world-to-pixel mapping is unchanged.
    let band = 2 * CAPTION_LINE + 12;
    let top = canvas.height;
    canvas.rgb.extend([255u8; 3].repeat(canvas.width * band));
    canvas.height += band;
    for (k, line) in caption(rec).iter().enumerate() {
        let y = (top + 6 + k * CAPTION_LINE) as i64;
        canvas.text(8, y, line, [20, 20, 20], 2);
    }
    canvas
}
