//! The GPU renderer against the CPU renderer on the shared test splats (files written by a real
//! tool) and on generated rooms: PSNR ≥ 40 dB on RGB, expected depth within 1 cm on opaque
//! pixels, instance and semantic ids equal on ≥ 99% of pixels; batches equal single renders;
//! the same bytes twice.
//!
//! Runs on any adapter wgpu finds (Mesa's lavapipe in CI). With `SAGE3D_REQUIRE_GPU` set (the
//! test command sets it) a missing adapter fails every test; without it they say so and pass.
#![cfg(feature = "gpu")]

use glam::Vec3;
use sage_scene::ply::read_splats_file;
use sage_scene::{Gaussian, Gaussians};
use sage_splat::gpu::{Gpu, GpuRenderer, GpuStats, SOFTWARE_PIECE};
use sage_splat::passes::{GPU_FEW_CHUNKS, GPU_SLABS};
use sage_splat::{
    Backend, Blending, Camera, Channels, Device, KernelShape, RenderOptions, RenderOutput, Renderer,
};
use sage_testkit::splats::{psnr, random_gaussians};
use std::path::PathBuf;
use std::sync::Arc;

mod common;
use common::{camera, home};

fn gpu() -> Option<Arc<Gpu>> {
    match Gpu::shared(false) {
        Ok(g) => Some(g),
        Err(e) if std::env::var_os("SAGE3D_REQUIRE_GPU").is_some() => {
            panic!("SAGE3D_REQUIRE_GPU is set and no GPU adapter opened: {e}")
        }
        Err(e) => {
            eprintln!("no GPU adapter, GPU test not run: {e}");
            None
        }
    }
}

fn testdata(name: &str) -> Gaussians {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name);
    read_splats_file(&path).unwrap().0
}

/// Checks the GPU image against the CPU image within the bounds; returns the PSNR.
fn agree(cpu: &RenderOutput, gpu: &RenderOutput, what: &str) -> f64 {
    assert_eq!((cpu.width, cpu.height), (gpu.width, gpu.height), "{what}");
    let p = psnr(&cpu.rgb_f32, &gpu.rgb_f32);
    assert!(p >= 40.0, "{what}: RGB PSNR {p:.1} dB");
    let n = cpu.alpha.len();
    let mut opaque = 0;
    for i in 0..n {
        assert!(
            (cpu.alpha[i] - gpu.alpha[i]).abs() < 0.02,
            "{what}: pixel {i} alpha"
        );
        if cpu.alpha[i] > 0.99 && gpu.alpha[i] > 0.99 {
            opaque += 1;
            let (a, b) = (cpu.depth_expected[i], gpu.depth_expected[i]);
            assert!((a - b).abs() < 0.01, "{what}: pixel {i}: depth {a} vs {b}");
        }
    }
    let same = |a: &[u32], b: &[u32]| a.iter().zip(b).filter(|(x, y)| x == y).count();
    let instance = same(&cpu.instance, &gpu.instance);
    assert!(
        instance as f64 >= 0.99 * n as f64,
        "{what}: instance agrees on {instance} of {n}"
    );
    let semantic = cpu
        .semantic
        .iter()
        .zip(&gpu.semantic)
        .filter(|(x, y)| x == y)
        .count();
    assert!(
        semantic as f64 >= 0.99 * n as f64,
        "{what}: semantic agrees on {semantic} of {n}"
    );
    let median = (0..n)
        .filter(|&i| (cpu.depth_median[i] - gpu.depth_median[i]).abs() < 0.01)
        .count();
    assert!(
        median as f64 >= 0.99 * n as f64,
        "{what}: median depth agrees on {median} of {n}"
    );
    assert!(opaque > 0, "{what}: nothing opaque to compare");
    p
}

/// Renders every camera on both executors and checks they agree: on the GPU in all
/// [`GPU_SLABS`] and in the slabs the renderer chooses (one for the few chunks of most test
/// scenes), so the path through several slabs meets the CPU renderer on every scene. Returns
/// the GPU renderer's work for the last camera in [`GPU_SLABS`] slabs.
fn compare(g: &Gaussians, categories: &[u16], cameras: &[Camera], what: &str) -> Option<GpuStats> {
    let gpu = gpu()?;
    let options = RenderOptions {
        background: [0.1, 0.2, 0.3],
        ..RenderOptions::default()
    };
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let mut cpu = Renderer::new(g);
    let mut in_all = None;
    for (k, cam) in cameras.iter().enumerate() {
        let a = cpu.render(g, categories, cam, &options).unwrap();
        for slabs in [Some(GPU_SLABS), None] {
            renderer.set_slabs(slabs).unwrap();
            let b = renderer.render(g, categories, cam, &options).unwrap();
            let p = agree(&a, &b, &format!("{what}, camera {k}, slabs {slabs:?}"));
            eprintln!("{what}, camera {k}, slabs {slabs:?}: PSNR {p:.1} dB");
            if slabs.is_some() {
                in_all = Some(renderer.stats());
            }
        }
    }
    in_all
}

