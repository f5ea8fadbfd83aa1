//! A scene resident on the GPU: the Gaussians as the store holds them (the same quantised
//! values the CPU renderer reads) and the chunk bounds of the CPU renderer's spatial index,
//! which the kernels cull against.

use super::Gpu;
use super::kernel::{FLOATS, TEXELS_ACROSS, WORDS, texel_bytes, texel_rows, texel_rows_texture};
use crate::fastmath::sigmoid;
use crate::index::SplatIndex;
use rayon::prelude::*;
use sage_scene::Gaussians;
use sage_scene::gaussians::sh_rest_count;
use wgpu::util::DeviceExt;

/// The scene's buffers and textures.
pub(crate) struct SceneBuffers {
    /// A texel per Gaussian (x, y, z, opacity), in rows of [`TEXELS_ACROSS`]: the opacity as
    /// the CPU renderer forms it ([`sigmoid`] of the logit), so both executors start from the
    /// same value and no kernel takes an exponential for it.
    pub(crate) positions: wgpu::TextureView,
    /// A texel per Gaussian: rotation and log-scales as i16 pairs, the last half-word zero (the
    /// opacity is in `positions`).
    pub(crate) shapes: wgpu::TextureView,
    /// [`appearance_texels`] texels per Gaussian: its SH degree 0 and step (f16 pairs), its
    /// instance, then its higher-order SH codes (i8, four to a word).
    pub(crate) appearance: wgpu::TextureView,
    pub(crate) chunk_bounds: wgpu::Buffer,
    /// The same bounds on the host, where a batch's slabs are chosen from what its cameras
    /// see before it is recorded.
    pub(crate) index: SplatIndex,
    /// Chunks of [`crate::index::CHUNK`] Gaussians.
    pub(crate) chunks: u32,
    /// Bytes of all of them.
    pub(crate) bytes: u64,
}

/// Words of packed i8 SH codes per Gaussian.
fn sh_words(sh_rest: usize) -> usize {
    (sh_rest * 3).div_ceil(4)
}

/// Words of a Gaussian's appearance before its SH codes: its colour and step, its instance.
const APPEARANCE_HEAD: usize = 3;

/// Texels of a Gaussian's appearance (1 to 4) with `sh_rest` higher-order SH coefficients.
pub(crate) fn appearance_texels(sh_rest: usize) -> u32 {
    (APPEARANCE_HEAD + sh_words(sh_rest)).div_ceil(4) as u32
}

/// A storage buffer holding `contents` (one zero word when empty), writable by copies.
pub(crate) fn init_buffer(gpu: &Gpu, label: &str, contents: &[u32]) -> wgpu::Buffer {
    let one = [0u32];
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(if contents.is_empty() { &one } else { contents }),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
}

/// A texture of `words`, four a texel, in rows of [`TEXELS_ACROSS`] (the last row padded with
/// zeros), read by `textureLoad`.
fn texel_texture(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    words: &[u32],
) -> wgpu::TextureView {
    let rows = texel_rows((words.len() / 4) as u32);
    let mut padded = words.to_vec();
    padded.resize(rows as usize * TEXELS_ACROSS as usize * 4, 0);
    let texture = gpu.device.create_texture_with_data(
        &gpu.queue,
        &texel_rows_texture(label, format, rows, wgpu::TextureUsages::TEXTURE_BINDING),
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&padded),
    );
    texture.create_view(&wgpu::TextureViewDescriptor::default())
}

/// `words` words for each of `n` Gaussians (zeroed, then filled by `fill(i, words of i)`), in
/// parallel: a million Gaussians take tens of milliseconds on one core.
fn per_gaussian(n: usize, words: usize, fill: impl Fn(usize, &mut [u32]) + Sync) -> Vec<u32> {
    let mut all = vec![0u32; n * words];
    all.par_chunks_exact_mut(words)
        .enumerate()
        .for_each(|(i, w)| fill(i, w));
    all
}

/// Two i16 in one word, low first.
fn pair(lo: i16, hi: i16) -> u32 {
    u32::from(lo as u16) | u32::from(hi as u16) << 16
}

impl SceneBuffers {
    /// Uploads the store and its chunk bounds.
    pub(crate) fn upload(gpu: &Gpu, g: &Gaussians) -> SceneBuffers {
        let n = g.len();
        let positions = per_gaussian(n, 4, |i, t| {
            let [x, y, z] = g.positions[i];
            t.copy_from_slice(&[x, y, z, sigmoid(g.opacity_logit(i))].map(f32::to_bits));
        });
        let shapes = per_gaussian(n, 4, |i, t| {
            let [w, x, y, z] = g.rotations[i];
            let [sx, sy, sz] = g.log_scales[i];
            t.copy_from_slice(&[pair(w, x), pair(y, z), pair(sx, sy), pair(sz, 0)]);
        });
        let half =
            |lo: half::f16, hi: half::f16| u32::from(lo.to_bits()) | u32::from(hi.to_bits()) << 16;
        let rest = sh_rest_count(g.sh_degree());
        let stride = 4 * appearance_texels(rest) as usize;
        let appearance = per_gaussian(n, stride, |i, t| {
            let [r, gr, b] = g.sh_dc[i];
            let step = if rest > 0 {
                g.sh_steps[i]
            } else {
                half::f16::ZERO
            };
            t[0] = half(r, gr);
            t[1] = half(b, step);
            t[2] = g.instances[i];
            let codes = &g.sh_codes[i * rest * 3..(i + 1) * rest * 3];
            for (j, &c) in codes.iter().enumerate() {
                t[APPEARANCE_HEAD + j / 4] |= u32::from(c as u8) << (8 * (j % 4));
            }
        });
        let index = SplatIndex::build(g);
        let chunk_bounds: Vec<u32> = index
            .bounds
            .iter()
            .flat_map(|b| {
                // An empty chunk is flagged rather than given infinite corners.
                let (held, lo, hi) = if b.is_empty() {
                    (0.0, [0.0; 3], [0.0; 3])
                } else {
                    (1.0, b.min.to_array(), b.max.to_array())
                };
                [lo[0], lo[1], lo[2], held, hi[0], hi[1], hi[2], 0.0f32]
            })
            .map(f32::to_bits)
            .collect();
        let texture_bytes = texel_bytes(n as u32, FLOATS)
            + texel_bytes(n as u32, WORDS)
            + texel_bytes((appearance.len() / 4) as u32, WORDS);
        let bytes = texture_bytes + 4 * chunk_bounds.len() as u64;
        SceneBuffers {
            positions: texel_texture(gpu, "positions", FLOATS, &positions),
            shapes: texel_texture(gpu, "shapes", WORDS, &shapes),
            appearance: texel_texture(gpu, "appearance", WORDS, &appearance),
            chunk_bounds: init_buffer(gpu, "chunk bounds", &chunk_bounds),
            chunks: index.bounds.len() as u32,
            index,
            bytes,
        }
    }
}
