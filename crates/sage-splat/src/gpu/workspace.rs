//! The buffers a batch of cameras renders in, kept from batch to batch and grown only when a
//! batch needs more (no allocation on the per-frame path), with the scan and sort plans and
//! the live-size programs built over them.

use super::Gpu;
use super::kernel::{
    FLOATS, Kernel, PAIRS, RUN_GROUP, WORDS, bind, bind_from, dynamic_uniform, layout, storage,
    texel_bytes, texel_rows, texels, texels_in, texels_out, threads_grid, uniform, uniform_buffer,
};
use super::live::{Count, Live, LiveBuilder, LivePrograms, Size};
use super::sort::{Finish, RadixSort, Scan, ScanPlan, SortInput, SortPlan, digit_words};
use crate::passes::{Blending, GPU_SLABS, KernelShape, PassTimes};

/// Most depth slabs a batch renders in ([`GPU_SLABS`]).
pub(crate) const SLABS: u32 = GPU_SLABS;

/// Bins of the per-camera histogram of chunk depths the slabs are cut from.
pub(crate) const DEPTH_BINS: u32 = 128;
/// Words of one camera's block (`Camera` in `splat.wgsl`: its array stride).
pub(crate) const CAMERA_WORDS: usize = 60;

/// Most cameras in one batch: the byte above the sort keys' [`DEPTH_KEY_BITS`].
pub(crate) const MAX_CAMERAS: u32 = 1 << (32 - DEPTH_KEY_BITS);

/// The cameras one batch holds on `gpu`: their blocks sit in one uniform buffer
/// (`cameras` in `splat.wgsl`), so [`MAX_CAMERAS`] (60 KB, within the 64 KB every WebGPU
/// adapter binds), or fewer where an adapter binds less.
pub(crate) fn camera_slots(gpu: &Gpu) -> u32 {
    camera_slots_within(gpu.limits().max_uniform_buffer_binding_size)
}

/// The camera blocks a uniform binding of `bytes` holds, at most [`MAX_CAMERAS`].
fn camera_slots_within(bytes: u64) -> u32 {
    (bytes / camera_block_bytes(1)).min(u64::from(MAX_CAMERAS)) as u32
}

/// Bytes of the uniform buffer holding `slots` camera blocks.
pub(crate) fn camera_block_bytes(slots: u32) -> u64 {
    u64::from(slots) * CAMERA_WORDS as u64 * 4
}

/// Planes of the blending state per camera (its pixels' words): r, g, b, transmittance,
/// weighted depth, median depth, instance, best weight.
pub(crate) const PLANES: u64 = 8;
/// The splat textures (`splat.wgsl`), a texel of four words per projected splat in each, and
/// their formats: shapes, weights and colours (floats), boxes (words).
const SPLAT_TEXTURES: [(&str, wgpu::TextureFormat); 4] = [
    ("splat shapes", FLOATS),
    ("splat weights", FLOATS),
    ("splat colours", FLOATS),
    ("splat boxes", WORDS),
];
/// Texels of the entry table per visible entry (`index_entries` in `splat.wgsl`): its first
/// splat and chunk, then its mask in two.
pub(crate) const ENTRY_TEXELS: u32 = 3;
// Live slots the host writes before each batch, one by one below.
/// Live slot: cameras × chunks.
pub(crate) const LIVE_CAMERA_CHUNKS: u32 = 0;
/// Live slot: the batch's tiles.
pub(crate) const LIVE_TILES: u32 = 1;
/// Live slot: the batch's cameras.
pub(crate) const LIVE_CAMERAS: u32 = 2;
/// Live slot: the batch's depth slabs.
pub(crate) const LIVE_SLABS: u32 = 3;
/// Live slot: the planes `compose` writes out (`OUT_*` bits).
pub(crate) const LIVE_OUT_PLANES: u32 = 4;
/// Live slot: the visible chunks below which a camera takes one slab of the batch's (zero
/// when the slabs are fixed).
pub(crate) const LIVE_FEW_CHUNKS: u32 = 5;
/// Live slot: the most entries one blending workgroup takes of its tile (a piece).
pub(crate) const LIVE_PIECE: u32 = 6;
/// Live slot: the blending passes per slab.
pub(crate) const LIVE_PASSES: u32 = 7;
/// Live slot: where in the tile lists the second list's count is ([`list_words`]), for the
/// size programs that read it.
pub(crate) const LIVE_SECOND_COUNT: u32 = 8;
/// Live slot: where in the tile lists a slab's last pass notes the passes it would have
/// needed ([`list_words`]).
pub(crate) const LIVE_WANTED_AT: u32 = 9;
/// The live slots the host writes, before those the size programs derive.
const LIVE_FIXED: u32 = 10;
/// Most blending passes per slab: a tile blends at most this many pieces in one slab.
pub(crate) const MAX_BLEND_PASSES: u32 = 64;

