//! The SuperSplat/PlayCanvas compressed PLY layout (what InteriorGS ships).
//!
//! - `element chunk` (one per 256 Gaussians), floats: `min_x min_y min_z max_x max_y max_z`,
//!   `min_scale_{x,y,z} max_scale_{x,y,z}` and, in 18-float records, `min_{r,g,b} max_{r,g,b}`.
//! - `element vertex`, uints: `packed_position` and `packed_scale` (11-10-11 bit unorms lerped
//!   between the chunk bounds; scales are logs), `packed_rotation` (2 bits naming the largest
//!   component of (w, x, y, z), then the other three as 10-bit values in [−1/√2, 1/√2]),
//!   `packed_color` (8-8-8-8: colour — lerped between the chunk colour bounds when present — and
//!   post-sigmoid opacity).
//! - optional `element sh`, uchars `f_rest_0..` (9, 24 or 45, channel-major): value
//!   `(u − 0.5) · 8` with `u = 0` for 0, `1` for 255, else `(byte + 0.5) / 256`.
//!
//! The writer always emits 18-float chunk records, and writes the Gaussians along a Z-order
//! curve unless the source's chunks are already compact ([`write_order`]).

use super::header::{Element, Header, Rows, Scalar, element_rows};
use super::standard::MAX_LOGIT;
use crate::gaussians::{
    Gaussian, Gaussians, SH_C0, morton_order, sh_degree_for_rest_len, sh_rest_count,
};
use crate::splats::{BlockDecoder, SplatSource, check_finite};
use glam::{Quat, Vec3};
use rayon::prelude::*;
use sage_core::{Error, Result};
use std::io::Write;

/// Gaussians per chunk record.
pub const CHUNK: usize = 256;

const CHUNK_POS: [&str; 12] = [
    "min_x",
    "min_y",
    "min_z",
    "max_x",
    "max_y",
    "max_z",
    "min_scale_x",
    "min_scale_y",
    "min_scale_z",
    "max_scale_x",
    "max_scale_y",
    "max_scale_z",
];
const CHUNK_COLOR: [&str; 6] = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"];
const PACKED: [&str; 4] = [
    "packed_position",
    "packed_rotation",
    "packed_scale",
    "packed_color",
];

fn fixed<'a>(rows: &Rows<'a>, name: &str) -> Result<(&'a [u8], usize)> {
    match rows {
        Rows::Fixed {
            bytes,
            stride,
            big_endian: false,
        } => Ok((*bytes, *stride)),
        _ => Err(Error::format(
            name,
            "the compressed layout must be binary little-endian without lists",
        )),
    }
}

fn offsets(e: &Element, names: &[&str], want: Scalar) -> Result<Vec<usize>> {
    names
        .iter()
        .map(|n| match e.scalar_offset(n) {
            Some((o, s)) if s == want => Ok(o),
            Some((_, s)) => Err(Error::format(
                format!("{}.{n}", e.name),
                format!("expected type {want:?}, found {s:?}"),
            )),
            None => Err(Error::format(format!("{}.{n}", e.name), "missing property")),
        })
        .collect()
}

#[inline]
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

#[inline]
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

#[inline]
fn unpack_11_10_11(v: u32) -> Vec3 {
    Vec3::new(
        ((v >> 21) & 0x7ff) as f32 / 2047.0,
        ((v >> 11) & 0x3ff) as f32 / 1023.0,
        (v & 0x7ff) as f32 / 2047.0,
    )
}

#[inline]
fn unpack_rotation(v: u32) -> Quat {
    let scale = std::f32::consts::SQRT_2;
    let small = [(v >> 20) & 0x3ff, (v >> 10) & 0x3ff, v & 0x3ff]
        .map(|c| (c as f32 / 1023.0 - 0.5) * scale);
    let largest = (v >> 30) as usize;
    let m = (1.0 - small.iter().map(|c| c * c).sum::<f32>())
        .max(0.0)
        .sqrt();
    let mut wxyz = [0.0f32; 4];
    let mut it = small.into_iter();
    for (i, c) in wxyz.iter_mut().enumerate() {
        *c = if i == largest {
            m
        } else {
            it.next().unwrap_or(0.0)
        };
    }
    Quat::from_xyzw(wxyz[1], wxyz[2], wxyz[3], wxyz[0])
}

