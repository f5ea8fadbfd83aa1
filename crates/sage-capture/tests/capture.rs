//! Synthetic scenes made into captures — turned Y-up and tilted, scaled, moved, with floaters
//! added and every annotation dropped — and aligned back: the floor, the free space and the
//! floaters are checked against the scene they came from.

use glam::{Quat, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_capture::transform::{self, Similarity};
use sage_capture::{CaptureSettings, Scale, Up, align};
use sage_nav::GridParams;
use sage_nav::grid::NavGrid;
use sage_nav::splat_grid::{SplatGridParams, gaussian_grid};
use sage_scene::Gaussians;
use sage_scene::gaussians::{Gaussian, opacity_to_logit};
use sage_scene::occupancy::FREE;
use sage_synth::{SceneKind, SynthConfig, generate};
use std::collections::HashSet;

/// A capture of a synthetic scene: its Gaussians moved by `to_capture` (W → capture), with
/// `floaters` isolated faint Gaussians added after the real ones.
struct Capture {
    gaussians: Gaussians,
    real: usize,
    truth: NavGrid,
}

fn make_capture(seed: u64, to_capture: &Similarity, floaters: usize) -> Capture {
    let scene = generate(&SynthConfig {
        seed,
        kind: SceneKind::Home,
        rooms: 3,
        objects: 25,
        gaussians: 60_000,
        ..SynthConfig::default()
    })
    .unwrap();
    let (truth, _) = NavGrid::from_scene(&scene, &GridParams::default()).unwrap();
    let mut g = scene.gaussians.clone();
    let real = g.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xf10a7);
    // A trained scene's surfaces are not exact planes: jitter every centre by up to 1 cm.
    for p in &mut g.positions {
        for v in p.iter_mut() {
            *v += rng.random_range(-0.01..0.01);
        }
    }
    // Floaters: faint, random, and isolated by construction (no real Gaussian within 15 cm).
    let b = g.bounds();
    let occupied: HashSet<[i32; 3]> = g
        .positions
        .iter()
        .map(|p| (Vec3::from_array(*p) / 0.15).floor().as_ivec3().to_array())
        .collect();
    let near = |p: Vec3| {
        let k = (p / 0.15).floor().as_ivec3();
        (-1..=1).any(|dz| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| occupied.contains(&(k + glam::IVec3::new(dx, dy, dz)).to_array()))
            })
        })
    };
    let mut added = 0;
    while added < floaters {
        let p = Vec3::new(
            rng.random_range(b.min.x..b.max.x),
            rng.random_range(b.min.y..b.max.y),
            rng.random_range(0.2..b.max.z),
        );
        if near(p) {
            continue;
        }
        let mut sh_rest = [[0.0; 3]; 15];
        sh_rest[1] = [rng.random_range(-0.3..0.3), 0.1, -0.1];
        g.push(&Gaussian {
            position: p,
            rotation: Quat::from_rotation_z(rng.random_range(0.0..6.0)),
            log_scale: Vec3::splat(rng.random_range(-4.0..-1.5)),
            opacity_logit: opacity_to_logit(rng.random_range(0.005..0.1)),
            sh_dc: [0.3, 0.2, 0.1],
            sh_rest,
            instance: 0,
        });
        added += 1;
    }
    let all = transform::all(&g);
    Capture {
        gaussians: transform::transform(&g, &all, to_capture).unwrap(),
        real,
        truth,
    }
}

/// Free-space intersection over union of `b` (in W') against `a` (in W), `w_to_b` mapping W
/// to W', compared at `a`'s cell centres.
fn free_iou(a: &NavGrid, b: &NavGrid, w_to_b: &Similarity) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for k in 0..a.cells.len() {
        let fa = a.cells[k] == FREE;
        let q = w_to_b.apply(a.center_of(k).extend(0.0)).truncate();
        let fb = b
            .cell_at(q)
            .is_some_and(|(i, j)| b.cells[b.index(i, j)] == FREE);
        both += usize::from(fa && fb);
        either += usize::from(fa || fb);
    }
    both as f64 / either.max(1) as f64
}