#[test]
fn the_shared_splat_files_match_the_cpu_renderer() {
    for name in ["random_4k_sh3.ply", "random_3k_sh0.ply"] {
        let g = testdata(name);
        let b = g.bounds();
        let centre = (b.min + b.max) * 0.5;
        let size = (b.max - b.min).max_element();
        let cameras: Vec<Camera> = [0.0f32, 1.3, 2.6, 4.0]
            .iter()
            .map(|&yaw| {
                let eye = centre - Vec3::new(yaw.cos(), yaw.sin(), 0.0) * size;
                camera(96, 72, eye, yaw, 0.0)
            })
            .collect();
        let stats = compare(&g, &[], &cameras, name);
        assert!(stats.is_none_or(|s| s.splats > 100), "{stats:?}");
    }
}

#[test]
fn every_sh_degree_matches_the_cpu_renderer() {
    for degree in 0..=3u8 {
        let g = random_gaussians(u64::from(degree) + 1, 3000, degree, 1.5);
        let cameras = [camera(72, 56, Vec3::new(0.0, 0.0, 1.2), 0.05, -0.1)];
        compare(&g, &[], &cameras, &format!("random SH degree {degree}"));
    }
}

#[test]
fn generated_rooms_match_the_cpu_renderer() {
    let scene = home(4, 2, 16, 40_000);
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cameras: Vec<Camera> = [(0.3f32, 64, 48), (2.0, 160, 120), (-2.4, 100, 37)]
        .iter()
        .map(|&(yaw, w, h)| camera(w, h, Vec3::new(c.x, c.y, 1.2), yaw, -0.15))
        .collect();
    compare(
        &scene.gaussians,
        &scene.instances.category_ids,
        &cameras,
        "generated room",
    );
}

#[test]
fn what_lies_behind_an_opaque_wall_is_not_projected() {
    // An opaque wall of 8,000 Gaussians two metres in front of the camera, filling the view,
    // and 20,000 behind it: the depth slabs behind finished tiles are skipped.
    let mut items = Vec::new();
    for i in 0..100 {
        for j in 0..80 {
            items.push(Gaussian {
                position: Vec3::new(2.0, -2.5 + 0.05 * i as f32, -0.8 + 0.05 * j as f32),
                log_scale: Vec3::splat(0.05f32.ln()),
                opacity_logit: 6.0,
                sh_dc: [0.5, -0.2, 0.1],
                instance: 1,
                ..Gaussian::default()
            });
        }
    }
    let wall = items.len();
    let behind = random_gaussians(3, 20_000, 0, 2.0);
    items.extend((0..behind.len()).map(|i| {
        let mut g = behind.get(i);
        g.position.x += 5.0;
        g
    }));
    let g = Gaussians::from_gaussians(&items, 0).unwrap();
    let cameras = [camera(64, 48, Vec3::new(0.0, 0.0, 1.2), 0.0, 0.0)];
    if let Some(stats) = compare(&g, &[], &cameras, "a wall in front of a cloud") {
        assert!(
            stats.splats >= wall as u64 / 2 && stats.splats < (wall + behind.len() / 10) as u64,
            "{stats:?}"
        );
    }
}

