// The image formation of the CPU renderer (SPEC §3) as compute kernels; the constants come
// from the Rust crate in a generated prelude (TILE, LOW_PASS, MIN_ALPHA, MAX_ALPHA,
// MIN_TRANSMITTANCE, the SH constants, the storage steps, SH_REST and SH_WORDS).
//
// Per camera: `project` (one thread per Gaussian) → scan of the visibility flags → `compact`
// (visible splats' depth keys) → radix sort by depth → `count_tiles` (per splat in depth
// order) → scan → `emit` (tile keys, depth order kept) → stable radix sort by tile →
// `clear_ranges` + `ranges` → `raster` (one workgroup per tile) → `record` (counts for the host).

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
    // width, height, tiles across, tiles down.
    size: vec4<u32>,
    // Gaussians, tile-entry capacity, 1 when the tile sort's result is in the second buffers,
    // the camera's index in the batch.
    work: vec4<u32>,
}

// The scene, resident.
@group(0) @binding(0) var<storage, read> positions: array<f32>;
// Rotation (w, x | y, z as snorm16 pairs), log-scales x, y | z and opacity logit (i16 pairs).
@group(0) @binding(1) var<storage, read> shapes: array<vec4<u32>>;
// SH degree 0 (r, g | b, step of the higher-order codes as f16 pairs).
@group(0) @binding(2) var<storage, read> colors: array<vec2<u32>>;
// Higher-order SH codes, i8, SH_WORDS words per Gaussian.
@group(0) @binding(3) var<storage, read> sh_codes: array<u32>;
@group(0) @binding(4) var<storage, read> instances: array<u32>;
@group(0) @binding(5) var<storage, read> categories: array<u32>;

// A frame's work space.
// Four vec4 per Gaussian: (x, y, conic a, conic b), (conic c, opacity, depth, instance bits),
// (r, g, b, cutoff), (extent x, extent y, -, -).
@group(1) @binding(0) var<storage, read_write> splats: array<vec4<f32>>;
// Visibility flags, then their exclusive scan (n + 1 entries: the last ends as the total).
@group(1) @binding(1) var<storage, read_write> visible: array<u32>;
// Depth-sort pairs: depth bits and Gaussian index (two buffers each, ping-pong).
@group(1) @binding(2) var<storage, read_write> depth_keys: array<u32>;
@group(1) @binding(3) var<storage, read_write> depth_values: array<u32>;
// Tiles per depth-ordered splat, then their exclusive scan (n + 1 entries).
@group(1) @binding(4) var<storage, read_write> tile_offsets: array<u32>;
// Tile-sort pairs: tile index and Gaussian index, in the first and second buffers.
@group(1) @binding(5) var<storage, read_write> tile_keys: array<u32>;
@group(1) @binding(6) var<storage, read_write> tile_values: array<u32>;
@group(1) @binding(7) var<storage, read_write> tile_keys_2: array<u32>;
@group(1) @binding(8) var<storage, read_write> tile_values_2: array<u32>;
// Per tile: first and one-past-last entry.
@group(1) @binding(9) var<storage, read_write> tile_ranges: array<vec2<u32>>;
// Per camera of the batch: visible splats and tile entries.
@group(1) @binding(10) var<storage, read_write> work_counts: array<u32>;
// The camera's images: 8 planes of width × height words (r, g, b, alpha, expected depth,
// median depth as f32 bits; instance; category).
@group(1) @binding(11) var<storage, read_write> images: array<u32>;

@group(2) @binding(0) var<uniform> cam: Camera;

fn thread_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.x + wid.y * nwg.x) * 256u + lid;
}

fn low_i16(w: u32) -> f32 {
    return f32(bitcast<i32>(w << 16u) >> 16u);
}

fn high_i16(w: u32) -> f32 {
    return f32(bitcast<i32>(w) >> 16u);
}

fn sh_code(g: u32, j: u32) -> f32 {
    let w = sh_codes[g * SH_WORDS + j / 4u];
    return f32(bitcast<i32>(w << (24u - 8u * (j % 4u))) >> 24u);
}

