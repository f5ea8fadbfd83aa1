//! The Gaussians of a scene in a compact structure of arrays.
//!
//! Layout and precision (per Gaussian, SH degree 3: 85 bytes; degree 1: 49; degree 0: 38):
//!
//! | field | storage | bytes | precision |
//! |---|---|---|---|
//! | position | `[f32; 3]` | 12 | exact |
//! | rotation (w, x, y, z), unit | `[i16; 4]` snorm16 | 8 | ≤ 1.6e-5 per component |
//! | log-scale | `[i16; 3]` in steps of 1/2048, range ±16 | 6 | ±1/4096: scale within 0.025 % |
//! | opacity logit | `i16` in steps of 1/1024, range ±32 | 2 | ±1/2048: opacity within 1.3e-4 |
//! | SH degree 0 (`f_dc`) | `[f16; 3]`, range ±65504 | 6 | relative 2⁻¹¹ (≪ 1/255 in colour) |
//! | SH degrees 1–3 (`f_rest`) | `i8` codes × per-Gaussian `f16` step, range ±8.3e6 | 45 + 2 | ≤ ½ step, step = max\|coeff\| / 127 |
//! | instance id | `u32` | 4 | exact |
//!
//! Higher-order SH are stored coefficient-major: for Gaussian `i`, coefficient `k` (1…15) and
//! channel `c`, the code is `sh_codes[(i * K + k - 1) * 3 + c]` with `K` the count for the degree
//! (3, 8 or 15). The Inria PLY stores them channel-major (`f_rest_{c*K + k-1}`); readers and
//! writers convert.

use glam::{Quat, Vec3, Vec4};
use half::f16;
use rayon::prelude::*;
use sage_core::{Error, Result};

/// The number of higher-order SH coefficients per channel for a degree (0–3).
pub const fn sh_rest_count(degree: u8) -> usize {
    match degree {
        0 => 0,
        1 => 3,
        2 => 8,
        _ => 15,
    }
}

/// The SH degree whose higher-order coefficient count (all channels) is `n`, if any.
pub fn sh_degree_for_rest_len(n: usize) -> Option<u8> {
    (0..=3u8).find(|&d| sh_rest_count(d) * 3 == n)
}

/// `Y_0^0`: the constant SH basis value, linking `f_dc` to colour (`rgb = 0.5 + SH_C0 · f_dc`).
pub const SH_C0: f32 = 0.282_094_8;

fn spread_bits(v: u32) -> u64 {
    let mut x = (v & 0x1f_ffff) as u64;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    (x | x << 2) & 0x1249_2492_4924_9249
}

/// The 63-bit Morton code of a point in the unit cube (clamped).
pub fn morton_code(unit: Vec3) -> u64 {
    let q = unit.clamp(Vec3::ZERO, Vec3::ONE) * 2_097_151.0;
    spread_bits(q.x as u32) | spread_bits(q.y as u32) << 1 | spread_bits(q.z as u32) << 2
}

/// The order that visits `n` points (`position(i)`, finite) along a Z-order (Morton) curve
/// over their bounds, 21 bits per axis; ties keep index order, so points already in it give
/// `0..n`.
pub fn morton_order(n: usize, position: impl Fn(usize) -> Vec3 + Sync) -> Vec<u32> {
    let bounds = (0..n)
        .into_par_iter()
        .map(|i| sage_core::Aabb::EMPTY.grow(position(i)))
        .reduce(|| sage_core::Aabb::EMPTY, |a, b| a.union(b));
    let (lo, size) = if bounds.is_empty() {
        (Vec3::ZERO, Vec3::ONE)
    } else {
        (bounds.min, bounds.size().max(Vec3::splat(1e-6)))
    };
    let inv = Vec3::ONE / size;
    let mut keyed: Vec<(u64, u32)> = (0..n as u32)
        .into_par_iter()
        .map(|i| (morton_code((position(i as usize) - lo) * inv), i))
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// One Gaussian at full precision: what readers produce and writers consume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaussian {
    /// Centre in metres (world frame W).
    pub position: Vec3,
    /// Orientation (any non-zero quaternion; stored normalised).
    pub rotation: Quat,
    /// Natural-log scale along the Gaussian's own axes.
    pub log_scale: Vec3,
    /// Opacity before the sigmoid.
    pub opacity_logit: f32,
    /// SH degree-0 coefficients (RGB).
    pub sh_dc: [f32; 3],
    /// Higher-order SH coefficients, coefficient-major (`[k][channel]`); unused ones are zero.
    pub sh_rest: [[f32; 3]; 15],
    /// Instance the Gaussian belongs to (`0` for none).
    pub instance: u32,
}

