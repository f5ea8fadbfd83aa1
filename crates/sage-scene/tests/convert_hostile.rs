//! Hostile input to `splat convert` and the 3DGS readers: a value that is not finite is refused
//! by every conversion exactly as the scene loaders refuse it (same message, naming the input,
//! the Gaussian and the field) and nothing is written; a compressed PLY's non-finite chunk
//! bound is named; truncated SOG and `.splat` files and `.splat` records holding a NaN say what
//! is wrong instead of "not a 3DGS file"; a directory is called one. Inputs are copies of the
//! files in `testdata/splats` (written by PlayCanvas `splat-transform`) with one value changed.

use glam::Vec3;
use sage_scene::splats::convert::{ConvertOptions, convert};
use sage_scene::splats::{self, Format, SplatTable};
use sage_scene::{Gaussian, SplatLayout, ply};
use std::path::{Path, PathBuf};

fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name)
}

fn read(name: &str) -> Vec<u8> {
    let p = testdata(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The byte where a binary PLY's data starts, and the names of the properties of its first
/// element (all 4-byte in the files used here).
fn ply_layout(bytes: &[u8]) -> (usize, Vec<String>) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("a PLY header")
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let mut names = Vec::new();
    let mut elements = 0;
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", ..] => elements += 1,
            ["property", "float" | "uint", name] if elements == 1 => names.push(name.to_string()),
            _ => {}
        }
    }
    (end, names)
}

/// Sets property `name` of row `row` of the first element of a binary little-endian PLY whose
/// first element's properties are all 4 bytes wide.
fn poke(bytes: &mut [u8], row: usize, name: &str, value: f32) {
    let (start, names) = ply_layout(bytes);
    let col = names.iter().position(|n| n == name).expect(name);
    let at = start + (row * names.len() + col) * 4;
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

/// The names of the files in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The output names of every writable format.
const OUTPUTS: [&str; 4] = [
    "out.ply",
    "out.compressed.ply",
    "out_compressed.ply",
    "out.spz",
];

/// Converts `input` to every writable format and asserts that each fails with `expected` (the
/// whole message) and writes nothing at all, temporary files included.
fn assert_every_conversion_refuses(input: &Path, expected: &str) {
    let dir = input.parent().unwrap();
    let before = listing(dir);
    for out in OUTPUTS {
        let e = convert(input, &dir.join(out), ConvertOptions::default())
            .expect_err(out)
            .to_string();
        assert_eq!(e, expected, "{out}");
        assert_eq!(listing(dir), before, "{out}: something was written");
    }
}

#[test]
fn a_non_finite_value_is_refused_by_every_conversion_as_the_loader_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bad.ply");
    for (row, property, value, field) in [
        (5, "x", f32::NAN, "position"),
        (7, "scale_1", f32::INFINITY, "scale"),
        (11, "opacity", f32::NAN, "opacity"),
        (13, "f_dc_2", f32::NEG_INFINITY, "f_dc"),
        (2999, "z", f32::NEG_INFINITY, "position"),
    ] {
        let mut bytes = read("random_3k_sh0.ply");
        poke(&mut bytes, row, property, value);
        std::fs::write(&input, &bytes).unwrap();
        let expected = format!(
            "{}: vertex[{row}].{field}: value is not finite (NaN or infinity)",
            input.display()
        );
        // The scene loaders' message, which the conversion must repeat.
        let loaded = splats::read_gaussians_file(&input).unwrap_err().to_string();
        assert_eq!(loaded, expected);
        let table = splats::read_table_file(&input).unwrap_err().to_string();
        assert_eq!(table, expected);
        assert_every_conversion_refuses(&input, &expected);
    }
    // Unchanged, the same file converts to every format.
    std::fs::copy(testdata("random_3k_sh0.ply"), &input).unwrap();
    for out in OUTPUTS {
        let report = convert(&input, &dir.path().join(out), ConvertOptions::default()).unwrap();
        assert_eq!(report.gaussians, 3000, "{out}");
    }
}

