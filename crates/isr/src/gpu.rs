//! The GPU path: the same frame as [`crate::render_cpu`] in wgpu compute passes, one shader
//! per pass in `shaders/isr/` (each pass module owns its pipeline, bind group layout and
//! dispatch), from a [`GpuGBuffer`] made by anyone into a caller-provided texture, with no
//! readback in the frame.
//!
//! Engine integration, a frame per submit:
//!
//! ```no_run
//! use isr::{GpuIsr, GpuIsrInputs, IsrScene, IsrSettings, ShadowSettings};
//! use scene_core::gpu::{GpuContext, GpuGBuffer};
//! use scene_core::{View, builtin};
//!
//! let ctx = GpuContext::new().unwrap();
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! // Once per scene: lights, shadow maps and emitters, uploaded.
//! let mut isr = GpuIsr::new(&ctx, &IsrScene::new(&scene, &ShadowSettings::default()).unwrap()).unwrap();
//! // The engine's own G-buffer (here an empty one) and its HDR target (Rgba32Float or
//! // Rgba16Float, with STORAGE_BINDING usage).
//! let gbuffer = GpuGBuffer::new(&ctx, 1024, 768).unwrap();
//! let target = ctx.device.create_texture(&wgpu::TextureDescriptor {
//!     label: Some("hdr"),
//!     size: wgpu::Extent3d { width: 1024, height: 768, depth_or_array_layers: 1 },
//!     mip_level_count: 1,
//!     sample_count: 1,
//!     dimension: wgpu::TextureDimension::D2,
//!     format: wgpu::TextureFormat::Rgba16Float,
//!     usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
//!     view_formats: &[],
//! });
//! let inputs = GpuIsrInputs { full: &gbuffer, coarse: None, view: &view };
//! // Records every pass into the engine's encoder; the engine submits it.
//! let mut encoder = ctx.device.create_command_encoder(&Default::default());
//! isr.encode(&mut encoder, &inputs, &IsrSettings::default(), &target).unwrap();
//! ctx.queue.submit([encoder.finish()]);
//! ```

use std::borrow::Cow;
use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use scene_core::gpu::{GpuContext, GpuError, GpuGBuffer};
use scene_core::{GBuffer, Image, View};
use wgpu::util::DeviceExt;

use crate::geometry::Screen;
use crate::lights::{IsrScene, LightKind};
use crate::radiosity::SamplePattern;
use crate::settings::{Blur, Estimator, IsrSettings, Sender};
use crate::shadow::MapKind;
use crate::{IsrError, PassTimings, blur, downsample, lighting, radiosity, upsample};

/// Workgroup edge of every ISR shader (8 x 8 invocations).
pub const WORKGROUP: u32 = 8;

/// The per-frame uniform block (`Globals` in the shaders).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// [`Screen::uniform`]; the `w` of the fifth row is the scene's extent.
    pub view: [[f32; 4]; 5],
    /// Full width, height; coarse width, height.
    pub sizes: [u32; 4],
    /// Samples, flags, light count, blur radius.
    pub config: [u32; 4],
    /// `k_dl`, `k_ssao`, `k_isr`, world radius.
    pub k: [f32; 4],
    /// Blur sigma, upsampling epsilon, upsampling normal power, ESM exponent.
    pub filters: [f32; 4],
    /// Shadow normal offset, depth bias (texels), unused, unused.
    pub shadow: [f32; 4],
}

/// Flag bits of [`Globals::config`]`[1]`.
pub mod flags {
    /// The indirect term is on.
    pub const INDIRECT: u32 = 1;
    /// SSAO is on.
    pub const SSAO: u32 = 2;
    /// AO multiplies the indirect term only.
    pub const AO_INDIRECT_ONLY: u32 = 4;
    /// Edge-aware blur.
    pub const EDGE_AWARE: u32 = 8;
    /// Eq. 25 as published.
    pub const THESIS: u32 = 16;
    /// Lit senders.
    pub const LIT: u32 = 32;
}