#[test]
fn splats_at_one_depth_blend_in_the_same_order_on_both_renderers() {
    // A wall seen square on, as a synthetic room's walls are: pairs of nearly opaque Gaussians
    // at one place, a black and a white one, one of them a float step behind the other (the
    // black one in a checkerboard's black squares). Sorted by exact depth the nearer one is in
    // front; by the shared depth key the two tie and the one first in the scene's order is.
    // Either is a right image; the two renderers must form the same one.
    let behind = f32::from_bits(2.0f32.to_bits() + 1);
    let mut items = Vec::new();
    for i in 0..60 {
        for j in 0..40 {
            let (y, z) = (-1.5 + 0.05 * i as f32, 0.2 + 0.05 * j as f32);
            let (black, white) = if (i + j) % 2 == 0 {
                (behind, 2.0)
            } else {
                (2.0, behind)
            };
            for (x, dc) in [(black, -3.0), (white, 3.0)] {
                items.push(Gaussian {
                    position: Vec3::new(x, y, z),
                    log_scale: Vec3::splat(0.04f32.ln()),
                    opacity_logit: 5.0,
                    sh_dc: [dc; 3],
                    instance: 1,
                    ..Gaussian::default()
                });
            }
        }
    }
    let g = Gaussians::from_gaussians(&items, 0).unwrap();
    let key = |z: f32| camera(64, 48, Vec3::ZERO, 0.0, 0.0).depth_key(z);
    assert_eq!(key(behind), key(2.0));
    let cameras = [camera(64, 48, Vec3::new(0.0, 0.0, 1.2), 0.0, 0.0)];
    let Some(gpu) = gpu() else { return };
    let options = RenderOptions {
        background: [1.0; 3],
        ..RenderOptions::default()
    };
    let a = Renderer::new(&g)
        .render(&g, &[], &cameras[0], &options)
        .unwrap();
    let b = GpuRenderer::new(&gpu, &g)
        .unwrap()
        .render(&g, &[], &cameras[0], &options)
        .unwrap();
    agree(&a, &b, "pairs of splats at one depth");
    let worst = a
        .rgb_f32
        .iter()
        .zip(&b.rgb_f32)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(worst < 0.01, "RGB differs by up to {worst}");
}

#[test]
fn a_batch_equals_its_cameras_rendered_alone_and_repeats_exactly() {
    let Some(gpu) = gpu() else { return };
    let scene = home(9, 3, 20, 30_000);
    let g = &scene.gaussians;
    let categories = &scene.instances.category_ids;
    let c = scene.floorplan.rooms[1].profile.centroid();
    let cameras: Vec<Camera> = (0..6)
        .map(|k| {
            let (w, h) = if k % 2 == 0 { (64, 64) } else { (90, 50) };
            camera(w, h, Vec3::new(c.x, c.y, 1.0), k as f32, 0.1)
        })
        .collect();
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let options = RenderOptions::default();
    let batch = renderer
        .render_batch(g, categories, &cameras, &options)
        .unwrap();
    assert_eq!(batch.len(), cameras.len());
    // Inside one room, every camera culls most of the house on the GPU: its chunks outside the
    // view, and what lies behind finished tiles.
    let stats = renderer.stats();
    assert_eq!(stats.cameras, cameras.len());
    assert!(
        stats.chunks > 0 && stats.splats < cameras.len() as u64 * g.len() as u64 / 2,
        "{stats:?} of {} Gaussians",
        g.len()
    );
    // Two batches in flight at once (the second submitted before the first is read back)
    // give the same images.
    let first = renderer
        .submit(g, categories, &cameras[..3], &options)
        .unwrap();
    let second = renderer
        .submit(g, categories, &cameras[3..], &options)
        .unwrap();
    let mut overlapped = first.wait().unwrap();
    overlapped.extend(second.wait().unwrap());
    assert!(
        batch == overlapped,
        "overlapped batches differ from one batch"
    );
    for (k, (cam, from_batch)) in cameras.iter().zip(&batch).enumerate() {
        let alone = renderer.render(g, categories, cam, &options).unwrap();
        assert!(&alone == from_batch, "camera {k} differs alone");
    }
    let again = renderer
        .render_batch(g, categories, &cameras, &options)
        .unwrap();
    assert!(batch == again, "the same batch rendered twice differs");
}

#[test]
fn the_images_are_the_same_in_any_number_of_depth_slabs_with_either_blending_kernel() {
    let Some(gpu) = gpu() else { return };
    let scene = home(11, 3, 20, 30_000);
    let g = &scene.gaussians;
    let categories = &scene.instances.category_ids;
    let c = scene.floorplan.rooms[0].profile.centroid();
    // Headings all round a room: some face a near wall (tiles finished in the first slab),
    // some look down the house; two sizes, one not a whole number of tiles.
    let cameras: Vec<Camera> = (0..5)
        .map(|k| {
            let (w, h) = if k % 2 == 0 { (72, 56) } else { (64, 48) };
            camera(w, h, Vec3::new(c.x, c.y, 1.1), 1.3 * k as f32, 0.0)
        })
        .collect();
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let options = RenderOptions::default();
    let mut renders = Vec::new();
    for blending in [Blending::Blocks, Blending::Columns] {
        renderer.set_blending(blending);
        for slabs in 1..=GPU_SLABS {
            renderer.set_slabs(Some(slabs)).unwrap();
            let batch = renderer
                .render_batch(g, categories, &cameras, &options)
                .unwrap();
            assert_eq!(renderer.stats().slabs, slabs);
            // A fixed count holds whatever the batch's work was.
            let alone = renderer
                .render(g, categories, &cameras[1], &options)
                .unwrap();
            assert!(alone == batch[1], "{blending}, {slabs} slabs: alone");
            assert_eq!(renderer.stats().slabs, slabs);
            renders.push((format!("{blending}, {slabs} slabs"), batch));
        }
    }
    let (_, first) = &renders[0];
    for (what, r) in &renders[1..] {
        assert!(r == first, "{what} differ from blocks in one slab");
    }
    let e = renderer.set_slabs(Some(GPU_SLABS + 1)).unwrap_err();
    assert!(e.message().contains("1 to 4"), "{e}");
    renderer.set_slabs(None).unwrap();
    let chosen = renderer
        .render_batch(g, categories, &cameras, &options)
        .unwrap();
    assert!(chosen == *first, "slabs chosen from the work differ");
}