#[test]
fn non_finite_rotations_and_higher_sh_are_refused_by_every_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bad_sh3.ply");
    for (row, property, value, field, why) in [
        (
            9,
            "rot_2",
            f32::NAN,
            "rot_*",
            "rotation is not finite or is zero",
        ),
        (
            4000,
            "f_rest_44",
            f32::INFINITY,
            "f_rest_*",
            "value is not finite (NaN or infinity)",
        ),
    ] {
        let mut bytes = read("random_4k_sh3.ply");
        poke(&mut bytes, row, property, value);
        std::fs::write(&input, &bytes).unwrap();
        let expected = format!("{}: vertex[{row}].{field}: {why}", input.display());
        let loaded = splats::read_gaussians_file(&input).unwrap_err().to_string();
        assert_eq!(loaded, expected);
        assert_every_conversion_refuses(&input, &expected);
    }
}

#[test]
fn a_stray_position_is_refused_and_extreme_finite_values_convert() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("stray.ply");
    // One Gaussian 10³⁰ m away would stretch its compressed chunk's quantisation over that
    // distance and collapse the other 255 of the chunk onto two points.
    let mut bytes = read("random_3k_sh0.ply");
    poke(&mut bytes, 1009, "y", 1e30);
    std::fs::write(&input, &bytes).unwrap();
    let loaded = splats::read_gaussians_file(&input).unwrap_err().to_string();
    assert!(
        loaded.starts_with(&format!("{}: vertex[1009].position: ", input.display()))
            && loaded.contains("beyond ±10⁷ m"),
        "{loaded}"
    );
    assert_every_conversion_refuses(&input, &loaded);
    // A rotation of tiny components normalises (its squared length underflows in f32), a huge
    // one too, and a colour beyond f16 saturates: each loads and converts to every format.
    let input = dir.path().join("extreme.ply");
    let mut bytes = read("random_3k_sh0.ply");
    for (row, scale) in [(3, 1e-30), (4, 1e30)] {
        for (k, v) in [1.0, 0.0, 0.0, 0.0].into_iter().enumerate() {
            poke(&mut bytes, row, &format!("rot_{k}"), v * scale);
        }
    }
    poke(&mut bytes, 5, "f_dc_0", 1e5);
    std::fs::write(&input, &bytes).unwrap();
    let g = splats::read_gaussians_file(&input).unwrap().0;
    for row in [3, 4] {
        let q = g.get(row).rotation;
        assert!((q.w.abs() - 1.0).abs() < 1e-4, "row {row}: {q}");
    }
    assert_eq!(g.get(5).sh_dc[0], 65504.0);
    for out in OUTPUTS {
        let report = convert(&input, &dir.path().join(out), ConvertOptions::default()).unwrap();
        assert_eq!(report.gaussians, 3000, "{out}");
    }
}

/// `n` plain Gaussians spread along x.
fn plain_table(n: usize) -> SplatTable {
    SplatTable {
        gaussians: (0..n)
            .map(|i| Gaussian {
                position: Vec3::new(i as f32 * 0.01, 1.0, -2.0),
                sh_dc: [0.1, -0.2, 0.3],
                ..Gaussian::default()
            })
            .collect(),
        sh_degree: 0,
    }
}

#[test]
fn the_gaussian_named_is_the_files_first_bad_one_in_any_block() {
    // Past the first decoding block (4096 Gaussians), with two bad ones in different blocks:
    // the message names the first, whichever thread finds which.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("big.ply");
    let mut table = plain_table(10_000);
    table.gaussians[9000].position.y = f32::NAN;
    table.gaussians[5000].log_scale.z = f32::INFINITY;
    // The standard writer writes every value as it is, the bad ones too.
    splats::write_file(&input, &table, Format::Ply(SplatLayout::Standard)).unwrap();
    let expected = format!(
        "{}: vertex[5000].scale: value is not finite (NaN or infinity)",
        input.display()
    );
    assert_eq!(
        splats::read_gaussians_file(&input).unwrap_err().to_string(),
        expected
    );
    assert_every_conversion_refuses(&input, &expected);
    table.gaussians[5000].log_scale.z = 0.0;
    splats::write_file(&input, &table, Format::Ply(SplatLayout::Standard)).unwrap();
    assert_every_conversion_refuses(
        &input,
        &format!(
            "{}: vertex[9000].position: value is not finite (NaN or infinity)",
            input.display()
        ),
    );
}

/// A change to one Gaussian.
type Edit = fn(&mut Gaussian);

