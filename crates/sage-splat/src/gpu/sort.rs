//! The two GPU primitives the binning needs: an exclusive prefix sum ([`Scan`]) and a stable
//! radix sort of (key, value) pairs ([`RadixSort`]) from two buffers or a texture into
//! textures of pairs, each recorded into a compute pass over storage of a fixed capacity,
//! with the live count read on the GPU and the workgroups dispatched indirectly from it
//! (`scan.wgsl`, `sort.wgsl`, [`super::live`]). The sort's kernels come in both
//! [`KernelShape`]s, one for hardware GPUs and one for CPU drivers; both leave the same bytes.

use super::Gpu;
use super::kernel::{
    Kernel, PAIRS, RUN_GROUP, TEXELS_ACROSS, bind, bind_from, layout, storage, texels_in,
    texels_out, uniform, uniform_buffer,
};
use super::live::{Count, Live, LiveBuilder, Size};
use crate::passes::KernelShape;

/// Elements one workgroup of `scan_blocks` covers (256 threads, a run of 16 each).
const SCAN_BLOCK: u32 = 4096;
/// Blocks one workgroup of the lanes-shaped `histogram` counts (fewer workgroups and barriers
/// for the same counting: a third less time under lavapipe than one block each).
const HISTOGRAM_BLOCKS: u32 = 4;

/// Pairs per block of a sort of `shape` (a column of the digit counts): a thread's each in
/// [`KernelShape::Lanes`] (`sort_lanes.wgsl`, ranked from bit masks in workgroup memory), one
/// thread's run in [`KernelShape::Runs`] (`sort_runs.wgsl`, counted and placed one at a time;
/// under lavapipe on two cores a 24-bit sort of 13,000 pairs takes half the time, of 100,000
/// a third).
fn sort_block(shape: KernelShape) -> u32 {
    match shape {
        KernelShape::Lanes => 256,
        KernelShape::Runs => 1024,
    }
}

/// Words of digit counts a sort of `shape` keeps for up to `pairs` pairs: 256 per block.
pub(crate) fn digit_words(shape: KernelShape, pairs: u32) -> u64 {
    u64::from(pairs.max(1).div_ceil(sort_block(shape))) * 256
}

/// Pairs one workgroup of `histogram` and one of `scatter` of `shape` take.
fn pairs_per_group(shape: KernelShape) -> (u32, u32) {
    let block = sort_block(shape);
    match shape {
        KernelShape::Lanes => (block * HISTOGRAM_BLOCKS, block),
        KernelShape::Runs => (block * RUN_GROUP, block * RUN_GROUP),
    }
}

/// The source of the sort's kernels of `shape`.
fn sort_kernels(shape: KernelShape) -> &'static str {
    match shape {
        KernelShape::Lanes => include_str!("sort_lanes.wgsl"),
        KernelShape::Runs => include_str!("sort_runs.wgsl"),
    }
}

/// The exclusive prefix sum kernels.
pub(crate) struct Scan {
    layout: wgpu::BindGroupLayout,
    scan_blocks: Kernel,
    add_sums: Kernel,
}

/// One level of a scan: its bind group and where its workgroups are.
struct ScanLevel {
    bind_group: wgpu::BindGroup,
    args: u64,
}

/// Where a scan leaves the offsets of its blocks of `SCAN_BLOCK` words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Finish {
    /// Added back into the data: every word ends as its exclusive prefix.
    InPlace,
    /// Kept apart ([`ScanPlan::block_offsets`]): every word ends as its prefix within its
    /// block, and a reader adds its block's offset. One dispatch fewer, for a reader that
    /// reads each word once (the radix sort's `scatter`).
    Apart,
}

/// A scan of one buffer of up to a fixed length: the levels of block sums, bottom first.
pub(crate) struct ScanPlan {
    levels: Vec<ScanLevel>,
    finish: Finish,
    /// The block-sum buffer of each level (the first: the blocks' offsets once scanned), and
    /// the parameter buffers, kept alive.
    buffers: Vec<wgpu::Buffer>,
}

