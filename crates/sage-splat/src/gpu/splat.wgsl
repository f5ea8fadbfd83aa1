// The image formation of the CPU renderer (SPEC §3) as compute kernels over a batch of
// cameras; the constants come from the Rust crate in a generated prelude (`prelude` in
// renderer.rs: the image formation's constants, the storage steps, the sizes of the batch's
// arrays, the key and entry bit widths, the output planes and the fixed live slots).
//
// Every camera of the batch goes through the same dispatches, and every pass after the first runs
// over what the one before found (`live`, dispatched indirectly). Once per batch: `clear` →
// `start_pixels` → `cull` (a thread per camera × chunk of 256 Gaussians: against the camera's
// frustum, then the chunk's depth range and screen rectangle, and a histogram of the chunks' middle
// depths) → `cut_slabs` (per camera, the batch's live[LIVE_SLABS] depth slabs, at most SLABS, at quantiles of that histogram). Then per
// slab, front to back, as the CPU renderer does: `finished_table` (per camera, a summed-area table
// of the tiles whose every pixel is finished) → `select_chunks` (the chunks reaching the slab and
// some unfinished tile) → scan → `list_chunks` (the selected (camera, chunk) entries) → `mark` (a
// workgroup per entry: which of its Gaussians project into the image, with depth in the slab, over
// an unfinished tile) → scan of the per-entry counts → `index_entries` (the entry table) →
// `project` (a thread per splat: writes the splats, compacted, camera-major and in Gaussian order,
// each with the unfinished tiles it reaches) → radix sort by camera and depth → `count_tiles`
// (those counts in that order) → scan → `emit` ((unfinished tile, splat) entries in that order) →
// stable radix sort by the tile within its camera → `ranges` (each tile's entries, and the list of
// tiles with any) → `raster` (a workgroup per listed tile, blending into the per-pixel state the
// slab before left; on a CPU driver at most a piece of the tile's entries, the rest in the
// slab's later blending passes, see `hand_on`). Last, `compose` turns the state into the
// images. Slabs partition depth and each tile blends in depth order, so the images are those of
// blending everything at once; what the slabs save is the work behind finished tiles.

struct Camera {
    // Camera-to-world rotation columns (right, down, forward) and centre; w unused.
    right: vec4<f32>,
    down: vec4<f32>,
    forward: vec4<f32>,
    position: vec4<f32>,
    // fx, fy, cx, cy.
    focal: vec4<f32>,
    // near, far, and the x/z, y/z limits of the Jacobian clamp.
    clip: vec4<f32>,
    // Colour behind everything (rgb).
    background: vec4<f32>,
    // The frustum as inward planes (n, d): n·p ≥ d inside (the CPU renderer's culling planes).
    planes: array<vec4<f32>, 6>,
    // width, height, tiles across, tiles down.
    size: vec4<u32>,
    // Its first tile in the batch's numbering, the first word of its blending state, the first
    // word of its finished-tile table, the first word of its images written out.
    place: vec4<u32>,
}

// Live slots of this workspace's derived sizes: visible (camera, chunk) entries, visible
// splats, (tile, splat) entries, and the tiles in each blending list (`tile_list`), each
// clamped to what the buffers hold.
struct Slots {
    entries: u32,
    splats: u32,
    tile_entries: u32,
    listed_tiles: u32,
    handed_on: u32,
}

// The scene, resident. Positions (x, y, z and the opacity, as the CPU renderer's sigmoid
// forms it from the logit) and shapes, a texel per Gaussian (`texel`): a
// texel is one gather under lavapipe (see the splat textures), and `mark` reads a position per
// Gaussian of every visible chunk. Shapes: rotation (w, x | y, z as snorm16 pairs), log-scales
// x, y | z (i16 pairs, the last half zero: the opacity is in the position).
@group(0) @binding(0) var positions: texture_2d<f32>;
@group(0) @binding(1) var shapes: texture_2d<u32>;
// What a Gaussian looks like, APPEARANCE_TEXELS texels each (`appearance`): words 0–1 its SH
// degree 0 (r, g | b, step of the higher-order codes as f16 pairs), word 2 its instance, then
// its higher-order SH codes, i8, four to a word. Texels, as they are read where `project`
// forms each visible splat's colour: a gather each under lavapipe, where reading a word of a
// storage array is a load per lane.
@group(0) @binding(2) var appearance_texels: texture_2d<u32>;
@group(0) @binding(3) var<storage, read> categories: array<u32>;
// Per chunk: (min, 1 when it holds anything) and (max, 0): what its Gaussians can touch.
@group(0) @binding(4) var<storage, read> chunk_bounds: array<vec4<f32>>;

// A batch's work space.
// A uniform buffer, not storage: lavapipe (Mesa 22) reads a storage array at an index it cannot
// prove uniform lane by lane behind a branch each, a uniform array as one gather, which halves
// `mark`; a GPU's constant cache serves the camera a workgroup shares.
@group(1) @binding(0) var<uniform> cameras: array<Camera, CAMERA_SLOTS>;
@group(1) @binding(1) var<storage, read> live: array<u32>;
// Per camera × chunk (+1): selected for this slab (`select_chunks`), then its exclusive scan.
@group(1) @binding(2) var<storage, read_write> chunk_flags: array<u32>;
// The visible entries, camera × CHUNKS + chunk.
@group(1) @binding(3) var<storage, read_write> chunk_list: array<u32>;
// Per entry: 256 bits, the lanes whose Gaussian projects into the image.
@group(1) @binding(4) var<storage, read_write> entry_masks: array<atomic<u32>>;
// Per entry (+1): visible Gaussians, then their exclusive scan (each entry's first splat).
@group(1) @binding(5) var<storage, read_write> entry_counts: array<atomic<u32>>;
// Depth-sort pairs as `project` writes them: camera and depth key (`depth_key`) and splat; the
// sort ends in a texture (`depth_sorted`).
@group(1) @binding(6) var<storage, read_write> depth_keys: array<u32>;
@group(1) @binding(7) var<storage, read_write> depth_values: array<u32>;
// Tiles per depth-ordered splat (+1), then their exclusive scan.
@group(1) @binding(8) var<storage, read_write> tile_counts: array<u32>;
// Per tile of the batch: first and one-past-last entry of this slab (zero where none; each
// raster workgroup zeroes its own after reading it).
@group(1) @binding(9) var<storage, read_write> tile_ranges: array<vec2<u32>>;
// Per camera from its first word: 8 planes of width × height words, the per-pixel state
// while slabs blend: r, g, b (background not added), transmittance (negative once the pixel
// is finished), Σ weight × depth, median depth (f32 bits), instance, best weight (f32 bits).
// After every camera's state, the images `compose` writes out (the only words read back):
// per camera from its `place.w`, a plane of width × height words per image asked for
// (`live[LIVE_OUT_PLANES]`), in the order of the `OUT_*` bits.
@group(1) @binding(10) var<storage, read_write> images: array<u32>;
@group(1) @binding(11) var<uniform> slots: Slots;
// Per camera × chunk: nearest and farthest depth of its bounds (f32 bits; the nearest is
// F32_MAX when culled) and its screen rectangle in tiles, grown by one tile as the CPU grows it
// (x0 | y0 << 16, x1 | y1 << 16).
@group(1) @binding(12) var<storage, read_write> chunk_views: array<vec4<u32>>;
// Per camera: DEPTH_BINS counts of its visible chunks' middle depths (where their splats'
// depths centre), in bins of equal depth ratio from its near to its far plane.
@group(1) @binding(13) var<storage, read_write> depth_histogram: array<atomic<u32>>;
// Per camera, SLABS + 1 depths: slab k holds the splats of depth in [cut k, cut k + 1).
@group(1) @binding(14) var<storage, read_write> slab_cuts: array<f32>;
// Per tile of the batch: its columns of four pixels (half a raster thread's) that are finished
// or outside the image; 64 once the whole tile is finished.
@group(1) @binding(15) var<storage, read_write> tile_done: array<atomic<u32>>;
// Per camera from `place.z`: the summed-area table of `tile_done`, (tiles across + 1) ×
// (tiles down + 1) words, row 0 and column 0 zero.
@group(1) @binding(16) var<storage, read_write> finished_sum: array<u32>;
// The slab being rendered (x) and its blending pass (y).
@group(1) @binding(17) var<uniform> slab: vec4<u32>;
// Two lists of tiles to blend, in no particular order (each is blended on its own), each of
// the batch's tiles long and followed by its count (`list_start`): list 0 holds the tiles with
// entries in this slab, as `ranges` finds them; a blending pass reads the list of its parity
// and hands a tile whose piece ended with entries left on to the other. After both, the most
// blending passes a tile of the batch wanted (`hand_on`).
@group(1) @binding(18) var<storage, read_write> tile_list: array<atomic<u32>>;

