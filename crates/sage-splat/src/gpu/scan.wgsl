// Exclusive prefix sum of `data[0..n]` in place, SCAN_BLOCK elements per workgroup (256
// threads, each a run of SCAN_BLOCK / 256; the constant comes from the Rust side), n read on
// the GPU (`live[n_slot]`) and the workgroups dispatched indirectly from it. `scan_blocks`
// scans each block and writes its total to `sums`; once `sums` is scanned the same way
// (recursively), `add_sums` adds each block's offset back; or, for a reader that adds its
// block's offset itself (the radix sort's `scatter`: `Finish::Apart` in sort.rs), the lowest
// level's offsets stay in `sums`.
//
// A block takes two barriers: a software driver (lavapipe) runs a workgroup's threads a vector
// at a time and switches between them at every barrier, which costs more than the additions.

struct Params {
    n_slot: u32,
}

@group(0) @binding(0) var<storage, read_write> data: array<u32>;
@group(0) @binding(1) var<storage, read_write> sums: array<u32>;
@group(0) @binding(2) var<uniform> params: Params;
@group(0) @binding(3) var<storage, read> live: array<u32>;

const RUN: u32 = SCAN_BLOCK / 256u;

// Per thread, the total of its run; then its exclusive prefix within its row of 16 threads.
var<workgroup> partial: array<u32, 256>;
// Per row of 16 threads, its total.
var<workgroup> row_total: array<u32, 16>;

@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    let n = live[params.n_slot];
    if block * SCAN_BLOCK >= n {
        return;
    }
    let base = block * SCAN_BLOCK + lid * RUN;
    let end = min(base + RUN, n);
    var total = 0u;
    for (var i = base; i < end; i++) {
        total += data[i];
    }
    partial[lid] = total;
    workgroupBarrier();
    if lid < 16u {
        var acc = 0u;
        for (var k = 0u; k < 16u; k++) {
            let v = partial[16u * lid + k];
            partial[16u * lid + k] = acc;
            acc += v;
        }
        row_total[lid] = acc;
    }
    workgroupBarrier();
    var before = partial[lid];
    for (var r = 0u; r < lid / 16u; r++) {
        before += row_total[r];
    }
    for (var i = base; i < end; i++) {
        let v = data[i];
        data[i] = before;
        before += v;
    }
    // After its run, the last thread's running sum is the block's total.
    if lid == 255u {
        sums[block] = before;
    }
}

@compute @workgroup_size(256)
fn add_sums(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    let n = live[params.n_slot];
    if block * SCAN_BLOCK >= n {
        return;
    }
    let offset = sums[block];
    let base = block * SCAN_BLOCK + lid * RUN;
    for (var i = base; i < min(base + RUN, n); i++) {
        data[i] += offset;
    }
}
