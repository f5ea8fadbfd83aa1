//! `sage-train`: fits 3D Gaussian Splatting parameters to posed images on the CPU.
//!
//! Its one job is reconstruction's optimisation step: given initial Gaussians (e.g. sampled
//! from a mesh's surface with [`init_gaussians`]) and views with known cameras, [`fit()`]
//! minimises the 3DGS photometric loss (L1 + D-SSIM) by Adam through a differentiable copy of
//! `sage-splat`'s image formation ([`forward`], [`backward`]), with the adaptive density
//! control of 3DGS ([`density`]), and reports PSNR on held-out views.
//!
//! It is meant for small scenes (thousands to tens of thousands of Gaussians, images of a few
//! hundred pixels); large scenes go to a GPU trainer through the exported `transforms.json`.
//! Results are deterministic: the same seed gives the same bytes for any thread count.

pub mod adam;
pub mod backward;
pub mod density;
pub mod fit;
pub mod forward;
pub mod init;
pub mod loss;
pub mod params;

pub use fit::{FitParams, FitReport, View, fit};
pub use init::init_gaussians;
