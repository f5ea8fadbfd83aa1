//! The differentiable rasteriser's forward pass: the image formation of `sage-splat` (EWA
//! projection with the 1.3× Jacobian clamp and the 0.3 px² low-pass, SH colour from the camera
//! centre, 16×16 tiles, front-to-back blending with alpha = min(0.99, o·e^power), skip below
//! 1/255, stop before transmittance falls under 1e-4), written in plain f32 and keeping what
//! the backward pass needs: every splat's projection inputs and, per pixel, the final
//! transmittance and how far down its tile's list it blended.

use crate::params::{Param, Params, sigmoid};
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use sage_splat::Camera;
use sage_splat::project::{LOW_PASS, MAX_ALPHA, MIN_ALPHA};
use sage_splat::sh::C0;
use sage_splat::tile::{MIN_TRANSMITTANCE, TILE, TileGrid};

/// `Y_1` basis constant.
pub(crate) const C1: f32 = 0.488_602_52;

/// One Gaussian projected into one view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projected {
    /// The Gaussian's index in [`Params::rows`].
    pub index: u32,
    /// Centre in pixels.
    pub mean: [f32; 2],
    /// Inverse 2-D covariance (a, b, c): power = −½(a dx² + c dy²) − b dx dy.
    pub conic: [f32; 3],
    /// 2-D covariance (xx, xy, yy) including the low-pass.
    pub cov: [f32; 3],
    /// Opacity after the sigmoid.
    pub opacity: f32,
    /// Colour (≥ 0).
    pub color: [f32; 3],
    /// Per channel, whether the colour was clamped at 0 (no gradient flows there).
    pub color_clamped: [bool; 3],
    /// Camera-space centre.
    pub t: Vec3,
    /// Half-width and half-height of the 1/255 ellipse's box (pixels).
    pub extent: [f32; 2],
    /// Radius of the 3σ circle of the larger axis (pixels): the screen size densification
    /// prunes by.
    pub radius: f32,
    /// A power below which alpha is certainly under 1/255 (−½ of the 1/255 Mahalanobis
    /// distance², less a margin): most pixels of a tile are rejected here without an `exp`.
    pub min_power: f32,
}

/// The camera quantities every projection of a view shares.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ViewGeometry {
    /// World → camera rotation (rows: right, down, forward).
    pub w2c: Mat3,
    pub position: Vec3,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// x/z and y/z limits of the Jacobian clamp.
    pub lim: [f32; 2],
    pub near: f32,
    pub far: f32,
    pub width: f32,
    pub height: f32,
}

impl ViewGeometry {
    pub fn new(camera: &Camera) -> ViewGeometry {
        let k = camera.intrinsics;
        ViewGeometry {
            w2c: camera.rotation.transpose(),
            position: camera.position,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            lim: [
                1.3 * (k.width as f32 * 0.5) / k.fx,
                1.3 * (k.height as f32 * 0.5) / k.fy,
            ],
            near: camera.near,
            far: camera.far,
            width: k.width as f32,
            height: k.height as f32,
        }
    }

    /// The clamped x/z and y/z of a camera-space point, and whether each was clamped.
    pub fn clamped_slopes(&self, t: Vec3) -> ([f32; 2], [bool; 2]) {
        let (sx, sy) = (t.x / t.z, t.y / t.z);
        let ux = sx.clamp(-self.lim[0], self.lim[0]);
        let uy = sy.clamp(-self.lim[1], self.lim[1]);
        ([ux, uy], [ux != sx, uy != sy])
    }

    /// The rows of M = J·W (the pinhole Jacobian at the clamped mean times world → camera).
    pub fn jw_rows(&self, t: Vec3, u: [f32; 2]) -> [Vec3; 2] {
        let (right, down, forward) = (self.w2c.row(0), self.w2c.row(1), self.w2c.row(2));
        [
            (right - forward * u[0]) * (self.fx / t.z),
            (down - forward * u[1]) * (self.fy / t.z),
        ]
    }
}

/// The columns of the rotation matrix of a unit quaternion (w, x, y, z).
pub(crate) fn rotation_columns([w, x, y, z]: [f32; 4]) -> [Vec3; 3] {
    [
        Vec3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y + w * z),
            2.0 * (x * z - w * y),
        ),
        Vec3::new(
            2.0 * (x * y - w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z + w * x),
        ),
        Vec3::new(
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ),
    ]
}

/// The quaternion scaled to unit length (w, x, y, z) and its original length.
pub(crate) fn normalized(q: [f32; 4]) -> ([f32; 4], f32) {
    let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
    (q.map(|v| v / n), n)
}