impl Globals {
    /// The block for one frame.
    pub fn new(
        screen: &Screen,
        scene: &IsrScene,
        settings: &IsrSettings,
        full: (u32, u32),
        coarse: (u32, u32),
    ) -> Self {
        let mut view = screen.uniform();
        view[4][3] = scene.extent;
        let mut f = 0;
        for (on, bit) in [
            (settings.indirect, flags::INDIRECT),
            (settings.ssao, flags::SSAO),
            (settings.ao_indirect_only, flags::AO_INDIRECT_ONLY),
            (settings.blur == Blur::EdgeAware, flags::EDGE_AWARE),
            (settings.estimator == Estimator::Thesis, flags::THESIS),
            (settings.sender == Sender::Lit, flags::LIT),
        ] {
            if on {
                f |= bit;
            }
        }
        Self {
            view,
            sizes: [full.0, full.1, coarse.0, coarse.1],
            config: [
                settings.samples,
                f,
                scene.lights.len() as u32,
                settings.blur_radius,
            ],
            k: [
                settings.k_dl,
                settings.k_ssao,
                settings.k_isr,
                settings.radius.world(scene.extent),
            ],
            filters: [
                settings.blur_sigma,
                settings.upsample_epsilon,
                settings.upsample_normal_power,
                scene.shadows.esm_exponent,
            ],
            shadow: [
                scene.shadows.normal_offset,
                scene.shadows.depth_bias,
                0.0,
                0.0,
            ],
        }
    }
}

/// One light in the light storage buffer (`Light` in `lighting.wgsl`, 112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    /// Position.
    pub position: [f32; 3],
    /// 0 point, 1 directional, 2 emitter sample.
    pub kind: u32,
    /// Intensity, irradiance or radiance.
    pub color: [f32; 3],
    /// Eq. 16's radius (0: inverse square).
    pub radius: f32,
    /// Travel direction or emitting normal.
    pub direction: [f32; 3],
    /// Emitter area of a sample.
    pub area: f32,
    /// Orthographic map: right vector.
    pub right: [f32; 3],
    /// Orthographic map: half width.
    pub half_extent: f32,
    /// Orthographic map: up vector.
    pub up: [f32; 3],
    /// Texels per side.
    pub map_res: u32,
    /// Orthographic map: eye.
    pub eye: [f32; 3],
    /// First texel, or `u32::MAX` without a map.
    pub map_offset: u32,
    /// Orthographic map: direction.
    pub forward: [f32; 3],
    /// 0 cube, 1 orthographic.
    pub map_kind: u32,
}

/// The lights of `scene` in the GPU layout.
pub fn gpu_lights(scene: &IsrScene) -> Vec<GpuLight> {
    scene
        .lights
        .iter()
        .map(|l| {
            let mut g = GpuLight {
                position: l.position.to_array(),
                kind: match l.kind {
                    LightKind::Point => 0,
                    LightKind::Directional => 1,
                    LightKind::EmitterSample => 2,
                },
                color: l.color.to_array(),
                radius: l.radius,
                direction: l.direction.to_array(),
                area: l.area,
                map_offset: u32::MAX,
                ..Default::default()
            };
            if let (Some(map), true) = (&l.shadow, scene.shadows.enabled) {
                g.map_res = map.resolution;
                g.map_offset = map.offset as u32;
                match map.kind {
                    MapKind::Cube { .. } => g.map_kind = 0,
                    MapKind::Ortho {
                        eye,
                        right,
                        up,
                        forward,
                        half_extent,
                    } => {
                        g.map_kind = 1;
                        g.eye = eye.to_array();
                        g.right = right.to_array();
                        g.up = up.to_array();
                        g.forward = forward.to_array();
                        g.half_extent = half_extent;
                    }
                }
            }
            g
        })
        .collect()
}

// ---- pipeline helpers used by the pass modules ----