/// In the tile-list buffer of a batch of `tiles` tiles: where the second list's count is and
/// where the passes wanted are (`list_start` and `list_count` in `splat.wgsl`: each list is
/// `tiles` words and its count).
pub(crate) fn list_words(tiles: u32) -> [u32; 2] {
    [2 * tiles + 1, 2 * tiles + 2]
}
/// Bits of a sort key below the camera (`depth_key`, `tile_key` in `splat.wgsl`): the camera
/// of the batch takes the byte above, so a batch holds at most 256 cameras.
pub(crate) use crate::camera::DEPTH_KEY_BITS;
/// Bits of a (tile, splat) entry's value that hold the splat's index in the splat textures
/// (its slot in `project`'s output, which the depth order's values name); the four above them say which 8×8 blocks of the tile the splat's box reaches (`emit` writes
/// them, the blending kernels read them with the splat).
pub(crate) const SPLAT_INDEX_BITS: u32 = 28;
/// Most 8-bit passes the tile sort takes (a camera's tiles below 2²⁴).
pub(crate) const TILE_SORT_PASSES: u32 = DEPTH_KEY_BITS / 8;
/// Most 8-bit passes the depth sort takes: the depth key and, in a batch, the camera.
const DEPTH_SORT_PASSES: u32 = 4;

/// What a batch needs the buffers to hold (or what they hold).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Caps {
    /// Cameras.
    pub(crate) cameras: u32,
    /// Cameras × chunks.
    pub(crate) camera_chunks: u32,
    /// Visible (camera, chunk) entries.
    pub(crate) entries: u32,
    /// Visible splats.
    pub(crate) splats: u32,
    /// (tile, splat) entries.
    pub(crate) tile_entries: u32,
    /// Tiles over the cameras.
    pub(crate) tiles: u32,
    /// Words of the cameras' blending state and of the images written out.
    pub(crate) image_words: u64,
}

impl Caps {
    /// True when buffers of `self` hold a batch needing `need`.
    pub(crate) fn holds(&self, need: &Caps) -> bool {
        self.cameras >= need.cameras
            && self.camera_chunks >= need.camera_chunks
            && self.entries >= need.entries
            && self.splats >= need.splats
            && self.tile_entries >= need.tile_entries
            && self.tiles >= need.tiles
            && self.image_words >= need.image_words
    }

    /// What a batch that found `entries`, `splats` and `tile_entries` (the largest over its
    /// slabs) in buffers of `self` should find room for next time (the entries found, the splats
    /// and tile entries a quarter over): `None` when all fitted. Only the splats the buffers held
    /// were binned, so when the splats overflowed, their tile entries scaled to every splat found
    /// stand for the rest: one growth then sizes both, where growing by what was counted would
    /// take a second.
    pub(crate) fn wanted(&self, [entries, splats, tile_entries]: [u32; 3]) -> Option<[u32; 3]> {
        if entries <= self.entries && splats <= self.splats && tile_entries <= self.tile_entries {
            return None;
        }
        let tile_entries = if splats > self.splats {
            let scaled =
                u64::from(tile_entries) * u64::from(splats) / u64::from(self.splats.max(1));
            u32::try_from(scaled).unwrap_or(u32::MAX)
        } else {
            tile_entries
        };
        let grow = |n: u32| n.saturating_add(n / 4);
        Some([entries, grow(splats), grow(tile_entries)])
    }

    /// The larger of each.
    pub(crate) fn max(&self, o: &Caps) -> Caps {
        Caps {
            cameras: self.cameras.max(o.cameras),
            camera_chunks: self.camera_chunks.max(o.camera_chunks),
            entries: self.entries.max(o.entries),
            splats: self.splats.max(o.splats),
            tile_entries: self.tile_entries.max(o.tile_entries),
            tiles: self.tiles.max(o.tiles),
            image_words: self.image_words.max(o.image_words),
        }
    }

    /// True when `gpu` binds buffers and textures of these capacities.
    pub(crate) fn fit(&self, gpu: &Gpu) -> bool {
        let most_rows = gpu.limits().max_texture_dimension_2d;
        self.largest_buffer() <= gpu.largest_binding()
            && self.splats <= 1 << SPLAT_INDEX_BITS
            && texel_rows(self.splats) <= most_rows
            && texel_rows(self.tile_entries) <= most_rows
            && texel_rows(self.entries.saturating_mul(ENTRY_TEXELS)) <= most_rows
    }

    /// The largest single buffer these need, bytes (checked against what one binding sees).
    pub(crate) fn largest_buffer(&self) -> u64 {
        [
            // The tile counts (a word per splat and the total).
            (u64::from(self.splats) + 1) * 4,
            u64::from(self.entries) * 32,
            // The tile sort's digit counts (256 per block of 256 entries: the most of either
            // kernel shape).
            digit_words(KernelShape::Lanes, self.tile_entries) * 4,
            u64::from(self.camera_chunks) * 16 + 4,
            self.image_words * 4,
        ]
        .into_iter()
        .max()
        .unwrap_or(0)
    }

