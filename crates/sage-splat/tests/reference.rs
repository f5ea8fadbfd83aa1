//! The fast tile renderer against a deliberately simple reference: per pixel, every Gaussian,
//! sorted by depth, no tiles, no culling beyond the near/far planes, written from the 3DGS
//! formulas without sharing the renderer's projection or colour code (the reference evaluates
//! the spherical harmonics itself, so a wrong sign or order in the renderer's SH shows here).

use glam::{Mat3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_scene::gaussians::sh_rest_count;
use sage_scene::{Gaussian, Gaussians};
use sage_splat::{Camera, Channels, RenderOptions, RenderOutput, Renderer, sh};
use sage_testkit::splats::{psnr, random_gaussians};

mod common;
use common::{camera, home};

/// One projected Gaussian of the reference.
struct RefSplat {
    mean: (f32, f32),
    inv: [[f32; 2]; 2],
    opacity: f32,
    color: [f32; 3],
    depth: f32,
    instance: u32,
}

fn rotation_matrix(q: Quat) -> [[f32; 3]; 3] {
    let q = q.normalize();
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The real spherical harmonic of band `l`, order `m` (−l…l) at unit direction (x, y, z), with
/// the constants and signs of the 3DGS reference implementation, in double precision.
fn real_sh(l: usize, m: isize, x: f64, y: f64, z: f64) -> f64 {
    const C0: f64 = 0.282_094_791_773_878_14;
    const C1: f64 = 0.488_602_511_902_919_9;
    const C2: [f64; 5] = [
        1.092_548_430_592_079_2,
        -1.092_548_430_592_079_2,
        0.315_391_565_252_520_05,
        -1.092_548_430_592_079_2,
        0.546_274_215_296_039_6,
    ];
    const C3: [f64; 7] = [
        -0.590_043_589_926_643_5,
        2.890_611_442_640_554,
        -0.457_045_799_464_465_8,
        0.373_176_332_590_115_4,
        -0.457_045_799_464_465_8,
        1.445_305_721_320_277,
        -0.590_043_589_926_643_5,
    ];
    let r2 = x * x + y * y;
    match (l, m) {
        (0, 0) => C0,
        (1, -1) => -C1 * y,
        (1, 0) => C1 * z,
        (1, 1) => -C1 * x,
        (2, -2) => C2[0] * x * y,
        (2, -1) => C2[1] * y * z,
        (2, 0) => C2[2] * (2.0 * z * z - r2),
        (2, 1) => C2[3] * x * z,
        (2, 2) => C2[4] * (x * x - y * y),
        (3, -3) => C3[0] * y * (3.0 * x * x - y * y),
        (3, -2) => C3[1] * x * y * z,
        (3, -1) => C3[2] * y * (4.0 * z * z - r2),
        (3, 0) => C3[3] * z * (2.0 * z * z - 3.0 * r2),
        (3, 1) => C3[4] * x * (4.0 * z * z - r2),
        (3, 2) => C3[5] * z * (x * x - y * y),
        (3, 3) => C3[6] * x * (x * x - 3.0 * y * y),
        _ => unreachable!("band {l} order {m}"),
    }
}

/// The colour of SH coefficients of `degree` seen along `dir` (camera centre → Gaussian):
/// `dc` weighs band 0 and `rest[k]` the k-th function after it, bands in order and orders
/// −l…l within a band (the Inria `f_rest` order); the sum plus 0.5, clamped below at 0.
fn reference_color(dc: [f32; 3], rest: &[[f32; 3]], degree: usize, dir: Vec3) -> [f32; 3] {
    let d = dir.as_dvec3().normalize();
    let mut sum = dc.map(|c| f64::from(c) * real_sh(0, 0, d.x, d.y, d.z));
    let mut k = 0;
    for l in 1..=degree {
        for m in -(l as isize)..=(l as isize) {
            let y = real_sh(l, m, d.x, d.y, d.z);
            for (s, c) in sum.iter_mut().zip(rest[k]) {
                *s += f64::from(c) * y;
            }
            k += 1;
        }
    }
    sum.map(|s| (s + 0.5).max(0.0) as f32)
}

fn reference_project(g: &Gaussian, degree: u8, cam: &Camera) -> Option<RefSplat> {
    let d = g.position - cam.position;
    let axes = [
        cam.rotation.x_axis,
        cam.rotation.y_axis,
        cam.rotation.z_axis,
    ];
    let t = [d.dot(axes[0]), d.dot(axes[1]), d.dot(axes[2])];
    if t[2] < cam.near || t[2] > cam.far {
        return None;
    }
    // Σ = R S² Rᵀ, element by element.
    let r = rotation_matrix(g.rotation);
    let s = g.log_scale.exp().to_array();
    let mut sigma = [[0.0f32; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            sigma[i][j] = (0..3).map(|k| r[i][k] * s[k] * s[k] * r[j][k]).sum();
        }
    }
    let lim_x = 1.3 * (cam.intrinsics.width as f32 / 2.0) / cam.intrinsics.fx;
    let lim_y = 1.3 * (cam.intrinsics.height as f32 / 2.0) / cam.intrinsics.fy;
    let tx = (t[0] / t[2]).clamp(-lim_x, lim_x) * t[2];
    let ty = (t[1] / t[2]).clamp(-lim_y, lim_y) * t[2];
    let jac = [
        [
            cam.intrinsics.fx / t[2],
            0.0,
            -cam.intrinsics.fx * tx / (t[2] * t[2]),
        ],
        [
            0.0,
            cam.intrinsics.fy / t[2],
            -cam.intrinsics.fy * ty / (t[2] * t[2]),
        ],
    ];
    // M = J · W, W the world→camera rotation (rows = camera axes).
    let mut m = [[0.0f32; 3]; 2];
    for i in 0..2 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| jac[i][k] * axes[k][j]).sum();
        }
    }
    let mut cov = [[0.0f32; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            cov[i][j] = (0..3)
                .map(|k| (0..3).map(|l| m[i][k] * sigma[k][l] * m[j][l]).sum::<f32>())
                .sum();
        }
    }
    cov[0][0] += 0.3;
    cov[1][1] += 0.3;
    let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
    if det <= 0.0 {
        return None;
    }
    let inv = [
        [cov[1][1] / det, -cov[0][1] / det],
        [-cov[1][0] / det, cov[0][0] / det],
    ];
    let dir = g.position - cam.position;
    Some(RefSplat {
        mean: (
            cam.intrinsics.fx * t[0] / t[2] + cam.intrinsics.cx,
            cam.intrinsics.fy * t[1] / t[2] + cam.intrinsics.cy,
        ),
        inv,
        opacity: 1.0 / (1.0 + (-g.opacity_logit).exp()),
        color: reference_color(g.sh_dc, &g.sh_rest, usize::from(degree), dir),
        depth: t[2],
        instance: g.instance,
    })
}