/// A sampled (read with `textureLoad`) 2D texture binding: `u32` or non-filterable float.
pub(crate) fn texture_entry(binding: u32, uint: bool) -> wgpu::BindGroupLayoutEntry {
    if uint {
        layout::texture(binding, wgpu::TextureSampleType::Uint)
    } else {
        layout::float_texture(binding)
    }
}

pub(crate) use scene_core::gpu::layout;
pub(crate) use scene_core::gpu::layout::{
    storage_buffer as storage_buffer_entry, storage_texture as storage_texture_entry,
    uniform as uniform_entry,
};

/// A compute pipeline (entry point `main`) and its bind group layout.
pub(crate) struct Pipeline {
    pub pipeline: wgpu::ComputePipeline,
    pub layout: wgpu::BindGroupLayout,
}

impl Pipeline {
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &str,
        source: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
    ) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(Cow::Owned(source.to_string())),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { pipeline, layout }
    }

    /// A bind group with `resources[i]` at binding `i`.
    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: r.clone(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// A bind group with `buffers` (whole) at bindings `0..`, then a default view of each of
    /// `textures` at the bindings after them.
    pub(crate) fn bind_buffers_then_textures(
        &self,
        device: &wgpu::Device,
        buffers: &[&wgpu::Buffer],
        textures: &[&wgpu::Texture],
    ) -> wgpu::BindGroup {
        let views: Vec<wgpu::TextureView> = textures.iter().map(|t| view_of(t)).collect();
        let mut res: Vec<wgpu::BindingResource<'_>> =
            buffers.iter().map(|b| b.as_entire_binding()).collect();
        res.extend(views.iter().map(wgpu::BindingResource::TextureView));
        self.bind(device, &res)
    }

    /// Records one dispatch covering `width x height` invocations.
    pub(crate) fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
        width: u32,
        height: u32,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: None,
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
    }
}

fn view_of(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&Default::default())
}

fn buffer(ctx: &GpuContext, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    // Storage bindings may not be empty.
    let bytes: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage,
        })
}

fn rgba_texture(ctx: &GpuContext, label: &str, width: u32, height: u32) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// The inputs of a GPU frame.
#[derive(Clone, Copy, Debug)]
pub struct GpuIsrInputs<'a> {
    /// The full-resolution G-buffer (anyone's: only its colour textures are read).
    pub full: &'a GpuGBuffer,
    /// The coarse G-buffer; `None` downsamples `full` on the GPU (depth-aware, half size).
    pub coarse: Option<&'a GpuGBuffer>,
    /// The view both were rendered from.
    pub view: &'a View,
}

/// Intermediate textures of one size.
struct Targets {
    full: (u32, u32),
    coarse: (u32, u32),
    coarse_gbuffer: Option<GpuGBuffer>,
    senders: wgpu::Texture,
    radiosity: wgpu::Texture,
    tmp: wgpu::Texture,
    blurred: wgpu::Texture,
    upsampled: wgpu::Texture,
}

/// Which pass a recorded command belongs to (for timings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Downsample,
    Senders,
    Radiosity,
    Blur,
    Upsample,
    Lighting,
}

/// Where passes are recorded: one caller's encoder, or one submit per pass, timed.
enum Recorder<'a> {
    Into(&'a mut wgpu::CommandEncoder),
    Timed(&'a GpuContext, PassTimings),
}

impl Recorder<'_> {
    fn pass(&mut self, stage: Stage, f: impl FnOnce(&mut wgpu::CommandEncoder)) {
        match self {
            Recorder::Into(encoder) => f(encoder),
            Recorder::Timed(ctx, timings) => {
                let start = Instant::now();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                f(&mut encoder);
                ctx.queue.submit([encoder.finish()]);
                let _ = ctx.device.poll(wgpu::PollType::wait_indefinitely());
                let t = start.elapsed();
                match stage {
                    Stage::Downsample => timings.downsample += t,
                    Stage::Senders => timings.senders += t,
                    Stage::Radiosity => timings.radiosity += t,
                    Stage::Blur => timings.blur += t,
                    Stage::Upsample => timings.upsample += t,
                    Stage::Lighting => timings.lighting += t,
                }
            }
        }
    }
}

