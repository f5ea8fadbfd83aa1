//! The tile renderer. Per frame:
//!
//! 1. **cull**: chunks outside the view volume are dropped; the rest are ordered by their
//!    nearest depth and given a conservative screen rectangle;
//! 2. the depth range is cut into slabs (at quantiles of the chunks' nearest depths), and for
//!    each slab, front to back:
//!    - **project** the Gaussians of the chunks that reach the slab, keeping those whose depth
//!      falls in it (chunks whose rectangle covers only finished tiles are skipped: every pixel
//!      there already reached the transmittance floor, so nothing behind can show);
//!    - **sort**: bin the splats into the unfinished 16×16 tiles they touch (exact
//!      ellipse–tile test) and order each tile's list by depth key
//!      ([`Camera::depth_key`]), ties in Gaussian order, as the GPU renderer orders it;
//!    - **raster**: blend each tile's list into its persistent per-pixel state.
//!
//! Because slabs partition depth and each tile is blended strictly front to back, the result is
//! exactly that of blending every Gaussian in depth order; it is also the same for any thread
//! count (all orders are by depth, then by a deterministic splat index).

use crate::camera::Camera;
use crate::fastmath::{exp_fast, sigmoid};
use crate::index::{CHUNK, MAX_SIGMAS, SplatIndex};
use crate::project::{Gaussians4, MIN_ALPHA, Splat, project4};
use crate::sh;
use crate::tile::{TILE, TileGrid, TileState, lane};
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use sage_core::{Aabb, Error, Result};
use sage_scene::Gaussians;
use sage_scene::gaussians::{LOG_SCALE_STEP, sh_rest_count};
use std::sync::Arc;
use std::time::Instant;
use wide::f32x4;

/// Depth slabs per frame (at most).
const SLABS: usize = 8;

/// Options of one render.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderOptions {
    /// Colour behind everything (linear 0–1); black by default.
    pub background: [f32; 3],
    /// The images to return (every one by default); the others come back empty.
    pub channels: Channels,
}

/// Which images of a [`RenderOutput`] a render fills, as a simulator's sensors are chosen:
/// an image not asked for comes back as an empty vector. The image formation is the same
/// whatever is asked for; asking for less saves the host the images' memory and, on the GPU,
/// the read-back (RGB and median depth are 8 bytes per pixel, every image 32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Channels {
    /// [`RenderOutput::rgb`].
    pub rgb: bool,
    /// [`RenderOutput::rgb_f32`].
    pub rgb_f32: bool,
    /// [`RenderOutput::alpha`].
    pub alpha: bool,
    /// [`RenderOutput::depth_expected`].
    pub depth_expected: bool,
    /// [`RenderOutput::depth_median`].
    pub depth_median: bool,
    /// [`RenderOutput::instance`].
    pub instance: bool,
    /// [`RenderOutput::semantic`].
    pub semantic: bool,
}

impl Channels {
    /// Every image.
    pub const ALL: Channels = Channels {
        rgb: true,
        rgb_f32: true,
        alpha: true,
        depth_expected: true,
        depth_median: true,
        instance: true,
        semantic: true,
    };

    /// No image (set the ones wanted: `Channels { rgb: true, ..Channels::NONE }`).
    pub const NONE: Channels = Channels {
        rgb: false,
        rgb_f32: false,
        alpha: false,
        depth_expected: false,
        depth_median: false,
        instance: false,
        semantic: false,
    };

    /// 8-bit colour only.
    pub const RGB: Channels = Channels {
        rgb: true,
        ..Channels::NONE
    };

    /// Each image's name: its [`RenderOutput`] field, in the order of [`Channels::flags`].
    const NAMES: [&'static str; 7] = [
        "rgb",
        "rgb_f32",
        "alpha",
        "depth_expected",
        "depth_median",
        "instance",
        "semantic",
    ];

    /// Each image's flag, in the order of [`Channels::NAMES`].
    fn flags(&mut self) -> [&mut bool; 7] {
        [
            &mut self.rgb,
            &mut self.rgb_f32,
            &mut self.alpha,
            &mut self.depth_expected,
            &mut self.depth_median,
            &mut self.instance,
            &mut self.semantic,
        ]
    }
}

impl Default for Channels {
    fn default() -> Channels {
        Channels::ALL
    }
}

impl std::str::FromStr for Channels {
    type Err = Error;