/// A W → capture map: Z up turned to Y up (`y_up`; to −Y, COLMAP's camera axes, with a
/// negative `tilt_deg`'s sign flipped), then tilted by `tilt_deg` about a
/// horizontal axis of the capture, units of `1 / metres_per_unit` metres, and moved.
fn to_capture(up: &str, tilt_deg: f32, metres_per_unit: f32, yaw: f32) -> Similarity {
    let turn = match up {
        "y" => Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        "-y" => Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
        _ => Quat::IDENTITY,
    };
    let tilt = Quat::from_axis_angle(Vec3::new(1.0, 0.0, 1.0).normalize(), tilt_deg.to_radians());
    Similarity {
        scale: 1.0 / metres_per_unit,
        rotation: (tilt * turn * Quat::from_rotation_z(yaw)).normalize(),
        translation: Vec3::new(3.0, -1.5, 7.25),
    }
}

#[test]
fn captures_align_back_onto_their_floor_with_their_free_space_and_without_floaters() {
    let cases = [
        // (seed, up axis, tilt°, metres per unit, yaw, scale given as)
        (1, "y", 4.0, 2.0, 0.3, "factor"),
        (2, "z", 3.0, 0.5, -0.6, "points"),
        (3, "-y", 7.0, 1.0, 1.0, "none"),
    ];
    for (seed, up_axis, tilt, mpu, yaw, how) in cases {
        let c2 = to_capture(up_axis, tilt, mpu, yaw);
        let floaters = 1500;
        let cap = make_capture(seed, &c2, floaters);
        let scale = match how {
            "none" => Scale::None,
            "factor" => Scale::Given { value: mpu },
            _ => {
                // Two points 2.5 m apart in W, given in capture coordinates.
                let (a, b) = (Vec3::new(1.0, 1.0, 0.0), Vec3::new(3.5, 1.0, 0.0));
                Scale::Points {
                    a: c2.apply(a),
                    b: c2.apply(b),
                    distance: 2.5,
                }
            }
        };
        let settings = CaptureSettings {
            scale,
            ..CaptureSettings::default()
        };
        let out = align(&cap.gaussians, &settings).unwrap();
        // W → capture → W': a turn about Z and a shift in x and y, if all went well.
        let back = c2.then(&out.transform);
        let up = back.rotation * Vec3::Z;
        let tilt_err = up.angle_between(Vec3::Z).to_degrees();
        let b = cap.truth.origin;
        let s = cap.truth.size();
        let corners = [b, b + Vec2::new(s.x, 0.0), b + s, b + Vec2::new(0.0, s.y)];
        let height_err = corners
            .iter()
            .map(|p| back.apply(p.extend(0.0)).z.abs())
            .fold(0.0f32, f32::max);
        let removed_floaters = (cap.real..cap.real + floaters)
            .filter(|&i| !out.kept.contains(&(i as u32)))
            .count();
        let kept: HashSet<u32> = out.kept.iter().copied().collect();
        let lost_real = (0..cap.real)
            .filter(|&i| !kept.contains(&(i as u32)))
            .count();
        let grid = gaussian_grid(
            &out.gaussians,
            0.05,
            (0.03, 1.2),
            0.5,
            &SplatGridParams::default(),
        )
        .unwrap();
        let iou = free_iou(&cap.truth, &grid, &back);
        println!(
            "seed {seed} ({up_axis} up, tilt {tilt} deg, {mpu} m/unit by {how}): floor tilt error {tilt_err:.3} deg, \
             height error {:.1} mm over the scene, scale error {:.2e}, floaters removed {removed_floaters}/{floaters} \
             ({:.1} %), real lost {lost_real}/{} ({:.3} %), free-space IoU {iou:.3}; fit: tilt {:.2} deg, area {:.1} m2, rms {:.1} mm, yaw {:.1} deg",
            height_err * 1000.0,
            (back.scale - 1.0).abs(),
            100.0 * removed_floaters as f64 / floaters as f64,
            cap.real,
            100.0 * lost_real as f64 / cap.real as f64,
            out.floor.tilt_deg,
            out.floor.area,
            out.floor.rms * 1000.0,
            out.floor.yaw.to_degrees(),
        );
        assert!(tilt_err <= 1.0, "seed {seed}: up off by {tilt_err} deg");
        assert!(
            height_err <= 0.02,
            "seed {seed}: floor off by {height_err} m"
        );
        assert!(
            (back.scale - 1.0).abs() < 1e-3,
            "seed {seed}: scale {}",
            back.scale
        );
        assert!(
            removed_floaters * 100 >= floaters * 95,
            "seed {seed}: {removed_floaters}"
        );
        assert!(
            lost_real * 100 < cap.real,
            "seed {seed}: {lost_real} real Gaussians lost"
        );
        assert!(iou >= 0.85, "seed {seed}: free-space IoU {iou}");
        assert_eq!(out.floaters, removed_floaters + lost_real);
    }
}

