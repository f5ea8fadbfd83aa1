//! The GPU renderer of one scene: the resident upload, the batches it renders in the
//! persistent work space, and the overlap of one batch's read-back with the next batch's
//! rendering (`splat.wgsl` holds the kernels, [`super::workspace`] the buffers).

use super::Gpu;
use super::kernel::{RUN_GROUP, TEXELS_ACROSS, bind, texel_rows};
use super::live::LIVE_WORDS;
use super::scene::{SceneBuffers, appearance_texels, init_buffer};
use super::workspace::{
    BatchPlan, CAMERA_WORDS, Caps, DEPTH_BINS, DEPTH_KEY_BITS, ENTRY_TEXELS, Kernels,
    LIVE_CAMERA_CHUNKS, LIVE_CAMERAS, LIVE_FEW_CHUNKS, LIVE_OUT_PLANES, LIVE_PASSES, LIVE_PIECE,
    LIVE_SECOND_COUNT, LIVE_SLABS, LIVE_TILES, LIVE_WANTED_AT, MAX_BLEND_PASSES, PLANES, SLABS,
    SPLAT_INDEX_BITS, TILE_SORT_PASSES, Workspace, camera_block_bytes, camera_slots, list_words,
};
use crate::camera::Camera;
use crate::index::{SplatIndex, frustum_planes};
use crate::passes::{Blending, GPU_FEW_CHUNKS, KernelShape, PassTimes};
use crate::project::{LOW_PASS, MAX_ALPHA, MIN_ALPHA};
use crate::render::{Channels, RenderOptions, RenderOutput, to_byte};
use crate::sh;
use crate::tile::{MIN_TRANSMITTANCE, TILE, TileGrid};
use rayon::prelude::*;
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use sage_scene::gaussians::{LOG_SCALE_STEP, sh_rest_count};
use std::collections::VecDeque;
use std::ops::Range;
use std::sync::{Arc, Mutex, MutexGuard, mpsc};

/// The WGSL constants shared with the CPU renderer, so both executors form images with the
/// same numbers, and the scene's sizes.
fn prelude(sh_rest: usize, gaussians: u32, chunks: u32, camera_slots: u32) -> String {
    let mut s = format!(
        "const TILE: u32 = {TILE}u;\nconst LOW_PASS: f32 = {LOW_PASS:?};\n\
         const MIN_ALPHA: f32 = {MIN_ALPHA:?};\nconst MAX_ALPHA: f32 = {MAX_ALPHA:?};\n\
         const MIN_TRANSMITTANCE: f32 = {MIN_TRANSMITTANCE:?};\n\
         const LOG_SCALE_STEP: f32 = {LOG_SCALE_STEP:?};\n\
         const SH_C0: f32 = {:?};\nconst SH_C1: f32 = {:?};\n\
         const SH_REST: u32 = {sh_rest}u;\nconst APPEARANCE_TEXELS: u32 = {}u;\n\
         const GAUSSIANS: u32 = {gaussians}u;\nconst CHUNKS: u32 = {chunks}u;\n\
         const LIVE_CAMERA_CHUNKS: u32 = {LIVE_CAMERA_CHUNKS}u;\n\
         const LIVE_TILES: u32 = {LIVE_TILES}u;\n\
         const LIVE_CAMERAS: u32 = {LIVE_CAMERAS}u;\nconst LIVE_SLABS: u32 = {LIVE_SLABS}u;\n\
         const LIVE_OUT_PLANES: u32 = {LIVE_OUT_PLANES}u;\n\
         const LIVE_FEW_CHUNKS: u32 = {LIVE_FEW_CHUNKS}u;\n\
         const LIVE_PIECE: u32 = {LIVE_PIECE}u;\nconst LIVE_PASSES: u32 = {LIVE_PASSES}u;\n\
         const DEPTH_KEY_BITS: u32 = {DEPTH_KEY_BITS}u;\n\
         const SPLAT_INDEX_BITS: u32 = {SPLAT_INDEX_BITS}u;\n\
         const ENTRY_TEXELS: u32 = {ENTRY_TEXELS}u;\n\
         const SLABS: u32 = {SLABS}u;\n\
         const DEPTH_BINS: u32 = {DEPTH_BINS}u;\nconst PLANES: u32 = {PLANES}u;\n\
         const CAMERA_SLOTS: u32 = {camera_slots}u;\n\
         const RUN_GROUP: u32 = {RUN_GROUP}u;\n\
         const TEXELS_ACROSS: u32 = {TEXELS_ACROSS}u;\n",
        sh::C0,
        sh::C1,
        appearance_texels(sh_rest),
    );
    s += &format!(
        "const LOG2_E: f32 = {:?};\nconst LN_2: f32 = {:?};\nconst SQRT_2: f32 = {:?};\n",
        std::f32::consts::LOG2_E,
        std::f32::consts::LN_2,
        std::f32::consts::SQRT_2
    );
    for (name, bit) in OUT_BITS {
        s += &format!("const {name}: u32 = {bit}u;\n");
    }
    for (k, c) in crate::fastmath::EXP2_POLY.iter().enumerate() {
        s += &format!("const EXP2_POLY_{k}: f32 = {c:?};\n");
    }
    for (k, c) in sh::C2.iter().enumerate() {
        s += &format!("const SH_C2_{k}: f32 = {c:?};\n");
    }
    for (k, c) in sh::C3.iter().enumerate() {
        s += &format!("const SH_C3_{k}: f32 = {c:?};\n");
    }
    s
}

