//! The GPU renderer of one scene: the resident upload, the frame work space, and the recording
//! of a batch of cameras into one submission (`splat.wgsl` holds the kernels).

use super::Gpu;
use super::kernel::{Kernel, bind, layout, storage, storage_at_offset, threads_grid, uniform};
use super::sort::{RadixSort, Scan, ScanPlan, SortPlan};
use crate::camera::Camera;
use crate::project::{LOW_PASS, MAX_ALPHA, MIN_ALPHA};
use crate::render::{RenderOptions, RenderOutput};
use crate::sh;
use crate::tile::{MIN_TRANSMITTANCE, TILE, TileGrid};
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use sage_scene::gaussians::{LOG_SCALE_STEP, OPACITY_LOGIT_STEP, sh_rest_count};
use std::sync::{Arc, Mutex, mpsc};
use wgpu::util::DeviceExt;

/// Bytes of one camera's uniform block (the largest offset alignment adapters ask for).
const CAMERA_BYTES: u64 = 256;
/// Image planes per camera: r, g, b, alpha, expected depth, median depth, instance, category.
const PLANES: u64 = 8;
/// Words per projected splat (four vec4).
const SPLAT_WORDS: u64 = 16;

/// The WGSL constants shared with the CPU renderer, so both executors form images with the
/// same numbers.
fn prelude(sh_rest: usize) -> String {
    let c2 = sh::C2;
    let c3 = sh::C3;
    let mut s = format!(
        "const TILE: u32 = {TILE}u;\nconst LOW_PASS: f32 = {LOW_PASS:?};\n\
         const MIN_ALPHA: f32 = {MIN_ALPHA:?};\nconst MAX_ALPHA: f32 = {MAX_ALPHA:?};\n\
         const MIN_TRANSMITTANCE: f32 = {MIN_TRANSMITTANCE:?};\n\
         const LOG_SCALE_STEP: f32 = {LOG_SCALE_STEP:?};\n\
         const OPACITY_LOGIT_STEP: f32 = {OPACITY_LOGIT_STEP:?};\n\
         const SH_C0: f32 = {:?};\nconst SH_C1: f32 = {:?};\n\
         const SH_REST: u32 = {sh_rest}u;\nconst SH_WORDS: u32 = {}u;\n",
        sh::C0,
        sh::C1,
        sh_words(sh_rest).max(1),
    );
    for (k, c) in c2.iter().enumerate() {
        s += &format!("const SH_C2_{k}: f32 = {c:?};\n");
    }
    for (k, c) in c3.iter().enumerate() {
        s += &format!("const SH_C3_{k}: f32 = {c:?};\n");
    }
    s
}

/// Words of packed i8 SH codes per Gaussian.
fn sh_words(sh_rest: usize) -> usize {
    (sh_rest * 3).div_ceil(4)
}

/// The kernels of `splat.wgsl` and the layouts of their three bind groups.
struct Kernels {
    scene_layout: wgpu::BindGroupLayout,
    frame_layout: wgpu::BindGroupLayout,
    camera_layout: wgpu::BindGroupLayout,
    project: Kernel,
    compact: Kernel,
    count_tiles: Kernel,
    emit: Kernel,
    clear_ranges: Kernel,
    ranges: Kernel,
    raster: Kernel,
    record: Kernel,
    scan: Scan,
    sort: RadixSort,
}

