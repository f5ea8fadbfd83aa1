//! The wgpu compute renderer (cargo feature `gpu`): the image formation of the CPU renderer
//! (the same constants, from [`crate::project`], [`crate::tile`] and [`crate::sh`], and the
//! same chunk culling, from [`crate::index`]) run as compute shaders — culling of chunks
//! against each camera's frustum, projection with EWA covariance and SH colour, tile binning
//! with a GPU radix sort by depth and tile, and per-tile front-to-back blending — over a batch
//! of cameras in the same dispatches, each pass sized by what the pass before found. A scene's
//! Gaussians are uploaded once and kept resident; the work space persists between batches.

mod context;
mod kernel;
mod live;
mod renderer;
mod scene;
mod sort;
mod workspace;

pub use context::Gpu;

/// True when `e` is a fault of the GPU itself (every such error names the adapter first:
/// `GPU <name>: …`), not of the request (a bad camera, another scene).
pub fn is_fault(e: &sage_core::Error) -> bool {
    e.message().starts_with("GPU ")
}
pub use renderer::{GpuRenderer, GpuStats, SOFTWARE_PIECE, Submitted};