    /// A comma-separated list of [`RenderOutput`] field names (`rgb,depth_median`), `all` or
    /// `none`.
    fn from_str(s: &str) -> Result<Channels> {
        let mut out = Channels::NONE;
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match (name, Channels::NAMES.iter().position(|n| *n == name)) {
                ("all", _) => out = Channels::ALL,
                ("none", _) => {}
                (_, Some(k)) => *out.flags()[k] = true,
                (other, None) => {
                    return Err(Error::invalid(format!(
                        "unknown image {other:?}: expected all, none or some of {}",
                        Channels::NAMES.join(", ")
                    )));
                }
            }
        }
        Ok(out)
    }
}

impl std::fmt::Display for Channels {
    /// `all`, or the names of the images asked for, comma-separated (`none` for none).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if *self == Channels::ALL {
            return f.write_str("all");
        }
        let mut flags = *self;
        let names: Vec<&str> = Channels::NAMES
            .into_iter()
            .zip(flags.flags())
            .filter_map(|(n, on)| on.then_some(n))
            .collect();
        if names.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&names.join(","))
        }
    }
}

/// The images of one render, row-major, `height × width` (RGB: × 3); an image not in the
/// render's [`Channels`] is empty.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOutput {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Colour, 8-bit (the blended colour clamped to 0–1).
    pub rgb: Vec<u8>,
    /// Colour before quantisation (0 and up).
    pub rgb_f32: Vec<f32>,
    /// Accumulated alpha, 1 − final transmittance.
    pub alpha: Vec<f32>,
    /// Expected z-depth (metres along the optical axis): Σ wᵢ zᵢ / Σ wᵢ, 0 where nothing was hit.
    pub depth_expected: Vec<f32>,
    /// Median z-depth: z of the Gaussian at which transmittance first drops to 0.5 or below;
    /// 0 where it never does (alpha < 0.5).
    pub depth_median: Vec<f32>,
    /// Instance id of the Gaussian with the largest blending weight (0 where nothing was hit).
    pub instance: Vec<u32>,
    /// Category id of that instance (0 where nothing was hit).
    pub semantic: Vec<u16>,
}

impl RenderOutput {
    /// These images with those not in `channels` emptied: what a render asking for `channels`
    /// returns.
    pub fn keep(mut self, channels: &Channels) -> RenderOutput {
        fn keep<T>(image: &mut Vec<T>, on: bool) {
            if !on {
                *image = Vec::new();
            }
        }
        keep(&mut self.rgb, channels.rgb);
        keep(&mut self.rgb_f32, channels.rgb_f32);
        keep(&mut self.alpha, channels.alpha);
        keep(&mut self.depth_expected, channels.depth_expected);
        keep(&mut self.depth_median, channels.depth_median);
        keep(&mut self.instance, channels.instance);
        keep(&mut self.semantic, channels.semantic);
        self
    }

    /// Images of `width × height` filled with zeros, the ones not in `channels` empty.
    pub(crate) fn sized(width: usize, height: usize, channels: &Channels) -> RenderOutput {
        let n = width * height;
        let image = |on: bool, len: usize| if on { len } else { 0 };
        RenderOutput {
            width,
            height,
            rgb: vec![0; image(channels.rgb, n * 3)],
            rgb_f32: vec![0.0; image(channels.rgb_f32, n * 3)],
            alpha: vec![0.0; image(channels.alpha, n)],
            depth_expected: vec![0.0; image(channels.depth_expected, n)],
            depth_median: vec![0.0; image(channels.depth_median, n)],
            instance: vec![0; image(channels.instance, n)],
            semantic: vec![0; image(channels.semantic, n)],
        }
    }
}

/// A blended colour channel as the 8-bit value of [`RenderOutput::rgb`]: clamped to 0–1,
/// scaled to 255 and rounded half away from zero, as `f32::round` does. Both executors
/// quantise through here (the GPU, when it packs the bytes itself, through `to_byte` of
/// `splat.wgsl`, the same rounding: a GPU test holds the two to the same bytes). Adding the
/// half in `f64`, where the sum of any `f32` and 0.5 is exact, and truncating gives that
/// rounding without a call to `roundf`, which the baseline x86-64 target has no instruction
/// for.
pub(crate) fn to_byte(v: f32) -> u8 {
    (f64::from(v.clamp(0.0, 1.0) * 255.0) + 0.5) as u8
}