impl ScanPlan {
    /// Per block of `SCAN_BLOCK` words, its offset: what a reader of a scan finished
    /// [`Finish::Apart`] adds to each word of the block.
    pub(crate) fn block_offsets(&self) -> &wgpu::Buffer {
        &self.buffers[0]
    }
}

impl Scan {
    /// Compiles the scan kernels.
    pub(crate) fn new(gpu: &Gpu) -> Scan {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("scan"),
                source: wgpu::ShaderSource::Wgsl(
                    format!(
                        "const SCAN_BLOCK: u32 = {SCAN_BLOCK}u;\n{}",
                        include_str!("scan.wgsl")
                    )
                    .into(),
                ),
            });
        let layout = layout(
            gpu,
            &[
                storage(0, false),
                storage(1, false),
                uniform(2),
                storage(3, true),
            ],
        );
        Scan {
            scan_blocks: Kernel::new(gpu, &module, "scan_blocks", &[&layout]),
            add_sums: Kernel::new(gpu, &module, "add_sums", &[&layout]),
            layout,
        }
    }

    /// A scan of the first `live[n_slot]` (at most `capacity`) words of `data`, its sizes
    /// derived in `builder`'s current stage.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn plan(
        &self,
        gpu: &Gpu,
        live: &Live,
        builder: &mut LiveBuilder,
        data: &wgpu::Buffer,
        capacity: u32,
        n_slot: u32,
        finish: Finish,
    ) -> ScanPlan {
        let mut levels = Vec::new();
        let mut buffers: Vec<wgpu::Buffer> = Vec::new();
        let mut cap = capacity.max(1);
        let mut size = Size::of(Count::Live(n_slot), cap);
        loop {
            let derived = builder.derive(size.dispatched(SCAN_BLOCK));
            let blocks = cap.div_ceil(SCAN_BLOCK);
            let sums = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("scan sums"),
                size: u64::from(blocks) * 4,
                // Copied out only by the tests.
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let params = uniform_buffer(gpu, &[derived.n, 0, 0, 0]);
            // Level 0 scans the data; each level above scans the sums of the one below.
            let input = if levels.is_empty() {
                data
            } else {
                &buffers[buffers.len() - 2]
            };
            let bind_group = bind(
                gpu,
                &self.layout,
                &[
                    input.as_entire_binding(),
                    sums.as_entire_binding(),
                    params.as_entire_binding(),
                    live.buffer.as_entire_binding(),
                ],
            );
            levels.push(ScanLevel {
                bind_group,
                args: derived.args,
            });
            buffers.push(sums);
            buffers.push(params);
            // Offsets kept apart are the first level's sums scanned: a level above it even
            // where one block holds everything.
            if blocks == 1 && (levels.len() > 1 || finish == Finish::InPlace) {
                break;
            }
            size = Size {
                div: SCAN_BLOCK,
                ..Size::of(Count::Live(derived.n), cap)
            };
            cap = blocks;
        }
        ScanPlan {
            levels,
            finish,
            buffers,
        }
    }

    /// Records `plan` into `pass`.
    pub(crate) fn encode(&self, pass: &mut wgpu::ComputePass<'_>, live: &Live, plan: &ScanPlan) {
        for level in &plan.levels {
            live.dispatch(
                pass,
                &self.scan_blocks,
                &[(&level.bind_group, &[])],
                level.args,
            );
        }
        // Each level's offsets go back into the level below, down to the data or, where
        // they are kept apart, to the first level's sums.
        let lowest = match plan.finish {
            Finish::InPlace => 0,
            Finish::Apart => 1,
        };
        for level in plan.levels[lowest..].iter().rev().skip(1) {
            live.dispatch(
                pass,
                &self.add_sums,
                &[(&level.bind_group, &[])],
                level.args,
            );
        }
    }
}

