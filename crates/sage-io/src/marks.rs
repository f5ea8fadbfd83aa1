//! The marks drawn over top-down maps: paths (the reference dashed, the agent's solid, both
//! over a white halo) and markers of a few shapes, with their widths and sizes — one look
//! shared by the evaluation report's episode maps and the training-data preview, so a preview
//! reads like a report's map. Colours come from [`crate::palette`].

use crate::canvas::Canvas;
use crate::palette::{AGENT_PATH, COLLISION, GOAL, REFERENCE_PATH, START};
use glam::Vec2;

/// The path marks in drawing order as (colour, label): the key of every map that draws them.
pub const LEGEND: [([u8; 3], &str); 5] = [
    (REFERENCE_PATH, "reference path"),
    (AGENT_PATH, "agent path"),
    (START, "start"),
    (GOAL, "goal"),
    (COLLISION, "collision"),
];

/// Pixel width of the reference path: wider than the agent's, so it shows beside it.
pub const REFERENCE_WIDTH: i64 = 5;
/// Pixel width of the agent's path.
pub const AGENT_WIDTH: i64 = 3;
/// Pixel width of the goal region's outline.
pub const REGION_WIDTH: i64 = 3;
/// Pixel radius of the start marker (and of other commands' disc markers).
pub const MARKER_RADIUS: i64 = 6;
/// Pixel radius of the goal's diamond outline: larger than the start, so both show when an
/// episode ends where it began.
pub const GOAL_RADIUS: i64 = 9;
/// Pixel radius of a collision cross.
pub const COLLISION_RADIUS: i64 = 5;
/// Pixel lengths of a dash of the reference path and of the gap after it.
pub const DASH: (f32, f32) = (14.0, 8.0);
/// White under the paths and markers, so they stand out on any background.
pub const HALO: [u8; 3] = [255, 255, 255];

/// The shape of a marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A filled disc.
    Disc,
    /// A filled square.
    Square,
    /// A diamond outline, four pixels wide: a marker under it (the start of an episode that
    /// ends where it began) still shows.
    Diamond,
    /// A diagonal cross.
    Cross,
}

impl Shape {
    /// Whether the pixel at offset (dx, dy) from the centre is inside the shape of `radius`
    /// grown by `pad` pixels (its halo).
    fn covers(self, dx: i64, dy: i64, radius: i64, pad: i64) -> bool {
        let r = radius + pad;
        match self {
            Shape::Disc => dx * dx + dy * dy <= r * r,
            // A square a pixel inside the radius covers about the disc's area.
            Shape::Square => dx.abs() < r && dy.abs() < r,
            Shape::Diamond => (radius - 2 - pad..=r + 1).contains(&(dx.abs() + dy.abs())),
            Shape::Cross => {
                dx.abs() <= r
                    && dy.abs() <= r
                    && ((dx - dy).abs() <= 1 + pad || (dx + dy).abs() <= 1 + pad)
            }
        }
    }
}

/// Stamps `shape` of `radius` grown by `pad` pixels, centred on world point `p`.
pub fn stamp(canvas: &mut Canvas, p: Vec2, shape: Shape, radius: i64, pad: i64, c: [u8; 3]) {
    let q = canvas.to_pixel(p);
    let (x, y, r) = (q.x as i64, q.y as i64, radius + pad);
    for dy in -r..=r {
        for dx in -r..=r {
            if shape.covers(dx, dy, radius, pad) {
                canvas.put(x + dx, y + dy, c);
            }
        }
    }
}

/// Pixels of white around a marker.
pub const MARK_HALO: i64 = 2;

/// A marker of `shape` centred on world point `p`, over a white halo.
pub fn mark(canvas: &mut Canvas, p: Vec2, shape: Shape, radius: i64, c: [u8; 3]) {
    stamp(canvas, p, shape, radius, MARK_HALO, HALO);
    stamp(canvas, p, shape, radius, 0, c);
}

/// A disc [`mark`]: the plain marker of other commands' maps (the training-data preview's
/// start, goal and current pose).
pub fn marker(canvas: &mut Canvas, p: Vec2, radius: i64, c: [u8; 3]) {
    mark(canvas, p, Shape::Disc, radius, c);
}

/// Pixel radius of the marker of an agent's current pose ([`pose_marker`]).
pub const POSE_RADIUS: i64 = 5;
/// Pixel length of the heading tick of [`pose_marker`], from the marker's centre.
pub const TICK_LENGTH: f32 = 14.0;
/// The heading tick's colour: near-black, over a white halo.
pub const TICK: [u8; 3] = [20, 20, 20];

/// The marker of an agent at world point `p` heading `yaw` (radians counter-clockwise from
/// +x): a tick [`TICK_LENGTH`] pixels long along the heading, then a disc of `c` over it.
pub fn pose_marker(canvas: &mut Canvas, p: Vec2, yaw: f32, c: [u8; 3]) {
    // The canvas maps world to pixels at one scale: two points one metre apart give it.
    let pixels_per_metre = canvas.to_pixel(p + Vec2::X).distance(canvas.to_pixel(p));
    let tip = p + Vec2::from_angle(yaw) * (TICK_LENGTH / pixels_per_metre.max(1e-6));
    canvas.line(p, tip, HALO, 5);
    canvas.line(p, tip, TICK, 3);
    marker(canvas, p, POSE_RADIUS, c);
}

/// A path `width` pixels wide over a white halo one pixel wider on each side.
pub fn polyline(canvas: &mut Canvas, points: &[Vec2], c: [u8; 3], width: i64) {
    halo(canvas, points, width);
    for w in points.windows(2) {
        canvas.line(w[0], w[1], c, width);
    }
}

/// [`polyline`] dashed ([`DASH`]) over a whole halo: the dashes run on along the path across
/// its corners, and the gaps show white.
pub fn dashed_polyline(canvas: &mut Canvas, points: &[Vec2], c: [u8; 3], width: i64) {
    halo(canvas, points, width);
    let (on, off) = DASH;
    let mut along = 0.0;
    for w in points.windows(2) {
        let len = canvas.to_pixel(w[0]).distance(canvas.to_pixel(w[1]));
        // The dashes that overlap this segment, as fractions of it.
        let mut start = (along / (on + off)).floor() * (on + off);
        while start < along + len {
            let (t0, t1) = ((start - along).max(0.0), (start + on - along).min(len));
            if t1 > t0 && len > 0.0 {
                canvas.line(
                    w[0].lerp(w[1], t0 / len),
                    w[0].lerp(w[1], t1 / len),
                    c,
                    width,
                );
            }
            start += on + off;
        }
        along += len;
    }
}

/// The white halo of a path `width` pixels wide.
fn halo(canvas: &mut Canvas, points: &[Vec2], width: i64) {
    for w in points.windows(2) {
        canvas.line(w[0], w[1], HALO, width + 2);
    }
}