/// Where the time of the last render went (milliseconds) and how much work there was.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderStats {
    /// Chunk frustum culling and ordering.
    pub cull_ms: f64,
    /// Projection and SH colour.
    pub project_ms: f64,
    /// Tile binning and per-tile depth sorting.
    pub sort_ms: f64,
    /// Blending, and assembling the images.
    pub raster_ms: f64,
    /// Chunks that passed frustum culling.
    pub visible_chunks: usize,
    /// Gaussians examined in visible chunks: inside the depth range of a slab, before the
    /// screen, finished-tile and opacity tests (summed over slabs).
    pub examined: usize,
    /// Splats after projection.
    pub splats: usize,
    /// (splat, tile) pairs.
    pub tile_entries: usize,
}

/// A visible chunk: its depth range along the optical axis and its screen rectangle in tiles.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ChunkView {
    chunk: u32,
    z_min: f32,
    z_max: f32,
    tiles: [usize; 4],
}

/// A renderer for one set of Gaussians: the spatial index plus buffers reused across frames.
pub struct Renderer {
    index: Arc<SplatIndex>,
    count: usize,
    visible: Vec<u32>,
    views: Vec<ChunkView>,
    splats: Vec<Splat>,
    scratch: Vec<Splat>,
    per_chunk: Vec<u32>,
    blocks: Vec<Vec<(u32, u32)>>,
    tile_entries: Vec<u64>,
    tile_start: Vec<u32>,
    tiles: Vec<TileState>,
    finished_sum: Vec<u32>,
    stats: RenderStats,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Depth range and a conservative tile rectangle (grown by one tile) of a chunk's bounds.
fn chunk_view(chunk: u32, b: &Aabb, camera: &Camera, w2c: &Mat3, grid: &TileGrid) -> ChunkView {
    let corners = (0..8).map(|k| {
        let p = Vec3::new(
            if k & 1 == 0 { b.min.x } else { b.max.x },
            if k & 2 == 0 { b.min.y } else { b.max.y },
            if k & 4 == 0 { b.min.z } else { b.max.z },
        );
        *w2c * (p - camera.position)
    });
    let (mut z_min, mut z_max) = (f32::INFINITY, f32::NEG_INFINITY);
    let (mut u0, mut v0, mut u1, mut v1) = (
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    );
    let mut straddles = false;
    for c in corners {
        z_min = z_min.min(c.z);
        z_max = z_max.max(c.z);
        if c.z < camera.near * 0.5 {
            straddles = true;
            continue;
        }
        let (u, v) = camera.project(c);
        (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
    }
    let full = [0, 0, grid.tiles_x - 1, grid.tiles_y - 1];
    let tiles = if straddles {
        full
    } else {
        let tile =
            |v: f32, n: usize| ((v / TILE as f32).floor().max(-1.0) as isize).clamp(-1, n as isize);
        let (x0, y0) = (tile(u0, grid.tiles_x) - 1, tile(v0, grid.tiles_y) - 1);
        let (x1, y1) = (tile(u1, grid.tiles_x) + 1, tile(v1, grid.tiles_y) + 1);
        [
            x0.clamp(0, full[2] as isize) as usize,
            y0.clamp(0, full[3] as isize) as usize,
            x1.clamp(0, full[2] as isize) as usize,
            y1.clamp(0, full[3] as isize) as usize,
        ]
    };
    ChunkView {
        chunk,
        z_min,
        z_max,
        tiles,
    }
}

impl Renderer {
    /// Indexes `gaussians` (Morton chunks) for rendering.
    pub fn new(gaussians: &Gaussians) -> Renderer {
        Renderer::with_index(Arc::new(SplatIndex::build(gaussians)), gaussians.len())
    }

    /// A renderer over the index of `count` Gaussians built already (shared by the renderers
    /// of a [`crate::RendererPool`]).
    pub(crate) fn with_index(index: Arc<SplatIndex>, count: usize) -> Renderer {
        Renderer {
            index,
            count,
            visible: Vec::new(),
            views: Vec::new(),
            splats: Vec::new(),
            scratch: Vec::new(),
            per_chunk: Vec::new(),
            blocks: Vec::new(),
            tile_entries: Vec::new(),
            tile_start: Vec::new(),
            tiles: Vec::new(),
            finished_sum: Vec::new(),
            stats: RenderStats::default(),
        }
    }

    /// How many Gaussians it was built for.
    pub fn gaussian_count(&self) -> usize {
        self.count
    }

    /// The spatial index.
    pub fn index(&self) -> &SplatIndex {
        &self.index
    }

    /// Timings and counts of the last render.
    pub fn stats(&self) -> RenderStats {
        self.stats
    }

    /// Renders `gaussians` (the same set the renderer was built for) from `camera`.
    /// `categories[instance]` gives the semantic id of each instance (missing → 0).
    pub fn render(
        &mut self,
        gaussians: &Gaussians,
        categories: &[u16],
        camera: &Camera,
        options: &RenderOptions,
    ) -> Result<RenderOutput> {
        if gaussians.len() != self.count {
            return Err(Error::invalid(format!(
                "renderer was built for {} Gaussians, asked to render {}",
                self.count,
                gaussians.len()
            )));
        }
        camera.validate()?;
        self.stats = RenderStats::default();
        let grid = TileGrid::new(camera);
        let w2c = camera.rotation.transpose();

        let start = Instant::now();
        self.index.visible_chunks(camera, &mut self.visible);
        let bounds = &self.index.bounds;
        self.views = self
            .visible
            .par_iter()
            .map(|&c| chunk_view(c, &bounds[c as usize], camera, &w2c, &grid))
            .collect();
        self.views
            .sort_by(|a, b| a.z_min.total_cmp(&b.z_min).then(a.chunk.cmp(&b.chunk)));
        self.stats.visible_chunks = self.views.len();
        self.reset_tiles(&grid);
        self.stats.cull_ms = ms(start);

        for (lo, hi) in slab_bounds(&self.views) {
            self.update_finished(&grid);
            let start = Instant::now();
            self.project_slab(gaussians, camera, &w2c, &grid, lo, hi);
            self.stats.project_ms += ms(start);
            if self.splats.is_empty() {
                continue;
            }
            let start = Instant::now();
            self.bin(camera, &grid);
            self.stats.sort_ms += ms(start);
            let start = Instant::now();
            self.blend(&grid);
            self.stats.raster_ms += ms(start);
        }
        let start = Instant::now();
        let out = self.assemble(&grid, categories, options);
        self.stats.raster_ms += ms(start);
        Ok(out)
    }

    fn reset_tiles(&mut self, grid: &TileGrid) {
        let n = grid.tiles();
        self.tiles.truncate(n);
        self.tiles.par_iter_mut().enumerate().for_each(|(t, s)| {
            let (_, _, tw, th) = grid.tile_rect(t);
            s.reset(tw, th);
        });
        for t in self.tiles.len()..n {
            let (_, _, tw, th) = grid.tile_rect(t);
            self.tiles.push(TileState::new(tw, th));
        }
    }

    /// Summed-area table of finished tiles, for O(1) "is this rectangle all finished" queries.
    fn update_finished(&mut self, grid: &TileGrid) {
        let (nx, ny) = (grid.tiles_x, grid.tiles_y);
        self.finished_sum.clear();
        self.finished_sum.resize((nx + 1) * (ny + 1), 0);
        for y in 0..ny {
            for x in 0..nx {
                let f = u32::from(self.tiles[y * nx + x].finished());
                self.finished_sum[(y + 1) * (nx + 1) + x + 1] = f
                    + self.finished_sum[y * (nx + 1) + x + 1]
                    + self.finished_sum[(y + 1) * (nx + 1) + x]
                    - self.finished_sum[y * (nx + 1) + x];
            }
        }
    }

    fn project_slab(
        &mut self,
        g: &Gaussians,
        camera: &Camera,
        w2c: &Mat3,
        grid: &TileGrid,
        lo: f32,
        hi: f32,
    ) {
        let mut candidates: Vec<u32> = self
            .views
            .iter()
            .filter(|v| {
                v.z_min < hi
                    && v.z_max >= lo
                    && !rect_finished(&self.finished_sum, grid.tiles_x, &v.tiles)
            })
            .map(|v| v.chunk)
            .collect();
        // In chunk order, so the slab's splats are in the order of their Gaussians: the order
        // in which splats of one depth key blend (`bin`), as on the GPU.
        candidates.sort_unstable();
        let ctx = SlabProjection {
            g,
            camera,
            w2c,
            grid,
            finished: &self.finished_sum,
            sh_rest: sh_rest_count(g.sh_degree()),
            lo,
            hi,
            lim: (
                1.3 * camera.intrinsics.width as f32 * 0.5 / camera.intrinsics.fx,
                1.3 * camera.intrinsics.height as f32 * 0.5 / camera.intrinsics.fy,
            ),
            reach_scale: MAX_SIGMAS * camera.intrinsics.fx.max(camera.intrinsics.fy),
        };
        // Chunks are projected a batch at a time into fixed slots, then compacted in chunk
        // order: scratch memory stays bounded however many chunks a slab touches.
        self.splats.clear();
        for batch in candidates.chunks(PROJECT_BATCH) {
            self.scratch.resize(batch.len() * CHUNK, Splat::default());
            self.per_chunk.clear();
            self.per_chunk.resize(batch.len(), 0);
            let examined: usize = self
                .scratch
                .par_chunks_mut(CHUNK)
                .zip(self.per_chunk.par_iter_mut())
                .zip(batch.par_iter())
                .map(|((out, count), &chunk)| {
                    let (n, examined) = ctx.chunk(chunk as usize, out);
                    *count = n as u32;
                    examined
                })
                .sum();
            self.stats.examined += examined;
            for (c, &n) in self.per_chunk.iter().enumerate() {
                self.splats
                    .extend_from_slice(&self.scratch[c * CHUNK..c * CHUNK + n as usize]);
            }
        }
        self.stats.splats += self.splats.len();
    }

    /// Fills `tile_entries` with depth key ([`Camera::depth_key`]) << 32 | splat, grouped by
    /// unfinished tile, each tile sorted front to back (ties by splat index), and `tile_start`
    /// with each tile's range.
    fn bin(&mut self, camera: &Camera, grid: &TileGrid) {
        let (w, h) = (
            camera.intrinsics.width as f32,
            camera.intrinsics.height as f32,
        );
        let (tiles_x, tiles_y) = (grid.tiles_x, grid.tiles_y);
        let tiles = &self.tiles;
        let n_blocks = self.splats.len().div_ceil(4096);
        if self.blocks.len() < n_blocks {
            self.blocks.resize_with(n_blocks, Vec::new);
        }
        self.blocks[..n_blocks]
            .par_iter_mut()
            .zip(self.splats.par_chunks(4096))
            .enumerate()
            .for_each(|(b, (out, splats))| {
                out.clear();
                for (j, s) in splats.iter().enumerate() {
                    let [ex, ey] = s.extent;
                    let x0 = ((s.x - ex).max(0.0) / TILE as f32) as usize;
                    let y0 = ((s.y - ey).max(0.0) / TILE as f32) as usize;
                    let x1 = (((s.x + ex).min(w - 1.0)).max(0.0) / TILE as f32) as usize;
                    let y1 = (((s.y + ey).min(h - 1.0)).max(0.0) / TILE as f32) as usize;
                    let (x1, y1) = (x1.min(tiles_x - 1), y1.min(tiles_y - 1));
                    let single = x0 == x1 && y0 == y1;
                    for ty in y0.min(tiles_y - 1)..=y1 {
                        for tx in x0.min(tiles_x - 1)..=x1 {
                            let t = ty * tiles_x + tx;
                            if tiles[t].finished() {
                                continue;
                            }
                            let (px0, py0) = ((tx * TILE) as f32 + 0.5, (ty * TILE) as f32 + 0.5);
                            let px1 = ((tx + 1) * TILE).min(camera.intrinsics.width as usize)
                                as f32
                                - 0.5;
                            let py1 = ((ty + 1) * TILE).min(camera.intrinsics.height as usize)
                                as f32
                                - 0.5;
                            if single || s.reaches_rect(px0, py0, px1, py1) {
                                out.push((t as u32, (b * 4096 + j) as u32));
                            }
                        }
                    }
                }
            });
        // Counting sort by tile over the blocks in order (so ties keep splat order).
        let blocks = &self.blocks[..n_blocks];
        let total: usize = blocks.iter().map(Vec::len).sum();
        self.stats.tile_entries += total;
        let n_tiles = grid.tiles();
        self.tile_start.clear();
        self.tile_start.resize(n_tiles + 1, 0);
        for &(t, _) in blocks.iter().flatten() {
            self.tile_start[t as usize + 1] += 1;
        }
        for t in 0..n_tiles {
            self.tile_start[t + 1] += self.tile_start[t];
        }
        let mut cursor: Vec<u32> = self.tile_start[..n_tiles].to_vec();
        self.tile_entries.clear();
        self.tile_entries.resize(total, 0);
        for &(t, s) in blocks.iter().flatten() {
            let slot = &mut cursor[t as usize];
            // Depth key high, splat index low: one integer sorts by depth, then index.
            self.tile_entries[*slot as usize] =
                u64::from(camera.depth_key(self.splats[s as usize].depth)) << 32 | u64::from(s);
            *slot += 1;
        }
        let mut rest: &mut [u64] = &mut self.tile_entries;
        let mut slices = Vec::with_capacity(n_tiles);
        for t in 0..n_tiles {
            let len = (self.tile_start[t + 1] - self.tile_start[t]) as usize;
            let (head, tail) = rest.split_at_mut(len);
            slices.push(head);
            rest = tail;
        }
        slices.into_par_iter().for_each(|s| s.sort_unstable());
    }

    fn blend(&mut self, grid: &TileGrid) {
        let (splats, entries, start) = (&self.splats, &self.tile_entries, &self.tile_start);
        self.tiles
            .par_iter_mut()
            .enumerate()
            .for_each(|(t, state)| {
                let list = &entries[start[t] as usize..start[t + 1] as usize];
                if !list.is_empty() {
                    let (x0, y0, _, _) = grid.tile_rect(t);
                    state.blend(splats, list, x0, y0);
                }
            });
    }

    fn assemble(
        &self,
        grid: &TileGrid,
        categories: &[u16],
        options: &RenderOptions,
    ) -> RenderOutput {
        let (width, height) = (grid.width, grid.height);
        let mut out = RenderOutput::sized(width, height, &options.channels);
        // One tile row (16 image rows) per task: each owns a contiguous band of every image
        // asked for (an empty band of the others).
        let band = TILE * width;
        let rows = grid.tiles_y;
        (
            bands(&mut out.rgb, band * 3, rows),
            bands(&mut out.rgb_f32, band * 3, rows),
            bands(&mut out.alpha, band, rows),
            bands(&mut out.depth_expected, band, rows),
            bands(&mut out.depth_median, band, rows),
            bands(&mut out.instance, band, rows),
            bands(&mut out.semantic, band, rows),
        )
            .into_par_iter()
            .enumerate()
            .for_each(
                |(ty, (rgb, rgb_f32, alpha, depth, median, instance, semantic))| {
                    for tx in 0..grid.tiles_x {
                        let t = ty * grid.tiles_x + tx;
                        let s = &self.tiles[t];
                        let (x0, _, tw, th) = grid.tile_rect(t);
                        for ly in 0..th {
                            for lx in 0..tw {
                                let (l, p) = (ly * TILE + lx, ly * width + x0 + lx);
                                let t_final = lane(&s.t, l).abs();
                                for (c, sum) in [&s.r, &s.g, &s.b].into_iter().enumerate() {
                                    let v = lane(sum, l) + t_final * options.background[c];
                                    put(rgb_f32, p * 3 + c, v);
                                    put(rgb, p * 3 + c, to_byte(v));
                                }
                                put(alpha, p, 1.0 - t_final);
                                // Σ wᵢ = Σ αᵢ Tᵢ telescopes to 1 − T: no separate weight sum is kept.
                                let w = 1.0 - t_final;
                                let hit = w > 0.0;
                                put(depth, p, if hit { lane(&s.wz, l) / w } else { 0.0 });
                                let m = if t_final <= 0.5 {
                                    lane(&s.median, l)
                                } else {
                                    0.0
                                };
                                put(median, p, m);
                                let id = lane(&s.instance, l).to_bits();
                                put(instance, p, id);
                                let category = if hit {
                                    categories.get(id as usize).copied().unwrap_or(0)
                                } else {
                                    0
                                };
                                put(semantic, p, category);
                            }
                        }
                    }
                },
            );
        out
    }
}

/// `v` cut into `rows` bands of `len`, or `rows` empty bands when `v` is an image not asked for.
fn bands<T>(v: &mut [T], len: usize, rows: usize) -> Vec<&mut [T]> {
    if v.is_empty() {
        (0..rows).map(|_| <&mut [T]>::default()).collect()
    } else {
        v.chunks_mut(len).collect()
    }
}

/// Writes `v` at `i` of a band of an image asked for (a band of one not asked for is empty).
fn put<T>(band: &mut [T], i: usize, v: T) {
    if let Some(slot) = band.get_mut(i) {
        *slot = v;
    }
}

/// Chunks projected per parallel batch (bounds the scratch slots to 64 × 256 splats).
const PROJECT_BATCH: usize = 64;

/// Everything the projection of one slab needs, shared by the parallel chunk tasks.
struct SlabProjection<'a> {
    g: &'a Gaussians,
    camera: &'a Camera,
    w2c: &'a Mat3,
    grid: &'a TileGrid,
    finished: &'a [u32],
    sh_rest: usize,
    lo: f32,
    hi: f32,
    /// x/z and y/z limits of the Jacobian clamp.
    lim: (f32, f32),
    /// 3.33 σ in pixels per metre of σ at unit depth (the larger focal length).
    reach_scale: f32,
}

impl SlabProjection<'_> {
    /// Projects the Gaussians of `chunk` whose depth is in the slab into `out`; returns how
    /// many splats it wrote and how many Gaussians it examined.
    fn chunk(&self, chunk: usize, out: &mut [Splat]) -> (usize, usize) {
        let ids = chunk * CHUNK..((chunk + 1) * CHUNK).min(self.g.len());
        // Cheap scalar tests first, then the costly projection four survivors at a time.
        let mut pending = [Survivor::default(); 4];
        let (mut waiting, mut n, mut examined) = (0, 0, 0);
        for i in ids {
            if let Some(s) = self.survivor(i, &mut examined) {
                pending[waiting] = s;
                waiting += 1;
                if waiting == 4 {
                    n += self.project_group(&pending, &mut out[n..]);
                    waiting = 0;
                }
            }
        }
        if waiting > 0 {
            n += self.project_group(&pending[..waiting], &mut out[n..]);
        }
        (n, examined)
    }