#[test]
fn the_quantising_writers_refuse_what_they_cannot_encode() {
    // Called directly, with a table nobody checked: a NaN is not written as its chunk's
    // minimum (compressed PLY) or as some byte (SPZ).
    let dir = tempfile::tempdir().unwrap();
    for (format, name) in [
        (Format::Ply(SplatLayout::Compressed), "w.compressed.ply"),
        (Format::Spz, "w.spz"),
    ] {
        let edits: [(Edit, &str); 4] = [
            (|g| g.position.x = f32::NAN, "position"),
            (|g| g.log_scale.y = f32::NAN, "scale"),
            (|g| g.opacity_logit = f32::NAN, "opacity"),
            (|g| g.sh_dc[1] = f32::INFINITY, "f_dc"),
        ];
        for (edit, field) in edits {
            let mut table = plain_table(1000);
            edit(&mut table.gaussians[300]);
            let out = dir.path().join(name);
            let e = splats::write_file(&out, &table, format)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!(
                    "vertex[300].{field}: value is not finite (NaN or infinity)"
                )),
                "{name}: {e}"
            );
            assert!(!out.exists(), "{name}");
        }
    }
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn a_non_finite_chunk_bound_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bad.compressed.ply");
    for (chunk, property) in [(3, "min_y"), (11, "max_scale_z"), (0, "max_b")] {
        for value in [f32::NAN, f32::INFINITY] {
            let mut bytes = read("random_3k_sh0.compressed.ply");
            poke(&mut bytes, chunk, property, value);
            std::fs::write(&input, &bytes).unwrap();
            let expected = format!(
                "{}: chunk[{chunk}].{property}: value is not finite (NaN or infinity)",
                input.display()
            );
            assert_eq!(
                splats::read_gaussians_file(&input).unwrap_err().to_string(),
                expected
            );
            assert_eq!(
                ply::read_splats_file(&input).unwrap_err().to_string(),
                expected
            );
            assert_every_conversion_refuses(&input, &expected);
        }
    }
    // Finite bounds whose range overflows decode to infinities: the Gaussians are named.
    let mut bytes = read("random_3k_sh0.compressed.ply");
    poke(&mut bytes, 2, "min_x", -3e38);
    poke(&mut bytes, 2, "max_x", 3e38);
    std::fs::write(&input, &bytes).unwrap();
    let expected = format!(
        "{}: vertex[512].position: value is not finite (NaN or infinity)",
        input.display()
    );
    assert_eq!(
        splats::read_gaussians_file(&input).unwrap_err().to_string(),
        expected
    );
    assert_every_conversion_refuses(&input, &expected);
}

#[test]
fn a_truncated_sog_says_truncated() {
    let dir = tempfile::tempdir().unwrap();
    let whole = read("random_3k_sh0.sog");
    // Named or not: the zip signature says what the file means to be.
    for name in ["cut.sog", "cut.bin"] {
        for keep in [30_000, whole.len() - 1, 100] {
            let input = dir.path().join(name);
            std::fs::write(&input, &whole[..keep]).unwrap();
            let e = splats::read_table_file(&input).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("{}: zip: truncated", input.display()))
                    && e.contains(&format!("its {keep} bytes")),
                "{name}, {keep} bytes: {e}"
            );
            assert!(!e.contains("not a 3DGS file"), "{e}");
            assert_eq!(
                splats::read_gaussians_file(&input).unwrap_err().to_string(),
                e
            );
            assert_every_conversion_refuses(&input, &e);
            std::fs::remove_file(&input).unwrap();
        }
    }
}

/// A `.splat` of `table` as antimatter15's `convert.py` writes it.
fn splat_bytes(table: &SplatTable) -> Vec<u8> {
    let byte = |v: f32| v.clamp(0.0, 255.0) as u8;
    let mut out = Vec::new();
    for g in &table.gaussians {
        for v in g.position.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in g.log_scale.to_array() {
            out.extend_from_slice(&v.exp().to_le_bytes());
        }
        for c in g.base_color() {
            out.push(byte(c * 255.0));
        }
        out.push(byte(g.opacity() * 255.0));
        let q = g.rotation.normalize();
        for v in [q.w, q.x, q.y, q.z] {
            out.push(byte(v * 128.0 + 128.0));
        }
    }
    out
}