impl Kernels {
    fn new(gpu: &Gpu, sh_rest: usize) -> Kernels {
        let source = prelude(sh_rest) + include_str!("splat.wgsl");
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("splat"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let scene_layout = layout(gpu, &(0..6).map(|b| storage(b, true)).collect::<Vec<_>>());
        let mut frame: Vec<_> = (0..11).map(|b| storage(b, false)).collect();
        frame.push(storage_at_offset(11));
        let frame_layout = layout(gpu, &frame);
        let camera_layout = layout(gpu, &[uniform(0, true)]);
        let layouts = [&scene_layout, &frame_layout, &camera_layout];
        let kernel = |entry: &str| Kernel::new(gpu, &module, entry, &layouts);
        Kernels {
            project: kernel("project"),
            compact: kernel("compact"),
            count_tiles: kernel("count_tiles"),
            emit: kernel("emit"),
            clear_ranges: kernel("clear_ranges"),
            ranges: kernel("ranges"),
            raster: kernel("raster"),
            record: kernel("record"),
            scan: Scan::new(gpu),
            sort: RadixSort::new(gpu),
            scene_layout,
            frame_layout,
            camera_layout,
        }
    }
}

/// The scene on the GPU.
struct SceneBuffers {
    positions: wgpu::Buffer,
    shapes: wgpu::Buffer,
    colors: wgpu::Buffer,
    sh_codes: wgpu::Buffer,
    instances: wgpu::Buffer,
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

fn init_buffer(gpu: &Gpu, label: &str, contents: &[u32]) -> wgpu::Buffer {
    let one = [0u32];
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(if contents.is_empty() { &one } else { contents }),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
}

/// Two i16 in one word, low first.
fn pair(lo: i16, hi: i16) -> u32 {
    u32::from(lo as u16) | u32::from(hi as u16) << 16
}

impl SceneBuffers {
    /// Uploads the store as it is (the same quantised values the CPU renderer reads).
    fn upload(gpu: &Gpu, g: &Gaussians) -> SceneBuffers {
        let n = g.len();
        let positions: Vec<u32> = g.positions.iter().flatten().map(|v| v.to_bits()).collect();
        let shapes: Vec<u32> = (0..n)
            .flat_map(|i| {
                let [w, x, y, z] = g.rotations[i];
                let [sx, sy, sz] = g.log_scales[i];
                [
                    pair(w, x),
                    pair(y, z),
                    pair(sx, sy),
                    pair(sz, g.opacity_logits[i]),
                ]
            })
            .collect();
        let half =
            |lo: half::f16, hi: half::f16| u32::from(lo.to_bits()) | u32::from(hi.to_bits()) << 16;
        let rest = sh_rest_count(g.sh_degree());
        let colors: Vec<u32> = (0..n)
            .flat_map(|i| {
                let [r, gr, b] = g.sh_dc[i];
                let step = if rest > 0 {
                    g.sh_steps[i]
                } else {
                    half::f16::ZERO
                };
                [half(r, gr), half(b, step)]
            })
            .collect();
        let words = sh_words(rest);
        let mut sh_codes = vec![0u32; n * words];
        if rest > 0 {
            for (i, codes) in g.sh_codes.chunks_exact(rest * 3).enumerate() {
                for (j, &c) in codes.iter().enumerate() {
                    sh_codes[i * words + j / 4] |= u32::from(c as u8) << (8 * (j % 4));
                }
            }
        }
        SceneBuffers {
            positions: init_buffer(gpu, "positions", &positions),
            shapes: init_buffer(gpu, "shapes", &shapes),
            colors: init_buffer(gpu, "colors", &colors),
            sh_codes: init_buffer(gpu, "sh codes", &sh_codes),
            instances: init_buffer(gpu, "instances", &g.instances),
        }
    }
}

/// A frame's buffers for up to `capacity` tile entries and `tiles` tiles.
struct Workspace {
    capacity: u32,
    tiles: u32,
    splats: wgpu::Buffer,
    visible: wgpu::Buffer,
    depth: [wgpu::Buffer; 4],
    tile_offsets: wgpu::Buffer,
    tile_pairs: [wgpu::Buffer; 4],
    tile_ranges: wgpu::Buffer,
    visible_scan: ScanPlan,
    offsets_scan: ScanPlan,
    depth_sort: SortPlan,
    tile_sort: SortPlan,
}

/// Most passes the tile sort takes: 8 bits each, up to 2²⁴ tiles (a 65536² image).
const TILE_SORT_PASSES: u32 = 3;

impl Workspace {
    fn new(gpu: &Gpu, k: &Kernels, n: u32, capacity: u32, tiles: u32) -> Workspace {
        let n1 = u64::from(n) + 1;
        let rw = wgpu::BufferUsages::empty();
        let splats = words_buffer(gpu, "splats", u64::from(n) * SPLAT_WORDS, rw);
        let visible = words_buffer(gpu, "visible", n1, rw);
        let depth = [
            "depth keys",
            "depth values",
            "depth keys 2",
            "depth values 2",
        ]
        .map(|l| words_buffer(gpu, l, u64::from(n), rw));
        let tile_offsets = words_buffer(gpu, "tile offsets", n1, rw);
        let tile_pairs = ["tile keys", "tile values", "tile keys 2", "tile values 2"]
            .map(|l| words_buffer(gpu, l, u64::from(capacity), rw));
        let tile_ranges = words_buffer(gpu, "tile ranges", 2 * u64::from(tiles), rw);
        let visible_scan = k.scan.plan(gpu, &visible, n + 1);
        let offsets_scan = k.scan.plan(gpu, &tile_offsets, n + 1);
        let depth_sort = k.sort.plan(
            gpu,
            &k.scan,
            (&depth[0], &depth[1]),
            (&depth[2], &depth[3]),
            n,
            &visible,
            n,
            4,
        );
        let tile_sort = k.sort.plan(
            gpu,
            &k.scan,
            (&tile_pairs[0], &tile_pairs[1]),
            (&tile_pairs[2], &tile_pairs[3]),
            capacity,
            &tile_offsets,
            n,
            TILE_SORT_PASSES,
        );
        Workspace {
            capacity,
            tiles,
            splats,
            visible,
            depth,
            tile_offsets,
            tile_pairs,
            tile_ranges,
            visible_scan,
            offsets_scan,
            depth_sort,
            tile_sort,
        }
    }
}

/// The work of the last batch a [`GpuRenderer`] rendered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GpuStats {
    /// Cameras in the batch.
    pub cameras: usize,
    /// Splats that passed projection, summed over the cameras.
    pub splats: u64,
    /// (splat, tile) pairs, summed over the cameras.
    pub tile_entries: u64,
    /// (splat, tile) pairs the work space holds per camera.
    pub capacity: u32,
    /// Times the batch was rendered again after growing the work space.
    pub regrown: u32,
}

/// A render one caller asked for, queued until whoever holds the GPU takes it: callers on
/// several threads (the walks of a training-data render, the workers of an evaluation) have
/// their cameras rendered together, in one submission.
struct Request {
    cameras: Vec<Camera>,
    categories: Vec<u16>,
    options: RenderOptions,
    reply: mpsc::Sender<Result<Vec<RenderOutput>>>,
}

/// The error of a request whose renderer failed before answering it.
fn lost() -> Error {
    Error::invalid("GPU renderer: the render was lost (the thread rendering it failed)")
}

/// What the frames of one renderer share, behind its lock.
struct State {
    stats: GpuStats,
    categories: Vec<u16>,
    scene_group: wgpu::BindGroup,
    categories_buffer: wgpu::Buffer,
    workspace: Option<Workspace>,
}

/// One scene's Gaussians resident on a [`Gpu`], and the buffers its frames reuse. Shared by
/// reference: renders from several threads take turns.
pub struct GpuRenderer {
    gpu: Arc<Gpu>,
    count: usize,
    kernels: Kernels,
    scene: SceneBuffers,
    state: Mutex<State>,
    /// Requests waiting for the GPU.
    pending: Mutex<Vec<Request>>,
}

/// A camera's place in a batch.
struct Slot {
    grid: TileGrid,
    /// Byte offset of its images in the output buffer.
    offset: u64,
    tile_passes: u32,
}

impl GpuRenderer {
    /// Uploads `gaussians` to `gpu` and compiles the kernels for their SH degree.
    ///
    /// # Errors
    ///
    /// A scene larger than the adapter's buffers, or a GPU fault.
    pub fn new(gpu: &Arc<Gpu>, gaussians: &Gaussians) -> Result<Arc<GpuRenderer>> {
        let n = gaussians.len();
        let largest = (n as u64 * SPLAT_WORDS * 4).max(n as u64 * 16);
        let bound = gpu.largest_binding();
        if largest > bound || n >= u32::MAX as usize / 2 {
            return Err(Error::invalid(format!(
                "GPU {}: a scene of {n} Gaussians needs {} MB buffers; the adapter binds at most {} MB",
                gpu.describe(),
                largest >> 20,
                bound >> 20
            )));
        }
        let kernels = Kernels::new(gpu, sh_rest_count(gaussians.sh_degree()));
        let scene = SceneBuffers::upload(gpu, gaussians);
        let categories_buffer = init_buffer(gpu, "categories", &[]);
        let scene_group = Self::scene_group(gpu, &kernels, &scene, &categories_buffer);
        gpu.check()?;
        Ok(Arc::new(GpuRenderer {
            gpu: gpu.clone(),
            count: n,
            kernels,
            scene,
            state: Mutex::new(State {
                stats: GpuStats::default(),
                categories: Vec::new(),
                scene_group,
                categories_buffer,
                workspace: None,
            }),
            pending: Mutex::new(Vec::new()),
        }))
    }