struct Reference {
    rgb: Vec<f32>,
    depth: Vec<f32>,
    median: Vec<f32>,
    alpha: Vec<f32>,
    instance: Vec<u32>,
}

fn reference_render(gs: &Gaussians, cam: &Camera, bg: [f32; 3]) -> Reference {
    let splats: Vec<RefSplat> = (0..gs.len())
        .filter_map(|i| reference_project(&gs.get(i), gs.sh_degree(), cam))
        .collect();
    let (w, h) = (
        cam.intrinsics.width as usize,
        cam.intrinsics.height as usize,
    );
    let mut out = Reference {
        rgb: vec![0.0; w * h * 3],
        depth: vec![0.0; w * h],
        median: vec![0.0; w * h],
        alpha: vec![0.0; w * h],
        instance: vec![0; w * h],
    };
    for py in 0..h {
        for px in 0..w {
            let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
            let mut hits: Vec<(f32, usize, f32)> = Vec::new();
            for (i, s) in splats.iter().enumerate() {
                let (dx, dy) = (s.mean.0 - cx, s.mean.1 - cy);
                let power =
                    -0.5 * (s.inv[0][0] * dx * dx + s.inv[1][1] * dy * dy) - s.inv[0][1] * dx * dy;
                if power > 0.0 {
                    continue;
                }
                let alpha = (s.opacity * power.exp()).min(0.99);
                if alpha >= 1.0 / 255.0 {
                    hits.push((s.depth, i, alpha));
                }
            }
            hits.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let (mut t, mut c, mut wz, mut ws, mut best) =
                (1.0f32, [0.0f32; 3], 0.0f32, 0.0f32, 0.0f32);
            let p = py * w + px;
            for (depth, i, alpha) in hits {
                let next = t * (1.0 - alpha);
                if next < 1e-4 {
                    break;
                }
                let wgt = alpha * t;
                for (acc, col) in c.iter_mut().zip(splats[i].color) {
                    *acc += wgt * col;
                }
                wz += wgt * depth;
                ws += wgt;
                if t > 0.5 && next <= 0.5 {
                    out.median[p] = depth;
                }
                if wgt > best {
                    best = wgt;
                    out.instance[p] = splats[i].instance;
                }
                t = next;
            }
            for k in 0..3 {
                out.rgb[p * 3 + k] = c[k] + t * bg[k];
            }
            out.alpha[p] = 1.0 - t;
            out.depth[p] = if ws > 0.0 { wz / ws } else { 0.0 };
        }
    }
    out
}

