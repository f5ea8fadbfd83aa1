//! One 16×16 tile's blending state and the front-to-back compositing of splats into it.

use crate::camera::Camera;
use crate::fastmath::exp4;
use crate::project::{MAX_ALPHA, MIN_ALPHA, Splat};
use wide::f32x4;

/// Tile edge in pixels.
pub const TILE: usize = 16;
/// Pixels per tile.
pub const TILE_PIXELS: usize = TILE * TILE;
/// Blending stops once transmittance would fall below this.
pub const MIN_TRANSMITTANCE: f32 = 1e-4;

/// A frame's grid of tiles (the last row and column may be cut by the image edge).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileGrid {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Tiles across.
    pub tiles_x: usize,
    /// Tiles down.
    pub tiles_y: usize,
}

impl TileGrid {
    /// The grid of `camera`'s image.
    pub fn new(camera: &Camera) -> TileGrid {
        let (width, height) = (
            camera.intrinsics.width as usize,
            camera.intrinsics.height as usize,
        );
        TileGrid {
            width,
            height,
            tiles_x: width.div_ceil(TILE),
            tiles_y: height.div_ceil(TILE),
        }
    }

    /// Number of tiles.
    pub fn tiles(&self) -> usize {
        self.tiles_x * self.tiles_y
    }

    /// Top-left pixel and in-image size of tile `t`.
    pub fn tile_rect(&self, t: usize) -> (usize, usize, usize, usize) {
        let (x0, y0) = ((t % self.tiles_x) * TILE, (t / self.tiles_x) * TILE);
        (
            x0,
            y0,
            TILE.min(self.width - x0),
            TILE.min(self.height - y0),
        )
    }

    /// The pixels (x, y) of tile `t`, row by row.
    pub fn tile_pixels(&self, t: usize) -> impl Iterator<Item = (usize, usize)> + use<> {
        let (x0, y0, w, h) = self.tile_rect(t);
        (y0..y0 + h).flat_map(move |y| (x0..x0 + w).map(move |x| (x, y)))
    }
}

/// Vectors per tile row (4 pixels each).
const ROW_VECTORS: usize = TILE / 4;
/// Vectors per tile.
const VECTORS: usize = TILE_PIXELS / 4;
/// Pixels beyond a row's exact ellipse interval still visited: rounding must err outwards,
/// since each visited pixel is then tested exactly.
const ROW_SLACK: f32 = 1e-3;
/// Each lane's offset within its vector.
const LANE_X: f32x4 = f32x4::new([0.0, 1.0, 2.0, 3.0]);
/// Lane masks (all bits set in selected lanes) for each 4-bit pattern of live pixels.
const LANE_MASKS: [f32x4; 16] = {
    let mut masks = [f32x4::ZERO; 16];
    let mut bits = 0;
    while bits < 16 {
        let mut lanes = [0.0f32; 4];
        let mut l = 0;
        while l < 4 {
            if bits >> l & 1 == 1 {
                lanes[l] = f32::from_bits(u32::MAX);
            }
            l += 1;
        }
        masks[bits] = f32x4::new(lanes);
        bits += 1;
    }
    masks
};

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
    /// Per tile row, bit `lx` set while pixel `lx` is inside the image and not done.
    pub live: [u16; TILE],
    /// Pixels of the tile inside the image that are not done.
    pub remaining: usize,
}

/// Lane `l % 4` of vector `l / 4`: pixel `l = ly * 16 + lx` of a per-tile array.
#[inline]
pub fn lane(v: &[f32x4; VECTORS], l: usize) -> f32 {
    v[l / 4].to_array()[l % 4]
}

impl TileState {
    /// A fresh tile whose in-image part is `width` × `height` pixels (edge tiles are smaller
    /// than 16 × 16).
    pub fn new(width: usize, height: usize) -> TileState {
        let zero = [f32x4::ZERO; VECTORS];
        let row = ((1u32 << width.min(TILE)) - 1) as u16;
        let mut live = [0u16; TILE];
        live[..height.min(TILE)].fill(row);
        TileState {
            t: [f32x4::ONE; VECTORS],
            r: zero,
            g: zero,
            b: zero,
            wz: zero,
            median: zero,
            best_w: zero,
            instance: zero,
            live,
            remaining: width.min(TILE) * height.min(TILE),
        }
    }

    /// Resets to fresh for a tile of `width` × `height` in-image pixels.
    pub fn reset(&mut self, width: usize, height: usize) {
        *self = TileState::new(width, height);
    }

    /// True when every pixel reached the transmittance floor.
    pub fn finished(&self) -> bool {
        self.remaining == 0
    }

    /// Blends `list` (depth-bits << 32 | splat index, already front to back) into the tile whose
    /// top-left pixel is (x0, y0).
    ///
    /// Each splat visits, row by row, only the pixel centres inside its 1/255 ellipse
    /// (`RowSpans`) that are still live, four pixels at a time. The rows' intervals are
    /// solved together before any pixel is touched: they do not depend on the pixel state, so
    /// their square roots stay off the blending's critical path.
    pub fn blend(&mut self, splats: &[Splat], list: &[u64], x0: usize, y0: usize) {
        let origin = (x0 as f32 + 0.5, y0 as f32 + 0.5);
        for &entry in list {
            if self.remaining == 0 {
                return;
            }
            let sp = &splats[entry as u32 as usize];
            self.blend_splat(sp, &RowSpans::of(sp, origin), origin);
        }
    }

