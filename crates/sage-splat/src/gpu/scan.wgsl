// Exclusive prefix sum of `data[0..n]` in place, 1024 elements per workgroup (256 threads × 4),
// n read on the GPU (`live[n_slot]`) and the workgroups dispatched indirectly from it.
// `scan_blocks` scans each block and writes its total to `sums`; once `sums` is scanned the
// same way (recursively), `add_sums` adds each block's offset back.

struct Params {
    n_slot: u32,
}

@group(0) @binding(0) var<storage, read_write> data: array<u32>;
@group(0) @binding(1) var<storage, read_write> sums: array<u32>;
@group(0) @binding(2) var<uniform> params: Params;
@group(0) @binding(3) var<storage, read> live: array<u32>;

var<workgroup> partial: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = wid.x + wid.y * nwg.x;
    let n = live[params.n_slot];
    if block * 1024u >= n {
        return;
    }
    let base = block * 1024u + lid * 4u;
    var local: array<u32, 4>;
    var total = 0u;
    for (var k = 0u; k < 4u; k++) {
        local[k] = total;
        if base + k < n {
            total += data[base + k];
        }
    }
    partial[lid] = total;
    workgroupBarrier();
    // Hillis–Steele inclusive scan of the 256 thread totals.
    for (var offset = 1u; offset < 256u; offset <<= 1u) {
        var add = 0u;
        if lid >= offset {
            add = partial[lid - offset];
        }
        workgroupBarrier();
        partial[lid] += add;
        workgroupBarrier();
    }
    let before = partial[lid] - total;
    for (var k = 0u; k < 4u; k++) {
        if base + k < n {
            data[base + k] = before + local[k];
        }
    }
    if lid == 255u {
        sums[block] = partial[255];
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
    if block * 1024u >= n {
        return;
    }
    let offset = sums[block];
    for (var k = 0u; k < 4u; k++) {
        let i = block * 1024u + lid * 4u + k;
        if i < n {
            data[i] += offset;
        }
    }
}