#[inline]
fn sh_value(byte: u8) -> f32 {
    let u = match byte {
        0 => 0.0,
        255 => 1.0,
        b => (b as f32 + 0.5) / 256.0,
    };
    (u - 0.5) * 8.0
}

/// A compressed-layout file opened for decoding (the header has been parsed already).
pub struct CompressedDecoder<'a> {
    n: usize,
    degree: u8,
    chunk_bytes: &'a [u8],
    chunk_stride: usize,
    chunk_off: Vec<usize>,
    color_off: Option<Vec<usize>>,
    vert_bytes: &'a [u8],
    vert_stride: usize,
    packed_off: Vec<usize>,
    sh: Option<(&'a [u8], usize, Vec<usize>)>,
}

impl<'a> CompressedDecoder<'a> {
    /// Locates the chunk, vertex and SH records of `bytes` as `header` describes them.
    ///
    /// # Errors
    ///
    /// A missing element or property, a wrong type, too few chunk records for the vertices or
    /// an SH element of another length, naming the element and property.
    pub fn open(header: &Header, bytes: &'a [u8]) -> Result<CompressedDecoder<'a>> {
        let (ci, chunk_el) = header
            .element("chunk")
            .ok_or_else(|| Error::format("chunk", "missing element"))?;
        let (vi, vertex_el) = header
            .element("vertex")
            .ok_or_else(|| Error::format("vertex", "missing element"))?;
        let rows = element_rows(header, bytes)?;
        let (chunk_bytes, chunk_stride) = fixed(&rows[ci], "chunk")?;
        let (vert_bytes, vert_stride) = fixed(&rows[vi], "vertex")?;
        let n = vertex_el.count;
        if chunk_el.count < n.div_ceil(CHUNK) {
            return Err(Error::format(
                "chunk",
                format!(
                    "{} chunk records cannot cover {n} vertices (need {})",
                    chunk_el.count,
                    n.div_ceil(CHUNK)
                ),
            ));
        }
        let chunk_off = offsets(chunk_el, &CHUNK_POS, Scalar::F32)?;
        let color_off = match chunk_el.property_index("min_r") {
            Some(_) => Some(offsets(chunk_el, &CHUNK_COLOR, Scalar::F32)?),
            None => None,
        };
        let packed_off = offsets(vertex_el, &PACKED, Scalar::U32)?;
        let sh = match header.element("sh") {
            None => None,
            Some((si, sh_el)) => {
                if sh_el.count != n {
                    return Err(Error::format(
                        "sh",
                        format!("has {} rows but vertex has {n}", sh_el.count),
                    ));
                }
                let names: Vec<String> = (0..sh_el.properties.len())
                    .map(|i| format!("f_rest_{i}"))
                    .collect();
                let names: Vec<&str> = names.iter().map(String::as_str).collect();
                let off = offsets(sh_el, &names, Scalar::U8)?;
                let (b, stride) = fixed(&rows[si], "sh")?;
                Some((b, stride, off))
            }
        };
        let degree = match &sh {
            None => 0,
            Some((_, _, off)) => sh_degree_for_rest_len(off.len()).ok_or_else(|| {
                Error::format(
                    "sh",
                    format!(
                        "found {} f_rest properties; expected 9, 24 or 45",
                        off.len()
                    ),
                )
            })?,
        };
        let decoder = CompressedDecoder {
            n,
            degree,
            chunk_bytes,
            chunk_stride,
            chunk_off,
            color_off,
            vert_bytes,
            vert_stride,
            packed_off,
            sh,
        };
        decoder.check_bounds()?;
        Ok(decoder)
    }

    /// Checks that every bound of the chunks the vertices use is finite: a NaN bound would
    /// decode to a NaN for every Gaussian of its chunk, and an infinite one to infinities.
    ///
    /// # Errors
    ///
    /// The first non-finite bound, naming its chunk and property.
    fn check_bounds(&self) -> Result<()> {
        let names = CHUNK_POS.iter().zip(&self.chunk_off).chain(
            self.color_off
                .iter()
                .flat_map(|o| CHUNK_COLOR.iter().zip(o)),
        );
        for c in 0..self.n.div_ceil(CHUNK) {
            let cb = &self.chunk_bytes[c * self.chunk_stride..];
            for (name, &o) in names.clone() {
                if !f32_at(cb, o).is_finite() {
                    return Err(Error::format(
                        format!("chunk[{c}].{name}"),
                        "value is not finite (NaN or infinity)",
                    ));
                }
            }
        }
        Ok(())
    }

    /// The position, log-scale and colour bounds of chunk `c`.
    fn bounds(&self, c: usize) -> ChunkBounds {
        let cb = &self.chunk_bytes[c * self.chunk_stride..];
        let f = |i: usize| f32_at(cb, self.chunk_off[i]);
        ChunkBounds {
            position: (Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5))),
            log_scale: (Vec3::new(f(6), f(7), f(8)), Vec3::new(f(9), f(10), f(11))),
            color: self.color_off.as_ref().map(|o| {
                let g = |i: usize| f32_at(cb, o[i]);
                (Vec3::new(g(0), g(1), g(2)), Vec3::new(g(3), g(4), g(5)))
            }),
        }
    }
}

