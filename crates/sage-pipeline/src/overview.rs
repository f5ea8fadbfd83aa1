//! The demo's overview picture: what the agent sees at the start of an episode, beside the
//! scene's semantic map with the episode's reference path and the agent's path.

use glam::Vec3;
use sage_core::{Error, Result};
use sage_eval::EvalRecord;
use sage_eval::report;
use sage_nav::{NavGrid, SemanticMap, TrajectoryParams};
use sage_scene::Scene;
use sage_splat::{Camera, Channels, Intrinsics, RenderOptions, Renderer};
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

/// Writes `out`: the first-person view at the start of an episode of `run` beside the
/// episode's map from the run's report (reference path, agent path, collisions, caption).
///
/// # Errors
///
/// The run holds no VLN episode, or its scene, records or image cannot be read or written.
pub fn write(scenes: &Path, run: &Path, out: &Path) -> Result<()> {
    let files = report::read_run(run)?;
    let rec = pick(&files.records)
        .ok_or_else(|| Error::invalid("no VLN episode with a path").in_file(run))?;
    let episode = rec.record.as_ref().expect("picked records have one");
    let (scene, _) = Scene::load_for_rendering(&scenes.join(&rec.scene))?;
    let (grid, _) = NavGrid::from_scene(&scene, &TrajectoryParams::default().grid)?;
    let map = report::maps::episode_map(&SemanticMap::build(&scene), &grid, rec);
    let height = map.height;
    let width = height * 4 / 3;
    let camera = Camera::from_yaw_pitch(
        Intrinsics::from_hfov(width as u32, height as u32, 90.0)?,
        Vec3::new(episode.start[0], episode.start[1], 1.2),
        episode.start_yaw,
        -0.1,
    );
    let view = Renderer::new(&scene.gaussians).render(
        &scene.gaussians,
        &scene.instances.category_ids,
        &camera,
        &RenderOptions {
            channels: Channels::RGB,
            ..RenderOptions::default()
        },
    )?;
    let total = width + map.width;
    let mut rgb = vec![255u8; total * height * 3];
    blit(&mut rgb, total, &view.rgb, width, height, 0);
    blit(&mut rgb, total, &map.rgb, map.width, height, width);
    sage_io::files::write_rgb_png(out, total, height, &rgb)?;
    eprintln!(
        "overview: {} (episode {} in {})",
        out.display(),
        rec.episode_id,
        rec.scene
    );
    Ok(())
}
