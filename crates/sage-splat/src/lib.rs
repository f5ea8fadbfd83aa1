//! `sage-splat`: the 3D Gaussian Splatting renderer of sage3d (G in G + M + Φ).
//!
//! The standard 3DGS image formation on the CPU — EWA projection with the frustum-edge clamp
//! and 0.3 px² low-pass, SH colour of degree 0–3 from the camera centre, 16×16 tiles, front to
//! back blending with alpha = min(0.99, o·e^power), skip below 1/255, stop at T < 1e-4 — with
//! the channels a simulator needs from the same pass: expected and median z-depth, the
//! instance of the largest blending weight, its category, and accumulated alpha.
//!
//! Large scenes stay cheap through Morton-ordered chunks of 256 Gaussians that are frustum
//! culled before projection ([`index`]), opacity-aware radii, and an exact ellipse–tile test
//! ([`project::Splat::reaches_rect`]). Results do not depend on the thread count.
//!
//! ```no_run
//! # fn demo(scene: &sage_scene::Scene) -> sage_core::Result<()> {
//! use sage_splat::{Camera, Intrinsics, Renderer, RenderOptions};
//! let camera = Camera::from_yaw_pitch(Intrinsics::from_hfov(224, 224, 90.0)?, glam::Vec3::new(0.0, 0.0, 1.2), 0.0, 0.0);
//! let mut renderer = Renderer::new(&scene.gaussians);
//! let out = renderer.render(&scene.gaussians, &scene.instances.category_ids, &camera, &RenderOptions::default())?;
//! # Ok(()) }
//! ```

// The docs name the GPU renderer's items, which exist only with the `gpu` feature.
#![cfg_attr(not(feature = "gpu"), allow(rustdoc::broken_intra_doc_links))]

pub mod camera;
pub mod device;
pub mod fastmath;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod index;
pub mod passes;
pub mod pool;
pub mod project;
pub mod render;
pub mod sh;
pub mod tile;

pub use camera::{Camera, CameraSpec, Intrinsics, MAX_IMAGE_SIDE};
pub use device::{Backend, Device, Rendering};
pub use passes::{Blending, KernelShape, PassTimes};
pub use pool::RendererPool;
pub use render::{Channels, RenderOptions, RenderOutput, RenderStats, Renderer};