impl Default for Gaussian {
    fn default() -> Self {
        Gaussian {
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            log_scale: Vec3::splat(-4.0),
            opacity_logit: 0.0,
            sh_dc: [0.0; 3],
            sh_rest: [[0.0; 3]; 15],
            instance: 0,
        }
    }
}

impl Gaussian {
    /// Opacity after the sigmoid.
    pub fn opacity(&self) -> f32 {
        1.0 / (1.0 + (-self.opacity_logit).exp())
    }

    /// Base colour (SH degree 0 only), unclamped.
    pub fn base_color(&self) -> [f32; 3] {
        self.sh_dc.map(|c| 0.5 + SH_C0 * c)
    }
}

/// The step of stored log-scales: 1/2048 keeps scales within 0.025 % over e^±16.
pub const LOG_SCALE_STEP: f32 = 1.0 / 2048.0;
/// The step of stored opacity logits: 1/1024 keeps opacity within 1.3e-4 over logits ±32.
pub const OPACITY_LOGIT_STEP: f32 = 1.0 / 1024.0;
/// Height above the floor (z = 0 in the world frame W) below which a Gaussian's centre is floor
/// rather than obstacle, metres: the floor of a trained capture is a layer of Gaussians a few
/// centimetres thick. The occupancy grid of a scene without a map counts no obstacle below it
/// (`sage_nav::splat_grid`) and the collision body of a capture's loose Gaussians starts above it
/// (`sage_physics::splat_bodies`), so that where the map is free an agent stands free.
pub const FLOOR_BAND: f32 = 0.05;
/// The farthest a Gaussian's centre may lie from the origin along any axis, metres: there a
/// float's steps are a metre (f32 holds 24 bits), so nothing of a room can be drawn, and one
/// such stray value would stretch whatever is built over the scene's bounds (chunk bounds,
/// a compressed file's quantisation, previews) over it.
pub const MAX_GAUSSIAN_COORDINATE: f32 = 1.0e7;
/// The code stored for a value that was not finite, so that [`Gaussians::validate`] can name it.
const NOT_FINITE: i16 = i16::MIN;

/// `v` in units of `step`, rounded to the nearest code and clamped to ±32767; NaN and
/// infinities become [`NOT_FINITE`].
fn fixed16(v: f32, step: f32) -> i16 {
    if v.is_finite() {
        // Half away from zero without the library call; the cast saturates.
        let x = v / step;
        (x + 0.5f32.copysign(x)).clamp(-32767.0, 32767.0) as i16
    } else {
        NOT_FINITE
    }
}

/// Inverse of the sigmoid, clamped so that 0 and 1 stay finite.
pub fn opacity_to_logit(alpha: f32) -> f32 {
    let a = alpha.clamp(1e-6, 1.0 - 1e-6);
    (a / (1.0 - a)).ln()
}

/// The Gaussians of one scene (see the module docs for layout and precision).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Gaussians {
    sh_degree: u8,
    /// Centres, metres.
    pub positions: Vec<[f32; 3]>,
    /// Unit quaternions (w, x, y, z) as snorm16.
    pub rotations: Vec<[i16; 4]>,
    /// Natural-log scales in units of [`LOG_SCALE_STEP`] (read with [`Gaussians::log_scale`]).
    pub log_scales: Vec<[i16; 3]>,
    /// Opacity logits in units of [`OPACITY_LOGIT_STEP`] (read with
    /// [`Gaussians::opacity_logit`]).
    pub opacity_logits: Vec<i16>,
    /// SH degree-0 coefficients.
    pub sh_dc: Vec<[f16; 3]>,
    /// Per-Gaussian step of the higher-order SH codes (empty at degree 0).
    pub sh_steps: Vec<f16>,
    /// Higher-order SH codes, coefficient-major (empty at degree 0).
    pub sh_codes: Vec<i8>,
    /// Instance ids (`0` = none).
    pub instances: Vec<u32>,
}

