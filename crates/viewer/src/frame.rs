//! The frame on the GPU: the scene's G-buffer, each mode on screen drawn into a frame-sized
//! buffer, the composed frame ([`Layout`]) and its presentation. Nothing is read back in a
//! frame; [`Renderer::read_frame`] (screenshots) and [`Renderer::read_slot`] (the error
//! view's mean, a few times a second) are the only readbacks.

use std::sync::Arc;

use gbuffer::{GpuPreparedScene, GpuRasterizer};
use glam::Vec3;
use ibrr_ldc::{GpuLdc, IbrrTechnique};
use isr::{GpuIsr, GpuIsrInputs, Intermediate, IsrSettings, LightSet, ShadowSettings};
use relight_pr::gpu::GpuRelight;
use relight_pr::packed::Precision;
use relight_pr::technique::Prepared;
use relight_pr::{RelightTechnique, relight};
use scene_core::gpu::compute::ComputePass;
use scene_core::gpu::layout::{float_texture, storage_buffer, storage_buffer_rw, uniform};
use scene_core::gpu::shader::ShaderPass;
use scene_core::gpu::{GpuContext, GpuGBuffer};
use scene_core::{Image, LightState, Scene, View};

use crate::mode::{Layout, Mode};

macro_rules! viewer_pass {
    ($name:literal, $file:literal) => {
        ShaderPass::new($name, scene_core::wgsl_file!("viewer", $file), &[])
    };
}

/// The resolve pass (`shaders/viewer/resolve.wgsl`).
pub const RESOLVE: ShaderPass = viewer_pass!("viewer/resolve", "resolve.wgsl");
/// The compose pass (`shaders/viewer/compose.wgsl`).
pub const COMPOSE: ShaderPass = viewer_pass!("viewer/compose", "compose.wgsl");
/// The present pass (`shaders/viewer/present.wgsl`).
pub const PRESENT: ShaderPass = viewer_pass!("viewer/present", "present.wgsl");
/// Every shader pass of the viewer, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] = &[RESOLVE, COMPOSE, PRESENT];

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

/// Relighting on the GPU: the solution uploaded once, relit per frame.
pub struct RelightGpu {
    /// What the technique prepared (solution, meshing, welding, rays), shared with the
    /// per-pixel direct light's worker.
    pub prepared: Arc<Prepared>,
    gpu: GpuRelight,
    elements: GpuPreparedScene,
    /// The per-pixel direct light of one view and size, when gathered.
    direct: Option<(View, (u32, u32), Vec<Vec3>)>,
    /// The direct light comes from scene-core's shadow-mapped lights, evaluated on the GPU
    /// every frame (`--relight-direct shadow-maps`).
    shadowed: bool,
}

impl RelightGpu {
    /// True when the per-pixel direct light of `view` at `size` is in hand.
    pub fn has_direct(&self, view: &View, size: (u32, u32)) -> bool {
        self.direct
            .as_ref()
            .is_some_and(|(v, s, _)| v == view && *s == size)
    }
}

/// The IBRR on the GPU: its layered depth cube uploaded once per construction.
pub struct IbrrGpu {
    /// The constructed technique.
    pub technique: IbrrTechnique,
    /// The light state it was built for.
    pub lights: LightState,
    ldc: GpuLdc,
}

/// Buffers and textures of one frame size.
struct Targets {
    width: u32,
    height: u32,
    gbuffer: GpuGBuffer,
    element_gbuffer: GpuGBuffer,
    isr_out: wgpu::Texture,
    /// The buffers of the left and right modes.
    slots: [wgpu::Buffer; 2],
    reference: wgpu::Buffer,
    frame: wgpu::Buffer,
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
}

/// Per-stage GPU times of a frame (scene-core's one stage profiler).
pub use scene_core::gpu::timing::StageProfiler as Profiler;

