//! Mutation fuzzing of the PLY readers: real files with flipped bytes, truncations and edited
//! header lines must give an `Err` or a valid result — never a panic, never an abort.
//! Run longer with `PROPTEST_CASES=100000 cargo test --release -p sage-scene --test ply_fuzz`.

use proptest::prelude::*;
use sage_scene::{mesh, ply};
use std::path::PathBuf;

fn testdata(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/splats")
        .join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

const FILES: [&str; 3] = [
    "random_3k_sh0.compressed.ply",
    "random_3k_sh0.decompressed.ply",
    "random_4k_sh3.compressed.ply",
];

/// One edit of a file.
#[derive(Debug, Clone)]
enum Mutation {
    Flip { at: usize, byte: u8 },
    Truncate { keep: usize },
    HeaderNumber { line: usize, value: u64 },
    HeaderDropLine { line: usize },
    HeaderSwap { a: usize, b: usize },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Flip { at, byte }),
        any::<usize>().prop_map(|keep| Mutation::Truncate { keep }),
        (
            any::<usize>(),
            prop_oneof![
                0u64..10,
                Just(u32::MAX as u64),
                Just(u64::MAX),
                0u64..100_000
            ]
        )
            .prop_map(|(line, value)| Mutation::HeaderNumber { line, value }),
        any::<usize>().prop_map(|line| Mutation::HeaderDropLine { line }),
        (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::HeaderSwap { a, b }),
    ]
}

fn split_header(bytes: &[u8]) -> (Vec<String>, Vec<u8>) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .map_or(bytes.len(), |p| p + 11);
    let header = String::from_utf8_lossy(&bytes[..end])
        .lines()
        .map(str::to_string)
        .collect();
    (header, bytes[end..].to_vec())
}

fn edit_header(bytes: &[u8], line: usize, edit: impl FnOnce(&mut Vec<String>, usize)) -> Vec<u8> {
    let (mut header, body) = split_header(bytes);
    let i = line % header.len();
    edit(&mut header, i);
    let mut out = (header.join("\n") + "\n").into_bytes();
    out.extend_from_slice(&body);
    out
}

fn apply(bytes: &[u8], m: &Mutation) -> Vec<u8> {
    match *m {
        Mutation::Flip { at, byte } => {
            let mut out = bytes.to_vec();
            let i = at % out.len();
            out[i] = byte;
            out
        }
        Mutation::Truncate { keep } => bytes[..keep % (bytes.len() + 1)].to_vec(),
        Mutation::HeaderNumber { line, value } => edit_header(bytes, line, |h, i| {
            let mut words: Vec<String> = h[i].split(' ').map(str::to_string).collect();
            if let Some(last) = words.last_mut() {
                *last = value.to_string();
            }
            h[i] = words.join(" ");
        }),
        Mutation::HeaderDropLine { line } => edit_header(bytes, line, |h, i| {
            h.remove(i);
        }),
        Mutation::HeaderSwap { a, b } => edit_header(bytes, a, |h, i| {
            let j = b % h.len();
            h.swap(i, j);
        }),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_files_never_panic(file in 0usize..FILES.len(), edits in prop::collection::vec(mutation(), 1..4)) {
        let mut bytes = testdata(FILES[file]);
        for m in &edits {
            bytes = apply(&bytes, m);
        }
        match ply::read_splats(&bytes) {
            Ok((g, _)) => prop_assert!(g.validate().is_ok()),
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
        let _ = mesh::read_ply(&bytes);
    }

    #[test]
    fn random_bytes_after_a_plausible_header_never_panic(body in prop::collection::vec(any::<u8>(), 0..2000), n in 0usize..50, ascii in any::<bool>()) {
        let format = if ascii { "ascii" } else { "binary_little_endian" };
        let mut bytes = format!("ply\nformat {format} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty float opacity\nelement face {n}\nproperty list uchar int vertex_indices\nend_header\n").into_bytes();
        bytes.extend_from_slice(&body);
        let _ = ply::read_splats(&bytes);
        let _ = mesh::read_ply(&bytes);
    }
}

#[test]
fn specific_bad_inputs_name_the_field() {
    let good = testdata("random_3k_sh0.decompressed.ply");
    let edit = |from: &str, to: &str| {
        let end = good.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let header = String::from_utf8_lossy(&good[..end]).replacen(from, to, 1);
        let mut bytes = header.into_bytes();
        bytes.extend_from_slice(&good[end..]);
        ply::read_splats(&bytes).unwrap_err().to_string()
    };
    assert_eq!(
        edit("property float opacity", "property float opacitx"),
        "vertex.opacity: missing property"
    );
    assert!(
        edit("element vertex 3000", "element vertex 3001")
            .contains("element 'vertex': file is truncated")
    );
    let body_start = good.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let mut bytes = good.clone();
    bytes[body_start..body_start + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = ply::read_splats(&bytes).unwrap_err().to_string();
    assert_eq!(
        e,
        "vertex[0].position: value is not finite (NaN or infinity)"
    );
}
