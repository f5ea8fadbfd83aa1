// One pass of a stable least-significant-digit radix sort of (key, value) pairs on the 8-bit
// digit at `shift`. The number of pairs is read on the GPU (`live[count_slot]`) and the
// workgroups dispatched indirectly from it, so a frame's passes are recorded without knowing
// it. The pairs fall in blocks of SORT_BLOCK: `histogram` counts each block's digits into
// `block_digits[digit * blocks + block]`; after an exclusive scan of that array (digit-major,
// so it holds every block's first slot for each digit; the scan leaves each word's prefix
// within its block of SCAN_BLOCK words and the blocks' offsets in `block_offsets`), `scatter`
// writes each pair there plus the number of equal digits before it in its block, which keeps
// equal keys in their input order. Two shapes of the two kernels follow this prelude
// (`sort_lanes.wgsl`, `sort_runs.wgsl`); the constants come from the Rust side.
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

// The digit of `key` this pass sorts by.
fn digit_of(key: u32) -> u32 {
    return (key >> params.shift) & 255u;
}

// The number of blocks of n pairs.
fn blocks_of(n: u32) -> u32 {
    return (n + SORT_BLOCK - 1u) / SORT_BLOCK;
}

// The first slot of the pairs of `digit` in `block` (of `blocks`), once the counts are scanned.
fn first_slot(digit: u32, block: u32, blocks: u32) -> u32 {
    let first = digit * blocks + block;
    return block_offsets[first / SCAN_BLOCK] + block_digits[first];
}
