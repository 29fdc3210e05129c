//! Relighting on the frame contract ([`scene_core::gpu::GpuFrame`], issue 30,
//! docs/engine.md): [`RelightFrame`] records a frame of the paper's display from any
//! G-buffer the host has, its own or the engine's converted by
//! [`scene_core::gpu::HostGBufferPass`], ids or none.
//!
//! The display reads which element each pixel sees (eq. 1 per pixel over the element's
//! welded vertices). The host's G-buffer cannot say it: an engine's G-buffer has no ids, and
//! its ids are of its own triangles. So the frame renders its elements' ids itself
//! ([`crate::element_ids::TriangleIdPass`], one raster pass of the element triangles in the
//! frame's view) and reads the host's albedo, normal and depth beside them. The direct light
//! is scene-core's shadow-mapped lights evaluated per pixel in the same encoder when
//! [`GpuRelight::set_shadowed_direct`] was called (a moving camera's quality equals a still
//! one's), else the elements' own.

use crate::element_ids::TriangleIdPass;
use glam::Vec3;
use scene_core::View;
use scene_core::gpu::{FrameInputs, GpuContext, KeptBuffer, PixelsToTexture, check_frame_target};

use crate::RelightError;
use crate::display::light_slots;
use crate::gpu::GpuRelight;
use crate::mesh::Meshing;
use crate::packed::Precision;
use crate::solver::Source;
use crate::technique::Prepared;
use scene_core::shadowed_lights::LightSet;

/// Relighting on the frame contract (module docs): the solution on the GPU, the pass that
/// renders the element ids, and the pass that writes the display into the host's target.
/// A frame costs the id raster, the direct pass (when shadow-mapped), the display and a
/// copy into the target; a light change costs k factor pairs.
pub struct RelightFrame {
    gpu: GpuRelight,
    sources: Vec<Source>,
    ids: TriangleIdPass,
    pixels: KeptBuffer,
    to_texture: PixelsToTexture,
    device: wgpu::Device,
    /// Per-pixel direct light gathered for one view and size
    /// ([`RelightFrame::set_pixel_direct`]).
    pixel_direct: Option<(View, (u32, u32), Vec<Vec3>)>,
}

impl std::fmt::Debug for RelightFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RelightFrame")
            .field("gpu", &self.gpu)
            .field("ids", &self.ids)
            .finish_non_exhaustive()
    }
}

/// How [`RelightFrame::prepare`] puts a solution on the GPU.
#[derive(Clone, Copy, Debug)]
pub struct RelightFrameSettings<'a> {
    /// The precision of the form-factor data on the GPU.
    pub precision: Precision,
    /// The direct light every frame evaluates per pixel from shadow maps: the scene's
    /// shadowed lights and the footprint grid (`n` x `n` samples over each pixel,
    /// [`GpuRelight::set_shadowed_direct`]). `None`: the elements' own direct light (or the
    /// values [`RelightFrame::set_pixel_direct`] hands in).
    pub shadowed_direct: Option<(&'a LightSet, u32)>,
}

impl Default for RelightFrameSettings<'_> {
    /// Full precision, the elements' direct light.
    fn default() -> Self {
        Self {
            precision: Precision::F32,
            shadowed_direct: None,
        }
    }
}

impl RelightFrame {
    /// Prepares relighting on the host's device `ctx` from its precomputed state (the
    /// meshing, the k single-source solutions and the welding of
    /// [`crate::RelightTechnique`]'s `prepare`, [`Prepared`]): uploads the solution
    /// ([`GpuRelight::new`]), the shadowed lights when `settings` name them, and the element
    /// triangles for the id raster, and compiles the passes. Every method's frame is made
    /// this way: `prepare(ctx, precomputed state, settings)`. Fails when the elements exceed
    /// the adapter's binding limit.
    pub fn prepare(
        ctx: &GpuContext,
        prepared: &Prepared,
        settings: &RelightFrameSettings<'_>,
    ) -> Result<Self, RelightError> {
        let (meshing, solution) = (&prepared.meshing, &prepared.solution);
        let mut gpu = GpuRelight::new(
            ctx,
            meshing,
            &prepared.welding,
            solution,
            settings.precision,
        )?;
        if let Some((lights, footprint)) = settings.shadowed_direct {
            gpu.set_shadowed_direct(lights, &light_slots(lights, &solution.sources), footprint)?;
        }
        Self::with_gpu(ctx, gpu, meshing, solution.sources.clone())
    }

