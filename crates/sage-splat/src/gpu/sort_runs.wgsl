// The radix sort's kernels shaped for CPU drivers (`sort.wgsl`): a thread per block of
// SORT_BLOCK pairs, which it counts and then places one at a time, keeping a count per digit.
// A CPU driver (lavapipe) runs a workgroup's threads a vector of lanes at a time, a memory
// access at an index it cannot prove uniform lane by lane: ranking a pair among a block's
// lanes takes some five such accesses in workgroup memory and a barrier, where a thread
// walking its own run takes two, with no barrier and no atomics. Hardware GPUs would leave
// most of their lanes idle this way.

// Per digit and thread of the workgroup: its pairs, then (in `scatter`) its next slot.
var<workgroup> digit_counts: array<u32, 256 * RUN_GROUP>;

// The block of thread lid of workgroup wid.
fn run_block(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.x + wid.y * nwg.x) * RUN_GROUP + lid;
}

@compute @workgroup_size(RUN_GROUP)
fn histogram(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = run_block(wid, nwg, lid);
    let n = live[params.count_slot];
    let blocks = blocks_of(n);
    if block >= blocks {
        return;
    }
    // Workgroup memory starts zeroed (WGSL's rule), so the counts need no clearing here.
    for (var i = block * SORT_BLOCK; i < min(n, (block + 1u) * SORT_BLOCK); i++) {
        digit_counts[digit_of(key_in(i)) * RUN_GROUP + lid] += 1u;
    }
    for (var d = 0u; d < 256u; d++) {
        block_digits[d * blocks + block] = digit_counts[d * RUN_GROUP + lid];
    }
}

@compute @workgroup_size(RUN_GROUP)
fn scatter(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = run_block(wid, nwg, lid);
    let n = live[params.count_slot];
    let blocks = blocks_of(n);
    if block >= blocks {
        return;
    }
    for (var d = 0u; d < 256u; d++) {
        digit_counts[d * RUN_GROUP + lid] = first_slot(d, block, blocks);
    }
    for (var i = block * SORT_BLOCK; i < min(n, (block + 1u) * SORT_BLOCK); i++) {
        let pair = pair_in(i);
        let at = digit_of(pair.x) * RUN_GROUP + lid;
        let slot = digit_counts[at];
        digit_counts[at] = slot + 1u;
        textureStore(pairs_out, texel(slot), vec4<u32>(pair, 0u, 0u));
    }
}