    fn scene_group(
        gpu: &Gpu,
        k: &Kernels,
        s: &SceneBuffers,
        categories: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        bind(
            gpu,
            &k.scene_layout,
            &[
                s.positions.as_entire_binding(),
                s.shapes.as_entire_binding(),
                s.colors.as_entire_binding(),
                s.sh_codes.as_entire_binding(),
                s.instances.as_entire_binding(),
                categories.as_entire_binding(),
            ],
        )
    }

    /// How many Gaussians it holds.
    pub fn gaussian_count(&self) -> usize {
        self.count
    }

    /// The work of the last batch.
    pub fn stats(&self) -> GpuStats {
        self.state.lock().unwrap_or_else(|p| p.into_inner()).stats
    }

    /// The GPU it renders on.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Renders one camera (see [`GpuRenderer::render_batch`]).
    ///
    /// # Errors
    ///
    /// As [`GpuRenderer::render_batch`].
    pub fn render(
        &self,
        gaussians: &Gaussians,
        categories: &[u16],
        camera: &Camera,
        options: &RenderOptions,
    ) -> Result<RenderOutput> {
        let mut out =
            self.render_batch(gaussians, categories, std::slice::from_ref(camera), options)?;
        Ok(out.remove(0))
    }

    /// Renders every camera of `cameras` (any sizes) in one submission and one read-back;
    /// `categories[instance]` gives each instance's semantic id (missing → 0). Calls from
    /// several threads at once take turns on the GPU, and whoever takes it renders what the
    /// others queued meanwhile in the same submission.
    ///
    /// # Errors
    ///
    /// Another set of Gaussians, a camera the renderer refuses, or a GPU fault.
    pub fn render_batch(
        &self,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        if gaussians.len() != self.count {
            return Err(Error::invalid(format!(
                "renderer was built for {} Gaussians, asked to render {}",
                self.count,
                gaussians.len()
            )));
        }
        for c in cameras {
            c.validate()?;
        }
        if cameras.is_empty() {
            return Ok(Vec::new());
        }
        let (reply, answer) = mpsc::channel();
        self.pending
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Request {
                cameras: cameras.to_vec(),
                categories: categories.to_vec(),
                options: *options,
                reply,
            });
        loop {
            // Another caller may have rendered this request with its own while this one
            // waited for the GPU.
            match answer.try_recv() {
                Ok(out) => return out,
                Err(mpsc::TryRecvError::Disconnected) => return Err(lost()),
                Err(mpsc::TryRecvError::Empty) => {}
            }
            let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
            match answer.try_recv() {
                Ok(out) => return out,
                Err(mpsc::TryRecvError::Disconnected) => return Err(lost()),
                Err(mpsc::TryRecvError::Empty) => {}
            }
            // Requests are only taken with the GPU held, so this one is still queued: render
            // everything queued now, this one included.
            let requests =
                std::mem::take(&mut *self.pending.lock().unwrap_or_else(|p| p.into_inner()));
            self.serve(&mut state, requests);
        }
    }