    /// Device bytes of buffers and textures of these capacities for kernels of `shape` (the
    /// sorts' digit counts included; not the scans' block sums, a word per block of
    /// `SCAN_BLOCK`, nor the uniform buffers the adapter's alignment sizes: the camera blocks
    /// and the slab entries).
    pub(crate) fn bytes(&self, shape: KernelShape) -> u64 {
        let words = u64::from(self.cameras) * u64::from(DEPTH_BINS + SLABS + 1)
            // Chunk flags and views.
            + 5 * u64::from(self.camera_chunks)
            // Chunk list, entry masks and counts.
            + 10 * u64::from(self.entries)
            // Depth keys and values, tile counts.
            + u64::from(self.splats) * 3
            + digit_words(shape, self.splats)
            + digit_words(shape, self.tile_entries)
            + 9 * u64::from(self.tiles)
            + self.image_words;
        let splat_textures: u64 = SPLAT_TEXTURES
            .iter()
            .map(|&(_, format)| texel_bytes(self.splats, format))
            .sum();
        // Each sort's result and the texture it ping-pongs with.
        let sorted = 2 * (texel_bytes(self.splats, PAIRS) + texel_bytes(self.tile_entries, PAIRS));
        let entry_table = texel_bytes(self.entries.saturating_mul(ENTRY_TEXELS), WORDS);
        words * 4 + splat_textures + sorted + entry_table
    }
}

/// The kernels of `splat.wgsl` and the layouts of their bind groups.
pub(crate) struct Kernels {
    pub(crate) scene_layout: wgpu::BindGroupLayout,
    frame_layout: wgpu::BindGroupLayout,
    /// The splat textures as `project` writes them and as later kernels read them.
    splats_out_layout: wgpu::BindGroupLayout,
    splats_in_layout: wgpu::BindGroupLayout,
    /// The texture `emit` writes the (tile, splat) entries to.
    tiles_out_layout: wgpu::BindGroupLayout,
    /// The entry table as `index_entries` writes it and as `project` reads it.
    entries_out_layout: wgpu::BindGroupLayout,
    entries_in_layout: wgpu::BindGroupLayout,
    clear: Kernel,
    cull: Kernel,
    cut_slabs: Kernel,
    finished_table: Kernel,
    select_chunks: Kernel,
    list_chunks: Kernel,
    /// `mark` or, for CPU drivers, `mark_runs` ([`Kernels::shape`]).
    mark: Kernel,
    index_entries: Kernel,
    project: Kernel,
    count_tiles: Kernel,
    emit: Kernel,
    ranges: Kernel,
    start_pixels: Kernel,
    raster: Kernel,
    raster_columns: Kernel,
    compose: Kernel,
    scan: Scan,
    sort: RadixSort,
    pub(crate) live: Live,
    /// The camera blocks `source` was compiled for ([`camera_slots`]).
    pub(crate) camera_slots: u32,
    /// The shape of `mark` and of the sort's kernels.
    pub(crate) shape: KernelShape,
}

impl Kernels {
    /// Compiles `source` (the prelude and `splat.wgsl`, with cameras in blocks of
    /// `camera_slots`) and the scan, sort and live kernels, those with two shapes in `shape`.
    pub(crate) fn new(gpu: &Gpu, source: String, camera_slots: u32, shape: KernelShape) -> Kernels {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("splat"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let scene = [
            texels_in(0, FLOATS),
            texels_in(1, WORDS),
            texels_in(2, WORDS),
            storage(3, true),
            storage(4, true),
        ];
        let scene_layout = layout(gpu, &scene);
        let mut frame = vec![uniform(0), storage(1, true)];
        frame.extend((2..11).map(|b| storage(b, false)));
        frame.push(uniform(11));
        frame.extend((12..17).map(|b| storage(b, false)));
        frame.push(dynamic_uniform(17));
        frame.push(storage(18, false));
        let frame_layout = layout(gpu, &frame);
        let splat_bindings = |first: u32, entry: fn(u32, wgpu::TextureFormat) -> _| {
            (first..)
                .zip(SPLAT_TEXTURES)
                .map(|(b, (_, format))| entry(b, format))
                .collect::<Vec<_>>()
        };
        let splats_out_layout = layout(gpu, &splat_bindings(0, texels_out));
        // The splats, then the depth order and the tile order (`depth_sorted`, `tiles_sorted`).
        let mut splats_in = splat_bindings(SPLAT_TEXTURES.len() as u32, texels_in);
        splats_in.extend([texels_in(8, PAIRS), texels_in(9, PAIRS)]);
        let splats_in_layout = layout(gpu, &splats_in);
        let tiles_out_layout = layout(gpu, &[texels_out(0, PAIRS)]);
        let entries_out_layout = layout(gpu, &[texels_out(10, WORDS)]);
        let entries_in_layout = layout(gpu, &[texels_in(1, WORDS)]);
        let kernel =
            |entry: &str| Kernel::new(gpu, &module, entry, &[&scene_layout, &frame_layout]);
        // Kernels over the splat textures, written or read.
        let over = |entry: &str, splats: &wgpu::BindGroupLayout| {
            Kernel::new(gpu, &module, entry, &[&scene_layout, &frame_layout, splats])
        };
        Kernels {
            clear: kernel("clear"),
            cull: kernel("cull"),
            cut_slabs: kernel("cut_slabs"),
            finished_table: kernel("finished_table"),
            select_chunks: kernel("select_chunks"),
            list_chunks: kernel("list_chunks"),
            mark: kernel(match shape {
                KernelShape::Lanes => "mark",
                KernelShape::Runs => "mark_runs",
            }),
            index_entries: over("index_entries", &entries_out_layout),
            project: Kernel::new(
                gpu,
                &module,
                "project",
                &[
                    &scene_layout,
                    &frame_layout,
                    &splats_out_layout,
                    &entries_in_layout,
                ],
            ),
            count_tiles: over("count_tiles", &splats_in_layout),
            emit: Kernel::new(
                gpu,
                &module,
                "emit",
                &[
                    &scene_layout,
                    &frame_layout,
                    &splats_in_layout,
                    &tiles_out_layout,
                ],
            ),
            ranges: over("ranges", &splats_in_layout),
            start_pixels: kernel("start_pixels"),
            raster: over("raster", &splats_in_layout),
            raster_columns: over("raster_columns", &splats_in_layout),
            compose: kernel("compose"),
            scan: Scan::new(gpu),
            sort: RadixSort::new(gpu, shape),
            live: Live::new(gpu),
            scene_layout,
            frame_layout,
            splats_out_layout,
            splats_in_layout,
            tiles_out_layout,
            entries_out_layout,
            entries_in_layout,
            camera_slots,
            shape,
        }
    }
}

/// How one batch is recorded.
pub(crate) struct BatchPlan<'a> {
    /// 8-bit passes of the depth sort.
    pub(crate) depth_passes: u32,
    /// 8-bit passes of the tile sort.
    pub(crate) tile_passes: u32,
    /// Depth slabs.
    pub(crate) slabs: u32,
    /// Blending passes per slab (at most [`MAX_BLEND_PASSES`]).
    pub(crate) blend_passes: u32,
    /// The blending kernel.
    pub(crate) blending: Blending,
    /// The per-pixel passes' grid: the largest camera's tiles across and down × cameras.
    pub(crate) grid: (u32, u32, u32),
    /// Where a timestamp goes before and after each stage ([`PassTimes::from_stamps`] reads
    /// them), when timing.
    pub(crate) stamps: Option<&'a wgpu::QuerySet>,
}