/// ISR on the GPU for one prepared scene: pipelines, the scene's lights, shadow maps and
/// emitters in storage buffers, and intermediate textures (recreated when the size changes).
pub struct GpuIsr {
    ctx: GpuContext,
    extent: f32,
    scene_globals: IsrScene,
    downsample: downsample::GpuPass,
    lighting: lighting::GpuPass,
    radiosity: radiosity::GpuPass,
    blur: blur::GpuPass,
    upsample: upsample::GpuPass,
    lights: wgpu::Buffer,
    shadow_texels: wgpu::Buffer,
    emitter_of: wgpu::Buffer,
    emitters: wgpu::Buffer,
    globals: wgpu::Buffer,
    /// Blur horizontal, blur vertical, senders, compose with ISR, compose without.
    params: [wgpu::Buffer; 5],
    pattern: Option<(u32, wgpu::Buffer)>,
    dummy: wgpu::Texture,
    targets: Option<Targets>,
}

impl std::fmt::Debug for GpuIsr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuIsr")
            .field("adapter", &self.ctx.adapter_summary())
            .field("lights", &self.scene_globals.lights.len())
            .finish()
    }
}

impl GpuIsr {
    /// Compiles the pipelines and uploads `scene`'s lights, shadow maps and emitters.
    /// Errors when a buffer exceeds the device's storage-buffer limit.
    pub fn new(ctx: &GpuContext, scene: &IsrScene) -> Result<Self, IsrError> {
        scoped(ctx, || Self::create(ctx, scene))
    }

    fn create(ctx: &GpuContext, scene: &IsrScene) -> Result<Self, IsrError> {
        let device = &ctx.device;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let limit = device.limits().max_storage_buffer_binding_size;
        let texel_bytes = scene.shadow_texels.len() as u64 * 4;
        if texel_bytes > limit {
            return Err(IsrError::Budget(format!(
                "shadow maps take {texel_bytes} bytes, over the device's storage buffer limit \
                 of {limit}; lower ShadowSettings resolutions or max_texels"
            )));
        }
        let lights = gpu_lights(scene);
        let mut table: Vec<[f32; 4]> = Vec::with_capacity(2 * scene.emitters.entries.len());
        for (l, n) in &scene.emitters.entries {
            table.push(l.extend(0.0).to_array());
            table.push(n.extend(0.0).to_array());
        }
        let per_triangle: &[u32] = if scene.emitters.entries.is_empty() {
            // No emitters: no triangle needs looking up.
            &[]
        } else {
            &scene.emitters.per_triangle
        };
        let uniform = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let param =
            |mode: [u32; 4]| buffer(ctx, "isr pass params", bytemuck::bytes_of(&mode), uniform);
        let this = Self {
            ctx: ctx.clone(),
            extent: scene.extent,
            scene_globals: IsrScene {
                shadow_texels: Vec::new(),
                emitters: Default::default(),
                ..scene.clone()
            },
            downsample: downsample::GpuPass::new(device),
            lighting: lighting::GpuPass::new(device),
            radiosity: radiosity::GpuPass::new(device),
            blur: blur::GpuPass::new(device),
            upsample: upsample::GpuPass::new(device),
            lights: buffer(ctx, "isr lights", bytemuck::cast_slice(&lights), storage),
            shadow_texels: buffer(
                ctx,
                "isr shadow maps",
                bytemuck::cast_slice(&scene.shadow_texels),
                storage,
            ),
            emitter_of: buffer(
                ctx,
                "isr emitter index",
                bytemuck::cast_slice(per_triangle),
                storage,
            ),
            emitters: buffer(ctx, "isr emitters", bytemuck::cast_slice(&table), storage),
            globals: buffer(
                ctx,
                "isr globals",
                bytemuck::bytes_of(&Globals::default()),
                uniform,
            ),
            params: [
                param([1, 0, 0, 0]),
                param([0, 0, 0, 0]),
                param([0, 0, 0, 0]),
                param([1, 1, 0, 0]),
                param([1, 0, 0, 0]),
            ],
            pattern: None,
            dummy: rgba_texture(ctx, "isr dummy", 1, 1),
            targets: None,
        };
        Ok(this)
    }

