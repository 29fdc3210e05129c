//! ISR's frame on the frame contract ([`scene_core::gpu::GpuFrame`], docs/engine.md): the
//! GPU passes of [`crate::gpu`] recorded into the host's encoder and target, the light
//! state applied each frame. Every method keeps its `GpuFrame` in a module of this name.

use crate::gpu::{GpuIsr, GpuIsrInputs};
use crate::settings::IsrSettings;
use crate::{IsrError, LightSenders, LightSet};
use scene_core::gpu::GpuContext;

/// ISR, or DL with [`IsrSettings::dl`], on the frame contract
/// ([`scene_core::gpu::GpuFrame`]): each frame applies the frame's light state
/// ([`GpuIsr::apply`], factors only) and records ISR's passes into the host's target
/// ([`GpuIsr::encode`]). Made by [`IsrFrame::prepare`] on the host's device.
pub struct IsrFrame {
    /// The prepared method.
    pub isr: GpuIsr,
    /// The settings every frame uses.
    pub settings: IsrSettings,
    name: &'static str,
}

impl std::fmt::Debug for IsrFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IsrFrame")
            .field("name", &self.name)
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl IsrFrame {
    /// Prepares ISR (or DL) on the host's device `ctx` from its precomputed state, the
    /// light set `lights` (lights, shadow maps, emitter samples: [`LightSet::new`]), to
    /// render every frame with `settings` (named `dl` when they are direct light only,
    /// `isr-ss` for screen-space senders alone, `isr` otherwise). Settings that gather light-space senders (the default's) need them given
    /// with [`IsrFrame::with_light_senders`]; [`IsrSettings::screen_space`] does not.
    /// Every method's frame is made this way: `prepare(ctx, precomputed state, settings)`.
    pub fn prepare(
        ctx: &GpuContext,
        lights: &LightSet,
        settings: IsrSettings,
    ) -> Result<Self, IsrError> {
        let name = if settings.is_direct_only() {
            "dl"
        } else if settings.light_senders > 0 {
            "isr"
        } else {
            "isr-ss"
        };
        Ok(Self {
            isr: GpuIsr::new(ctx, lights)?,
            settings,
            name,
        })
    }

    /// The same frame gathering the light-space senders `senders` as well ([`LightSenders`],
    /// made from the scene and `lights`), for settings that ask for them
    /// ([`IsrSettings::light_senders`] above 0, e.g. [`IsrSettings::with_light_senders`]).
    pub fn with_light_senders(mut self, senders: &LightSenders) -> Result<Self, IsrError> {
        self.isr.set_light_senders(senders)?;
        Ok(self)
    }
}

impl scene_core::gpu::GpuFrame for IsrFrame {
    fn name(&self) -> &str {
        self.name
    }

    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &scene_core::gpu::FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), scene_core::Error> {
        self.isr.apply(inputs.lights);
        let frame = GpuIsrInputs {
            full: inputs.gbuffer,
            coarse: None,
            view: inputs.view,
        };
        Ok(self.isr.encode(encoder, &frame, &self.settings, target)?)
    }
}
