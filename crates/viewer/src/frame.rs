//! The frame on the GPU: the scene's G-buffer, each mode on screen drawn through the frame
//! contract ([`scene_core::gpu::GpuFrame`]) into a frame-sized target and resolved into the
//! buffer the composed frame ([`Layout`]) reads, and its presentation. Nothing is read back in a
//! frame; [`Renderer::read_frame`] (screenshots) and [`Renderer::read_slot`] (the error
//! view's mean, a few times a second) are the only readbacks.

use std::collections::HashMap;
use std::sync::Arc;

use gbuffer::{GpuPreparedScene, GpuRasterizer};
use glam::Vec3;
use ibrr_ldc::{IbrrFrame, IbrrTechnique};
use isr::{Intermediate, IsrFrame, IsrSettings, LightSenders, LightSet, ShadowSettings};
use relight_pr::packed::Precision;
use relight_pr::{Prepared, RelightFrame, RelightFrameSettings, RelightTechnique};
use scene_core::gpu::compute::ComputePass;
use scene_core::gpu::layout::{
    float_texture, storage_buffer, storage_buffer_rw, storage_texture, uniform,
};
use scene_core::gpu::shader::ShaderPass;
use scene_core::gpu::{FrameInputs, FrameWriter, GpuContext, GpuFrame, GpuGBuffer};
use scene_core::reference::{PathTracerFrame, PathTracerFrameSettings};
use scene_core::{Image, LightState, Scene, View};

use crate::mode::{Layout, Mode};

macro_rules! viewer_pass {
    ($name:literal, $file:literal) => {
        ShaderPass::new($name, scene_core::wgsl_file!("viewer", $file), &[])
    };
}

/// The resolve pass (`shaders/viewer/resolve.wgsl`).
pub const RESOLVE: ShaderPass = viewer_pass!("viewer/resolve", "resolve.wgsl");
/// The resolve pass writing a frame target texture (the ISR buffer views).
pub const RESOLVE_TO_TEXTURE: ShaderPass =
    RESOLVE.with_defs("viewer/resolve (to texture)", &["TO_TEXTURE"]);
/// The compose pass (`shaders/viewer/compose.wgsl`).
pub const COMPOSE: ShaderPass = viewer_pass!("viewer/compose", "compose.wgsl");
/// The present pass (`shaders/viewer/present.wgsl`).
pub const PRESENT: ShaderPass = viewer_pass!("viewer/present", "present.wgsl");
/// Every shader pass of the viewer, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] = &[RESOLVE, RESOLVE_TO_TEXTURE, COMPOSE, PRESENT];

/// The ISR settings of an ISR-family mode, and which of its textures the mode shows
/// (`None`: the output; else an intermediate buffer) with which channel (0 colour, 1 the
/// fourth channel as grey).
pub fn isr_view(mode: Mode) -> Option<(IsrSettings, Option<Intermediate>, u32)> {
    Some(match mode {
        Mode::Dl => (IsrSettings::dl(), None, 0),
        Mode::Isr => (IsrSettings::default(), None, 0),
        Mode::IsrIndirect => (
            IsrSettings {
                k_dl: 0.0,
                ..IsrSettings::default()
            },
            None,
            0,
        ),
        Mode::IsrAo => (
            IsrSettings {
                indirect: false,
                ssao: true,
                ..IsrSettings::default()
            },
            Some(Intermediate::Upsampled),
            1,
        ),
        Mode::IsrCoarse => (IsrSettings::default(), Some(Intermediate::Blurred), 0),
        _ => return None,
    })
}

/// The frame size for a `width x height` window at render scale `scale` under limits of
/// `max_bytes` per buffer (16 bytes a pixel) and `max_side` pixels a side: scaled, then
/// shrunk with the aspect ratio kept until both hold; at least 1 x 1.
pub fn fit_frame(width: u32, height: u32, scale: f32, max_bytes: u64, max_side: u32) -> (u32, u32) {
    let (w, h) = (width.max(1) as f64, height.max(1) as f64);
    let by_bytes = (max_bytes as f64 / (w * h * 16.0)).sqrt();
    let by_side = max_side as f64 / w.max(h);
    let s = (scale as f64).min(by_bytes).min(by_side).min(1.0);
    let size = |x: f64| ((x * s).floor() as u32).max(1);
    (size(w), size(h))
}

/// Relighting on the frame contract: what the technique prepared (shared with the per-pixel
/// direct light's worker) and its frame.
pub struct RelightGpu {
    /// What the technique prepared (solution, meshing, welding, rays).
    pub prepared: Arc<Prepared>,
    frame: RelightFrame,
}