// The visible splats, a texel each (`texel`) of four textures: shapes (x, y, conic a, conic b),
// weights (conic c, opacity, depth, cutoff), colours (r, g, b, instance bits), boxes (extent x,
// extent y as f32 bits, camera | tiles reached << 8, reached bits: where its tile box holds at
// most 32 tiles, a bit per tile of the box, row-major).
// Textures, not storage: lavapipe (Mesa 22) reads a storage array, and workgroup memory, at an
// index it cannot prove uniform lane by lane behind a branch each, component by component, a
// texel as one gather, and the blending kernels read a splat per pixel vector; it also stores a
// texel per lane where a storage vector takes a store per component. The blending kernels test
// a splat's reach with the first two and read the colour only where it reaches a pixel.
// `project` writes them (bindings 0–3, its own bind group); later kernels read them (4–7),
// with the sorts' results: (camera and depth key, splat) in depth order and (camera and tile,
// splat) in tile order, a texel each (8, 9; as the sorts leave them, `sort.wgsl`).
@group(2) @binding(0) var shapes_out: texture_storage_2d<rgba32float, write>;
@group(2) @binding(1) var weights_out: texture_storage_2d<rgba32float, write>;
@group(2) @binding(2) var colours_out: texture_storage_2d<rgba32float, write>;
@group(2) @binding(3) var boxes_out: texture_storage_2d<rgba32uint, write>;
@group(2) @binding(4) var splat_shapes: texture_2d<f32>;
@group(2) @binding(5) var splat_weights: texture_2d<f32>;
@group(2) @binding(6) var splat_colours: texture_2d<f32>;
@group(2) @binding(7) var splat_boxes: texture_2d<u32>;
@group(2) @binding(8) var depth_sorted: texture_2d<u32>;
@group(2) @binding(9) var tiles_sorted: texture_2d<u32>;
// Where `emit` writes the (camera and tile, splat) entries, a texel each: the texture the tile
// sort starts from (its own bind group, as the sort's second texture is also `tiles_sorted`).
@group(3) @binding(0) var tile_pairs_out: texture_storage_2d<rg32uint, write>;
// Per visible entry, three texels: its first splat (the scan of its count) and its camera ×
// CHUNKS + chunk; its mask words 0–3; words 4–7. `index_entries` writes them once the counts
// are scanned (binding 10 of its own group), so `project` finds its entry by a binary search
// of gathers (binding 1 of its own group) where lavapipe read the storage arrays lane by lane.
@group(2) @binding(10) var entry_table_out: texture_storage_2d<rgba32uint, write>;
@group(3) @binding(1) var entry_table: texture_2d<u32>;

fn splat_shape(s: u32) -> vec4<f32> {
    return textureLoad(splat_shapes, texel(s), 0);
}

fn splat_weight(s: u32) -> vec4<f32> {
    return textureLoad(splat_weights, texel(s), 0);
}

fn splat_colour(s: u32) -> vec4<f32> {
    return textureLoad(splat_colours, texel(s), 0);
}

fn splat_box(s: u32) -> vec4<u32> {
    return textureLoad(splat_boxes, texel(s), 0);
}

const F32_MAX: f32 = 3.4028235e38;

fn thread_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.x + wid.y * nwg.x) * 256u + lid;
}

// e^x as the CPU renderer computes it (`fastmath::exp4`), four lanes: 2^(x log₂e) split at
// the nearest integer, the fraction by the same polynomial, in the same order of operations.
fn exp_fast4(x: vec4<f32>) -> vec4<f32> {
    let y = clamp(x * LOG2_E, vec4<f32>(-126.0), vec4<f32>(126.0));
    let n = round(y);
    let f = y - n;
    let f2 = f * f;
    let low = 1.0 + f * EXP2_POLY_0;
    let mid = EXP2_POLY_1 + f * EXP2_POLY_2;
    let high = EXP2_POLY_3 + f * EXP2_POLY_4;
    let p = low + f2 * (mid + f2 * high);
    return bitcast<vec4<f32>>(vec4<u32>(vec4<i32>(n) + 127) << vec4<u32>(23u)) * p;
}

fn exp_fast(x: f32) -> f32 {
    return exp_fast4(vec4<f32>(x)).x;
}

// ln x for positive normal x as the CPU renderer computes it (`fastmath::ln4`).
fn ln_fast(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    var m = bitcast<f32>((bits & 0x007fffffu) | 0x3f800000u);
    var e = f32(i32((bits >> 23u) & 0xffu) - 127);
    if m > SQRT_2 {
        m = m * 0.5;
        e = e + 1.0;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 1.0 + s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0)));
    return e * LN_2 + 2.0 * s * series;
}

fn group_index(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.x + wid.y * nwg.x;
}

fn low_i16(w: u32) -> f32 {
    return f32(bitcast<i32>(w << 16u) >> 16u);
}

fn high_i16(w: u32) -> f32 {
    return f32(bitcast<i32>(w) >> 16u);
}

// Texel k of Gaussian g's appearance.
fn appearance(g: u32, k: u32) -> vec4<u32> {
    return textureLoad(appearance_texels, texel(APPEARANCE_TEXELS * g + k), 0);
}

// The four i8 codes of a word, in its byte order.
fn sh_bytes(w: u32) -> vec4<f32> {
    return vec4<f32>(vec4<i32>(vec4<u32>(w) << vec4<u32>(24u, 16u, 8u, 0u)) >> vec4<u32>(24u));
}

// Coefficient `code` (its three codes) of colour `c` times basis function `y`, steps of `step`:
// the CPU's order of operations.
fn sh_term(c: vec3<f32>, code: vec3<f32>, step: f32, y: f32) -> vec3<f32> {
    return c + code * step * y;
}

// The colour of Gaussian g, whose first appearance texel is `head`, seen along unit direction
// d: max(0, Σ c·Y + 0.5), the CPU's basis and order. Coefficient k's codes are bytes 3k…3k+2,
// so each three words hold four coefficients (written out: the texels it reads and the words it
// indexes are constants).
fn sh_color(g: u32, head: vec4<u32>, d: vec3<f32>) -> vec3<f32> {
    let rg = unpack2x16float(head.x);
    let b_step = unpack2x16float(head.y);
    var c = vec3<f32>(rg.x, rg.y, b_step.x) * SH_C0;
    let step = b_step.y;
    let x = d.x;
    let y = d.y;
    let z = d.z;
    if SH_REST >= 3u {
        let t1 = appearance(g, 1u);
        let w0 = sh_bytes(head.w);
        let w1 = sh_bytes(t1.x);
        let w2 = sh_bytes(t1.y);
        c = sh_term(c, w0.xyz, step, -SH_C1 * y);
        c = sh_term(c, vec3<f32>(w0.w, w1.xy), step, SH_C1 * z);
        c = sh_term(c, vec3<f32>(w1.zw, w2.x), step, -SH_C1 * x);
        if SH_REST >= 8u {
            let t2 = appearance(g, 2u);
            let w3 = sh_bytes(t1.z);
            let w4 = sh_bytes(t1.w);
            let w5 = sh_bytes(t2.x);
            let xx = x * x;
            let yy = y * y;
            let zz = z * z;
            c = sh_term(c, w2.yzw, step, SH_C2_0 * x * y);
            c = sh_term(c, w3.xyz, step, SH_C2_1 * y * z);
            c = sh_term(c, vec3<f32>(w3.w, w4.xy), step, SH_C2_2 * (2.0 * zz - xx - yy));
            c = sh_term(c, vec3<f32>(w4.zw, w5.x), step, SH_C2_3 * x * z);
            c = sh_term(c, w5.yzw, step, SH_C2_4 * (xx - yy));
            if SH_REST >= 15u {
                let t3 = appearance(g, 3u);
                let w6 = sh_bytes(t2.y);
                let w7 = sh_bytes(t2.z);
                let w8 = sh_bytes(t2.w);
                let w9 = sh_bytes(t3.x);
                let w10 = sh_bytes(t3.y);
                let w11 = sh_bytes(t3.z);
                c = sh_term(c, w6.xyz, step, SH_C3_0 * y * (3.0 * xx - yy));
                c = sh_term(c, vec3<f32>(w6.w, w7.xy), step, SH_C3_1 * x * y * z);
                c = sh_term(c, vec3<f32>(w7.zw, w8.x), step, SH_C3_2 * y * (4.0 * zz - xx - yy));
                c = sh_term(c, w8.yzw, step, SH_C3_3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy));
                c = sh_term(c, w9.xyz, step, SH_C3_4 * x * (4.0 * zz - xx - yy));
                c = sh_term(c, vec3<f32>(w9.w, w10.xy), step, SH_C3_5 * z * (xx - yy));
                c = sh_term(c, vec3<f32>(w10.zw, w11.x), step, SH_C3_6 * x * (xx - 3.0 * yy));
            }
        }
    }
    return max(c + vec3<f32>(0.5), vec3<f32>(0.0));
}

