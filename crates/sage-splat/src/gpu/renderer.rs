//! The GPU renderer of one scene.

use super::Gpu;
use crate::camera::Camera;
use crate::render::{RenderOptions, RenderOutput};
use sage_core::{Error, Result};
use sage_scene::Gaussians;
use std::sync::Arc;

/// One scene's Gaussians resident on a [`Gpu`], and the buffers its frames reuse. Shared by
/// reference: renders from several threads take turns.
pub struct GpuRenderer {
    gpu: Arc<Gpu>,
    count: usize,
}

impl GpuRenderer {
    /// Uploads `gaussians` to `gpu`.
    ///
    /// # Errors
    ///
    /// A scene larger than the adapter's buffers.
    pub fn new(gpu: &Arc<Gpu>, gaussians: &Gaussians) -> Result<Arc<GpuRenderer>> {
        Ok(Arc::new(GpuRenderer {
            gpu: gpu.clone(),
            count: gaussians.len(),
        }))
    }

    /// The GPU it renders on.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Renders one camera (see [`GpuRenderer::render_batch`]).
    ///
    /// # Errors
    ///
    /// As [`GpuRenderer::render_batch`].
    pub fn render(
        &self,
        gaussians: &Gaussians,
        categories: &[u16],
        camera: &Camera,
        options: &RenderOptions,
    ) -> Result<RenderOutput> {
        let mut out =
            self.render_batch(gaussians, categories, std::slice::from_ref(camera), options)?;
        Ok(out.remove(0))
    }

    /// Renders every camera of `cameras` in one submission and one read-back.
    ///
    /// # Errors
    ///
    /// Another set of Gaussians, a camera the renderer refuses, or a GPU fault.
    pub fn render_batch(
        &self,
        gaussians: &Gaussians,
        _categories: &[u16],
        _cameras: &[Camera],
        _options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        if gaussians.len() != self.count {
            return Err(Error::invalid(format!(
                "renderer was built for {} Gaussians, asked to render {}",
                self.count,
                gaussians.len()
            )));
        }
        Err(Error::invalid("the GPU renderer is being written"))
    }
}