/// The bounds of one chunk record: (min, max) of positions, log-scales and (18-float records)
/// colours.
struct ChunkBounds {
    position: (Vec3, Vec3),
    log_scale: (Vec3, Vec3),
    color: Option<(Vec3, Vec3)>,
}

impl BlockDecoder for CompressedDecoder<'_> {
    fn len(&self) -> usize {
        self.n
    }

    fn sh_degree(&self) -> u8 {
        self.degree
    }

    fn decode(&self, start: usize, out: &mut [Gaussian]) -> Result<()> {
        let k = sh_rest_count(self.degree);
        let mut chunk = None;
        for (j, g) in out.iter_mut().enumerate() {
            let row = start + j;
            let c = row / CHUNK;
            let b = match &chunk {
                Some((at, b)) if *at == c => b,
                _ => &chunk.insert((c, self.bounds(c))).1,
            };
            let vb = &self.vert_bytes[row * self.vert_stride..];
            let [pp, pr, ps, pc] = [0, 1, 2, 3].map(|i| u32_at(vb, self.packed_off[i]));
            let raw = Vec3::new(
                (pc >> 24) as f32,
                ((pc >> 16) & 0xff) as f32,
                ((pc >> 8) & 0xff) as f32,
            ) / 255.0;
            let rgb = match b.color {
                Some((lo, hi)) => lo + (hi - lo) * raw,
                None => raw,
            };
            let alpha = (pc & 0xff) as f32 / 255.0;
            let mut sh_rest = [[0.0; 3]; 15];
            if let Some((sb, stride, off)) = &self.sh {
                let row_bytes = &sb[row * stride..];
                for (idx, o) in off.iter().enumerate() {
                    sh_rest[idx % k][idx / k] = sh_value(row_bytes[*o]);
                }
            }
            let ((pmin, pmax), (smin, smax)) = (b.position, b.log_scale);
            *g = Gaussian {
                position: pmin + (pmax - pmin) * unpack_11_10_11(pp),
                rotation: unpack_rotation(pr),
                log_scale: smin + (smax - smin) * unpack_11_10_11(ps),
                // 0 and 255 give logits of ∓infinity, kept at ∓20 as `splat-transform` keeps
                // them (sigmoid(±20) re-encodes to the same byte).
                opacity_logit: (-(1.0 / alpha - 1.0).ln()).clamp(-MAX_LOGIT, MAX_LOGIT),
                sh_dc: ((rgb - Vec3::splat(0.5)) / SH_C0).to_array(),
                sh_rest,
                instance: 0,
            };
        }
        Ok(())
    }
}