    /// Gaussian `i` with its camera-space centre and opacity if it may add to the slab: centre
    /// depth inside it, on or near the screen by its largest possible reach, over unfinished
    /// tiles, and not too transparent. Counts it in `examined` once its depth is in the slab.
    fn survivor(&self, i: usize, examined: &mut usize) -> Option<Survivor> {
        let (g, camera, grid) = (self.g, self.camera, self.grid);
        let k = camera.intrinsics;
        let t = *self.w2c * (Vec3::from_array(g.positions[i]) - camera.position);
        if !(t.z >= self.lo && t.z < self.hi && t.z >= camera.near && t.z <= camera.far) {
            return None;
        }
        *examined += 1;
        // ‖J‖ ≤ (f/z)·sqrt(2 + (x/z)² + (y/z)²) (Frobenius bound), +1 px for the low-pass.
        let inv_z = 1.0 / t.z;
        let (sx, sy) = (t.x * inv_z, t.y * inv_z);
        let (cx, cy) = (
            sx.clamp(-self.lim.0, self.lim.0),
            sy.clamp(-self.lim.1, self.lim.1),
        );
        let stretch = (2.0 + cx * cx + cy * cy).sqrt();
        let reach = self.reach_scale * exp_fast(g.max_log_scale(i)) * stretch * inv_z + 1.0;
        let (u, v) = (k.fx * sx + k.cx, k.fy * sy + k.cy);
        let (width, height) = (k.width as f32, k.height as f32);
        if u < -reach || v < -reach || u > width + reach || v > height + reach {
            return None;
        }
        // Nothing to add where every tile the splat can reach is already opaque.
        let tile = |p: f32, n: usize| ((p / TILE as f32).max(0.0) as i32 as usize).min(n - 1);
        let rect = [
            tile(u - reach, grid.tiles_x),
            tile(v - reach, grid.tiles_y),
            tile(u + reach, grid.tiles_x),
            tile(v + reach, grid.tiles_y),
        ];
        if rect_finished(self.finished, grid.tiles_x, &rect) {
            return None;
        }
        let opacity = sigmoid(g.opacity_logit(i));
        (opacity >= MIN_ALPHA).then_some(Survivor {
            index: i as u32,
            t,
            opacity,
        })
    }

