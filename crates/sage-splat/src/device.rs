//! Choosing the executor: the CPU tile renderer ([`Renderer`](crate::render::Renderer)) or the wgpu compute renderer
//! ([`crate::gpu::GpuRenderer`], cargo feature `gpu`). Both form the same images (SPEC §3);
//! [`Backend`] is what commands and environments hold, whichever was chosen.

use crate::camera::Camera;
use crate::passes::{Blending, GPU_SLABS, PassTimes};
use crate::pool::RendererPool;
use crate::render::{RenderOptions, RenderOutput};
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

/// Where images are rendered: `cpu`, `gpu`, or `auto` (a hardware GPU when there is one,
/// else the CPU).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Device {
    /// The CPU tile renderer: works everywhere, results independent of the thread count.
    #[default]
    Cpu,
    /// The GPU compute renderer on any adapter wgpu finds, software ones (Mesa's lavapipe)
    /// included; an error when there is none.
    Gpu,
    /// The GPU renderer on a hardware adapter when one exists, else the CPU renderer.
    Auto,
}

impl Device {
    /// The names accepted by [`Device::from_str`].
    pub const NAMES: [&'static str; 3] = ["cpu", "gpu", "auto"];

    /// What renders on this device in this process, in the words [`Backend::describe`] will
    /// use, opening the GPU if it needs one (once per process): a command checks its
    /// `--device` with it before any work.
    ///
    /// # Errors
    ///
    /// `gpu` without a usable adapter, or a build without the GPU renderer.
    pub fn probe(self) -> Result<String> {
        match self {
            Device::Cpu => Ok(cpu_description()),
            Device::Gpu => gpu_description(false),
            Device::Auto => Ok(gpu_description(true)
                .unwrap_or_else(|e| format!("{} (auto: {})", cpu_description(), e.message()))),
        }
    }

    /// Checks a fixed count of the GPU renderer's depth slabs before any work: 1 to
    /// [`GPU_SLABS`], on the GPU only (the CPU renderer's slabs are its own; `auto` may
    /// render on either).
    ///
    /// # Errors
    ///
    /// A fixed count outside 1 to [`GPU_SLABS`], or one for another device than `gpu`.
    pub fn check_slabs(self, slabs: Option<u32>) -> Result<()> {
        match slabs {
            None => Ok(()),
            Some(_) if self != Device::Gpu => Err(Error::invalid(
                "slabs: only the GPU renderer's depth slabs can be fixed (--device gpu)",
            )),
            Some(n) if !(1..=GPU_SLABS).contains(&n) => Err(Error::invalid(format!(
                "slabs: the GPU renderer renders in 1 to {GPU_SLABS} depth slabs, got {n}"
            ))),
            Some(_) => Ok(()),
        }
    }

    /// Checks a choice of the GPU renderer's blending kernel before any work: another kernel
    /// than the default on the GPU only.
    ///
    /// # Errors
    ///
    /// [`Blending::Columns`] for another device than `gpu`.
    pub fn check_blending(self, blending: Blending) -> Result<()> {
        if blending != Blending::default() && self != Device::Gpu {
            return Err(Error::invalid(format!(
                "blending: only the GPU renderer's kernel can be chosen (--device gpu), got {blending}"
            )));
        }
        Ok(())
    }
}

/// The CPU renderer in words.
fn cpu_description() -> String {
    format!("cpu ({} threads)", rayon::current_num_threads())
}

/// The process's GPU in words (`hardware_only`: as `auto` takes it).
#[cfg(feature = "gpu")]
fn gpu_description(hardware_only: bool) -> Result<String> {
    Ok(format!(
        "gpu: {}",
        crate::gpu::Gpu::shared(hardware_only)?.describe()
    ))
}

#[cfg(not(feature = "gpu"))]
fn gpu_description(_: bool) -> Result<String> {
    Err(no_gpu_build())
}

/// The error of a build without the GPU renderer.
#[cfg(not(feature = "gpu"))]
fn no_gpu_build() -> Error {
    Error::invalid("this build has no GPU renderer (it was built without the cargo feature `gpu`)")
}

impl fmt::Display for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
            Device::Auto => "auto",
        })
    }
}

sage_core::named_by_string!(Device);