/// A mutable window onto consecutive Gaussians, for filling a store in parallel.
pub struct GaussiansSliceMut<'a> {
    sh_degree: u8,
    positions: &'a mut [[f32; 3]],
    rotations: &'a mut [[i16; 4]],
    log_scales: &'a mut [[i16; 3]],
    opacity_logits: &'a mut [i16],
    sh_dc: &'a mut [[f16; 3]],
    sh_steps: &'a mut [f16],
    sh_codes: &'a mut [i8],
    instances: &'a mut [u32],
}

/// `q` as a unit quaternion, or `None` when it is zero or not finite. One of tiny or huge
/// components (1e-30, 1e30), whose squared length underflows to zero or overflows, is scaled
/// by its largest component first, so that it still normalises.
pub fn unit_rotation(q: Quat) -> Option<Quat> {
    if !q.is_finite() {
        return None;
    }
    if q.length_squared().is_normal() {
        return Some(q.normalize());
    }
    let largest = Vec4::from(q).abs().max_element();
    if largest == 0.0 {
        return None;
    }
    Some(Quat::from_vec4(Vec4::from(q) / largest).normalize())
}

fn snorm16(v: f32) -> i16 {
    (v.clamp(-1.0, 1.0) * 32767.0).round() as i16
}

/// An SH degree-0 coefficient as stored: a finite one beyond what f16 holds is clamped to
/// ±65504 (its colour saturates either way), a NaN or infinity stays one for
/// [`Gaussians::validate`] to name.
fn dc_half(v: f32) -> f16 {
    let max = f16::MAX.to_f32();
    f16::from_f32(if v.is_finite() { v.clamp(-max, max) } else { v })
}

fn quantize_sh_rest(rest: &[[f32; 3]], codes: &mut [i8]) -> f16 {
    let max_abs = rest.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
    if max_abs == 0.0 || !max_abs.is_finite() {
        codes.fill(0);
        return f16::ZERO;
    }
    // Coefficients beyond 127 of the largest f16 step (8.3e6, whose colour saturates either
    // way) clamp to it.
    let mut step = f16::from_f32((max_abs / 127.0).min(f16::MAX.to_f32()));
    // Round the step up so the largest coefficient still fits in ±127.
    while step.to_f32() * 127.0 < max_abs && step < f16::MAX {
        step = f16::from_bits(step.to_bits() + 1);
    }
    let s = step.to_f32();
    for (code, v) in codes.iter_mut().zip(rest.iter().flatten()) {
        *code = (v / s).round().clamp(-127.0, 127.0) as i8;
    }
    step
}

impl GaussiansSliceMut<'_> {
    /// The number of Gaussians in the window.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True for an empty window.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Stores `g` at index `j` of the window.
    pub fn set(&mut self, j: usize, g: &Gaussian) {
        self.positions[j] = g.position.to_array();
        let q = unit_rotation(g.rotation).unwrap_or(Quat::IDENTITY);
        self.rotations[j] = [snorm16(q.w), snorm16(q.x), snorm16(q.y), snorm16(q.z)];
        self.log_scales[j] = g.log_scale.to_array().map(|v| fixed16(v, LOG_SCALE_STEP));
        self.opacity_logits[j] = fixed16(g.opacity_logit, OPACITY_LOGIT_STEP);
        self.sh_dc[j] = g.sh_dc.map(dc_half);
        self.instances[j] = g.instance;
        let k = sh_rest_count(self.sh_degree);
        if k > 0 {
            let codes = &mut self.sh_codes[j * k * 3..(j + 1) * k * 3];
            self.sh_steps[j] = quantize_sh_rest(&g.sh_rest[..k], codes);
        }
    }
}

impl Gaussians {
    /// An empty store for SH degree `sh_degree` (0–3).
    pub fn new(sh_degree: u8) -> Result<Self> {
        if sh_degree > 3 {
            return Err(Error::invalid(format!(
                "SH degree must be 0-3, got {sh_degree}"
            )));
        }
        Ok(Gaussians {
            sh_degree,
            ..Default::default()
        })
    }

    /// A store of `n` default Gaussians, ready to be filled with [`Gaussians::par_chunks_mut`].
    pub fn with_len(n: usize, sh_degree: u8) -> Result<Self> {
        let mut g = Gaussians::new(sh_degree)?;
        let k = sh_rest_count(sh_degree);
        g.positions = vec![[0.0; 3]; n];
        g.rotations = vec![[32767, 0, 0, 0]; n];
        g.log_scales = vec![[0; 3]; n];
        g.opacity_logits = vec![0; n];
        g.sh_dc = vec![[f16::ZERO; 3]; n];
        g.instances = vec![0; n];
        if k > 0 {
            g.sh_steps = vec![f16::ZERO; n];
            g.sh_codes = vec![0; n * k * 3];
        }
        Ok(g)
    }