/// The images `compose` writes out, as `live[LIVE_OUT_PLANES]`'s bits, in the order their
/// planes follow each other.
const OUT_BITS: [(&str, u32); 7] = [
    ("OUT_RGB8", 1),
    ("OUT_RGB_F32", 2),
    ("OUT_ALPHA", 4),
    ("OUT_DEPTH_EXPECTED", 8),
    ("OUT_DEPTH_MEDIAN", 16),
    ("OUT_INSTANCE", 32),
    ("OUT_SEMANTIC", 64),
];

/// What the GPU writes out and reads back for the images of `channels`: the `OUT_*` bits and
/// the words per pixel. The 8-bit colour comes packed, a word per pixel, unless the float
/// colour is asked for too: then the host rounds the floats, as the CPU renderer does.
fn out_planes(channels: &Channels) -> (u32, u64) {
    let planes = [
        (channels.rgb && !channels.rgb_f32, 1),
        (channels.rgb_f32, 3),
        (channels.alpha, 1),
        (channels.depth_expected, 1),
        (channels.depth_median, 1),
        (channels.instance, 1),
        (channels.semantic, 1),
    ];
    planes
        .iter()
        .zip(OUT_BITS)
        .filter(|((on, _), _)| *on)
        .fold((0, 0), |(bits, words), ((_, w), (_, bit))| {
            (bits | bit, words + w)
        })
}

/// The slabs a batch of `cameras` renders in unless they are fixed: one where every camera
/// sees fewer than [`GPU_FEW_CHUNKS`] chunks of `index` (counted on the host, as `cull` counts
/// them), else [`SLABS`], in which `cut_slabs` still gives such a camera the first alone. Chosen
/// from the batch itself, not from the one before, so that a view of many chunks after views
/// of few is never rendered in one slab (on lavapipe 1.2–3.9 times its time in four); the
/// images are the same whatever the slabs.
fn slabs_for(index: &SplatIndex, cameras: &[Camera]) -> u32 {
    let few = GPU_FEW_CHUNKS as usize;
    if cameras
        .par_iter()
        .all(|c| index.visible_count(c, few) < few)
    {
        1
    } else {
        SLABS
    }
}

/// The most entries of its tile a blending workgroup takes at once on a CPU driver
/// ([`GpuRenderer::set_blend_piece`]): `raster` spends at most about 305 loop iterations per
/// 256 entries (each splat reaching its block, and the words of block bits), so a piece spends
/// some 39,000 of lavapipe's 65,535 per invocation, the rest kept for the kernel's other loops.
pub const SOFTWARE_PIECE: u32 = 32 * 1024;

/// The blending piece on `gpu` by default: [`SOFTWARE_PIECE`] on a CPU driver, else unbounded.
fn default_piece(gpu: &Gpu) -> u32 {
    if gpu.is_software() {
        SOFTWARE_PIECE
    } else {
        u32::MAX
    }
}

/// The work of the last batch a [`GpuRenderer`] rendered.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GpuStats {
    /// Cameras in the batch.
    pub cameras: usize,
    /// Depth slabs it rendered in (its last part's, when rendered in parts).
    pub slabs: u32,
    /// (camera, chunk of 256 Gaussians) pairs projected, summed over the cameras and the depth
    /// slabs: those in the view that reach a slab and some unfinished tile (a chunk spanning
    /// several slabs counts in each).
    pub chunks: u64,
    /// Splats projected (in the image, over some unfinished tile), summed over the cameras.
    pub splats: u64,
    /// (splat, unfinished tile) pairs, summed over the cameras.
    pub tile_entries: u64,
    /// (splat, tile) pairs the work space holds.
    pub capacity: u32,
    /// Times a batch (or a part of one) was rendered again after growing the work space or its
    /// blending passes, or in two halves where one work space could not hold it.
    pub regrown: u32,
    /// Blending passes per slab: a tile blends at most [`GpuRenderer::set_blend_piece`]'s
    /// entries in one pass and the rest in the passes after.
    pub blend_passes: u32,
    /// Device bytes of the work space (the scene's upload not included).
    pub workspace_bytes: u64,
    /// GPU time of each stage, when the renderer times its passes
    /// ([`GpuRenderer::time_passes`]).
    pub passes: Option<PassTimes>,
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
    /// Depth slabs every batch renders in, when fixed ([`GpuRenderer::set_slabs`]).
    fixed_slabs: Option<u32>,
    /// The blending kernel ([`GpuRenderer::set_blending`]).
    blending: Blending,
    /// The most entries of its tile a blending workgroup takes at once
    /// ([`GpuRenderer::set_blend_piece`]), and the blending passes per slab, grown when a tile
    /// of a batch wanted more.
    piece: u32,
    blend_passes: u32,
    categories: Vec<u16>,
    scene_group: wgpu::BindGroup,
    categories_buffer: wgpu::Buffer,
    workspace: Option<Workspace>,
    /// The most splats and (tile, splat) entries a camera needed, from batches that found more
    /// than the work space held: a batch of as many cameras is sized for them before it renders
    /// (or split, where one binding would not hold them) rather than rendered in vain again.
    per_camera: [u32; 2],
    /// Read-back buffers not in flight.
    staging: Vec<wgpu::Buffer>,
    /// The timestamps of the passes and the buffer they resolve into, while timing.
    timing: Option<(wgpu::QuerySet, wgpu::Buffer)>,
}

