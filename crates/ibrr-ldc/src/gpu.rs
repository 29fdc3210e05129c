//! Reconstruction on the GPU (wgpu compute, `shaders/ibrr-ldc/reconstruct.wgsl`): the
//! flattened LDC ([`Ldc`]'s offsets, planes and values) is uploaded once; a frame binds the
//! camera's [`GpuGBuffer`] and runs two passes that mirror [`crate::reconstruct()`] and
//! [`crate::shade`] pixel for pixel: the lookup (entry point `main`) into an irradiance
//! buffer kept across frames, then the hole fill and the shading (`fill`) into the output.

use glam::Vec3;
use scene_core::gpu::compute::ComputePass;
use scene_core::gpu::layout::{float_texture, storage_buffer, storage_buffer_rw, texture, uniform};
use scene_core::gpu::shader::ShaderPass;
use scene_core::gpu::{FrameWriter, GpuContext, GpuError, GpuGBuffer, KeptBuffer};
use scene_core::lights::{LightId, SpotRamp};
use scene_core::view::{FrustumReconstruction, Projection};
use scene_core::{Image, LightState, Scene, View};

use crate::error::IbrrError;
use crate::ldc::Ldc;
use crate::settings::{Lookup, Reading};

/// The reconstruction pass (`shaders/ibrr-ldc/reconstruct.wgsl`, importing
/// `scene_core::reconstruct`).
pub const RECONSTRUCT: ShaderPass = ShaderPass::new(
    "ibrr-ldc/reconstruct",
    scene_core::wgsl_file!("ibrr-ldc", "reconstruct.wgsl"),
    &[
        scene_core::gpu::shader::RECONSTRUCT,
        scene_core::gpu::shader::LIMITS,
    ],
);

/// The gather pass (`shaders/ibrr-ldc/gather.wgsl`, importing `scene_core::reconstruct`).
pub const GATHER: ShaderPass = ShaderPass::new(
    "ibrr-ldc/gather",
    scene_core::wgsl_file!("ibrr-ldc", "gather.wgsl"),
    &[
        scene_core::gpu::shader::RECONSTRUCT,
        scene_core::gpu::shader::LIMITS,
    ],
);

/// Every shader pass of the IBRR, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] = &[RECONSTRUCT, GATHER];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    frustum: [[f32; 4]; 6],
    view_projection: [[f32; 4]; 4],
    origin: [f32; 4],
    eye: [f32; 4],
    width: u32,
    height: u32,
    resolution: u32,
    fallback_radius: u32,
    eps_distance: f32,
    eps_normal: f32,
    band: f32,
    triangles: u32,
    fill_radius: u32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuTriangle {
    glow: [f32; 4],
    normal: [f32; 4],
}

/// How a GPU frame went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuFrameCounts {
    /// Pixels with geometry and no matching layer.
    pub missing: u64,
    /// Pixels served by the fallback search.
    pub fallback: u64,
    /// Pixels without a layer filled from the camera pixels around them.
    pub filled: u64,
}

/// An LDC resident on the GPU.
pub struct GpuLdc {
    ctx: GpuContext,
    ldc_frame: crate::ldc::LdcFrame,
    offsets: wgpu::Buffer,
    planes: wgpu::Buffer,
    values: wgpu::Buffer,
    pass: ComputePass,
    /// The hole fill and the shading (`fill`), after `pass`.
    fill: ComputePass,
    reading: Reading,
    /// Each pixel's irradiance and status between the two passes.
    irradiance: KeptBuffer,
    bytes: u64,
    /// What the glow table was last built for (scene address, triangle count, light
    /// fingerprint) and its length: rebuilt and written (into `glow_buffer`, by a copy in the
    /// frame's encoder) only when the lights change.
    glow: scene_core::gpu::Keyed<(usize, usize, u64), u32>,
    glow_buffer: KeptBuffer,
    /// A frame's parameters go into `params` by a copy in the frame's own encoder.
    writer: FrameWriter,
    params: wgpu::Buffer,
    /// The two passes' bind groups and what they were made for.
    bound: scene_core::gpu::Keyed<BindKey, [wgpu::BindGroup; 2]>,
    /// Relit layer values from [`GpuLdc::update_values`], written in the next frame.
    pending_values: Option<Vec<[f32; 4]>>,
}