@compute @workgroup_size(256)
fn clear(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    if i < live[LIVE_CAMERAS] * DEPTH_BINS {
        atomicStore(&depth_histogram[i], 0u);
    }
}

// The histogram bin of depth z in camera c (depths before the near plane in the first).
fn depth_bin(c: u32, z: f32) -> u32 {
    let clip = cameras[c].clip;
    let b = log2(max(z, clip.x) / clip.x) / log2(clip.y / clip.x) * f32(DEPTH_BINS);
    return u32(clamp(b, 0.0, f32(DEPTH_BINS - 1u)));
}

// The depth where bin b of camera c starts.
fn bin_depth(c: u32, b: u32) -> f32 {
    let clip = cameras[c].clip;
    return clip.x * exp2(f32(b) / f32(DEPTH_BINS) * log2(clip.y / clip.x));
}

// Tile of pixel coordinate v, as the CPU renderer's chunk rectangle takes it: −1 before the
// image, n past it.
fn chunk_tile(v: f32, n: u32) -> i32 {
    return i32(clamp(floor(v / f32(TILE)), -1.0, f32(n)));
}

// The depth range of chunk k's bounds seen by camera c and its screen rectangle in tiles, grown
// by one tile (the CPU renderer's `chunk_view`): the whole image when a corner is near or
// behind the camera.
fn chunk_view(c: u32, lo: vec3<f32>, hi: vec3<f32>) -> vec4<u32> {
    let cam = cameras[c];
    var z_min = F32_MAX;
    var z_max = -F32_MAX;
    var u = vec2<f32>(F32_MAX);
    var v = vec2<f32>(-F32_MAX);
    var straddles = false;
    for (var k = 0u; k < 8u; k++) {
        let p = select(lo, hi, vec3<bool>((k & 1u) != 0u, (k & 2u) != 0u, (k & 4u) != 0u));
        let rel = p - cam.position.xyz;
        let t = vec3<f32>(dot(cam.right.xyz, rel), dot(cam.down.xyz, rel), dot(cam.forward.xyz, rel));
        z_min = min(z_min, t.z);
        z_max = max(z_max, t.z);
        if t.z < cam.clip.x * 0.5 {
            straddles = true;
            continue;
        }
        let screen = cam.focal.xy * t.xy / t.z + cam.focal.zw;
        u = min(u, screen);
        v = max(v, screen);
    }
    let last = vec2<i32>(cam.size.zw) - vec2<i32>(1);
    var r = vec4<i32>(0, 0, last.x, last.y);
    if !straddles {
        let x0 = chunk_tile(u.x, cam.size.z) - 1;
        let y0 = chunk_tile(u.y, cam.size.w) - 1;
        let x1 = chunk_tile(v.x, cam.size.z) + 1;
        let y1 = chunk_tile(v.y, cam.size.w) + 1;
        r = clamp(vec4<i32>(x0, y0, x1, y1), vec4<i32>(0), vec4<i32>(last, last));
    }
    let q = vec4<u32>(r);
    return vec4<u32>(bitcast<u32>(z_min), bitcast<u32>(z_max), q.x | (q.y << 16u), q.z | (q.w << 16u));
}

@compute @workgroup_size(256)
fn cull(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    if i >= live[LIVE_CAMERA_CHUNKS] {
        return;
    }
    let c = i / CHUNKS;
    let k = i % CHUNKS;
    let lo = chunk_bounds[2u * k];
    let hi = chunk_bounds[2u * k + 1u].xyz;
    var visible = lo.w > 0.0;
    for (var p = 0u; p < 6u; p++) {
        let plane = cameras[c].planes[p];
        let far_corner = select(lo.xyz, hi, plane.xyz >= vec3<f32>(0.0));
        if dot(plane.xyz, far_corner) < plane.w {
            visible = false;
        }
    }
    var view = vec4<u32>(bitcast<u32>(F32_MAX), 0u, 0u, 0u);
    if visible {
        view = chunk_view(c, lo.xyz, hi);
        let middle = 0.5 * (bitcast<f32>(view.x) + bitcast<f32>(view.y));
        atomicAdd(&depth_histogram[c * DEPTH_BINS + depth_bin(c, middle)], 1u);
    }
    chunk_views[i] = view;
}

// Per camera, the cuts of the batch's live[LIVE_SLABS] slabs at quantiles of its chunks'
// middle depths (rounded up to a bin's end, so a slab holds at least its share): −F32_MAX, the
// cuts, then F32_MAX up to SLABS. A camera that sees fewer than live[LIVE_FEW_CHUNKS] chunks
// (nothing, say) has everything in its first slab.
@compute @workgroup_size(256)
fn cut_slabs(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let c = thread_index(wid, nwg, lid);
    if c >= live[LIVE_CAMERAS] {
        return;
    }
    let bins = c * DEPTH_BINS;
    var total = 0u;
    for (var b = 0u; b < DEPTH_BINS; b++) {
        total += atomicLoad(&depth_histogram[bins + b]);
    }
    let base = c * (SLABS + 1u);
    slab_cuts[base] = -F32_MAX;
    slab_cuts[base + SLABS] = F32_MAX;
    // Bins before `b` hold `below` chunks.
    var b = 0u;
    var below = 0u;
    // In more slabs its chunks would each be marked in several (`GPU_FEW_CHUNKS` in `passes.rs`).
    var slabs = clamp(live[LIVE_SLABS], 1u, SLABS);
    if total < live[LIVE_FEW_CHUNKS] {
        slabs = 1u;
    }
    for (var k = 1u; k < SLABS; k++) {
        let rank = k * total / slabs;
        loop {
            if b >= DEPTH_BINS {
                break;
            }
            let n = atomicLoad(&depth_histogram[bins + b]);
            if below + n > rank {
                break;
            }
            below += n;
            b++;
        }
        var cut = F32_MAX;
        if k < slabs && b + 1u < DEPTH_BINS {
            cut = bin_depth(c, b + 1u);
        }
        slab_cuts[base + k] = cut;
    }
}

// A workgroup per camera: its summed-area table of finished tiles, so "is this rectangle all
// finished" costs four reads.
@compute @workgroup_size(256)
fn finished_table(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let c = group_index(wid, nwg);
    if c >= live[LIVE_CAMERAS] {
        return;
    }
    let size = cameras[c].size;
    let base = cameras[c].place.z;
    let tiles = cameras[c].place.x;
    let w = size.z + 1u;
    // Rows first (row y + 1 sums tile row y), then the columns of the rows' sums.
    for (var y = lid; y <= size.w; y += 256u) {
        var run = 0u;
        finished_sum[base + y * w] = 0u;
        for (var x = 0u; x < size.z; x++) {
            if y > 0u {
                run += select(0u, 1u, atomicLoad(&tile_done[tiles + (y - 1u) * size.z + x]) == 64u);
            }
            finished_sum[base + y * w + x + 1u] = run;
        }
    }
    storageBarrier();
    for (var x = lid; x < w; x += 256u) {
        var run = 0u;
        for (var y = 0u; y <= size.w; y++) {
            run += finished_sum[base + y * w + x];
            finished_sum[base + y * w + x] = run;
        }
    }
}

// True when every tile of camera c in r = [x0, y0, x1, y1] (inclusive) is finished.
fn rect_finished(c: u32, r: vec4<u32>) -> bool {
    let w = cameras[c].size.z + 1u;
    let base = cameras[c].place.z;
    let total = finished_sum[base + (r.w + 1u) * w + r.z + 1u] + finished_sum[base + r.y * w + r.x]
        - finished_sum[base + r.y * w + r.z + 1u] - finished_sum[base + (r.w + 1u) * w + r.x];
    return total == (r.z - r.x + 1u) * (r.w - r.y + 1u);
}

// Depths [lo, hi) of this slab in camera c.
fn slab_range(c: u32) -> vec2<f32> {
    let base = c * (SLABS + 1u) + slab.x;
    return vec2<f32>(slab_cuts[base], slab_cuts[base + 1u]);
}

