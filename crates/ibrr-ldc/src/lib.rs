//! # ibrr-ldc
//!
//! The image-based radiosity representation (IBRR) of Tom Mertens and Frank Van Reeth, "An
//! Image-Based Radiosity Representation", Eurographics 2002 Short Presentations
//! (doi:10.2312/egs.20021045): Keller's instant radiosity made view-independent. Particle walks place instant-radiosity point lights (IRPLs,
//! [`irpl`]); the scene is rendered around each through any
//! [`scene_core::GBufferRenderer`] and every pixel's irradiance from that IRPL (eq. 2) is
//! warped into a layered depth cube whose pixels are planes ([`ldc`], [`construct`]); a
//! camera view is then shaded by warping its pixels into the cube ([`mod@reconstruct`]), at a
//! cost that depends on the image, not on the triangles.
//!
//! ```
//! use std::sync::Arc;
//! use ibrr_ldc::{IbrrSettings, IbrrTechnique};
//! use scene_core::{builtin, gbuffer::RayCastRenderer, FrameRequest, Technique};
//!
//! let scene = Arc::new(builtin::scene("cornell").unwrap());
//! let settings = IbrrSettings { resolution: 32, irpls: 8, ..Default::default() };
//! let mut ibrr = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
//! ibrr.prepare(scene.clone()).unwrap();
//! let image = ibrr.render(&FrameRequest::camera(&scene.cameras[0], 16, 16)).unwrap();
//! assert!(image.pixels.iter().all(|p| p.is_finite()));
//! assert!(ibrr.ldc().unwrap().layer_count() > 0);
//! ```

pub mod compensate;
pub mod construct;
pub mod error;
pub mod estimate;
pub mod gpu;
pub mod gpu_frame;
pub mod irpl;
pub mod ldc;
pub mod reconstruct;
pub mod settings;
pub mod technique;

pub use construct::{Construction, ConstructionStats};
pub use error::IbrrError;
pub use estimate::{ErrorEstimate, Stop};
pub use gpu::GpuLdc;
pub use gpu_frame::IbrrFrame;
pub use irpl::{Irpl, IrplKind, IrplSet};
pub use ldc::{Ldc, LdcFrame};
pub use reconstruct::{Reconstruction, Served, fill_holes, lookup, reconstruct, shade};
pub use settings::{Compensation, IbrrSettings, Lookup, Reading, Splat};
pub use technique::{FrameTimings, IbrrTechnique};

/// Every shader pass of the IBRR, as `cargo xtask shaders` validates them.
pub use gpu::SHADER_PASSES;
pub use scene_core;