impl PassTimes {
    /// Timestamps a batch of `slabs` slabs writes (see [`Workspace::encode`]).
    pub(crate) fn stamps(slabs: u32) -> u32 {
        3 + 4 * slabs
    }

    /// The stages' times from the timestamps of one batch of `slabs` slabs, `period`
    /// nanoseconds per tick; a timestamp after those of the stages is the read-back copy's end.
    pub(crate) fn from_stamps(ticks: &[u64], slabs: u32, period: f32) -> PassTimes {
        let mut t = PassTimes::default();
        let ms = |i: usize| ticks[i].saturating_sub(ticks[i - 1]) as f64 * f64::from(period) * 1e-6;
        let stages = (Self::stamps(slabs) as usize).min(ticks.len());
        if ticks.len() > stages {
            t.read_back_ms = ms(stages);
        }
        let last = stages.saturating_sub(1);
        for i in 1..stages {
            let stage = match i {
                1 => &mut t.setup_ms,
                i if i == last => &mut t.compose_ms,
                i => match (i - 2) % 4 {
                    0 => &mut t.project_ms,
                    1 => &mut t.depth_sort_ms,
                    2 => &mut t.bin_ms,
                    _ => &mut t.raster_ms,
                },
            };
            *stage += ms(i);
        }
        t
    }

    /// The sum of each stage.
    pub(crate) fn add(&self, o: &PassTimes) -> PassTimes {
        PassTimes {
            setup_ms: self.setup_ms + o.setup_ms,
            project_ms: self.project_ms + o.project_ms,
            depth_sort_ms: self.depth_sort_ms + o.depth_sort_ms,
            bin_ms: self.bin_ms + o.bin_ms,
            raster_ms: self.raster_ms + o.raster_ms,
            compose_ms: self.compose_ms + o.compose_ms,
            read_back_ms: self.read_back_ms + o.read_back_ms,
            unpack_ms: self.unpack_ms + o.unpack_ms,
        }
    }
}

/// Byte offsets of the indirect arguments of the passes over live sizes.
struct Dispatches {
    /// A thread per camera × chunk (+1).
    camera_chunks: u64,
    /// A workgroup per visible entry (+1).
    entries: u64,
    /// A thread per visible entry, in workgroups of [`RUN_GROUP`].
    entry_runs: u64,
    /// A thread per visible entry.
    entry_threads: u64,
    /// A thread per visible splat (+1).
    splats: u64,
    /// A thread per (tile, splat) entry.
    tile_entries: u64,
    /// A workgroup per tile in each blending list.
    listed_tiles: [u64; 2],
}

