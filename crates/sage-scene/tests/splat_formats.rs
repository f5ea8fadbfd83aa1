//! Every 3DGS format through the one door (`sage_scene::splats`): each reader against the
//! reference tool's own decoding of the same file (`testdata/splats`, written by PlayCanvas
//! `splat-transform`), format detection from content, lossless conversion, writer round trips,
//! scene folders holding any format, and no panic on damaged files.

use proptest::prelude::*;
use sage_scene::splats::convert::{ConvertOptions, convert};
use sage_scene::splats::{self, Format, SplatTable};
use sage_scene::{Gaussian, Scene, SplatLayout};
use std::path::{Path, PathBuf};

fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name)
}

fn table(name: &str) -> (SplatTable, Format) {
    splats::read_table_file(&testdata(name)).unwrap()
}

/// The largest differences between two tables, field by field: position, log-scale, opacity
/// (after the sigmoid: 8-bit formats keep alpha, whose logit is loose near 0 and 1), f_dc,
/// higher SH, rotation (normalised, up to sign). Relative to 1 + |value|.
fn max_errors(a: &SplatTable, b: &SplatTable) -> [f32; 6] {
    assert_eq!(a.gaussians.len(), b.gaussians.len(), "Gaussian counts");
    assert_eq!(a.sh_degree, b.sh_degree, "SH degrees");
    let mut m = [0f32; 6];
    let max = |m: &mut f32, x: f32, y: f32| *m = m.max((x - y).abs() / (1.0 + y.abs()));
    for (x, y) in a.gaussians.iter().zip(&b.gaussians) {
        for c in 0..3 {
            max(&mut m[0], x.position[c], y.position[c]);
            max(&mut m[1], x.log_scale[c], y.log_scale[c]);
            max(&mut m[3], x.sh_dc[c], y.sh_dc[c]);
        }
        max(&mut m[2], x.opacity(), y.opacity());
        for (p, q) in x.sh_rest.iter().flatten().zip(y.sh_rest.iter().flatten()) {
            max(&mut m[4], *p, *q);
        }
        let (p, q) = (x.rotation.normalize(), y.rotation.normalize());
        m[5] = m[5].max(1.0 - p.dot(q).abs());
    }
    m
}

#[test]
fn every_reader_matches_the_reference_tools_decoding() {
    for (file, reference, format) in [
        (
            "random_4k_sh3.compressed.ply",
            "random_4k_sh3.decompressed.ply",
            Format::Ply(SplatLayout::Compressed),
        ),
        (
            "random_3k_sh0.compressed.ply",
            "random_3k_sh0.decompressed.ply",
            Format::Ply(SplatLayout::Compressed),
        ),
        (
            "random_4k_sh3.spz",
            "random_4k_sh3.spz.decoded.ply",
            Format::Spz,
        ),
        (
            "random_3k_sh0.spz",
            "random_3k_sh0.spz.decoded.ply",
            Format::Spz,
        ),
        (
            "random_3k_sh0.sog",
            "random_3k_sh0.sog.decoded.ply",
            Format::Sog,
        ),
        // The tool does not read GLB back: its input PLY is the reference.
        ("random_4k_sh3.glb", "random_4k_sh3.ply", Format::Gltf),
        ("random_3k_sh0.glb", "random_3k_sh0.ply", Format::Gltf),
    ] {
        let (ours, detected) = table(file);
        assert_eq!(detected, format, "{file}");
        let (theirs, _) = table(reference);
        let m = max_errors(&ours, &theirs);
        // Float rounding: the tool computes in float32 (JavaScript) or float64.
        assert!(m.iter().all(|e| *e <= 2e-5), "{file}: max errors {m:?}");
    }
}

