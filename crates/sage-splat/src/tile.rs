//! One 16×16 tile's blending state and the front-to-back compositing of splats into it.

use crate::project::{MAX_ALPHA, MIN_ALPHA, Splat};

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Pixels per tile.
pub const TILE_PIXELS: usize = TILE * TILE;
/// Blending stops once transmittance would fall below this.
pub const MIN_TRANSMITTANCE: f32 = 1e-4;

/// Per-pixel accumulators of one tile, kept across depth slabs.
#[derive(Clone)]
pub struct TileState {
    /// Transmittance.
    pub t: [f32; TILE_PIXELS],
    /// Σ w · colour.
    pub rgb: [[f32; 3]; TILE_PIXELS],
    /// Σ w · z.
    pub wz: [f32; TILE_PIXELS],
    /// Σ w.
    pub w: [f32; TILE_PIXELS],
    /// z where transmittance first fell to 0.5 or below (0 until then).
    pub median: [f32; TILE_PIXELS],
    /// The largest weight so far.
    pub best_w: [f32; TILE_PIXELS],
    /// Instance of the largest weight.
    pub instance: [u32; TILE_PIXELS],
    /// Pixels that reached the transmittance floor.
    pub done: [bool; TILE_PIXELS],
    /// Pixels of the tile inside the image that are not done.
    pub remaining: usize,
}

impl TileState {
    /// A fresh tile holding `pixels` image pixels (edge tiles hold fewer than 256).
    pub fn new(pixels: usize) -> TileState {
        TileState {
            t: [1.0; TILE_PIXELS],
            rgb: [[0.0; 3]; TILE_PIXELS],
            wz: [0.0; TILE_PIXELS],
            w: [0.0; TILE_PIXELS],
            median: [0.0; TILE_PIXELS],
            best_w: [0.0; TILE_PIXELS],
            instance: [0; TILE_PIXELS],
            done: [false; TILE_PIXELS],
            remaining: pixels,
        }
    }

    /// Resets to fresh for a tile of `pixels` pixels.
    pub fn reset(&mut self, pixels: usize) {
        self.t = [1.0; TILE_PIXELS];
        self.rgb = [[0.0; 3]; TILE_PIXELS];
        self.wz = [0.0; TILE_PIXELS];
        self.w = [0.0; TILE_PIXELS];
        self.median = [0.0; TILE_PIXELS];
        self.best_w = [0.0; TILE_PIXELS];
        self.instance = [0; TILE_PIXELS];
        self.done = [false; TILE_PIXELS];
        self.remaining = pixels;
    }

    /// True when every pixel reached the transmittance floor.
    pub fn finished(&self) -> bool {
        self.remaining == 0
    }

    /// Blends `list` (splat indices into `splats`, already front to back) into the tile whose
    /// top-left pixel is (x0, y0) and whose in-image size is tw × th.
    ///
    /// Each splat visits, row by row, only the pixel centres inside its 1/255 ellipse (the
    /// exact interval of the quadratic form, widened by a hair so no boundary pixel is lost).
    pub fn blend(
        &mut self,
        splats: &[Splat],
        list: &[(u32, u32)],
        x0: usize,
        y0: usize,
        tw: usize,
        th: usize,
    ) {
        for &(_, si) in list {
            if self.remaining == 0 {
                return;
            }
            let sp = &splats[si as usize];
            let [a, b, c] = sp.conic;
            // Float-to-int casts truncate; with the max(0) first they floor (floorf and ceilf
            // are library calls on baseline x86-64, too slow for this loop).
            let ly0 = ((sp.y - sp.radius - y0 as f32 - 0.5).max(0.0) as usize).min(th);
            let ly1 = ((sp.y + sp.radius - y0 as f32 + 1.5).max(0.0) as usize).min(th);
            for ly in ly0..ly1 {
                let py = (y0 + ly) as f32 + 0.5;
                let dy = sp.y - py;
                // a dx² + 2 b dy dx + (c dy² − cutoff) ≤ 0.
                let disc = b * b * dy * dy - a * (c * dy * dy - sp.cutoff);
                if disc < 0.0 {
                    continue;
                }
                let root = disc.sqrt();
                let (dx_lo, dx_hi) = ((-b * dy - root) / a, (-b * dy + root) / a);
                // Pixel centres x0 + lx + 0.5 inside [sp.x − dx_hi, sp.x − dx_lo], widened by a hair.
                let first = ceil_index(sp.x - dx_hi - x0 as f32 - 0.5 - 1e-3);
                let last = floor_index(sp.x - dx_lo - x0 as f32 - 0.5 + 1e-3)
                    .wrapping_add(1)
                    .min(tw);
                for lx in first..last {
                    let l = ly * TILE + lx;
                    if self.done[l] {
                        continue;
                    }
                    let power = sp.power((x0 + lx) as f32 + 0.5, py);
                    if power > 0.0 {
                        continue;
                    }
                    let alpha = (sp.opacity * fast_exp(power)).min(MAX_ALPHA);
                    if alpha < MIN_ALPHA {
                        continue;
                    }
                    let t = self.t[l];
                    let next = t * (1.0 - alpha);
                    if next < MIN_TRANSMITTANCE {
                        self.done[l] = true;
                        self.remaining -= 1;
                        continue;
                    }
                    let w = alpha * t;
                    for k in 0..3 {
                        self.rgb[l][k] += w * sp.color[k];
                    }
                    self.wz[l] += w * sp.depth;
                    self.w[l] += w;
                    if t > 0.5 && next <= 0.5 {
                        self.median[l] = sp.depth;
                    }
                    if w > self.best_w[l] {
                        self.best_w[l] = w;
                        self.instance[l] = sp.instance;
                    }
                    self.t[l] = next;
                }
            }
        }
    }
}

/// ⌈v⌉ clamped at 0, without the library call `ceilf` (slow on baseline x86-64).
#[inline]
fn ceil_index(v: f32) -> usize {
    if v <= 0.0 {
        return 0;
    }
    let t = v as usize;
    if (t as f32) < v { t + 1 } else { t }
}

/// ⌊v⌋ for v ≥ 0; negative values give `usize::MAX` wrapped to an empty range by the caller's
/// `+ 1` (so they read as "before pixel 0").
#[inline]
fn floor_index(v: f32) -> usize {
    if v < 0.0 { usize::MAX } else { v as usize }
}

/// e^x for x ≤ 0 down to about −87, with relative error below 2e-5: 2^(x log₂e) split into an
/// exponent and a degree-6 polynomial of the fraction. The blending loop calls it for every
/// pixel a splat reaches, so it matters more than anything else for speed.
#[inline]
pub fn fast_exp(x: f32) -> f32 {
    let y = (x * std::f32::consts::LOG2_E).max(-126.0);
    // floor without a library call: truncate, then step down for negative fractions.
    let t = y as i32;
    let n = if (t as f32) > y { t - 1 } else { t };
    let f = y - n as f32;
    let p = 1.0
        + f * (std::f32::consts::LN_2
            + f * (0.240_226_5
                + f * (0.055_504_11
                    + f * (0.009_618_129 + f * (0.001_333_355_8 + f * 0.000_154_035_3)))));
    f32::from_bits(((n + 127) as u32) << 23) * p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_exp_is_accurate_where_it_is_used() {
        let mut x = -20.0f32;
        while x <= 0.0 {
            let (a, b) = (fast_exp(x), x.exp());
            assert!((a - b).abs() <= b * 2e-5, "exp({x}) = {a} vs {b}");
            x += 0.001;
        }
    }
}