#[test]
fn damaged_splat_files_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let (table, _) = splats::read_table_file(&testdata("random_3k_sh0.ply")).unwrap();
    let whole = splat_bytes(&table);
    assert_eq!(whole.len(), 3000 * 32);
    // Whole, it is detected from its content under any name.
    for name in ["ok.splat", "ok.bin"] {
        let p = dir.path().join(name);
        std::fs::write(&p, &whole).unwrap();
        let (read, format) = splats::read_table_file(&p).unwrap();
        assert_eq!(
            (read.gaussians.len(), format),
            (3000, Format::Splat),
            "{name}"
        );
        std::fs::remove_file(&p).unwrap();
    }

    // Truncated: expected and actual sizes.
    let input = dir.path().join("cut.splat");
    std::fs::write(&input, &whole[..30_000]).unwrap();
    let e = splats::read_table_file(&input).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: file length: truncated", input.display()))
            && e.contains("expected 30016 bytes for 938 records, got 30000"),
        "{e}"
    );
    assert_eq!(
        splats::read_gaussians_file(&input).unwrap_err().to_string(),
        e
    );
    assert_every_conversion_refuses(&input, &e);
    std::fs::remove_file(&input).unwrap();

    // A NaN in a leading record (which detection looks at) or a later one: the record and
    // field, with the decoder's own message either way.
    let input = dir.path().join("nan.splat");
    for (record, at) in [(2usize, 0usize), (7, 8), (100, 4)] {
        let mut bytes = whole.clone();
        bytes[record * 32 + at..record * 32 + at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&input, &bytes).unwrap();
        let expected = format!(
            "{}: record[{record}].position: is not finite (NaN or infinity)",
            input.display()
        );
        assert_eq!(
            splats::read_table_file(&input).unwrap_err().to_string(),
            expected
        );
        assert_eq!(
            splats::read_gaussians_file(&input).unwrap_err().to_string(),
            expected
        );
        assert_every_conversion_refuses(&input, &expected);
    }
    std::fs::remove_file(&input).unwrap();

    // A leading record that decodes but is no Gaussian (rotation bytes of no unit quaternion).
    let input = dir.path().join("odd.splat");
    let mut bytes = whole.clone();
    bytes[3 * 32 + 28..3 * 32 + 32].copy_from_slice(&[128; 4]);
    bytes[3 * 32 + 28] = 250;
    bytes[3 * 32 + 29] = 250;
    std::fs::write(&input, &bytes).unwrap();
    let e = splats::read_table_file(&input).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: record[3].rotation:", input.display()))
            && e.contains("not a .splat record"),
        "{e}"
    );

    // Without the name, nothing says the file means to be a .splat: what was tried.
    let input = dir.path().join("cut.bin");
    std::fs::write(&input, &whole[..30_000]).unwrap();
    let e = splats::read_table_file(&input).unwrap_err().to_string();
    assert!(e.contains("not a 3DGS file sage3d reads"), "{e}");
}

#[test]
fn other_damaged_files_named_for_their_format_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, want) in [
        ("empty.splat", Vec::new(), "file: empty (0 bytes)"),
        (
            "x.ply",
            b"hello, world\n".to_vec(),
            "header: does not start with 'ply'",
        ),
        ("x.gltf", b"hello, world\n".to_vec(), ""),
        ("x.spz", b"hello, world\n".to_vec(), ""),
    ] {
        let input = dir.path().join(name);
        std::fs::write(&input, &bytes).unwrap();
        let e = splats::read_table_file(&input).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}: {want}", input.display())),
            "{name}: {e}"
        );
        assert!(!e.contains("not a 3DGS file"), "{name}: {e}");
    }
}

#[test]
fn a_directory_is_called_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("scene.ply");
    std::fs::create_dir(&input).unwrap();
    let expected = format!(
        "{}: a directory, not a file: give the 3DGS file itself",
        input.display()
    );
    let out = dir.path().join("y.ply");
    let e = convert(&input, &out, ConvertOptions::default())
        .unwrap_err()
        .to_string();
    assert_eq!(e, expected);
    assert!(!out.exists());
    assert_eq!(
        splats::read_gaussians_file(&input).unwrap_err().to_string(),
        expected
    );
    assert_eq!(
        splats::read_table_file(&input).unwrap_err().to_string(),
        expected
    );
    assert_eq!(
        ply::read_splats_file(&input).unwrap_err().to_string(),
        expected
    );
}