#[test]
fn formats_are_told_from_content_not_names() {
    let dir = tempfile::tempdir().unwrap();
    for (file, format) in [
        ("random_4k_sh3.ply", Format::Ply(SplatLayout::Standard)),
        (
            "random_4k_sh3.compressed.ply",
            Format::Ply(SplatLayout::Compressed),
        ),
        ("random_4k_sh3.spz", Format::Spz),
        ("random_3k_sh0.sog", Format::Sog),
        ("random_4k_sh3.glb", Format::Gltf),
    ] {
        let misnamed = dir.path().join("gaussians.bin");
        std::fs::copy(testdata(file), &misnamed).unwrap();
        let (_, detected) = splats::read_table_file(&misnamed).unwrap();
        assert_eq!(detected, format, "{file}");
    }
    std::fs::write(dir.path().join("x.bin"), b"hello, world\n").unwrap();
    let e = splats::read_table_file(&dir.path().join("x.bin"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x.bin") && e.contains("tried PLY, SPZ, SOG"),
        "{e}"
    );
}

#[test]
fn compressed_to_standard_is_lossless() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["random_4k_sh3", "random_3k_sh0"] {
        let out = dir.path().join(format!("{name}.ply"));
        let report = convert(
            &testdata(&format!("{name}.compressed.ply")),
            &out,
            ConvertOptions::default(),
        )
        .unwrap();
        assert!(report.losses.is_empty(), "{:?}", report.losses);
        // Exactly our decoding of the compressed file, and so within float rounding of the
        // tool's (the test above): no value passed through the compact store.
        let (written, format) = splats::read_table_file(&out).unwrap();
        assert_eq!(format, Format::Ply(SplatLayout::Standard));
        let (decoded, _) = table(&format!("{name}.compressed.ply"));
        assert_eq!(written, decoded, "{name}");
        let (theirs, _) = table(&format!("{name}.decompressed.ply"));
        let m = max_errors(&written, &theirs);
        assert!(
            m[4] == 0.0,
            "{name}: SH differs from the tool's by {}",
            m[4]
        );
    }
}

#[test]
fn writers_round_trip_within_their_quantisation() {
    let dir = tempfile::tempdir().unwrap();
    let (source, _) = table("random_4k_sh3.ply");
    for (name, format, tolerance) in [
        ("a.ply", Format::Ply(SplatLayout::Standard), 1e-6),
        (
            "a.compressed.ply",
            Format::Ply(SplatLayout::Compressed),
            0.3,
        ),
        ("a.spz", Format::Spz, 0.3),
    ] {
        let path = dir.path().join(name);
        splats::write_file(&path, &source, format).unwrap();
        let (back, detected) = splats::read_table_file(&path).unwrap();
        assert_eq!(detected, format);
        if format == Format::Ply(SplatLayout::Standard) {
            assert_eq!(back, source, "standard PLY holds every value");
        }
        let written = match format {
            Format::Ply(SplatLayout::Compressed) => in_write_order(&source),
            _ => source.clone(),
        };
        let m = max_errors(&back, &written);
        assert!(m.iter().all(|e| *e <= tolerance), "{name}: {m:?}");
        // Writing what was read loses nothing more (at most float rounding of the bounds).
        let again = dir.path().join(format!("again-{name}"));
        splats::write_file(&again, &back, format).unwrap();
        let (back2, _) = splats::read_table_file(&again).unwrap();
        let m = max_errors(&back2, &back);
        assert!(
            m.iter().all(|e| *e <= tolerance.min(1e-4)),
            "{name} again: {m:?}"
        );
    }
}