/// Reads the compressed layout into the compact store (the header has been parsed already).
///
/// # Errors
///
/// As [`CompressedDecoder::open`], and the store's validation.
pub fn read(header: &Header, bytes: &[u8]) -> Result<Gaussians> {
    CompressedDecoder::open(header, bytes)?.to_gaussians()
}

fn unorm(v: f32, bits: u32) -> u32 {
    let max = ((1u32 << bits) - 1) as f32;
    (v.clamp(0.0, 1.0) * max).round() as u32
}

fn normalized(v: Vec3, lo: Vec3, hi: Vec3) -> Vec3 {
    let range = hi - lo;
    Vec3::select(range.cmpgt(Vec3::ZERO), (v - lo) / range, Vec3::ZERO)
}

fn pack_11_10_11(u: Vec3) -> u32 {
    (unorm(u.x, 11) << 21) | (unorm(u.y, 10) << 11) | unorm(u.z, 11)
}

fn pack_rotation(q: Quat) -> u32 {
    let q = q.normalize();
    let wxyz = [q.w, q.x, q.y, q.z];
    let largest = (0..4)
        .max_by(|&a, &b| wxyz[a].abs().total_cmp(&wxyz[b].abs()))
        .unwrap_or(0);
    let sign = if wxyz[largest] < 0.0 { -1.0 } else { 1.0 };
    let mut packed = (largest as u32) << 30;
    let mut shift = 20u32;
    for (i, c) in wxyz.iter().enumerate() {
        if i != largest {
            packed |= unorm(c * sign * std::f32::consts::FRAC_1_SQRT_2 + 0.5, 10) << shift;
            shift = shift.saturating_sub(10);
        }
    }
    packed
}

fn sh_byte(v: f32) -> u8 {
    ((v / 8.0 + 0.5) * 256.0).clamp(0.0, 255.0) as u8
}

/// The 18 chunk floats for Gaussians `items`.
fn chunk_bounds(items: &[Gaussian]) -> [f32; 18] {
    let (mut pl, mut ph) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let (mut sl, mut sh) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let (mut cl, mut ch) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for g in items {
        pl = pl.min(g.position);
        ph = ph.max(g.position);
        let s = g.log_scale.clamp(Vec3::splat(-20.0), Vec3::splat(20.0));
        sl = sl.min(s);
        sh = sh.max(s);
        let c = Vec3::from_array(g.base_color());
        cl = cl.min(c);
        ch = ch.max(c);
    }
    let mut out = [0.0; 18];
    for (i, v) in [pl, ph, sl, sh, cl, ch].iter().enumerate() {
        out[i * 3..i * 3 + 3].copy_from_slice(&v.to_array());
    }
    out
}

/// The header of the compressed layout.
pub fn header_text(n: usize, degree: u8) -> String {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\ncomment Generated by sage3d\n");
    h += &format!("element chunk {}\n", n.div_ceil(CHUNK));
    for p in CHUNK_POS.iter().chain(CHUNK_COLOR.iter()) {
        h += &format!("property float {p}\n");
    }
    h += &format!("element vertex {n}\n");
    for p in PACKED {
        h += &format!("property uint {p}\n");
    }
    let k = sh_rest_count(degree);
    if k > 0 {
        h += &format!("element sh {n}\n");
        for i in 0..k * 3 {
            h += &format!("property uchar f_rest_{i}\n");
        }
    }
    h + "end_header\n"
}

/// One encoded chunk: its 18 floats, its packed vertices and its SH bytes.
type EncodedChunk = ([f32; 18], Vec<u8>, Vec<u8>);