impl RelightGpu {
    /// True when the per-pixel direct light of `view` at `size` is in hand.
    pub fn has_direct(&self, view: &View, size: (u32, u32)) -> bool {
        self.frame.has_pixel_direct(view, size)
    }
}

/// One of ISR's buffers shown as a mode (the ambient accessibility, the blurred coarse
/// radiosity): ISR's frame, then the buffer resolved into the target (nearest texel,
/// `channel` 0 colour or 1 the fourth channel as grey). A frame on the contract like any
/// other, so the frame loop treats it as one.
struct IsrBufferView {
    isr: IsrFrame,
    which: Intermediate,
    resolve: ComputePass,
    params: wgpu::Buffer,
    bound: scene_core::gpu::Keyed<(wgpu::Texture, wgpu::Texture), wgpu::BindGroup>,
    device: wgpu::Device,
}

impl GpuFrame for IsrBufferView {
    fn name(&self) -> &str {
        "isr buffer"
    }

    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs<'_>,
        target: &wgpu::Texture,
    ) -> Result<(), scene_core::Error> {
        self.isr.encode(encoder, inputs, target)?;
        let source = self
            .isr
            .isr
            .intermediate(self.which)
            .ok_or_else(|| {
                scene_core::gpu::GpuError::Validation("ISR has no intermediate buffers yet".into())
            })?
            .clone();
        let key = (source, target.clone());
        let bind = self.bound.get_or_make(key, |(source, target)| {
            let source_view = source.create_view(&Default::default());
            let target_view = target.create_view(&Default::default());
            self.resolve.bind(
                &self.device,
                &[
                    self.params.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&source_view),
                    wgpu::BindingResource::TextureView(&target_view),
                ],
            )
        });
        self.resolve
            .dispatch(encoder, bind, target.width(), target.height(), None);
        Ok(())
    }
}

/// Buffers, textures and bind groups of one frame size, made once per size.
struct Targets {
    width: u32,
    height: u32,
    gbuffer: GpuGBuffer,
    /// The targets of the left and right modes (every mode is a `GpuFrame`).
    slot_textures: [wgpu::Texture; 2],
    /// The same resolved into buffers the compose pass reads.
    slots: [wgpu::Buffer; 2],
    reference: wgpu::Buffer,
    frame: wgpu::Buffer,
    resolve_binds: [wgpu::BindGroup; 2],
    /// Compose bind groups by (left is the reference, right is the reference).
    compose_binds: [[wgpu::BindGroup; 2]; 2],
    present_bind: wgpu::BindGroup,
}

/// What one frame shows.
#[derive(Clone, Copy, Debug)]
pub struct FrameSpec<'a> {
    /// The view.
    pub view: &'a View,
    /// Light settings.
    pub lights: &'a LightState,
    /// The (left) mode.
    pub mode: Mode,
    /// The layout.
    pub layout: Layout,
    /// The error view's scale: the per-pixel error mapped to the top of the colour map.
    pub error_scale: f32,
    /// The exposure in stops the frame is presented at.
    pub exposure: f32,
    /// The window's surface size in pixels.
    pub surface: (u32, u32),
}

/// Per-stage GPU times of a frame (scene-core's one stage profiler).
pub use crate::profiler::StageProfiler as Profiler;