/// The radix-sort kernels of one shape: a pass reading a pair of buffers (the first) and one
/// reading the texture the pass before wrote (`sort_buffers.wgsl`, `sort_texture.wgsl`).
pub(crate) struct RadixSort {
    shape: KernelShape,
    from_buffers: SortKernels,
    from_texture: SortKernels,
}

/// The two kernels of a pass over one kind of input, and their layout.
struct SortKernels {
    layout: wgpu::BindGroupLayout,
    histogram: Kernel,
    scatter: Kernel,
}

impl SortKernels {
    /// Compiles `sort.wgsl` and `shape`'s kernels after `input` (the prelude of `key_in` and
    /// `pair_in`) over `input_bindings` (below 2).
    fn new(
        gpu: &Gpu,
        shape: KernelShape,
        label: &str,
        input: &str,
        input_bindings: &[wgpu::BindGroupLayoutEntry],
    ) -> SortKernels {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(
                    format!(
                        "const HISTOGRAM_BLOCKS: u32 = {HISTOGRAM_BLOCKS}u;\n\
                         const RUN_GROUP: u32 = {RUN_GROUP}u;\n\
                         const SORT_BLOCK: u32 = {}u;\n\
                         const SCAN_BLOCK: u32 = {SCAN_BLOCK}u;\n\
                         const TEXELS_ACROSS: u32 = {TEXELS_ACROSS}u;\n{}{input}{}{}",
                        sort_block(shape),
                        include_str!("texel.wgsl"),
                        include_str!("sort.wgsl"),
                        sort_kernels(shape)
                    )
                    .into(),
                ),
            });
        let mut entries = input_bindings.to_vec();
        entries.extend([
            texels_out(2, PAIRS),
            storage(3, false),
            storage(4, true),
            uniform(5),
            storage(6, true),
        ]);
        let layout = layout(gpu, &entries);
        SortKernels {
            histogram: Kernel::new(gpu, &module, "histogram", &[&layout]),
            scatter: Kernel::new(gpu, &module, "scatter", &[&layout]),
            layout,
        }
    }
}

/// A sort of up to `capacity` pairs into two textures of (key, value) texels, ping-pong: pass
/// `k` reads texture `(k + 1) % 2` (pass 0 the buffers instead, where it starts from buffers)
/// and writes texture `k % 2` ([`SortPlan::result`]).
pub(crate) struct SortPlan {
    /// Per 8-bit pass: its kernels' bind group (input, output, digits, live sizes and the
    /// digit shift).
    passes: Vec<wgpu::BindGroup>,
    /// Whether pass 0 reads buffers.
    from_buffers: bool,
    /// Where the workgroups of `histogram` and of `scatter` are.
    histogram_args: u64,
    scatter_args: u64,
    digits_scan: ScanPlan,
    _buffers: Vec<wgpu::Buffer>,
}

impl SortPlan {
    /// Which of the two textures holds the pairs sorted by `passes` passes.
    pub(crate) fn result(passes: u32) -> usize {
        (passes as usize + 1) % 2
    }
}

/// Where a sort's pairs start.
#[derive(Clone, Copy)]
pub(crate) enum SortInput<'a> {
    /// Two buffers, keys and values.
    Buffers(&'a wgpu::Buffer, &'a wgpu::Buffer),
    /// The second of the sort's textures, a (key, value) texel each.
    Texture,
}

impl RadixSort {
    /// Compiles the sort kernels of `shape`.
    pub(crate) fn new(gpu: &Gpu, shape: KernelShape) -> RadixSort {
        RadixSort {
            shape,
            from_buffers: SortKernels::new(
                gpu,
                shape,
                "radix sort from buffers",
                include_str!("sort_buffers.wgsl"),
                &[storage(0, true), storage(1, true)],
            ),
            from_texture: SortKernels::new(
                gpu,
                shape,
                "radix sort from a texture",
                include_str!("sort_texture.wgsl"),
                &[texels_in(1, PAIRS)],
            ),
        }
    }

