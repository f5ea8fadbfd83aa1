//! Small helpers over wgpu for compute kernels: bind group layouts, bind groups, pipelines and
//! dispatches over grids larger than one dimension allows.

use super::Gpu;
use wgpu::util::DeviceExt;

/// A storage buffer binding.
pub(crate) fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A uniform buffer binding.
pub(crate) fn uniform(binding: u32) -> wgpu::BindGroupLayoutEntry {
    uniform_entry(binding, false)
}

/// A uniform buffer binding of 16 bytes whose offset is given at each dispatch.
pub(crate) fn dynamic_uniform(binding: u32) -> wgpu::BindGroupLayoutEntry {
    uniform_entry(binding, true)
}

fn uniform_entry(binding: u32, dynamic: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: dynamic.then(|| wgpu::BufferSize::new(16)).flatten(),
        },
        count: None,
    }
}

/// Threads per workgroup of the kernels shaped for CPU drivers ([`KernelShape::Runs`]): a
/// vector of lanes under lavapipe on AVX2, so even a little work makes several workgroups for
/// its threads to share.
///
/// [`KernelShape::Runs`]: crate::passes::KernelShape::Runs
pub(crate) const RUN_GROUP: u32 = 8;

/// Texels across a row of every texture the kernels index by a flat number (`TEXELS_ACROSS`
/// and `texel` in `texel.wgsl`, which the splat and sort kernels include): rows of 64 KB, and at least 8,192 rows (33.5 million texels)
/// on every WebGPU adapter.
pub(crate) const TEXELS_ACROSS: u32 = 4096;

/// Rows of a texture of `n` texels in rows of [`TEXELS_ACROSS`] (at least one).
pub(crate) fn texel_rows(n: u32) -> u32 {
    n.div_ceil(TEXELS_ACROSS).max(1)
}

/// Bytes of a texture of `n` texels of `format` in whole rows of [`TEXELS_ACROSS`].
pub(crate) fn texel_bytes(n: u32, format: wgpu::TextureFormat) -> u64 {
    let texel = format.block_copy_size(None).unwrap_or(16);
    u64::from(texel_rows(n)) * u64::from(TEXELS_ACROSS) * u64::from(texel)
}

/// Four floats a texel.
pub(crate) const FLOATS: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Four words a texel.
pub(crate) const WORDS: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

/// Two words a texel: a (key, value) pair of the radix sort.
pub(crate) const PAIRS: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Uint;

/// A write-only storage texture binding of `format` ([`FLOATS`], [`WORDS`] or [`PAIRS`]:
/// every WebGPU adapter stores each from a compute kernel).
pub(crate) fn texels_out(binding: u32, format: wgpu::TextureFormat) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// A texture binding of `format` ([`FLOATS`], [`WORDS`] or [`PAIRS`]), read with
/// `textureLoad` (never filtered).
pub(crate) fn texels_in(binding: u32, format: wgpu::TextureFormat) -> wgpu::BindGroupLayoutEntry {
    let sample_type = if format == FLOATS {
        wgpu::TextureSampleType::Float { filterable: false }
    } else {
        wgpu::TextureSampleType::Uint
    };
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// The descriptor of a texture of `rows` rows of [`TEXELS_ACROSS`] texels of `format`, for
/// `usage`.
pub(crate) fn texel_rows_texture<'a>(
    label: &'a str,
    format: wgpu::TextureFormat,
    rows: u32,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'a> {
    wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: TEXELS_ACROSS,
            height: rows,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    }
}

/// A texture of `rows` rows of texels of `format` that kernels write and later ones read.
pub(crate) fn texels(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    rows: u32,
) -> wgpu::Texture {
    gpu.device.create_texture(&texel_rows_texture(
        label,
        format,
        rows,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
    ))
}

/// A bind group layout of `entries`.
pub(crate) fn layout(gpu: &Gpu, entries: &[wgpu::BindGroupLayoutEntry]) -> wgpu::BindGroupLayout {
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: None,
            entries,
        })
}

/// A bind group of `layout` with `resources` at bindings 0, 1, …
pub(crate) fn bind(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    resources: &[wgpu::BindingResource<'_>],
) -> wgpu::BindGroup {
    bind_from(gpu, layout, 0, resources)
}

/// A bind group of `layout` with `resources` at bindings `first`, `first` + 1, …
pub(crate) fn bind_from(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    first: u32,
    resources: &[wgpu::BindingResource<'_>],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
        .iter()
        .enumerate()
        .map(|(i, r)| wgpu::BindGroupEntry {
            binding: first + i as u32,
            resource: r.clone(),
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout,
        entries: &entries,
    })
}

/// A uniform buffer holding `words`.
pub(crate) fn uniform_buffer(gpu: &Gpu, words: &[u32]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(words),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// One entry point of a shader module, as a compute pipeline.
pub(crate) struct Kernel {
    pipeline: wgpu::ComputePipeline,
}

/// The most workgroups one dispatch dimension takes (the WebGPU default limit).
const MAX_GROUPS: u32 = 65_535;

impl Kernel {
    /// The pipeline of `entry` in `module` over bind groups of `layouts`.
    pub(crate) fn new(
        gpu: &Gpu,
        module: &wgpu::ShaderModule,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> Kernel {
        let layouts: Vec<Option<&wgpu::BindGroupLayout>> =
            layouts.iter().map(|l| Some(*l)).collect();
        let pipeline_layout = gpu
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(entry),
                bind_group_layouts: &layouts,
                immediate_size: 0,
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            });
        Kernel { pipeline }
    }

    /// Dispatches `workgroups` linear workgroups (folded into a 2-D grid when more than one
    /// dimension takes; the shaders rebuild the linear index and skip the excess).
    pub(crate) fn run(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        groups: &[&wgpu::BindGroup],
        workgroups: u32,
    ) {
        let x = workgroups.clamp(1, MAX_GROUPS);
        self.run_grid(
            pass,
            &groups.iter().map(|g| (*g, &[][..])).collect::<Vec<_>>(),
            (x, workgroups.max(1).div_ceil(x), 1),
        );
    }

    /// Dispatches a `grid` of workgroups with bind groups and their dynamic offsets.
    pub(crate) fn run_grid(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        groups: &[(&wgpu::BindGroup, &[u32])],
        grid: (u32, u32, u32),
    ) {
        self.bind(pass, groups);
        pass.dispatch_workgroups(grid.0, grid.1, grid.2);
    }

    /// Sets the pipeline and the bind groups with their dynamic offsets, for a dispatch.
    pub(crate) fn bind(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        groups: &[(&wgpu::BindGroup, &[u32])],
    ) {
        pass.set_pipeline(&self.pipeline);
        for (i, (group, offsets)) in groups.iter().enumerate() {
            pass.set_bind_group(i as u32, *group, offsets);
        }
    }
}

/// Linear workgroups of 256 threads for `threads` threads, as a 2-D grid.
pub(crate) fn threads_grid(threads: u32) -> (u32, u32, u32) {
    let groups = threads.div_ceil(256).max(1);
    let x = groups.min(MAX_GROUPS);
    (x, groups.div_ceil(x), 1)
}