/// The viewer's GPU side.
pub struct Renderer {
    /// The context (device, queue).
    pub ctx: GpuContext,
    scene: Arc<Scene>,
    raster: GpuRasterizer,
    scene_gpu: GpuPreparedScene,
    isr: GpuIsr,
    resolve: ComputePass,
    compose: ComputePass,
    present: wgpu::RenderPipeline,
    present_layout: wgpu::BindGroupLayout,
    surface_is_srgb: bool,
    targets: Option<Targets>,
    /// Relighting, once its solve is done.
    pub relight: Option<RelightGpu>,
    /// The IBRR, once constructed.
    pub ibrr: Option<IbrrGpu>,
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
    /// Uploads `scene`, builds ISR's lights and shadow maps and compiles every pass;
    /// `surface_format` is the window's.
    pub fn new(
        ctx: GpuContext,
        scene: Arc<Scene>,
        surface_format: wgpu::TextureFormat,
    ) -> Result<Self, String> {
        let raster = GpuRasterizer::new(&ctx).map_err(err)?;
        let scene_gpu = raster.upload(&scene).map_err(err)?;
        let lights = LightSet::new(&scene, &ShadowSettings::default()).map_err(err)?;
        let isr = GpuIsr::new(&ctx, &lights).map_err(err)?;
        let device = &ctx.device;
        let modules = [&RESOLVE, &COMPOSE, &PRESENT].map(|p| p.create_module(device));
        let [resolve_module, compose_module, present_module] = modules;
        let (resolve_module, compose_module, module) = (
            resolve_module.map_err(err)?,
            compose_module.map_err(err)?,
            present_module.map_err(err)?,
        );
        let (resolve, compose, present, present_layout) = ctx
            .validated(|| {
                let resolve = ComputePass::from_module(
                    device,
                    "viewer resolve",
                    &resolve_module,
                    &[uniform(0), float_texture(1), storage_buffer_rw(2)],
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
                (resolve, compose, present, layout)
            })
            .map_err(err)?;
        Ok(Self {
            ctx,
            scene,
            raster,
            scene_gpu,
            isr,
            resolve,
            compose,
            present,
            present_layout,
            surface_is_srgb: surface_format.is_srgb(),
            targets: None,
            relight: None,
            ibrr: None,
        })
    }

    /// A uniform buffer holding `params`.
    fn uniform<T: bytemuck::Pod>(&self, label: &str, params: &T) -> wgpu::Buffer {
        self.ctx.uniform_buffer(label, params)
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

    /// (Re)creates the frame-sized buffers and textures.
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
        self.targets = Some(Targets {
            width,
            height,
            gbuffer: GpuGBuffer::new(ctx, width, height).map_err(err)?,
            element_gbuffer: GpuGBuffer::new(ctx, width, height).map_err(err)?,
            isr_out: self.isr.output_texture(width, height).map_err(err)?,
            slots: [buffer("viewer left"), buffer("viewer right")],
            reference: buffer("viewer reference"),
            frame: buffer("viewer frame"),
        });
        Ok(())
    }

    /// Uploads relighting's solution (after its solve), with `shadow_maps` its lights' shadow
    /// maps for the per-frame direct light too; returns what was prepared, shared.
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
        let mut gpu = GpuRelight::new(
            &self.ctx,
            &p.meshing,
            &p.welding,
            &p.solution,
            Precision::F32,
        )
        .map_err(err)?;
        if shadow_maps {
            let set = LightSet::new(&p.scene, &ShadowSettings::default()).map_err(err)?;
            let slots = relight_pr::display::light_slots(&set, &p.solution.sources);
            let footprint = match relight_pr::direct::DirectLight::shadow_maps() {
                relight_pr::direct::DirectLight::ShadowMaps { footprint, .. } => footprint,
                _ => 1,
            };
            gpu.set_shadowed_direct(&set, &slots, footprint)
                .map_err(err)?;
        }
        let elements = self
            .raster
            .upload(&p.meshing.element_scene(&p.scene))
            .map_err(err)?;
        self.relight = Some(RelightGpu {
            prepared: p.clone(),
            gpu,
            elements,
            direct: None,
            shadowed: shadow_maps,
        });
        Ok(p)
    }