#[test]
fn a_decompressed_or_uncompressed_name_is_written_as_a_standard_ply() {
    // `splat-transform` names its decoded output `NAME.decompressed.ply`: converting a
    // compressed file to that name must give the lossless standard layout, not quantise again.
    let dir = tempfile::tempdir().unwrap();
    let input = testdata("random_3k_sh0.compressed.ply");
    let (source, _) = table("random_3k_sh0.compressed.ply");
    for name in ["x.decompressed.ply", "x_uncompressed.ply"] {
        let out = dir.path().join(name);
        let report = convert(&input, &out, ConvertOptions::default()).unwrap();
        assert_eq!(
            report.output_format,
            Format::Ply(SplatLayout::Standard),
            "{name}"
        );
        assert!(report.losses.is_empty(), "{name}: {:?}", report.losses);
        let (back, detected) = splats::read_table_file(&out).unwrap();
        assert_eq!(detected, Format::Ply(SplatLayout::Standard), "{name}");
        assert_eq!(back, source, "{name}: standard PLY holds every value");
    }
    for name in ["x.compressed.ply", "x_compressed.ply"] {
        let out = dir.path().join(name);
        let report = convert(&input, &out, ConvertOptions::default()).unwrap();
        assert_eq!(
            report.output_format,
            Format::Ply(SplatLayout::Compressed),
            "{name}"
        );
        let (_, detected) = splats::read_table_file(&out).unwrap();
        assert_eq!(detected, Format::Ply(SplatLayout::Compressed), "{name}");
    }
}

/// `table` in the order the compressed writer puts it in.
fn in_write_order(table: &SplatTable) -> SplatTable {
    match sage_scene::ply::compressed::write_order(table) {
        Some(order) => SplatTable {
            gaussians: order.iter().map(|&i| table.gaussians[i as usize]).collect(),
            sh_degree: table.sh_degree,
        },
        None => table.clone(),
    }
}

/// The largest distance, along any axis, of a position in `back` from the same Gaussian's in
/// `source` (both in one order).
fn max_position_error(back: &SplatTable, source: &SplatTable) -> f32 {
    back.gaussians
        .iter()
        .zip(&source.gaussians)
        .map(|(a, b)| (a.position - b.position).abs().max_element())
        .fold(0.0, f32::max)
}

#[test]
fn a_loose_order_is_compressed_along_a_z_curve_and_a_compressed_one_kept() {
    let dir = tempfile::tempdir().unwrap();
    // The tool's random scene is in no spatial order, as a trained PLY is: each chunk of 256
    // would span the whole scene.
    let input = testdata("random_4k_sh3.ply");
    let out = dir.path().join("a.compressed.ply");
    let report = convert(&input, &out, ConvertOptions::default()).unwrap();
    assert!(report.reordered);
    assert!(
        report.losses.iter().any(|l| l.contains("Z-order")),
        "{:?}",
        report.losses
    );
    let (source, _) = table("random_4k_sh3.ply");
    let (back, _) = splats::read_table_file(&out).unwrap();
    let ordered = in_write_order(&source);
    let mut seen: Vec<[u32; 3]> = back
        .gaussians
        .iter()
        .zip(&ordered.gaussians)
        .map(|(a, b)| {
            assert!((a.opacity() - b.opacity()).abs() <= 0.5 / 255.0 + 1e-4);
            b.position.to_array().map(f32::to_bits)
        })
        .collect();
    let mut all: Vec<[u32; 3]> = source
        .gaussians
        .iter()
        .map(|g| g.position.to_array().map(f32::to_bits))
        .collect();
    seen.sort_unstable();
    all.sort_unstable();
    assert_eq!(seen, all, "every Gaussian written once");
    // In the source's order every chunk spans the scene, so its 11-10-11 bit steps would be
    // the scene's extent over 2047 / 1023 / 2047 and a position's error a quarter step on
    // average; along the curve a chunk spans a part of the scene (the few straddling one of
    // the curve's large steps excepted), and the errors shrink with it.
    let extent = sage_core::Aabb::from_points(source.gaussians.iter().map(|g| g.position)).size();
    let scene_step = extent / glam::Vec3::new(2047.0, 1023.0, 2047.0);
    let mean_error = back
        .gaussians
        .iter()
        .zip(&ordered.gaussians)
        .map(|(a, b)| ((a.position - b.position).abs() / scene_step).element_sum() / 3.0)
        .sum::<f32>()
        / back.gaussians.len() as f32;
    assert!(mean_error < 0.15, "{mean_error} of a whole-scene step");
    // The tool's compressed file is chunked already: converting it again moves no Gaussian.
    let again = dir.path().join("again.compressed.ply");
    let report = convert(
        &testdata("random_4k_sh3.compressed.ply"),
        &again,
        ConvertOptions::default(),
    )
    .unwrap();
    assert!(!report.reordered, "{:?}", report.losses);
    let (theirs, _) = table("random_4k_sh3.compressed.ply");
    let (ours, _) = splats::read_table_file(&again).unwrap();
    assert!(max_position_error(&ours, &theirs) < 1e-4);
}