/// A batch's buffers for up to [`Caps`], with what is recorded over them.
pub(crate) struct Workspace {
    pub(crate) caps: Caps,
    pub(crate) cameras: wgpu::Buffer,
    pub(crate) images: wgpu::Buffer,
    frame_group: wgpu::BindGroup,
    /// The splat textures to write (`project`) and to read with the sorts' results (`emit`,
    /// `ranges`, blending): one group for each texture the depth sort and the tile sort end
    /// in ([`SortPlan::result`]), indexed by both.
    splats_out: wgpu::BindGroup,
    splats_in: [[wgpu::BindGroup; 2]; 2],
    /// Where `emit` writes: the tile sort's second texture, where its first pass starts.
    tiles_out: wgpu::BindGroup,
    /// The entry table, to write (`index_entries`) and to read (`project`).
    entries_out: wgpu::BindGroup,
    entries_in: wgpu::BindGroup,
    /// The splat textures, then the depth sort's two textures of pairs and the tile sort's,
    /// then the entry table.
    _textures: [wgpu::Texture; 9],
    programs: LivePrograms,
    dispatches: Dispatches,
    flags_scan: ScanPlan,
    entries_scan: ScanPlan,
    tiles_scan: ScanPlan,
    depth_sort: SortPlan,
    tile_sort: SortPlan,
    /// Live slots of the unclamped counts over the slabs, largest then sum: entries, splats,
    /// tile entries.
    pub(crate) peaks: [u32; 3],
    pub(crate) totals: [u32; 3],
    /// Live slot of the most blending passes a tile of the batch wanted.
    pub(crate) passes_wanted: u32,
    /// Bytes between the (slab, blending pass) entries of the slab buffer.
    slab_stride: u32,
    _buffers: Vec<wgpu::Buffer>,
}

/// A storage buffer of `words` u32 (at least one).
fn words_buffer(gpu: &Gpu, label: &str, words: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: words.max(1) * 4,
        usage: wgpu::BufferUsages::STORAGE | extra,
        mapped_at_creation: false,
    })
}