/// Compares the renderer with the reference; returns the PSNR.
fn compare(gs: &Gaussians, cam: &Camera, what: &str) -> f64 {
    let bg = [0.1, 0.2, 0.3];
    let fast = Renderer::new(gs)
        .render(
            gs,
            &[],
            cam,
            &RenderOptions {
                background: bg,
                ..RenderOptions::default()
            },
        )
        .unwrap();
    let slow = reference_render(gs, cam, bg);
    let p = psnr(&fast.rgb_f32, &slow.rgb);
    assert!(p >= 40.0, "{what}: PSNR {p:.1} dB");
    let mut checked = 0;
    for i in 0..fast.alpha.len() {
        if fast.alpha[i] > 0.5 && slow.alpha[i] > 0.5 {
            checked += 1;
            assert!(
                (fast.depth_expected[i] - slow.depth[i]).abs() < 0.01,
                "{what}: pixel {i}: expected depth {} vs {}",
                fast.depth_expected[i],
                slow.depth[i]
            );
        }
    }
    let same_median = (0..fast.alpha.len())
        .filter(|&i| (fast.depth_median[i] - slow.median[i]).abs() < 0.01)
        .count();
    assert!(
        same_median as f64 >= 0.99 * fast.alpha.len() as f64,
        "{what}: median depth agrees on {same_median}"
    );
    let same_instance = fast
        .instance
        .iter()
        .zip(&slow.instance)
        .filter(|(a, b)| a == b)
        .count();
    assert!(
        same_instance as f64 >= 0.99 * fast.instance.len() as f64,
        "{what}: instance agrees on {same_instance}"
    );
    assert!(
        checked > 0 || what.contains("sparse"),
        "{what}: nothing opaque to compare"
    );
    p
}

#[test]
fn the_reference_sh_agrees_with_the_renderers_sh() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut directions = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    while directions.len() < 200 {
        let d = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if d.length() > 0.1 {
            directions.push(d.normalize());
        }
    }
    for degree in 0..=3u8 {
        let k = sh_rest_count(degree);
        for &d in &directions {
            let dc = [0.0; 3].map(|_: f32| rng.random_range(-1.5..1.5));
            let rest: Vec<[f32; 3]> = (0..k)
                .map(|_| [0.0; 3].map(|_: f32| rng.random_range(-1.0..1.0)))
                .collect();
            let fast = sh::color(dc, &rest, d);
            let slow = reference_color(dc, &rest, usize::from(degree), d);
            for c in 0..3 {
                assert!(
                    (fast[c] - slow[c]).abs() <= 1e-5 * (1.0 + slow[c].abs()),
                    "degree {degree}, direction {d}, channel {c}: {} vs {}",
                    fast[c],
                    slow[c]
                );
            }
        }
    }
}

#[test]
fn random_scenes_match_the_reference() {
    for (seed, degree) in [(1, 0), (2, 1), (5, 2), (3, 3)] {
        let g = random_gaussians(seed, 3000, degree, 1.5);
        let cam = camera(72, 56, Vec3::new(0.0, 0.0, 1.2), 0.05, -0.1);
        compare(&g, &cam, &format!("random seed {seed} degree {degree}"));
    }
}

#[test]
fn a_synthetic_room_matches_the_reference() {
    let scene = home(4, 2, 16, 25_000);
    let room = &scene.floorplan.rooms[0].profile;
    let c = room.centroid();
    for yaw in [0.3f32, 2.0, -2.4] {
        let cam = camera(64, 48, Vec3::new(c.x, c.y, 1.2), yaw, -0.15);
        compare(&scene.gaussians, &cam, &format!("synthetic room yaw {yaw}"));
    }
}

