//! Hemicube G-buffers: the five faces at a surface point (a full front face looking along
//! the normal and four half side faces), as `ibrr-ldc` and `relight-pr` need them. Every
//! [`scene_core::GBufferRenderer`] renders them
//! ([`GBufferRenderer::render_hemicube`](scene_core::GBufferRenderer::render_hemicube));
//! the views and face sizes live in scene-core beside the G-buffer. It renders the five
//! faces as one batch ([`GBufferRenderer::render_views`](scene_core::GBufferRenderer::render_views)),
//! which the GPU rasteriser records into one submission, and
//! [`GpuRasterizer::render_hemicube_gpu`] keeps them on the GPU without readback.
//!
//! [`GpuRasterizer::render_hemicube_gpu`]: crate::GpuRasterizer::render_hemicube_gpu

pub use scene_core::gbuffer::{HemicubeFaceBuffer, hemicube_views};