    /// A sort of the first `live[count_slot]` (at most `capacity`) pairs in `input` into
    /// `textures` (rows of [`PAIRS`] texels holding `capacity`) over up to `passes` 8-bit digits
    /// from the lowest, its sizes derived in `builder`'s current stage.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn plan(
        &self,
        gpu: &Gpu,
        scan: &Scan,
        live: &Live,
        builder: &mut LiveBuilder,
        input: SortInput<'_>,
        textures: [&wgpu::Texture; 2],
        capacity: u32,
        count_slot: u32,
        passes: u32,
    ) -> SortPlan {
        let capacity = capacity.max(1);
        let block = sort_block(self.shape);
        let digit_capacity = digit_words(self.shape, capacity);
        let pairs = Size::of(Count::Live(count_slot), capacity);
        let (histogram_pairs, scatter_pairs) = pairs_per_group(self.shape);
        let histogram_args = builder.derive(pairs.dispatched(histogram_pairs)).args;
        let scatter_args = builder.derive(pairs.dispatched(scatter_pairs)).args;
        let digit_count = builder.derive(Size {
            div: block,
            mul: 256,
            ..Size::of(Count::Live(count_slot), capacity)
        });
        let digits = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radix digits"),
            size: digit_capacity * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let digits_scan = scan.plan(
            gpu,
            live,
            builder,
            &digits,
            u32::try_from(digit_capacity).expect("a sort's digit counts fit its u32 sizes"),
            digit_count.n,
            Finish::Apart,
        );
        let views = textures.map(|t| t.create_view(&wgpu::TextureViewDescriptor::default()));
        let mut buffers = Vec::new();
        let passes = (0..passes as usize)
            .map(|k| {
                let params = uniform_buffer(gpu, &[8 * k as u32, count_slot, 0, 0]);
                let rest = [
                    wgpu::BindingResource::TextureView(&views[k % 2]),
                    digits.as_entire_binding(),
                    live.buffer.as_entire_binding(),
                    params.as_entire_binding(),
                    digits_scan.block_offsets().as_entire_binding(),
                ];
                let bind_group = match input {
                    SortInput::Buffers(keys, values) if k == 0 => {
                        let mut resources =
                            vec![keys.as_entire_binding(), values.as_entire_binding()];
                        resources.extend(rest);
                        bind(gpu, &self.from_buffers.layout, &resources)
                    }
                    _ => {
                        let mut resources =
                            vec![wgpu::BindingResource::TextureView(&views[(k + 1) % 2])];
                        resources.extend(rest);
                        bind_from(gpu, &self.from_texture.layout, 1, &resources)
                    }
                };
                buffers.push(params);
                bind_group
            })
            .collect();
        buffers.push(digits);
        SortPlan {
            passes,
            from_buffers: matches!(input, SortInput::Buffers(..)),
            histogram_args,
            scatter_args,
            digits_scan,
            _buffers: buffers,
        }
    }

    /// Records the first `passes` passes of `plan` into `pass`.
    pub(crate) fn encode(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        scan: &Scan,
        live: &Live,
        plan: &SortPlan,
        passes: usize,
    ) {
        for (k, group) in plan.passes[..passes].iter().enumerate() {
            let kernels = if k == 0 && plan.from_buffers {
                &self.from_buffers
            } else {
                &self.from_texture
            };
            live.dispatch(
                pass,
                &kernels.histogram,
                &[(group, &[])],
                plan.histogram_args,
            );
            scan.encode(pass, live, &plan.digits_scan);
            live.dispatch(pass, &kernels.scatter, &[(group, &[])], plan.scatter_args);
        }
    }
}

#[cfg(test)]
mod tests {
    //! The scan and the sort on the GPU against the standard library, at sizes on both sides
    //! of their block edges and of several scan levels.
    use super::super::kernel::{texel_rows, texel_rows_texture};
    use super::*;
    use rand::{Rng, SeedableRng};

    const SIZES: [u32; 10] = [1, 255, 256, 257, 1025, 4095, 4096, 4097, 70_000, 300_001];