/// What the frame's bind groups depend on: the G-buffer's textures and the output by
/// identity, and the glow and irradiance buffers' generations.
#[derive(Clone, Debug, PartialEq)]
struct BindKey {
    textures: [wgpu::Texture; 4],
    output: wgpu::Buffer,
    glow: u64,
    irradiance: u64,
}

impl std::fmt::Debug for GpuLdc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuLdc")
            .field("bytes", &self.bytes)
            .field("reading", &self.reading)
            .finish_non_exhaustive()
    }
}

pub(crate) fn gpu(e: GpuError) -> IbrrError {
    IbrrError::Core(e.into())
}

impl GpuLdc {
    /// Uploads `ldc` for frames that read it as `reading` says (kernel, fallback, hole
    /// fill). Fails with [`IbrrError::Budget`] before allocating when a buffer exceeds the
    /// adapter's storage-binding or buffer size.
    pub fn new(ctx: &GpuContext, ldc: &Ldc, reading: Reading) -> Result<Self, IbrrError> {
        let limit = ctx.storage_binding_limit();
        let layers = ldc.layer_count() as u64;
        for (what, bytes) in [
            ("per-pixel layer offsets", ldc.offsets.len() as u64 * 4),
            ("layer planes", layers * 16),
            ("layer values", layers * 32),
        ] {
            if bytes > limit {
                return Err(IbrrError::Budget {
                    needed: bytes,
                    limit,
                    what: format!("the {what} on this adapter (a lower LDC resolution fits)"),
                });
            }
        }
        let values = Self::values_of(ldc);
        let planes: Vec<[f32; 4]> = ldc.planes.iter().map(|p| p.to_array()).collect();
        let (mode, radius) = match reading.lookup {
            Lookup::Nearest => (0.0, 0.0),
            Lookup::Average { radius } => (1.0, f64::from(radius)),
            Lookup::Bilinear => (2.0, 0.0),
        };
        let module = RECONSTRUCT.create_module(&ctx.device).map_err(gpu)?;
        let entries = [
            uniform(0),
            storage_buffer(1),
            storage_buffer(2),
            storage_buffer(3),
            storage_buffer(4),
            storage_buffer_rw(5),
            storage_buffer_rw(6),
            float_texture(7),
            float_texture(8),
            float_texture(9),
            texture(10, wgpu::TextureSampleType::Uint),
        ];
        let constants = [("LOOKUP", mode), ("AVERAGE_RADIUS", radius)];
        let [pass, fill] =
            [("main", "ibrr-ldc reconstruct"), ("fill", "ibrr-ldc fill")].map(|(entry, label)| {
                ComputePass::from_entry_point(
                    &ctx.device,
                    label,
                    &module,
                    entry,
                    &entries,
                    &constants,
                )
            });
        ctx.validated(|| Self {
            ctx: ctx.clone(),
            ldc_frame: ldc.frame,
            offsets: ctx.storage_with(
                "LDC offsets",
                bytemuck::cast_slice(&ldc.offsets),
                wgpu::BufferUsages::empty(),
            ),
            planes: ctx.storage_with(
                "LDC planes",
                bytemuck::cast_slice(&planes),
                wgpu::BufferUsages::empty(),
            ),
            values: ctx.storage_with(
                "LDC values",
                bytemuck::cast_slice(&values),
                wgpu::BufferUsages::COPY_DST,
            ),
            pass,
            fill,
            reading,
            irradiance: KeptBuffer::new("ibrr irradiance", wgpu::BufferUsages::STORAGE),
            bytes: ldc.offsets.len() as u64 * 4 + layers * 48,
            glow: scene_core::gpu::Keyed::new(),
            glow_buffer: KeptBuffer::new("ibrr triangles", wgpu::BufferUsages::STORAGE),
            writer: FrameWriter::new(&ctx.device, 4096),
            params: ctx.frame_buffer(
                "ibrr params",
                std::mem::size_of::<Params>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            bound: scene_core::gpu::Keyed::new(),
            pending_values: None,
        })
        .map_err(gpu)
    }

    /// Bytes resident on the GPU.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The layers' values as the pass reads them: direct and indirect, padded to vec4.
    fn values_of(ldc: &Ldc) -> Vec<[f32; 4]> {
        ldc.direct
            .iter()
            .zip(&ldc.indirect)
            .flat_map(|(d, i)| [d.extend(0.0).to_array(), i.extend(0.0).to_array()])
            .collect()
    }

    /// Replaces the layers' values with `ldc`'s (the same LDC relit, [`Ldc::relight`]): a
    /// copy recorded in the next frame's encoder ([`GpuLdc::encode`]), no new allocation on
    /// the GPU. Errors when `ldc` has another number of layers than the one uploaded.
    pub fn update_values(&mut self, ldc: &Ldc) -> Result<(), IbrrError> {
        let values = Self::values_of(ldc);
        let bytes = std::mem::size_of_val(values.as_slice()) as u64;
        if bytes != self.values.size() {
            return Err(IbrrError::Settings(format!(
                "relit LDC has {} layers, the uploaded one {}",
                ldc.layer_count(),
                self.values.size() / 32
            )));
        }
        // Written by a copy in the next frame's encoder, before its pass (a queue write
        // would stage a buffer of its own, and land before earlier frames of the same
        // submission).
        self.pending_values = Some(values);
        Ok(())
    }

    /// The per-triangle glow table of `scene` under `lights` (emission times the light's
    /// direct factor, and the emitting side's normal).
    fn triangles(scene: &Scene, lights: &LightState) -> Vec<GpuTriangle> {
        let mut out = Vec::with_capacity(scene.triangle_count());
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            let factor = lights.get(LightId::Emissive(mi as u32)).direct_factor();
            for (local, (t, &m)) in mesh.indices.iter().zip(&mesh.material_ids).enumerate() {
                let mat = &scene.materials[m as usize];
                let (glow, normal) = if mat.is_emissive() {
                    let p = t.map(|i| mesh.positions[i as usize]);
                    // With an emission texture, its mean over the triangle.
                    let le = scene.triangle_emission(mi, local);
                    (le * factor, (p[1] - p[0]).cross(p[2] - p[0]))
                } else {
                    (Vec3::ZERO, Vec3::ZERO)
                };
                out.push(GpuTriangle {
                    glow: glow.extend(0.0).to_array(),
                    normal: normal.extend(0.0).to_array(),
                });
            }
        }
        out
    }

