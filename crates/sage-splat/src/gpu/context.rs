//! The process's GPU: the adapter wgpu found, its device and queue, and the errors it reported.

use sage_core::{Error, Result};
use std::sync::{Arc, Mutex, OnceLock};

/// A wgpu device and queue on the adapter [`Gpu::open`] chose.
pub struct Gpu {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    /// The first error the device reported outside an error scope (wgpu's default would panic).
    fault: Arc<Mutex<Option<String>>>,
}

/// The features that time the passes of a batch (`GpuRenderer::time_passes`).
const TIMESTAMPS: wgpu::Features =
    wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES);

/// The feature that times the read-back copy too, between passes.
const ENCODER_TIMESTAMPS: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;

/// Names a user may set to pick an adapter by (part of) its name on a machine with several.
pub(crate) const ADAPTER_VARIABLE: &str = "SAGE3D_GPU_ADAPTER";

impl Gpu {
    /// The process-wide GPU, opened on first use (one per `hardware_only` choice).
    ///
    /// # Errors
    ///
    /// As [`Gpu::open`]; the error is remembered, so a machine without a GPU is asked once.
    pub fn shared(hardware_only: bool) -> Result<Arc<Gpu>> {
        static ANY: OnceLock<std::result::Result<Arc<Gpu>, String>> = OnceLock::new();
        static HARDWARE: OnceLock<std::result::Result<Arc<Gpu>, String>> = OnceLock::new();
        let cell = if hardware_only { &HARDWARE } else { &ANY };
        cell.get_or_init(|| {
            Gpu::open(hardware_only)
                .map(Arc::new)
                .map_err(|e| e.message().to_string())
        })
        .clone()
        .map_err(Error::invalid)
    }

    /// Opens the best adapter over Vulkan, Metal or DX12: a discrete GPU before an integrated
    /// one before a virtual one before a software rasteriser (which `hardware_only` refuses).
    /// `SAGE3D_GPU_ADAPTER`, when set, keeps only adapters whose name contains it.
    ///
    /// # Errors
    ///
    /// No adapter (naming what to install), or a device the adapter would not create.
    pub fn open(hardware_only: bool) -> Result<Gpu> {
        // The workgroup counts of every indirect dispatch come from `derive` (`live.wgsl`),
        // which keeps each under the least per-dimension limit a device may have, so wgpu's
        // own check of them (a dispatch of its own before each one, doubling a frame's
        // dispatches) is left out; not on DX12, where `num_workgroups` in the kernels needs it.
        let checked = wgpu::InstanceFlags::default();
        let instances = [
            (
                wgpu::Backends::VULKAN | wgpu::Backends::METAL,
                checked - wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL,
            ),
            (wgpu::Backends::DX12, checked),
        ]
        .map(|(backends, flags)| {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            desc.flags = flags;
            wgpu::Instance::new(desc)
        });
        let wanted = std::env::var(ADAPTER_VARIABLE).ok();
        let all: Vec<wgpu::Adapter> = instances
            .iter()
            .flat_map(|i| pollster::block_on(i.enumerate_adapters(wgpu::Backends::all())))
            .collect();
        let seen: Vec<String> = all
            .iter()
            .map(|a| {
                let info = a.get_info();
                format!("{} ({:?})", info.name, info.device_type)
            })
            .collect();
        let mut adapters: Vec<wgpu::Adapter> = all
            .into_iter()
            .filter(|a| {
                let info = a.get_info();
                (!hardware_only || info.device_type != wgpu::DeviceType::Cpu)
                    && wanted.as_deref().is_none_or(|w| info.name.contains(w))
            })
            .collect();
        adapters.sort_by_key(|a| rank(a.get_info().device_type));
        let Some(adapter) = adapters.into_iter().next() else {
            let what = if hardware_only {
                "no hardware GPU adapter"
            } else {
                "no GPU adapter"
            };
            let filter = wanted
                .map(|w| format!(" whose name contains {w:?} ({ADAPTER_VARIABLE})"))
                .unwrap_or_default();
            return Err(Error::invalid(if seen.is_empty() {
                format!(
                    "{what}{filter}: wgpu found none over Vulkan, Metal or DX12 (on Linux: a \
                     Vulkan driver and the loader libvulkan1; Mesa's software driver is the \
                     package mesa-vulkan-drivers)"
                )
            } else {
                format!("{what}{filter}: wgpu found only {}", seen.join(", "))
            }));
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("sage3d"),
            // Timestamps inside passes (and between them), where the adapter has them, time the
            // passes (and the read-back copy) on request.
            required_features: adapter.features() & TIMESTAMPS.union(ENCODER_TIMESTAMPS),
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::invalid(format!("GPU {}: cannot open a device: {e}", info.name)))?;
        let fault: Arc<Mutex<Option<String>>> = Arc::default();
        let sink = fault.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert_with(|| e.to_string());
        }));
        Ok(Gpu {
            device,
            queue,
            info,
            fault,
        })
    }

    /// The adapter in words: `NVIDIA H100 (Vulkan, discrete)`.
    pub fn describe(&self) -> String {
        let kind = match self.info.device_type {
            wgpu::DeviceType::DiscreteGpu => "discrete",
            wgpu::DeviceType::IntegratedGpu => "integrated",
            wgpu::DeviceType::VirtualGpu => "virtual",
            wgpu::DeviceType::Cpu => "software",
            wgpu::DeviceType::Other => "other",
        };
        format!("{} ({:?}, {kind})", self.info.name, self.info.backend)
    }

    /// True for a software rasteriser (lavapipe, WARP).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// True when the device writes timestamps between dispatches (to time the passes).
    pub fn has_timestamps(&self) -> bool {
        self.device.features().contains(TIMESTAMPS)
    }

    /// True when the device also writes timestamps between passes (to time the read-back copy).
    pub fn has_encoder_timestamps(&self) -> bool {
        self.has_timestamps() && self.device.features().contains(ENCODER_TIMESTAMPS)
    }

    /// The device's limits.
    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    /// The largest storage buffer one binding may see, in bytes.
    pub(crate) fn largest_binding(&self) -> u64 {
        let limits = self.device.limits();
        limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
    }

    /// The first error the device reported, as an error naming the adapter.
    pub(crate) fn check(&self) -> Result<()> {
        let slot = self.fault.lock().unwrap_or_else(|p| p.into_inner());
        match slot.as_ref() {
            Some(e) => Err(Error::invalid(format!("GPU {}: {e}", self.info.name))),
            None => Ok(()),
        }
    }
}

/// Preference order of adapter kinds (lower first).
fn rank(kind: wgpu::DeviceType) -> u8 {
    match kind {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}