/// `n` small splats over part of the first 8×8 block of a 16×16 camera at the origin facing
/// +x (`camera(16, 16, …)`), from 1 to 1.5 m away, and one opaque splat behind them all: the
/// block's other pixels stay unfinished through the whole list of its tile.
fn crowded_tile(n: usize) -> Gaussians {
    let (xn, yn) = ((2.0 - 8.0) / 8.0, (4.0 - 8.0) / 8.0);
    let mut items: Vec<Gaussian> = (0..n)
        .map(|i| {
            let d = 1.0 + 0.5 * i as f32 / n as f32;
            Gaussian {
                position: Vec3::new(d, -xn * d, -yn * d),
                log_scale: Vec3::splat((0.0625 * d).ln()),
                opacity_logit: 0.0,
                sh_dc: [1.0, -1.0, 0.5],
                instance: 1,
                ..Gaussian::default()
            }
        })
        .collect();
    items.push(Gaussian {
        position: Vec3::new(5.0, 0.0, 0.0),
        log_scale: Vec3::splat(3.0f32.ln()),
        opacity_logit: 5.0,
        sh_dc: [-1.0, 1.0, 0.0],
        instance: 2,
        ..Gaussian::default()
    });
    Gaussians::from_gaussians(&items, 0).unwrap()
}

#[test]
fn a_tile_listing_more_entries_than_a_piece_is_blended_whole_in_later_passes() {
    let Some(gpu) = gpu() else { return };
    // 70,001 entries in one tile's list of one slab: more loop iterations than a CPU driver
    // lets one invocation run (lavapipe's 65,535), blended whole only in pieces.
    let g = crowded_tile(70_000);
    let cam = camera(16, 16, Vec3::ZERO, 0.0, 0.0);
    let options = RenderOptions::default();
    let cpu = Renderer::new(&g).render(&g, &[], &cam, &options).unwrap();
    assert!(cpu.instance.contains(&1) && cpu.instance.contains(&2));
    let renderer = GpuRenderer::new(&gpu, &g).unwrap();
    renderer.set_slabs(Some(1)).unwrap();
    renderer.set_blend_piece(Some(SOFTWARE_PIECE)).unwrap();
    let mut renders = Vec::new();
    for blending in [Blending::Blocks, Blending::Columns] {
        renderer.set_blending(blending);
        let b = renderer.render(&g, &[], &cam, &options).unwrap();
        agree(&cpu, &b, &format!("a crowded tile, {blending}"));
        assert!(cpu.instance == b.instance, "{blending}: instances differ");
        let stats = renderer.stats();
        assert_eq!(stats.blend_passes, 3, "{blending}: {stats:?}");
        assert!(stats.tile_entries > 70_000, "{stats:?}");
        renders.push(b);
    }
    assert!(renders[0] == renders[1], "the two blending kernels differ");
    // The passes are kept: the next batch is not rendered again.
    assert_eq!(renderer.stats().regrown, 0);
    // A new piece starts again from one pass; a submitted batch that wants more is rendered
    // again when waited for.
    renderer.set_blend_piece(Some(2 * SOFTWARE_PIECE)).unwrap();
    let submitted = renderer.submit(&g, &[], &[cam], &options).unwrap();
    let waited = submitted.wait().unwrap();
    assert!(waited[0] == renders[1], "a submitted batch differs");
    let stats = renderer.stats();
    assert_eq!((stats.blend_passes, stats.regrown), (2, 1), "{stats:?}");
    // The passes a batch wanted in pieces since changed are not taken for the new pieces: in
    // pieces of 256 this tile wants 274 passes, in the default ones 3.
    renderer.set_blend_piece(Some(256)).unwrap();
    let submitted = renderer.submit(&g, &[], &[cam], &options).unwrap();
    renderer.set_blend_piece(None).unwrap();
    let waited = submitted.wait().unwrap();
    assert!(
        waited[0] == renders[1],
        "a batch submitted before the piece changed differs"
    );
    // More pieces than the passes a slab records: an error that says so, not wrong pixels.
    renderer.set_blend_piece(Some(256)).unwrap();
    let e = renderer.render(&g, &[], &cam, &options).unwrap_err();
    assert!(e.message().contains("blending passes"), "{e}");
    assert!(renderer.set_blend_piece(Some(0)).is_err());
}

