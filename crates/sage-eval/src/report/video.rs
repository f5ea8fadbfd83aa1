//! Episode videos: an animated GIF of one evaluated episode, to watch what an agent did.
//!
//! A video has one frame for the start and one per step. Each frame shows, on the left, the
//! agent's first-person RGB at that pose (rendered again from the scene through the agent's
//! camera, [`EnvConfig::camera`], level: the record holds no pitch), and on the right the
//! scene's semantic map ([`maps::base_map_rows`]) with the record's reference path, the
//! agent's path so far, the contacts so far as crosses ([`maps::overlay`] of the steps taken)
//! and a marker with a heading tick at the current pose. Above both a white band holds the
//! episode, its instruction wrapped over as many lines as it needs, and the step's status
//! on two lines (one would not fit beside a 320-pixel view): `step k/n · action` and
//! `contact c(t)=… · d_goal=…`. Frames follow each other every
//! [`STEP_DELAY`]; the last one stays [`END_DELAY`]. The same record and scene give the same
//! bytes (the renderer on the CPU is independent of the thread count, the GIF encoding
//! deterministic).

use super::maps;
use crate::records::EvalRecord;
use glam::{Vec2, Vec3};
use sage_core::pose::wrap_angle;
use sage_core::{Error, Pose, Result};
use sage_env::{EnvConfig, SceneContext};
use sage_io::canvas::{Canvas, clip, printable, wrap};
use sage_io::gif::GifWriter;
use sage_io::marks::pose_marker;
use sage_io::palette::AGENT_PATH;
use sage_metrics::{EpisodeRecord, StepRecord};
use sage_nav::{NavGrid, SemanticMap};
use sage_splat::{Channels, RenderOptions};

/// The folder of the videos, under the report folder.
pub const VIDEOS_DIR: &str = "videos";
/// How long each frame is shown, hundredths of a second.
pub const STEP_DELAY: u16 = 25;
/// How long the last frame is shown, hundredths of a second: time to see where the walk ended
/// before the video loops.
pub const END_DELAY: u16 = 200;
/// Frames rendered per call of the renderer (one call for many cameras is cheaper than one
/// per frame; the frames of a batch are held in memory together).
const RENDER_BATCH: usize = 16;
/// Margin around and between the parts of a frame, pixels.
const PAD: usize = 8;
/// The map panel's height over the first-person view's: a little taller, so the map reads.
const MAP_OVER_FPV: (usize, usize) = (4, 3);
/// The widest the map panel gets, as a multiple of its height (a long floor plan is fitted
/// into that width instead, and drawn shorter).
const MAP_MAX_ASPECT: usize = 2;
/// A turn smaller than this (radians) is not called a turn: physics may nudge the heading.
const TURN_EPS: f32 = 1e-3;
/// Text.
const INK: [u8; 3] = [20, 20, 20];
/// The episode line's colour, quieter than the instruction.
const QUIET: [u8; 3] = [90, 90, 90];
/// Separator of the status line's parts (a middle dot, which the bitmap font has).
const SEP: &str = " \u{B7} ";

/// The size of the first-person view in a video's frames, pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VideoSize {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl Default for VideoSize {
    /// 320 × 240.
    fn default() -> Self {
        VideoSize {
            width: 320,
            height: 240,
        }
    }
}

/// Where everything goes in the frames of one episode's video (all its frames share it).
#[derive(Debug, Clone, PartialEq)]
pub struct VideoLayout {
    /// The frame's width, pixels.
    pub width: usize,
    /// The frame's height, pixels.
    pub height: usize,
    /// The first-person view: top-left pixel (x, y), then its size (the [`VideoSize`]).
    pub fpv: (usize, usize, usize, usize),
    /// The map panel: top-left pixel (x, y), then its size.
    pub map: (usize, usize, usize, usize),
    /// The bitmap font's scale (glyphs in cells of 6 × 10 pixels times it).
    pub text_scale: usize,
    /// The instruction as wrapped onto the band's lines.
    pub instruction: Vec<String>,
}