    /// Renders queued requests — those with the same categories and options in one
    /// submission — and sends each its images.
    fn serve(&self, state: &mut State, mut requests: Vec<Request>) {
        while let Some(first) = requests.first() {
            let (categories, options) = (first.categories.clone(), first.options);
            let (group, rest): (Vec<Request>, Vec<Request>) = requests
                .into_iter()
                .partition(|r| r.categories == categories && r.options == options);
            requests = rest;
            let cameras: Vec<Camera> = group.iter().flat_map(|r| r.cameras.clone()).collect();
            match self.render_held(state, &categories, &cameras, &options) {
                Ok(images) => {
                    let mut images = images.into_iter();
                    for r in group {
                        let mine = images.by_ref().take(r.cameras.len()).collect();
                        // A caller that went away no longer wants its images.
                        let _ = r.reply.send(Ok(mine));
                    }
                }
                Err(e) => {
                    for r in group {
                        let _ = r.reply.send(Err(Error::invalid(e.message().to_string())));
                    }
                }
            }
        }
    }

    /// Renders `cameras` in one submission with the GPU held.
    fn render_held(
        &self,
        state: &mut State,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        let gpu = &*self.gpu;
        if state.categories != categories {
            let words: Vec<u32> = categories.iter().map(|&c| u32::from(c)).collect();
            state.categories_buffer = init_buffer(gpu, "categories", &words);
            state.scene_group =
                Self::scene_group(gpu, &self.kernels, &self.scene, &state.categories_buffer);
            state.categories = categories.to_vec();
        }
        let align = u64::from(gpu.limits().min_storage_buffer_offset_alignment).max(4);
        let mut offset = 0;
        let slots: Vec<Slot> = cameras
            .iter()
            .map(|c| {
                let grid = TileGrid::new(c);
                let bits = u32::BITS - (grid.tiles() as u32 - 1).leading_zeros();
                let slot = Slot {
                    grid,
                    offset,
                    tile_passes: bits.div_ceil(8).max(1),
                };
                offset += (PLANES * 4 * (grid.width * grid.height) as u64).next_multiple_of(align);
                slot
            })
            .collect();
        let tiles = slots
            .iter()
            .map(|s| s.grid.tiles() as u32)
            .max()
            .unwrap_or(1);
        let n = self.count as u32;
        let most_entries = (gpu.largest_binding() / 4).min(u64::from(u32::MAX)) as u32;
        let mut regrown = 0;
        let mut capacity = state
            .workspace
            .as_ref()
            .map_or(n.saturating_mul(2).saturating_add(65_536), |w| w.capacity)
            .min(most_entries);
        loop {
            let fits = state
                .workspace
                .as_ref()
                .is_some_and(|w| w.tiles >= tiles && w.capacity >= capacity);
            if !fits {
                let tiles = state
                    .workspace
                    .as_ref()
                    .map_or(tiles, |w| w.tiles.max(tiles));
                state.workspace = Some(Workspace::new(gpu, &self.kernels, n, capacity, tiles));
            }
            let workspace = state.workspace.as_ref().expect("allocated above");
            let (images, counts) =
                self.run_batch(&state.scene_group, workspace, cameras, &slots, options)?;
            let needed = counts.iter().skip(1).step_by(2).copied().max().unwrap_or(0);
            if needed > workspace.capacity {
                // More (splat, tile) entries than the buffers hold: grow and render again.
                if needed > most_entries {
                    return Err(Error::invalid(format!(
                        "GPU {}: a frame needs {needed} (splat, tile) entries; the adapter's \
                         buffers hold {most_entries} (render smaller images)",
                        gpu.describe()
                    )));
                }
                capacity = needed.saturating_add(needed / 4).min(most_entries);
                regrown += 1;
                continue;
            }
            let sum = |k: usize| {
                counts
                    .iter()
                    .skip(k)
                    .step_by(2)
                    .map(|&c| u64::from(c))
                    .sum()
            };
            state.stats = GpuStats {
                cameras: cameras.len(),
                splats: sum(0),
                tile_entries: sum(1),
                capacity: workspace.capacity,
                regrown,
            };
            return Ok(slots.iter().map(|s| unpack(&images, s)).collect());
        }
    }

