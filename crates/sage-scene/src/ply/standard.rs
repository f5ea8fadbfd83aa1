//! The standard (Inria) 3DGS PLY layout.
//!
//! Properties are matched by name: `x y z`, `f_dc_0..2` (or `red green blue` as a fallback),
//! `f_rest_*` (0, 9, 24 or 45 of them, channel-major), `opacity`, `scale_0..2`, `rot_0..3`
//! (w, x, y, z). Any scalar type is accepted; unknown properties (normals …) are ignored.

use super::header::{Element, Header, Rows, Scalar, element_rows};
use crate::gaussians::{Gaussian, Gaussians, SH_C0, sh_degree_for_rest_len, sh_rest_count};
use crate::splats::{BlockDecoder, SplatSource};
use glam::{Quat, Vec3};
use rayon::prelude::*;
use sage_core::{Error, Result};
use std::io::Write;

/// Where each needed value sits in a row: (byte offset, type) for fixed rows, else property index.
enum Source {
    Offset(usize, Scalar),
    Index(usize),
}

fn locate(e: &Element, fixed: bool, name: &str) -> Option<Source> {
    if fixed {
        e.scalar_offset(name).map(|(o, s)| Source::Offset(o, s))
    } else {
        e.property_index(name).map(Source::Index)
    }
}

/// Colour as `f_dc`, or as 8-bit / float `red green blue`.
enum ColorSource {
    Dc([Source; 3]),
    Rgb([Source; 3], f64),
}

struct Layout {
    position: [Source; 3],
    color: ColorSource,
    rest: Vec<Source>,
    opacity: Source,
    scale: [Source; 3],
    rotation: [Source; 4],
}

fn require(e: &Element, fixed: bool, name: &str) -> Result<Source> {
    locate(e, fixed, name)
        .ok_or_else(|| Error::format(format!("vertex.{name}"), "missing property"))
}

fn layout(e: &Element, fixed: bool) -> Result<(Layout, u8)> {
    let req = |n: &str| require(e, fixed, n);
    let color = if e.property_index("f_dc_0").is_some() {
        ColorSource::Dc([req("f_dc_0")?, req("f_dc_1")?, req("f_dc_2")?])
    } else if let Some(i) = e.property_index("red") {
        let max = if e.properties[i].scalar == Scalar::U8 {
            255.0
        } else {
            1.0
        };
        ColorSource::Rgb([req("red")?, req("green")?, req("blue")?], max)
    } else {
        return Err(Error::format(
            "vertex.f_dc_0",
            "missing property (and no red/green/blue)",
        ));
    };
    let rest_count = e
        .properties
        .iter()
        .filter(|p| p.name.starts_with("f_rest_"))
        .count();
    let degree = sh_degree_for_rest_len(rest_count).ok_or_else(|| {
        Error::format(
            "vertex.f_rest_*",
            format!("found {rest_count} f_rest properties; expected 0, 9, 24 or 45"),
        )
    })?;
    let rest = (0..rest_count)
        .map(|i| req(&format!("f_rest_{i}")))
        .collect::<Result<Vec<_>>>()?;
    Ok((
        Layout {
            position: [req("x")?, req("y")?, req("z")?],
            color,
            rest,
            opacity: req("opacity")?,
            scale: [req("scale_0")?, req("scale_1")?, req("scale_2")?],
            rotation: [req("rot_0")?, req("rot_1")?, req("rot_2")?, req("rot_3")?],
        },
        degree,
    ))
}

/// A standard-layout file opened for decoding (the header has been parsed already).
pub struct StandardDecoder<'a> {
    element: Element,
    rows: Rows<'a>,
    layout: Layout,
    degree: u8,
}

impl<'a> StandardDecoder<'a> {
    /// Locates the vertex rows of `bytes` and the properties the Gaussians need.
    ///
    /// # Errors
    ///
    /// No `vertex` element, a missing property or an SH count that is no degree, naming them.
    pub fn open(header: &Header, bytes: &'a [u8]) -> Result<StandardDecoder<'a>> {
        let (vi, element) = header
            .element("vertex")
            .ok_or_else(|| Error::format("vertex", "missing element"))?;
        let rows = element_rows(header, bytes)?
            .into_iter()
            .nth(vi)
            .ok_or_else(|| Error::format("vertex", "missing rows"))?;
        let (layout, degree) = layout(element, matches!(rows, Rows::Fixed { .. }))?;
        Ok(StandardDecoder {
            element: element.clone(),
            rows,
            layout,
            degree,
        })
    }

    /// The value of `s` in row `row`.
    fn get(&self, row: usize, s: &Source) -> f32 {
        match (s, &self.rows) {
            (
                Source::Offset(o, t),
                Rows::Fixed {
                    bytes,
                    stride,
                    big_endian,
                },
            ) => t.read(&bytes[row * stride + o..], *big_endian) as f32,
            (Source::Index(i), rows) => rows
                .values(&self.element, row, *i)
                .first()
                .copied()
                .unwrap_or(f64::NAN) as f32,
            _ => f32::NAN,
        }
    }
}

impl BlockDecoder for StandardDecoder<'_> {
    fn len(&self) -> usize {
        self.element.count
    }