impl VideoLayout {
    /// The layout of the frames of a video over `grid`'s map with a first-person view of
    /// `size`, showing `instruction`.
    pub fn new(grid: &NavGrid, size: VideoSize, instruction: &str) -> VideoLayout {
        let (fw, fh) = (size.width.max(1) as usize, size.height.max(1) as usize);
        let (gw, gh) = (grid.width.max(1) as f64, grid.height.max(1) as f64);
        let mut map_h = (fh * MAP_OVER_FPV.0).div_ceil(MAP_OVER_FPV.1);
        let mut map_w = (gw / gh * map_h as f64).round().max(1.0) as usize;
        if map_w > MAP_MAX_ASPECT * map_h {
            map_w = MAP_MAX_ASPECT * map_h;
            map_h = (gh / gw * map_w as f64).round().max(1.0) as usize;
        }
        let width = 3 * PAD + fw + map_w;
        // The larger font where a line still holds a sentence's worth of words.
        let text_scale = if width >= 640 { 2 } else { 1 };
        let chars = ((width - 2 * PAD) / (6 * text_scale)).max(1);
        let text = printable(instruction);
        let mut lines = wrap(&text, chars, usize::MAX);
        if lines.is_empty() {
            lines.push("(no instruction)".into());
        }
        // The episode line, the instruction, the two status lines.
        let band = (lines.len() + 3) * 10 * text_scale;
        let top = 2 * PAD + band;
        VideoLayout {
            width,
            height: top + fh.max(map_h) + PAD,
            fpv: (PAD, top, fw, fh),
            map: (2 * PAD + fw, top, map_w, map_h),
            text_scale,
            instruction: lines,
        }
    }

    /// Characters that fit one line of the band.
    fn chars_per_line(&self) -> usize {
        ((self.width - 2 * PAD) / (6 * self.text_scale)).max(1)
    }

    /// The top of the band's line `k`.
    fn line_y(&self, k: usize) -> i64 {
        (PAD + k * 10 * self.text_scale) as i64
    }
}

/// What a step of an episode record did, as the record implies it: records keep poses, not
/// actions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepMove {
    /// The agent called STOP (the last step of an episode that did).
    Stop,
    /// A translation was commanded, metres.
    Forward(f32),
    /// The heading alone changed, radians (counter-clockwise positive).
    Turn(f32),
    /// Nothing the record shows (a camera tilt, or a step that did nothing).
    Nothing,
}

/// What step `k` (0-based) of `rec` did: [`StepMove::Stop`] for the last step of an episode
/// that called STOP, [`StepMove::Forward`] for a commanded translation, [`StepMove::Turn`] for a
/// change of heading alone, else [`StepMove::Nothing`].
pub fn step_move(rec: &EpisodeRecord, k: usize) -> StepMove {
    let Some(step) = rec.steps.get(k) else {
        return StepMove::Nothing;
    };
    if rec.stop_called && k + 1 == rec.steps.len() {
        return StepMove::Stop;
    }
    if step.commanded > 0.0 {
        return StepMove::Forward(step.commanded);
    }
    let before = if k == 0 {
        rec.start_yaw
    } else {
        rec.steps[k - 1].yaw
    };
    let turn = wrap_angle(step.yaw - before);
    if turn.abs() < TURN_EPS {
        StepMove::Nothing
    } else {
        StepMove::Turn(turn)
    }
}

/// What step `k` (0-based) of `rec` did, in words ([`step_move`]): `stop`, `forward 0.25m`,
/// `turn left 15deg` or `turn right 15deg`, `-` for anything else.
pub fn step_action(rec: &EpisodeRecord, k: usize) -> String {
    match step_move(rec, k) {
        StepMove::Stop => "stop".into(),
        StepMove::Forward(m) => format!("forward {m:.2}m"),
        StepMove::Turn(turn) => {
            let side = if turn > 0.0 { "left" } else { "right" };
            format!("turn {side} {:.0}deg", turn.abs().to_degrees())
        }
        StepMove::Nothing => "-".into(),
    }
}

/// The poses of the frames: the start, then where each step left the agent.
fn poses(rec: &EpisodeRecord) -> Vec<Pose> {
    std::iter::once(Pose::new(Vec3::from(rec.start), rec.start_yaw))
        .chain(
            rec.steps
                .iter()
                .map(|s| Pose::new(Vec3::from(s.position), s.yaw)),
        )
        .collect()
}

