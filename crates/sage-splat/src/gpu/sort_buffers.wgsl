// The radix sort's input from two buffers, keys and values (`sort.wgsl`).
@group(0) @binding(0) var<storage, read> keys_in: array<u32>;
@group(0) @binding(1) var<storage, read> values_in: array<u32>;

fn key_in(i: u32) -> u32 {
    return keys_in[i];
}

fn pair_in(i: u32) -> vec2<u32> {
    return vec2<u32>(keys_in[i], values_in[i]);
}