impl FromStr for Device {
    type Err = Error;

    fn from_str(s: &str) -> Result<Device> {
        match s {
            "cpu" => Ok(Device::Cpu),
            "gpu" => Ok(Device::Gpu),
            "auto" => Ok(Device::Auto),
            _ => Err(Error::invalid(format!(
                "unknown device {s:?}: expected one of cpu, gpu, auto"
            ))),
        }
    }
}

/// The executor behind a [`Backend`].
enum Executor {
    Cpu(Arc<RendererPool>),
    #[cfg(feature = "gpu")]
    Gpu(Arc<crate::gpu::GpuRenderer>),
}

/// A renderer for one set of Gaussians on the chosen device.
pub struct Backend {
    executor: Executor,
    description: String,
    /// Opened by `auto`: a GPU that fails while rendering hands over to the CPU renderer.
    auto: bool,
    /// The CPU renderers that every handle on one GPU upload hands over to under `auto`, and
    /// their description: one pool for them all, as they shared one upload before the fault.
    #[cfg(feature = "gpu")]
    fallback: Arc<std::sync::OnceLock<(Arc<RendererPool>, String)>>,
}

impl Backend {
    /// The CPU renderer for `gaussians` (a pool of its own: see [`Backend::shared_clone`]).
    pub fn cpu(gaussians: &Gaussians) -> Backend {
        Backend {
            executor: Executor::Cpu(Arc::new(RendererPool::new(gaussians))),
            description: cpu_description(),
            auto: false,
            #[cfg(feature = "gpu")]
            fallback: Arc::default(),
        }
    }

    /// A renderer for `gaussians` on `device`. `auto` falls back to the CPU when there is no
    /// hardware GPU or it fails, and says why in [`Backend::describe`].
    ///
    /// # Errors
    ///
    /// `gpu` without a usable adapter (or in a build without the `gpu` feature), or a scene too
    /// large for the adapter's buffers.
    pub fn open(device: Device, gaussians: &Gaussians) -> Result<Backend> {
        match device {
            Device::Cpu => Ok(Backend::cpu(gaussians)),
            Device::Gpu => Backend::gpu(gaussians, false),
            Device::Auto => match Backend::gpu(gaussians, true) {
                Ok(mut b) => {
                    b.auto = true;
                    Ok(b)
                }
                Err(e) => Ok(Backend::cpu(gaussians).because(&e)),
            },
        }
    }

    /// This CPU backend, saying that `auto` chose it because of `e`.
    fn because(mut self, e: &Error) -> Backend {
        self.description = format!("{} (auto: {})", self.description, e.message());
        self
    }

    /// After a GPU fault under `auto`: the CPU renderer from now on (it says why), or the
    /// error where the device was asked for explicitly. Every handle on the upload that
    /// faults hands over to the same pool of CPU renderers, made (and the fault told) once.
    #[cfg(feature = "gpu")]
    fn fall_back(&mut self, gaussians: &Gaussians, e: Error) -> Result<()> {
        if !self.auto || gaussians.len() != self.gaussian_count() {
            return Err(e);
        }
        self.fallback.get_or_init(|| {
            eprintln!("warning: the GPU renderer failed ({e}); rendering on the CPU from now on");
            let description = format!("{} (auto: {})", cpu_description(), e.message());
            (Arc::new(RendererPool::new(gaussians)), description)
        });
        self.follow_fallback();
        Ok(())
    }

    /// Hands over to the CPU renderers of the upload's fallback once any handle on the upload
    /// made one, so that no handle tries a failed GPU again (a handle cloned after the fault
    /// included).
    #[cfg(feature = "gpu")]
    fn follow_fallback(&mut self) {
        if let (Executor::Gpu(_), Some((pool, description))) = (&self.executor, self.fallback.get())
        {
            self.executor = Executor::Cpu(pool.clone());
            self.description = description.clone();
        }
    }

    /// How many Gaussians the backend was opened for.
    #[cfg(feature = "gpu")]
    fn gaussian_count(&self) -> usize {
        match &self.executor {
            Executor::Cpu(r) => r.gaussian_count(),
            Executor::Gpu(r) => r.gaussian_count(),
        }
    }