// The colour seen along unit direction d: max(0, Σ c·Y + 0.5), the CPU's basis and order.
fn sh_color(g: u32, d: vec3<f32>) -> vec3<f32> {
    let dc = colors[g];
    let rg = unpack2x16float(dc.x);
    let b_step = unpack2x16float(dc.y);
    var c = vec3<f32>(rg.x, rg.y, b_step.x) * SH_C0;
    if SH_REST > 0u {
        let step = b_step.y;
        let x = d.x;
        let y = d.y;
        let z = d.z;
        let xx = x * x;
        let yy = y * y;
        let zz = z * z;
        var basis = array<f32, 15>(
            -SH_C1 * y,
            SH_C1 * z,
            -SH_C1 * x,
            SH_C2_0 * x * y,
            SH_C2_1 * y * z,
            SH_C2_2 * (2.0 * zz - xx - yy),
            SH_C2_3 * x * z,
            SH_C2_4 * (xx - yy),
            SH_C3_0 * y * (3.0 * xx - yy),
            SH_C3_1 * x * y * z,
            SH_C3_2 * y * (4.0 * zz - xx - yy),
            SH_C3_3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            SH_C3_4 * x * (4.0 * zz - xx - yy),
            SH_C3_5 * z * (xx - yy),
            SH_C3_6 * x * (xx - 3.0 * yy),
        );
        for (var k = 0u; k < SH_REST; k++) {
            let coeff = vec3<f32>(sh_code(g, 3u * k), sh_code(g, 3u * k + 1u), sh_code(g, 3u * k + 2u));
            c += coeff * step * basis[k];
        }
    }
    return max(c + vec3<f32>(0.5), vec3<f32>(0.0));
}

@compute @workgroup_size(256)
fn project(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let g = thread_index(wid, nwg, lid);
    let n = cam.work.x;
    if g > n {
        return;
    }
    // Entry n is the scan's total: zero before the scan.
    visible[g] = 0u;
    if g == n {
        return;
    }
    let p = vec3<f32>(positions[3u * g], positions[3u * g + 1u], positions[3u * g + 2u]);
    let rel = p - cam.position.xyz;
    let right = cam.right.xyz;
    let down = cam.down.xyz;
    let forward = cam.forward.xyz;
    let t = vec3<f32>(dot(right, rel), dot(down, rel), dot(forward, rel));
    let near = cam.clip.x;
    let far = cam.clip.y;
    if !(t.z >= near && t.z <= far) {
        return;
    }
    let shape = shapes[g];
    let opacity = 1.0 / (1.0 + exp(-high_i16(shape.w) * OPACITY_LOGIT_STEP));
    if !(opacity >= MIN_ALPHA) {
        return;
    }
    let fx = cam.focal.x;
    let fy = cam.focal.y;
    let inv_z = 1.0 / t.z;
    let sx = clamp(t.x * inv_z, -cam.clip.z, cam.clip.z);
    let sy = clamp(t.y * inv_z, -cam.clip.w, cam.clip.w);
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
    var c = LOW_PASS;
    for (var k = 0u; k < 3u; k++) {
        let variance = exp(log_scale[k] + log_scale[k]);
        let d0 = dot(axes[k], r0);
        let d1 = dot(axes[k], r1);
        a += variance * d0 * d0;
        b += variance * d0 * d1;
        c += variance * d1 * d1;
    }
    let det = a * c - b * b;
    let cutoff = 2.0 * log(255.0 * max(opacity, MIN_ALPHA)) + 1e-3;
    let extent = vec2<f32>(sqrt(cutoff * a), sqrt(cutoff * c));
    let px = fx * t.x * inv_z + cam.focal.z;
    let py = fy * t.y * inv_z + cam.focal.w;
    let width = f32(cam.size.x);
    let height = f32(cam.size.y);
    if !(det > 0.0 && det < 3.4e38 && px + extent.x >= 0.0 && px - extent.x <= width
        && py + extent.y >= 0.0 && py - extent.y <= height) {
        return;
    }
    let inv_det = 1.0 / det;
    let color = sh_color(g, normalize(rel));
    splats[4u * g] = vec4<f32>(px, py, c * inv_det, -b * inv_det);
    splats[4u * g + 1u] = vec4<f32>(a * inv_det, opacity, t.z, bitcast<f32>(instances[g]));
    splats[4u * g + 2u] = vec4<f32>(color, cutoff);
    splats[4u * g + 3u] = vec4<f32>(extent, 0.0, 0.0);
    visible[g] = 1u;
}

@compute @workgroup_size(256)
fn compact(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let g = thread_index(wid, nwg, lid);
    let n = cam.work.x;
    if g >= n {
        return;
    }
    let slot = visible[g];
    if visible[g + 1u] != slot {
        // Depths are positive, so their bits sort like the values.
        depth_keys[slot] = bitcast<u32>(splats[4u * g + 1u].z);
        depth_values[slot] = g;
    }
}

