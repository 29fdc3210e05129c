//! The IBRR's frame on the frame contract ([`scene_core::gpu::GpuFrame`], docs/engine.md):
//! the LDC on the GPU ([`crate::gpu::GpuLdc`]) reconstructed into the host's target, the
//! layers' light recombined when the light state changes. Every method keeps its
//! `GpuFrame` in a module of this name.

use scene_core::gpu::{GpuContext, KeptBuffer};
use scene_core::{LightState, Scene};

use crate::error::IbrrError;
use crate::gpu::{GpuLdc, gpu};

/// The IBRR on the frame contract ([`scene_core::gpu::GpuFrame`]): a constructed
/// [`crate::IbrrTechnique`], its LDC on the GPU and the pass that writes the
/// reconstruction into the host's target. A frame whose light state differs from the last
/// recombines the layers' per-source light on the CPU ([`crate::IbrrTechnique::relight`],
/// milliseconds) and hands the values over through the frame's encoder; a light state that
/// lights a source the IRPLs were made without keeps the last one shown (only a rebuild can
/// show it).
pub struct IbrrFrame {
    technique: crate::IbrrTechnique,
    scene: std::sync::Arc<Scene>,
    ldc: GpuLdc,
    shown: LightState,
    pixels: KeptBuffer,
    to_texture: scene_core::gpu::PixelsToTexture,
    device: wgpu::Device,
}

impl std::fmt::Debug for IbrrFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IbrrFrame").finish_non_exhaustive()
    }
}

impl IbrrFrame {
    /// Prepares the IBRR on the host's device `ctx` from its precomputed state, `technique`
    /// with its LDC constructed ([`crate::IbrrTechnique`]'s `prepare`; its settings choose
    /// the lookup and the fallback): uploads the LDC and compiles the passes. Every method's
    /// frame is made this way: `prepare(ctx, precomputed state[, settings])`. Fails when the
    /// technique holds no LDC.
    pub fn prepare(ctx: &GpuContext, technique: crate::IbrrTechnique) -> Result<Self, IbrrError> {
        let not_built = || IbrrError::Settings("the IBRR has no LDC: prepare it first".into());
        let ldc = technique.ldc().ok_or_else(not_built)?;
        let scene = technique.scene().ok_or_else(not_built)?.clone();
        let s = &technique.settings;
        let on_gpu = GpuLdc::new(ctx, ldc, s.reading())?;
        Ok(Self {
            ldc: on_gpu,
            shown: LightState::default(),
            pixels: KeptBuffer::new("ibrr frame pixels", wgpu::BufferUsages::STORAGE),
            to_texture: scene_core::gpu::PixelsToTexture::new(ctx).map_err(gpu)?,
            device: ctx.device.clone(),
            technique,
            scene,
        })
    }
}

impl IbrrFrame {
    /// The constructed technique.
    pub fn technique(&self) -> &crate::IbrrTechnique {
        &self.technique
    }

    /// True when the frame cannot show `lights`: they light a source the IRPLs were made
    /// without, so frames keep the last state shown until the LDC is rebuilt.
    pub fn is_stale(&self, lights: &LightState) -> bool {
        !self.technique.shows(lights)
    }
}

impl scene_core::gpu::GpuFrame for IbrrFrame {
    fn name(&self) -> &str {
        "ibrr"
    }

    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &scene_core::gpu::FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), scene_core::Error> {
        let g = inputs.gbuffer;
        scene_core::gpu::check_frame_target(target, g.width, g.height)?;
        let lights = inputs.lights;
        if !self.technique.shows(lights)
            && self.technique.relight(lights)?.is_some()
            && let Some(ldc) = self.technique.ldc()
        {
            self.ldc.update_values(ldc)?;
        }
        if self.shown.fingerprint() != lights.fingerprint() && self.technique.shows(lights) {
            self.shown = lights.clone();
        }
        let bytes = u64::from(g.width) * u64::from(g.height) * 16;
        let pixels = self.pixels.ensure(&self.device, bytes).clone();
        self.ldc
            .encode(encoder, &self.scene, g, inputs.view, &self.shown, &pixels)?;
        self.to_texture
            .encode(&self.device, encoder, &pixels, target)?;
        Ok(())
    }
}