    /// Records, submits and reads back one batch; returns the images (all slots) and the
    /// visible-splat and tile-entry counts of each camera.
    fn run_batch(
        &self,
        scene_group: &wgpu::BindGroup,
        w: &Workspace,
        cameras: &[Camera],
        slots: &[Slot],
        options: &RenderOptions,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        let gpu = &*self.gpu;
        let k = &self.kernels;
        let n = self.count as u32;
        let last = slots.last().expect("a batch has cameras");
        let largest = slots
            .iter()
            .map(|s| PLANES * 4 * (s.grid.width * s.grid.height) as u64)
            .max()
            .unwrap_or(4);
        let image_bytes = last.offset + largest;
        let images = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("images"),
            size: image_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let counts_bytes = 8 * cameras.len() as u64;
        let counts = words_buffer(
            gpu,
            "counts",
            2 * cameras.len() as u64,
            wgpu::BufferUsages::COPY_SRC,
        );
        let mut uniforms = Vec::with_capacity(cameras.len() * CAMERA_BYTES as usize / 4);
        for (i, (c, s)) in cameras.iter().zip(slots).enumerate() {
            uniforms.extend_from_slice(&camera_block(c, s, n, w.capacity, i as u32, options));
        }
        let camera_buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("cameras"),
                contents: bytemuck::cast_slice(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let camera_group = bind(
            gpu,
            &k.camera_layout,
            &[wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &camera_buffer,
                offset: 0,
                size: wgpu::BufferSize::new(CAMERA_BYTES),
            })],
        );
        let [d0, d1, ..] = &w.depth;
        let [t0, t1, t2, t3] = &w.tile_pairs;
        let frame_group = bind(
            gpu,
            &k.frame_layout,
            &[
                w.splats.as_entire_binding(),
                w.visible.as_entire_binding(),
                d0.as_entire_binding(),
                d1.as_entire_binding(),
                w.tile_offsets.as_entire_binding(),
                t0.as_entire_binding(),
                t1.as_entire_binding(),
                t2.as_entire_binding(),
                t3.as_entire_binding(),
                w.tile_ranges.as_entire_binding(),
                counts.as_entire_binding(),
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &images,
                    offset: 0,
                    size: wgpu::BufferSize::new(largest),
                }),
            ],
        );
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("render"),
                timestamp_writes: None,
            });
            for (i, s) in slots.iter().enumerate() {
                let camera_offset = (i as u64 * CAMERA_BYTES) as u32;
                let groups: [(&wgpu::BindGroup, &[u32]); 3] = [
                    (scene_group, &[]),
                    (&frame_group, &[s.offset as u32]),
                    (&camera_group, &[camera_offset]),
                ];
                let all = threads_grid(n + 1);
                k.project.run_grid(&mut pass, &groups, all);
                k.scan.encode(&mut pass, &w.visible_scan);
                k.compact.run_grid(&mut pass, &groups, all);
                k.sort.encode(&mut pass, &k.scan, &w.depth_sort, 4);
                k.count_tiles.run_grid(&mut pass, &groups, all);
                k.scan.encode(&mut pass, &w.offsets_scan);
                k.emit.run_grid(&mut pass, &groups, all);
                k.sort
                    .encode(&mut pass, &k.scan, &w.tile_sort, s.tile_passes as usize);
                k.clear_ranges
                    .run_grid(&mut pass, &groups, threads_grid(s.grid.tiles() as u32));
                k.ranges
                    .run_grid(&mut pass, &groups, threads_grid(w.capacity));
                k.raster.run_grid(
                    &mut pass,
                    &groups,
                    (s.grid.tiles_x as u32, s.grid.tiles_y as u32),
                );
                k.record.run_grid(&mut pass, &groups, (1, 1));
            }
        }
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: image_bytes + counts_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_buffer_to_buffer(&images, 0, &staging, 0, image_bytes);
        encoder.copy_buffer_to_buffer(&counts, 0, &staging, image_bytes, counts_bytes);
        gpu.queue.submit([encoder.finish()]);
        let words = read_back(gpu, &staging)?;
        let split = (image_bytes / 4) as usize;
        Ok((words[..split].to_vec(), words[split..].to_vec()))
    }
}

