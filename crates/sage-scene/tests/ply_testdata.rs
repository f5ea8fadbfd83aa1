//! Checks the PLY readers and writers against files made by PlayCanvas `splat-transform`
//! (`testdata/splats/`, see its README).

use glam::Vec3;
use sage_scene::gaussians::{Gaussian, Gaussians, LOG_SCALE_STEP, SH_C0, sh_rest_count};
use sage_scene::ply::{self, SplatLayout, compressed::CHUNK};
use std::path::PathBuf;

fn testdata(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn read(name: &str) -> (Gaussians, SplatLayout) {
    ply::read_splats(&testdata(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

fn max_abs_rest(g: &Gaussian) -> f32 {
    g.sh_rest
        .iter()
        .flatten()
        .fold(0.0f32, |m, v| m.max(v.abs()))
}

/// Our decoding of `X.compressed.ply` must equal the tool's own decoding, Gaussian by Gaussian.
fn compressed_matches_tool_decoding(stem: &str, degree: u8) {
    let (ours, layout) = read(&format!("{stem}.compressed.ply"));
    let (tool, tool_layout) = read(&format!("{stem}.decompressed.ply"));
    assert_eq!(layout, SplatLayout::Compressed);
    assert_eq!(tool_layout, SplatLayout::Standard);
    assert_eq!(ours.len(), tool.len());
    assert_eq!(ours.sh_degree(), degree);
    assert_eq!(tool.sh_degree(), degree);
    for i in 0..ours.len() {
        let (a, b) = (ours.get(i), tool.get(i));
        assert!(
            (a.position - b.position).abs().max_element() < 1e-5,
            "{i}: position {a:?} vs {b:?}"
        );
        assert!(
            // Both sides are rounded to the store's log-scale step.
            (a.log_scale - b.log_scale).abs().max_element() < 1e-4 + LOG_SCALE_STEP,
            "{i}: scale"
        );
        assert!(
            a.rotation.normalize().dot(b.rotation.normalize()).abs() > 1.0 - 1e-6,
            "{i}: rotation {:?} vs {:?}",
            a.rotation,
            b.rotation
        );
        assert!(
            (sigmoid(a.opacity_logit) - sigmoid(b.opacity_logit)).abs() < 1.0 / 255.0,
            "{i}: opacity"
        );
        for c in 0..3 {
            assert!(
                (a.sh_dc[c] - b.sh_dc[c]).abs() < 2e-3,
                "{i}: f_dc {c}: {} vs {}",
                a.sh_dc[c],
                b.sh_dc[c]
            );
        }
        let tol = max_abs_rest(&b) / 127.0 + 1e-6;
        for (x, y) in a.sh_rest.iter().flatten().zip(b.sh_rest.iter().flatten()) {
            assert!((x - y).abs() <= tol, "{i}: f_rest {x} vs {y}");
        }
    }
}

#[test]
fn compressed_sh3_matches_splat_transform() {
    compressed_matches_tool_decoding("random_4k_sh3", 3);
}

#[test]
fn compressed_sh0_matches_splat_transform() {
    compressed_matches_tool_decoding("random_3k_sh0", 0);
}

/// Our compressed writer, read back by our reader, stays within one quantisation step of the
/// source, each Gaussian of its chunk in the writer's order.
fn writer_within_quantisation_error(stem: &str) {
    let (src, _) = read(&format!("{stem}.ply"));
    let mut bytes = Vec::new();
    ply::compressed::write(&mut bytes, &src).unwrap();
    let (back, layout) = ply::read_splats(&bytes).unwrap();
    assert_eq!(layout, SplatLayout::Compressed);
    assert_eq!(back.len(), src.len());
    assert_eq!(back.sh_degree(), src.sh_degree());
    let order = ply::compressed::write_order(&src);
    let at = |j: usize| order.as_ref().map_or(j, |o| o[j] as usize);
    let k = sh_rest_count(src.sh_degree());
    for c in 0..src.len().div_ceil(CHUNK) {
        let items: Vec<Gaussian> = (c * CHUNK..((c + 1) * CHUNK).min(src.len()))
            .map(|j| src.get(at(j)))
            .collect();
        let extent = |f: &dyn Fn(&Gaussian) -> Vec3| {
            let lo = items.iter().map(f).fold(Vec3::INFINITY, Vec3::min);
            let hi = items.iter().map(f).fold(Vec3::NEG_INFINITY, Vec3::max);
            hi - lo
        };
        let pos_step = extent(&|g| g.position) / Vec3::new(2047.0, 1023.0, 2047.0);
        let scale_step = extent(&|g| g.log_scale) / Vec3::new(2047.0, 1023.0, 2047.0);
        let color_step = extent(&|g| Vec3::from_array(g.base_color())) / 255.0;
        for (j, a) in items.iter().enumerate() {
            let i = c * CHUNK + j;
            let b = back.get(i);
            assert!(
                ((a.position - b.position).abs() - pos_step * 0.5).max_element() < 1e-5,
                "{i}: position"
            );
            assert!(
                ((a.log_scale - b.log_scale).abs() - scale_step * 0.5).max_element()
                    < 1e-4 + LOG_SCALE_STEP,
                "{i}: scale"
            );
            assert!(
                a.rotation.normalize().dot(b.rotation.normalize()).abs() > 1.0 - 2e-6,
                "{i}: rotation {:?} vs {:?}",
                a.rotation,
                b.rotation
            );
            assert!(
                (a.opacity() - b.opacity()).abs() <= 0.5 / 255.0 + 1e-4,
                "{i}: opacity"
            );
            let dc_err = (Vec3::from_array(a.sh_dc) - Vec3::from_array(b.sh_dc)).abs() * SH_C0;
            assert!(
                (dc_err - color_step * 0.5).max_element() < 2e-3,
                "{i}: colour"
            );
            let tol = 4.0 / 256.0 + max_abs_rest(a) / 127.0 + 1e-5;
            for (x, y) in a.sh_rest[..k]
                .iter()
                .flatten()
                .zip(b.sh_rest[..k].iter().flatten())
            {
                assert!((x - y).abs() <= tol, "{i}: f_rest {x} vs {y}");
            }
        }
    }
}

#[test]
fn compressed_writer_sh3_within_quantisation_error() {
    writer_within_quantisation_error("random_4k_sh3");
}

#[test]
fn compressed_writer_sh0_within_quantisation_error() {
    writer_within_quantisation_error("random_3k_sh0");
}

#[test]
fn standard_round_trip_keeps_order_and_values() {
    let (src, _) = read("random_4k_sh3.ply");
    let mut bytes = Vec::new();
    ply::standard::write(&mut bytes, &src).unwrap();
    let (back, layout) = ply::read_splats(&bytes).unwrap();
    assert_eq!(layout, SplatLayout::Standard);
    for i in 0..src.len() {
        let (a, b) = (src.get(i), back.get(i));
        assert_eq!(a.position, b.position);
        assert_eq!(a.log_scale, b.log_scale);
        assert_eq!(a.opacity_logit, b.opacity_logit);
        assert_eq!(a.sh_dc, b.sh_dc);
        assert!(a.rotation.normalize().dot(b.rotation.normalize()) > 1.0 - 1e-6);
        let tol = max_abs_rest(&a) / 127.0 + 1e-6;
        for (x, y) in a.sh_rest.iter().flatten().zip(b.sh_rest.iter().flatten()) {
            assert!((x - y).abs() <= tol);
        }
    }
}

#[test]
fn compressed_round_trip_is_stable() {
    // Decoding then re-encoding a compressed file must reproduce the same Gaussians.
    let (a, _) = read("random_4k_sh3.compressed.ply");
    let mut bytes = Vec::new();
    ply::compressed::write(&mut bytes, &a).unwrap();
    let (b, _) = ply::read_splats(&bytes).unwrap();
    for i in 0..a.len() {
        let (x, y) = (a.get(i), b.get(i));
        assert!((x.position - y.position).abs().max_element() < 1e-4, "{i}");
        assert!((x.opacity() - y.opacity()).abs() < 1e-6, "{i}: opacity");
    }
}
