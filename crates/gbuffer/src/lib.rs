//! # gbuffer
//!
//! Deferred G-buffers (thesis figure 4.1) on the CPU and the GPU, coarse buffers and
//! position reconstruction, for every crate that consumes scene-core's [`GBuffer`]:
//!
//! ```
//! use gbuffer::{downsample, CpuRasterizer, DownsampleMode, FrustumReconstruction};
//! use scene_core::{builtin, glam::Vec2, GBufferRenderer, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! let g = CpuRasterizer::new().render(&scene, &view, 64, 48).unwrap();
//!
//! // A coarse (32x24) buffer for ISR, and the world position of one pixel (eq. 24).
//! let coarse = downsample(&g, DownsampleMode::NearestToMedian);
//! assert_eq!((coarse.width, coarse.height), (32, 24));
//! let i = 24 * 64 + 32;
//! let uv = Vec2::new(32.5 / 64.0, 24.5 / 48.0);
//! let p = FrustumReconstruction::new(&view).world(uv, g.depth[i]);
//! assert!((view.linear_depth(p) - g.depth[i]).abs() < 1e-5);
//! ```
//!
//! ## What is here
//!
//! * [`CpuRasterizer`] ([`raster`]): a tiled, rayon-parallel, watertight triangle
//!   rasteriser (near-plane clipping, fixed-point top-left fill rule, depth test,
//!   two-sided triangles, perspective-correct interpolation, bilinear albedo textures).
//!   Bit-identical output for any thread count.
//! * [`GpuRasterizer`] ([`mrt`]): a wgpu render pipeline writing the four targets of
//!   scene-core's [`GpuGBuffer`](scene_core::gpu::GpuGBuffer) in one pass
//!   (`shaders/gbuffer/mrt.wgsl`). The result stays on the GPU; reading it back is an
//!   explicit step. Both renderers implement [`GBufferRenderer`](scene_core::GBufferRenderer)
//!   and agree to about 1e-5 in depth and normals (tested to 1e-4) wherever they pick the
//!   same triangle.
//! * Views: any scene-core [`View`](scene_core::View): cameras, orthographic shadow-map
//!   views, and the five faces of a hemicube ([`hemicube`]).
//! * Coarse buffers ([`downsample`](mod@downsample)): 2x downsampling on the CPU and the
//!   GPU, with the thesis' averaging and three depth-aware modes (one of them ISR's), and
//!   [`compare_with_direct`] to measure them. The modes live in scene-core beside the
//!   G-buffer (`scene_core::gbuffer::downsample`, shared with ISR), re-exported here; the
//!   measurement is this crate's.
//! * Position reconstruction ([`reconstruct`]): eqs. 23-24 (frustum corners) and inverse
//!   matrices, on the CPU and in WGSL, for the micro-benchmark of `cargo xtask bench
//!   gbuffer`.
//! * [`packing`]: eq. 22's 8-bit normals, with their measured error (not used by the
//!   G-buffers, which keep float normals).
//!
//! ## Conventions (scene-core's, see `docs/gbuffer.md`)
//!
//! Row-major, top row first; pixel `(x, y)` has its centre at image coordinates
//! `((x + 0.5) / w, (y + 0.5) / h)`. Albedo `w` is the radiation mask (1 on geometry);
//! normals are unit, world space, flipped to face the viewer; depth is the distance along
//! the view direction divided by `far`; background is depth 1, normal 0, albedo 0 and
//! triangle id [`BACKGROUND_ID`](scene_core::BACKGROUND_ID).
//!
//! [`GBuffer`]: scene_core::GBuffer

pub mod downsample;
pub mod hemicube;
pub mod mrt;
pub mod packing;
pub mod raster;
pub mod reconstruct;
pub mod scene_upload;

/// Every shader pass of the crate, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[scene_core::gpu::shader::ShaderPass] =
    &[mrt::MRT, reconstruct::RECONSTRUCT];

pub use downsample::{
    DownsampleMode, DownsampleStats, GpuDownsampler, coarse_size, compare_with_direct, downsample,
};
pub use hemicube::{HemicubeFaceBuffer, hemicube_views};
pub use mrt::{GpuPreparedScene, GpuRasterizer};
pub use raster::CpuRasterizer;
pub use reconstruct::{
    FrustumReconstruction, GpuReconstructor, InverseMatrixReconstruction, ReconstructionMethod,
    reconstruct_buffer, reconstruct_into,
};
pub use scene_core;