    #[cfg(feature = "gpu")]
    fn gpu(gaussians: &Gaussians, hardware_only: bool) -> Result<Backend> {
        let gpu = crate::gpu::Gpu::shared(hardware_only)?;
        Ok(Backend::from_gpu(crate::gpu::GpuRenderer::new(
            &gpu, gaussians,
        )?))
    }

    #[cfg(not(feature = "gpu"))]
    fn gpu(_: &Gaussians, _: bool) -> Result<Backend> {
        Err(no_gpu_build())
    }

    /// A backend over a GPU renderer that may be shared (one resident copy of a scene for
    /// every environment over it).
    #[cfg(feature = "gpu")]
    pub fn from_gpu(renderer: Arc<crate::gpu::GpuRenderer>) -> Backend {
        Backend {
            description: format!("gpu: {}", renderer.gpu().describe()),
            executor: Executor::Gpu(renderer),
            auto: false,
            fallback: Arc::default(),
        }
    }

    /// Which executor renders, in words: `cpu (2 threads)`, `gpu: NVIDIA H100 (Vulkan)`, or
    /// the CPU with the reason `auto` did not take a GPU.
    pub fn describe(&self) -> &str {
        &self.description
    }

    /// Another handle on the same renderer: on a GPU the same resident scene (every
    /// environment over a scene shares one upload), on the CPU the same [`RendererPool`] (every
    /// environment over a scene holds the frame buffers of as many renders as run at once,
    /// not a set of its own).
    pub fn shared_clone(&self) -> Backend {
        Backend {
            executor: match &self.executor {
                Executor::Cpu(pool) => Executor::Cpu(pool.clone()),
                #[cfg(feature = "gpu")]
                Executor::Gpu(r) => Executor::Gpu(r.clone()),
            },
            description: self.description.clone(),
            auto: self.auto,
            #[cfg(feature = "gpu")]
            fallback: self.fallback.clone(),
        }
    }

    /// Device memory the GPU renderer holds, bytes: the resident scene and the work space as
    /// the last batch left it (`None` on the CPU).
    pub fn device_bytes(&self) -> Option<u64> {
        match &self.executor {
            Executor::Cpu(_) => None,
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => Some(r.scene_bytes() + r.stats().workspace_bytes),
        }
    }

    /// Times the GPU renderer's stages from now on (or stops); false, timing nothing, on the
    /// CPU or on a device that cannot write timestamps between dispatches.
    #[cfg_attr(not(feature = "gpu"), expect(unused_variables))]
    pub fn time_passes(&self, on: bool) -> bool {
        match &self.executor {
            Executor::Cpu(_) => false,
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => r.time_passes(on),
        }
    }

    /// Fixes the depth slabs of the GPU renderer's batches (`None`: chosen from the last
    /// batch's work; see [`crate::gpu::GpuRenderer::set_slabs`]).
    ///
    /// # Errors
    ///
    /// As [`Device::check_slabs`] for the executor that renders.
    pub fn set_slabs(&self, slabs: Option<u32>) -> Result<()> {
        match &self.executor {
            Executor::Cpu(_) => Device::Cpu.check_slabs(slabs),
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => r.set_slabs(slabs),
        }
    }

    /// Chooses the GPU renderer's blending kernel (see
    /// [`crate::gpu::GpuRenderer::set_blending`]).
    ///
    /// # Errors
    ///
    /// Another kernel than the default on the CPU renderer, which blends its own way.
    pub fn set_blending(&self, blending: Blending) -> Result<()> {
        match &self.executor {
            Executor::Cpu(_) => Device::Cpu.check_blending(blending),
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => {
                r.set_blending(blending);
                Ok(())
            }
        }
    }

    /// The GPU time of each stage of the last batch, while timing ([`Backend::time_passes`]).
    pub fn pass_times(&self) -> Option<PassTimes> {
        match &self.executor {
            Executor::Cpu(_) => None,
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => r.stats().passes,
        }
    }

    /// True when the GPU renders.
    pub fn is_gpu(&self) -> bool {
        !matches!(self.executor, Executor::Cpu(_))
    }