#[test]
fn the_images_are_the_same_whatever_the_blending_piece() {
    let Some(gpu) = gpu() else { return };
    let scene = home(12, 3, 20, 30_000);
    let g = &scene.gaussians;
    let categories = &scene.instances.category_ids;
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cameras: Vec<Camera> = (0..4)
        .map(|k| camera(64, 48, Vec3::new(c.x, c.y, 1.1), 1.6 * k as f32, 0.0))
        .collect();
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let options = RenderOptions::default();
    for slabs in [1, GPU_SLABS] {
        renderer.set_slabs(Some(slabs)).unwrap();
        for blending in [Blending::Blocks, Blending::Columns] {
            renderer.set_blending(blending);
            renderer.set_blend_piece(None).unwrap();
            let whole = renderer
                .render_batch(g, categories, &cameras, &options)
                .unwrap();
            renderer.set_blend_piece(Some(512)).unwrap();
            let pieces = renderer
                .render_batch(g, categories, &cameras, &options)
                .unwrap();
            let stats = renderer.stats();
            eprintln!("{slabs} slabs, {blending}: {stats:?}");
            assert!(stats.blend_passes > 1, "{stats:?}");
            assert!(whole == pieces, "{slabs} slabs, {blending}: pieces differ");
        }
    }
}

#[test]
fn a_camera_that_sees_few_chunks_takes_one_slab_of_a_batch_rendered_in_several() {
    let Some(gpu) = gpu() else { return };
    // A cloud of 240,000 Gaussians (over GPU_FEW_CHUNKS chunks) ahead of the eye and a faint
    // one of 20,000 behind it (no tile of it is ever finished, so more slabs only add work),
    // in Morton order so that chunks are compact.
    let ahead = random_gaussians(21, 240_000, 0, 2.0);
    let behind = random_gaussians(22, 20_000, 0, 1.0);
    let mut items: Vec<Gaussian> = (0..ahead.len()).map(|i| ahead.get(i)).collect();
    items.extend((0..behind.len()).map(|i| Gaussian {
        position: behind.get(i).position * Vec3::new(-1.0, 1.0, 1.0),
        opacity_logit: -3.0,
        ..behind.get(i)
    }));
    let g = Gaussians::from_gaussians(&items, 0).unwrap();
    let g = g.permuted(&g.morton_order());
    let eye = Vec3::new(-0.5, 0.0, 1.2);
    let cameras = [
        camera(48, 40, eye, 0.0, 0.0),
        camera(40, 32, eye, std::f32::consts::PI, 0.0),
    ];
    let options = RenderOptions::default();
    let renderer = GpuRenderer::new(&gpu, &g).unwrap();
    let alone = |k: usize, slabs: u32| {
        renderer.set_slabs(Some(slabs)).unwrap();
        let out = renderer.render(&g, &[], &cameras[k], &options).unwrap();
        (out, renderer.stats().chunks)
    };
    let (many, many_in_one) = alone(0, 1);
    let (few, few_in_one) = alone(1, 1);
    let (_, many_in_all) = alone(0, GPU_SLABS);
    let (_, few_in_all) = alone(1, GPU_SLABS);
    // The premises: the first camera sees many chunks, and the second's few span slabs.
    let few_chunks = u64::from(GPU_FEW_CHUNKS);
    assert!(
        many_in_one >= few_chunks && few_in_one < few_chunks,
        "{many_in_one}, {few_in_one}"
    );
    assert!(few_in_all > few_in_one, "{few_in_all} against {few_in_one}");
    // The batch is in all the slabs (one camera sees many chunks); the camera that sees few
    // takes the first alone, the other all of them, and the images do not change.
    let fresh = GpuRenderer::new(&gpu, &g).unwrap();
    let batch = fresh.render_batch(&g, &[], &cameras, &options).unwrap();
    let stats = fresh.stats();
    assert_eq!(stats.slabs, GPU_SLABS);
    assert_eq!(stats.chunks, many_in_all + few_in_one, "{stats:?}");
    assert!(
        batch[0] == many && batch[1] == few,
        "the batch differs from its cameras alone"
    );
    // The slabs follow each batch's own cameras, not the batch before: the camera that sees
    // few alone takes one, and the one that sees many right after it takes them all.
    for (k, slabs) in [(1, 1), (0, GPU_SLABS), (1, 1), (1, 1), (0, GPU_SLABS)] {
        let out = fresh.render(&g, &[], &cameras[k], &options).unwrap();
        assert_eq!(fresh.stats().slabs, slabs, "camera {k}");
        assert!(
            out == *[&many, &few][k],
            "camera {k} differs from its render above"
        );
    }
}