/// Encodes one chunk.
fn encode_chunk(items: &[Gaussian], k: usize) -> EncodedChunk {
    let b = chunk_bounds(items);
    let v3 = |i: usize| Vec3::new(b[i], b[i + 1], b[i + 2]);
    let (pl, ph, sl, sh, cl, ch) = (v3(0), v3(3), v3(6), v3(9), v3(12), v3(15));
    let mut vertices = Vec::with_capacity(items.len() * 16);
    let mut sh_bytes = Vec::with_capacity(items.len() * k * 3);
    for g in items {
        let c = normalized(Vec3::from_array(g.base_color()), cl, ch);
        let alpha = g.opacity();
        let color =
            (unorm(c.x, 8) << 24) | (unorm(c.y, 8) << 16) | (unorm(c.z, 8) << 8) | unorm(alpha, 8);
        let s = g.log_scale.clamp(Vec3::splat(-20.0), Vec3::splat(20.0));
        for word in [
            pack_11_10_11(normalized(g.position, pl, ph)),
            pack_rotation(g.rotation),
            pack_11_10_11(normalized(s, sl, sh)),
            color,
        ] {
            vertices.extend_from_slice(&word.to_le_bytes());
        }
        for c in 0..3 {
            sh_bytes.extend(g.sh_rest[..k].iter().map(|coeff| sh_byte(coeff[c])));
        }
    }
    (b, vertices, sh_bytes)
}

/// The source order's chunks may be this much wider (summed over chunks and axes) than a
/// Morton order's for [`write_order`] to keep it: splat-transform's compressed files, decoded,
/// are within 0.1 % of a fresh Morton order; a shuffled 1M-Gaussian home is 13.5 times wider.
const KEEP_ORDER_SPREAD: f64 = 1.25;

/// The order [`write()`] puts the Gaussians of `g` in, as indices into `g` (`None`: the source's
/// own). Each chunk's positions, scales and colours are quantised between that chunk's own
/// bounds, so a chunk of Gaussians from all over the scene (a trained PLY's order) would cost
/// most of their precision: such a source is written along a Z-order curve
/// ([`morton_order`]), as splat-transform and SuperSplat write this layout. A source whose
/// chunks are already compact (within `KEEP_ORDER_SPREAD` of that order's, as a decoded
/// compressed file is) keeps its order, so re-encoding moves no Gaussian.
pub fn write_order(g: &impl SplatSource) -> Option<Vec<u32>> {
    morton_if_loose(g, chunk_spread(g, &|j| j))
}

/// A source whose chunks, in its order, span on average at most this share of the scene's
/// extent (summed over the axes) is taken as compact by [`loose_order`] without a Morton
/// order to compare with: a Morton order's chunks span 0.07 of a 1M-Gaussian home's, a
/// shuffled order's all of it.
const SURELY_COMPACT: f64 = 0.25;

/// [`write_order`]'s Morton order when the 256-Gaussian chunks of `g`, in its order, are
/// loose; `None` when they are compact. Chunks that span under a quarter of the scene on
/// average are compact at the cost of one pass over the positions; others are compared with a
/// Morton order.
pub fn loose_order(g: &impl SplatSource) -> Option<Vec<u32>> {
    let source = chunk_spread(g, &|j| j);
    let whole = sage_core::Aabb::from_points((0..g.len()).map(|i| g.position(i))).size();
    let whole = f64::from(whole.x) + f64::from(whole.y) + f64::from(whole.z);
    let chunks = g.len().div_ceil(CHUNK) as f64;
    if source <= SURELY_COMPACT * chunks * whole {
        return None;
    }
    morton_if_loose(g, source)
}