impl Workspace {
    /// Buffers of `caps`, their plans and programs.
    pub(crate) fn new(gpu: &Gpu, k: &Kernels, caps: Caps) -> Workspace {
        let none = wgpu::BufferUsages::empty();
        let buffer = |label: &str, words: u64| words_buffer(gpu, label, words, none);
        let cameras = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cameras"),
            size: camera_block_bytes(k.camera_slots),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let flags = buffer("chunk flags", u64::from(caps.camera_chunks) + 1);
        let chunk_list = buffer("chunk list", u64::from(caps.entries));
        let masks = buffer("entry masks", 8 * u64::from(caps.entries));
        let entry_counts = buffer("entry counts", u64::from(caps.entries) + 1);
        let rows = texel_rows(caps.splats);
        let splat_textures = SPLAT_TEXTURES.map(|(label, format)| texels(gpu, label, format, rows));
        let views = splat_textures
            .each_ref()
            .map(|t| t.create_view(&wgpu::TextureViewDescriptor::default()));
        let views: Vec<_> = views
            .iter()
            .map(wgpu::BindingResource::TextureView)
            .collect();
        let splats_out = bind(gpu, &k.splats_out_layout, &views);
        let depth = ["depth keys", "depth values"].map(|l| buffer(l, u64::from(caps.splats)));
        let depth_sorted = ["depth order", "depth order 2"]
            .map(|l| texels(gpu, l, PAIRS, texel_rows(caps.splats)));
        let tile_counts = buffer("tile counts", u64::from(caps.splats) + 1);
        let tiles_sorted = ["tile order", "tile order 2"]
            .map(|l| texels(gpu, l, PAIRS, texel_rows(caps.tile_entries)));
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (depth_views, tile_views) = (
            depth_sorted.each_ref().map(view),
            tiles_sorted.each_ref().map(view),
        );
        let splats_in = [0, 1].map(|d| {
            [0, 1].map(|t| {
                let mut resources = views.clone();
                resources.push(wgpu::BindingResource::TextureView(&depth_views[d]));
                resources.push(wgpu::BindingResource::TextureView(&tile_views[t]));
                bind_from(
                    gpu,
                    &k.splats_in_layout,
                    SPLAT_TEXTURES.len() as u32,
                    &resources,
                )
            })
        });
        let entry_table = texels(
            gpu,
            "entry table",
            WORDS,
            texel_rows(caps.entries.saturating_mul(ENTRY_TEXELS)),
        );
        let entry_view = view(&entry_table);
        let entry_view = [wgpu::BindingResource::TextureView(&entry_view)];
        let entries_out = bind_from(gpu, &k.entries_out_layout, 10, &entry_view);
        let entries_in = bind_from(gpu, &k.entries_in_layout, 1, &entry_view);
        let tiles_out = bind(
            gpu,
            &k.tiles_out_layout,
            &[wgpu::BindingResource::TextureView(&tile_views[1])],
        );
        let tile_ranges = buffer("tile ranges", 2 * u64::from(caps.tiles));
        let chunk_views = buffer("chunk views", 4 * u64::from(caps.camera_chunks));
        let histogram = buffer("depth histogram", u64::from(caps.cameras * DEPTH_BINS));
        let cuts = buffer("slab cuts", u64::from(caps.cameras * (SLABS + 1)));
        let tile_done = buffer("finished tiles", u64::from(caps.tiles));
        // (tiles across + 1)(tiles down + 1) ≤ 4 × tiles per camera.
        let finished_sum = buffer("finished-tile tables", 4 * u64::from(caps.tiles));
        let tile_list = buffer("listed tiles", 2 * u64::from(caps.tiles) + 3);
        let slab_stride = gpu
            .device
            .limits()
            .min_uniform_buffer_offset_alignment
            .max(16);
        let slab_words: Vec<u32> = (0..SLABS * MAX_BLEND_PASSES)
            .flat_map(|k| {
                let mut entry = vec![0; slab_stride as usize / 4];
                entry[0] = k / MAX_BLEND_PASSES;
                entry[1] = k % MAX_BLEND_PASSES;
                entry
            })
            .collect();
        let slab_indices = uniform_buffer(gpu, &slab_words);
        let images = words_buffer(
            gpu,
            "images",
            caps.image_words,
            wgpu::BufferUsages::COPY_SRC,
        );
        let live = &k.live;
        let mut b = LiveBuilder::new(LIVE_FIXED);
        // Stage 0, from the host's counts: the culling and the scan of its flags.
        b.stage();
        let flag_count = b.derive(
            Size {
                add: 1,
                ..Size::of(Count::Live(LIVE_CAMERA_CHUNKS), caps.camera_chunks + 1)
            }
            .dispatched(256),
        );
        let flags_scan = k.scan.plan(
            gpu,
            live,
            &mut b,
            &flags,
            caps.camera_chunks + 1,
            flag_count.n,
            Finish::InPlace,
        );
        // Stage 1, from the flags' total: the visible entries.
        b.stage();
        let entries = b.derive(Size {
            keep_raw: true,
            ..Size::of(Count::SourceAt(LIVE_CAMERA_CHUNKS), caps.entries)
        });
        let entry_groups = b.derive(
            Size {
                add: 1,
                ..Size::of(Count::Live(entries.n), caps.entries + 1)
            }
            .dispatched(1),
        );
        let entry_threads =
            b.derive(Size::of(Count::Live(entries.n), caps.entries).dispatched(256));
        let entry_runs =
            b.derive(Size::of(Count::Live(entries.n), caps.entries).dispatched(RUN_GROUP));
        let entries_scan = k.scan.plan(
            gpu,
            live,
            &mut b,
            &entry_counts,
            caps.entries + 1,
            entry_groups.n,
            Finish::InPlace,
        );
        // Stage 2, from the entries' total: the visible splats, their sort and binning.
        b.stage();
        let splat_count = b.derive(Size {
            keep_raw: true,
            ..Size::of(Count::SourceAt(entries.n), caps.splats)
        });
        let splat_threads = b.derive(
            Size {
                add: 1,
                ..Size::of(Count::Live(splat_count.n), caps.splats + 1)
            }
            .dispatched(256),
        );
        let [d0, d1] = &depth;
        let depth_sort = k.sort.plan(
            gpu,
            &k.scan,
            live,
            &mut b,
            SortInput::Buffers(d0, d1),
            depth_sorted.each_ref(),
            caps.splats,
            splat_count.n,
            DEPTH_SORT_PASSES,
        );
        let tiles_scan = k.scan.plan(
            gpu,
            live,
            &mut b,
            &tile_counts,
            caps.splats + 1,
            splat_threads.n,
            Finish::InPlace,
        );
        // Stage 3, from the tile counts' total: the (tile, splat) entries and their sort.
        b.stage();
        let tile_entries = b.derive(
            Size {
                keep_raw: true,
                ..Size::of(Count::SourceAt(splat_count.n), caps.tile_entries)
            }
            .dispatched(256),
        );
        let tile_sort = k.sort.plan(
            gpu,
            &k.scan,
            live,
            &mut b,
            SortInput::Texture,
            tiles_sorted.each_ref(),
            caps.tile_entries,
            tile_entries.n,
            TILE_SORT_PASSES,
        );
        // Stages 4 and 5, from the counts after the tile lists: the tiles a blending pass of
        // each parity blends (the first list is the one the binning's ranges fill).
        b.stage();
        let listed_tiles =
            b.derive(Size::of(Count::SourceAt(LIVE_TILES), caps.tiles).dispatched(1));
        b.stage();
        let handed_on =
            b.derive(Size::of(Count::SourceAt(LIVE_SECOND_COUNT), caps.tiles).dispatched(1));
        // Stage 6, once the slabs are blended: the most passes a tile wanted, for the host.
        b.stage();
        let passes_wanted = b.derive(Size {
            keep_raw: true,
            ..Size::of(Count::SourceAt(LIVE_WANTED_AT), u32::MAX)
        });
        let programs = live.programs(
            gpu,
            &b,
            &[
                &flags,
                &flags,
                &entry_counts,
                &tile_counts,
                &tile_list,
                &tile_list,
                &tile_list,
            ],
        );
        let slots = uniform_buffer(
            gpu,
            &[
                entries.n,
                splat_count.n,
                tile_entries.n,
                listed_tiles.n,
                handed_on.n,
                0,
                0,
                0,
            ],
        );
        let frame_group = bind(
            gpu,
            &k.frame_layout,
            &[
                cameras.as_entire_binding(),
                live.buffer.as_entire_binding(),
                flags.as_entire_binding(),
                chunk_list.as_entire_binding(),
                masks.as_entire_binding(),
                entry_counts.as_entire_binding(),
                d0.as_entire_binding(),
                d1.as_entire_binding(),
                tile_counts.as_entire_binding(),
                tile_ranges.as_entire_binding(),
                images.as_entire_binding(),
                slots.as_entire_binding(),
                chunk_views.as_entire_binding(),
                histogram.as_entire_binding(),
                cuts.as_entire_binding(),
                tile_done.as_entire_binding(),
                finished_sum.as_entire_binding(),
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &slab_indices,
                    offset: 0,
                    size: wgpu::BufferSize::new(16),
                }),
                tile_list.as_entire_binding(),
            ],
        );
        let [d0, d1] = depth;
        let [s0, s1, s2, s3] = splat_textures;
        let [o0, o1] = depth_sorted;
        let [o2, o3] = tiles_sorted;
        Workspace {
            caps,
            peaks: [entries.peak, splat_count.peak, tile_entries.peak],
            totals: [entries.total, splat_count.total, tile_entries.total],
            passes_wanted: passes_wanted.peak,
            slab_stride,
            dispatches: Dispatches {
                camera_chunks: flag_count.args,
                entries: entry_groups.args,
                entry_threads: entry_threads.args,
                entry_runs: entry_runs.args,
                splats: splat_threads.args,
                tile_entries: tile_entries.args,
                listed_tiles: [listed_tiles.args, handed_on.args],
            },
            cameras,
            images,
            frame_group,
            splats_out,
            splats_in,
            tiles_out,
            entries_out,
            entries_in,
            _textures: [s0, s1, s2, s3, o0, o1, o2, o3, entry_table],
            programs,
            flags_scan,
            entries_scan,
            tiles_scan,
            depth_sort,
            tile_sort,
            _buffers: vec![
                flags,
                chunk_list,
                masks,
                entry_counts,
                d0,
                d1,
                tile_counts,
                tile_ranges,
                slots,
                chunk_views,
                histogram,
                cuts,
                tile_done,
                finished_sum,
                slab_indices,
                tile_list,
            ],
        }
    }

    /// Records the whole batch `b` into `pass`.
    pub(crate) fn encode(
        &self,
        k: &Kernels,
        scene_group: &wgpu::BindGroup,
        pass: &mut wgpu::ComputePass<'_>,
        b: &BatchPlan<'_>,
    ) {
        let BatchPlan {
            depth_passes,
            tile_passes,
            slabs,
            blend_passes,
            blending,
            grid,
            stamps,
        } = *b;
        let mut next_stamp = 0;
        let mut stamp = |pass: &mut wgpu::ComputePass<'_>| {
            if let Some(q) = stamps {
                pass.write_timestamp(q, next_stamp);
                next_stamp += 1;
            }
        };
        stamp(pass);
        let live = &k.live;
        let cameras = grid.2;
        let d = &self.dispatches;
        let first = [0];
        let groups: [(&wgpu::BindGroup, &[u32]); 2] =
            [(scene_group, &[]), (&self.frame_group, &first)];
        k.clear
            .run_grid(pass, &groups, threads_grid(cameras * DEPTH_BINS));
        k.start_pixels.run_grid(pass, &groups, grid);
        live.encode(pass, &self.programs, 0);
        live.dispatch(pass, &k.cull, &groups, d.camera_chunks);
        k.cut_slabs.run_grid(pass, &groups, threads_grid(cameras));
        stamp(pass);
        for slab in 0..slabs {
            let offset = [slab * MAX_BLEND_PASSES * self.slab_stride];
            let groups: [(&wgpu::BindGroup, &[u32]); 2] =
                [(scene_group, &[]), (&self.frame_group, &offset)];
            k.finished_table
                .run_grid(pass, &groups, threads_grid(cameras * 256));
            live.dispatch(pass, &k.select_chunks, &groups, d.camera_chunks);
            k.scan.encode(pass, live, &self.flags_scan);
            live.dispatch(pass, &k.list_chunks, &groups, d.camera_chunks);
            live.encode(pass, &self.programs, 1);
            let marks = match k.shape {
                KernelShape::Lanes => d.entries,
                KernelShape::Runs => d.entry_runs,
            };
            live.dispatch(pass, &k.mark, &groups, marks);
            k.scan.encode(pass, live, &self.entries_scan);
            let [scene, frame] = groups;
            let entries_out = [scene, frame, (&self.entries_out, &[][..])];
            live.dispatch(pass, &k.index_entries, &entries_out, d.entry_threads);
            live.encode(pass, &self.programs, 2);
            let splats_out = [
                scene,
                frame,
                (&self.splats_out, &[][..]),
                (&self.entries_in, &[][..]),
            ];
            let sorted =
                &self.splats_in[SortPlan::result(depth_passes)][SortPlan::result(tile_passes)];
            let splats_in = [scene, frame, (sorted, &[][..])];
            live.dispatch(pass, &k.project, &splats_out, d.splats);
            stamp(pass);
            k.sort
                .encode(pass, &k.scan, live, &self.depth_sort, depth_passes as usize);
            stamp(pass);
            live.dispatch(pass, &k.count_tiles, &splats_in, d.splats);
            k.scan.encode(pass, live, &self.tiles_scan);
            live.encode(pass, &self.programs, 3);
            // Its splats group binds the tile sort's first texture where the tile order goes,
            // since `emit` writes the second.
            let emit = [
                scene,
                frame,
                (&self.splats_in[SortPlan::result(depth_passes)][0], &[][..]),
                (&self.tiles_out, &[][..]),
            ];
            live.dispatch(pass, &k.emit, &emit, d.splats);
            k.sort
                .encode(pass, &k.scan, live, &self.tile_sort, tile_passes as usize);
            live.dispatch(pass, &k.ranges, &splats_in, d.tile_entries);
            stamp(pass);
            let raster = match blending {
                Blending::Blocks => &k.raster,
                Blending::Columns => &k.raster_columns,
            };
            // Pass p blends list p mod 2 and hands tiles with entries left on to the other.
            for p in 0..blend_passes {
                let list = (p % 2) as usize;
                live.encode(pass, &self.programs, 4 + list);
                let offset = [offset[0] + p * self.slab_stride];
                let splats_in = [scene, (&self.frame_group, &offset[..]), splats_in[2]];
                live.dispatch(pass, raster, &splats_in, d.listed_tiles[list]);
            }
            stamp(pass);
        }
        live.encode(pass, &self.programs, 6);
        k.compose.run_grid(pass, &groups, grid);
        stamp(pass);
    }
}

