//! The backward pass against central finite differences of the forward pass, for every
//! parameter of every Gaussian of tiny scenes (SH degree 0 and 1, a coloured background,
//! overlapping and saturating splats, one Gaussian beyond the Jacobian clamp).
//!
//! The forward pass is only piecewise smooth: a pixel drops a splat below alpha 1/255 and stops
//! before transmittance 1e-4. A difference is compared only when the set of splats blended at
//! every pixel is the same at both ends of the step (the step is shrunk a few times before a
//! sample is given up); most samples must be compared.

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sage_splat::{Camera, Intrinsics};
use sage_train::backward::backward;
use sage_train::forward::{Frame, forward};
use sage_train::params::{Param, Params};

fn camera() -> Camera {
    Camera::from_yaw_pitch(
        Intrinsics::from_hfov(24, 20, 70.0).unwrap(),
        Vec3::new(0.0, 0.0, 1.0),
        0.1,
        -0.05,
    )
}

/// A few Gaussians 1.5–3 m in front of the camera, overlapping on screen.
fn scene(seed: u64, n: usize, sh_degree: u8) -> Params {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let cam = camera();
    let mut rows = Vec::new();
    for _ in 0..n {
        let ahead = cam.position
            + cam.rotation.z_axis * rng.random_range(1.5..3.0)
            + cam.rotation.x_axis * rng.random_range(-0.4..0.4)
            + cam.rotation.y_axis * rng.random_range(-0.3..0.3);
        let q = Quat::from_xyzw(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.5..1.0),
        );
        rows.push(Param {
            mean: ahead.to_array(),
            log_scale: std::array::from_fn(|_| rng.random_range(-2.6..-1.6)),
            // Deliberately not unit length: the normalisation is differentiated too.
            rotation: [q.w, q.x, q.y, q.z].map(|v| v * 1.3),
            opacity_logit: rng.random_range(-0.5..2.5),
            sh_dc: std::array::from_fn(|_| rng.random_range(-0.5..1.2)),
            sh_rest: if sh_degree >= 1 {
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-0.3..0.3)))
            } else {
                [[0.0; 3]; 3]
            },
        });
    }
    Params {
        sh_degree,
        instances: vec![0; rows.len()],
        rows,
    }
}

/// Per pixel, the splats (Gaussian indices) blended, front to back.
fn active_set(frame: &Frame) -> Vec<Vec<u32>> {
    let g = frame.grid;
    let mut out = vec![Vec::new(); g.width * g.height];
    for t in 0..g.tiles_x * g.tiles_y {
        let list = &frame.lists[frame.tile_start[t] as usize..frame.tile_start[t + 1] as usize];
        for (x, y) in g.tile_pixels(t) {
            let p = y * g.width + x;
            for &s in &list[..frame.last[p] as usize] {
                let sp = &frame.splats[s as usize];
                if sp.alpha_at(x as f32 + 0.5, y as f32 + 0.5).is_some() {
                    out[p].push(sp.index);
                }
            }
        }
    }
    out
}

/// The linear loss Σ wᵢ·rgbᵢ (accumulated in f64) and the frame's active set.
fn evaluate(params: &Params, cam: &Camera, weights: &[f32], bg: [f32; 3]) -> (f64, Vec<Vec<u32>>) {
    let frame = forward(params, cam, bg);
    let value = frame
        .rgb
        .iter()
        .zip(weights)
        .map(|(c, w)| *c as f64 * *w as f64)
        .sum();
    (value, active_set(&frame))
}

const KINDS: [(&str, std::ops::Range<usize>); 6] = [
    ("mean", 0..3),
    ("log_scale", 3..6),
    ("rotation", 6..10),
    ("opacity_logit", 10..11),
    ("sh_dc", 11..14),
    ("sh_rest", 14..23),
];

fn check(seed: u64, params: &Params, bg: [f32; 3]) {
    let cam = camera();
    let frame = forward(params, &cam, bg);
    assert!(
        frame.final_t.iter().any(|&t| t < 0.5),
        "the scene should cover part of the image"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let weights: Vec<f32> = (0..frame.rgb.len())
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let grads = backward(params, &cam, &frame, &weights);
    let (mut compared, mut skipped) = (0, 0);
    for (i, g) in grads.params.iter().enumerate() {
        let analytic: &[f32; Param::LEN] = bytemuck::cast_ref(g);
        for (kind, range) in KINDS.iter() {
            if *kind == "sh_rest" && params.sh_degree == 0 {
                assert!(analytic[range.clone()].iter().all(|&v| v == 0.0));
                continue;
            }
            for k in range.clone() {
                let mut eps = 1e-3f32;
                let mut done = false;
                for _ in 0..4 {
                    let at = |d: f32| {
                        let mut p = params.clone();
                        let row: &mut [f32; Param::LEN] = bytemuck::cast_mut(&mut p.rows[i]);
                        row[k] += d;
                        evaluate(&p, &cam, &weights, bg)
                    };
                    let ((plus, set_plus), (minus, set_minus)) = (at(eps), at(-eps));
                    if set_plus != set_minus {
                        eps *= 0.25;
                        continue;
                    }
                    let fd = ((plus - minus) / (2.0 * eps as f64)) as f32;
                    let a = analytic[k];
                    // f32 noise of the forward pass, divided by the step.
                    let noise = 4e-6 / eps;
                    assert!(
                        (fd - a).abs() <= 0.02 * a.abs().max(fd.abs()) + noise,
                        "Gaussian {i} {kind}[{}]: analytic {a} vs finite difference {fd} (step {eps})",
                        k - range.start
                    );
                    done = true;
                    break;
                }
                if done {
                    compared += 1;
                } else {
                    skipped += 1;
                }
            }
        }
    }
    assert!(
        skipped * 10 <= compared,
        "only {compared} of {} parameters could be compared",
        compared + skipped
    );
}

#[test]
fn gradients_match_finite_differences_at_sh_degree_0() {
    check(1, &scene(1, 5, 0), [0.0; 3]);
}

#[test]
fn gradients_match_finite_differences_at_sh_degree_1_over_a_background() {
    check(2, &scene(2, 6, 1), [0.2, 0.5, 0.9]);
}

#[test]
fn gradients_match_finite_differences_where_pixels_saturate_and_slopes_clamp() {
    let mut params = scene(3, 6, 1);
    // Opaque splats stacked on the same spot: pixels reach the transmittance floor.
    let cam = camera();
    for (k, row) in params.rows.iter_mut().enumerate() {
        row.mean = (cam.position + cam.rotation.z_axis * (1.5 + 0.2 * k as f32)).to_array();
        row.opacity_logit = 4.0 + k as f32 * 0.1;
        row.log_scale = [-1.8; 3];
    }
    // A large Gaussian beyond the Jacobian clamp (x/z > 1.3 tan(hfov/2)) reaching into view.
    let side = cam.position + cam.rotation.z_axis * 1.0 + cam.rotation.x_axis * 1.2;
    params.rows.push(Param {
        mean: side.to_array(),
        log_scale: [-0.4, -0.6, -0.5],
        rotation: [1.0, 0.1, 0.0, 0.0],
        opacity_logit: 0.5,
        sh_dc: [0.8, 0.1, -0.3],
        sh_rest: [[0.1; 3]; 3],
    });
    params.instances.push(0);
    check(3, &params, [0.1, 0.1, 0.1]);
}