    /// The image of `g` (the camera's G-buffer of `scene` from `view`) under `lights`, and
    /// the pixel counts of the fallback and of pixels without a layer. Records, submits
    /// and reads back; [`GpuLdc::encode`] is the frame without the readback.
    pub fn render(
        &mut self,
        scene: &Scene,
        g: &GpuGBuffer,
        view: &View,
        lights: &LightState,
    ) -> Result<(Image, GpuFrameCounts), IbrrError> {
        let (w, h) = (g.width, g.height);
        let pixels = w as usize * h as usize;
        let image = self.ctx.pixel_buffer("ibrr image", w, h);
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, scene, g, view, lights, &image)?;
        let ctx = &self.ctx;
        ctx.queue.submit([encoder.finish()]);
        let v: Vec<[f32; 4]> = ctx.read_buffer_as(&image).map_err(gpu)?;
        let mut counts = GpuFrameCounts::default();
        let pixels_out = v
            .iter()
            .take(pixels)
            .map(|p| {
                match p[3] as u32 {
                    1 => counts.fallback += 1,
                    2 => counts.missing += 1,
                    4 => counts.filled += 1,
                    _ => {}
                }
                let l = Vec3::new(p[0], p[1], p[2]);
                if l.is_finite() { l } else { Vec3::ZERO }
            })
            .collect();
        Ok((
            Image {
                width: w,
                height: h,
                pixels: pixels_out,
            },
            counts,
        ))
    }

    /// Records the reconstruction of `g` (the camera's G-buffer of `scene` from `view`)
    /// under `lights` into `encoder`, writing `output` (at least `g.width * g.height`
    /// `vec4<f32>`, e.g. [`GpuContext::pixel_buffer`]: radiance in `xyz`, and in `w` 1 where
    /// the fallback served the pixel, 2 where no layer matched and nothing was filled, 3 on
    /// the background, 4 where the hole fill served it). Nothing is read back.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &Scene,
        g: &GpuGBuffer,
        view: &View,
        lights: &LightState,
        output: &wgpu::Buffer,
    ) -> Result<(), IbrrError> {
        let (w, h) = (g.width, g.height);
        GpuContext::check_pixel_buffer(output, w, h, "reconstruction output").map_err(gpu)?;
        let f = &self.ldc_frame;
        let eye = match view.projection {
            Projection::Perspective { .. } => view.eye.extend(1.0),
            Projection::Orthographic { .. } => view.forward.extend(0.0),
        };
        let key = (
            std::ptr::from_ref(scene) as usize,
            scene.triangle_count(),
            lights.fingerprint(),
        );
        let glow_table = if self.glow.is_for(&key) {
            None
        } else {
            let table = Self::triangles(scene, lights);
            self.glow.set(key, table.len() as u32);
            Some(table)
        };
        let triangles = self.glow.value().copied().unwrap_or(0);
        let glow_bytes = u64::from(triangles) * std::mem::size_of::<GpuTriangle>() as u64;
        let tri = self
            .glow_buffer
            .ensure(&self.ctx.device, glow_bytes)
            .clone();
        let params = Params {
            frustum: FrustumReconstruction::new(view).uniform(),
            view_projection: view.view_projection().to_cols_array_2d(),
            origin: f.origin.extend(f.side).to_array(),
            eye: eye.to_array(),
            width: w,
            height: h,
            resolution: f.resolution,
            fallback_radius: self.reading.fallback_radius,
            eps_distance: f.eps_distance,
            eps_normal: f.eps_normal,
            band: f.band,
            triangles,
            fill_radius: self.reading.fill_radius,
            pad_a: 0,
            pad_b: 0,
            pad_c: 0,
        };
        let irradiance_bytes = u64::from(w) * u64::from(h) * 32;
        let limit = self.ctx.storage_binding_limit();
        if irradiance_bytes > limit {
            return Err(IbrrError::Budget {
                needed: irradiance_bytes,
                limit,
                what: format!(
                    "the {w}x{h} frame's irradiance between the lookup and the fill on this adapter (a smaller frame fits)"
                ),
            });
        }
        let irradiance = self
            .irradiance
            .ensure(&self.ctx.device, irradiance_bytes)
            .clone();
        let ctx = &self.ctx;
        let bind_key = BindKey {
            textures: [
                g.albedo.clone(),
                g.normal.clone(),
                g.depth.clone(),
                g.triangle_id.clone(),
            ],
            output: output.clone(),
            glow: self.glow_buffer.generation(),
            irradiance: self.irradiance.generation(),
        };
        self.bound.get_or_make(bind_key, |_| {
            let buffers = [
                &self.params,
                &self.offsets,
                &self.planes,
                &self.values,
                &tri,
                output,
                &irradiance,
            ];
            let textures = [&g.albedo, &g.normal, &g.depth, &g.triangle_id];
            [&self.pass, &self.fill]
                .map(|pass| pass.bind_buffers_then_textures(&ctx.device, &buffers, &textures))
        });
        self.writer
            .write(encoder, &self.params, 0, bytemuck::bytes_of(&params));
        if let Some(values) = self.pending_values.take() {
            self.writer
                .write(encoder, &self.values, 0, bytemuck::cast_slice(&values));
        }
        if let Some(table) = glow_table {
            self.writer
                .write(encoder, &tri, 0, bytemuck::cast_slice(&table));
        }
        self.writer.finish(encoder);
        let Some([lookup, fill]) = self.bound.value() else {
            unreachable!("made above")
        };
        self.pass.dispatch(encoder, lookup, w, h, None);
        self.fill.dispatch(encoder, fill, w, h, None);
        Ok(())
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GatherParams {
    origin: [f32; 4],
    irpl_position: [f32; 4],
    irpl_normal: [f32; 4],
    irpl_power: [f32; 4],
    resolution: u32,
    layers: u32,
    renders: u32,
    groups_x: u32,
    eps_distance: f32,
    eps_normal: f32,
    scale: f32,
    has_radius: u32,
    /// A point source's spot ramp (scale 0, offset 1 without a cone); its axis is in
    /// `irpl_normal.xyz`.
    spot_scale: f32,
    spot_offset: f32,
    pad_a: u32,
    pad_b: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuRender {
    view_projection: [[f32; 4]; 4],
    frustum: [[f32; 4]; 6],
    eye: [f32; 4],
    forward: [f32; 4],
    size: [u32; 4],
}

const GATHER_GROUP: u32 = 64;
const MAX_GROUPS_X: u32 = 32768;

/// The exact mode's gather on the GPU ([`crate::construct`]: every layer is lit by the
/// share of its centre that nothing of the IRPL's renders lies in front of). Layers are uploaded as they appear; each IRPL uploads its renders'
/// normals and depths and reads back one value per layer.
pub struct GpuGather {
    ctx: GpuContext,
    pass: ComputePass,
    planes: Option<wgpu::Buffer>,
    pixels: Option<wgpu::Buffer>,
    capacity: usize,
    uploaded: usize,
    limit: u64,
}

impl std::fmt::Debug for GpuGather {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuGather")
            .field("capacity", &self.capacity)
            .field("uploaded", &self.uploaded)
            .finish_non_exhaustive()
    }
}

impl GpuGather {
    /// The pass on `ctx`.
    pub fn new(ctx: &GpuContext) -> Result<Self, IbrrError> {
        let pass = ctx
            .validated(|| {
                ComputePass::new(
                    &ctx.device,
                    "ibrr-ldc gather",
                    &GATHER,
                    &[
                        uniform(0),
                        storage_buffer(1),
                        storage_buffer(2),
                        storage_buffer(3),
                        storage_buffer(4),
                        storage_buffer_rw(5),
                    ],
                    &[],
                )
            })
            .map_err(gpu)?
            .map_err(gpu)?;
        Ok(Self {
            ctx: ctx.clone(),
            pass,
            planes: None,
            pixels: None,
            capacity: 0,
            uploaded: 0,
            limit: ctx.storage_binding_limit(),
        })
    }

    /// Values for every layer of `builder` lit by `irpl` (geometry term clamped at `g_max`,
    /// times `scale`) as seen by its renders (`targets`, `buffers`); `None` where unlit.
    pub(crate) fn gather(
        &mut self,
        builder: &crate::ldc::LdcBuilder,
        irpl: &crate::irpl::Irpl,
        g_max: f32,
        scale: f32,
        targets: &[scene_core::ViewTarget],
        buffers: &[scene_core::GBuffer],
    ) -> Result<Vec<Option<Vec3>>, IbrrError> {
        use crate::irpl::IrplKind;
        let n = builder.layer_count();
        if n == 0 {
            return Ok(Vec::new());
        }
        let ctx = self.ctx.clone();
        // Layers: grow the buffers by doubling (re-uploading all), else append.
        if n > self.capacity {
            let capacity = n.next_power_of_two().max(1024);
            let bytes = capacity as u64 * 16;
            if bytes > self.limit {
                return Err(IbrrError::Budget {
                    needed: bytes,
                    limit: self.limit,
                    what: "layer planes for the GPU gather on this adapter".into(),
                });
            }
            let make = |label: &str, size: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            self.planes = Some(make("gather planes", bytes));
            self.pixels = Some(make("gather pixels", capacity as u64 * 4));
            self.capacity = capacity;
            self.uploaded = 0;
        }
        let (Some(planes_buf), Some(pixels_buf)) = (&self.planes, &self.pixels) else {
            return Ok(vec![None; n]);
        };
        if self.uploaded < n {
            let new = builder.layers_from(self.uploaded);
            let planes: Vec<[f32; 4]> = new.iter().map(|(p, _)| p.to_array()).collect();
            let pixels: Vec<u32> = new.iter().map(|(_, k)| *k).collect();
            ctx.queue.write_buffer(
                planes_buf,
                self.uploaded as u64 * 16,
                bytemuck::cast_slice(&planes),
            );
            ctx.queue.write_buffer(
                pixels_buf,
                self.uploaded as u64 * 4,
                bytemuck::cast_slice(&pixels),
            );
            self.uploaded = n;
        }
        // The renders: per pixel (normal, depth), background negative.
        let mut records = Vec::with_capacity(targets.len());
        let mut texels: Vec<[f32; 4]> = Vec::new();
        for (t, g) in targets.iter().zip(buffers) {
            let (perspective, pixel) = match t.view.projection {
                Projection::Perspective { left, right, .. } => {
                    (1.0, (right - left) / g.width as f32)
                }
                Projection::Orthographic { left, right, .. } => {
                    (0.0, (right - left) / g.width as f32)
                }
            };
            records.push(GpuRender {
                view_projection: t.view.view_projection().to_cols_array_2d(),
                frustum: FrustumReconstruction::new(&t.view).uniform(),
                eye: t.view.eye.extend(perspective).to_array(),
                forward: t.view.forward.extend(pixel).to_array(),
                size: [g.width, g.height, texels.len() as u32, 0],
            });
            texels.extend((0..g.len()).map(|i| {
                if g.is_background(i) {
                    [0.0, 0.0, 0.0, -1.0]
                } else {
                    g.normal[i].extend(g.depth[i]).to_array()
                }
            }));
        }
        let none = SpotRamp::NONE;
        let (kind, normal, radius, spot) = match irpl.kind {
            IrplKind::PointSource { radius, spot } => (0.0, spot.axis, radius, spot),
            IrplKind::DirectionalSource { direction } => (1.0, direction, None, none),
            IrplKind::EmitterSample | IrplKind::Bounce => (2.0, irpl.normal, None, none),
        };
        let groups = (n as u32).div_ceil(GATHER_GROUP);
        let groups_x = groups.min(MAX_GROUPS_X);
        let params = GatherParams {
            origin: builder.frame.origin.extend(builder.frame.side).to_array(),
            irpl_position: irpl.position.extend(kind).to_array(),
            irpl_normal: normal.extend(radius.unwrap_or(0.0)).to_array(),
            irpl_power: irpl.power.extend(g_max.min(f32::MAX)).to_array(),
            resolution: builder.frame.resolution,
            layers: n as u32,
            renders: records.len() as u32,
            groups_x,
            eps_distance: builder.frame.eps_distance,
            eps_normal: builder.frame.eps_normal,
            scale,
            has_radius: radius.is_some() as u32,
            spot_scale: spot.scale,
            spot_offset: spot.offset,
            pad_a: 0,
            pad_b: 0,
        };
        let uniform = ctx.uniform_buffer("gather params", &params);
        let renders = ctx.storage_with(
            "gather renders",
            bytemuck::cast_slice(&records),
            wgpu::BufferUsages::empty(),
        );
        let texel_buf = ctx.storage_with(
            "gather render pixels",
            bytemuck::cast_slice(&texels),
            wgpu::BufferUsages::empty(),
        );
        let out = ctx.storage_with(
            "gather values",
            &vec![0u8; n * 16],
            wgpu::BufferUsages::COPY_SRC,
        );
        let bind = self.pass.bind(
            &ctx.device,
            &[
                uniform.as_entire_binding(),
                planes_buf.as_entire_binding(),
                pixels_buf.as_entire_binding(),
                renders.as_entire_binding(),
                texel_buf.as_entire_binding(),
                out.as_entire_binding(),
            ],
        );
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("ibrr-ldc gather"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pass.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups_x, groups.div_ceil(groups_x), 1);
        }
        ctx.queue.submit([encoder.finish()]);
        let v: Vec<[f32; 4]> = ctx.read_buffer_as(&out).map_err(gpu)?;
        Ok(v.iter()
            .take(n)
            .map(|x| (x[3] > 0.0).then(|| Vec3::new(x[0], x[1], x[2])))
            .collect())
    }
}