@compute @workgroup_size(256)
fn select_chunks(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    let count = live[LIVE_CAMERA_CHUNKS];
    if i > count {
        return;
    }
    // Entry `count` is the scan's total: zero before the scan.
    var selected = 0u;
    if i < count {
        let c = i / CHUNKS;
        let v = chunk_views[i];
        let range = slab_range(c);
        let rect = vec4<u32>(v.z & 0xffffu, v.z >> 16u, v.w & 0xffffu, v.w >> 16u);
        if bitcast<f32>(v.x) < range.y && bitcast<f32>(v.y) >= range.x && !rect_finished(c, rect) {
            selected = 1u;
        }
    }
    chunk_flags[i] = selected;
}

@compute @workgroup_size(256)
fn list_chunks(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    if i >= live[LIVE_CAMERA_CHUNKS] {
        return;
    }
    let slot = chunk_flags[i];
    let entries = arrayLength(&chunk_list);
    if chunk_flags[i + 1u] != slot && slot < entries {
        chunk_list[slot] = i;
        // Empty for `mark`, which only sets bits and counts.
        for (var word = 0u; word < 8u; word++) {
            atomicStore(&entry_masks[8u * slot + word], 0u);
        }
        atomicStore(&entry_counts[slot], 0u);
    }
    if i + 1u == live[LIVE_CAMERA_CHUNKS] {
        // The scan's total: zero before the scan.
        atomicStore(&entry_counts[min(chunk_flags[i + 1u], entries)], 0u);
    }
}

// The screen footprint of Gaussian g seen by camera c (the CPU renderer's projection).
struct Footprint {
    visible: bool,
    // Pixel position of the mean.
    centre: vec2<f32>,
    // The 2-D covariance (a, b; b, c), low-pass included.
    cov: vec3<f32>,
    opacity: f32,
    depth: f32,
    cutoff: f32,
    extent: vec2<f32>,
    // From the camera to the mean, in W.
    ray: vec3<f32>,
}

// Only a mean at depth in `depths` = [near, far) is visible: the slab's, tested before the
// rest, so the Gaussians of a chunk outside the slab cost a dot product.
fn footprint(c: u32, g: u32, depths: vec2<f32>) -> Footprint {
    var f: Footprint;
    f.visible = false;
    let position = textureLoad(positions, texel(g), 0);
    let p = position.xyz;
    let rel = p - cameras[c].position.xyz;
    let right = cameras[c].right.xyz;
    let down = cameras[c].down.xyz;
    let forward = cameras[c].forward.xyz;
    let t = vec3<f32>(dot(right, rel), dot(down, rel), dot(forward, rel));
    let clip = cameras[c].clip;
    if !(t.z >= clip.x && t.z <= clip.y && t.z >= depths.x && t.z < depths.y) {
        return f;
    }
    let opacity = position.w;
    if !(opacity >= MIN_ALPHA) {
        return f;
    }
    let shape = textureLoad(shapes, texel(g), 0);
    let focal = cameras[c].focal;
    let fx = focal.x;
    let fy = focal.y;
    let inv_z = 1.0 / t.z;
    let sx = clamp(t.x * inv_z, -clip.z, clip.z);
    let sy = clamp(t.y * inv_z, -clip.w, clip.w);
    // Rows of J·W at the clamped mean.
    let r0 = (right - forward * sx) * (fx * inv_z);
    let r1 = (down - forward * sy) * (fy * inv_z);
    var q = vec4<f32>(low_i16(shape.x), high_i16(shape.x), low_i16(shape.y), high_i16(shape.y));
    q = q / sqrt(dot(q, q));
    let w = q.x;
    let x = q.y;
    let y = q.z;
    let z = q.w;
    let x2 = x + x;
    let y2 = y + y;
    let z2 = z + z;
    let xx = x * x2;
    let xy = x * y2;
    let xz = x * z2;
    let yy = y * y2;
    let yz = y * z2;
    let zz = z * z2;
    let wx = w * x2;
    let wy = w * y2;
    let wz = w * z2;
    var axes = array<vec3<f32>, 3>(
        vec3<f32>(1.0 - (yy + zz), xy + wz, xz - wy),
        vec3<f32>(xy - wz, 1.0 - (xx + zz), yz + wx),
        vec3<f32>(xz + wy, yz - wx, 1.0 - (xx + yy)),
    );
    let log_scale = vec3<f32>(low_i16(shape.z), high_i16(shape.z), low_i16(shape.w)) * LOG_SCALE_STEP;
    var a = LOW_PASS;
    var b = 0.0;
    var cc = LOW_PASS;
    for (var k = 0u; k < 3u; k++) {
        let variance = exp_fast(log_scale[k] + log_scale[k]);
        let d0 = dot(axes[k], r0);
        let d1 = dot(axes[k], r1);
        a += variance * d0 * d0;
        b += variance * d0 * d1;
        cc += variance * d1 * d1;
    }
    let det = a * cc - b * b;
    let cutoff = 2.0 * ln_fast(255.0 * max(opacity, MIN_ALPHA)) + 1e-3;
    let extent = vec2<f32>(sqrt(cutoff * a), sqrt(cutoff * cc));
    let px = fx * t.x * inv_z + focal.z;
    let py = fy * t.y * inv_z + focal.w;
    let width = f32(cameras[c].size.x);
    let height = f32(cameras[c].size.y);
    if !(det > 0.0 && det < 3.4e38 && px + extent.x >= 0.0 && px - extent.x <= width
        && py + extent.y >= 0.0 && py - extent.y <= height) {
        return f;
    }
    f.visible = true;
    f.centre = vec2<f32>(px, py);
    f.cov = vec3<f32>(a, b, cc);
    f.opacity = opacity;
    f.depth = t.z;
    f.cutoff = cutoff;
    f.extent = extent;
    f.ray = rel;
    return f;
}

// True when Gaussian g projects into camera c's image with its depth in this slab and its
// box over some unfinished tile.
fn in_slab(c: u32, g: u32) -> bool {
    let f = footprint(c, g, slab_range(c));
    return f.visible && !rect_finished(c, tile_box(f.centre, f.extent, c));
}

@compute @workgroup_size(256)
fn mark(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let entry = group_index(wid, nwg);
    if entry >= live[slots.entries] {
        return;
    }
    let flat = chunk_list[entry];
    let g = (flat % CHUNKS) * 256u + lid;
    if g < GAUSSIANS && in_slab(flat / CHUNKS, g) {
        atomicOr(&entry_masks[8u * entry + lid / 32u], 1u << (lid % 32u));
        atomicAdd(&entry_counts[entry], 1u);
    }
}

// `mark` shaped for CPU drivers (`KernelShape::Runs`): a thread per entry goes through its
// chunk's 256 Gaussians one at a time, building the mask words and the count in registers
// with no atomics (eight entries side by side in a vector's lanes, under lavapipe).
@compute @workgroup_size(RUN_GROUP)
fn mark_runs(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let entry = group_index(wid, nwg) * RUN_GROUP + lid;
    if entry >= live[slots.entries] {
        return;
    }
    let flat = chunk_list[entry];
    let c = flat / CHUNKS;
    let first = (flat % CHUNKS) * 256u;
    var count = 0u;
    for (var w = 0u; w < 8u; w++) {
        var word = 0u;
        for (var b = 0u; b < 32u; b++) {
            let g = first + 32u * w + b;
            if g < GAUSSIANS && in_slab(c, g) {
                word |= 1u << b;
            }
        }
        atomicStore(&entry_masks[8u * entry + w], word);
        count += countOneBits(word);
    }
    atomicStore(&entry_counts[entry], count);
}

// Bit `n` (from 0) among the set bits of `w` (which has more than n).
fn nth_set_bit(w: u32, n: u32) -> u32 {
    var bits = w;
    for (var k = 0u; k < n; k++) {
        bits &= bits - 1u;
    }
    return firstTrailingBit(bits);
}

// A thread per visible entry, once the counts are scanned: its texels of the entry table.
@compute @workgroup_size(256)
fn index_entries(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let e = thread_index(wid, nwg, lid);
    if e >= live[slots.entries] {
        return;
    }
    textureStore(entry_table_out, entry_place(e, 0u), vec4<u32>(atomicLoad(&entry_counts[e]), chunk_list[e], 0u, 0u));
    textureStore(entry_table_out, entry_place(e, 1u), mask_words(8u * e));
    textureStore(entry_table_out, entry_place(e, 2u), mask_words(8u * e + 4u));
}

// Words m to m + 3 of the entries' masks.
fn mask_words(m: u32) -> vec4<u32> {
    return vec4<u32>(
        atomicLoad(&entry_masks[m]),
        atomicLoad(&entry_masks[m + 1u]),
        atomicLoad(&entry_masks[m + 2u]),
        atomicLoad(&entry_masks[m + 3u]),
    );
}

// Where texel k of entry e's ENTRY_TEXELS lies in the entry table.
fn entry_place(e: u32, k: u32) -> vec2<u32> {
    return texel(ENTRY_TEXELS * e + k);
}

