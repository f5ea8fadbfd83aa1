//! The wgpu compute renderer (cargo feature `gpu`): the image formation of the CPU renderer
//! (the same constants, from [`crate::project`], [`crate::tile`] and [`crate::sh`]) run as
//! compute shaders — projection with EWA covariance and SH colour, tile binning with a GPU
//! radix sort by depth and tile, and per-tile front-to-back blending — with a scene's
//! Gaussians uploaded once and kept resident, and many cameras rendered in one submission.

mod context;
mod kernel;
mod renderer;
mod sort;

pub use context::Gpu;

/// True when `e` is a fault of the GPU itself (every such error names the adapter first:
/// `GPU <name>: …`), not of the request (a bad camera, another scene).
pub fn is_fault(e: &sage_core::Error) -> bool {
    e.message().starts_with("GPU ")
}
pub use renderer::{GpuRenderer, GpuStats};
