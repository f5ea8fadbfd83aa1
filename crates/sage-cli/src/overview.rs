//! The demo's overview picture: what the agent sees at the start of an episode, beside the
//! scene's semantic map with the episode's reference path and the agent's path.

use glam::{Vec2, Vec3};
use sage_bench::eval::{EvalRecord, RECORDS_FILE};
use sage_core::{Error, Result};
use sage_nav::{GridParams, NavGrid, SemanticMap};
use sage_scene::Scene;
use sage_splat::{Camera, Intrinsics, RenderOptions, Renderer};
use std::path::Path;

/// The longest successful VLN episode of a run (ties by id), else its first VLN episode.
fn pick(records: &[EvalRecord]) -> Option<&EvalRecord> {
    let vln = || {
        records.iter().filter(|r| {
            r.record
                .as_ref()
                .is_some_and(|x| !x.reference_path.is_empty())
        })
    };
    let success = |r: &EvalRecord| r.metrics.as_ref().and_then(|m| m.sr) == Some(1.0);
    let length = |r: &EvalRecord| r.record.as_ref().map_or(0, |x| x.reference_path.len());
    vln()
        .filter(|r| success(r))
        .max_by(|a, b| {
            length(a)
                .cmp(&length(b))
                .then_with(|| b.episode_id.cmp(&a.episode_id))
        })
        .or_else(|| vln().next())
}

/// Copies `src` (`w × h` RGB) into `dst` (`dst_w` wide) at column `x0`.
fn blit(dst: &mut [u8], dst_w: usize, src: &[u8], w: usize, h: usize, x0: usize) {
    for y in 0..h {
        let d = (y * dst_w + x0) * 3;
        dst[d..d + w * 3].copy_from_slice(&src[y * w * 3..(y + 1) * w * 3]);
    }
}

/// Writes `out`: the first-person view at the start of an episode of `run` (its records)
/// beside the semantic map of its scene (under `scenes`) with the reference path (blue), the
/// agent's path (orange) and its collisions (red).
///
/// # Errors
///
/// The run holds no VLN episode, or its scene, records or image cannot be read or written.
pub fn write(scenes: &Path, run: &Path, out: &Path) -> Result<()> {
    let records_path = run.join(RECORDS_FILE);
    let text = std::fs::read_to_string(&records_path).map_err(|e| Error::io(&records_path, e))?;
    let records: Vec<EvalRecord> = text
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let rec = pick(&records)
        .ok_or_else(|| Error::invalid("no VLN episode with a path").in_file(&records_path))?;
    let episode = rec.record.as_ref().expect("picked records have one");
    let (scene, _) = Scene::load(&scenes.join(&rec.scene))?;
    let (grid, _) = NavGrid::from_scene(&scene, &GridParams::default())?;
    let mut map = SemanticMap::build(&scene)
        .draw(
            &grid,
            &[
                (REFERENCE, "reference path".into()),
                (AGENT, format!("{} path", rec.agent)),
                (COLLISION, "collision".into()),
            ],
        )
        .0;
    let reference: Vec<Vec2> = episode
        .reference_path
        .iter()
        .map(|p| Vec2::new(p[0], p[1]))
        .collect();
    let start = Vec2::new(episode.start[0], episode.start[1]);
    let agent: Vec<Vec2> = std::iter::once(start)
        .chain(
            episode
                .steps
                .iter()
                .map(|s| Vec2::new(s.position[0], s.position[1])),
        )
        .collect();
    draw_path(&mut map, &reference, REFERENCE, 3);
    draw_path(&mut map, &agent, AGENT, 2);
    for s in episode.steps.iter().filter(|s| s.contact) {
        map.disc(Vec2::new(s.position[0], s.position[1]), 4, COLLISION);
    }
    let height = map.height;
    let width = height * 4 / 3;
    let camera = Camera::from_yaw_pitch(
        Intrinsics::from_hfov(width as u32, height as u32, 90.0)?,
        Vec3::new(start.x, start.y, 1.2),
        episode.start_yaw,
        -0.1,
    );
    let view = Renderer::new(&scene.gaussians).render(
        &scene.gaussians,
        &scene.instances.category_ids,
        &camera,
        &RenderOptions::default(),
    )?;
    let total = width + map.width;
    let mut rgb = vec![255u8; total * height * 3];
    blit(&mut rgb, total, &view.rgb, width, height, 0);
    blit(&mut rgb, total, &map.rgb, map.width, height, width);
    sage_scene::fsutil::write_rgb_png(out, total, height, &rgb)?;
    eprintln!(
        "overview: {} (episode {} in {})",
        out.display(),
        rec.episode_id,
        rec.scene
    );
    Ok(())
}

const REFERENCE: [u8; 3] = [40, 90, 220];
const AGENT: [u8; 3] = [245, 140, 20];
const COLLISION: [u8; 3] = [220, 30, 30];

/// Draws a polyline of world points.
fn draw_path(canvas: &mut sage_nav::draw::Canvas, points: &[Vec2], c: [u8; 3], thickness: i64) {
    for w in points.windows(2) {
        canvas.line(w[0], w[1], c, thickness);
    }
}