#[test]
fn the_kernels_shaped_for_hardware_and_for_cpu_drivers_form_the_same_bytes() {
    let Some(gpu) = gpu() else { return };
    // Two scenes: a house (many chunks, so four slabs and several sort blocks), and one of
    // 300 Gaussians (a chunk's last lanes past the scene's end, a sort of a single block).
    let scene = home(12, 3, 20, 30_000);
    let small = random_gaussians(5, 300, 1, 1.5);
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cameras: Vec<Camera> = (0..6)
        .map(|k| {
            let (w, h) = if k % 2 == 0 { (72, 56) } else { (80, 48) };
            camera(w, h, Vec3::new(c.x, c.y, 1.1), 1.1 * k as f32, 0.0)
        })
        .collect();
    let around = |k: usize| {
        camera(
            48,
            40,
            Vec3::new(0.0, 0.0, 1.2),
            0.05 + 0.2 * k as f32,
            -0.1,
        )
    };
    let small_cameras: Vec<Camera> = (0..3).map(around).collect();
    let options = RenderOptions::default();
    let cases = [
        (
            &scene.gaussians,
            &scene.instances.category_ids[..],
            &cameras,
        ),
        (&small, &[][..], &small_cameras),
    ];
    for (g, categories, cameras) in cases {
        let renders = [KernelShape::Lanes, KernelShape::Runs].map(|shape| {
            let renderer = GpuRenderer::with_shape(&gpu, g, shape).unwrap();
            let batch = renderer
                .render_batch(g, categories, cameras, &options)
                .unwrap();
            let alone = renderer
                .render(g, categories, &cameras[1], &options)
                .unwrap();
            assert!(
                alone == batch[1],
                "{shape:?}: a camera alone differs from its batch"
            );
            assert!(renderer.stats().splats > 0, "{shape:?}: nothing drawn");
            batch
        });
        assert!(renders[0] == renders[1], "the two shapes differ");
    }
}

/// Sets of images a caller may ask for: each alone, the sensors of an RGB-D agent, the 8-bit
/// colour with its floats (then rounded on the host), and none.
fn channel_sets() -> Vec<Channels> {
    let names = "rgb rgb_f32 alpha depth_expected depth_median instance semantic none";
    names
        .split(' ')
        .chain(["rgb,depth_median", "rgb,rgb_f32", "instance,semantic"])
        .map(|set| set.parse().unwrap())
        .collect()
}

#[test]
fn the_images_asked_for_equal_the_full_render_and_the_rest_are_empty() {
    let Some(gpu) = gpu() else { return };
    let scene = home(4, 3, 20, 30_000);
    let g = &scene.gaussians;
    let categories = &scene.instances.category_ids;
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cameras: Vec<Camera> = (0..4)
        .map(|k| {
            let (w, h) = if k % 2 == 0 { (48, 40) } else { (70, 33) };
            camera(w, h, Vec3::new(c.x, c.y, 1.2), 1.5 * k as f32, -0.1)
        })
        .collect();
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let mut cpu = Renderer::new(g);
    let full = RenderOptions {
        background: [0.2, 0.1, 0.4],
        ..RenderOptions::default()
    };
    let gpu_full = renderer
        .render_batch(g, categories, &cameras, &full)
        .unwrap();
    let cpu_full: Vec<RenderOutput> = cameras
        .iter()
        .map(|cam| cpu.render(g, categories, cam, &full).unwrap())
        .collect();
    for channels in channel_sets() {
        let options = RenderOptions { channels, ..full };
        let part = renderer
            .render_batch(g, categories, &cameras, &options)
            .unwrap();
        for (k, cam) in cameras.iter().enumerate() {
            let full = gpu_full[k].clone().keep(&channels);
            assert!(part[k] == full, "GPU, {channels}, camera {k}");
            let alone = cpu.render(g, categories, cam, &options).unwrap();
            let full = cpu_full[k].clone().keep(&channels);
            assert!(alone == full, "CPU, {channels}, camera {k}");
        }
    }
}

