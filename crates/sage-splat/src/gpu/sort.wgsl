// One pass of a stable least-significant-digit radix sort of (key, value) pairs on the 8-bit
// digit at `shift`. The number of pairs is read on the GPU (`live[count_slot]`) and the
// workgroups dispatched indirectly from it, so a frame's passes are recorded without knowing
// it. Blocks of 256 pairs: `histogram` counts each block's digits into
// `block_digits[digit * blocks + block]`; after an exclusive scan of that array (digit-major,
// so it holds every pair's first slot; the scan leaves each word's prefix within its block of
// SCAN_BLOCK words and the blocks' offsets in `block_offsets`), `scatter` writes each pair
// there plus its rank among the equal digits before it in its block, which keeps equal keys
// in their input order.
// A workgroup of `histogram` counts HISTOGRAM_BLOCKS blocks (the constant comes from the Rust
// side), a pair of each per thread, between the same two barriers.
// The pairs come in through `key_in` and `pair_in`, from one of two preludes: a pair of
// buffers (the first pass, over what a kernel wrote) or a texture (`pairs_in`, the passes
// after). They go out as a texel each of `pairs_out` (`texel`): under lavapipe (Mesa 22) a
// texel is one gather, where a storage array read at an index it cannot prove uniform is a
// read per lane behind a branch; and one store per lane for the pair, not one per word.

struct Params {
    shift: u32,
    count_slot: u32,
}

@group(0) @binding(2) var pairs_out: texture_storage_2d<rg32uint, write>;
@group(0) @binding(3) var<storage, read_write> block_digits: array<u32>;
@group(0) @binding(4) var<storage, read> live: array<u32>;
@group(0) @binding(5) var<uniform> params: Params;
@group(0) @binding(6) var<storage, read> block_offsets: array<u32>;

// Per block of the workgroup and digit, its pairs.
var<workgroup> histogram_of_block: array<atomic<u32>, HISTOGRAM_BLOCKS * 256>;
// Per row of 32 pairs and digit, a bit per pair of the row holding that digit.
var<workgroup> row_digits: array<atomic<u32>, 2048>;

@compute @workgroup_size(256)
fn histogram(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let first = (wid.x + wid.y * nwg.x) * HISTOGRAM_BLOCKS;
    let n = live[params.count_slot];
    let blocks = (n + 255u) / 256u;
    if first >= blocks {
        return;
    }
    // Workgroup memory starts zeroed (WGSL's rule), so the counts need no clearing here.
    for (var k = 0u; k < HISTOGRAM_BLOCKS; k++) {
        let i = (first + k) * 256u + lid;
        if i < n {
            atomicAdd(&histogram_of_block[k * 256u + ((key_in(i) >> params.shift) & 255u)], 1u);
        }
    }
    workgroupBarrier();
    for (var k = 0u; k < HISTOGRAM_BLOCKS; k++) {
        if first + k < blocks {
            block_digits[lid * blocks + first + k] = atomicLoad(&histogram_of_block[k * 256u + lid]);
        }
    }
}

@compute @workgroup_size(256)
fn scatter(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    let n = live[params.count_slot];
    let blocks = (n + 255u) / 256u;
    if block >= blocks {
        return;
    }
    let i = block * 256u + lid;
    let valid = i < n;
    var pair = vec2<u32>(0u);
    // 256 marks a missing pair: no real digit equals it.
    var digit = 256u;
    if valid {
        pair = pair_in(i);
        digit = (pair.x >> params.shift) & 255u;
    }
    // The bits start zeroed (workgroup memory, WGSL's rule).
    let row = lid / 32u;
    let bit = 1u << (lid % 32u);
    if valid {
        atomicOr(&row_digits[row * 256u + digit], bit);
    }
    workgroupBarrier();
    if valid {
        // The rank among equal digits before this pair: those earlier in its row (its bit's
        // lower neighbours), plus every one of the rows above.
        var rank = countOneBits(atomicLoad(&row_digits[row * 256u + digit]) & (bit - 1u));
        for (var r = 0u; r < row; r++) {
            rank += countOneBits(atomicLoad(&row_digits[r * 256u + digit]));
        }
        let first = digit * blocks + block;
        let slot = block_offsets[first / SCAN_BLOCK] + block_digits[first] + rank;
        textureStore(pairs_out, texel(slot), vec4<u32>(pair, 0u, 0u));
    }
}