    /// The context the pipelines live on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// A `width x height` `Rgba32Float` texture usable as [`GpuIsr::render`]'s output (with
    /// `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC` usage).
    pub fn output_texture(&self, width: u32, height: u32) -> Result<wgpu::Texture, IsrError> {
        self.ctx.check_texture_size(width, height)?;
        Ok(rgba_texture(&self.ctx, "isr output", width, height))
    }

    /// Blocks until the device has finished all submitted work (for timing).
    pub fn wait(&self) -> Result<(), IsrError> {
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(format!("device poll failed: {e}")).into())
    }

    /// Records one frame into `encoder` (queue writes of the frame's uniforms happen now
    /// and apply at the next submit, so submit one frame before encoding the next). Nothing
    /// is read back. `output` must be `full`'s size, `Rgba32Float` or `Rgba16Float`, with
    /// `STORAGE_BINDING` usage.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<(), IsrError> {
        self.record(&mut Recorder::Into(encoder), inputs, settings, output)
    }

    /// Records and submits one frame (no readback, no waiting).
    pub fn render(
        &mut self,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<(), IsrError> {
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, inputs, settings, output)?;
        self.ctx.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Runs one frame submitting and waiting for each pass, and returns the wall-clock time
    /// of each (for benchmarks; slower than [`GpuIsr::render`]).
    pub fn render_timed(
        &mut self,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<PassTimings, IsrError> {
        let ctx = self.ctx.clone();
        let mut rec = Recorder::Timed(&ctx, PassTimings::default());
        self.record(&mut rec, inputs, settings, output)?;
        match rec {
            Recorder::Timed(_, t) => Ok(t),
            Recorder::Into(_) => Ok(PassTimings::default()),
        }
    }

    /// Convenience for tests and the `Technique`: uploads CPU G-buffers (`coarse: None`
    /// downsamples on the GPU), runs a timed frame into an `Rgba32Float` texture and reads
    /// the image back.
    pub fn render_gbuffers(
        &mut self,
        full: &GBuffer,
        coarse: Option<&GBuffer>,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        crate::frame::check_gbuffer("full", full)?;
        if let Some(c) = coarse {
            crate::frame::check_gbuffer("coarse", c)?;
        }
        let ctx = self.ctx.clone();
        scoped(&ctx, || self.run_uploaded(full, coarse, view, settings))
    }

    fn run_uploaded(
        &mut self,
        full: &GBuffer,
        coarse: Option<&GBuffer>,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        let ctx = self.ctx.clone();
        let gfull = GpuGBuffer::upload(&ctx, full)?;
        let gcoarse = coarse.map(|c| GpuGBuffer::upload(&ctx, c)).transpose()?;
        let output = rgba_texture(&ctx, "isr output", full.width, full.height);
        let inputs = GpuIsrInputs {
            full: &gfull,
            coarse: gcoarse.as_ref(),
            view,
        };
        let timings = self.render_timed(&inputs, settings, &output)?;
        let texels = ctx.read_texture_rgba32f(&output)?;
        let image = Image {
            width: full.width,
            height: full.height,
            pixels: texels
                .into_iter()
                .map(|[r, g, b, _]| glam::Vec3::new(r, g, b))
                .collect(),
        };
        Ok((image, timings))
    }

    /// [`GpuIsr::render_gbuffers`] with the coarse buffer made on the GPU.
    pub fn render_gbuffer(
        &mut self,
        full: &GBuffer,
        view: &View,
        settings: &IsrSettings,
    ) -> Result<(Image, PassTimings), IsrError> {
        self.render_gbuffers(full, None, view, settings)
    }

    fn check_output(&self, output: &wgpu::Texture, full: &GpuGBuffer) -> Result<(), IsrError> {
        let format = output.format();
        if !matches!(
            format,
            wgpu::TextureFormat::Rgba32Float | wgpu::TextureFormat::Rgba16Float
        ) {
            return Err(GpuError::WrongFormat {
                expected: "Rgba32Float or Rgba16Float",
                found: format,
            }
            .into());
        }
        if !output
            .usage()
            .contains(wgpu::TextureUsages::STORAGE_BINDING)
        {
            return Err(GpuError::Validation(format!(
                "the ISR output texture needs STORAGE_BINDING usage (has {:?})",
                output.usage()
            ))
            .into());
        }
        if (output.width(), output.height()) != (full.width, full.height) {
            return Err(IsrError::SizeMismatch(format!(
                "output texture {}x{}, G-buffer {}x{}",
                output.width(),
                output.height(),
                full.width,
                full.height
            )));
        }
        Ok(())
    }

    fn ensure_targets(
        &mut self,
        full: (u32, u32),
        coarse: (u32, u32),
        own_coarse: bool,
    ) -> Result<(), IsrError> {
        let fits = self.targets.as_ref().is_some_and(|t| {
            t.full == full && t.coarse == coarse && t.coarse_gbuffer.is_some() == own_coarse
        });
        if fits {
            return Ok(());
        }
        let ctx = &self.ctx;
        let (cw, ch) = coarse;
        self.targets = Some(Targets {
            full,
            coarse,
            coarse_gbuffer: if own_coarse {
                Some(GpuGBuffer::new(ctx, cw, ch)?)
            } else {
                None
            },
            senders: rgba_texture(ctx, "isr senders", cw, ch),
            radiosity: rgba_texture(ctx, "isr radiosity", cw, ch),
            tmp: rgba_texture(ctx, "isr blur tmp", cw, ch),
            blurred: rgba_texture(ctx, "isr blurred", cw, ch),
            upsampled: rgba_texture(ctx, "isr upsampled", full.0, full.1),
        });
        Ok(())
    }

    fn record(
        &mut self,
        rec: &mut Recorder<'_>,
        inputs: &GpuIsrInputs<'_>,
        settings: &IsrSettings,
        output: &wgpu::Texture,
    ) -> Result<(), IsrError> {
        settings.validate(self.extent)?;
        let full = inputs.full;
        self.check_output(output, full)?;
        let full_size = (full.width, full.height);
        let coarse_size = match inputs.coarse {
            Some(c) => (c.width, c.height),
            None => downsample::coarse_size(full.width, full.height),
        };
        self.ensure_targets(full_size, coarse_size, inputs.coarse.is_none())?;
        if self
            .pattern
            .as_ref()
            .is_none_or(|(n, _)| *n != settings.samples)
        {
            let data = SamplePattern::new(settings.samples).to_gpu();
            self.pattern = Some((
                settings.samples,
                buffer(
                    &self.ctx,
                    "isr sample pattern",
                    bytemuck::cast_slice(&data),
                    wgpu::BufferUsages::STORAGE,
                ),
            ));
        }
        let screen = Screen::new(inputs.view);
        let globals = Globals::new(
            &screen,
            &self.scene_globals,
            settings,
            full_size,
            coarse_size,
        );
        self.ctx
            .queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
        let device = &self.ctx.device;
        let Some(t) = self.targets.as_ref() else {
            return Err(IsrError::SizeMismatch("no intermediate textures".into()));
        };
        let Some((_, pattern)) = self.pattern.as_ref() else {
            return Err(IsrError::SizeMismatch("no sample pattern".into()));
        };
        let coarse: &GpuGBuffer = match (inputs.coarse, t.coarse_gbuffer.as_ref()) {
            (Some(c), _) => c,
            (None, Some(own)) => {
                let bg = self.downsample.bind(device, full, own);
                rec.pass(Stage::Downsample, |e| {
                    self.downsample
                        .pipeline
                        .dispatch(e, &bg, own.width, own.height)
                });
                own
            }
            (None, None) => return Err(IsrError::SizeMismatch("no coarse buffer".into())),
        };
        let run_isr = !settings.is_direct_only() && self.scene_globals.has_light();
        let scene_buffers = lighting::SceneBuffers {
            lights: &self.lights,
            shadow_texels: &self.shadow_texels,
            emitter_of: &self.emitter_of,
            emitters: &self.emitters,
        };
        if run_isr {
            let lit = settings.indirect && settings.sender == Sender::Lit;
            if lit {
                let lp = self.lighting.pipeline(wgpu::TextureFormat::Rgba32Float);
                let bg = lighting::bind(
                    lp,
                    device,
                    &self.globals,
                    &self.params[2],
                    coarse,
                    &self.dummy,
                    &scene_buffers,
                    &view_of(&t.senders),
                );
                rec.pass(Stage::Senders, |e| {
                    lp.dispatch(e, &bg, coarse.width, coarse.height)
                });
            }
            let senders = if lit { &t.senders } else { &self.dummy };
            let bg = self.radiosity.bind(
                device,
                &self.globals,
                pattern,
                coarse,
                senders,
                &t.radiosity,
            );
            rec.pass(Stage::Radiosity, |e| {
                self.radiosity
                    .pipeline
                    .dispatch(e, &bg, coarse.width, coarse.height)
            });
            let blurred = if settings.blur_radius > 0 {
                let h = self.blur.bind(
                    device,
                    &self.globals,
                    &self.params[0],
                    coarse,
                    &t.radiosity,
                    &t.tmp,
                );
                let v = self.blur.bind(
                    device,
                    &self.globals,
                    &self.params[1],
                    coarse,
                    &t.tmp,
                    &t.blurred,
                );
                rec.pass(Stage::Blur, |e| {
                    self.blur
                        .pipeline
                        .dispatch(e, &h, coarse.width, coarse.height);
                    self.blur
                        .pipeline
                        .dispatch(e, &v, coarse.width, coarse.height);
                });
                &t.blurred
            } else {
                &t.radiosity
            };
            let bg = self
                .upsample
                .bind(device, &self.globals, full, coarse, blurred, &t.upsampled);
            rec.pass(Stage::Upsample, |e| {
                self.upsample
                    .pipeline
                    .dispatch(e, &bg, full.width, full.height)
            });
        }
        let out_view = view_of(output);
        let (isr_tex, params) = if run_isr {
            (&t.upsampled, &self.params[3])
        } else {
            (&self.dummy, &self.params[4])
        };
        let lighting_pass = self.lighting.pipeline(output.format());
        let bg = lighting::bind(
            lighting_pass,
            device,
            &self.globals,
            params,
            full,
            isr_tex,
            &scene_buffers,
            &out_view,
        );
        rec.pass(Stage::Lighting, |e| {
            lighting_pass.dispatch(e, &bg, full.width, full.height)
        });
        Ok(())
    }
}

/// Runs `f` inside a validation error scope; a captured error becomes
/// [`GpuError::Validation`].
fn scoped<T>(ctx: &GpuContext, f: impl FnOnce() -> Result<T, IsrError>) -> Result<T, IsrError> {
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let result = f();
    if let Some(Some(e)) = ready(scope.pop()) {
        return Err(GpuError::Validation(e.to_string()).into());
    }
    result
}

/// Blocks on a future that wgpu resolves without needing to be polled by an executor (the
/// error scopes of native backends).
pub(crate) fn ready<F: std::future::Future>(f: F) -> Option<F::Output> {
    let mut f = std::pin::pin!(f);
    let waker = std::task::Waker::noop();
    match f.as_mut().poll(&mut std::task::Context::from_waker(waker)) {
        std::task::Poll::Ready(v) => Some(v),
        std::task::Poll::Pending => None,
    }
}