#[test]
fn a_named_up_axis_is_followed_and_a_cloud_without_floor_is_refused() {
    let c2 = to_capture("y", 2.0, 1.0, 0.0);
    let cap = make_capture(4, &c2, 0);
    let settings = CaptureSettings {
        floor: sage_capture::FloorSettings {
            up: Up::Y,
            ..Default::default()
        },
        ..CaptureSettings::default()
    };
    let out = align(&cap.gaussians, &settings).unwrap();
    let up = c2.then(&out.transform).rotation * Vec3::Z;
    assert!(up.angle_between(Vec3::Z).to_degrees() < 1.0);

    // A ball of round, opaque Gaussians: no surface, no floor.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut ball = Gaussians::new(0).unwrap();
    for _ in 0..5000 {
        ball.push(&Gaussian {
            position: Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ),
            log_scale: Vec3::splat(-3.0),
            opacity_logit: 3.0,
            ..Gaussian::default()
        });
    }
    let e = align(&ball, &CaptureSettings::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no floor found"), "{e}");
}

/// The capture of a synthetic home (seed `seed`) by `to_capture`, keeping only the Gaussians
/// below `cut` metres in W (a ceiling cut away, as handheld captures often miss it).
fn cut_capture(seed: u64, to_capture: &Similarity, cut: f32) -> Gaussians {
    let scene = generate(&SynthConfig {
        seed,
        kind: SceneKind::Home,
        rooms: 3,
        objects: 25,
        gaussians: 60_000,
        ..SynthConfig::default()
    })
    .unwrap();
    let g = &scene.gaussians;
    let keep: Vec<u32> = (0..g.len() as u32)
        .filter(|&i| g.positions[i as usize][2] < cut)
        .collect();
    transform::transform(g, &keep, to_capture).unwrap()
}

