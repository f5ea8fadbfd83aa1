// Sizes known only on the GPU: each record of `program` reads a count (from `live` or from the
// buffer just scanned), clamps it to what the buffers hold, and writes the size and the
// indirect dispatch arguments of the passes that depend on it back into `live`, so the passes
// after it run over what is there rather than over buffer capacity.

struct Derive {
    // 0: live[src]; 1: source[live[src]].
    kind: u32,
    src: u32,
    // n = ceil(min(value + add, cap) / div) * mul.
    add: u32,
    div: u32,
    mul: u32,
    cap: u32,
    // Slots of live (NONE: not written): n, the largest and the sum of the unclamped values
    // over the batch (the host zeroes them), and the (x, y, 1) workgroups of
    // ceil(n / per_group) folded into two dimensions.
    out: u32,
    peak: u32,
    total: u32,
    args: u32,
    per_group: u32,
    _pad: u32,
}

const NONE: u32 = 0xffffffffu;
const MAX_GROUPS: u32 = 65535u;

@group(0) @binding(0) var<storage, read_write> live: array<u32>;
@group(0) @binding(1) var<storage, read> source: array<u32>;
@group(0) @binding(2) var<storage, read> program: array<Derive>;
// First record and number of records of this run.
@group(0) @binding(3) var<uniform> range: vec4<u32>;

@compute @workgroup_size(1)
fn derive() {
    for (var i = range.x; i < range.x + range.y; i++) {
        let d = program[i];
        var value = live[d.src];
        if d.kind == 1u {
            value = source[value];
        }
        if d.peak != NONE {
            live[d.peak] = max(live[d.peak], value);
            live[d.total] = live[d.total] + min(value, 0xffffffffu - live[d.total]);
        }
        var n = min(value, d.cap);
        n = min(n + d.add, d.cap);
        n = (n + d.div - 1u) / d.div * d.mul;
        if d.out != NONE {
            live[d.out] = n;
        }
        if d.args != NONE {
            let groups = (n + d.per_group - 1u) / d.per_group;
            let x = min(groups, MAX_GROUPS);
            live[d.args] = x;
            live[d.args + 1u] = select(1u, (groups + x - 1u) / max(x, 1u), x > 0u);
            live[d.args + 2u] = 1u;
        }
    }
}