    /// Projects up to four survivors into the front of `out`; returns how many splats it wrote.
    fn project_group(&self, group: &[Survivor], out: &mut [Splat]) -> usize {
        let g = self.g;
        // Short groups repeat their last member; the extra lanes are ignored.
        let lanes = [0, 1, 2, 3].map(|k| group[k.min(group.len() - 1)]);
        let quats = lanes.map(|s| g.rotations[s.index as usize]);
        let log_scales = lanes.map(|s| g.log_scales[s.index as usize]);
        let input = Gaussians4 {
            t: [
                f32x4::new(lanes.map(|s| s.t.x)),
                f32x4::new(lanes.map(|s| s.t.y)),
                f32x4::new(lanes.map(|s| s.t.z)),
            ],
            rotation: [0, 1, 2, 3].map(|c| f32x4::new(quats.map(|q| f32::from(q[c])))),
            log_scale: [0, 1, 2].map(|c| {
                f32x4::new(log_scales.map(|l| f32::from(l[c]))) * f32x4::splat(LOG_SCALE_STEP)
            }),
            opacity: f32x4::new(lanes.map(|s| s.opacity)),
        };
        let f = project4(self.camera, &input);
        let (x, y, cutoff) = (f.x.to_array(), f.y.to_array(), f.cutoff.to_array());
        let extent = f.extent.map(|v| v.to_array());
        let conic = f.conic.map(|v| v.to_array());
        let mut rest = [[0.0f32; 3]; 15];
        let mut n = 0;
        for (k, s) in group.iter().enumerate() {
            if f.visible >> k & 1 == 0 {
                continue;
            }
            let i = s.index as usize;
            if self.sh_rest > 0 {
                g.sh_rest_into(i, &mut rest);
            }
            let dir = (Vec3::from_array(g.positions[i]) - self.camera.position).normalize_or_zero();
            out[n] = Splat {
                x: x[k],
                y: y[k],
                conic: [conic[0][k], conic[1][k], conic[2][k]],
                opacity: s.opacity,
                color: sh::color(g.sh_dc[i].map(|v| v.to_f32()), &rest[..self.sh_rest], dir),
                depth: s.t.z,
                instance: g.instances[i],
                extent: [extent[0][k], extent[1][k]],
                cutoff: cutoff[k],
            };
            n += 1;
        }
        n
    }
}