#[test]
fn a_capture_without_its_ceiling_keeps_its_floor_and_up_and_records_no_ceiling() {
    let wall = SynthConfig::default().wall_height;
    for (seed, up_axis, tilt, yaw) in [(1, "y", 4.0, 0.3), (2, "z", 3.0, -0.6), (5, "-y", 6.0, 1.0)]
    {
        let c2 = to_capture(up_axis, tilt, 0.5, yaw);
        let settings = |up: Up| CaptureSettings {
            scale: Scale::Given { value: 0.5 },
            floor: sage_capture::FloorSettings {
                up,
                ..Default::default()
            },
            ..CaptureSettings::default()
        };
        let whole = align(&cut_capture(seed, &c2, f32::INFINITY), &settings(Up::Auto)).unwrap();
        assert!(
            (whole.floor.ceiling - wall).abs() < 0.05,
            "seed {seed}: ceiling {}",
            whole.floor.ceiling
        );
        let named = match up_axis {
            "y" => Up::Y,
            "-y" => Up::NegY,
            _ => Up::Z,
        };
        // The ceiling plane cut away (walls kept to full height), and the top of the rooms.
        for cut in [wall - 0.1, 2.0] {
            let capture = cut_capture(seed, &c2, cut);
            for up in [Up::Auto, named] {
                let out = align(&capture, &settings(up)).unwrap();
                let turned = c2.then(&out.transform).rotation * Vec3::Z;
                let tilt_err = turned.angle_between(Vec3::Z).to_degrees();
                let same_up = out.floor.up.angle_between(whole.floor.up).to_degrees();
                println!(
                    "seed {seed} ({up_axis} up), cut at {cut} m, --up {up}: up off by {tilt_err:.3} deg \
                     ({same_up:.3} deg from the whole capture's), floor {:.4} vs {:.4}, ceiling {}, \
                     highest plane {:.2} m ({:.1} m2 of {:.1}), side {:?}, lower share {:.2}",
                    out.floor.offset,
                    whole.floor.offset,
                    out.floor.ceiling,
                    out.floor.top_plane,
                    out.floor.top_plane_area,
                    out.floor.area,
                    out.floor.side,
                    out.floor.lower_share,
                );
                assert!(
                    tilt_err < 1.0,
                    "seed {seed}, cut {cut}, {up}: upside down or tilted by {tilt_err} deg"
                );
                assert!(same_up < 0.5, "seed {seed}, cut {cut}, {up}: {same_up} deg");
                assert!(
                    (out.floor.offset - whole.floor.offset).abs() < 0.01,
                    "seed {seed}, cut {cut}, {up}: floor at {} instead of {}",
                    out.floor.offset,
                    whole.floor.offset
                );
                assert_eq!(out.floor.ceiling, 0.0, "seed {seed}, cut {cut}, {up}");
                assert!(!out.floor.side_doubtful, "seed {seed}, cut {cut}, {up}");
            }
        }
    }
}

#[test]
fn a_named_up_axis_upside_down_is_doubted() {
    let c2 = to_capture("y", 2.0, 1.0, 0.0);
    let cap = make_capture(4, &c2, 0);
    for (up, doubtful) in [(Up::Y, false), (Up::NegY, true)] {
        let settings = CaptureSettings {
            floor: sage_capture::FloorSettings {
                up,
                ..Default::default()
            },
            ..CaptureSettings::default()
        };
        let out = align(&cap.gaussians, &settings).unwrap();
        assert_eq!(out.floor.side_doubtful, doubtful, "{up}: {:?}", out.floor);
    }
}

#[test]
fn a_capture_far_from_the_origin_is_brought_back_and_one_too_large_refused() {
    // A capture kept in a georeferenced frame: 20 km east, 5 km below its frame's origin.
    let far = Similarity {
        scale: 1.0,
        rotation: Quat::IDENTITY,
        translation: Vec3::new(20_000.0, 0.0, -5_000.0),
    };
    let cap = make_capture(6, &far, 0);
    let out = align(&cap.gaussians, &CaptureSettings::default()).unwrap();
    let shift = out.recentred.expect("moved back to the origin");
    assert!(
        (shift[0] + 20_000.0).abs() < 20.0 && shift[1].abs() < 20.0,
        "{shift:?}"
    );
    assert_eq!(shift.map(f32::fract), [0.0, 0.0], "whole metres");
    let b = out.gaussians.bounds();
    assert!(b.min.abs().max(b.max.abs()).max_element() < 50.0, "{b:?}");
    // The recorded transform is the one applied.
    let back = far.then(&out.transform);
    let p = back.apply(Vec3::new(1.0, 2.0, 0.0));
    assert!(p.z.abs() < 0.02 && p.x.abs() < 50.0, "{p}");

    // Near the origin nothing moves: existing imports stay as they were.
    let near = make_capture(6, &Similarity::IDENTITY, 0);
    assert_eq!(
        align(&near.gaussians, &CaptureSettings::default())
            .unwrap()
            .recentred,
        None
    );

    // Two far stray Gaussians 30 km apart: no shift brings both within ±10 km.
    let mut g = near.gaussians.clone();
    for x in [-15_000.0, 15_000.0] {
        g.push(&Gaussian {
            position: Vec3::new(x, 0.0, 1.0),
            log_scale: Vec3::splat(-3.0),
            opacity_logit: 3.0,
            ..Gaussian::default()
        });
    }
    let e = align(&g, &CaptureSettings::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("10000") && e.contains("-15000..15000"), "{e}");
}