    /// Builds a store from full-precision Gaussians, in parallel.
    pub fn from_gaussians(items: &[Gaussian], sh_degree: u8) -> Result<Self> {
        let mut store = Gaussians::with_len(items.len(), sh_degree)?;
        store
            .par_chunks_mut(4096)
            .enumerate()
            .for_each(|(c, mut w)| {
                for j in 0..w.len() {
                    w.set(j, &items[c * 4096 + j]);
                }
            });
        Ok(store)
    }

    /// The SH degree (0–3).
    pub fn sh_degree(&self) -> u8 {
        self.sh_degree
    }

    /// The number of Gaussians.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Appends one Gaussian.
    pub fn push(&mut self, g: &Gaussian) {
        let k = sh_rest_count(self.sh_degree);
        self.positions.push([0.0; 3]);
        self.rotations.push([0; 4]);
        self.log_scales.push([0; 3]);
        self.opacity_logits.push(0);
        self.sh_dc.push([f16::ZERO; 3]);
        self.instances.push(0);
        if k > 0 {
            self.sh_steps.push(f16::ZERO);
            self.sh_codes.extend(std::iter::repeat_n(0, k * 3));
        }
        let last = self.len() - 1;
        self.window(last, last + 1).set(0, g);
    }

    fn window(&mut self, start: usize, end: usize) -> GaussiansSliceMut<'_> {
        let k3 = sh_rest_count(self.sh_degree) * 3;
        GaussiansSliceMut {
            sh_degree: self.sh_degree,
            positions: &mut self.positions[start..end],
            rotations: &mut self.rotations[start..end],
            log_scales: &mut self.log_scales[start..end],
            opacity_logits: &mut self.opacity_logits[start..end],
            sh_dc: &mut self.sh_dc[start..end],
            sh_steps: if k3 > 0 {
                &mut self.sh_steps[start..end]
            } else {
                &mut []
            },
            sh_codes: &mut self.sh_codes[start * k3..end * k3],
            instances: &mut self.instances[start..end],
        }
    }

    /// Overwrites Gaussian `i`.
    pub fn set(&mut self, i: usize, g: &Gaussian) {
        self.window(i, i + 1).set(0, g);
    }

    /// Splits the store into windows of `chunk` consecutive Gaussians, for parallel filling.
    pub fn par_chunks_mut(
        &mut self,
        chunk: usize,
    ) -> impl IndexedParallelIterator<Item = GaussiansSliceMut<'_>> {
        let n = self.len();
        let k3 = sh_rest_count(self.sh_degree) * 3;
        let degree = self.sh_degree;
        let chunk = chunk.max(1);
        let windows = n.div_ceil(chunk);
        // At degree 0 the SH arrays are empty: hand out empty slices, one pair per window.
        let sh: Vec<(&mut [f16], &mut [i8])> = if k3 > 0 {
            self.sh_steps
                .chunks_mut(chunk)
                .zip(self.sh_codes.chunks_mut(chunk * k3))
                .collect()
        } else {
            (0..windows).map(|_| (&mut [][..], &mut [][..])).collect()
        };
        (
            self.positions.par_chunks_mut(chunk),
            self.rotations.par_chunks_mut(chunk),
            self.log_scales.par_chunks_mut(chunk),
            self.opacity_logits.par_chunks_mut(chunk),
            self.sh_dc.par_chunks_mut(chunk),
            self.instances.par_chunks_mut(chunk),
            sh.into_par_iter(),
        )
            .into_par_iter()
            .map(
                move |(
                    positions,
                    rotations,
                    log_scales,
                    opacity_logits,
                    sh_dc,
                    instances,
                    (sh_steps, sh_codes),
                )| {
                    GaussiansSliceMut {
                        sh_degree: degree,
                        positions,
                        rotations,
                        log_scales,
                        opacity_logits,
                        sh_dc,
                        sh_steps,
                        sh_codes,
                        instances,
                    }
                },
            )
    }

    /// Orientation of Gaussian `i` (unit, w-first in storage).
    pub fn rotation(&self, i: usize) -> Quat {
        let [w, x, y, z] = self.rotations[i].map(|v| v as f32 / 32767.0);
        Quat::from_xyzw(x, y, z, w)
    }

    /// Higher-order SH coefficients of Gaussian `i`, coefficient-major, into the first
    /// `sh_rest_count(degree)` entries of `out` (the rest is left as it is: the renderer's hot
    /// loop reads only those).
    pub fn sh_rest_into(&self, i: usize, out: &mut [[f32; 3]; 15]) {
        let k = sh_rest_count(self.sh_degree);
        if k == 0 {
            return;
        }
        let step = self.sh_steps[i].to_f32();
        let codes = &self.sh_codes[i * k * 3..(i + 1) * k * 3];
        for (j, c) in codes.iter().enumerate() {
            out[j / 3][j % 3] = *c as f32 * step;
        }
    }

    /// The natural-log scale of Gaussian `i`.
    #[inline]
    pub fn log_scale(&self, i: usize) -> Vec3 {
        Vec3::from_array(self.log_scales[i].map(|c| f32::from(c) * LOG_SCALE_STEP))
    }

    /// The largest natural-log scale of Gaussian `i` (its longest axis).
    #[inline]
    pub fn max_log_scale(&self, i: usize) -> f32 {
        let [x, y, z] = self.log_scales[i];
        f32::from(x.max(y).max(z)) * LOG_SCALE_STEP
    }

    /// The opacity logit of Gaussian `i`.
    #[inline]
    pub fn opacity_logit(&self, i: usize) -> f32 {
        f32::from(self.opacity_logits[i]) * OPACITY_LOGIT_STEP
    }

    /// Gaussian `i` at the store's precision.
    pub fn get(&self, i: usize) -> Gaussian {
        let mut sh_rest = [[0.0; 3]; 15];
        self.sh_rest_into(i, &mut sh_rest);
        Gaussian {
            position: Vec3::from_array(self.positions[i]),
            rotation: self.rotation(i),
            log_scale: self.log_scale(i),
            opacity_logit: self.opacity_logit(i),
            sh_dc: self.sh_dc[i].map(f16::to_f32),
            sh_rest,
            instance: self.instances[i],
        }
    }

    /// Heap bytes held by the store (what a loaded scene costs per Gaussian, ×len).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.positions.as_slice())
            + size_of_val(self.rotations.as_slice())
            + size_of_val(self.log_scales.as_slice())
            + size_of_val(self.opacity_logits.as_slice())
            + size_of_val(self.sh_dc.as_slice())
            + size_of_val(self.sh_steps.as_slice())
            + size_of_val(self.sh_codes.as_slice())
            + size_of_val(self.instances.as_slice())
    }

    /// Checks that every value is finite, and every position within
    /// ±[`MAX_GAUSSIAN_COORDINATE`], and names the first Gaussian and field that is not.
    pub fn validate(&self) -> Result<()> {
        let bad = |i: usize, field: &str| {
            Err(Error::format(
                format!("vertex[{i}].{field}"),
                "value is not finite (NaN or infinity)",
            ))
        };
        for i in 0..self.len() {
            let p = self.positions[i];
            if !p.iter().all(|v| v.is_finite()) {
                return bad(i, "position");
            }
            if p.iter().any(|v| v.abs() > MAX_GAUSSIAN_COORDINATE) {
                return Err(Error::format(
                    format!("vertex[{i}].position"),
                    format!(
                        "{p:?} lies beyond ±10⁷ m, where a float's steps are a metre: a stray value, not part of a scene"
                    ),
                ));
            }
            if self.log_scales[i].contains(&NOT_FINITE) {
                return bad(i, "scale");
            }
            if self.opacity_logits[i] == NOT_FINITE {
                return bad(i, "opacity");
            }
            if !self.sh_dc[i].iter().all(|v| v.is_finite()) {
                return bad(i, "f_dc");
            }
        }
        Ok(())
    }

    /// The order that visits the Gaussians along a Z-order (Morton) curve over their bounds
    /// ([`morton_order`]). Renderers chunk Gaussians in this order, and a store already in it
    /// is read sequentially.
    pub fn morton_order(&self) -> Vec<u32> {
        morton_order(self.len(), |i| Vec3::from_array(self.positions[i]))
    }

    /// Puts the Gaussians in [`Gaussians::morton_order`] (no copy when already in it) and
    /// says whether any moved: renderers chunk consecutive Gaussians, so this order makes their
    /// chunks compact.
    pub fn sort_morton(&mut self) -> bool {
        let order = self.morton_order();
        if order.iter().enumerate().all(|(j, &i)| i as usize == j) {
            return false;
        }
        *self = self.permuted(&order);
        true
    }

    /// The store with Gaussian `order[j]` moved to position `j` (`order` must be a permutation).
    pub fn permuted(&self, order: &[u32]) -> Gaussians {
        let pick = |v: &Vec<_>| order.iter().map(|&i| v[i as usize]).collect();
        let k3 = sh_rest_count(self.sh_degree) * 3;
        Gaussians {
            sh_degree: self.sh_degree,
            positions: order.iter().map(|&i| self.positions[i as usize]).collect(),
            rotations: order.iter().map(|&i| self.rotations[i as usize]).collect(),
            log_scales: order.iter().map(|&i| self.log_scales[i as usize]).collect(),
            opacity_logits: order
                .iter()
                .map(|&i| self.opacity_logits[i as usize])
                .collect(),
            sh_dc: order.iter().map(|&i| self.sh_dc[i as usize]).collect(),
            sh_steps: if k3 > 0 {
                pick(&self.sh_steps)
            } else {
                Vec::new()
            },
            sh_codes: order
                .iter()
                .flat_map(|&i| &self.sh_codes[i as usize * k3..(i as usize + 1) * k3])
                .copied()
                .collect(),
            instances: order.iter().map(|&i| self.instances[i as usize]).collect(),
        }
    }

    /// The axis-aligned bounds of the centres.
    pub fn bounds(&self) -> sage_core::Aabb {
        sage_core::Aabb::from_points(self.positions.iter().map(|p| Vec3::from_array(*p)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_gaussian() -> impl Strategy<Value = Gaussian> {
        (
            prop::array::uniform3(-50.0f32..50.0),
            prop::array::uniform4(-1.0f32..1.0),
            prop::array::uniform3(-8.0f32..1.0),
            -8.0f32..8.0,
            prop::array::uniform3(-3.0f32..3.0),
            prop::collection::vec(-4.0f32..4.0, 45),
            any::<u32>(),
        )
            .prop_filter("non-zero quaternion", |t| {
                t.1.iter().map(|v| v * v).sum::<f32>() > 0.01
            })
            .prop_map(|(p, q, s, o, dc, rest, inst)| Gaussian {
                position: Vec3::from_array(p),
                rotation: Quat::from_xyzw(q[1], q[2], q[3], q[0]),
                log_scale: Vec3::from_array(s),
                opacity_logit: o,
                sh_dc: dc,
                sh_rest: std::array::from_fn(|k| [rest[k * 3], rest[k * 3 + 1], rest[k * 3 + 2]]),
                instance: inst,
            })
    }

    proptest! {
        #[test]
        fn store_round_trip_within_documented_precision(g in arb_gaussian(), degree in 0u8..=3) {
            let mut s = Gaussians::new(degree).unwrap();
            s.push(&g);
            let r = s.get(0);
            prop_assert_eq!(r.position, g.position);
            // Half a step, plus the rounding of the product.
            prop_assert!((r.log_scale - g.log_scale).abs().max_element() <= LOG_SCALE_STEP * 0.501);
            prop_assert!((r.opacity_logit - g.opacity_logit).abs() <= OPACITY_LOGIT_STEP * 0.501);
            prop_assert_eq!(r.instance, g.instance);
            let q = g.rotation.normalize();
            prop_assert!((r.rotation.dot(q).abs() - 1.0).abs() < 1e-4);
            for c in 0..3 {
                prop_assert!((r.sh_dc[c] - g.sh_dc[c]).abs() <= g.sh_dc[c].abs() * 1e-3 + 1e-4);
            }
            let k = sh_rest_count(degree);
            let max_abs = g.sh_rest[..k].iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
            for j in 0..15 {
                for c in 0..3 {
                    let want = if j < k { g.sh_rest[j][c] } else { 0.0 };
                    prop_assert!((r.sh_rest[j][c] - want).abs() <= max_abs / 254.0 * 1.01 + 1e-7);
                }
            }
        }

        #[test]
        fn parallel_fill_matches_push(items in prop::collection::vec(arb_gaussian(), 0..40), degree in 0u8..=3) {
            let mut pushed = Gaussians::new(degree).unwrap();
            for g in &items {
                pushed.push(g);
            }
            let built = Gaussians::from_gaussians(&items, degree).unwrap();
            prop_assert_eq!(built, pushed);
        }
    }

    #[test]
    fn bytes_per_gaussian_are_as_documented() {
        for (degree, bytes) in [(0, 38), (1, 49), (3, 85)] {
            let s = Gaussians::with_len(1000, degree).unwrap();
            assert_eq!(s.heap_bytes(), bytes * 1000);
        }
    }

    #[test]
    fn rotations_of_tiny_or_huge_components_normalise_and_zero_ones_do_not() {
        for (q, unit) in [
            (Quat::from_xyzw(0.0, 0.0, 0.0, 1e-30), Quat::IDENTITY),
            (
                Quat::from_xyzw(1e30, 0.0, 0.0, 1e30),
                Quat::from_xyzw(0.5f32.sqrt(), 0.0, 0.0, 0.5f32.sqrt()),
            ),
            (
                Quat::from_xyzw(0.0, 3e38, 0.0, 0.0),
                Quat::from_xyzw(0.0, 1.0, 0.0, 0.0),
            ),
        ] {
            let got = unit_rotation(q).unwrap();
            assert!(
                (Vec4::from(got) - Vec4::from(unit)).abs().max_element() < 1e-6,
                "{q}: {got}"
            );
        }
        for q in [
            Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
            Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0),
            Quat::from_xyzw(f32::INFINITY, 0.0, 0.0, 1.0),
        ] {
            assert_eq!(unit_rotation(q), None, "{q}");
        }
    }

    #[test]
    fn values_beyond_the_fixed_range_clamp_and_non_finite_ones_are_reported() {
        let mut s = Gaussians::new(0).unwrap();
        s.push(&Gaussian {
            log_scale: Vec3::new(-40.0, 40.0, 0.0),
            opacity_logit: 100.0,
            ..Gaussian::default()
        });
        assert_eq!(s.log_scale(0).x, -32767.0 * LOG_SCALE_STEP);
        assert_eq!(s.log_scale(0).y, 32767.0 * LOG_SCALE_STEP);
        assert!(s.opacity_logit(0) > 31.9);
        s.validate().unwrap();
        // Finite colours beyond f16 clamp, as do higher-order ones beyond the largest step.
        let mut sh_rest = [[0.0; 3]; 15];
        sh_rest[0] = [1e30, -1e9, 0.5];
        let mut big = Gaussians::new(1).unwrap();
        big.push(&Gaussian {
            sh_dc: [1e5, -1e30, 0.25],
            sh_rest,
            ..Gaussian::default()
        });
        big.validate().unwrap();
        let g = big.get(0);
        assert_eq!(g.sh_dc, [65504.0, -65504.0, 0.25]);
        assert!(
            g.sh_rest[0][0] > 8e6 && g.sh_rest[0][1] < -8e6,
            "{:?}",
            g.sh_rest[0]
        );
        s.push(&Gaussian {
            log_scale: Vec3::new(0.0, f32::NAN, 0.0),
            ..Gaussian::default()
        });
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("vertex[1].scale"), "{e}");
        let mut far = Gaussians::new(0).unwrap();
        far.push(&Gaussian::default());
        far.push(&Gaussian {
            position: Vec3::new(0.0, -1e30, 0.0),
            ..Gaussian::default()
        });
        let e = far.validate().unwrap_err().to_string();
        assert!(
            e.contains("vertex[1].position") && e.contains("beyond ±10⁷ m"),
            "{e}"
        );
    }

    #[test]
    fn permuting_by_morton_order_keeps_every_gaussian() {
        let items: Vec<Gaussian> = (0..300)
            .map(|i| {
                let mut sh_rest = [[0.0; 3]; 15];
                sh_rest[0] = [i as f32 * 0.01, 0.0, -0.5];
                Gaussian {
                    position: Vec3::new((i * 7 % 13) as f32, (i % 5) as f32, 0.5),
                    sh_rest,
                    instance: i,
                    ..Gaussian::default()
                }
            })
            .collect();
        let g = Gaussians::from_gaussians(&items, 1).unwrap();
        let order = g.morton_order();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..300).collect::<Vec<u32>>());
        let p = g.permuted(&order);
        for (j, &i) in order.iter().enumerate() {
            assert_eq!(p.get(j), g.get(i as usize));
        }
        assert_eq!(
            p.morton_order(),
            (0..300).collect::<Vec<u32>>(),
            "a sorted store is its own order"
        );
    }

    #[test]
    fn degree_four_is_rejected() {
        assert!(Gaussians::new(4).is_err());
    }
}