#[cfg(test)]
mod tests {
    use super::super::kernel::TEXELS_ACROSS;
    use super::*;

    #[test]
    fn a_batch_holds_every_camera_a_sort_key_names_where_the_uniform_binding_allows() {
        assert_eq!(camera_slots_within(64 << 10), MAX_CAMERAS);
        let all = camera_block_bytes(MAX_CAMERAS);
        assert_eq!(camera_slots_within(all), MAX_CAMERAS);
        assert_eq!(camera_slots_within(all - 1), MAX_CAMERAS - 1);
        // The least a WebGL2-class adapter binds.
        assert_eq!(camera_slots_within(16 << 10), 68);
    }

    #[test]
    fn a_batch_that_overflowed_asks_for_room_for_all_it_would_bin_at_once() {
        let caps = Caps {
            entries: 50,
            splats: 1000,
            tile_entries: 3000,
            ..Caps::default()
        };
        assert_eq!(caps.wanted([50, 1000, 3000]), None);
        // Only the tile entries overflowed: a quarter over those counted.
        assert_eq!(caps.wanted([40, 900, 4000]), Some([40, 1125, 5000]));
        // Three times the splats that fitted: the 2,000 tile entries binned from those stand
        // for 6,000, more than the buffers hold, though fewer than them were counted.
        assert_eq!(caps.wanted([40, 3000, 2000]), Some([40, 3750, 7500]));
        // The scaling saturates rather than wrapping.
        let wanted = caps.wanted([1, u32::MAX, u32::MAX]).unwrap();
        assert_eq!(wanted[2], u32::MAX);
    }