// The tiles of splat g's box, as the CPU bins them: [x0, y0, x1, y1], inclusive.
fn tile_box(g: u32) -> vec4<u32> {
    let s = splats[4u * g];
    let e = splats[4u * g + 3u].xy;
    let w = f32(cam.size.x);
    let h = f32(cam.size.y);
    let last = cam.size.zw - vec2<u32>(1u);
    let x0 = min(u32(max(s.x - e.x, 0.0) / f32(TILE)), last.x);
    let y0 = min(u32(max(s.y - e.y, 0.0) / f32(TILE)), last.y);
    let x1 = min(u32(max(min(s.x + e.x, w - 1.0), 0.0) / f32(TILE)), last.x);
    let y1 = min(u32(max(min(s.y + e.y, h - 1.0), 0.0) / f32(TILE)), last.y);
    return vec4<u32>(x0, y0, x1, y1);
}

// True when some pixel centre of tile (tx, ty) gets alpha ≥ 1/255 from splat g: the minimum
// of the conic's quadratic form over the tile's pixel-centre rectangle against the cutoff.
fn reaches_tile(g: u32, tx: u32, ty: u32) -> bool {
    let s = splats[4u * g];
    let a = s.z;
    let b = s.w;
    let c = splats[4u * g + 1u].x;
    let cutoff = splats[4u * g + 2u].w;
    let x0 = f32(tx * TILE) + 0.5;
    let y0 = f32(ty * TILE) + 0.5;
    let x1 = f32(min((tx + 1u) * TILE, cam.size.x)) - 0.5;
    let y1 = f32(min((ty + 1u) * TILE, cam.size.y)) - 0.5;
    if x0 <= s.x && s.x <= x1 && y0 <= s.y && s.y <= y1 {
        return true;
    }
    let dx0 = x0 - s.x;
    let dx1 = x1 - s.x;
    let dy0 = y0 - s.y;
    let dy1 = y1 - s.y;
    let ya = clamp(-b * dx0 / c, dy0, dy1);
    let yb = clamp(-b * dx1 / c, dy0, dy1);
    let xa = clamp(-b * dy0 / a, dx0, dx1);
    let xb = clamp(-b * dy1 / a, dx0, dx1);
    let q0 = a * dx0 * dx0 + 2.0 * b * dx0 * ya + c * ya * ya;
    let q1 = a * dx1 * dx1 + 2.0 * b * dx1 * yb + c * yb * yb;
    let q2 = a * xa * xa + 2.0 * b * xa * dy0 + c * dy0 * dy0;
    let q3 = a * xb * xb + 2.0 * b * xb * dy1 + c * dy1 * dy1;
    return min(min(q0, q1), min(q2, q3)) <= cutoff;
}

// Counts the tiles splat g reaches; with `write`, also records them as entries from `first`
// on (those past the capacity are counted, not written: the host grows the buffers).
fn bin(g: u32, first: u32, write: bool) -> u32 {
    let r = tile_box(g);
    let single = r.x == r.z && r.y == r.w;
    var slot = first;
    for (var ty = r.y; ty <= r.w; ty++) {
        for (var tx = r.x; tx <= r.z; tx++) {
            if single || reaches_tile(g, tx, ty) {
                if write && slot < cam.work.y {
                    tile_keys[slot] = ty * cam.size.z + tx;
                    tile_values[slot] = g;
                }
                slot += 1u;
            }
        }
    }
    return slot - first;
}

@compute @workgroup_size(256)
fn count_tiles(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    let n = cam.work.x;
    if i > n {
        return;
    }
    var count = 0u;
    if i < visible[n] {
        count = bin(depth_values[i], 0u, false);
    }
    tile_offsets[i] = count;
}

@compute @workgroup_size(256)
fn emit(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    if i >= visible[cam.work.x] {
        return;
    }
    bin(depth_values[i], tile_offsets[i], true);
}

@compute @workgroup_size(256)
fn clear_ranges(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let t = thread_index(wid, nwg, lid);
    if t < cam.size.z * cam.size.w {
        tile_ranges[t] = vec2<u32>(0u);
    }
}

fn sorted_tile(i: u32) -> u32 {
    if cam.work.z == 1u {
        return tile_keys_2[i];
    }
    return tile_keys[i];
}

fn sorted_splat(i: u32) -> u32 {
    if cam.work.z == 1u {
        return tile_values_2[i];
    }
    return tile_values[i];
}

fn entry_count() -> u32 {
    return min(tile_offsets[cam.work.x], cam.work.y);
}

