//! One 16×16 tile's blending state and the front-to-back compositing of splats into it.

use crate::project::{MAX_ALPHA, MIN_ALPHA, Splat};
use wide::bytemuck::cast;
use wide::{f32x4, i32x4};

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Pixels per tile.
pub const TILE_PIXELS: usize = TILE * TILE;
/// Blending stops once transmittance would fall below this.
pub const MIN_TRANSMITTANCE: f32 = 1e-4;

/// Vectors per tile row (4 pixels each).
const ROW_VECTORS: usize = TILE / 4;
/// Vectors per tile.
const VECTORS: usize = TILE_PIXELS / 4;

/// Per-pixel accumulators of one tile, kept across depth slabs, four pixels to a vector
/// (vector `ly * 4 + lx / 4`, lane `lx % 4`).
#[derive(Clone)]
pub struct TileState {
    /// Transmittance, negated once the pixel reached the floor (so "done" costs no extra lane
    /// state: live pixels have t ≥ 1e-4 > 0, and the magnitude is the final transmittance).
    pub t: [f32x4; VECTORS],
    /// Σ w · red.
    pub r: [f32x4; VECTORS],
    /// Σ w · green.
    pub g: [f32x4; VECTORS],
    /// Σ w · blue.
    pub b: [f32x4; VECTORS],
    /// Σ w · z.
    pub wz: [f32x4; VECTORS],
    /// z of the last splat blended while transmittance was above 0.5: the median depth once
    /// transmittance ends at or below 0.5.
    pub median: [f32x4; VECTORS],
    /// The largest weight so far.
    pub best_w: [f32x4; VECTORS],
    /// Instance of the largest weight: the id's bits in each lane (read with `to_bits`), so
    /// lanes are chosen with the same bitwise select as the floats.
    pub instance: [f32x4; VECTORS],
    /// Pixels of the tile inside the image that are not done.
    pub remaining: usize,
}

/// Lane `l % 4` of vector `l / 4`: pixel `l = ly * 16 + lx` of a per-tile array.
#[inline]
pub fn lane(v: &[f32x4; VECTORS], l: usize) -> f32 {
    v[l / 4].to_array()[l % 4]
}

impl TileState {
    /// A fresh tile holding `pixels` image pixels (edge tiles hold fewer than 256).
    pub fn new(pixels: usize) -> TileState {
        let zero = [f32x4::ZERO; VECTORS];
        TileState {
            t: [f32x4::ONE; VECTORS],
            r: zero,
            g: zero,
            b: zero,
            wz: zero,
            median: zero,
            best_w: zero,
            instance: zero,
            remaining: pixels,
        }
    }

    /// Resets to fresh for a tile of `pixels` pixels.
    pub fn reset(&mut self, pixels: usize) {
        *self = TileState::new(pixels);
    }

    /// True when every pixel reached the transmittance floor.
    pub fn finished(&self) -> bool {
        self.remaining == 0
    }

    /// Blends `list` (depth-bits << 32 | splat index, already front to back) into the tile whose
    /// top-left pixel is (x0, y0) and whose in-image size is tw × th.
    ///
    /// Each splat visits, row by row, only the pixel centres inside its 1/255 ellipse (the
    /// exact interval of the quadratic form, widened by a hair so no boundary pixel is lost),
    /// four pixels at a time.
    pub fn blend(
        &mut self,
        splats: &[Splat],
        list: &[u64],
        x0: usize,
        y0: usize,
        tw: usize,
        th: usize,
    ) {
        let lane_x = f32x4::new([0.0, 1.0, 2.0, 3.0]);
        for &entry in list {
            let si = entry as u32;
            if self.remaining == 0 {
                return;
            }
            let sp = &splats[si as usize];
            let [a, b, c] = sp.conic;
            // Float-to-int casts truncate; with the max(0) first they floor (floorf and ceilf
            // are library calls on baseline x86-64, too slow for this loop).
            let ly0 = ((sp.y - sp.radius - y0 as f32 - 0.5).max(0.0) as usize).min(th);
            let ly1 = ((sp.y + sp.radius - y0 as f32 + 1.5).max(0.0) as usize).min(th);
            let splat = SplatLanes::new(sp);
            // Columns of the splat's square, as whole vectors; lanes outside the ellipse fail the
            // alpha test, which is cheaper than solving for each row's exact interval.
            let first = ((sp.x - sp.radius - x0 as f32 - 0.5).max(0.0) as usize).min(tw);
            let last = ((sp.x + sp.radius - x0 as f32 + 0.5).max(0.0) as usize + 1).min(tw);
            if first >= last {
                continue;
            }
            let (first_f, last_f) = (f32x4::splat(first as f32), f32x4::splat(last as f32));
            for ly in ly0..ly1 {
                let dy = sp.y - ((y0 + ly) as f32 + 0.5);
                let row_part = f32x4::splat(-0.5 * c * dy * dy);
                let b_dy = f32x4::splat(b * dy);
                for gx in first / 4..=(last - 1) / 4 {
                    let v = ly * ROW_VECTORS + gx;
                    let lx = lane_x + f32x4::splat((gx * 4) as f32);
                    // Live lanes: inside the square and not yet at the floor (done pixels hold −T).
                    let live =
                        lx.simd_ge(first_f) & lx.simd_lt(last_f) & self.t[v].simd_gt(f32x4::ZERO);
                    if live.none() {
                        continue;
                    }
                    let dx = f32x4::splat(sp.x - x0 as f32 - 0.5) - lx;
                    let power = row_part - (f32x4::splat(0.5 * a) * dx + b_dy) * dx;
                    self.blend_vector(&splat, v, live, power);
                }
            }
        }
    }