/// A Morton order of `g` when the source's chunks, of `source` spread ([`chunk_spread`]), are
/// more than `KEEP_ORDER_SPREAD` times as wide as that order's.
fn morton_if_loose(g: &impl SplatSource, source: f64) -> Option<Vec<u32>> {
    let morton = morton_order(g.len(), |i| g.position(i));
    let sorted = chunk_spread(g, &|j| morton[j] as usize);
    (source > KEEP_ORDER_SPREAD * sorted).then_some(morton)
}

/// Summed over the chunks of `g` taken in the order `at` (place `j` holds Gaussian `at(j)`),
/// the extent of the chunk's positions along the three axes.
fn chunk_spread(g: &impl SplatSource, at: &(dyn Fn(usize) -> usize + Sync)) -> f64 {
    (0..g.len().div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let size = sage_core::Aabb::from_points(
                (c * CHUNK..((c + 1) * CHUNK).min(g.len())).map(|j| g.position(at(j))),
            )
            .size();
            f64::from(size.x) + f64::from(size.y) + f64::from(size.z)
        })
        .sum()
}

/// Writes the compressed layout, the Gaussians in [`write_order`].
///
/// # Errors
///
/// A value the scene store refuses ([`check_finite`], naming the Gaussian's index in the
/// source: a NaN would otherwise be written as its chunk's minimum, an infinity stretch the
/// chunk's bounds), or the write error.
pub fn write(w: &mut impl Write, g: &impl SplatSource) -> std::io::Result<()> {
    // Every value checked before the positions are ordered.
    check_all(g)?;
    encode_in_order(w, g, write_order(g).as_deref())
}

/// [`write()`] with the Gaussians in `order` (indices into `g`; `None`: its own), for a caller
/// that has taken [`write_order`] already.
///
/// # Errors
///
/// As [`write()`].
pub fn write_in_order(
    w: &mut impl Write,
    g: &impl SplatSource,
    order: Option<&[u32]>,
) -> std::io::Result<()> {
    check_all(g)?;
    encode_in_order(w, g, order)
}

/// [`check_finite`] over every Gaussian of `g`, in blocks; the first failing block, whatever
/// the threads' order.
fn check_all(g: &impl SplatSource) -> std::io::Result<()> {
    let n = g.len();
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let items: Vec<Gaussian> = (c * CHUNK..((c + 1) * CHUNK).min(n))
                .map(|i| g.get(i))
                .collect();
            check_finite(c * CHUNK, &items)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<Result<()>>()
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string()))
}

/// Encodes and writes the checked Gaussians of `g` in `order` (`None`: its own).
fn encode_in_order(
    w: &mut impl Write,
    g: &impl SplatSource,
    order: Option<&[u32]>,
) -> std::io::Result<()> {
    let n = g.len();
    let at = |j: usize| order.map_or(j, |o| o[j] as usize);
    let k = sh_rest_count(g.sh_degree());
    let chunks: Vec<EncodedChunk> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let items: Vec<Gaussian> = (c * CHUNK..((c + 1) * CHUNK).min(n))
                .map(|j| g.get(at(j)))
                .collect();
            encode_chunk(&items, k)
        })
        .collect();
    w.write_all(header_text(n, g.sh_degree()).as_bytes())?;
    for (bounds, _, _) in &chunks {
        for f in bounds {
            w.write_all(&f.to_le_bytes())?;
        }
    }
    for (_, vertices, _) in &chunks {
        w.write_all(vertices)?;
    }
    if k > 0 {
        for (_, _, sh) in &chunks {
            w.write_all(sh)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn rotation_pack_round_trip(w in -1.0f32..1.0, x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let q = Quat::from_xyzw(x, y, z, w);
            prop_assume!(q.length() > 0.1);
            let q = q.normalize();
            let r = unpack_rotation(pack_rotation(q));
            prop_assert!(r.dot(q).abs() > 1.0 - 2e-5, "{q:?} -> {r:?}");
        }

        #[test]
        fn sh_byte_round_trip(v in -4.0f32..4.0) {
            prop_assert!((sh_value(sh_byte(v)) - v).abs() <= 8.0 / 256.0);
        }
    }
}