/// Every struct written for the shaders has the layout naga gives its WGSL twin, in the
/// module the composer builds (a field moved on one side fails here).
#[cfg(test)]
mod layout_tests {
    use super::*;
    use scene_core::check_layout;

    #[test]
    fn uniforms_and_tables_match_their_wgsl_structs() {
        let reconstruct = RECONSTRUCT.compose().unwrap();
        check_layout!(
            &reconstruct,
            "Params",
            Params {
                frustum,
                view_projection,
                origin,
                eye,
                width,
                height,
                resolution,
                fallback_radius,
                eps_distance,
                eps_normal,
                band,
                triangles,
                fill_radius,
                pad_a,
                pad_b,
                pad_c,
            }
        )
        .unwrap();
        check_layout!(&reconstruct, "Triangle", GpuTriangle { glow, normal }).unwrap();
        let gather = GATHER.compose().unwrap();
        check_layout!(
            &gather,
            "Params",
            GatherParams {
                origin,
                irpl_position,
                irpl_normal,
                irpl_power,
                resolution,
                layers,
                renders,
                groups_x,
                eps_distance,
                eps_normal,
                scale,
                has_radius,
                spot_scale,
                spot_offset,
                pad_a,
                pad_b,
            }
        )
        .unwrap();
        check_layout!(
            &gather,
            "Render",
            GpuRender {
                view_projection,
                frustum,
                eye,
                forward,
                size
            }
        )
        .unwrap();
    }
}
