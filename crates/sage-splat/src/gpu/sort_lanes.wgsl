// The radix sort's kernels shaped for hardware GPUs (`sort.wgsl`): a thread per pair, blocks
// of 256. A workgroup of `histogram` counts HISTOGRAM_BLOCKS blocks, a pair of each per thread,
// before one barrier (workgroup memory starts zeroed); `scatter` ranks each pair among the equal digits of its block
// from bit masks in workgroup memory.

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
    let blocks = blocks_of(n);
    if first >= blocks {
        return;
    }
    // Workgroup memory starts zeroed (WGSL's rule), so the counts need no clearing here.
    for (var k = 0u; k < HISTOGRAM_BLOCKS; k++) {
        let i = (first + k) * SORT_BLOCK + lid;
        if i < n {
            atomicAdd(&histogram_of_block[k * 256u + digit_of(key_in(i))], 1u);
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
    let blocks = blocks_of(n);
    if block >= blocks {
        return;
    }
    let i = block * SORT_BLOCK + lid;
    let valid = i < n;
    var pair = vec2<u32>(0u);
    // 256 marks a missing pair: no real digit equals it.
    var digit = 256u;
    if valid {
        pair = pair_in(i);
        digit = digit_of(pair.x);
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
        textureStore(pairs_out, texel(first_slot(digit, block, blocks) + rank), vec4<u32>(pair, 0u, 0u));
    }
}