#[test]
fn edge_cases_match_the_reference() {
    let cam = camera(64, 48, Vec3::new(0.0, 0.0, 1.0), 0.0, 0.0);
    let mut g = Gaussians::new(1).unwrap();
    let mut base = Gaussian {
        opacity_logit: 3.0,
        sh_dc: [0.8, -0.2, 0.1],
        ..Gaussian::default()
    };
    base.sh_rest[..3].copy_from_slice(&[[0.4, -0.3, 0.2], [-0.2, 0.5, 0.1], [0.3, 0.1, -0.4]]);
    // Behind the camera, straddling the near plane (centre just in front of and just behind it).
    for (x, s) in [(-1.0, -1.0), (0.11, -1.5), (0.09, -1.5), (0.3, -3.0)] {
        g.push(&Gaussian {
            position: Vec3::new(x, 0.02, 1.0),
            log_scale: Vec3::splat(s),
            ..base
        });
    }
    // Huge, tiny, elongated.
    g.push(&Gaussian {
        position: Vec3::new(8.0, 1.0, 1.5),
        log_scale: Vec3::new(1.6, 1.6, 0.2),
        opacity_logit: 0.5,
        ..base
    });
    g.push(&Gaussian {
        position: Vec3::new(2.0, 0.1, 1.0),
        log_scale: Vec3::splat(-9.0),
        ..base
    });
    g.push(&Gaussian {
        position: Vec3::new(3.0, -0.5, 0.8),
        log_scale: Vec3::new(-4.0, 0.8, -4.0),
        rotation: Quat::from_rotation_x(0.7),
        ..base
    });
    // Centres exactly on tile borders (x = 16, 32 px and y = 16 px at depth 2 m).
    for px in [16.0f32, 32.0, 48.0] {
        let d = 2.0;
        let y_world = -(px - 32.0) / cam.intrinsics.fx * d;
        g.push(&Gaussian {
            position: Vec3::new(d, y_world, 1.0 - (16.0 - 24.0) / cam.intrinsics.fy * d),
            log_scale: Vec3::splat(-3.5),
            ..base
        });
    }
    compare(&g, &cam, "edge cases (sparse)");
}

#[test]
fn same_image_for_any_thread_count() {
    let scene = home(8, 3, 20, 40_000);
    let c = scene.floorplan.rooms[1].profile.centroid();
    let cam = camera(96, 80, Vec3::new(c.x, c.y, 1.2), 1.0, 0.0);
    let render = |threads: usize| -> RenderOutput {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            Renderer::new(&scene.gaussians)
                .render(
                    &scene.gaussians,
                    &scene.instances.category_ids,
                    &cam,
                    &RenderOptions::default(),
                )
                .unwrap()
        })
    };
    let one = render(1);
    assert_eq!(one, render(2));
    assert_eq!(one, render(3));
    assert!(one.semantic.iter().any(|&c| c != 0));
}

#[test]
fn semantic_ids_follow_the_instance_table() {
    let scene = home(2, 2, 12, 20_000);
    let c = scene.floorplan.rooms[0].profile.centroid();
    let cam = camera(48, 48, Vec3::new(c.x, c.y, 1.2), 0.5, -0.3);
    let out = Renderer::new(&scene.gaussians)
        .render(
            &scene.gaussians,
            &scene.instances.category_ids,
            &cam,
            &RenderOptions::default(),
        )
        .unwrap();
    for (i, &inst) in out.instance.iter().enumerate() {
        assert_eq!(out.semantic[i], scene.instances.category_ids[inst as usize]);
    }
    // Looking down from 1.2 m, most of the picture is floor, walls or objects, never "none".
    assert!(out.instance.iter().filter(|&&i| i != 0).count() > out.instance.len() * 9 / 10);
    let _ = Mat3::IDENTITY;
}

#[test]
fn each_image_asked_for_alone_equals_the_full_render() {
    let scene = home(3, 2, 12, 20_000);
    let c = scene.floorplan.rooms[0].profile.centroid();
    // A width that is not a whole number of tiles: the last band of each image is short.
    let cam = camera(50, 37, Vec3::new(c.x, c.y, 1.2), 2.0, -0.2);
    let mut renderer = Renderer::new(&scene.gaussians);
    let mut render = |channels: Channels| {
        let options = RenderOptions {
            channels,
            ..RenderOptions::default()
        };
        let categories = &scene.instances.category_ids;
        renderer
            .render(&scene.gaussians, categories, &cam, &options)
            .unwrap()
    };
    let full = render(Channels::ALL);
    assert!(full.semantic.iter().any(|&c| c != 0) && !full.rgb.is_empty());
    let names = "rgb rgb_f32 alpha depth_expected depth_median instance semantic none";
    let sets = names
        .split(' ')
        .chain(["rgb,depth_median", "instance,semantic"]);
    for set in sets {
        let channels: Channels = set.parse().unwrap();
        let part = render(channels);
        assert!(part == full.clone().keep(&channels), "{set}");
        assert_eq!((part.width, part.height), (50, 37), "{set}");
    }
}
