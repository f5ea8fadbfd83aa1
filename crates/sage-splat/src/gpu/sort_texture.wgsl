// The radix sort's input from a texture of (key, value) texels, as the pass before left it
// (`sort.wgsl`).
@group(0) @binding(1) var pairs_in: texture_2d<u32>;

fn key_in(i: u32) -> u32 {
    return textureLoad(pairs_in, texel(i), 0).x;
}

fn pair_in(i: u32) -> vec2<u32> {
    return textureLoad(pairs_in, texel(i), 0).xy;
}
