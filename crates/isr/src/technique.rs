//! `isr` and `dl` as [`scene_core::Technique`]s: a G-buffer from any
//! [`GBufferRenderer`], the coarse buffer by [`crate::downsample`], then the frame on the
//! CPU or the GPU.

use scene_core::{Camera, Error, GBufferRenderer, Image, Scene, Technique, View};

use crate::downsample::downsample;
use crate::frame::{IsrInputs, PassTimings, render_cpu, timed};
use crate::lights::IsrScene;
use crate::settings::{IsrSettings, ShadowSettings};

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

/// What identifies the scene a technique was prepared for.
#[derive(Clone, Debug, PartialEq)]
struct Fingerprint {
    name: String,
    triangles: usize,
    lights: (usize, usize),
    bounds: [f32; 6],
}

impl Fingerprint {
    fn of(scene: &Scene) -> Self {
        let b = scene.bounds();
        Self {
            name: scene.name.clone(),
            triangles: scene.triangle_count(),
            lights: (scene.point_lights.len(), scene.directional_lights.len()),
            bounds: [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z],
        }
    }
}

/// Image-space radiosity as a [`Technique`]: `prepare` builds the lights and shadow maps
/// ([`IsrScene`]), `render` renders the G-buffer with the renderer it holds, downsamples it
/// (depth-aware, see [`crate::downsample`]) and runs one frame with its [`IsrSettings`].
pub struct IsrTechnique {
    name: String,
    /// The frame parameters.
    pub settings: IsrSettings,
    /// The shadow-map parameters (used by the next `prepare`).
    pub shadows: ShadowSettings,
    renderer: Box<dyn GBufferRenderer + Send>,
    backend: Backend,
    gpu: Option<crate::GpuIsr>,
    prepared: Option<(Fingerprint, IsrScene)>,
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
            timings: PassTimings::default(),
        }
    }

    /// The same with other shadow settings.
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

    /// The prepared scene, after `prepare` or the first `render`.
    pub fn prepared(&self) -> Option<&IsrScene> {
        self.prepared.as_ref().map(|p| &p.1)
    }

    fn ensure_prepared(&mut self, scene: &Scene) -> Result<(), Error> {
        let fp = Fingerprint::of(scene);
        if self.prepared.as_ref().is_none_or(|(f, _)| *f != fp) {
            let s = IsrScene::new(scene, &self.shadows)?;
            self.prepared = Some((fp, s));
            self.gpu = None;
        }
        Ok(())
    }
}

impl Technique for IsrTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: &Scene) -> Result<(), Error> {
        self.prepared = None;
        self.ensure_prepared(scene)
    }

    /// Renders `camera` (its aspect ratio replaced by `width / height`) at `width x height`.
    fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Image, Error> {
        if width == 0 || height == 0 {
            return Err(crate::IsrError::ZeroSize {
                which: "output",
                width,
                height,
            }
            .into());
        }
        self.ensure_prepared(scene)?;
        let camera = camera.with_aspect(width as f32 / height as f32);
        let view = View::from_camera(&camera);
        let full = self.renderer.render(scene, &view, width, height)?;
        let (coarse, t_down) = timed(|| downsample(&full));
        let Some((_, prepared)) = self.prepared.as_ref() else {
            return Err(Error::InvalidArgument("technique not prepared".into()));
        };
        match &self.backend {
            Backend::Cpu => {
                let inputs = IsrInputs {
                    full: &full,
                    coarse: &coarse,
                    view: &view,
                };
                let frame = render_cpu(prepared, &inputs, &self.settings)?;
                self.timings = frame.timings;
                self.timings.downsample = t_down;
                Ok(frame.image)
            }
            Backend::Gpu(ctx) => {
                if self.gpu.is_none() {
                    self.gpu = Some(crate::GpuIsr::new(ctx, prepared)?);
                }
                let Some(gpu) = self.gpu.as_mut() else {
                    return Err(Error::InvalidArgument("GPU state missing".into()));
                };
                let (image, timings) = gpu.render_gbuffer(&full, &view, &self.settings)?;
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

    fn prepare(&mut self, scene: &Scene) -> Result<(), Error> {
        self.0.prepare(scene)
    }

    fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Image, Error> {
        self.0.render(scene, camera, width, height)
    }
}