// Texel k of entry e's ENTRY_TEXELS in the entry table.
fn entry_texel(e: u32, k: u32) -> vec4<u32> {
    return textureLoad(entry_table, entry_place(e, k), 0);
}

// A thread per splat (so the work follows what is visible, not the lanes of the marked
// chunks): its entry is the last whose first slot is at or before it, its Gaussian the entry's
// lane of that rank among the marked ones.
@compute @workgroup_size(256)
fn project(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let slot = thread_index(wid, nwg, lid);
    if slot >= live[slots.splats] {
        return;
    }
    var lo = 0u;
    var hi = live[slots.entries];
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if entry_texel(mid, 0u).x <= slot {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let head = entry_texel(lo, 0u);
    let low = entry_texel(lo, 1u);
    let high = entry_texel(lo, 2u);
    let masks = array<u32, 8>(low.x, low.y, low.z, low.w, high.x, high.y, high.z, high.w);
    var rank = slot - head.x;
    var lane = 0u;
    for (var word = 0u; word < 8u; word++) {
        let mask = masks[word];
        let n = countOneBits(mask);
        if rank < n {
            lane = 32u * word + nth_set_bit(mask, rank);
            break;
        }
        rank -= n;
    }
    let flat = head.y;
    let c = flat / CHUNKS;
    let g = (flat % CHUNKS) * 256u + lane;
    let f = footprint(c, g, slab_range(c));
    let inv_det = 1.0 / (f.cov.x * f.cov.z - f.cov.y * f.cov.y);
    let conic = vec3<f32>(f.cov.z * inv_det, -f.cov.y * inv_det, f.cov.x * inv_det);
    // The unfinished tiles it reaches, counted and (for a small box) marked here, where the
    // splat is at hand, rather than found in `count_tiles` and again in `emit`.
    let tiles = walk_tiles(f.centre, conic, f.cutoff, c, tile_box(f.centre, f.extent, c));
    let at = texel(slot);
    textureStore(shapes_out, at, vec4<f32>(f.centre, conic.xy));
    textureStore(weights_out, at, vec4<f32>(conic.z, f.opacity, f.depth, f.cutoff));
    let looks = appearance(g, 0u);
    textureStore(colours_out, at, vec4<f32>(sh_color(g, looks, normalize(f.ray)), bitcast<f32>(looks.z)));
    textureStore(boxes_out, at, vec4<u32>(bitcast<vec2<u32>>(f.extent), c | (tiles.x << 8u), tiles.y));
    depth_keys[slot] = depth_key(c, f.depth);
    depth_values[slot] = slot;
}

// The depth-sort key of a splat at depth z in camera c: the camera in the top byte, so the
// batch sorts camera-major and its tile sort needs only the tiles of one camera; below, the
// CPU renderer's key (`Camera::depth_key`): z's place between the near and far planes in
// DEPTH_KEY_BITS (24) bits, z's bits less the near plane's shifted right just enough to fit.
// It depends on the camera alone, not on the slab or the batch.
fn depth_key(c: u32, z: f32) -> u32 {
    let clip = cameras[c].clip;
    let near = bitcast<u32>(clip.x);
    let span = bitcast<u32>(clip.y) - near;
    let shift = max(32u - countLeadingZeros(span), DEPTH_KEY_BITS) - DEPTH_KEY_BITS;
    return (c << DEPTH_KEY_BITS) | ((bitcast<u32>(z) - near) >> shift);
}

// The splat at place i of the depth order.
fn sorted_depth_value(i: u32) -> u32 {
    return textureLoad(depth_sorted, texel(i), 0).y;
}

// The unfinished tiles splat s reaches (found by `project`).
fn splat_tiles(s: u32) -> u32 {
    return splat_box(s).z >> 8u;
}

// The tiles of the box `m` ± `e` in camera c, as the CPU bins them: [x0, y0, x1, y1],
// inclusive.
fn tile_box(m: vec2<f32>, e: vec2<f32>, c: u32) -> vec4<u32> {
    let size = cameras[c].size;
    let w = f32(size.x);
    let h = f32(size.y);
    let last = size.zw - vec2<u32>(1u);
    let x0 = min(u32(max(m.x - e.x, 0.0) / f32(TILE)), last.x);
    let y0 = min(u32(max(m.y - e.y, 0.0) / f32(TILE)), last.y);
    let x1 = min(u32(max(min(m.x + e.x, w - 1.0), 0.0) / f32(TILE)), last.x);
    let y1 = min(u32(max(min(m.y + e.y, h - 1.0), 0.0) / f32(TILE)), last.y);
    return vec4<u32>(x0, y0, x1, y1);
}

// True when some pixel centre of tile (tx, ty) of camera c gets alpha ≥ 1/255 from a splat
// at `m` with `conic` (a, b, c) and `cutoff`: the minimum of the conic's quadratic form over the
// tile's pixel-centre rectangle against the cutoff.
fn reaches_tile(m: vec2<f32>, conic: vec3<f32>, cutoff: f32, c: u32, tx: u32, ty: u32) -> bool {
    let a = conic.x;
    let b = conic.y;
    let cc = conic.z;
    let size = cameras[c].size;
    let x0 = f32(tx * TILE) + 0.5;
    let y0 = f32(ty * TILE) + 0.5;
    let x1 = f32(min((tx + 1u) * TILE, size.x)) - 0.5;
    let y1 = f32(min((ty + 1u) * TILE, size.y)) - 0.5;
    if x0 <= m.x && m.x <= x1 && y0 <= m.y && m.y <= y1 {
        return true;
    }
    let dx0 = x0 - m.x;
    let dx1 = x1 - m.x;
    let dy0 = y0 - m.y;
    let dy1 = y1 - m.y;
    let ya = clamp(-b * dx0 / cc, dy0, dy1);
    let yb = clamp(-b * dx1 / cc, dy0, dy1);
    let xa = clamp(-b * dy0 / a, dx0, dx1);
    let xb = clamp(-b * dy1 / a, dx0, dx1);
    let q0 = a * dx0 * dx0 + 2.0 * b * dx0 * ya + cc * ya * ya;
    let q1 = a * dx1 * dx1 + 2.0 * b * dx1 * yb + cc * yb * yb;
    let q2 = a * xa * xa + 2.0 * b * xa * dy0 + cc * dy0 * dy0;
    let q3 = a * xb * xb + 2.0 * b * xb * dy1 + cc * dy1 * dy1;
    return min(min(q0, q1), min(q2, q3)) <= cutoff;
}

// Writes entry `slot`: tile (tx, ty) of camera c and splat s, whose box `lo`–`hi` reaches the
// tile's blocks `box_blocks` names (kept above the splat's index, so the blending kernels take
// a splat's blocks with its index); one past the texture is counted by the caller, not
// written (the host grows the work space).
fn write_entry(slot: u32, c: u32, tx: u32, ty: u32, s: u32, lo: vec2<f32>, hi: vec2<f32>) {
    if slot < live[slots.tile_entries] {
        let t = ty * cameras[c].size.z + tx;
        let value = (box_blocks(lo, hi, vec2<f32>(vec2<u32>(tx, ty) * TILE)) << SPLAT_INDEX_BITS) | s;
        textureStore(tile_pairs_out, texel(slot), vec4<u32>(tile_key(c, t), value, 0u, 0u));
    }
}

// True when tile box r is small enough for a bit per tile (32), which `project` keeps and
// `emit` walks.
fn box_has_bits(r: vec4<u32>) -> bool {
    return (r.z - r.x + 1u) * (r.w - r.y + 1u) <= 32u;
}

// True when tile (tx, ty) of box r in camera c is unfinished and a splat at `m` with `conic`
// and `cutoff` reaches it (a box of one tile is reached: the splat's box passed the culling).
fn tile_reached(m: vec2<f32>, conic: vec3<f32>, cutoff: f32, c: u32, r: vec4<u32>, tx: u32, ty: u32) -> bool {
    let single = r.x == r.z && r.y == r.w;
    let t = cameras[c].place.x + ty * cameras[c].size.z + tx;
    return atomicLoad(&tile_done[t]) < 64u && (single || reaches_tile(m, conic, cutoff, c, tx, ty));
}

// Walks the tiles of box r in camera c, row-major, that a splat at `m` with `conic` and `cutoff`
// reaches (`tile_reached`): their count and, where the box holds at most 32 tiles, a bit per
// tile of the box.
fn walk_tiles(m: vec2<f32>, conic: vec3<f32>, cutoff: f32, c: u32, r: vec4<u32>) -> vec2<u32> {
    let box_width = r.z - r.x + 1u;
    let small = box_has_bits(r);
    var count = 0u;
    var bits = 0u;
    for (var ty = r.y; ty <= r.w; ty++) {
        for (var tx = r.x; tx <= r.z; tx++) {
            if tile_reached(m, conic, cutoff, c, r, tx, ty) {
                if small {
                    bits |= 1u << ((ty - r.y) * box_width + tx - r.x);
                }
                count += 1u;
            }
        }
    }
    return vec2<u32>(count, bits);
}

@compute @workgroup_size(256)
fn count_tiles(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    let n = live[slots.splats];
    if i > n {
        return;
    }
    var count = 0u;
    if i < n {
        count = splat_tiles(sorted_depth_value(i));
    }
    tile_counts[i] = count;
}

// The entries of each splat in depth order, from its first slot: from the bits `project` left
// where its box is small, else by walking the box again. They go to the texture the tile
// sort starts from (`tile_pairs_out`, a texel each as the sort's passes read them).
@compute @workgroup_size(256)
fn emit(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    if i >= live[slots.splats] {
        return;
    }
    let s = sorted_depth_value(i);
    let first = tile_counts[i];
    let m = splat_shape(s);
    let e = splat_box(s);
    let c = e.z & 255u;
    let extent = bitcast<vec2<f32>>(e.xy);
    let r = tile_box(m.xy, extent, c);
    let lo = m.xy - extent;
    let hi = m.xy + extent;
    var slot = first;
    if !box_has_bits(r) {
        let sb = splat_weight(s);
        for (var ty = r.y; ty <= r.w; ty++) {
            for (var tx = r.x; tx <= r.z; tx++) {
                if tile_reached(m.xy, vec3<f32>(m.zw, sb.x), sb.w, c, r, tx, ty) {
                    write_entry(slot, c, tx, ty, s, lo, hi);
                    slot += 1u;
                }
            }
        }
        return;
    }
    var bits = e.w;
    let box_width = r.z - r.x + 1u;
    while bits != 0u {
        let k = firstTrailingBit(bits);
        bits &= bits - 1u;
        write_entry(slot, c, r.x + k % box_width, r.y + k / box_width, s, lo, hi);
        slot += 1u;
    }
}

// The tile-sort key of tile t of camera c: the camera in the top byte, above the tile bits
// the sort takes. The entries come camera-major out of the depth order, so the stable sort by
// tile keeps each camera's entries of a tile together, in depth order.
fn tile_key(c: u32, t: u32) -> u32 {
    return (c << DEPTH_KEY_BITS) | t;
}

// The key (camera and tile) at place i of the tile order.
fn sorted_tile(i: u32) -> u32 {
    return textureLoad(tiles_sorted, texel(i), 0).x;
}

// The splat at place i of the tile order.
fn sorted_splat(i: u32) -> u32 {
    return textureLoad(tiles_sorted, texel(i), 0).y & ((1u << SPLAT_INDEX_BITS) - 1u);
}

// The blocks of its tile (`box_blocks`) that the splat at place i of the tile order reaches.
fn sorted_blocks(i: u32) -> u32 {
    return textureLoad(tiles_sorted, texel(i), 0).y >> SPLAT_INDEX_BITS;
}

// The first word of blending list q (0 or 1; 2: the passes wanted), and where its count is
// (the host's `list_words` has the same places).
fn list_start(q: u32) -> u32 {
    return q * (live[LIVE_TILES] + 1u);
}

fn list_count(q: u32) -> u32 {
    return list_start(q) + live[LIVE_TILES];
}

@compute @workgroup_size(256)
fn ranges(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    let m = live[slots.tile_entries];
    if i >= m {
        return;
    }
    let key = sorted_tile(i);
    // The tile numbered over the batch.
    let t = cameras[key >> DEPTH_KEY_BITS].place.x + (key & ((1u << DEPTH_KEY_BITS) - 1u));
    if i == 0u || sorted_tile(i - 1u) != key {
        tile_ranges[t].x = i;
        atomicStore(&tile_list[atomicAdd(&tile_list[list_count(0u)], 1u)], t);
    }
    if i + 1u == m || sorted_tile(i + 1u) != key {
        tile_ranges[t].y = i + 1u;
    }
}

// The camera whose tiles hold batch tile t: the last whose first tile is at or before it.
fn tile_camera(t: u32) -> u32 {
    var lo = 0u;
    var hi = live[LIVE_CAMERAS];
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if cameras[mid].place.x <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// The columns of four pixels (half a raster thread's) of tile (tx, ty) of a camera of `size` that
// hold no pixel of the image.
fn outside_columns(size: vec4<u32>, tx: u32, ty: u32) -> u32 {
    let columns = min(TILE, size.x - tx * TILE);
    let rows = (min(TILE, size.y - ty * TILE) + 3u) / 4u;
    return 64u - columns * rows;
}

// A thread per pixel of every camera's tiles: nothing blended yet (and per tile, its columns
// outside the image counted as finished, no entries, and the list of tiles to blend empty).
@compute @workgroup_size(256)
fn start_pixels(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let c = wid.z;
    let size = cameras[c].size;
    if wid.x >= size.z || wid.y >= size.w {
        return;
    }
    if lid == 0u {
        let t = cameras[c].place.x + wid.y * size.z + wid.x;
        atomicStore(&tile_done[t], outside_columns(size, wid.x, wid.y));
        tile_ranges[t] = vec2<u32>(0u);
        if t == 0u {
            atomicStore(&tile_list[list_count(0u)], 0u);
            atomicStore(&tile_list[list_count(1u)], 0u);
            atomicStore(&tile_list[list_start(2u)], 0u);
        }
    }
    let px = wid.x * TILE + lid % TILE;
    let py = wid.y * TILE + lid / TILE;
    if px >= size.x || py >= size.y {
        return;
    }
    let pixels = size.x * size.y;
    let p = cameras[c].place.y + py * size.x + px;
    for (var k = 0u; k < PLANES; k++) {
        images[k * pixels + p] = 0u;
    }
    images[3u * pixels + p] = bitcast<u32>(1.0);
}

// Per block of 8×8 pixels, a bit per splat of the batch of 256 being blended whose box reaches
// it (8 words of 32).
var<workgroup> block_bits: array<u32, 32>;
var<workgroup> threads_done: atomic<u32>;
var<workgroup> all_done: u32;
// The tile a raster workgroup blends and its range of entries.
var<workgroup> raster_tile: vec3<u32>;

// The blocks of 8 columns × 8 rows of a tile (bit 2·row half + column half) that the box
// `lo`…`hi` reaches at some pixel centre.
fn box_blocks(lo: vec2<f32>, hi: vec2<f32>, tile: vec2<f32>) -> u32 {
    var columns = 0u;
    for (var h = 0u; h < 2u; h++) {
        let x0 = tile.x + f32(8u * h) + 0.5;
        if hi.x >= x0 && lo.x <= x0 + 7.0 {
            columns |= 1u << h;
        }
    }
    var blocks = 0u;
    for (var r = 0u; r < 2u; r++) {
        let y0 = tile.y + f32(8u * r) + 0.5;
        if hi.y >= y0 && lo.y <= y0 + 7.0 {
            blocks |= columns << (2u * r);
        }
    }
    return blocks;
}

// The blending state of four pixels of a column (the lanes of each vector).
struct Pixels {
    red: vec4<f32>,
    green: vec4<f32>,
    blue: vec4<f32>,
    transmittance: vec4<f32>,
    weighted_depth: vec4<f32>,
    median: vec4<f32>,
    best_weight: vec4<f32>,
    instance: vec4<u32>,
    // Inside the image and not finished.
    live: vec4<bool>,
}

// The state the slab before left at pixels `p` (those `inside` the image of `pixels` pixels);
// a finished pixel keeps its transmittance negated.
fn load_pixels(p: vec4<u32>, inside: vec4<bool>, pixels: u32) -> Pixels {
    var q: Pixels;
    q.transmittance = vec4<f32>(1.0);
    for (var j = 0u; j < 4u; j++) {
        if inside[j] {
            q.red[j] = bitcast<f32>(images[p[j]]);
            q.green[j] = bitcast<f32>(images[pixels + p[j]]);
            q.blue[j] = bitcast<f32>(images[2u * pixels + p[j]]);
            q.transmittance[j] = bitcast<f32>(images[3u * pixels + p[j]]);
            q.weighted_depth[j] = bitcast<f32>(images[4u * pixels + p[j]]);
            q.median[j] = bitcast<f32>(images[5u * pixels + p[j]]);
            q.instance[j] = images[6u * pixels + p[j]];
            q.best_weight[j] = bitcast<f32>(images[7u * pixels + p[j]]);
        }
    }
    q.live = inside & (q.transmittance > vec4<f32>(0.0));
    q.transmittance = abs(q.transmittance);
    return q;
}

// Gives the pixels' state back for the next slab (a finished pixel's transmittance negated).
fn store_pixels(q: ptr<function, Pixels>, p: vec4<u32>, inside: vec4<bool>, pixels: u32) {
    let kept = select((*q).transmittance, -(*q).transmittance, !(*q).live);
    for (var j = 0u; j < 4u; j++) {
        if inside[j] {
            images[p[j]] = bitcast<u32>((*q).red[j]);
            images[pixels + p[j]] = bitcast<u32>((*q).green[j]);
            images[2u * pixels + p[j]] = bitcast<u32>((*q).blue[j]);
            images[3u * pixels + p[j]] = bitcast<u32>(kept[j]);
            images[4u * pixels + p[j]] = bitcast<u32>((*q).weighted_depth[j]);
            images[5u * pixels + p[j]] = bitcast<u32>((*q).median[j]);
            images[6u * pixels + p[j]] = (*q).instance[j];
            images[7u * pixels + p[j]] = bitcast<u32>((*q).best_weight[j]);
        }
    }
}

// Blends splat (sb: conic c, opacity, depth, cutoff; c: r, g, b, instance) at `power` into the
// pixels, with the CPU renderer's rules.
fn blend(q: ptr<function, Pixels>, power: vec4<f32>, sb: vec4<f32>, c: vec4<f32>) {
    // Below e^-40 alpha is far under 1/255 whatever it is: the clamp keeps the exponential out
    // of subnormal numbers, which CPUs (lavapipe) compute slowly.
    let alpha = min(sb.y * exp_fast4(max(power, vec4<f32>(-40.0))), vec4<f32>(MAX_ALPHA));
    let transmittance = (*q).transmittance;
    let next = transmittance * (1.0 - alpha);
    let counts = (*q).live & (power <= vec4<f32>(0.0)) & (alpha >= vec4<f32>(MIN_ALPHA));
    // A pixel whose transmittance would fall below the floor is finished without it.
    let ends = counts & (next < vec4<f32>(MIN_TRANSMITTANCE));
    let blend = counts & !ends;
    let weight = alpha * transmittance;
    let w = select(vec4<f32>(0.0), weight, blend);
    (*q).red += w * c.x;
    (*q).green += w * c.y;
    (*q).blue += w * c.z;
    (*q).weighted_depth += w * sb.z;
    // Transmittance only falls: the last splat blended while it was above 0.5 is the one that
    // crossed it (kept only if it ends at or below 0.5).
    (*q).median = select((*q).median, vec4<f32>(sb.z), blend & (transmittance > vec4<f32>(0.5)));
    let better = blend & (weight > (*q).best_weight);
    (*q).best_weight = select((*q).best_weight, weight, better);
    (*q).instance = select((*q).instance, vec4<u32>(bitcast<u32>(c.w)), better);
    (*q).transmittance = select(transmittance, next, blend);
    (*q).live = (*q).live & !ends;
}

// What a raster workgroup blends: a tile of the batch, its entries of this slab left to blend
// (first, one past the last), the end of the piece it blends now (at most `LIVE_PIECE`
// entries), its camera and the camera's size, and the tile's first pixel.
struct RasterJob {
    tile: u32,
    range: vec2<u32>,
    end: u32,
    camera: u32,
    size: vec4<u32>,
    origin: vec2<u32>,
}

// The tiles in this pass's list (the workgroups dispatched may be more).
fn listed_tiles() -> u32 {
    return live[select(slots.listed_tiles, slots.handed_on, (slab.y & 1u) == 1u)];
}

// The job of the workgroup of listed tile `listed`: thread 0 takes the tile from the pass's
// list and every thread reads it through the workgroup, so the tile and the loop bounds are
// uniform; the tile's range is emptied for the next slab (the list's count was read before
// this dispatch, and emptied here for the pass after next).
fn raster_job(lid: u32, listed: u32) -> RasterJob {
    let list = slab.y & 1u;
    if lid == 0u {
        atomicStore(&threads_done, 0u);
        let t = atomicLoad(&tile_list[list_start(list) + listed]);
        raster_tile = vec3<u32>(t, tile_ranges[t]);
        tile_ranges[t] = vec2<u32>(0u);
        if listed == 0u {
            atomicStore(&tile_list[list_count(list)], 0u);
        }
    }
    let job = workgroupUniformLoad(&raster_tile);
    let c = tile_camera(job.x);
    let size = cameras[c].size;
    let local = job.x - cameras[c].place.x;
    let end = job.y + min(live[LIVE_PIECE], job.z - job.y);
    let origin = vec2<u32>(local % size.z, local / size.z) * TILE;
    return RasterJob(job.x, job.yz, end, c, size, origin);
}

// After a piece of a workgroup of `threads` threads (each counted in `threads_done` once its
// pixels are all finished; `finished_now` when this thread's finished but is not counted yet):
// when the piece ended with entries of its tile left and some pixel is unfinished, the rest
// goes to the next pass's list, or, in the slab's last pass, the passes the tile wanted are
// noted for the host, which renders the batch again with as many. Pieces bound the loop
// iterations of one invocation, which a CPU driver caps (lavapipe's shared budget of 65,535
// ends every loop early once spent, silently).
fn hand_on(lid: u32, job: RasterJob, threads: u32, finished_now: bool) {
    if job.end == job.range.y {
        return;
    }
    if finished_now {
        atomicAdd(&threads_done, 1u);
    }
    workgroupBarrier();
    if lid != 0u || atomicLoad(&threads_done) == threads {
        return;
    }
    if slab.y + 1u < live[LIVE_PASSES] {
        tile_ranges[job.tile] = vec2<u32>(job.end, job.range.y);
        let next = (slab.y + 1u) & 1u;
        let at = atomicAdd(&tile_list[list_count(next)], 1u);
        atomicStore(&tile_list[list_start(next) + at], job.tile);
    } else {
        let pieces = (job.range.y - job.end - 1u) / live[LIVE_PIECE] + 1u;
        atomicMax(&tile_list[list_start(2u)], slab.y + 1u + pieces);
    }
}

// The Gaussian's exponent at a column of four pixel centres `dx` across and `dy` down from
// splat (s: x, y, conic a, conic b; sb: conic c, …), `across` = a·dx² shared by the column's
// vectors: one formula, so both blending kernels form the same bytes.
fn splat_power(s: vec4<f32>, sb: vec4<f32>, dx: f32, across: f32, dy: vec4<f32>) -> vec4<f32> {
    return -0.5 * (across + sb.x * dy * dy) - s.w * dx * dy;
}

// True when splat (sb: conic c, opacity, depth, cutoff) at `power` may blend into some `live`
// pixel: past half the cutoff alpha is below 1/255 (the cutoff errs outwards).
fn reaches(live: vec4<bool>, power: vec4<f32>, sb: vec4<f32>) -> bool {
    return any(live & (power >= vec4<f32>(-0.5 * sb.w)));
}

// Each of a workgroup's 32 threads blends a column of eight pixels
// (as two vectors of four lanes), so a splat read (its index and the splat, from the textures)
// serves eight pixels.
// Eight neighbouring threads cover a block of 8×8 pixels and go through only the splats whose
// box reaches their block, stopping once their pixels are finished: a vector unit of a CPU
// (lavapipe) runs such eight together and skips the rest; on a GPU each thread steps through
// its own block's list, so a warp takes as many steps as the longest list of its blocks.
// A workgroup per tile with entries in this slab (`tile_list`); the pixels' state comes from
// the slab before and goes back to `images`, and a column of four that finishes here is
// counted in `tile_done`.
@compute @workgroup_size(32)
fn raster(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let listed = group_index(wid, nwg);
    if listed >= listed_tiles() {
        return;
    }
    let job = raster_job(lid, listed);
    let range = vec2<u32>(job.range.x, job.end);
    let c = job.camera;
    let size = job.size;
    let px = job.origin.x + lid % TILE;
    let py_upper = job.origin.y + (lid / TILE) * 8u + vec4<u32>(0u, 1u, 2u, 3u);
    let py_lower = py_upper + 4u;
    // Threads 8b…8b+7 are block b: row half b / 2, column half b % 2 (as in `box_blocks`).
    let block = lid / 8u;
    let inside_upper = vec4<bool>(px < size.x) & (py_upper < vec4<u32>(size.y));
    let inside_lower = vec4<bool>(px < size.x) & (py_lower < vec4<u32>(size.y));
    let cx = f32(px) + 0.5;
    let cy_upper = vec4<f32>(py_upper) + 0.5;
    let cy_lower = vec4<f32>(py_lower) + 0.5;
    let pixels = size.x * size.y;
    let p_upper = cameras[c].place.y + py_upper * size.x + px;
    let p_lower = cameras[c].place.y + py_lower * size.x + px;
    var upper = load_pixels(p_upper, inside_upper, pixels);
    var lower = load_pixels(p_lower, inside_lower, pixels);
    let was_live = vec2<bool>(any(upper.live), any(lower.live));
    var counted = false;
    for (var start = range.x; start < range.y; start += 256u) {
        if !any(upper.live) && !any(lower.live) && !counted {
            counted = true;
            atomicAdd(&threads_done, 1u);
        }
        workgroupBarrier();
        if lid == 0u {
            all_done = atomicLoad(&threads_done);
        }
        if workgroupUniformLoad(&all_done) == 32u {
            break;
        }
        // Thread b·8 + w finds word w of block b's bits: which of the batch's splats 32w to
        // 32w + 31 reach its block, from the blocks `emit` kept with each entry. Each thread
        // reads its own run of entries (texel gathers), and no thread reads what another wrote
        // but the words: under lavapipe a read of workgroup memory is a read per lane.
        var word = 0u;
        for (var i = 0u; i < 32u; i++) {
            let e = start + 32u * (lid % 8u) + i;
            if e < range.y {
                word |= ((sorted_blocks(e) >> block) & 1u) << i;
            }
        }
        block_bits[lid] = word;
        workgroupBarrier();
        for (var word_index = 0u; word_index < 8u; word_index++) {
            var bits = block_bits[8u * block + word_index];
            loop {
                if bits == 0u || !(any(upper.live) || any(lower.live)) {
                    break;
                }
                let k = 32u * word_index + firstTrailingBit(bits);
                bits &= bits - 1u;
                let g = sorted_splat(start + k);
                let s = splat_shape(g);
                let sb = splat_weight(g);
                let dx = s.x - cx;
                let across = s.z * dx * dx;
                let power_upper = splat_power(s, sb, dx, across, s.y - cy_upper);
                let power_lower = splat_power(s, sb, dx, across, s.y - cy_lower);
                let reaches_upper = reaches(upper.live, power_upper, sb);
                let reaches_lower = reaches(lower.live, power_lower, sb);
                // The colour is read only where the splat reaches a pixel: under lavapipe each
                // read is a gather of a texel per lane.
                if reaches_upper || reaches_lower {
                    let c = splat_colour(g);
                    if reaches_upper {
                        blend(&upper, power_upper, sb, c);
                    }
                    if reaches_lower {
                        blend(&lower, power_lower, sb, c);
                    }
                }
            }
        }
    }
    hand_on(lid, job, 32u, !counted && !any(upper.live) && !any(lower.live));
    let finished = select(0u, 1u, was_live.x && !any(upper.live))
        + select(0u, 1u, was_live.y && !any(lower.live));
    if finished > 0u {
        atomicAdd(&tile_done[job.tile], finished);
    }
    store_pixels(&upper, p_upper, inside_upper, pixels);
    store_pixels(&lower, p_lower, inside_lower, pixels);
}

var<workgroup> column_a: array<vec4<f32>, 64>;
var<workgroup> column_b: array<vec4<f32>, 64>;
var<workgroup> column_c: array<vec4<f32>, 64>;

// The blending kernel for hardware GPUs (`Blending::Columns`): a workgroup of 64 threads per
// listed tile, each blending a column of four pixels (one vector), all stepping through the
// tile's whole list together in batches of 64 splats read into workgroup memory at once. A warp
// runs in step over the same splat (no per-block lists to diverge on), with 3 KB of workgroup
// memory for two warps where `raster` holds about 150 bytes for one. The same rules and the
// same bytes as `raster`; a column of four that finishes here counts in `tile_done`.
@compute @workgroup_size(64)
fn raster_columns(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let listed = group_index(wid, nwg);
    if listed >= listed_tiles() {
        return;
    }
    let job = raster_job(lid, listed);
    let range = vec2<u32>(job.range.x, job.end);
    let c = job.camera;
    let size = job.size;
    let px = job.origin.x + lid % TILE;
    let py = job.origin.y + (lid / TILE) * 4u + vec4<u32>(0u, 1u, 2u, 3u);
    let inside = vec4<bool>(px < size.x) & (py < vec4<u32>(size.y));
    let cx = f32(px) + 0.5;
    let cy = vec4<f32>(py) + 0.5;
    let pixels = size.x * size.y;
    let p = cameras[c].place.y + py * size.x + px;
    var q = load_pixels(p, inside, pixels);
    let was_live = any(q.live);
    var counted = false;
    for (var start = range.x; start < range.y; start += 64u) {
        if !any(q.live) && !counted {
            counted = true;
            atomicAdd(&threads_done, 1u);
        }
        workgroupBarrier();
        let e = start + lid;
        if e < range.y {
            let g = sorted_splat(e);
            column_a[lid] = splat_shape(g);
            column_b[lid] = splat_weight(g);
            column_c[lid] = splat_colour(g);
        }
        if lid == 0u {
            all_done = atomicLoad(&threads_done);
        }
        if workgroupUniformLoad(&all_done) == 64u {
            break;
        }
        let n = min(64u, range.y - start);
        for (var k = 0u; k < n; k++) {
            if !any(q.live) {
                break;
            }
            let s = column_a[k];
            let sb = column_b[k];
            let dx = s.x - cx;
            let power = splat_power(s, sb, dx, s.z * dx * dx, s.y - cy);
            if reaches(q.live, power, sb) {
                blend(&q, power, sb, column_c[k]);
            }
        }
    }
    hand_on(lid, job, 64u, !counted && !any(q.live));
    if was_live && !any(q.live) {
        atomicAdd(&tile_done[job.tile], 1u);
    }
    store_pixels(&q, p, inside, pixels);
}

// A colour channel as the CPU renderer's `to_byte` rounds it: clamped to 0–1 (NaN to 0),
// scaled to 255, rounded half up. The half is compared against rather than subtracted, so no
// compiler can fuse the scaling into the rounding: the same bytes as the host's.
fn to_byte(v: f32) -> u32 {
    let x = select(0.0, min(v, 1.0), v > 0.0) * 255.0;
    let f = floor(x);
    return u32(f) + select(0u, 1u, x >= f + 0.5);
}

// A thread per pixel of every camera's tiles: the images asked for from the blended state
// (the background behind what remains transparent, depths normalised, the category of the
// instance), written out after the state.
@compute @workgroup_size(256)
fn compose(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let c = wid.z;
    let size = cameras[c].size;
    let px = wid.x * TILE + lid % TILE;
    let py = wid.y * TILE + lid / TILE;
    if px >= size.x || py >= size.y {
        return;
    }
    let pixels = size.x * size.y;
    let p = cameras[c].place.y + py * size.x + px;
    let t = abs(bitcast<f32>(images[3u * pixels + p]));
    let hit = 1.0 - t;
    let instance = images[6u * pixels + p];
    var depth = 0.0;
    var category = 0u;
    if hit > 0.0 {
        depth = bitcast<f32>(images[4u * pixels + p]) / hit;
        if instance < arrayLength(&categories) {
            category = categories[instance];
        }
    }
    let median = select(images[5u * pixels + p], 0u, t > 0.5);
    let background = cameras[c].background.xyz;
    let red = bitcast<f32>(images[p]) + t * background.x;
    let green = bitcast<f32>(images[pixels + p]) + t * background.y;
    let blue = bitcast<f32>(images[2u * pixels + p]) + t * background.z;
    let planes = live[LIVE_OUT_PLANES];
    var o = cameras[c].place.w + py * size.x + px;
    if (planes & OUT_RGB8) != 0u {
        images[o] = to_byte(red) | to_byte(green) << 8u | to_byte(blue) << 16u;
        o += pixels;
    }
    if (planes & OUT_RGB_F32) != 0u {
        images[o] = bitcast<u32>(red);
        images[o + pixels] = bitcast<u32>(green);
        images[o + 2u * pixels] = bitcast<u32>(blue);
        o += 3u * pixels;
    }
    if (planes & OUT_ALPHA) != 0u {
        images[o] = bitcast<u32>(hit);
        o += pixels;
    }
    if (planes & OUT_DEPTH_EXPECTED) != 0u {
        images[o] = bitcast<u32>(depth);
        o += pixels;
    }
    if (planes & OUT_DEPTH_MEDIAN) != 0u {
        images[o] = median;
        o += pixels;
    }
    if (planes & OUT_INSTANCE) != 0u {
        images[o] = instance;
        o += pixels;
    }
    if (planes & OUT_SEMANTIC) != 0u {
        images[o] = category;
    }
}