/// The viewer's GPU side. Every mode is a method on the frame contract
/// ([`scene_core::gpu::GpuFrame`]) reading the frame's G-buffer, view and light state and
/// writing its slot's target texture; the frame loop has one path for all of them. Nothing
/// is created per frame once a mode and a size have been seen.
pub struct Renderer {
    /// The context (device, queue).
    pub ctx: GpuContext,
    raster: GpuRasterizer,
    scene_gpu: GpuPreparedScene,
    /// The scene's lights and shadow maps, for the ISR-family modes' frames.
    light_set: LightSet,
    /// The scene, for the light-space senders.
    scene: Arc<Scene>,
    /// The light-space senders of the ISR modes' settings ([`IsrSettings::light_senders`]),
    /// made when an ISR mode is first shown.
    light_senders: Option<LightSenders>,
    /// The ISR-family modes' frames by mode and slot (a mode on both sides of a split has
    /// a frame for each, so that neither remakes its bind groups), each made when first
    /// shown.
    isr_frames: HashMap<(Mode, usize), Box<dyn GpuFrame>>,
    resolve: ComputePass,
    resolve_to_texture: ComputePass,
    compose: ComputePass,
    present: wgpu::RenderPipeline,
    present_layout: wgpu::BindGroupLayout,
    surface_is_srgb: bool,
    /// Uniforms written by the frame's encoder: the resolve's (per size), compose's and
    /// present's.
    resolve_params: wgpu::Buffer,
    compose_params: wgpu::Buffer,
    present_params: wgpu::Buffer,
    writer: FrameWriter,
    targets: Option<Targets>,
    /// Relighting, once its solve is done.
    pub relight: Option<RelightGpu>,
    /// The IBRR, once constructed.
    pub ibrr: Option<IbrrFrame>,
    /// The progressive reference on the GPU ([`Renderer::use_gpu_reference`]) and the
    /// frame-sized target its frames write (the image reaches the reference buffer by a
    /// copy of its running mean).
    gpu_reference: Option<(PathTracerFrame, Option<wgpu::Texture>)>,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ResolveParams {
    width: u32,
    height: u32,
    channel: u32,
    pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ComposeParams {
    width: u32,
    height: u32,
    layout: u32,
    divider: u32,
    error_scale: f32,
    pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct PresentParams {
    width: u32,
    height: u32,
    scale: f32,
    encode: u32,
    surface_width: u32,
    surface_height: u32,
    pad: [u32; 2],
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

impl Renderer {
    /// Uploads `scene`, builds the lights and shadow maps of the ISR-family modes and
    /// compiles the viewer's passes; `surface_format` is the window's.
    pub fn new(
        ctx: GpuContext,
        scene: Arc<Scene>,
        surface_format: wgpu::TextureFormat,
    ) -> Result<Self, String> {
        let raster = GpuRasterizer::new(&ctx).map_err(err)?;
        let scene_gpu = raster.upload(&scene).map_err(err)?;
        let light_set = LightSet::new(&scene, &ShadowSettings::default()).map_err(err)?;
        let device = &ctx.device;
        let modules =
            [&RESOLVE, &RESOLVE_TO_TEXTURE, &COMPOSE, &PRESENT].map(|p| p.create_module(device));
        let [
            resolve_module,
            to_texture_module,
            compose_module,
            present_module,
        ] = modules;
        let (resolve_module, to_texture_module, compose_module, module) = (
            resolve_module.map_err(err)?,
            to_texture_module.map_err(err)?,
            compose_module.map_err(err)?,
            present_module.map_err(err)?,
        );
        let (resolve, resolve_to_texture, compose, present, present_layout) = ctx
            .validated(|| {
                let resolve = ComputePass::from_module(
                    device,
                    "viewer resolve",
                    &resolve_module,
                    &[uniform(0), float_texture(1), storage_buffer_rw(2)],
                    &[],
                );
                let resolve_to_texture = ComputePass::from_module(
                    device,
                    "viewer resolve to texture",
                    &to_texture_module,
                    &[
                        uniform(0),
                        float_texture(1),
                        storage_texture(2, wgpu::TextureFormat::Rgba32Float),
                    ],
                    &[],
                );
                let compose = ComputePass::from_module(
                    device,
                    "viewer compose",
                    &compose_module,
                    &[
                        uniform(0),
                        storage_buffer(1),
                        storage_buffer(2),
                        storage_buffer(3),
                        storage_buffer_rw(4),
                    ],
                    &[],
                );
                let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
                    binding,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                };
                let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("viewer present"),
                    entries: &[
                        entry(0, wgpu::BufferBindingType::Uniform),
                        entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
                    ],
                });
                let pipeline_layout =
                    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("viewer present"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
                let present = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("viewer present"),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_main"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_main"),
                        compilation_options: Default::default(),
                        targets: &[Some(surface_format.into())],
                    }),
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: None,
                    multisample: wgpu::MultisampleState::default(),
                    multiview_mask: None,
                    cache: None,
                });
                (resolve, resolve_to_texture, compose, present, layout)
            })
            .map_err(err)?;
        let params = |label: &str, bytes: usize| {
            ctx.frame_buffer(label, bytes as u64, wgpu::BufferUsages::UNIFORM)
        };
        Ok(Self {
            raster,
            scene_gpu,
            light_set,
            scene: scene.clone(),
            light_senders: None,
            isr_frames: HashMap::new(),
            resolve,
            resolve_to_texture,
            compose,
            present,
            present_layout,
            surface_is_srgb: surface_format.is_srgb(),
            resolve_params: params("viewer resolve", std::mem::size_of::<ResolveParams>()),
            compose_params: params("viewer compose", std::mem::size_of::<ComposeParams>()),
            present_params: params("viewer present", std::mem::size_of::<PresentParams>()),
            writer: FrameWriter::new(&ctx.device, 1024),
            targets: None,
            relight: None,
            ibrr: None,
            gpu_reference: None,
            ctx,
        })
    }

    /// The frame size in pixels (zero before the first [`Renderer::resize`]).
    pub fn size(&self) -> (u32, u32) {
        self.targets
            .as_ref()
            .map_or((0, 0), |t| (t.width, t.height))
    }

    /// The frame size for a `width x height` window at render scale `scale`: scaled, then
    /// shrunk (keeping the aspect ratio) until a frame buffer fits the adapter's
    /// storage-binding and buffer limits and its 2D texture limit.
    pub fn fit(&self, width: u32, height: u32, scale: f32) -> (u32, u32) {
        let max_bytes = self.ctx.storage_binding_limit();
        fit_frame(
            width,
            height,
            scale,
            max_bytes,
            self.ctx.device.limits().max_texture_dimension_2d,
        )
    }

    /// (Re)creates the frame-sized buffers, textures and bind groups.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), String> {
        if self.size() == (width, height) {
            return Ok(());
        }
        let ctx = &self.ctx;
        ctx.check_texture_size(width, height).map_err(err)?;
        let bytes = width as u64 * height as u64 * 16;
        let limit = ctx.storage_binding_limit();
        if bytes > limit {
            return Err(format!(
                "a {width}x{height} frame needs {bytes}-byte buffers; this adapter binds at most {limit}"
            ));
        }
        let buffer = |label: &str| ctx.pixel_buffer(label, width, height);
        let texture = |label: &str| {
            ctx.create_texture_2d(
                label,
                width,
                height,
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::STORAGE_BINDING
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
            )
        };
        let slot_textures = [texture("viewer left"), texture("viewer right")];
        let slots = [buffer("viewer left"), buffer("viewer right")];
        let (reference, frame) = (buffer("viewer reference"), buffer("viewer frame"));
        // The resolve's size and channel are the frame's until the next resize.
        ctx.queue.write_buffer(
            &self.resolve_params,
            0,
            bytemuck::bytes_of(&ResolveParams {
                width,
                height,
                channel: 0,
                pad: 0,
            }),
        );
        let resolve_binds = [0, 1].map(|i| {
            let view = slot_textures[i].create_view(&Default::default());
            self.resolve.bind(
                &ctx.device,
                &[
                    self.resolve_params.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&view),
                    slots[i].as_entire_binding(),
                ],
            )
        });
        let compose_bind = |a: &wgpu::Buffer, b: &wgpu::Buffer| {
            self.compose.bind(
                &ctx.device,
                &[
                    self.compose_params.as_entire_binding(),
                    a.as_entire_binding(),
                    b.as_entire_binding(),
                    reference.as_entire_binding(),
                    frame.as_entire_binding(),
                ],
            )
        };
        let compose_binds = [
            [
                compose_bind(&slots[0], &slots[1]),
                compose_bind(&slots[0], &reference),
            ],
            [
                compose_bind(&reference, &slots[1]),
                compose_bind(&reference, &reference),
            ],
        ];
        let present_bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("viewer present"),
            layout: &self.present_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.present_params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: frame.as_entire_binding(),
                },
            ],
        });
        self.targets = Some(Targets {
            width,
            height,
            gbuffer: GpuGBuffer::new(ctx, width, height).map_err(err)?,
            slot_textures,
            slots,
            reference,
            frame,
            resolve_binds,
            compose_binds,
            present_bind,
        });
        Ok(())
    }

    /// Puts relighting's solution on the GPU (after its solve) on the frame contract, with
    /// `shadow_maps` its lights' shadow maps for the per-frame direct light too; returns what
    /// was prepared, shared.
    pub fn set_relight(
        &mut self,
        technique: RelightTechnique,
        shadow_maps: bool,
    ) -> Result<Arc<Prepared>, String> {
        let p = Arc::new(
            technique
                .into_prepared()
                .ok_or("relighting was not prepared")?,
        );
        let lights = if shadow_maps {
            Some(LightSet::new(&p.scene, &ShadowSettings::default()).map_err(err)?)
        } else {
            None
        };
        let footprint = match relight_pr::direct::DirectLight::shadow_maps() {
            relight_pr::direct::DirectLight::ShadowMaps { footprint, .. } => footprint,
            _ => 1,
        };
        let settings = RelightFrameSettings {
            precision: Precision::F32,
            shadowed_direct: lights.as_ref().map(|l| (l, footprint)),
        };
        let frame = RelightFrame::prepare(&self.ctx, &p, &settings).map_err(err)?;
        self.relight = Some(RelightGpu {
            prepared: p.clone(),
            frame,
        });
        Ok(p)
    }

    /// Hands relighting the per-pixel direct light of `view` at `size` (`k` values per
    /// pixel, pixel-major); frames of that view and size use it.
    pub fn set_relight_direct(&mut self, view: View, size: (u32, u32), values: Vec<Vec3>) {
        if let Some(r) = self.relight.as_mut() {
            r.frame.set_pixel_direct(view, size, values);
        }
    }

    /// Puts the IBRR's layered depth cube on the GPU (after its construction) on the frame
    /// contract; frames relight it to their light state.
    pub fn set_ibrr(&mut self, technique: IbrrTechnique) -> Result<(), String> {
        self.ibrr = Some(IbrrFrame::prepare(&self.ctx, technique).map_err(err)?);
        Ok(())
    }

    /// Makes the progressive reference a GPU path tracer on the viewer's device
    /// ([`PathTracerFrame`]) with `settings`: frames that show the reference then add
    /// samples on the GPU ([`Renderer::encode_reference`]) instead of the CPU worker's
    /// uploads.
    pub fn use_gpu_reference(
        &mut self,
        scene: Arc<Scene>,
        settings: PathTracerFrameSettings,
    ) -> Result<(), String> {
        let frame = PathTracerFrame::prepare(&self.ctx, scene, settings).map_err(err)?;
        self.gpu_reference = Some((frame, None));
        Ok(())
    }

    /// True when the reference is traced on the GPU.
    pub fn has_gpu_reference(&self) -> bool {
        self.gpu_reference.is_some()
    }

    /// Stops the GPU reference at `max_spp` samples per pixel (frames after that show it).
    pub fn set_reference_max_spp(&mut self, max_spp: u32) {
        if let Some((frame, _)) = self.gpu_reference.as_mut() {
            frame.set_max_spp(max_spp);
        }
    }

    /// Records one frame of the GPU reference for `view` under `lights` (a new view, size or
    /// light state starts it again; otherwise it adds samples until its maximum) and copies
    /// its running mean into the buffer the reference modes show. Returns the samples per
    /// pixel of the image, or `None` without a GPU reference or a frame size.
    pub fn encode_reference(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        view: &View,
        lights: &LightState,
    ) -> Result<Option<u32>, String> {
        let (Some((frame, target)), Some(t)) = (self.gpu_reference.as_mut(), &self.targets) else {
            return Ok(None);
        };
        if target
            .as_ref()
            .is_none_or(|x| (x.width(), x.height()) != (t.width, t.height))
        {
            *target = Some(self.ctx.create_texture_2d(
                "viewer gpu reference",
                t.width,
                t.height,
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::STORAGE_BINDING,
            ));
        }
        let target = target.as_ref().expect("made above");
        let inputs = FrameInputs {
            gbuffer: &t.gbuffer,
            view,
            lights,
        };
        self.ctx
            .validated_with(|| frame.encode(encoder, &inputs, target))
            .map_err(err)?;
        frame.copy_mean_to(encoder, &t.reference);
        Ok(Some(frame.spp()))
    }

    /// Reads the reference buffer back (the error view's mean error against a GPU
    /// reference, a few times a second).
    pub fn read_reference(&self) -> Result<Image, String> {
        let t = self.targets.as_ref().ok_or("no frame yet")?;
        self.read_buffer(&t.reference)
    }

    /// Uploads the reference's accumulated image (row-major, the frame's size).
    pub fn upload_reference(&self, pixels: &[Vec3]) {
        let Some(t) = &self.targets else { return };
        if pixels.len() != t.width as usize * t.height as usize {
            return;
        }
        let data: Vec<[f32; 4]> = pixels.iter().map(|p| p.extend(1.0).to_array()).collect();
        self.ctx
            .queue
            .write_buffer(&t.reference, 0, bytemuck::cast_slice(&data));
    }

    /// Clears the reference image (a restart).
    pub fn clear_reference(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(t) = &self.targets {
            encoder.clear_buffer(&t.reference, 0, None);
        }
    }

    /// The frame of `mode`: relighting's and the IBRR's once precomputed, direct light (DL)
    /// meanwhile, never a black frame (the panel says so); the ISR family's made when first
    /// shown.
    fn frame_of(&mut self, mode: Mode, slot: usize) -> Result<&mut dyn GpuFrame, String> {
        match mode {
            Mode::Relight if self.relight.is_some() => {
                return Ok(&mut self.relight.as_mut().expect("checked").frame);
            }
            Mode::Ibrr if self.ibrr.is_some() => {
                return Ok(self.ibrr.as_mut().expect("checked"));
            }
            _ => {}
        }
        let mode = if isr_view(mode).is_some() {
            mode
        } else {
            Mode::Dl
        };
        if !self.isr_frames.contains_key(&(mode, slot)) {
            let (settings, which, channel) = isr_view(mode).expect("an ISR-family mode");
            let mut isr = IsrFrame::prepare(&self.ctx, &self.light_set, settings).map_err(err)?;
            if settings.light_senders > 0 && settings.indirect {
                if self.light_senders.is_none() {
                    self.light_senders = Some(
                        LightSenders::with_bounces(
                            &self.scene,
                            &self.light_set,
                            settings.light_senders,
                            settings.light_sender_bounces,
                        )
                        .map_err(err)?,
                    );
                }
                let senders = self.light_senders.as_ref().expect("made above");
                isr = isr.with_light_senders(senders).map_err(err)?;
            }
            let frame: Box<dyn GpuFrame> = match which {
                None => Box::new(isr),
                Some(which) => Box::new(IsrBufferView {
                    isr,
                    which,
                    resolve: self.resolve_to_texture.clone(),
                    params: self.ctx.uniform_buffer(
                        "viewer isr buffer",
                        &ResolveParams {
                            width: 0,
                            height: 0,
                            channel,
                            pad: 0,
                        },
                    ),
                    bound: scene_core::gpu::Keyed::new(),
                    device: self.ctx.device.clone(),
                }),
            };
            self.isr_frames.insert((mode, slot), frame);
        }
        Ok(self
            .isr_frames
            .get_mut(&(mode, slot))
            .expect("inserted above")
            .as_mut())
    }

    /// Records the frame: the G-buffer, each mode on screen through the frame contract into
    /// its slot, then the composed frame.
    pub fn encode_frame(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        spec: &FrameSpec<'_>,
        profiler: &mut Profiler<'_>,
    ) -> Result<(), String> {
        let mut modes = vec![(spec.mode, 0)];
        if let Layout::Split { right, .. } = spec.layout {
            modes.push((right, 1));
        }
        let Some(t) = self.targets.take() else {
            return Err("no frame size yet".into());
        };
        let result = self.encode_with(encoder, spec, profiler, &modes, &t);
        self.targets = Some(t);
        result
    }

    fn encode_with(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        spec: &FrameSpec<'_>,
        profiler: &mut Profiler<'_>,
        modes: &[(Mode, usize)],
        t: &Targets,
    ) -> Result<(), String> {
        let (w, h) = (t.width, t.height);
        if modes.iter().any(|(m, _)| *m != Mode::Reference) {
            self.raster
                .encode(encoder, &self.scene_gpu, spec.view, &t.gbuffer)
                .map_err(err)?;
        }
        for &(mode, slot) in modes {
            if mode == Mode::Reference {
                continue;
            }
            let inputs = FrameInputs {
                gbuffer: &t.gbuffer,
                view: spec.view,
                lights: spec.lights,
            };
            self.frame_of(mode, slot)?
                .encode(encoder, &inputs, &t.slot_textures[slot])
                .map_err(err)?;
            self.resolve
                .dispatch(encoder, &t.resolve_binds[slot], w, h, None);
            profiler.mark(mode.name(), encoder);
        }
        let (layout, divider, right) = match spec.layout {
            Layout::Single => (0, 0, spec.mode),
            Layout::Split { right, divider } => (
                1,
                (divider.clamp(0.0, 1.0) * w as f32).round() as u32,
                right,
            ),
            Layout::Error => (2, 0, spec.mode),
        };
        let compose = ComposeParams {
            width: w,
            height: h,
            layout,
            divider,
            error_scale: spec.error_scale,
            pad: [0; 3],
        };
        let present = PresentParams {
            width: w,
            height: h,
            scale: spec.exposure.exp2(),
            encode: u32::from(!self.surface_is_srgb),
            surface_width: spec.surface.0.max(1),
            surface_height: spec.surface.1.max(1),
            pad: [0; 2],
        };
        self.writer.write(
            encoder,
            &self.compose_params,
            0,
            bytemuck::bytes_of(&compose),
        );
        self.writer.write(
            encoder,
            &self.present_params,
            0,
            bytemuck::bytes_of(&present),
        );
        self.writer.finish(encoder);
        let bind = &t.compose_binds[usize::from(spec.mode == Mode::Reference)]
            [usize::from(right == Mode::Reference)];
        self.compose.dispatch(encoder, bind, w, h, None);
        profiler.mark("compose", encoder);
        Ok(())
    }

    /// Draws the composed frame into `pass` (a pass over the window's surface texture, the
    /// frame stretched over it, nearest pixel, at the exposure and surface size of the last
    /// [`Renderer::encode_frame`]).
    pub fn draw_present(&self, pass: &mut wgpu::RenderPass<'_>) {
        let Some(t) = &self.targets else { return };
        pass.set_pipeline(&self.present);
        pass.set_bind_group(0, &t.present_bind, &[]);
        pass.draw(0..3, 0..1);
    }

    fn read_buffer(&self, buffer: &wgpu::Buffer) -> Result<Image, String> {
        let Some(t) = &self.targets else {
            return Err("no frame yet".into());
        };
        let v: Vec<[f32; 4]> = self.ctx.read_buffer_as(buffer).map_err(err)?;
        Ok(Image {
            width: t.width,
            height: t.height,
            pixels: v
                .iter()
                .take(t.width as usize * t.height as usize)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
        })
    }

    /// Reads the composed frame back (a screenshot: exactly what was presented, before
    /// exposure and encoding).
    pub fn read_frame(&self) -> Result<Image, String> {
        let t = self.targets.as_ref().ok_or("no frame yet")?;
        self.read_buffer(&t.frame)
    }

    /// Reads the buffer of the left mode back (the error view's mean error).
    pub fn read_slot(&self, slot: usize) -> Result<Image, String> {
        let t = self.targets.as_ref().ok_or("no frame yet")?;
        self.read_buffer(&t.slots[slot.min(1)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_fit_the_adapter_and_keep_their_shape() {
        let mib = 1u64 << 20;
        // A window that fits is rendered at its size, or at the scale asked for.
        assert_eq!(fit_frame(960, 600, 1.0, 128 * mib, 8192), (960, 600));
        assert_eq!(fit_frame(960, 600, 0.5, 128 * mib, 8192), (480, 300));
        // A 4K window is 132.7 MB of frame buffer: above a 128 MiB binding limit it shrinks.
        let (w, h) = fit_frame(3840, 2160, 1.0, 128 * mib, 16384);
        assert!(w as u64 * h as u64 * 16 <= 128 * mib, "{w}x{h}");
        assert!(
            w > 3700 && (w as f64 / h as f64 - 16.0 / 9.0).abs() < 1e-2,
            "{w}x{h}"
        );
        // The texture side limit holds too, and nothing is ever empty.
        assert_eq!(fit_frame(10000, 5000, 1.0, u64::MAX, 4096), (4096, 2048));
        assert_eq!(fit_frame(0, 0, 0.05, 128 * mib, 8192), (1, 1));
    }
}

/// A renderer of the Cornell box at `width x height` (for the tests).
#[cfg(test)]
fn cornell_renderer(ctx: &GpuContext, width: u32, height: u32) -> (Arc<Scene>, Renderer) {
    let scene = Arc::new(scene_core::builtin::scene("cornell").unwrap());
    let mut r = Renderer::new(
        ctx.clone(),
        scene.clone(),
        wgpu::TextureFormat::Rgba8UnormSrgb,
    )
    .unwrap();
    r.resize(width, height).unwrap();
    (scene, r)
}

/// The viewer's frame loop on the frame contract creates no GPU object once each mode and
/// the size have been seen: every mode in a single layout, split against another, and the
/// error view (relighting and the IBRR show direct light until precomputed, so their
/// frames are DL's here; their own frames are checked by their crates' tests).
#[cfg(test)]
mod allocation_tests {
    use super::*;
    use scene_core::gpu::ObjectCounts;
    use scene_core::testing::gpu_test_context;

    #[test]
    fn steady_frames_of_every_mode_create_no_gpu_objects() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let (scene, mut r) = cornell_renderer(&ctx, 40, 30);
        let view = View::from_camera(&scene.cameras[0].with_aspect(40.0 / 30.0));
        let lights = LightState::default();
        let layouts = [
            Layout::Single,
            Layout::Split {
                right: Mode::Isr,
                divider: 0.5,
            },
            Layout::Error,
        ];
        for mode in Mode::ALL {
            for layout in layouts {
                for frame in 0..3 {
                    let spec = FrameSpec {
                        view: &view,
                        lights: &lights,
                        mode,
                        layout,
                        error_scale: 1.0,
                        exposure: 0.0,
                        surface: (80, 60),
                    };
                    let mut encoder = ctx.device.create_command_encoder(&Default::default());
                    let mut profiler = Profiler::new(&ctx, false, false);
                    let (result, created) = ObjectCounts::during(&ctx.device, || {
                        r.encode_frame(&mut encoder, &spec, &mut profiler)
                    });
                    result.unwrap();
                    ctx.queue.submit([encoder.finish()]);
                    // Each frame done before the next is recorded, as the other crates'
                    // tests read theirs back: the staging chunks come back once their
                    // submission has run (frames still in flight take new ones).
                    ctx.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .unwrap();
                    if frame == 2 {
                        assert!(created.is_zero(), "{mode:?} {layout:?}: {created}");
                    }
                }
            }
        }
    }
}

/// The GPU progressive reference in the viewer's frame: the reference buffer the reference
/// modes show holds, after k frames of one view, the GPU path tracer's image at k times the
/// samples per frame, bit for bit (its running mean does not depend on how the samples are
/// split); a maximum set stops it there; a new view starts again.
#[cfg(test)]
mod gpu_reference_tests {
    use super::*;
    use scene_core::reference::{Bounces, ReferenceSettings, render_gpu};
    use scene_core::testing::gpu_test_context;

    #[test]
    fn the_gpu_reference_accumulates_the_gpu_tracers_image() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let (w, h) = (20, 15);
        let (scene, mut r) = cornell_renderer(&ctx, w, h);
        let settings = PathTracerFrameSettings {
            samples_per_frame: 4,
            max_spp: 1024,
            bounces: Bounces::Limited(2),
            seed: 7,
        };
        r.use_gpu_reference(scene.clone(), settings).unwrap();
        r.set_reference_max_spp(10);
        let view = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32));
        let lights = LightState::default();
        let frame = |r: &mut Renderer, view: &View| {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let spp = r.encode_reference(&mut encoder, view, &lights).unwrap();
            ctx.queue.submit([encoder.finish()]);
            spp.unwrap()
        };
        // 4 + 4 + 2 (the maximum), then frames only show it.
        let spps: Vec<u32> = (0..4).map(|_| frame(&mut r, &view)).collect();
        assert_eq!(spps, [4, 8, 10, 10]);
        let shown = r.read_reference().unwrap();
        let traced = render_gpu(
            &ctx,
            &scene,
            &view,
            &ReferenceSettings {
                width: w,
                height: h,
                spp: 10,
                bounces: settings.bounces,
                seed: settings.seed,
            },
            &lights,
            None,
        )
        .unwrap();
        assert!(traced.image.mean().max_element() > 0.0);
        assert_eq!(shown.pixels, traced.image.pixels);
        // A new view starts again.
        let moved = View::from_camera(&scene.cameras[0].with_aspect(w as f32 / h as f32 * 1.1));
        assert_eq!(frame(&mut r, &moved), 4);
    }
}

/// The viewer's passes compose, and every uniform has the layout naga gives its WGSL twin
/// (a field moved on one side fails here).
#[cfg(test)]
mod layout_tests {
    use super::*;
    use scene_core::check_layout;

    #[test]
    fn uniforms_match_their_wgsl_structs() {
        let resolve = RESOLVE.compose().unwrap();
        check_layout!(
            &resolve,
            "Params",
            ResolveParams {
                width,
                height,
                channel,
                pad
            }
        )
        .unwrap();
        let compose = COMPOSE.compose().unwrap();
        check_layout!(
            &compose,
            "Params",
            ComposeParams {
                width,
                height,
                arrangement: layout,
                divider,
                error_scale,
                pad0: pad,
                pad1: pad + 4,
                pad2: pad + 8,
            }
        )
        .unwrap();
        let present = PRESENT.compose().unwrap();
        check_layout!(
            &present,
            "Params",
            PresentParams {
                width,
                height,
                scale,
                encode,
                surface_width,
                surface_height,
                pad0: pad,
                pad1: pad + 4,
            }
        )
        .unwrap();
    }
}