    /// Wraps `gpu` (a solution over `meshing`) and the solution's `sources`: uploads the
    /// element triangles for the id raster and compiles the passes on `ctx`'s device (the
    /// one `gpu` lives on). Fails when the element count or the sources do not match `gpu`'s,
    /// or the elements exceed the adapter's binding limit.
    fn with_gpu(
        ctx: &GpuContext,
        gpu: GpuRelight,
        meshing: &Meshing,
        sources: Vec<Source>,
    ) -> Result<Self, RelightError> {
        // A solution without sources packs no element (its display is black).
        let elements_differ = gpu.sources() > 0 && meshing.elements.len() != gpu.mesh_elements();
        if elements_differ || sources.len() != gpu.sources() {
            return Err(RelightError::InvalidSetting(format!(
                "a solution of {} mesh elements and {} sources on the GPU, a meshing of {} \
                 mesh elements and {} sources given",
                gpu.mesh_elements(),
                gpu.sources(),
                meshing.elements.len(),
                sources.len()
            )));
        }
        let triangles: Vec<[Vec3; 3]> = meshing.elements.iter().map(|e| e.corners).collect();
        let gpu_err = |e: scene_core::gpu::GpuError| RelightError::Gpu(Box::new(e));
        Ok(Self {
            ids: TriangleIdPass::new(ctx, &triangles).map_err(gpu_err)?,
            to_texture: PixelsToTexture::new(ctx).map_err(gpu_err)?,
            pixels: KeptBuffer::new("relight frame pixels", wgpu::BufferUsages::STORAGE),
            device: ctx.device.clone(),
            pixel_direct: None,
            gpu,
            sources,
        })
    }

    /// The solution on the GPU.
    pub fn gpu(&self) -> &GpuRelight {
        &self.gpu
    }

    /// Hands the frame the direct light of `view` at `size` gathered per pixel on the CPU
    /// (`k` values per pixel, pixel-major, [`crate::display::pixel_direct`]): frames of that
    /// view and size show it, others the elements' direct light, unless the shadow-mapped
    /// direct light was set ([`GpuRelight::set_shadowed_direct`]), which every frame uses.
    /// Values of another length are dropped.
    pub fn set_pixel_direct(&mut self, view: View, size: (u32, u32), values: Vec<Vec3>) {
        let ok = values.len() == size.0 as usize * size.1 as usize * self.sources.len();
        self.pixel_direct = ok.then_some((view, size, values));
    }

    /// True when the per-pixel direct light of `view` at `size` is in hand.
    pub fn has_pixel_direct(&self, view: &View, size: (u32, u32)) -> bool {
        self.pixel_direct
            .as_ref()
            .is_some_and(|(v, s, _)| v == view && *s == size)
    }
}

impl scene_core::gpu::GpuFrame for RelightFrame {
    fn name(&self) -> &str {
        "relight"
    }

    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), scene_core::Error> {
        let g = inputs.gbuffer;
        check_frame_target(target, g.width, g.height)?;
        let ids = self
            .ids
            .encode(encoder, inputs.view, g.width, g.height, Some(&g.depth))?;
        let elements = TriangleIdPass::gbuffer(g, ids)?;
        let factors = crate::relight::source_factors(&self.sources, inputs.lights);
        let bytes = u64::from(g.width) * u64::from(g.height) * 16;
        let pixels = self.pixels.ensure(&self.device, bytes).clone();
        let base = Vec3::ZERO;
        if self.gpu.has_shadowed_direct() {
            self.gpu.encode_display_shadowed(
                encoder,
                &elements,
                inputs.view,
                &factors,
                base,
                &pixels,
            )?;
        } else {
            let size = (g.width, g.height);
            let direct = self
                .pixel_direct
                .as_ref()
                .filter(|(v, s, _)| v == inputs.view && *s == size)
                .map(|(_, _, values)| values.as_slice());
            self.gpu.encode_display(
                encoder,
                &elements,
                inputs.view,
                &factors,
                base,
                direct,
                &pixels,
            )?;
        }
        self.to_texture
            .encode(&self.device, encoder, &pixels, target)?;
        Ok(())
    }
}