    fn gpu() -> Option<std::sync::Arc<Gpu>> {
        match Gpu::shared(false) {
            Ok(g) => Some(g),
            Err(e) if std::env::var_os("SAGE3D_REQUIRE_GPU").is_some() => {
                panic!("SAGE3D_REQUIRE_GPU is set and no GPU adapter opened: {e}")
            }
            Err(e) => {
                eprintln!("no GPU adapter, GPU test not run: {e}");
                None
            }
        }
    }

    fn words(gpu: &Gpu, data: &[u32]) -> wgpu::Buffer {
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: (data.len() * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(data));
        buffer
    }

    /// Runs `record` in one compute pass after writing `n` to live slot 0, then reads back
    /// each of `outputs`.
    fn run(
        gpu: &Gpu,
        live: &Live,
        n: u32,
        record: impl FnOnce(&mut wgpu::ComputePass<'_>),
        outputs: &[&wgpu::Buffer],
    ) -> Vec<Vec<u32>> {
        gpu.queue
            .write_buffer(&live.buffer, 0, bytemuck::bytes_of(&n));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            record(&mut pass);
        }
        let staging: Vec<wgpu::Buffer> = outputs
            .iter()
            .map(|b| {
                let s = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: None,
                    size: b.size(),
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                encoder.copy_buffer_to_buffer(b, 0, &s, 0, b.size());
                s
            })
            .collect();
        gpu.queue.submit([encoder.finish()]);
        for s in &staging {
            s.map_async(wgpu::MapMode::Read, .., |r| r.expect("mapped"));
        }
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("GPU work finished");
        staging
            .iter()
            .map(|s| {
                let view = s.slice(..).get_mapped_range().expect("mapped");
                bytemuck::cast_slice(&view).to_vec()
            })
            .collect()
    }

    #[test]
    fn the_scan_is_the_exclusive_prefix_sum_in_place_or_with_its_block_offsets_apart() {
        let Some(gpu) = gpu() else { return };
        let live = Live::new(&gpu);
        let scan = Scan::new(&gpu);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        // And past SCAN_BLOCK² elements: three levels.
        for n in SIZES.into_iter().chain([SCAN_BLOCK * SCAN_BLOCK + 1]) {
            // Room past the live count: the scan must leave it alone.
            let data: Vec<u32> = (0..n + 300).map(|_| rng.random_range(0..9)).collect();
            let mut want = data.clone();
            let mut total = 0;
            for w in &mut want[..n as usize] {
                (*w, total) = (total, total + *w);
            }
            for finish in [Finish::InPlace, Finish::Apart] {
                let buffer = words(&gpu, &data);
                let mut builder = LiveBuilder::new(1);
                builder.stage();
                let plan = scan.plan(&gpu, &live, &mut builder, &buffer, n + 300, 0, finish);
                let programs = live.programs(&gpu, &builder, &[&buffer]);
                let mut out = run(
                    &gpu,
                    &live,
                    n,
                    |pass| {
                        live.encode(pass, &programs, 0);
                        scan.encode(pass, &live, &plan);
                    },
                    &[&buffer, plan.block_offsets()],
                );
                if finish == Finish::Apart {
                    let offsets = out.pop().unwrap();
                    for (i, w) in out[0][..n as usize].iter_mut().enumerate() {
                        *w += offsets[i / SCAN_BLOCK as usize];
                    }
                }
                assert_eq!(out[0], want, "{n} elements, {finish:?}");
            }
        }
    }