    /// Blends one splat into the live pixels of `span`, four at a time.
    fn blend_splat(&mut self, sp: &Splat, span: &RowSpans, origin: (f32, f32)) {
        let [a, b, c] = sp.conic;
        let (cx, cy) = (sp.x - origin.0, sp.y - origin.1);
        let splat = SplatLanes::new(sp);
        for ly in span.first_row as usize..span.end_row as usize {
            let row_bits = u32::from(self.live[ly] & span.bits[ly]);
            if row_bits == 0 {
                continue;
            }
            let dy = cy - ly as f32;
            let first = row_bits.trailing_zeros() as usize;
            let last = 31 - row_bits.leading_zeros() as usize;
            let row_part = f32x4::splat(-0.5 * c * dy * dy);
            let b_dy = f32x4::splat(b * dy);
            for gx in first / 4..=last / 4 {
                let bits = (row_bits >> (gx * 4)) & 0xf;
                if bits == 0 {
                    continue;
                }
                let dx = f32x4::splat(cx - (gx * 4) as f32) - LANE_X;
                let power = row_part - (f32x4::splat(0.5 * a) * dx + b_dy) * dx;
                self.blend_vector(&splat, ly, gx, LANE_MASKS[bits as usize], power);
            }
        }
    }

    /// Blends one splat into the live lanes (`live`) of vector `gx` of row `ly`.
    #[inline]
    fn blend_vector(&mut self, sp: &SplatLanes, ly: usize, gx: usize, live: f32x4, power: f32x4) {
        let v = ly * ROW_VECTORS + gx;
        let t = self.t[v];
        // The row interval already keeps lanes within the 1/255 ellipse, so the exact alpha
        // test is the only one (power ≤ 0 guards against rounding in the conic).
        let alpha = (sp.opacity * exp4(power)).min(f32x4::splat(MAX_ALPHA));
        let valid = live & alpha.simd_ge(f32x4::splat(MIN_ALPHA)) & power.simd_le(f32x4::ZERO);
        if valid.none() {
            return;
        }
        let next = t * (f32x4::ONE - alpha);
        let saturated = valid & next.simd_lt(f32x4::splat(MIN_TRANSMITTANCE));
        if saturated.any() {
            let bits = saturated.to_bitmask();
            self.remaining -= bits.count_ones() as usize;
            self.live[ly] &= !((bits as u16) << (gx * 4));
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
            r: f32x4::splat(s.color[0]),
            g: f32x4::splat(s.color[1]),
            b: f32x4::splat(s.color[2]),
            depth: f32x4::splat(s.depth),
            instance: f32x4::splat(f32::from_bits(s.instance)),
        }
    }
}

/// The pixels of a tile that a splat's 1/255 ellipse covers: rows `first_row..end_row`, and
/// per row a bit per pixel centre inside the ellipse.
#[derive(Clone, Copy)]
struct RowSpans {
    first_row: u8,
    end_row: u8,
    bits: [u16; TILE],
}

impl RowSpans {
    const EMPTY: RowSpans = RowSpans {
        first_row: 0,
        end_row: 0,
        bits: [0; TILE],
    };

    /// The span of `sp` in the tile whose first pixel centre is `origin`.
    ///
    /// In row dy the pixels with a dx² + 2b dx dy + c dy² ≤ cutoff (dx = cx − lx) are
    /// lx ∈ mid ± half with mid = cx + (b/a) dy, half = √(disc)/a and
    /// disc = a·cutoff − (ac − b²) dy², widened by a hair so that no boundary pixel is lost
    /// (each covered pixel is then tested exactly). Four rows are solved at a time.
    fn of(sp: &Splat, origin: (f32, f32)) -> RowSpans {
        let [a, b, c] = sp.conic;
        let (cx, cy) = (sp.x - origin.0, sp.y - origin.1);
        let reach_y = sp.extent[1] + ROW_SLACK;
        let mut span = RowSpans::EMPTY;
        if cy + reach_y < 0.0 {
            return span;
        }
        let first_row = floor_index(cy - reach_y + 1.0);
        let end_row = (floor_index(cy + reach_y) + 1).min(TILE);
        span.first_row = first_row as u8;
        span.end_row = end_row.max(first_row) as u8;
        let (det, inv_a) = (a * c - b * b, 1.0 / a);
        let splat = f32x4::splat;
        let mut ly = first_row;
        while ly < end_row {
            let dy = splat(cy) - (splat(ly as f32) + LANE_X);
            let disc = splat(a * sp.cutoff) - splat(det) * dy * dy;
            let half = disc.max(f32x4::ZERO).sqrt() * splat(inv_a) + splat(ROW_SLACK);
            let mid = splat(cx) + splat(b * inv_a) * dy;
            let lo = (mid - half + f32x4::ONE)
                .max(f32x4::ZERO)
                .min(splat(TILE as f32));
            let (lo, hi) = (lo.to_array(), (mid + half).to_array());
            let inside = disc.simd_ge(f32x4::ZERO).to_bitmask();
            for k in 0..4 {
                let row = ly + k;
                if row >= end_row || inside >> k & 1 == 0 || hi[k] < 0.0 {
                    continue;
                }
                // Truncation floors here: both bounds are non-negative.
                let first = lo[k] as usize;
                let last = hi[k].min((TILE - 1) as f32) as usize;
                if first <= last {
                    span.bits[row] = ((u32::MAX >> (31 - last)) & !((1u32 << first) - 1)) as u16;
                }
            }
            ly += 4;
        }
        span
    }
}

/// ⌊x⌋ clamped to 0 … 16 (a pixel index within a tile, or one past the end), without the
/// library call: truncation floors once x is clamped to be non-negative.
#[inline]
fn floor_index(x: f32) -> usize {
    x.clamp(0.0, TILE as f32) as i32 as usize
}