    /// The CPU renderers, when they are the executor (for their timings and index).
    pub fn as_cpu(&self) -> Option<&RendererPool> {
        match &self.executor {
            Executor::Cpu(pool) => Some(pool),
            #[cfg(feature = "gpu")]
            Executor::Gpu(_) => None,
        }
    }

    /// Renders `gaussians` (the set the backend was opened for) from `camera`;
    /// `categories[instance]` gives each instance's semantic id.
    ///
    /// # Errors
    ///
    /// A camera the renderer refuses, another set of Gaussians, or a GPU fault (under `auto`
    /// the CPU renderer takes over instead).
    pub fn render(
        &mut self,
        gaussians: &Gaussians,
        categories: &[u16],
        camera: &Camera,
        options: &RenderOptions,
    ) -> Result<RenderOutput> {
        let mut out =
            self.render_batch(gaussians, categories, std::slice::from_ref(camera), options)?;
        Ok(out.remove(0))
    }

    /// Renders every camera of `cameras` (any sizes), in order: on the GPU in one submission
    /// with one read-back, on the CPU one after the other.
    ///
    /// # Errors
    ///
    /// As [`Backend::render`], for any camera.
    pub fn render_batch(
        &mut self,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        #[cfg(feature = "gpu")]
        self.follow_fallback();
        #[cfg(feature = "gpu")]
        if let Executor::Gpu(r) = &self.executor {
            match r.render_batch(gaussians, categories, cameras, options) {
                Ok(out) => return Ok(out),
                Err(e) if crate::gpu::is_fault(&e) => self.fall_back(gaussians, e)?,
                Err(e) => return Err(e),
            }
        }
        match &self.executor {
            Executor::Cpu(pool) => pool.render_batch(gaussians, categories, cameras, options),
            #[cfg(feature = "gpu")]
            Executor::Gpu(r) => r.render_batch(gaussians, categories, cameras, options),
        }
    }