    #[test]
    fn the_splat_textures_hold_every_splat_in_whole_rows_counted_in_the_work_space() {
        assert_eq!(texel_rows(0), 1);
        assert_eq!(texel_rows(TEXELS_ACROSS), 1);
        assert_eq!(texel_rows(TEXELS_ACROSS + 1), 2);
        // The least every WebGPU adapter allows a texture's side.
        assert!(texel_rows(33_554_432) <= 8192);
        let one = Caps {
            splats: 1,
            ..Caps::default()
        };
        let row = Caps {
            splats: TEXELS_ACROSS,
            ..Caps::default()
        };
        // Radix digit counts: a word per pair in blocks of 256 for hardware GPUs, a quarter
        // of that in blocks of 1,024 for CPU drivers.
        assert_eq!(digit_words(KernelShape::Lanes, TEXELS_ACROSS), 4096);
        assert_eq!(digit_words(KernelShape::Runs, TEXELS_ACROSS), 1024);
        for shape in [KernelShape::Lanes, KernelShape::Runs] {
            let digits = |pairs: u32| digit_words(shape, pairs) * 4;
            // A row of texels is allocated whole: the bytes differ by the words of the splats
            // alone (depth keys and values, tile counts) and the depth sort's digit counts.
            let per_splat = 3 * 4;
            assert_eq!(
                row.bytes(shape) - one.bytes(shape),
                u64::from(TEXELS_ACROSS - 1) * per_splat + digits(TEXELS_ACROSS) - digits(1)
            );
            // A row of each splat texture and of the entry table (16 bytes a texel), and of the
            // two textures of each sort's pairs (8 bytes a texel); a block of digit counts for
            // each sort.
            let row_of = |bytes: u64| u64::from(TEXELS_ACROSS) * bytes;
            assert_eq!(
                one.bytes(shape),
                per_splat
                    + 2 * digits(1)
                    + (SPLAT_TEXTURES.len() as u64 + 1) * row_of(16)
                    + 4 * row_of(8)
            );
        }
    }
}