/// A Gaussian that passed the cheap tests of a slab, waiting for projection.
#[derive(Debug, Clone, Copy, Default)]
struct Survivor {
    index: u32,
    t: Vec3,
    opacity: f32,
}

/// True when every tile of the rectangle `r` ([x0, y0, x1, y1], inclusive) is finished, from
/// the summed-area table `sum` of a grid `tiles_x` wide.
fn rect_finished(sum: &[u32], tiles_x: usize, r: &[usize; 4]) -> bool {
    let w = tiles_x + 1;
    let total = sum[(r[3] + 1) * w + r[2] + 1] + sum[r[1] * w + r[0]]
        - sum[r[1] * w + r[2] + 1]
        - sum[(r[3] + 1) * w + r[0]];
    total as usize == (r[2] - r[0] + 1) * (r[3] - r[1] + 1)
}

/// Slab boundaries: quantiles of the chunks' nearest depths, first from −∞, last to +∞.
fn slab_bounds(views: &[ChunkView]) -> Vec<(f32, f32)> {
    let n = views.len();
    let slabs = SLABS.min(n.max(1));
    let mut cuts = vec![f32::NEG_INFINITY];
    for k in 1..slabs {
        let z = views[k * n / slabs].z_min;
        if z > *cuts.last().unwrap_or(&f32::NEG_INFINITY) {
            cuts.push(z);
        }
    }
    cuts.push(f32::INFINITY);
    cuts.windows(2).map(|w| (w[0], w[1])).collect()
}