#[test]
fn the_gpu_rounds_colours_to_bytes_as_the_host_does() {
    let Some(gpu) = gpu() else { return };
    // Nothing in view: every pixel is the background, so the 8-bit colour the GPU packs is
    // its rounding of the background's channels, at and beside every rounding boundary.
    let g = random_gaussians(5, 200, 0, 1.0);
    let cam = camera(8, 8, Vec3::new(0.0, 0.0, 1.2), std::f32::consts::PI, 0.0);
    let renderer = GpuRenderer::new(&gpu, &g).unwrap();
    let mut cpu = Renderer::new(&g);
    let mut values: Vec<f32> = vec![0.0, -0.0, -0.5, 1.0, 1.5, f32::INFINITY, f32::NAN];
    for k in 0..256 {
        let tie = (k as f32 + 0.5) / 255.0;
        values.extend([tie.next_down(), tie, tie.next_up(), k as f32 / 255.0]);
    }
    for background in values.chunks(3) {
        let mut bg = [0.0; 3];
        bg[..background.len()].copy_from_slice(background);
        let packed = RenderOptions {
            background: bg,
            channels: Channels::RGB,
        };
        let from_floats = RenderOptions {
            channels: Channels::ALL,
            ..packed
        };
        let a = renderer.render(&g, &[], &cam, &packed).unwrap();
        let b = renderer.render(&g, &[], &cam, &from_floats).unwrap();
        let c = cpu.render(&g, &[], &cam, &packed).unwrap();
        assert!(
            b.rgb_f32.chunks(3).all(|p| p
                .iter()
                .zip(bg)
                .all(|(v, x)| *v == x || v.is_nan() && x.is_nan())),
            "background {bg:?}: the pixels are not the background"
        );
        assert_eq!(
            a.rgb, b.rgb,
            "background {bg:?}: packed on the GPU and rounded on the host"
        );
        assert_eq!(a.rgb, c.rgb, "background {bg:?}: GPU and CPU renderer");
    }
}

#[test]
fn a_batch_of_more_cameras_than_a_sort_key_holds_is_rendered_in_parts_alike() {
    // A batch's sort keys hold its camera in one byte: 300 cameras go in two submissions, and
    // each camera's images still equal those it gets alone.
    let Some(gpu) = gpu() else { return };
    let scene = home(4, 2, 8, 8_000);
    let (g, categories) = (&scene.gaussians, &scene.instances.category_ids);
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cameras: Vec<Camera> = (0..300)
        .map(|k| camera(16, 12, Vec3::new(c.x, c.y, 1.1), 0.021 * k as f32, 0.0))
        .collect();
    let renderer = GpuRenderer::new(&gpu, g).unwrap();
    let options = RenderOptions::default();
    let batch = renderer
        .render_batch(g, categories, &cameras, &options)
        .unwrap();
    assert_eq!(renderer.stats().cameras, cameras.len());
    for k in [0, 1, 137, 255, 256, 299] {
        let alone = renderer
            .render(g, categories, &cameras[k], &options)
            .unwrap();
        assert!(alone == batch[k], "camera {k} of the batch differs alone");
        assert!(
            alone.alpha.iter().any(|&a| a > 0.5),
            "camera {k} sees nothing"
        );
    }
}

#[test]
fn frames_with_more_tile_entries_than_the_first_buffers_hold_still_match() {
    // Few Gaussians, each large on screen: many more (splat, tile) pairs than the renderer's
    // first guess of twice the Gaussians, so it must grow its buffers and render again.
    let mut g = testdata("random_3k_sh0.ply");
    let b = g.bounds();
    let (centre, size) = ((b.min + b.max) * 0.5, (b.max - b.min).max_element());
    // Every Gaussian blown up to a tenth of the cloud (log-scales are stored in 1/2048 steps).
    let code = ((0.1 * size).ln() * 2048.0) as i16;
    for s in &mut g.log_scales {
        *s = [code, code / 2 + code / 4, code];
    }
    let cameras = [camera(640, 480, centre - Vec3::X * size, 0.0, 0.0)];
    if let Some(stats) = compare(&g, &[], &cameras, "large splats at 640×480") {
        assert!(stats.regrown > 0, "{stats:?}");
        assert!(
            stats.tile_entries > 2 * g.len() as u64 + 65_536,
            "{stats:?}"
        );
    }
}