/// The distance to the goal at each frame's position, as the status line writes it: the
/// step's recorded geodesic distance to the goal point when it has one, else the geodesic
/// distance over the scene's path finder, else (off the navigable grid) the straight line,
/// said so; `-` without a goal.
fn goal_distances(ctx: &SceneContext, rec: &EpisodeRecord) -> Vec<String> {
    let positions: Vec<(Vec2, Option<f32>)> = std::iter::once((xy(&rec.start), None))
        .chain(
            rec.steps
                .iter()
                .map(|s: &StepRecord| (xy(&s.position), s.geodesic_to_goal_point)),
        )
        .collect();
    let Some(goal) = &rec.goal else {
        return vec!["-".into(); positions.len()];
    };
    let g = Vec2::new(goal.point[0] as f32, goal.point[1] as f32);
    // One search from the goal answers every position (the length graph is symmetric).
    let field = ctx.pathfinder.geodesic_field(g).ok();
    positions
        .iter()
        .map(|(p, recorded)| {
            match recorded.or_else(|| field.as_ref().and_then(|f| f.distance_to(*p))) {
                Some(d) => format!("{d:.2}m"),
                None => format!("{:.2}m (straight)", p.distance(g)),
            }
        })
        .collect()
}

fn xy(p: &[f32; 3]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

/// The record of an evaluated episode, or an error saying it has none.
fn record_of(rec: &EvalRecord) -> Result<&EpisodeRecord> {
    rec.record.as_ref().ok_or_else(|| {
        Error::invalid(format!(
            "episode {} has no trajectory record (it faulted): no video",
            rec.episode_id
        ))
    })
}

/// What a video is made from (the arguments of [`episode_frames`]).
struct Inputs<'a> {
    ctx: &'a SceneContext,
    config: &'a EnvConfig,
    map: &'a SemanticMap,
    grid: &'a NavGrid,
    rec: &'a EvalRecord,
    instruction: &'a str,
    size: VideoSize,
}

/// Calls `each(k, n, frame)` for every frame `k` of the `n` of the video (see
/// [`episode_frames`]) in order, rendering [`RENDER_BATCH`] first-person views at a time.
fn for_each_frame(
    inputs: &Inputs<'_>,
    each: &mut dyn FnMut(usize, usize, Canvas) -> Result<()>,
) -> Result<()> {
    let Inputs {
        ctx,
        config,
        map,
        grid,
        rec,
        instruction,
        size,
    } = *inputs;
    let record = record_of(rec)?;
    let layout = VideoLayout::new(grid, size, instruction);
    let profile = config.profile()?;
    let poses = poses(record);
    let cameras = poses
        .iter()
        .map(|p| config.camera(&profile, *p, 0.0, size.width, size.height))
        .collect::<Result<Vec<_>>>()?;
    let distances = goal_distances(ctx, record);
    let (_, _, map_w, map_h) = layout.map;
    let base = maps::base_map_rows(map, grid, map_h, map_w, map_h);
    let header = clip(
        &printable(&format!(
            "episode {}{SEP}scene {}",
            rec.episode_id, rec.scene
        )),
        layout.chars_per_line(),
    );
    let mut renderer = ctx.renderer(config.device)?;
    let n = record.steps.len();
    for (b, batch) in cameras.chunks(RENDER_BATCH).enumerate() {
        let views = renderer.render_batch(
            &ctx.scene.gaussians,
            &ctx.scene.instances.category_ids,
            batch,
            &RenderOptions {
                channels: Channels::RGB,
                ..RenderOptions::default()
            },
        )?;
        for (i, view) in views.into_iter().enumerate() {
            let k = b * RENDER_BATCH + i;
            let mut frame = Canvas::new(
                layout.width,
                layout.height,
                [255; 3],
                Vec2::ZERO,
                1.0,
                layout.height,
            );
            let (fx, fy, _, _) = layout.fpv;
            frame.blit(&view.rgb, view.width, view.height, fx, fy);
            let panel = map_panel(&base, record, k, &poses[k]);
            let (mx, my, _, _) = layout.map;
            frame.blit(&panel.rgb, panel.width, panel.height, mx, my);
            let ts = layout.text_scale as i64;
            let left = PAD as i64;
            frame.text(left, layout.line_y(0), &header, QUIET, ts);
            for (j, line) in layout.instruction.iter().enumerate() {
                frame.text(left, layout.line_y(1 + j), line, INK, ts);
            }
            let (action, intensity) = match k {
                0 => ("start".to_string(), 0.0),
                _ => (step_action(record, k - 1), record.steps[k - 1].intensity),
            };
            let status = [
                format!("step {k}/{n}{SEP}{action}"),
                format!("contact c(t)={intensity:.2}{SEP}d_goal={}", distances[k]),
            ];
            for (j, line) in status.iter().enumerate() {
                let y = layout.line_y(1 + layout.instruction.len() + j);
                frame.text(left, y, &clip(line, layout.chars_per_line()), INK, ts);
            }
            each(k, n + 1, frame)?;
        }
    }
    Ok(())
}

