// One pass of a stable least-significant-digit radix sort of (key, value) pairs on the 8-bit
// digit at `shift`. The number of pairs is read on the GPU (`counts[count_at]`, at most
// `capacity`), so a frame's passes are recorded without knowing it. Blocks of 256 pairs:
// `histogram` counts each block's digits into `block_digits[digit * blocks + block]`; after
// an exclusive scan of that array (digit-major, so it holds every pair's first slot), `scatter`
// writes each pair there plus its rank among the equal digits before it in its block, which
// keeps equal keys in their input order.

struct Params {
    shift: u32,
    blocks: u32,
    capacity: u32,
    count_at: u32,
}

@group(0) @binding(0) var<storage, read> keys_in: array<u32>;
@group(0) @binding(1) var<storage, read> values_in: array<u32>;
@group(0) @binding(2) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(3) var<storage, read_write> values_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> block_digits: array<u32>;
@group(0) @binding(5) var<storage, read> counts: array<u32>;
@group(0) @binding(6) var<uniform> params: Params;

var<workgroup> histogram_of_block: array<atomic<u32>, 256>;
var<workgroup> digits: array<u32, 256>;

fn pair_count() -> u32 {
    return min(counts[params.count_at], params.capacity);
}

@compute @workgroup_size(256)
fn histogram(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    if block >= params.blocks {
        return;
    }
    atomicStore(&histogram_of_block[lid], 0u);
    workgroupBarrier();
    let i = block * 256u + lid;
    if i < pair_count() {
        atomicAdd(&histogram_of_block[(keys_in[i] >> params.shift) & 255u], 1u);
    }
    workgroupBarrier();
    block_digits[lid * params.blocks + block] = atomicLoad(&histogram_of_block[lid]);
}

@compute @workgroup_size(256)
fn scatter(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    if block >= params.blocks {
        return;
    }
    let i = block * 256u + lid;
    let valid = i < pair_count();
    var key = 0u;
    // 256 marks a missing pair: no real digit equals it.
    var digit = 256u;
    if valid {
        key = keys_in[i];
        digit = (key >> params.shift) & 255u;
    }
    digits[lid] = digit;
    workgroupBarrier();
    if valid {
        var rank = 0u;
        for (var j = 0u; j < lid; j++) {
            rank += select(0u, 1u, digits[j] == digit);
        }
        let slot = block_digits[digit * params.blocks + block] + rank;
        keys_out[slot] = key;
        values_out[slot] = values_in[i];
    }
}