#[test]
fn the_backend_opens_the_gpu_and_refuses_another_scene() {
    if gpu().is_none() {
        return;
    }
    let g = testdata("random_3k_sh0.ply");
    let mut backend = Backend::open(Device::Gpu, &g).unwrap();
    assert!(backend.is_gpu(), "{}", backend.describe());
    assert!(
        backend.describe().starts_with("gpu: "),
        "{}",
        backend.describe()
    );
    let other = testdata("random_4k_sh3.ply");
    let cam = camera(32, 32, Vec3::ZERO, 0.0, 0.0);
    let e = backend
        .render(&other, &[], &cam, &RenderOptions::default())
        .unwrap_err();
    assert!(e.message().contains("built for 3000 Gaussians"), "{e}");
}

#[test]
fn auto_takes_a_hardware_gpu_or_says_why_it_renders_on_the_cpu() {
    let g = testdata("random_3k_sh0.ply");
    let backend = Backend::open(Device::Auto, &g).unwrap();
    match Gpu::shared(true) {
        Ok(gpu) => {
            assert!(backend.is_gpu(), "{}", backend.describe());
            assert!(!gpu.is_software());
        }
        Err(e) => {
            assert!(!backend.is_gpu());
            assert!(
                backend.describe().starts_with("cpu (")
                    && backend
                        .describe()
                        .contains(&format!("auto: {}", e.message())),
                "{}",
                backend.describe()
            );
        }
    }
}

#[test]
fn renders_from_many_threads_at_once_equal_renders_alone() {
    let Some(gpu) = gpu() else { return };
    let g = testdata("random_4k_sh3.ply");
    let b = g.bounds();
    let (centre, size) = ((b.min + b.max) * 0.5, (b.max - b.min).max_element());
    // Two backgrounds: requests with other options are rendered in a submission of their own.
    let requests: Vec<(Camera, RenderOptions)> = (0..8)
        .map(|k| {
            let yaw = k as f32 * 0.8;
            let eye = centre - Vec3::new(yaw.cos(), yaw.sin(), 0.0) * size;
            let options = RenderOptions {
                background: [0.1 * (k % 2) as f32, 0.2, 0.3],
                ..RenderOptions::default()
            };
            (camera(48 + 8 * k, 40, eye, yaw, 0.0), options)
        })
        .collect();
    let renderer = GpuRenderer::new(&gpu, &g).unwrap();
    let alone: Vec<RenderOutput> = requests
        .iter()
        .map(|(c, o)| renderer.render(&g, &[], c, o).unwrap())
        .collect();
    let together: Vec<RenderOutput> = std::thread::scope(|s| {
        let handles: Vec<_> = requests
            .iter()
            .map(|(c, o)| s.spawn(|| renderer.render(&g, &[], c, o).unwrap()))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(alone, together);
}

#[test]
fn passes_are_timed_on_request_and_timing_changes_no_byte() {
    let Some(gpu) = gpu() else { return };
    let g = testdata("random_3k_sh0.ply");
    let b = g.bounds();
    let (centre, size) = ((b.min + b.max) * 0.5, (b.max - b.min).max_element());
    let cam = camera(64, 48, centre - Vec3::X * size, 0.0, 0.0);
    let options = RenderOptions::default();
    let renderer = GpuRenderer::new(&gpu, &g).unwrap();
    let plain = renderer.render(&g, &[], &cam, &options).unwrap();
    assert!(renderer.stats().passes.is_none());
    let timed = renderer.time_passes(true);
    assert_eq!(timed, gpu.has_timestamps());
    let image = renderer.render(&g, &[], &cam, &options).unwrap();
    assert_eq!(image, plain);
    match renderer.stats().passes {
        Some(p) => {
            let stages = [
                p.setup_ms,
                p.project_ms,
                p.depth_sort_ms,
                p.bin_ms,
                p.raster_ms,
                p.compose_ms,
                p.read_back_ms,
                p.unpack_ms,
            ];
            assert!(stages.iter().all(|t| t.is_finite() && *t >= 0.0), "{p:?}");
            assert!(stages[..6].iter().sum::<f64>() > 0.0, "{p:?}");
            // The copy is timed exactly where the device writes timestamps between passes.
            assert_eq!(p.read_back_ms > 0.0, gpu.has_encoder_timestamps(), "{p:?}");
        }
        None => assert!(!timed),
    }
    renderer.time_passes(false);
    renderer.render(&g, &[], &cam, &options).unwrap();
    assert!(renderer.stats().passes.is_none());
}