    /// Blends one splat into the live lanes (`live`) of vector `v`.
    #[inline]
    fn blend_vector(&mut self, sp: &SplatLanes, v: usize, live: f32x4, power: f32x4) {
        // Lanes beyond the splat's 1/255 ellipse are dropped before the exponential.
        let t = self.t[v];
        let reached = live & power.simd_ge(sp.min_power) & power.simd_le(f32x4::ZERO);
        if reached.none() {
            return;
        }
        let alpha = (sp.opacity * exp4(power)).min(f32x4::splat(MAX_ALPHA));
        let valid = reached & alpha.simd_ge(f32x4::splat(MIN_ALPHA));
        if valid.none() {
            return;
        }
        let next = t * (f32x4::ONE - alpha);
        let saturated = valid & next.simd_lt(f32x4::splat(MIN_TRANSMITTANCE));
        if saturated.any() {
            self.remaining -= saturated.to_bitmask().count_ones() as usize;
        }
        let blend = valid & !saturated;
        let w = (alpha * t) & blend;
        self.r[v] += w * sp.r;
        self.g[v] += w * sp.g;
        self.b[v] += w * sp.b;
        self.wz[v] += w * sp.depth;
        // Transmittance only falls, so the last splat blended while T was still above 0.5 is
        // the one that crossed it — provided T ends at or below 0.5 (checked when assembling).
        let above = blend & t.simd_gt(f32x4::splat(0.5));
        self.median[v] = above.select(sp.depth, self.median[v]);
        let better = blend & w.simd_gt(self.best_w[v]);
        self.best_w[v] = better.select(w, self.best_w[v]);
        self.instance[v] = better.select(sp.instance, self.instance[v]);
        self.t[v] = blend.select(next, saturated.select(-t, t));
    }
}

/// A splat's per-lane constants for [`TileState::blend_vector`].
struct SplatLanes {
    opacity: f32x4,
    min_power: f32x4,
    r: f32x4,
    g: f32x4,
    b: f32x4,
    depth: f32x4,
    instance: f32x4,
}

impl SplatLanes {
    fn new(s: &Splat) -> SplatLanes {
        SplatLanes {
            opacity: f32x4::splat(s.opacity),
            // power ≥ −cutoff/2 ⟺ inside the ellipse where alpha can reach 1/255 (the cutoff
            // errs outwards, so no lane that passes the exact alpha test is lost).
            min_power: f32x4::splat(-0.5 * s.cutoff),
            r: f32x4::splat(s.color[0]),
            g: f32x4::splat(s.color[1]),
            b: f32x4::splat(s.color[2]),
            depth: f32x4::splat(s.depth),
            instance: f32x4::splat(f32::from_bits(s.instance)),
        }
    }
}

/// e^x, four lanes, for x ≤ 0 down to about −87 (relative error below 5e-6): 2^(x log₂e) split
/// at the nearest integer, the fraction in [−½, ½] by a degree-5 polynomial.
#[inline]
pub fn exp4(x: f32x4) -> f32x4 {
    let y = (x * f32x4::splat(std::f32::consts::LOG2_E)).max(f32x4::splat(-126.0));
    let n = y.round_int();
    let f = y - f32x4::from_i32x4(n);
    let p = f32x4::ONE
        + f * (f32x4::splat(std::f32::consts::LN_2)
            + f * (f32x4::splat(0.240_226_5)
                + f * (f32x4::splat(0.055_504_11)
                    + f * (f32x4::splat(0.009_618_129) + f * f32x4::splat(0.001_333_355_8)))));
    let scale: f32x4 = cast((n + i32x4::splat(127)) << 23);
    scale * p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp4_is_accurate_where_it_is_used() {
        let mut x = -20.0f32;
        while x <= 0.0 {
            let got = exp4(f32x4::new([x, x - 1e-3, x - 2e-3, x - 3e-3])).to_array();
            for (k, g) in got.iter().enumerate() {
                let want = (x - k as f32 * 1e-3).exp();
                assert!((g - want).abs() <= want * 5e-6, "exp({x}) = {g} vs {want}");
            }
            x += 0.004;
        }
    }
}