/// The map panel of frame `k`: the record's paths with the steps taken so far (the agent's
/// path and contacts up to `k`) and the agent's marker at `pose`.
fn map_panel(base: &Canvas, record: &EpisodeRecord, k: usize, pose: &Pose) -> Canvas {
    let mut panel = base.clone();
    let so_far = EpisodeRecord {
        steps: record.steps[..k].to_vec(),
        ..record.clone()
    };
    maps::overlay(&mut panel, &so_far);
    pose_marker(
        &mut panel,
        Vec2::new(pose.position.x, pose.position.y),
        pose.yaw,
        AGENT_PATH,
    );
    panel
}

/// The frames of the video of `rec` (see the module docs): one for the start and one per
/// step, each [`VideoLayout::new`]'s size, the first-person view of `size` rendered with
/// `ctx`'s renderer on `config.device` through `config`'s agent camera, the map drawn from
/// `map` over `grid` (the scene's, as [`super::scene_map`] gives them). All frames are held in
/// memory: [`episode_gif`] streams them instead.
///
/// # Errors
///
/// `rec` has no trajectory record (a faulted episode), the config names an unknown agent
/// profile or makes no camera of `size`, or the renderer fails.
pub fn episode_frames(
    ctx: &SceneContext,
    config: &EnvConfig,
    map: &SemanticMap,
    grid: &NavGrid,
    rec: &EvalRecord,
    instruction: &str,
    size: VideoSize,
) -> Result<Vec<Canvas>> {
    let inputs = Inputs {
        ctx,
        config,
        map,
        grid,
        rec,
        instruction,
        size,
    };
    let mut frames = Vec::new();
    for_each_frame(&inputs, &mut |_, _, f| {
        frames.push(f);
        Ok(())
    })?;
    Ok(frames)
}

/// The delay of frame `k` of `n`: [`END_DELAY`] for the last one, at least `delay_cs`.
fn delay_of(k: usize, n: usize, delay_cs: u16) -> u16 {
    if k + 1 == n {
        END_DELAY.max(delay_cs)
    } else {
        delay_cs
    }
}

/// An error of GIF encoding, in words.
fn gif_error(e: std::io::Error) -> Error {
    Error::invalid(format!("episode video: {e}"))
}

/// A looping GIF of `frames` (all of one size), each shown `delay_cs` hundredths of a second
/// but the last, held [`END_DELAY`] (or `delay_cs`, when longer). Each frame has its own
/// palette; the same frames give the same bytes.
///
/// # Errors
///
/// No frames, frames of different sizes, or a size a GIF cannot hold (over 65535 pixels).
pub fn encode_gif(frames: &[Canvas], delay_cs: u16) -> Result<Vec<u8>> {
    let first = frames
        .first()
        .ok_or_else(|| Error::invalid("episode video: no frames"))?;
    let mut gif = GifWriter::new(Vec::new(), first.width, first.height).map_err(gif_error)?;
    for (k, f) in frames.iter().enumerate() {
        if (f.width, f.height) != (first.width, first.height) {
            return Err(Error::invalid(format!(
                "episode video: frame {k} is {}×{} pixels, frame 0 {}×{}",
                f.width, f.height, first.width, first.height
            )));
        }
        gif.frame(&f.rgb, delay_of(k, frames.len(), delay_cs))
            .map_err(gif_error)?;
    }
    gif.finish().map_err(gif_error)
}

