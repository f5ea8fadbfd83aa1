//! Sizes known only on the GPU ("live" counts): a small buffer of slots that kernels read
//! their element counts from and indirect dispatches read their workgroups from, and the
//! programs (`live.wgsl`) that fill it from the counts a pass has just produced. So every pass
//! after the chunk culling runs over what is visible, not over what the buffers could hold.

use super::Gpu;
use super::kernel::{Kernel, bind, layout, storage, uniform, uniform_buffer};

/// Words of the live buffer: every slot a workspace's plans allocate fits (a few hundred).
pub(crate) const LIVE_WORDS: u32 = 1024;
/// A slot not written.
const NONE: u32 = u32::MAX;

/// Where a derivation reads its count.
#[derive(Clone, Copy)]
pub(crate) enum Count {
    /// A slot of the live buffer.
    Live(u32),
    /// A word of the stage's source buffer at the index held by a live slot (the total an
    /// exclusive scan of that many elements leaves after them).
    SourceAt(u32),
}

/// One record of a derive program (`Derive` in `live.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Derive {
    kind: u32,
    src: u32,
    add: u32,
    div: u32,
    mul: u32,
    cap: u32,
    out: u32,
    peak: u32,
    total: u32,
    args: u32,
    per_group: u32,
    pad: u32,
}

/// A size to derive: `ceil(min(count + add, cap) / div) * mul`, with the workgroups of
/// `per_group` elements each when something is dispatched over it.
#[derive(Clone, Copy)]
pub(crate) struct Size {
    pub(crate) count: Count,
    pub(crate) add: u32,
    pub(crate) div: u32,
    pub(crate) mul: u32,
    pub(crate) cap: u32,
    pub(crate) per_group: Option<u32>,
    /// Also keep the count itself, before clamping, as its largest and its sum over the
    /// times the stage runs in a batch (the host checks the largest against the buffers).
    pub(crate) keep_raw: bool,
}

impl Size {
    /// `count` (at most `cap`) as it is.
    pub(crate) fn of(count: Count, cap: u32) -> Size {
        Size {
            count,
            add: 0,
            div: 1,
            mul: 1,
            cap,
            per_group: None,
            keep_raw: false,
        }
    }

    /// With workgroups of `per_group` elements.
    pub(crate) fn dispatched(mut self, per_group: u32) -> Size {
        self.per_group = Some(per_group);
        self
    }
}

/// The slots of a derived size.
#[derive(Clone, Copy)]
pub(crate) struct Derived {
    /// The size.
    pub(crate) n: u32,
    /// The largest count before clamping over the batch's runs of the stage (when kept).
    pub(crate) peak: u32,
    /// The sum of those counts (when kept).
    pub(crate) total: u32,
    /// Byte offset of the indirect dispatch arguments (when dispatched).
    pub(crate) args: u64,
}

/// The live buffer and the derive kernel, one per renderer.
pub(crate) struct Live {
    pub(crate) buffer: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    kernel: Kernel,
}

/// Slots and derive records as a workspace's plans ask for them, in stages: a stage's records
/// run together, after the pass that produced their counts.
pub(crate) struct LiveBuilder {
    slots: u32,
    records: Vec<Derive>,
    /// Per stage: its first record.
    stages: Vec<u32>,
}

/// The derive programs of one workspace: per stage a bind group (its source buffer, its
/// records).
pub(crate) struct LivePrograms {
    stages: Vec<wgpu::BindGroup>,
    _buffers: Vec<wgpu::Buffer>,
}

impl Live {
    /// The live buffer and the derive kernel.
    pub(crate) fn new(gpu: &Gpu) -> Live {
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("live sizes"),
                source: wgpu::ShaderSource::Wgsl(include_str!("live.wgsl").into()),
            });
        let layout = layout(
            gpu,
            &[
                storage(0, false),
                storage(1, true),
                storage(2, true),
                uniform(3),
            ],
        );
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("live sizes"),
            size: u64::from(LIVE_WORDS) * 4,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Live {
            kernel: Kernel::new(gpu, &module, "derive", &[&layout]),
            buffer,
            layout,
        }
    }

    /// Builds the programs of `builder`, stage `k` reading `sources[k]`.
    pub(crate) fn programs(
        &self,
        gpu: &Gpu,
        builder: &LiveBuilder,
        sources: &[&wgpu::Buffer],
    ) -> LivePrograms {
        assert_eq!(sources.len(), builder.stages.len(), "one source per stage");
        let records = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("live programs"),
            size: (std::mem::size_of::<Derive>() * builder.records.len().max(1)) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue
            .write_buffer(&records, 0, bytemuck::cast_slice(&builder.records));
        let mut buffers = vec![records];
        let mut stages = Vec::new();
        for (k, source) in sources.iter().enumerate() {
            let first = builder.stages[k];
            let end = builder
                .stages
                .get(k + 1)
                .copied()
                .unwrap_or(builder.records.len() as u32);
            let range = uniform_buffer(gpu, &[first, end - first, 0, 0]);
            stages.push(bind(
                gpu,
                &self.layout,
                &[
                    self.buffer.as_entire_binding(),
                    source.as_entire_binding(),
                    buffers[0].as_entire_binding(),
                    range.as_entire_binding(),
                ],
            ));
            buffers.push(range);
        }
        LivePrograms {
            stages,
            _buffers: buffers,
        }
    }

    /// Records stage `k` of `programs` into `pass`.
    pub(crate) fn encode(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        programs: &LivePrograms,
        k: usize,
    ) {
        self.kernel.run(pass, &[&programs.stages[k]], 1);
    }

    /// Dispatches `kernel` over the workgroups at byte `args` of the live buffer.
    pub(crate) fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        kernel: &Kernel,
        groups: &[(&wgpu::BindGroup, &[u32])],
        args: u64,
    ) {
        kernel.bind(pass, groups);
        pass.dispatch_workgroups_indirect(&self.buffer, args);
    }
}

impl LiveBuilder {
    /// No derived slots and no stages yet; the first `fixed` slots are the host's to write.
    pub(crate) fn new(fixed: u32) -> LiveBuilder {
        LiveBuilder {
            slots: fixed,
            records: Vec::new(),
            stages: Vec::new(),
        }
    }

    /// A new slot (three words with `words = 3`).
    fn slot(&mut self, words: u32) -> u32 {
        let s = self.slots;
        self.slots += words;
        assert!(self.slots <= LIVE_WORDS, "live buffer slots exhausted");
        s
    }

    /// Starts a stage: the records derived from now on run after the pass that fills its
    /// source buffer.
    pub(crate) fn stage(&mut self) {
        self.stages.push(self.records.len() as u32);
    }

    /// Derives `size` in the current stage.
    pub(crate) fn derive(&mut self, size: Size) -> Derived {
        assert!(!self.stages.is_empty(), "derive records belong to a stage");
        let n = self.slot(1);
        let (peak, total) = if size.keep_raw {
            (self.slot(1), self.slot(1))
        } else {
            (NONE, NONE)
        };
        let args = size.per_group.map_or(NONE, |_| self.slot(3));
        let (kind, src) = match size.count {
            Count::Live(s) => (0, s),
            Count::SourceAt(s) => (1, s),
        };
        self.records.push(Derive {
            kind,
            src,
            add: size.add,
            div: size.div.max(1),
            mul: size.mul.max(1),
            cap: size.cap,
            out: n,
            peak,
            total,
            args,
            per_group: size.per_group.unwrap_or(1).max(1),
            pad: 0,
        });
        Derived {
            n,
            peak,
            total,
            args: u64::from(args) * 4,
        }
    }
}