    /// The first `n` texels of `texture` (of [`PAIRS`]), copied out.
    fn pairs_of(gpu: &Gpu, texture: &wgpu::Texture, n: u32) -> Vec<(u32, u32)> {
        let size = texture.size();
        let row_bytes = size.width * 8;
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: u64::from(row_bytes * size.height),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row_bytes),
                    rows_per_image: None,
                },
            },
            size,
        );
        gpu.queue.submit([encoder.finish()]);
        staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("mapped"));
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("GPU work finished");
        let view = staging.slice(..).get_mapped_range().expect("mapped");
        let words: &[u32] = bytemuck::cast_slice(&view);
        words
            .chunks_exact(2)
            .take(n as usize)
            .map(|p| (p[0], p[1]))
            .collect()
    }

    #[test]
    fn the_sort_shaped_for_hardware_is_stable_by_key_with_every_pass_count() {
        sorts_stably_by_key(KernelShape::Lanes);
    }

    #[test]
    fn the_sort_shaped_for_cpu_drivers_is_stable_by_key_with_every_pass_count() {
        sorts_stably_by_key(KernelShape::Runs);
    }

    /// Sorts with `shape`'s kernels, from either input, and checks against the standard
    /// library's stable sort.
    fn sorts_stably_by_key(shape: KernelShape) {
        let Some(gpu) = gpu() else { return };
        let live = Live::new(&gpu);
        let scan = Scan::new(&gpu);
        let sort = RadixSort::new(&gpu, shape);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        // Every pass count (ending in either texture), from buffers and from the second
        // texture, and one pass over SCAN_BLOCK² + 1 pairs: as many digits in blocks of 256
        // (three levels of the digits' scan, its block offsets apart), a quarter in blocks
        // of 1,024 (two).
        let cases = SIZES.into_iter().zip([4, 1, 2, 3].into_iter().cycle());
        for (i, (n, passes)) in cases.chain([(SCAN_BLOCK * SCAN_BLOCK + 1, 1)]).enumerate() {
            // Every other size with few distinct keys, so stability is tested.
            let keys: Vec<u32> = (0..n)
                .map(|_| match i % 2 {
                    0 => rng.random(),
                    _ => rng.random_range(0..5) << (8 * passes - 4),
                })
                .collect();
            let values: Vec<u32> = (0..n).collect();
            let (k, v) = (words(&gpu, &keys), words(&gpu, &values));
            let textures = ["pairs", "pairs 2"].map(|l| {
                gpu.device.create_texture(&texel_rows_texture(
                    l,
                    PAIRS,
                    texel_rows(n),
                    wgpu::TextureUsages::STORAGE_BINDING
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_SRC
                        | wgpu::TextureUsages::COPY_DST,
                ))
            });
            // Every third size starts from the second texture, as the tile sort does.
            let input = if i % 3 == 1 {
                let texels: Vec<u32> = keys
                    .iter()
                    .zip(&values)
                    .flat_map(|(&k, &v)| [k, v])
                    .collect();
                let mut bytes: Vec<u8> = bytemuck::cast_slice(&texels).to_vec();
                bytes.resize(
                    textures[1].size().height as usize * TEXELS_ACROSS as usize * 8,
                    0,
                );
                gpu.queue.write_texture(
                    textures[1].as_image_copy(),
                    &bytes,
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(TEXELS_ACROSS * 8),
                        rows_per_image: None,
                    },
                    textures[1].size(),
                );
                SortInput::Texture
            } else {
                SortInput::Buffers(&k, &v)
            };
            let mut builder = LiveBuilder::new(1);
            builder.stage();
            let plan = sort.plan(
                &gpu,
                &scan,
                &live,
                &mut builder,
                input,
                textures.each_ref(),
                n,
                0,
                passes,
            );
            let programs = live.programs(&gpu, &builder, &[&k]);
            run(
                &gpu,
                &live,
                n,
                |pass| {
                    live.encode(pass, &programs, 0);
                    sort.encode(pass, &scan, &live, &plan, passes as usize);
                },
                &[],
            );
            let got = pairs_of(&gpu, &textures[SortPlan::result(passes)], n);
            let digits = (1u64 << (8 * passes)) - 1;
            let mut want: Vec<(u32, u32)> = keys.into_iter().zip(values).collect();
            want.sort_by_key(|p| u64::from(p.0) & digits);
            assert!(
                got == want,
                "{n} pairs, {passes} passes: not sorted stably by key"
            );
        }
    }
}
