// The radix sort's kernels shaped for CPU drivers (`sort.wgsl`): a thread per block of
// SORT_BLOCK pairs, which it counts and then places one at a time, keeping a count per digit.
// A CPU driver (lavapipe) runs a workgroup's threads a vector of lanes at a time, a memory
// access at an index it cannot prove uniform lane by lane: ranking a pair among a block's
// lanes takes some five such accesses in workgroup memory and a barrier, where a thread
// walking its own run takes two, with no barrier and no atomics. Hardware GPUs would leave
// most of their lanes idle this way.

// Per digit and thread of the workgroup: its pairs, then (in `scatter`) its next slot.
var<workgroup> digit_counts: array<u32, 256 * RUN_GROUP>;

// A thread's block of pairs: its number, the pass's number of blocks (the block is past them
// when the thread has none), and its first and one-past-last pair.
struct Run {
    block: u32,
    blocks: u32,
    first: u32,
    end: u32,
}

// The block of thread lid of workgroup wid.
fn run_of(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> Run {
    let block = (wid.x + wid.y * nwg.x) * RUN_GROUP + lid;
    let n = live[params.count_slot];
    return Run(block, blocks_of(n), block * SORT_BLOCK, min(n, (block + 1u) * SORT_BLOCK));
}

@compute @workgroup_size(RUN_GROUP)
fn histogram(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let run = run_of(wid, nwg, lid);
    if run.block >= run.blocks {
        return;
    }
    // Workgroup memory starts zeroed (WGSL's rule), so the counts need no clearing here.
    for (var i = run.first; i < run.end; i++) {
        digit_counts[digit_of(key_in(i)) * RUN_GROUP + lid] += 1u;
    }
    for (var d = 0u; d < 256u; d++) {
        block_digits[d * run.blocks + run.block] = digit_counts[d * RUN_GROUP + lid];
    }
}

@compute @workgroup_size(RUN_GROUP)
fn scatter(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let run = run_of(wid, nwg, lid);
    if run.block >= run.blocks {
        return;
    }
    for (var d = 0u; d < 256u; d++) {
        digit_counts[d * RUN_GROUP + lid] = first_slot(d, run.block, run.blocks);
    }
    for (var i = run.first; i < run.end; i++) {
        let pair = pair_in(i);
        let at = digit_of(pair.x) * RUN_GROUP + lid;
        let slot = digit_counts[at];
        digit_counts[at] = slot + 1u;
        textureStore(pairs_out, texel(slot), vec4<u32>(pair, 0u, 0u));
    }
}