@compute @workgroup_size(256)
fn ranges(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = thread_index(wid, nwg, lid);
    let m = entry_count();
    if i >= m {
        return;
    }
    let t = sorted_tile(i);
    if i == 0u || sorted_tile(i - 1u) != t {
        tile_ranges[t].x = i;
    }
    if i + 1u == m || sorted_tile(i + 1u) != t {
        tile_ranges[t].y = i + 1u;
    }
}

var<workgroup> batch_a: array<vec4<f32>, 256>;
var<workgroup> batch_b: array<vec4<f32>, 256>;
var<workgroup> batch_c: array<vec4<f32>, 256>;
var<workgroup> pixels_done: atomic<u32>;
var<workgroup> all_done: u32;
var<workgroup> tile_range: vec2<u32>;

@compute @workgroup_size(16, 16)
fn raster(
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let px = wid.x * TILE + local.x;
    let py = wid.y * TILE + local.y;
    let inside = px < cam.size.x && py < cam.size.y;
    let centre = vec2<f32>(f32(px) + 0.5, f32(py) + 0.5);
    var transmittance = 1.0;
    var color = vec3<f32>(0.0);
    var weighted_depth = 0.0;
    var median = 0.0;
    var best_weight = 0.0;
    var instance = 0u;
    var done = !inside;
    if lid == 0u {
        atomicStore(&pixels_done, 0u);
        tile_range = tile_ranges[wid.y * cam.size.z + wid.x];
    }
    // Read through the workgroup so every thread sees the same (uniform) loop bounds.
    let range = workgroupUniformLoad(&tile_range);
    if done {
        atomicAdd(&pixels_done, 1u);
    }
    for (var start = range.x; start < range.y; start += 256u) {
        workgroupBarrier();
        let e = start + lid;
        if e < range.y {
            let g = sorted_splat(e);
            batch_a[lid] = splats[4u * g];
            batch_b[lid] = splats[4u * g + 1u];
            batch_c[lid] = splats[4u * g + 2u];
        }
        if lid == 0u {
            all_done = atomicLoad(&pixels_done);
        }
        if workgroupUniformLoad(&all_done) == 256u {
            break;
        }
        let n = min(256u, range.y - start);
        for (var k = 0u; k < n && !done; k++) {
            let s = batch_a[k];
            let d = vec2<f32>(s.x, s.y) - centre;
            let sb = batch_b[k];
            let power = -0.5 * (s.z * d.x * d.x + sb.x * d.y * d.y) - s.w * d.x * d.y;
            let alpha = min(sb.y * exp(power), MAX_ALPHA);
            if power > 0.0 || !(alpha >= MIN_ALPHA) {
                continue;
            }
            let next = transmittance * (1.0 - alpha);
            if next < MIN_TRANSMITTANCE {
                done = true;
                atomicAdd(&pixels_done, 1u);
                break;
            }
            let weight = alpha * transmittance;
            color += weight * batch_c[k].xyz;
            weighted_depth += weight * sb.z;
            // Transmittance only falls: the last splat blended while it was above 0.5 is the
            // one that crossed it (kept only if it ends at or below 0.5).
            if transmittance > 0.5 {
                median = sb.z;
            }
            if weight > best_weight {
                best_weight = weight;
                instance = bitcast<u32>(sb.w);
            }
            transmittance = next;
        }
    }
    if !inside {
        return;
    }
    let pixels = cam.size.x * cam.size.y;
    let p = py * cam.size.x + px;
    let rgb = color + transmittance * cam.background.xyz;
    let hit = 1.0 - transmittance;
    var depth = 0.0;
    var category = 0u;
    if hit > 0.0 {
        depth = weighted_depth / hit;
        if instance < arrayLength(&categories) {
            category = categories[instance];
        }
    }
    if transmittance > 0.5 {
        median = 0.0;
    }
    images[p] = bitcast<u32>(rgb.x);
    images[pixels + p] = bitcast<u32>(rgb.y);
    images[2u * pixels + p] = bitcast<u32>(rgb.z);
    images[3u * pixels + p] = bitcast<u32>(hit);
    images[4u * pixels + p] = bitcast<u32>(depth);
    images[5u * pixels + p] = bitcast<u32>(median);
    images[6u * pixels + p] = instance;
    images[7u * pixels + p] = category;
}

@compute @workgroup_size(1)
fn record() {
    let n = cam.work.x;
    work_counts[2u * cam.work.w] = visible[n];
    work_counts[2u * cam.work.w + 1u] = tile_offsets[n];
}