    fn sh_degree(&self) -> u8 {
        self.degree
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        let k = sh_rest_count(self.degree);
        let layout = &self.layout;
        for (j, g) in out.iter_mut().enumerate() {
            let row = start + j;
            let get = |s: &Source| self.get(row, s);
            let sh_dc = match &layout.color {
                ColorSource::Dc(s) => s.each_ref().map(get),
                ColorSource::Rgb(s, max) => {
                    s.each_ref().map(|c| (get(c) / *max as f32 - 0.5) / SH_C0)
                }
            };
            let mut sh_rest = [[0.0; 3]; 15];
            for (idx, s) in layout.rest.iter().enumerate() {
                sh_rest[idx % k][idx / k] = get(s);
            }
            let [w, x, y, z] = layout.rotation.each_ref().map(get);
            let rotation = Quat::from_xyzw(x, y, z, w);
            let bad = |field: &str, why: &str| {
                Err(Error::format(
                    format!("vertex[{row}].{field}"),
                    why.to_string(),
                ))
            };
            if crate::gaussians::unit_rotation(rotation).is_none() {
                return bad("rot_*", "rotation is not finite or is zero");
            }
            if !sh_rest.iter().flatten().all(|v| v.is_finite()) {
                return bad("f_rest_*", "value is not finite (NaN or infinity)");
            }
            *g = Gaussian {
                position: Vec3::from_array(layout.position.each_ref().map(get)),
                rotation,
                log_scale: Vec3::from_array(layout.scale.each_ref().map(get)),
                opacity_logit: finite_logit(get(&layout.opacity)),
                sh_dc,
                sh_rest,
                instance: 0,
            };
        }
        Ok(())
    }
}

/// Reads the standard layout into the compact store (the header has been parsed already).
///
/// # Errors
///
/// As [`StandardDecoder::open`] and [`BlockDecoder::decode`], and the store's validation.
pub fn read(header: &Header, bytes: &[u8]) -> Result<Gaussians> {
    StandardDecoder::open(header, bytes)?.to_gaussians()
}

/// Tools write alpha 0 and 1 as logits of ∓infinity; keep them finite (NaN stays NaN and is
/// rejected by validation).
fn finite_logit(x: f32) -> f32 {
    x.clamp(-MAX_LOGIT, MAX_LOGIT)
}

/// The largest opacity logit kept: sigmoid(±20) is within 2e-9 of 0 or 1.
pub const MAX_LOGIT: f32 = 20.0;

/// The header of the standard layout for `n` Gaussians of SH degree `degree`.
pub fn header_text(n: usize, degree: u8) -> String {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\ncomment Generated by sage3d\n");
    h += &format!("element vertex {n}\n");
    for p in [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ] {
        h += &format!("property float {p}\n");
    }
    for i in 0..sh_rest_count(degree) * 3 {
        h += &format!("property float f_rest_{i}\n");
    }
    for p in [
        "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ] {
        h += &format!("property float {p}\n");
    }
    h + "end_header\n"
}

fn encode_row(g: &Gaussian, k: usize, out: &mut Vec<u8>) {
    let q = g.rotation;
    let mut push = |v: f32| out.extend_from_slice(&v.to_le_bytes());
    g.position.to_array().into_iter().for_each(&mut push);
    [0.0; 3].into_iter().for_each(&mut push);
    g.sh_dc.into_iter().for_each(&mut push);
    for c in 0..3 {
        for coeff in &g.sh_rest[..k] {
            push(coeff[c]);
        }
    }
    push(g.opacity_logit);
    g.log_scale.to_array().into_iter().for_each(&mut push);
    [q.w, q.x, q.y, q.z].into_iter().for_each(&mut push);
}

/// Writes the standard layout (binary little-endian), in the source's order.
pub fn write(w: &mut impl Write, g: &impl SplatSource) -> std::io::Result<()> {
    w.write_all(header_text(g.len(), g.sh_degree()).as_bytes())?;
    const BLOCK: usize = 16384;
    let mut rows = Vec::with_capacity(BLOCK.min(g.len()));
    for start in (0..g.len()).step_by(BLOCK) {
        rows.clear();
        rows.extend((start..(start + BLOCK).min(g.len())).map(|i| g.get(i)));
        write_rows(w, &rows, g.sh_degree())?;
    }
    Ok(())
}

/// Writes the rows of `rows` (after [`header_text`] for SH degree `degree`), encoded in
/// parallel; a caller streaming a large file writes it block by block.
pub fn write_rows(w: &mut impl Write, rows: &[Gaussian], degree: u8) -> std::io::Result<()> {
    let k = sh_rest_count(degree);
    let parts: Vec<Vec<u8>> = rows
        .par_chunks(1024)
        .map(|chunk| {
            let mut buf = Vec::with_capacity(chunk.len() * (62 * 4));
            for g in chunk {
                encode_row(g, k, &mut buf);
            }
            buf
        })
        .collect();
    for p in parts {
        w.write_all(&p)?;
    }
    Ok(())
}