#[test]
fn sh_bands_can_be_dropped_not_added() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sh1.ply");
    let report = convert(
        &testdata("random_4k_sh3.ply"),
        &out,
        ConvertOptions {
            sh_degree: Some(1),
            force: false,
        },
    )
    .unwrap();
    assert_eq!((report.sh_degree_in, report.sh_degree_out), (3, 1));
    assert!(
        report.losses[0].contains("SH bands 2–3 dropped"),
        "{:?}",
        report.losses
    );
    let one = splats::convert::losses(splats::Format::Spz, 1, 0);
    assert!(one[0].starts_with("SH band 1 dropped (1 of 4"), "{one:?}");
    let (kept, _) = splats::read_table_file(&out).unwrap();
    let (full, _) = table("random_4k_sh3.ply");
    assert_eq!(kept.sh_degree, 1);
    for (k, f) in kept.gaussians.iter().zip(&full.gaussians) {
        assert_eq!(k.sh_rest[..3], f.sh_rest[..3]);
        assert!(k.sh_rest[3..].iter().flatten().all(|v| *v == 0.0));
    }
    let e = convert(
        &testdata("random_3k_sh0.ply"),
        &dir.path().join("sh2.ply"),
        ConvertOptions {
            sh_degree: Some(2),
            force: false,
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("dropped, not added"), "{e}");
}

#[test]
fn an_spz_of_a_wide_scene_reports_the_coarser_position_step_it_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let positions = |report: &splats::convert::ConvertReport| -> String {
        report
            .losses
            .iter()
            .find(|l| l.starts_with("positions"))
            .cloned()
            .unwrap()
    };
    let input = testdata("random_3k_sh0.ply");
    let report = convert(
        &input,
        &dir.path().join("near.spz"),
        ConvertOptions::default(),
    )
    .unwrap();
    assert_eq!(
        positions(&report),
        "positions quantised to 24-bit fixed point (1/4096 m steps)"
    );
    // One Gaussian 3 km out: 12 fraction bits would overflow 24 bits, so the writer uses 11.
    let (mut wide, _) = table("random_3k_sh0.ply");
    wide.gaussians[17].position.x = 3000.0;
    let wide_ply = dir.path().join("wide.ply");
    splats::write_file(&wide_ply, &wide, Format::Ply(SplatLayout::Standard)).unwrap();
    let out = dir.path().join("wide.spz");
    let report = convert(&wide_ply, &out, ConvertOptions::default()).unwrap();
    assert_eq!(
        positions(&report),
        "positions quantised to 24-bit fixed point (1/2048 m steps: the scene reaches beyond \
         ±2048 m along an axis, where 1/4096 m steps would overflow 24 bits)"
    );
    let bytes = std::fs::read(&out).unwrap();
    let decoder = splats::spz::SpzDecoder::open(&bytes).unwrap();
    assert_eq!(
        decoder.fractional_bits(),
        11,
        "the step reported is the one written"
    );
}