/// One scene's Gaussians resident on a [`Gpu`], and the buffers its frames reuse. Shared by
/// reference: renders from several threads take turns.
pub struct GpuRenderer {
    gpu: Arc<Gpu>,
    count: usize,
    chunks: u32,
    scene_bytes: u64,
    kernels: Kernels,
    scene: SceneBuffers,
    state: Mutex<State>,
    /// Requests waiting for the GPU.
    pending: Mutex<Vec<Request>>,
}

/// A camera's place in a batch's read-back.
struct Slot {
    grid: TileGrid,
    /// First word of its images after the read-back's live words.
    offset: u64,
}

/// A batch recorded and submitted, its read-back not yet mapped.
struct InFlight {
    staging: wgpu::Buffer,
    submission: wgpu::SubmissionIndex,
    mapped: mpsc::Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
    slots: Vec<Slot>,
    /// The images asked for.
    channels: Channels,
    /// Their words in the read-back.
    image_words: u64,
    /// Timestamps after the images in the read-back (0 when not timed).
    stamps: u32,
    /// Depth slabs it rendered in, its blending passes per slab and their piece.
    slabs: u32,
    blend_passes: u32,
    piece: u32,
    /// The live slot of the most blending passes a tile wanted.
    passes_wanted: u32,
    /// What the work space held when it rendered, and the live slots of its unclamped counts
    /// (largest and sum over the slabs).
    caps: Caps,
    peaks: [u32; 3],
    totals: [u32; 3],
}

/// The outcome of a batch: its images, or the larger work space or the blending passes per
/// slab it needs.
enum Finished {
    Images(Vec<RenderOutput>, GpuStats),
    Grow(Caps),
    /// The blending passes per slab a tile wanted, in pieces of `piece` entries.
    MorePasses {
        passes: u32,
        piece: u32,
    },
}

/// A batch submitted to the GPU by [`GpuRenderer::submit`]: the caller does other work while
/// it renders and reads back, then [`Submitted::wait`]s for the images.
pub struct Submitted {
    renderer: Arc<GpuRenderer>,
    cameras: Vec<Camera>,
    categories: Vec<u16>,
    options: RenderOptions,
    flight: Flight,
}

/// Where a submitted batch is.
enum Flight {
    /// On the GPU.
    Out(Box<InFlight>),
    /// Rendered already (a batch too large for one submission is rendered in parts at once).
    Done(Vec<RenderOutput>),
}

impl Submitted {
    /// The images, in camera order (rendered again, after the work space or the blending
    /// passes grew, when the batch needed more than they held: counted in
    /// [`GpuStats::regrown`]).
    ///
    /// # Errors
    ///
    /// A GPU fault.
    pub fn wait(self) -> Result<Vec<RenderOutput>> {
        let flight = match self.flight {
            Flight::Done(images) => return Ok(images),
            Flight::Out(flight) => *flight,
        };
        let r = &self.renderer;
        let mut state = r.lock();
        match r.finish(&mut state, flight)? {
            Finished::Images(images, stats) => {
                state.stats = stats;
                return Ok(images);
            }
            Finished::Grow(need) => {
                if need.fit(&r.gpu) {
                    r.grow(&mut state, need);
                }
            }
            Finished::MorePasses { passes, piece } => r.more_passes(&mut state, passes, piece)?,
        }
        // Rendered again, with this batch's categories bound (another caller may have changed
        // them since).
        let images = r.render_held(&mut state, &self.categories, &self.cameras, &self.options)?;
        state.stats.regrown += 1;
        Ok(images)
    }
}

impl GpuRenderer {
    /// Uploads `gaussians` to `gpu` and compiles the kernels for their SH degree, in the
    /// shape for the adapter ([`KernelShape::for_adapter`]).
    ///
    /// # Errors
    ///
    /// A scene larger than the adapter's buffers or textures, or a GPU fault.
    pub fn new(gpu: &Arc<Gpu>, gaussians: &Gaussians) -> Result<Arc<GpuRenderer>> {
        Self::with_shape(gpu, gaussians, KernelShape::for_adapter(gpu.is_software()))
    }