#[cfg(test)]
mod tests {
    use super::{Channels, to_byte};

    /// Every set of images prints as a list that parses back to it; unknown names are refused.
    #[test]
    fn channels_print_and_parse_back() {
        for bits in 0..128u32 {
            let on = |k: u32| bits & (1 << k) != 0;
            let c = Channels {
                rgb: on(0),
                rgb_f32: on(1),
                alpha: on(2),
                depth_expected: on(3),
                depth_median: on(4),
                instance: on(5),
                semantic: on(6),
            };
            let text = c.to_string();
            assert_eq!(text.parse::<Channels>().unwrap(), c, "{text}");
        }
        assert_eq!("all".parse::<Channels>().unwrap(), Channels::ALL);
        assert_eq!(
            " rgb , depth_median".parse::<Channels>().unwrap(),
            Channels {
                rgb: true,
                depth_median: true,
                ..Channels::NONE
            }
        );
        let e = "rgb,depth".parse::<Channels>().unwrap_err().to_string();
        assert!(e.contains("\"depth\"") && e.contains("depth_median"), "{e}");
    }

    /// `to_byte` gives `f32::round`'s bytes on every float within 4,096 ulps of a rounding
    /// boundary (k + ½) / 255, where adding a half in `f32` would round up, on a stride through
    /// 0–1, and outside 0–1.
    #[test]
    fn to_byte_rounds_as_f32_round() {
        let round = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        let mut values = vec![
            f32::NAN,
            f32::NEG_INFINITY,
            f32::INFINITY,
            f32::MAX,
            -0.0,
            -1.0,
            1.0,
            2.0,
        ];
        for k in 0..255 {
            let boundary = ((f64::from(k) + 0.5) / 255.0) as f32;
            let bits = boundary.to_bits();
            values.extend((bits - 4096..=bits + 4096).map(f32::from_bits));
        }
        values.extend((0..=1f32.to_bits()).step_by(9_973).map(f32::from_bits));
        for v in values {
            assert_eq!(to_byte(v), round(v), "{v:e}");
        }
    }
}
