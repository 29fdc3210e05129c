//! `isr` and `dl` as [`scene_core::Technique`]s: a G-buffer from any
//! [`GBufferRenderer`], the coarse buffer by [`crate::downsample`], then the frame on the
//! CPU or the GPU.

use std::sync::Arc;

use scene_core::{Error, FrameRequest, GBufferRenderer, Image, Scene, Technique, ViewTarget};

use crate::frame::{IsrInputs, PassTimings, render_cpu_with, timed};
use crate::light_senders::LightSenders;
use crate::light_set::LightSet;
use crate::settings::{IsrSettings, ShadowSettings};
use scene_core::gbuffer::downsample;

/// Where a technique runs its frames.
#[derive(Clone, Debug, Default)]
pub enum Backend {
    /// rayon on the CPU.
    #[default]
    Cpu,
    /// wgpu compute passes; the G-buffer is uploaded and the image read back (the frame
    /// itself needs no readback, see [`crate::GpuIsr`]).
    Gpu(scene_core::gpu::GpuContext),
}

/// Image-space radiosity as a [`Technique`]: `prepare` hands the scene to its G-buffer
/// renderer and builds the lights and shadow maps ([`LightSet`]); `render` applies the
/// frame's [`scene_core::LightState`] to the lights (no rebuild), renders the G-buffer of
/// the frame's view, downsamples it ([`IsrSettings::downsample`]) and runs one frame with
/// its [`IsrSettings`].
pub struct IsrTechnique {
    name: String,
    /// The frame parameters.
    pub settings: IsrSettings,
    /// The shadow-map parameters (used by the next `prepare`).
    pub shadows: ShadowSettings,
    renderer: Box<dyn GBufferRenderer + Send>,
    backend: Backend,
    gpu: Option<crate::GpuIsr>,
    prepared: Option<(Arc<Scene>, LightSet)>,
    light_senders: Option<LightSenders>,
    timings: PassTimings,
}

impl std::fmt::Debug for IsrTechnique {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IsrTechnique")
            .field("name", &self.name)
            .field("settings", &self.settings)
            .field("shadows", &self.shadows)
            .field("renderer", &self.renderer.name())
            .field("backend", &self.backend)
            .finish()
    }
}

impl IsrTechnique {
    /// ISR with `settings`, G-buffers from `renderer`, on the CPU, default shadows.
    pub fn new(settings: IsrSettings, renderer: Box<dyn GBufferRenderer + Send>) -> Self {
        let name = if settings.is_direct_only() {
            "dl"
        } else {
            "isr"
        };
        Self {
            name: name.into(),
            settings,
            shadows: ShadowSettings::default(),
            renderer,
            backend: Backend::Cpu,
            gpu: None,
            prepared: None,
            light_senders: None,
            timings: PassTimings::default(),
        }
    }

    /// The same with other shadow settings (they take effect at the next `prepare`).
    pub fn with_shadows(mut self, shadows: ShadowSettings) -> Self {
        self.shadows = shadows;
        self.prepared = None;
        self
    }

    /// The same running on `backend`.
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self.gpu = None;
        self
    }

    /// The same with another report name.
    pub fn named(mut self, name: &str) -> Self {
        self.name = name.into();
        self
    }

    /// The pass timings of the last frame (CPU wall clock; on the GPU, of the submitted
    /// work including waiting for it).
    pub fn last_timings(&self) -> PassTimings {
        self.timings
    }

    /// The prepared lights, after `prepare`, with the last frame's light state applied.
    pub fn prepared(&self) -> Option<&LightSet> {
        self.prepared.as_ref().map(|p| &p.1)
    }
}

impl Technique for IsrTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.prepared = None;
        self.gpu = None;
        scene_core::contract::check(&scene)?;
        self.renderer.prepare(scene.clone())?;
        // With light-space senders, one ray-query tree serves the shadow maps' cubes and the
        // senders' rays.
        let senders = self.settings.light_senders > 0 && self.settings.indirect;
        let rays = senders.then(|| Arc::new(scene_core::ray::RayScene::build(&scene)));
        let lights = match &rays {
            Some(rays) => LightSet::with_rays(&scene, &self.shadows, rays),
            None => LightSet::new(&scene, &self.shadows),
        }
        .map_err(crate::IsrError::from)?;
        self.light_senders = match rays {
            Some(rays) => Some(LightSenders::with_rays(
                &scene,
                Some(rays),
                &lights,
                self.settings.light_senders,
                self.settings.light_sender_bounces,
            )?),
            None => None,
        };
        self.prepared = Some((scene, lights));
        Ok(())
    }

    /// Renders `frame` with its light state: a changed light setting changes this frame;
    /// nothing prepared depends on it.
    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        let (width, height) = (frame.width, frame.height);
        if width == 0 || height == 0 {
            return Err(crate::IsrError::ZeroSize {
                which: "output",
                width,
                height,
            }
            .into());
        }
        let Some((_, lights)) = self.prepared.as_mut() else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        lights.apply(frame.lights);
        match &self.backend {
            Backend::Cpu => {
                let full = self.renderer.render_view(&frame.view, width, height)?;
                let (coarse, t_down) = timed(|| downsample(&full, self.settings.downsample));
                let inputs = IsrInputs {
                    full: &full,
                    coarse: &coarse,
                    view: &frame.view,
                };
                let out =
                    render_cpu_with(lights, &inputs, &self.settings, self.light_senders.as_ref())?;
                self.timings = out.timings;
                self.timings.downsample = t_down;
                Ok(out.image)
            }
            Backend::Gpu(ctx) => {
                if self.gpu.is_none() {
                    let mut gpu = crate::GpuIsr::new(ctx, lights)?;
                    if let Some(senders) = &self.light_senders {
                        gpu.set_light_senders(senders)?;
                    }
                    self.gpu = Some(gpu);
                }
                let Some(gpu) = self.gpu.as_mut() else {
                    return Err(Error::NotPrepared("the GPU ISR pipelines".into()));
                };
                gpu.apply(frame.lights);
                // A renderer that rasterises on the GPU hands its G-buffer over where it
                // is (the frame contract's input): no read-back and upload again; only the
                // image is read back. Others render on the CPU and are uploaded.
                let target = ViewTarget::new(frame.view, width, height);
                let on_gpu = self
                    .renderer
                    .render_views_gpu(std::slice::from_ref(&target))?
                    .and_then(|mut g| g.pop());
                let (image, timings) = match on_gpu {
                    Some(g) => gpu.render_gpu_gbuffer(&g, &frame.view, &self.settings)?,
                    None => {
                        let full = self.renderer.render_view(&frame.view, width, height)?;
                        gpu.render_gbuffer(&full, None, &frame.view, &self.settings)?
                    }
                };
                self.timings = timings;
                Ok(image)
            }
        }
    }
}

/// The thesis' DL baseline (`I_DL`) as a [`Technique`]: [`IsrTechnique`] with ISR and SSAO
/// off (direct light with ESM shadows and visible emitters only).
#[derive(Debug)]
pub struct DlTechnique(pub IsrTechnique);

impl DlTechnique {
    /// DL with G-buffers from `renderer`, on the CPU.
    pub fn new(renderer: Box<dyn GBufferRenderer + Send>) -> Self {
        Self(IsrTechnique::new(IsrSettings::dl(), renderer))
    }
}

impl Technique for DlTechnique {
    fn name(&self) -> &str {
        "dl"
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.0.prepare(scene)
    }

    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        self.0.render(frame)
    }
}