    /// Starts rendering `cameras` and returns: on the GPU the batch renders and reads back
    /// while the caller does its own work (encoding the last images, stepping physics) until
    /// it [`Rendering::wait`]s; the CPU renders them now. The images equal
    /// [`Backend::render_batch`]'s.
    ///
    /// # Errors
    ///
    /// As [`Backend::render_batch`] (a GPU fault under `auto` hands over to the CPU here; one
    /// found while waiting is returned).
    pub fn submit_batch(
        &mut self,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Rendering> {
        #[cfg(feature = "gpu")]
        self.follow_fallback();
        #[cfg(feature = "gpu")]
        if let Executor::Gpu(r) = &self.executor {
            match r.submit(gaussians, categories, cameras, options) {
                Ok(s) => return Ok(Rendering::Gpu(s)),
                Err(e) if crate::gpu::is_fault(&e) => self.fall_back(gaussians, e)?,
                Err(e) => return Err(e),
            }
        }
        self.render_batch(gaussians, categories, cameras, options)
            .map(Rendering::Done)
    }
}

/// A batch handed to a [`Backend`] by [`Backend::submit_batch`]: on the GPU still rendering
/// (the caller works meanwhile), on the CPU rendered already.
pub enum Rendering {
    /// The images.
    Done(Vec<RenderOutput>),
    /// On the GPU.
    #[cfg(feature = "gpu")]
    Gpu(crate::gpu::Submitted),
}

impl Rendering {
    /// The images, in camera order.
    ///
    /// # Errors
    ///
    /// A GPU fault.
    pub fn wait(self) -> Result<Vec<RenderOutput>> {
        match self {
            Rendering::Done(images) => Ok(images),
            #[cfg(feature = "gpu")]
            Rendering::Gpu(s) => s.wait(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for name in Device::NAMES {
            let d: Device = name.parse().unwrap();
            assert_eq!(d.to_string(), name);
            assert_eq!(serde_json::to_string(&d).unwrap(), format!("\"{name}\""));
        }
        let e = "tpu".parse::<Device>().unwrap_err();
        assert!(e.message().contains("cpu, gpu, auto"), "{e}");
    }

    #[test]
    fn only_the_gpu_is_tuned_and_only_to_settings_it_has() {
        for d in [Device::Cpu, Device::Gpu, Device::Auto] {
            assert!(d.check_slabs(None).is_ok());
        }
        for n in 1..=GPU_SLABS {
            assert!(Device::Gpu.check_slabs(Some(n)).is_ok());
            for d in [Device::Cpu, Device::Auto] {
                let e = d.check_slabs(Some(n)).unwrap_err();
                assert!(e.message().contains("--device gpu"), "{e}");
            }
        }
        for n in [0, GPU_SLABS + 1, u32::MAX] {
            let e = Device::Gpu.check_slabs(Some(n)).unwrap_err();
            assert!(e.message().contains(&format!("got {n}")), "{e}");
        }
        let cpu = Backend::cpu(&Gaussians::default());
        assert!(cpu.set_slabs(None).is_ok());
        assert!(cpu.set_slabs(Some(1)).is_err());
        // Likewise the blending kernel: the default anywhere, another on the GPU only.
        for d in [Device::Cpu, Device::Gpu, Device::Auto] {
            assert!(d.check_blending(Blending::Blocks).is_ok());
        }
        assert!(Device::Gpu.check_blending(Blending::Columns).is_ok());
        for d in [Device::Cpu, Device::Auto] {
            let e = d.check_blending(Blending::Columns).unwrap_err();
            assert!(e.message().contains("--device gpu"), "{e}");
        }
        assert!(cpu.set_blending(Blending::Blocks).is_ok());
        assert!(cpu.set_blending(Blending::Columns).is_err());
    }

    /// Every handle on one GPU upload that faults under `auto` hands over to one pool of CPU
    /// renderers; a device asked for explicitly returns the fault.
    #[cfg(feature = "gpu")]
    #[test]
    fn handles_on_one_upload_fall_back_to_one_pool() {
        let gpu = match crate::gpu::Gpu::shared(false) {
            Ok(gpu) => gpu,
            Err(e) if std::env::var_os("SAGE3D_REQUIRE_GPU").is_some() => {
                panic!("SAGE3D_REQUIRE_GPU is set and no GPU adapter opened: {e}")
            }
            Err(e) => return eprintln!("no GPU adapter, GPU test not run: {e}"),
        };
        let mut g = Gaussians::new(0).unwrap();
        for i in 0..300 {
            g.push(&sage_scene::Gaussian {
                position: glam::Vec3::new(0.01 * i as f32, 2.0, 0.0),
                opacity_logit: 2.0,
                ..sage_scene::Gaussian::default()
            });
        }
        let upload = crate::gpu::GpuRenderer::new(&gpu, &g).unwrap();
        let mut explicit = Backend::from_gpu(upload.clone());
        // What a scene's context keeps: the handle it clones for each environment.
        let mut kept = Backend::from_gpu(upload);
        kept.auto = true;
        let mut first = kept.shared_clone();
        let mut second = kept.shared_clone();
        let fault = || Error::invalid("device lost");
        first.fall_back(&g, fault()).unwrap();
        second.fall_back(&g, fault()).unwrap();
        assert!(std::ptr::eq(
            first.as_cpu().unwrap(),
            second.as_cpu().unwrap()
        ));
        assert!(
            first.describe().starts_with("cpu (")
                && first.describe().ends_with("(auto: device lost)"),
            "{}",
            first.describe()
        );
        let k = crate::camera::Intrinsics::from_hfov(32, 24, 90.0).unwrap();
        let camera = Camera::from_yaw_pitch(k, glam::Vec3::ZERO, std::f32::consts::FRAC_PI_2, 0.0);
        first
            .render(&g, &[], &camera, &RenderOptions::default())
            .unwrap();
        second
            .render(&g, &[], &camera, &RenderOptions::default())
            .unwrap();
        assert_eq!(first.as_cpu().unwrap().renderers(), 1);
        // A handle cloned afterwards from the kept one, which never faulted, renders on the CPU
        // without trying the GPU again.
        assert!(kept.is_gpu());
        let mut later = kept.shared_clone();
        later
            .render(&g, &[], &camera, &RenderOptions::default())
            .unwrap();
        assert!(!later.is_gpu() && later.describe() == first.describe());
        let e = explicit.fall_back(&g, fault()).unwrap_err();
        assert_eq!(e.message(), "device lost");
        assert!(explicit.is_gpu());
    }
}