#[test]
fn sh_quantisation_is_reported_only_when_the_output_holds_higher_sh() {
    let compressed = Format::Ply(SplatLayout::Compressed);
    let sh = |losses: &[String]| -> Vec<String> {
        losses
            .iter()
            .filter(|l| l.contains("SH"))
            .cloned()
            .collect()
    };
    // Degree 3 to a compressed PLY of degree 0: the bands are dropped, nothing is quantised.
    let dropped = splats::convert::losses(compressed, 3, 0);
    assert_eq!(
        sh(&dropped),
        ["SH bands 1–3 dropped (1 of 16 coefficients per colour channel kept)"]
    );
    assert!(sh(&splats::convert::losses(compressed, 0, 0)).is_empty());
    assert!(sh(&splats::convert::losses(Format::Spz, 0, 0)).is_empty());
    assert_eq!(
        sh(&splats::convert::losses(compressed, 1, 1)),
        ["higher SH quantised to 8 bits over [-4, 4]"]
    );
    assert_eq!(
        sh(&splats::convert::losses(Format::Spz, 1, 1)),
        ["higher SH quantised to 5 bits per coefficient"]
    );
    assert_eq!(
        sh(&splats::convert::losses(Format::Spz, 3, 2))[1],
        "higher SH quantised to 5 bits (degree 1) and 4 bits (degree 2) per coefficient"
    );
    assert_eq!(
        sh(&splats::convert::losses(Format::Spz, 3, 3)),
        ["higher SH quantised to 5 bits (degree 1) and 4 bits (degrees 2–3) per coefficient"]
    );
}

#[test]
fn convert_never_replaces_a_file_unasked_and_writes_only_what_it_can() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mine.ply");
    std::fs::write(&out, b"precious").unwrap();
    let input = testdata("random_3k_sh0.spz");
    let e = convert(&input, &out, ConvertOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("`force`"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    convert(
        &input,
        &out,
        ConvertOptions {
            sh_degree: None,
            force: true,
        },
    )
    .unwrap();
    assert_eq!(
        splats::read_table_file(&out).unwrap().1,
        Format::Ply(SplatLayout::Standard)
    );
    for name in ["x.sog", "x.glb", "x.splat", "x"] {
        let e = convert(&input, &dir.path().join(name), ConvertOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("NAME.spz"), "{name}: {e}");
        assert!(!dir.path().join(name).exists());
    }
}

#[test]
fn a_scene_folder_may_hold_any_format() {
    let dir = tempfile::tempdir().unwrap();
    for (file, name, format) in [
        ("random_4k_sh3.spz", "3dgs.spz", Format::Spz),
        ("random_3k_sh0.sog", "3dgs.sog", Format::Sog),
        ("random_4k_sh3.glb", "3dgs.glb", Format::Gltf),
        // Content decides: a compressed file under the standard name is read as compressed.
        (
            "random_3k_sh0.compressed.ply",
            "3dgs.ply",
            Format::Ply(SplatLayout::Compressed),
        ),
    ] {
        let scene = dir.path().join(name);
        std::fs::create_dir_all(&scene).unwrap();
        std::fs::copy(testdata(file), scene.join(name)).unwrap();
        let (loaded, report) = Scene::load(&scene).unwrap();
        assert_eq!(report.splat_format, Some(format), "{file}");
        let (t, _) = table(file);
        assert_eq!(loaded.gaussians.len(), t.gaussians.len(), "{file}");
        assert_eq!(loaded.gaussians.sh_degree(), t.sh_degree, "{file}");
    }
}

/// The test files of every format, for the no-panic properties.
fn samples() -> Vec<Vec<u8>> {
    [
        "random_3k_sh0.ply",
        "random_3k_sh0.compressed.ply",
        "random_3k_sh0.spz",
        "random_3k_sh0.sog",
        "random_3k_sh0.glb",
    ]
    .iter()
    .map(|f| std::fs::read(testdata(f)).unwrap())
    .collect()
}

/// Decodes `bytes` through the one door; any outcome but a panic is fine.
fn decode(bytes: &[u8]) -> sage_core::Result<Vec<Gaussian>> {
    let (decoder, _) = splats::open(bytes)?;
    Ok(decoder.to_table()?.gaussians)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn damaged_files_of_any_format_are_errors_not_panics(
        which in 0usize..5,
        cut in 0.0f64..1.0,
        flips in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..8),
    ) {
        let files = samples();
        let mut bytes = files[which].clone();
        for (at, value) in flips {
            let i = ((bytes.len() - 1) as f64 * at) as usize;
            bytes[i] = value;
        }
        let _ = decode(&bytes);
        bytes.truncate((bytes.len() as f64 * cut) as usize);
        let _ = decode(&bytes);
    }
}