/// The SH degree-1 basis along unit direction `d` (the sign convention of `sage_splat::sh`).
pub(crate) fn sh1_basis(d: Vec3) -> [f32; 3] {
    [-C1 * d.y, C1 * d.z, -C1 * d.x]
}

/// Projects one Gaussian, or `None` where the renderer would drop it: centre outside the clip
/// range, opacity below 1/255, a degenerate covariance, or a footprint off the image.
pub(crate) fn project(p: &Param, index: u32, sh_degree: u8, v: &ViewGeometry) -> Option<Projected> {
    let mean = Vec3::from_array(p.mean);
    let t = v.w2c * (mean - v.position);
    if !(t.z >= v.near && t.z <= v.far) {
        return None;
    }
    let opacity = sigmoid(p.opacity_logit);
    if opacity < MIN_ALPHA {
        return None;
    }
    let (u, _) = v.clamped_slopes(t);
    let [m0, m1] = v.jw_rows(t, u);
    let (q, _) = normalized(p.rotation);
    let axes = rotation_columns(q);
    let (mut a, mut b, mut c) = (LOW_PASS, 0.0, LOW_PASS);
    for (axis, ls) in axes.iter().zip(p.log_scale) {
        let variance = (2.0 * ls).exp();
        let (d0, d1) = (axis.dot(m0), axis.dot(m1));
        a += variance * d0 * d0;
        b += variance * d0 * d1;
        c += variance * d1 * d1;
    }
    let det = a * c - b * b;
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let cutoff = 2.0 * (255.0 * opacity).ln() + 1e-3;
    let extent = [(cutoff * a).sqrt(), (cutoff * c).sqrt()];
    let x = v.fx * t.x / t.z + v.cx;
    let y = v.fy * t.y / t.z + v.cy;
    if x + extent[0] < 0.0
        || x - extent[0] > v.width
        || y + extent[1] < 0.0
        || y - extent[1] > v.height
    {
        return None;
    }
    let mid = 0.5 * (a + c);
    let lambda_max = mid + (mid * mid - det).max(0.0).sqrt();
    let mut raw = Vec3::from_array(p.sh_dc) * C0 + Vec3::splat(0.5);
    if sh_degree >= 1 {
        let basis = sh1_basis((mean - v.position).normalize_or_zero());
        for (coeff, y) in p.sh_rest.iter().zip(basis) {
            raw += Vec3::from_array(*coeff) * y;
        }
    }
    let raw = raw.to_array();
    Some(Projected {
        index,
        mean: [x, y],
        conic: [c / det, -b / det, a / det],
        cov: [a, b, c],
        opacity,
        color: raw.map(|r| r.max(0.0)),
        color_clamped: raw.map(|r| r < 0.0),
        t,
        extent,
        radius: 3.0 * lambda_max.sqrt(),
        min_power: -0.5 * cutoff - 1e-3,
    })
}

impl Projected {
    /// The exponent at pixel centre (px, py).
    #[inline]
    pub fn power(&self, px: f32, py: f32) -> f32 {
        let (dx, dy) = (self.mean[0] - px, self.mean[1] - py);
        -0.5 * (self.conic[0] * dx * dx + self.conic[2] * dy * dy) - self.conic[1] * dx * dy
    }

    /// The tile rectangle [x0, y0, x1, y1] (inclusive) of the 1/255 box, clamped to the grid.
    fn tiles(&self, grid: &TileGrid) -> [usize; 4] {
        let tile = |p: f32, n: usize| ((p / TILE as f32).max(0.0) as usize).min(n - 1);
        [
            tile(self.mean[0] - self.extent[0], grid.tiles_x),
            tile(self.mean[1] - self.extent[1], grid.tiles_y),
            tile(self.mean[0] + self.extent[0], grid.tiles_x),
            tile(self.mean[1] + self.extent[1], grid.tiles_y),
        ]
    }
}

/// One view rendered by the forward pass, with what the backward pass needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The tile grid.
    pub grid: TileGrid,
    /// The Gaussians that survived projection, in index order.
    pub splats: Vec<Projected>,
    /// Start of each tile's list in `lists` (one more entry than tiles).
    pub tile_start: Vec<u32>,
    /// Per tile, indices into `splats` front to back (by depth, then index).
    pub lists: Vec<u32>,
    /// Blended colour plus background, `height × width × 3` (not clamped).
    pub rgb: Vec<f32>,
    /// Final transmittance per pixel.
    pub final_t: Vec<f32>,
    /// Per pixel, one past the last entry of its tile's list that it blended.
    pub last: Vec<u32>,
    /// The background colour.
    pub background: [f32; 3],
}