/// The GIF of the video of `rec`: [`episode_frames`] encoded as [`encode_gif`] does with
/// [`STEP_DELAY`], made frame by frame (only a batch of frames is in memory at a time).
///
/// # Errors
///
/// As [`episode_frames`] and [`encode_gif`].
pub fn episode_gif(
    ctx: &SceneContext,
    config: &EnvConfig,
    map: &SemanticMap,
    grid: &NavGrid,
    rec: &EvalRecord,
    instruction: &str,
    size: VideoSize,
) -> Result<Vec<u8>> {
    let inputs = Inputs {
        ctx,
        config,
        map,
        grid,
        rec,
        instruction,
        size,
    };
    let layout = VideoLayout::new(grid, size, instruction);
    let mut gif = GifWriter::new(Vec::new(), layout.width, layout.height).map_err(gif_error)?;
    for_each_frame(&inputs, &mut |k, n, f| {
        gif.frame(&f.rgb, delay_of(k, n, STEP_DELAY))
            .map_err(gif_error)
    })?;
    gif.finish().map_err(gif_error)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sage_core::Task;
    use sage_metrics::distance::OfficialGoal;

    fn step(position: [f32; 3], yaw: f32, commanded: f32) -> StepRecord {
        StepRecord {
            position,
            yaw,
            time: 0.0,
            commanded,
            achieved: commanded,
            contact: false,
            intensity: 0.0,
            geodesic_to_goal_point: None,
        }
    }

    fn record(steps: Vec<StepRecord>, stop_called: bool) -> EpisodeRecord {
        EpisodeRecord {
            episode_id: "e".into(),
            task: Task::Vln,
            start: [0.0; 3],
            start_yaw: 3.0,
            steps,
            stop_called,
            reference_path: Vec::new(),
            goal: None,
            geodesics: Default::default(),
            official_goal: OfficialGoal::NoMap,
            gnbench: None,
        }
    }

    #[test]
    fn actions_are_read_from_the_record() {
        let quarter = 15f32.to_radians();
        let steps = vec![
            // Across ±π: a left turn of 15°, not a right turn of 345°.
            step([0.0; 3], wrap_angle(3.0 + quarter), 0.0),
            step([0.25, 0.0, 0.0], wrap_angle(3.0 + quarter), 0.25),
            step([0.25, 0.0, 0.0], wrap_angle(3.0), 0.0),
            step([0.25, 0.0, 0.0], wrap_angle(3.0), 0.0),
            step([0.25, 0.0, 0.0], wrap_angle(3.0), 0.0),
        ];
        let rec = record(steps.clone(), true);
        let words: Vec<String> = (0..5).map(|k| step_action(&rec, k)).collect();
        assert_eq!(
            words,
            [
                "turn left 15deg",
                "forward 0.25m",
                "turn right 15deg",
                "-",
                "stop"
            ]
        );
        // Without STOP the last step is what it did.
        assert_eq!(step_action(&record(steps, false), 4), "-");
    }

    #[test]
    fn a_long_floor_plan_is_fitted_into_the_panel() {
        let grid = |w: usize, h: usize| {
            NavGrid::new(Vec2::ZERO, Vec2::new(w as f32, h as f32), 1.0).unwrap()
        };
        let size = VideoSize::default();
        let square = VideoLayout::new(&grid(100, 100), size, "go");
        assert_eq!((square.map.2, square.map.3), (320, 320));
        assert_eq!(square.fpv, (8, square.map.1, 320, 240));
        assert_eq!(square.height, square.map.1 + 320 + 8);
        let long = VideoLayout::new(&grid(1000, 100), size, "go");
        assert_eq!((long.map.2, long.map.3), (640, 64));
        assert_eq!(long.height, long.map.1 + 240 + 8);
        // Every word of a long instruction is on some line, none wider than the band.
        let text = "walk ".repeat(60);
        let l = VideoLayout::new(&grid(100, 100), size, &text);
        assert_eq!(l.instruction.join(" ").split(' ').count(), 60);
        assert!(l.instruction.len() > 3);
        assert!(l.instruction.iter().all(|s| s.len() <= l.chars_per_line()));
    }
}
