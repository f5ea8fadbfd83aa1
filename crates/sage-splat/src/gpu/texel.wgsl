// Texel i of a texture indexed by a flat number (splats, Gaussians, sort pairs): rows of
// TEXELS_ACROSS (the constant comes from the Rust side).
fn texel(i: u32) -> vec2<u32> {
    return vec2<u32>(i % TEXELS_ACROSS, i / TEXELS_ACROSS);
}