/// Renders `params` from `camera` over `background`.
pub fn forward(params: &Params, camera: &Camera, background: [f32; 3]) -> Frame {
    let grid = TileGrid::new(camera);
    let view = ViewGeometry::new(camera);
    let splats: Vec<Projected> = params
        .rows
        .par_iter()
        .enumerate()
        .filter_map(|(i, p)| project(p, i as u32, params.sh_degree, &view))
        .collect();
    let (tile_start, lists) = bin(&splats, &grid);
    let n_tiles = grid.tiles_x * grid.tiles_y;
    let tiles: Vec<Vec<(f32, [f32; 3], u32)>> = (0..n_tiles)
        .into_par_iter()
        .map(|t| {
            let list = &lists[tile_start[t] as usize..tile_start[t + 1] as usize];
            grid.tile_pixels(t)
                .map(|(x, y)| blend_pixel(&splats, list, x as f32 + 0.5, y as f32 + 0.5))
                .collect()
        })
        .collect();
    let n = grid.width * grid.height;
    let mut frame = Frame {
        grid,
        rgb: vec![0.0; n * 3],
        final_t: vec![0.0; n],
        last: vec![0; n],
        splats,
        tile_start,
        lists,
        background,
    };
    for (t, pixels) in tiles.into_iter().enumerate() {
        for ((x, y), (final_t, color, last)) in grid.tile_pixels(t).zip(pixels) {
            let p = y * grid.width + x;
            for c in 0..3 {
                frame.rgb[p * 3 + c] = color[c] + final_t * background[c];
            }
            frame.final_t[p] = final_t;
            frame.last[p] = last;
        }
    }
    frame
}

/// Blends one pixel: its final transmittance, colour (without background) and one past the
/// last list entry blended.
fn blend_pixel(splats: &[Projected], list: &[u32], px: f32, py: f32) -> (f32, [f32; 3], u32) {
    let (mut t, mut color, mut last) = (1.0f32, [0.0f32; 3], 0);
    for (k, &s) in list.iter().enumerate() {
        let sp = &splats[s as usize];
        let Some(alpha) = sp.alpha_at(px, py) else {
            continue;
        };
        let next = t * (1.0 - alpha);
        if next < MIN_TRANSMITTANCE {
            break;
        }
        for (acc, c) in color.iter_mut().zip(sp.color) {
            *acc += alpha * t * c;
        }
        t = next;
        last = k as u32 + 1;
    }
    (t, color, last)
}

impl Projected {
    /// The alpha this splat blends with at pixel centre (px, py), or `None` where it is skipped
    /// (power above 0 from rounding, or alpha below 1/255).
    #[inline]
    pub fn alpha_at(&self, px: f32, py: f32) -> Option<f32> {
        let power = self.power(px, py);
        if power > 0.0 || power < self.min_power {
            return None;
        }
        let alpha = (self.opacity * power.exp()).min(MAX_ALPHA);
        (alpha >= MIN_ALPHA).then_some(alpha)
    }
}

/// Tile lists: every splat in each tile of its 1/255 box, each list sorted front to back
/// (depth, then splat index — the renderer's order).
fn bin(splats: &[Projected], grid: &TileGrid) -> (Vec<u32>, Vec<u32>) {
    let n_tiles = grid.tiles_x * grid.tiles_y;
    let mut start = vec![0u32; n_tiles + 1];
    let rects: Vec<[usize; 4]> = splats.iter().map(|s| s.tiles(grid)).collect();
    for r in &rects {
        for ty in r[1]..=r[3] {
            for tx in r[0]..=r[2] {
                start[ty * grid.tiles_x + tx + 1] += 1;
            }
        }
    }
    for t in 0..n_tiles {
        start[t + 1] += start[t];
    }
    let mut cursor = start[..n_tiles].to_vec();
    let mut lists = vec![0u32; start[n_tiles] as usize];
    for (s, r) in rects.iter().enumerate() {
        for ty in r[1]..=r[3] {
            for tx in r[0]..=r[2] {
                let slot = &mut cursor[ty * grid.tiles_x + tx];
                lists[*slot as usize] = s as u32;
                *slot += 1;
            }
        }
    }
    for t in 0..n_tiles {
        lists[start[t] as usize..start[t + 1] as usize].sort_by(|&a, &b| {
            splats[a as usize]
                .t
                .z
                .total_cmp(&splats[b as usize].t.z)
                .then(a.cmp(&b))
        });
    }
    (start, lists)
}
