//! The two GPU primitives the binning needs: an exclusive prefix sum ([`Scan`]) and a stable
//! radix sort of (key, value) pairs ([`RadixSort`]), each recorded into a compute pass over
//! buffers of a fixed capacity, with the live count read on the GPU (`scan.wgsl`, `sort.wgsl`).

use super::Gpu;
use super::kernel::{Kernel, bind, layout, storage, uniform, uniform_buffer};

/// Elements one workgroup of `scan_blocks` covers.
const SCAN_BLOCK: u32 = 1024;
/// Pairs per radix-sort block (one per thread).
const SORT_BLOCK: u32 = 256;

/// The exclusive prefix sum kernels.
pub(crate) struct Scan {
    layout: wgpu::BindGroupLayout,
    scan_blocks: Kernel,
    add_sums: Kernel,
}

/// One level of a scan: its bind group and how many blocks it has.
struct ScanLevel {
    bind_group: wgpu::BindGroup,
    blocks: u32,
}

/// A scan of one buffer of fixed length: the levels of block sums, bottom first.
pub(crate) struct ScanPlan {
    levels: Vec<ScanLevel>,
    /// Keeps the block-sum buffers alive.
    _sums: Vec<wgpu::Buffer>,
}

impl Scan {
    /// Compiles the scan kernels.
    pub(crate) fn new(gpu: &Gpu) -> Scan {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("scan"),
                source: wgpu::ShaderSource::Wgsl(include_str!("scan.wgsl").into()),
            });
        let layout = layout(
            gpu,
            &[storage(0, false), storage(1, false), uniform(2, false)],
        );
        Scan {
            scan_blocks: Kernel::new(gpu, &module, "scan_blocks", &[&layout]),
            add_sums: Kernel::new(gpu, &module, "add_sums", &[&layout]),
            layout,
        }
    }

    /// A scan of the first `n` words of `data`, with the block-sum buffers it needs.
    pub(crate) fn plan(&self, gpu: &Gpu, data: &wgpu::Buffer, n: u32) -> ScanPlan {
        let mut levels = Vec::new();
        let mut sums_buffers: Vec<wgpu::Buffer> = Vec::new();
        let mut len = n.max(1);
        loop {
            let blocks = len.div_ceil(SCAN_BLOCK);
            let sums = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("scan sums"),
                size: u64::from(blocks.max(1)) * 4,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            });
            let params = uniform_buffer(gpu, &[len, 0, 0, 0]);
            let input = sums_buffers.last().unwrap_or(data);
            let bind_group = bind(
                gpu,
                &self.layout,
                &[
                    input.as_entire_binding(),
                    sums.as_entire_binding(),
                    params.as_entire_binding(),
                ],
            );
            levels.push(ScanLevel { bind_group, blocks });
            sums_buffers.push(sums);
            if blocks == 1 {
                break;
            }
            len = blocks;
        }
        ScanPlan {
            levels,
            _sums: sums_buffers,
        }
    }

    /// Records `plan` into `pass`.
    pub(crate) fn encode(&self, pass: &mut wgpu::ComputePass<'_>, plan: &ScanPlan) {
        for level in &plan.levels {
            self.scan_blocks
                .run(pass, &[&level.bind_group], level.blocks);
        }
        for level in plan.levels.iter().rev().skip(1) {
            self.add_sums.run(pass, &[&level.bind_group], level.blocks);
        }
    }
}

/// The radix-sort kernels.
pub(crate) struct RadixSort {
    layout: wgpu::BindGroupLayout,
    histogram: Kernel,
    scatter: Kernel,
}

/// One 8-bit pass of a sort: its bind group (input, output, digits, count, digit shift).
struct SortPass {
    bind_group: wgpu::BindGroup,
}

/// A sort of up to `capacity` pairs between two pairs of buffers, ping-pong: pass `k` reads
/// the first pair when `k` is even. After an odd number of passes the result is in the second.
pub(crate) struct SortPlan {
    passes: Vec<SortPass>,
    blocks: u32,
    digits_scan: ScanPlan,
    _buffers: Vec<wgpu::Buffer>,
}

/// Two (keys, values) buffers.
pub(crate) type Pairs<'a> = (&'a wgpu::Buffer, &'a wgpu::Buffer);

impl RadixSort {
    /// Compiles the sort kernels.
    pub(crate) fn new(gpu: &Gpu) -> RadixSort {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("radix sort"),
                source: wgpu::ShaderSource::Wgsl(include_str!("sort.wgsl").into()),
            });
        let layout = layout(
            gpu,
            &[
                storage(0, true),
                storage(1, true),
                storage(2, false),
                storage(3, false),
                storage(4, false),
                storage(5, true),
                uniform(6, false),
            ],
        );
        RadixSort {
            histogram: Kernel::new(gpu, &module, "histogram", &[&layout]),
            scatter: Kernel::new(gpu, &module, "scatter", &[&layout]),
            layout,
        }
    }

    /// A sort of up to `capacity` pairs in `first` (ping-pong with `second`) over `passes`
    /// 8-bit digits from the lowest; the live count is word `count_at` of `counts`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn plan(
        &self,
        gpu: &Gpu,
        scan: &Scan,
        first: Pairs<'_>,
        second: Pairs<'_>,
        capacity: u32,
        counts: &wgpu::Buffer,
        count_at: u32,
        passes: u32,
    ) -> SortPlan {
        let blocks = capacity.max(1).div_ceil(SORT_BLOCK);
        let digits = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radix digits"),
            size: u64::from(blocks) * 256 * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let digits_scan = scan.plan(gpu, &digits, blocks * 256);
        let mut buffers = Vec::new();
        let passes = (0..passes)
            .map(|k| {
                let (input, output) = if k % 2 == 0 {
                    (first, second)
                } else {
                    (second, first)
                };
                let params = uniform_buffer(gpu, &[8 * k, blocks, capacity, count_at]);
                let bind_group = bind(
                    gpu,
                    &self.layout,
                    &[
                        input.0.as_entire_binding(),
                        input.1.as_entire_binding(),
                        output.0.as_entire_binding(),
                        output.1.as_entire_binding(),
                        digits.as_entire_binding(),
                        counts.as_entire_binding(),
                        params.as_entire_binding(),
                    ],
                );
                buffers.push(params);
                SortPass { bind_group }
            })
            .collect();
        buffers.push(digits);
        SortPlan {
            passes,
            blocks,
            digits_scan,
            _buffers: buffers,
        }
    }

    /// Records the first `passes` passes of `plan` into `pass`.
    pub(crate) fn encode(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        scan: &Scan,
        plan: &SortPlan,
        passes: usize,
    ) {
        for p in &plan.passes[..passes] {
            self.histogram.run(pass, &[&p.bind_group], plan.blocks);
            scan.encode(pass, &plan.digits_scan);
            self.scatter.run(pass, &[&p.bind_group], plan.blocks);
        }
    }
}