    /// Hands relighting the per-pixel direct light of `view` at `size` (`k` values per
    /// pixel, pixel-major); frames of that view and size use it.
    pub fn set_relight_direct(&mut self, view: View, size: (u32, u32), values: Vec<Vec3>) {
        if let Some(r) = self.relight.as_mut() {
            let k = r.prepared.solution.k();
            let ok = values.len() == size.0 as usize * size.1 as usize * k;
            r.direct = ok.then_some((view, size, values));
        }
    }

    /// Uploads the IBRR's layered depth cube (after its construction for `lights`).
    pub fn set_ibrr(&mut self, technique: IbrrTechnique, lights: LightState) -> Result<(), String> {
        let ldc = technique.ldc().ok_or("the IBRR was not constructed")?;
        let s = &technique.settings;
        let ldc = GpuLdc::new(&self.ctx, ldc, s.lookup, s.fallback_radius).map_err(err)?;
        self.ibrr = Some(IbrrGpu {
            technique,
            lights,
            ldc,
        });
        Ok(())
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

    /// Records `mode` into its buffer (`slot` 0 or 1; the reference has its own). A mode
    /// whose precomputation is not done yet (relighting's solve, the IBRR's construction)
    /// shows direct light (DL) meanwhile, never a black frame; the panel says so.
    fn encode_mode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        spec: &FrameSpec<'_>,
        mode: Mode,
        slot: usize,
        gbuffer_done: &mut bool,
    ) -> Result<(), String> {
        let Some(t) = &self.targets else {
            return Err("no frame size yet".into());
        };
        let (w, h) = (t.width, t.height);
        if (mode.is_isr() || mode == Mode::Ibrr) && !*gbuffer_done {
            self.raster
                .encode(encoder, &self.scene_gpu, spec.view, &t.gbuffer)
                .map_err(err)?;
            *gbuffer_done = true;
        }
        if let Some((settings, which, channel)) = isr_view(mode) {
            self.isr.apply(spec.lights);
            let inputs = GpuIsrInputs {
                full: &t.gbuffer,
                coarse: None,
                view: spec.view,
            };
            self.isr
                .encode(encoder, &inputs, &settings, &t.isr_out)
                .map_err(err)?;
            let source = match which {
                None => &t.isr_out,
                Some(i) => self
                    .isr
                    .intermediate(i)
                    .ok_or("ISR has no intermediate buffers yet")?,
            };
            let params = ResolveParams {
                width: w,
                height: h,
                channel,
                pad: 0,
            };
            let uniform = self.uniform("viewer resolve", &params);
            let view = source.create_view(&Default::default());
            let bind = self.resolve.bind(
                &self.ctx.device,
                &[
                    uniform.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&view),
                    t.slots[slot].as_entire_binding(),
                ],
            );
            self.resolve.dispatch(encoder, &bind, w, h, None);
            return Ok(());
        }
        match mode {
            Mode::Relight => match &self.relight {
                Some(r) => {
                    let p = &r.prepared;
                    let direct = r
                        .direct
                        .as_ref()
                        .filter(|(v, s, _)| v == spec.view && *s == (w, h))
                        .map(|(_, _, values)| values.as_slice());
                    self.raster
                        .encode(encoder, &r.elements, spec.view, &t.element_gbuffer)
                        .map_err(err)?;
                    let (factors, base) = relight::weights(&p.solution, spec.lights, true);
                    if r.shadowed {
                        r.gpu.encode_display_shadowed(
                            encoder,
                            &t.element_gbuffer,
                            spec.view,
                            &factors,
                            base,
                            &t.slots[slot],
                        )
                    } else {
                        r.gpu.encode_display(
                            encoder,
                            &t.element_gbuffer,
                            spec.view,
                            &factors,
                            base,
                            direct,
                            &t.slots[slot],
                        )
                    }
                    .map_err(err)?;
                }
                None => return self.encode_mode(encoder, spec, Mode::Dl, slot, gbuffer_done),
            },
            Mode::Ibrr => match self.ibrr.as_mut() {
                Some(b) => {
                    // The LDC keeps its light per source: a new light state is a
                    // recombination and one buffer write, not a rebuild.
                    if b.lights.fingerprint() != spec.lights.fingerprint()
                        && b.technique.relight(spec.lights).map_err(err)?.is_some()
                    {
                        let ldc = b.technique.ldc().ok_or("the IBRR was not constructed")?;
                        b.ldc.update_values(ldc).map_err(err)?;
                        b.lights = spec.lights.clone();
                    }
                    b.ldc
                        .encode(
                            encoder,
                            &self.scene,
                            &t.gbuffer,
                            spec.view,
                            &b.lights,
                            &t.slots[slot],
                        )
                        .map_err(err)?;
                }
                None => return self.encode_mode(encoder, spec, Mode::Dl, slot, gbuffer_done),
            },
            _ => {}
        }
        Ok(())
    }

    /// Records the frame: each mode on screen, then the composed frame.
    pub fn encode_frame(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        spec: &FrameSpec<'_>,
        profiler: &mut Profiler<'_>,
    ) -> Result<(), String> {
        let mut gbuffer_done = false;
        let mut modes = vec![(spec.mode, 0)];
        if let Layout::Split { right, .. } = spec.layout {
            modes.push((right, 1));
        }
        for &(mode, slot) in &modes {
            if mode != Mode::Reference {
                self.encode_mode(encoder, spec, mode, slot, &mut gbuffer_done)?;
                profiler.mark(mode.name(), encoder);
            }
        }
        let Some(t) = &self.targets else {
            return Err("no frame size yet".into());
        };
        let source = |mode: Mode, slot: usize| {
            if mode == Mode::Reference {
                &t.reference
            } else {
                &t.slots[slot]
            }
        };
        let (layout, divider, right) = match spec.layout {
            Layout::Single => (0, 0, spec.mode),
            Layout::Split { right, divider } => (
                1,
                (divider.clamp(0.0, 1.0) * t.width as f32).round() as u32,
                right,
            ),
            Layout::Error => (2, 0, spec.mode),
        };
        let params = ComposeParams {
            width: t.width,
            height: t.height,
            layout,
            divider,
            error_scale: spec.error_scale,
            pad: [0; 3],
        };
        let uniform = self.uniform("viewer compose", &params);
        let bind = self.compose.bind(
            &self.ctx.device,
            &[
                uniform.as_entire_binding(),
                source(spec.mode, 0).as_entire_binding(),
                source(right, 1).as_entire_binding(),
                t.reference.as_entire_binding(),
                t.frame.as_entire_binding(),
            ],
        );
        self.compose
            .dispatch(encoder, &bind, t.width, t.height, None);
        profiler.mark("compose", encoder);
        Ok(())
    }

    /// Draws the composed frame into `pass` (a pass over the window's surface texture of
    /// `surface` pixels, the frame stretched over it, nearest pixel), scaled by
    /// `2^exposure`.
    pub fn draw_present(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        surface: (u32, u32),
        exposure: f32,
    ) {
        let Some(t) = &self.targets else { return };
        let params = PresentParams {
            width: t.width,
            height: t.height,
            scale: exposure.exp2(),
            encode: u32::from(!self.surface_is_srgb),
            surface_width: surface.0.max(1),
            surface_height: surface.1.max(1),
            pad: [0; 2],
        };
        let uniform = self.uniform("viewer present", &params);
        let bind = self
            .ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("viewer present"),
                layout: &self.present_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: t.frame.as_entire_binding(),
                    },
                ],
            });
        pass.set_pipeline(&self.present);
        pass.set_bind_group(0, &bind, &[]);
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