/// Maps `staging` after the queue finished and copies it out.
fn read_back(gpu: &Gpu, staging: &wgpu::Buffer) -> Result<Vec<u32>> {
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::invalid(format!("GPU {}: {e}", gpu.describe())))?;
    gpu.check()?;
    match rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(Error::invalid(format!(
                "GPU {}: read-back failed: {e}",
                gpu.describe()
            )));
        }
        Err(_) => {
            return Err(Error::invalid(format!(
                "GPU {}: the device was lost during the read-back",
                gpu.describe()
            )));
        }
    }
    let words = {
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| Error::invalid(format!("GPU {}: {e}", gpu.describe())))?;
        bytemuck::cast_slice::<u8, u32>(&view).to_vec()
    };
    staging.unmap();
    Ok(words)
}

/// The uniform block of one camera (`Camera` in `splat.wgsl`), padded to [`CAMERA_BYTES`].
fn camera_block(
    c: &Camera,
    s: &Slot,
    n: u32,
    capacity: u32,
    index: u32,
    options: &RenderOptions,
) -> [u32; CAMERA_BYTES as usize / 4] {
    let k = c.intrinsics;
    let r = c.rotation;
    let floats: [[f32; 4]; 7] = [
        [r.x_axis.x, r.x_axis.y, r.x_axis.z, 0.0],
        [r.y_axis.x, r.y_axis.y, r.y_axis.z, 0.0],
        [r.z_axis.x, r.z_axis.y, r.z_axis.z, 0.0],
        [c.position.x, c.position.y, c.position.z, 0.0],
        [k.fx, k.fy, k.cx, k.cy],
        [
            c.near,
            c.far,
            1.3 * k.width as f32 * 0.5 / k.fx,
            1.3 * k.height as f32 * 0.5 / k.fy,
        ],
        [
            options.background[0],
            options.background[1],
            options.background[2],
            0.0,
        ],
    ];
    let mut block = [0u32; CAMERA_BYTES as usize / 4];
    for (i, v) in floats.iter().flatten().enumerate() {
        block[i] = v.to_bits();
    }
    let words = [
        s.grid.width as u32,
        s.grid.height as u32,
        s.grid.tiles_x as u32,
        s.grid.tiles_y as u32,
        n,
        capacity,
        s.tile_passes % 2,
        index,
    ];
    block[28..36].copy_from_slice(&words);
    block
}

/// One camera's images from the read-back words.
fn unpack(words: &[u32], s: &Slot) -> RenderOutput {
    let (width, height) = (s.grid.width, s.grid.height);
    let p = width * height;
    let base = (s.offset / 4) as usize;
    let plane = |k: usize| &words[base + k * p..base + (k + 1) * p];
    let float = |k: usize| {
        plane(k)
            .iter()
            .map(|&w| f32::from_bits(w))
            .collect::<Vec<f32>>()
    };
    let (r, g, b) = (float(0), float(1), float(2));
    let rgb_f32: Vec<f32> = (0..p).flat_map(|i| [r[i], g[i], b[i]]).collect();
    let rgb = rgb_f32
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    RenderOutput {
        width,
        height,
        rgb,
        rgb_f32,
        alpha: float(3),
        depth_expected: float(4),
        depth_median: float(5),
        instance: plane(6).to_vec(),
        semantic: plane(7).iter().map(|&c| c as u16).collect(),
    }
}
