//! GPU path: not implemented yet (the next commit adds it).
use glam::Vec3;
use scene_core::{GBuffer, Image, View};

use crate::{IsrError, IsrScene, IsrSettings, PassTimings};

/// GPU state.
#[derive(Debug)]
pub struct GpuIsr;

/// GPU inputs.
#[derive(Debug)]
pub struct GpuIsrInputs;

impl GpuIsr {
    /// New.
    pub fn new(_ctx: &scene_core::gpu::GpuContext, _scene: &IsrScene) -> Result<Self, IsrError> {
        Ok(Self)
    }
    /// Render.
    pub fn render_gbuffer(
        &mut self,
        g: &GBuffer,
        _v: &View,
        _s: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        Ok((
            Image::filled(g.width, g.height, Vec3::ZERO),
            PassTimings::default(),
        ))
    }
}