    /// As [`GpuRenderer::new`], with the kernels of `shape` whatever the adapter: the images
    /// are the same bytes, only the time differs.
    ///
    /// # Errors
    ///
    /// As [`GpuRenderer::new`].
    pub fn with_shape(
        gpu: &Arc<Gpu>,
        gaussians: &Gaussians,
        shape: KernelShape,
    ) -> Result<Arc<GpuRenderer>> {
        let n = gaussians.len();
        // The largest scene texture: the appearance, up to four texels a Gaussian.
        let texels = n as u64 * u64::from(appearance_texels(sh_rest_count(gaussians.sh_degree())));
        let rows = texel_rows(u32::try_from(texels).unwrap_or(u32::MAX));
        let most_rows = gpu.limits().max_texture_dimension_2d;
        if rows > most_rows || n >= u32::MAX as usize / 2 {
            return Err(Error::invalid(format!(
                "GPU {}: a scene of {n} Gaussians needs textures of {rows} rows of \
                 {TEXELS_ACROSS} texels; the adapter holds at most {most_rows} rows",
                gpu.describe(),
            )));
        }
        let scene = SceneBuffers::upload(gpu, gaussians);
        let slots = camera_slots(gpu);
        let source = prelude(
            sh_rest_count(gaussians.sh_degree()),
            n as u32,
            scene.chunks,
            slots,
        ) + include_str!("texel.wgsl")
            + include_str!("splat.wgsl");
        let kernels = Kernels::new(gpu, source, slots, shape);
        let categories_buffer = init_buffer(gpu, "categories", &[]);
        let scene_group = Self::scene_group(gpu, &kernels, &scene, &categories_buffer);
        gpu.check()?;
        Ok(Arc::new(GpuRenderer {
            gpu: gpu.clone(),
            count: n,
            chunks: scene.chunks,
            scene_bytes: scene.bytes,
            kernels,
            scene,
            state: Mutex::new(State {
                stats: GpuStats::default(),
                fixed_slabs: None,
                blending: Blending::default(),
                piece: default_piece(gpu),
                blend_passes: 1,
                categories: Vec::new(),
                scene_group,
                categories_buffer,
                workspace: None,
                per_camera: [0; 2],
                staging: Vec::new(),
                timing: None,
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
                wgpu::BindingResource::TextureView(&s.positions),
                wgpu::BindingResource::TextureView(&s.shapes),
                wgpu::BindingResource::TextureView(&s.appearance),
                categories.as_entire_binding(),
                s.chunk_bounds.as_entire_binding(),
            ],
        )
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// How many Gaussians it holds.
    pub fn gaussian_count(&self) -> usize {
        self.count
    }

    /// Device bytes of the resident scene (Gaussians and chunk bounds).
    pub fn scene_bytes(&self) -> u64 {
        self.scene_bytes
    }

    /// The work of the last batch.
    pub fn stats(&self) -> GpuStats {
        self.lock().stats
    }

    /// The GPU it renders on.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Times the stages of every batch from now on (or stops): [`GpuStats::passes`]. Returns
    /// false, timing nothing, when the device cannot write timestamps between dispatches.
    pub fn time_passes(&self, on: bool) -> bool {
        let mut state = self.lock();
        if !on || !self.gpu.has_timestamps() {
            state.timing = None;
            return false;
        }
        if state.timing.is_none() {
            let count = PassTimes::stamps(SLABS) + 1;
            let queries = self.gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            });
            let resolved = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("resolved timestamps"),
                size: u64::from(count) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            state.timing = Some((queries, resolved));
        }
        true
    }

    /// Renders every batch from now on in `slabs` depth slabs (1 to
    /// [`GPU_SLABS`](crate::passes::GPU_SLABS)), every camera of it in all of them, or, with
    /// `None` (the default), in one when every camera of the batch sees fewer than
    /// [`GPU_FEW_CHUNKS`] chunks, else in all of them with such a camera in the first alone.
    /// The images are the same whatever the slabs: what changes is the work skipped behind
    /// finished tiles against the dispatches each slab costs, which weigh differently on each
    /// device (`sage3d bench render --slabs` measures them).
    ///
    /// # Errors
    ///
    /// A count outside 1 to [`GPU_SLABS`](crate::passes::GPU_SLABS).
    pub fn set_slabs(&self, slabs: Option<u32>) -> Result<()> {
        crate::Device::Gpu.check_slabs(slabs)?;
        let mut state = self.lock();
        state.fixed_slabs = slabs;
        Ok(())
    }

    /// Blends every batch from now on with `blending`'s kernel (the default,
    /// [`Blending::Blocks`], is the one measured fastest so far; `sage3d bench render
    /// --blending` measures each). The images are the same bytes with either.
    pub fn set_blending(&self, blending: Blending) {
        self.lock().blending = blending;
    }

    /// Lets one blending workgroup take at most `entries` of its tile's entries in a slab
    /// (rounded up to a multiple of 256) before handing the rest on to a later pass, or, with
    /// `None`, the adapter's default: [`SOFTWARE_PIECE`] on a CPU driver, whose shaders stop
    /// every loop of an invocation silently once a budget of iterations is spent (lavapipe's
    /// 65,535), and no bound on a hardware GPU. A batch whose tile wants more passes than the
    /// renderer records is rendered again with as many (counted in [`GpuStats::regrown`]), and
    /// later batches keep them until the piece changes. The images are the same bytes whatever
    /// the pieces.
    ///
    /// # Errors
    ///
    /// Zero entries.
    pub fn set_blend_piece(&self, entries: Option<u32>) -> Result<()> {
        let piece = match entries {
            Some(0) => return Err(Error::invalid("blending piece: at least one entry")),
            Some(n) => n.div_ceil(256).saturating_mul(256).max(256),
            None => default_piece(&self.gpu),
        };
        let mut state = self.lock();
        if state.piece != piece {
            // Passes are counted in pieces: they grow again as batches want.
            state.piece = piece;
            state.blend_passes = 1;
        }
        Ok(())
    }

    /// Records `passes` blending passes per slab from now on, as a batch's tile wanted in
    /// pieces of `piece` entries (nothing when the piece has changed since: the batch rendered
    /// again in the new pieces says what it wants).
    fn more_passes(&self, state: &mut State, passes: u32, piece: u32) -> Result<()> {
        if piece != state.piece {
            return Ok(());
        }
        if passes > MAX_BLEND_PASSES {
            return Err(Error::invalid(format!(
                "GPU {}: a tile lists more than {} (splat, tile) entries in one depth slab, more \
                 than {MAX_BLEND_PASSES} blending passes of {piece} take (render with more slabs \
                 or a larger blending piece)",
                self.gpu.describe(),
                u64::from(MAX_BLEND_PASSES) * u64::from(piece),
            )));
        }
        state.blend_passes = state.blend_passes.max(passes);
        Ok(())
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

    /// Checks a request: the scene it was built for, cameras it can render.
    fn check(&self, gaussians: &Gaussians, cameras: &[Camera]) -> Result<()> {
        if gaussians.len() != self.count {
            return Err(Error::invalid(format!(
                "renderer was built for {} Gaussians, asked to render {}",
                self.count,
                gaussians.len()
            )));
        }
        cameras.iter().try_for_each(Camera::validate)
    }

    /// Renders every camera of `cameras` (any sizes) in the same dispatches, one submission
    /// and one read-back per batch that fits the adapter's buffers; `categories[instance]`
    /// gives each instance's semantic id (missing → 0). Calls from several threads at once
    /// are rendered together: whoever takes the GPU renders everything queued.
    ///
    /// # Errors
    ///
    /// Another set of Gaussians than the renderer was built for, a camera the CPU renderer
    /// would refuse, a frame larger than the adapter's buffers, or a GPU fault.
    pub fn render_batch(
        &self,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        self.check(gaussians, cameras)?;
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
            let mut state = self.lock();
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

    /// Submits `cameras` as one batch and returns at once: the caller overlaps its own work
    /// (encoding the last batch's images, stepping physics) with the rendering and read-back,
    /// then [`Submitted::wait`]s. Images equal [`GpuRenderer::render_batch`]'s.
    ///
    /// # Errors
    ///
    /// As [`GpuRenderer::render_batch`].
    pub fn submit(
        self: &Arc<Self>,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Submitted> {
        self.check(gaussians, cameras)?;
        let mut state = self.lock();
        self.use_categories(&mut state, categories);
        let need = self.need(&state, cameras, &options.channels);
        let flight = if cameras.is_empty() {
            Flight::Done(Vec::new())
        } else if !need.fit(&self.gpu) || cameras.len() > self.kernels.camera_slots as usize {
            // Too large for one submission: rendered in parts now.
            Flight::Done(self.render_held(&mut state, categories, cameras, options)?)
        } else {
            Flight::Out(Box::new(self.launch(&mut state, cameras, options, need)?))
        };
        Ok(Submitted {
            renderer: self.clone(),
            cameras: cameras.to_vec(),
            categories: categories.to_vec(),
            options: *options,
            flight,
        })
    }

    /// Renders queued requests — those with the same categories and options in one
    /// submission — and sends each its images.
    fn serve(&self, state: &mut State, mut requests: Vec<Request>) {
        while !requests.is_empty() {
            let first = requests.remove(0);
            let (categories, options) = (first.categories.clone(), first.options);
            // The first request is always served (options with a NaN equal nothing, not even
            // themselves).
            let (mut group, rest): (Vec<Request>, Vec<Request>) = requests
                .into_iter()
                .partition(|r| r.categories == categories && r.options == options);
            group.insert(0, first);
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

    /// Points the scene's bind group at `categories`, when they changed.
    fn use_categories(&self, state: &mut State, categories: &[u16]) {
        if state.categories != categories {
            let words: Vec<u32> = categories.iter().map(|&c| u32::from(c)).collect();
            state.categories_buffer = init_buffer(&self.gpu, "categories", &words);
            state.scene_group = Self::scene_group(
                &self.gpu,
                &self.kernels,
                &self.scene,
                &state.categories_buffer,
            );
            state.categories = categories.to_vec();
        }
    }

    /// What a batch of `cameras` needs the work space to hold: its cameras, tiles, blending
    /// state and images of `channels` exactly; the counts found on the GPU as the work space
    /// holds them now, or a first guess, and at least what a camera needed before (grown after
    /// the batch when short).
    fn need(&self, state: &State, cameras: &[Camera], channels: &Channels) -> Caps {
        let c = cameras.len() as u32;
        let camera_chunks = c.saturating_mul(self.chunks);
        let out_words = out_planes(channels).1;
        let (tiles, image_words) = cameras.iter().fold((0u32, 0u64), |(t, w), cam| {
            let grid = TileGrid::new(cam);
            (
                t.saturating_add(grid.tiles() as u32),
                w + (PLANES + out_words) * (grid.width * grid.height) as u64,
            )
        });
        let splats = c.saturating_mul(self.count.min(1 << 18) as u32);
        let (splats, tile_entries) = match &state.workspace {
            Some(w) => (w.caps.splats, w.caps.tile_entries),
            None => (splats, splats.saturating_mul(2).saturating_add(65_536)),
        };
        let [per_splats, per_entries] = state.per_camera;
        Caps {
            cameras: c,
            camera_chunks,
            entries: camera_chunks,
            splats: splats.max(c.saturating_mul(per_splats)),
            tile_entries: tile_entries.max(c.saturating_mul(per_entries)),
            tiles,
            image_words,
        }
    }

    /// Renders `cameras` with the GPU held: in parts the adapter's buffers hold, each part's
    /// read-back overlapping the next part's rendering. A part that found more on the GPU than
    /// the work space held is rendered again after growing it, or in halves where the grown
    /// buffers would pass what one binding sees.
    fn render_held(
        &self,
        state: &mut State,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        self.use_categories(state, categories);
        let mut queue: VecDeque<Range<usize>> =
            self.parts(state, cameras, &options.channels)?.into();
        let mut out: Vec<Option<RenderOutput>> = cameras.iter().map(|_| None).collect();
        let mut total = GpuStats::default();
        let mut previous: Option<(InFlight, Range<usize>)> = None;
        loop {
            let next = match queue.pop_front() {
                Some(range) => {
                    let part = &cameras[range.clone()];
                    let need = self.need(state, part, &options.channels);
                    Some((self.launch(state, part, options, need)?, range))
                }
                None => None,
            };
            if let Some((flight, range)) = previous.take() {
                match self.finish(state, flight)? {
                    Finished::Images(images, stats) => {
                        for (slot, image) in out[range].iter_mut().zip(images) {
                            *slot = Some(image);
                        }
                        total.chunks += stats.chunks;
                        total.splats += stats.splats;
                        total.tile_entries += stats.tile_entries;
                        total.capacity = stats.capacity;
                        total.slabs = stats.slabs;
                        total.blend_passes = stats.blend_passes;
                        total.passes = match (total.passes, stats.passes) {
                            (Some(a), Some(b)) => Some(a.add(&b)),
                            (a, b) => a.or(b),
                        };
                        total.workspace_bytes = stats.workspace_bytes;
                    }
                    Finished::Grow(need) if need.fit(&self.gpu) => {
                        total.regrown += 1;
                        self.grow(state, need);
                        queue.push_front(range);
                    }
                    Finished::Grow(_) if range.len() > 1 => {
                        total.regrown += 1;
                        let mid = range.start + range.len() / 2;
                        queue.push_front(mid..range.end);
                        queue.push_front(range.start..mid);
                    }
                    Finished::Grow(need) => {
                        return Err(self.too_large(&cameras[range.start], &need));
                    }
                    Finished::MorePasses { passes, piece } => {
                        total.regrown += 1;
                        self.more_passes(state, passes, piece)?;
                        queue.push_front(range);
                    }
                }
            }
            previous = next;
            if previous.is_none() && queue.is_empty() {
                break;
            }
        }
        total.cameras = cameras.len();
        state.stats = total;
        Ok(out
            .into_iter()
            .map(|o| o.expect("every part was rendered"))
            .collect())
    }

    /// Grows the work space to hold `need` (what a batch in flight holds stays alive until it
    /// finished).
    fn grow(&self, state: &mut State, need: Caps) {
        let caps = state.workspace.as_ref().map_or(need, |w| w.caps.max(&need));
        state.workspace = None;
        state.workspace = Some(Workspace::new(&self.gpu, &self.kernels, caps));
    }

    /// The error of a single `camera` whose work space `need` passes what one binding of the
    /// adapter sees.
    fn too_large(&self, camera: &Camera, need: &Caps) -> Error {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let adapter = self.gpu.describe();
        let (largest, bound) = (need.largest_buffer(), self.gpu.largest_binding());
        Error::invalid(if largest > bound {
            format!(
                "GPU {adapter}: a {w}x{h} frame needs {} MB of work space in one buffer; the \
                 adapter binds at most {} MB (render smaller images)",
                largest >> 20,
                bound >> 20
            )
        } else {
            format!(
                "GPU {adapter}: a {w}x{h} frame projects {} splats into {} (tile, splat) \
                 entries, more than the adapter's largest textures hold (render smaller images)",
                need.splats, need.tile_entries
            )
        })
    }

    /// Splits `cameras` into batches the adapter's buffers hold (whole cameras each) with the
    /// images of `channels`.
    fn parts(
        &self,
        state: &State,
        cameras: &[Camera],
        channels: &Channels,
    ) -> Result<Vec<Range<usize>>> {
        let mut parts = Vec::new();
        let mut start = 0;
        while start < cameras.len() {
            let mut end = cameras
                .len()
                .min(start + self.kernels.camera_slots as usize);
            loop {
                let need = self.need(state, &cameras[start..end], channels);
                if need.fit(&self.gpu) {
                    break;
                }
                if end - start == 1 {
                    return Err(self.too_large(&cameras[start], &need));
                }
                end = start + (end - start).div_ceil(2);
            }
            parts.push(start..end);
            start = end;
        }
        Ok(parts)
    }

    /// Records and submits one batch of `cameras` into a work space of at least `need`.
    fn launch(
        &self,
        state: &mut State,
        cameras: &[Camera],
        options: &RenderOptions,
        need: Caps,
    ) -> Result<InFlight> {
        let gpu = &*self.gpu;
        if !state
            .workspace
            .as_ref()
            .is_some_and(|w| w.caps.holds(&need))
        {
            let caps = state.workspace.as_ref().map_or(need, |w| w.caps.max(&need));
            // Drop the old buffers before allocating the new ones.
            state.workspace = None;
            state.workspace = Some(Workspace::new(gpu, &self.kernels, caps));
        }
        let w = state.workspace.as_ref().expect("made above");
        let slabs = state
            .fixed_slabs
            .unwrap_or_else(|| slabs_for(&self.scene.index, cameras));
        let (out_bits, out_words) = out_planes(&options.channels);
        let grids: Vec<TileGrid> = cameras.iter().map(TileGrid::new).collect();
        // The images written out follow every camera's blending state.
        let state_words: u64 = grids
            .iter()
            .map(|g| PLANES * (g.width * g.height) as u64)
            .sum();
        let mut offset = 0;
        let mut out_offset = 0;
        let mut tile_base = 0u32;
        let mut table_base = 0u32;
        let mut blocks = Vec::with_capacity(cameras.len() * CAMERA_WORDS);
        let mut slots = Vec::with_capacity(cameras.len());
        let mut grid = (1, 1, cameras.len() as u32);
        let mut camera_tiles = 1;
        for (c, g) in cameras.iter().zip(grids) {
            let place = [
                tile_base,
                offset as u32,
                table_base,
                (state_words + out_offset) as u32,
            ];
            blocks.extend_from_slice(&camera_block(c, &g, place, options));
            grid.0 = grid.0.max(g.tiles_x as u32);
            grid.1 = grid.1.max(g.tiles_y as u32);
            slots.push(Slot {
                grid: g,
                offset: out_offset,
            });
            tile_base += g.tiles() as u32;
            camera_tiles = camera_tiles.max(g.tiles() as u32);
            table_base += ((g.tiles_x + 1) * (g.tiles_y + 1)) as u32;
            offset += PLANES * (g.width * g.height) as u64;
            out_offset += out_words * (g.width * g.height) as u64;
        }
        let tiles = tile_base;
        // The tile sort takes the tiles of the largest camera (the camera sits above them in
        // the key, and the entries arrive camera-major); the depth sort takes the camera's byte
        // only when the batch has more than one.
        let bits = u32::BITS - (camera_tiles - 1).leading_zeros();
        let tile_passes = bits.div_ceil(8).clamp(1, TILE_SORT_PASSES);
        let depth_passes = DEPTH_KEY_BITS / 8 + u32::from(cameras.len() > 1);
        gpu.queue
            .write_buffer(&w.cameras, 0, bytemuck::cast_slice(&blocks));
        // The fixed slots, and zero where the slabs' largest and summed counts gather.
        let mut fixed = vec![0u32; LIVE_WORDS as usize];
        fixed[LIVE_CAMERA_CHUNKS as usize] = cameras.len() as u32 * self.chunks;
        fixed[LIVE_TILES as usize] = tiles;
        fixed[LIVE_CAMERAS as usize] = cameras.len() as u32;
        fixed[LIVE_SLABS as usize] = slabs;
        fixed[LIVE_OUT_PLANES as usize] = out_bits;
        fixed[LIVE_FEW_CHUNKS as usize] = if state.fixed_slabs.is_some() {
            0
        } else {
            GPU_FEW_CHUNKS
        };
        fixed[LIVE_PIECE as usize] = state.piece;
        fixed[LIVE_PASSES as usize] = state.blend_passes;
        let [second_count, wanted_at] = list_words(tiles);
        fixed[LIVE_SECOND_COUNT as usize] = second_count;
        fixed[LIVE_WANTED_AT as usize] = wanted_at;
        gpu.queue
            .write_buffer(&self.kernels.live.buffer, 0, bytemuck::cast_slice(&fixed));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("render"),
                timestamp_writes: None,
            });
            w.encode(
                &self.kernels,
                &state.scene_group,
                &mut pass,
                &BatchPlan {
                    depth_passes,
                    tile_passes,
                    slabs,
                    blend_passes: state.blend_passes,
                    blending: state.blending,
                    grid,
                    stamps: state.timing.as_ref().map(|(q, _)| q),
                },
            );
        }
        let image_bytes = out_offset * 4;
        let live_bytes = self.kernels.live.buffer.size();
        // The stages' timestamps, and one after the read-back copy where the device writes
        // timestamps between passes.
        let copy_stamp = u32::from(gpu.has_encoder_timestamps());
        let stamps = state
            .timing
            .as_ref()
            .map_or(0, |_| PassTimes::stamps(slabs) + copy_stamp);
        let size = image_bytes + live_bytes + u64::from(stamps) * 8;
        let staging = match state.staging.iter().position(|b| b.size() >= size) {
            Some(i) => state.staging.swap_remove(i),
            None => gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("read-back"),
                size: size.next_power_of_two(),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        encoder.copy_buffer_to_buffer(&self.kernels.live.buffer, 0, &staging, 0, live_bytes);
        encoder.copy_buffer_to_buffer(
            &w.images,
            state_words * 4,
            &staging,
            live_bytes,
            image_bytes,
        );
        if let Some((queries, resolved)) = &state.timing {
            if copy_stamp == 1 {
                encoder.write_timestamp(queries, stamps - 1);
            }
            encoder.resolve_query_set(queries, 0..stamps, resolved, 0);
            let at = live_bytes + image_bytes;
            encoder.copy_buffer_to_buffer(resolved, 0, &staging, at, u64::from(stamps) * 8);
        }
        let submission = gpu.queue.submit([encoder.finish()]);
        let (tx, mapped) = mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        Ok(InFlight {
            staging,
            submission,
            mapped,
            slots,
            channels: options.channels,
            image_words: out_offset,
            stamps,
            slabs,
            blend_passes: state.blend_passes,
            piece: state.piece,
            passes_wanted: w.passes_wanted,
            caps: w.caps,
            peaks: w.peaks,
            totals: w.totals,
        })
    }

    /// Waits for `flight`'s read-back: its images, or the work space it needs when a count
    /// found on the GPU passed what the buffers held.
    fn finish(&self, state: &mut State, flight: InFlight) -> Result<Finished> {
        let gpu = &*self.gpu;
        let fault =
            |e: &dyn std::fmt::Display| Error::invalid(format!("GPU {}: {e}", gpu.describe()));
        gpu.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(flight.submission),
                timeout: None,
            })
            .map_err(|e| fault(&e))?;
        gpu.check()?;
        match flight.mapped.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(fault(&format!("read-back failed: {e}"))),
            Err(_) => return Err(fault(&"the device was lost during the read-back")),
        }
        let live_words = (self.kernels.live.buffer.size() / 4) as usize;
        let result = {
            let view = flight.staging.get_mapped_range(..).map_err(|e| fault(&e))?;
            let words: &[u32] = bytemuck::cast_slice(&view);
            let caps = flight.caps;
            let found = flight.peaks.map(|slot| words[slot as usize]);
            let totals = flight.totals.map(|slot| u64::from(words[slot as usize]));
            let passes_wanted = words[flight.passes_wanted as usize];
            if let Some([entries, splats, tile_entries]) = caps.wanted(found) {
                let cameras = flight.slots.len() as u32;
                let per_camera = [splats, tile_entries].map(|n| n.div_ceil(cameras));
                for (most, n) in state.per_camera.iter_mut().zip(per_camera) {
                    *most = (*most).max(n);
                }
                Finished::Grow(Caps {
                    entries: caps.entries.max(entries),
                    splats: caps.splats.max(splats),
                    tile_entries: caps.tile_entries.max(tile_entries),
                    ..caps
                })
            } else if passes_wanted > flight.blend_passes {
                Finished::MorePasses {
                    passes: passes_wanted,
                    piece: flight.piece,
                }
            } else {
                let end = live_words + flight.image_words as usize;
                let images = &words[live_words..end];
                let unpacking = std::time::Instant::now();
                let outputs = flight
                    .slots
                    .par_iter()
                    .map(|s| unpack(images, s, &flight.channels))
                    .collect();
                let unpack_ms = unpacking.elapsed().as_secs_f64() * 1e3;
                let passes = (flight.stamps > 0).then(|| {
                    let ticks: Vec<u64> = words[end..end + 2 * flight.stamps as usize]
                        .chunks_exact(2)
                        .map(|w| u64::from(w[0]) | u64::from(w[1]) << 32)
                        .collect();
                    PassTimes {
                        unpack_ms,
                        ..PassTimes::from_stamps(
                            &ticks,
                            flight.slabs,
                            gpu.queue.get_timestamp_period(),
                        )
                    }
                });
                Finished::Images(
                    outputs,
                    GpuStats {
                        cameras: flight.slots.len(),
                        slabs: flight.slabs,
                        blend_passes: flight.blend_passes,
                        chunks: totals[0],
                        splats: totals[1],
                        tile_entries: totals[2],
                        capacity: caps.tile_entries,
                        regrown: 0,
                        workspace_bytes: caps.bytes(self.kernels.shape)
                            + camera_block_bytes(self.kernels.camera_slots),
                        passes,
                    },
                )
            }
        };
        flight.staging.unmap();
        state.staging.push(flight.staging);
        Ok(result)
    }
}

/// The block of one camera (`Camera` in `splat.wgsl`): its pose, intrinsics, clipping,
/// background, culling planes, size and place in the batch (its first tile, state word,
/// finished-tile table word and written-out image word).
fn camera_block(
    c: &Camera,
    g: &TileGrid,
    place: [u32; 4],
    options: &RenderOptions,
) -> [u32; CAMERA_WORDS] {
    let k = c.intrinsics;
    let r = c.rotation;
    let [br, bg, bb] = options.background;
    let mut floats: Vec<[f32; 4]> = vec![
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
        [br, bg, bb, 0.0],
    ];
    floats.extend(frustum_planes(c).map(|(n, d)| [n.x, n.y, n.z, d]));
    let mut block = [0u32; CAMERA_WORDS];
    for (i, v) in floats.iter().flatten().enumerate() {
        block[i] = v.to_bits();
    }
    let words = [
        g.width as u32,
        g.height as u32,
        g.tiles_x as u32,
        g.tiles_y as u32,
        place[0],
        place[1],
        place[2],
        place[3],
    ];
    block[52..60].copy_from_slice(&words);
    block
}

/// One camera's images from the read-back words: the planes of `channels` in `compose`'s
/// order.
fn unpack(words: &[u32], s: &Slot, channels: &Channels) -> RenderOutput {
    let (width, height) = (s.grid.width, s.grid.height);
    let p = width * height;
    let mut next = s.offset as usize;
    let mut plane = || {
        next += p;
        &words[next - p..next]
    };
    let float = |v: &[u32]| v.iter().map(|&w| f32::from_bits(w)).collect::<Vec<f32>>();
    let mut out = RenderOutput::sized(width, height, &Channels::NONE);
    if channels.rgb_f32 {
        let (r, g, b) = (plane(), plane(), plane());
        out.rgb_f32 = (0..p)
            .flat_map(|i| [r[i], g[i], b[i]].map(f32::from_bits))
            .collect();
        if channels.rgb {
            out.rgb = out.rgb_f32.iter().copied().map(to_byte).collect();
        }
    } else if channels.rgb {
        out.rgb = plane()
            .iter()
            .flat_map(|w| {
                let [r, g, b, _] = w.to_le_bytes();
                [r, g, b]
            })
            .collect();
    }
    if channels.alpha {
        out.alpha = float(plane());
    }
    if channels.depth_expected {
        out.depth_expected = float(plane());
    }
    if channels.depth_median {
        out.depth_median = float(plane());
    }
    if channels.instance {
        out.instance = plane().to_vec();
    }
    if channels.semantic {
        out.semantic = plane().iter().map(|&c| c as u16).collect();
    }
    out
}
