//! An engine's G-buffer as the engine keeps it, turned into the toolkit's [`GpuGBuffer`] on
//! the GPU (`shaders/scene-core/host_gbuffer.wgsl`): albedo in any float-sampled format
//! (`Rgba8UnormSrgb`, `Rgba16Float`...), normals as `xyz` (`Rgba16Float`, `Rgba32Float`) or
//! octahedral (`Rg16Float`, `Rg32Float`, `Rg16Snorm` where the device has 16-bit norm
//! formats), the depth buffer itself (`Depth32Float`, in the convention
//! [`crate::View::from_host_matrices`] read off the engine's projection), and triangle ids
//! when the engine has them ([`SURFACE_WITHOUT_ID`] on geometry when it has not).
//!
//! Each frame is one compute pass recorded into the engine's encoder; it creates no GPU
//! object once its textures have been seen (docs/engine.md).

use crate::gpu::compute::ComputePass;
use crate::gpu::layout::{float_texture, storage_texture, texture, uniform};
use crate::gpu::shader::ShaderPass;
use crate::gpu::{FrameWriter, GpuContext, GpuError, GpuGBuffer};
use crate::view::DepthConvention;

/// The conversion pass.
pub const HOST_GBUFFER: ShaderPass = ShaderPass::new(
    "scene-core/host_gbuffer",
    crate::wgsl_file!("scene-core", "host_gbuffer.wgsl"),
    &[],
);

/// The triangle id of a surface pixel whose engine gave no ids: the methods treat it as a
/// surface that emits nothing (every per-triangle table is shorter).
pub const SURFACE_WITHOUT_ID: u32 = 0xffff_fffe;

/// How an engine's normal texture holds a unit normal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalEncoding {
    /// `xyz` of a four-channel float texture.
    Xyz,
    /// Octahedral coordinates in [-1, 1]^2 in a two-channel texture.
    Octahedral,
}

impl NormalEncoding {
    /// The encoding of a normal texture of `format`, `None` where it holds no normal the
    /// pass can read.
    pub fn of(format: wgpu::TextureFormat) -> Option<Self> {
        use wgpu::TextureFormat as F;
        match format {
            F::Rgba16Float | F::Rgba32Float => Some(Self::Xyz),
            F::Rg16Float | F::Rg32Float | F::Rg16Snorm => Some(Self::Octahedral),
            _ => None,
        }
    }
}

/// An engine's G-buffer textures (each single-sampled 2D with `TEXTURE_BINDING` usage, all
/// of one size).
#[derive(Clone, Copy, Debug)]
pub struct HostGBuffer<'a> {
    /// Linear albedo in `rgb` (an sRGB format decodes on load), any float-sampled format.
    pub albedo: &'a wgpu::Texture,
    /// Unit world-space normals ([`NormalEncoding::of`] says which formats).
    pub normal: &'a wgpu::Texture,
    /// The engine's depth buffer, `Depth32Float`, cleared to the far value (1, or 0
    /// reversed) where nothing was drawn.
    pub depth: &'a wgpu::Texture,
    /// Triangle ids (`R32Uint`) in the scene's numbering, if the engine has them.
    pub triangle_id: Option<&'a wgpu::Texture>,
}

impl HostGBuffer<'_> {
    /// Checks every texture, naming the one at fault; returns the size and the normal
    /// encoding.
    pub fn check(&self) -> Result<((u32, u32), NormalEncoding), GpuError> {
        let size = (self.albedo.width(), self.albedo.height());
        let fault =
            |texture: &'static str, problem: String| GpuError::HostTexture { texture, problem };
        let mut all = vec![
            ("albedo", self.albedo),
            ("normal", self.normal),
            ("depth", self.depth),
        ];
        all.extend(self.triangle_id.map(|t| ("triangle id", t)));
        for (name, t) in all {
            if (t.width(), t.height()) != size {
                return Err(fault(
                    name,
                    format!(
                        "{}x{} where the albedo is {}x{}",
                        t.width(),
                        t.height(),
                        size.0,
                        size.1
                    ),
                ));
            }
            if t.dimension() != wgpu::TextureDimension::D2
                || t.sample_count() != 1
                || t.depth_or_array_layers() != 1
            {
                return Err(fault(
                    name,
                    "not a single-sampled, single-layer 2D texture".into(),
                ));
            }
            if !t.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
                return Err(fault(
                    name,
                    format!("usage {:?} lacks TEXTURE_BINDING", t.usage()),
                ));
            }
        }
        let float = |f: wgpu::TextureFormat| {
            matches!(
                f.sample_type(None, None),
                Some(wgpu::TextureSampleType::Float { .. })
            )
        };
        if !float(self.albedo.format()) || self.albedo.format().components() < 3 {
            return Err(fault(
                "albedo",
                format!(
                    "format {:?}: a colour format with rgb read as float is needed \
                     (Rgba8UnormSrgb, Rgba16Float, Rgba32Float...)",
                    self.albedo.format()
                ),
            ));
        }
        let Some(encoding) = NormalEncoding::of(self.normal.format()) else {
            return Err(fault(
                "normal",
                format!(
                    "format {:?}: Rgba16Float or Rgba32Float (xyz), or Rg16Float, Rg32Float \
                     or Rg16Snorm (octahedral) is needed",
                    self.normal.format()
                ),
            ));
        };
        if self.depth.format() != wgpu::TextureFormat::Depth32Float {
            return Err(fault(
                "depth",
                format!("format {:?}: Depth32Float is needed", self.depth.format()),
            ));
        }
        if let Some(t) = self.triangle_id
            && t.format() != wgpu::TextureFormat::R32Uint
        {
            return Err(fault(
                "triangle id",
                format!("format {:?}: R32Uint is needed", t.format()),
            ));
        }
        Ok((size, encoding))
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    m22: f32,
    m32: f32,
    far: f32,
    flags: u32,
    width: u32,
    height: u32,
    pad: [u32; 2],
}

/// What the bind group depends on (textures by identity).
#[derive(Clone, Debug, PartialEq)]
struct Key {
    sources: Vec<wgpu::Texture>,
    target: [wgpu::Texture; 4],
    variant: usize,
}

/// Turns an engine's G-buffer into the toolkit's, on the engine's device
/// ([`GpuContext::from_device`]). All four pipelines (normal encoding x ids or not) are
/// compiled by [`HostGBufferPass::new`].
pub struct HostGBufferPass {
    ctx: GpuContext,
    passes: Vec<ComputePass>,
    params: wgpu::Buffer,
    writer: FrameWriter,
    no_ids: wgpu::Texture,
    bound: Option<(Key, wgpu::BindGroup)>,
}

impl std::fmt::Debug for HostGBufferPass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HostGBufferPass").finish_non_exhaustive()
    }
}

impl HostGBufferPass {
    /// Compiles the pass's pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let module = ctx.validated(|| HOST_GBUFFER.create_module(device))??;
        let entries = [
            uniform(0),
            float_texture(1),
            float_texture(2),
            texture(3, wgpu::TextureSampleType::Depth),
            texture(4, wgpu::TextureSampleType::Uint),
            storage_texture(5, GpuGBuffer::ALBEDO_FORMAT),
            storage_texture(6, GpuGBuffer::NORMAL_FORMAT),
            storage_texture(7, GpuGBuffer::DEPTH_FORMAT),
            storage_texture(8, GpuGBuffer::TRIANGLE_ID_FORMAT),
        ];
        let mut passes = Vec::new();
        for variant in 0..4u8 {
            let (octahedral, ids) = (variant & 1, variant >> 1);
            passes.push(ctx.validated(|| {
                ComputePass::from_module(
                    device,
                    "host gbuffer",
                    &module,
                    &entries,
                    &[
                        ("OCTAHEDRAL", f64::from(octahedral)),
                        ("HAS_IDS", f64::from(ids)),
                    ],
                )
            })?);
        }
        Ok(Self {
            ctx: ctx.clone(),
            passes,
            params: ctx.frame_buffer(
                "host gbuffer params",
                std::mem::size_of::<Params>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            writer: FrameWriter::new(device, 1024),
            no_ids: ctx.create_texture_2d(
                "host gbuffer: no ids",
                1,
                1,
                wgpu::TextureFormat::R32Uint,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            bound: None,
        })
    }

    /// Records the conversion of `host` (read with `depth`, the engine's convention from
    /// [`crate::View::from_host_matrices`]) into `target` (same size) into `encoder`.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        host: &HostGBuffer<'_>,
        depth: &DepthConvention,
        target: &GpuGBuffer,
    ) -> Result<(), GpuError> {
        let ((w, h), encoding) = host.check()?;
        if (target.width, target.height) != (w, h) {
            return Err(GpuError::InvalidSize {
                width: target.width,
                height: target.height,
                reason: format!("the target G-buffer must match the engine's {w}x{h}"),
            });
        }
        let variant = usize::from(encoding == NormalEncoding::Octahedral)
            + 2 * usize::from(host.triangle_id.is_some());
        let key = Key {
            sources: [host.albedo, host.normal, host.depth]
                .into_iter()
                .chain(host.triangle_id)
                .cloned()
                .collect(),
            target: [
                target.albedo.clone(),
                target.normal.clone(),
                target.depth.clone(),
                target.triangle_id.clone(),
            ],
            variant,
        };
        if self.bound.as_ref().is_none_or(|(k, _)| *k != key) {
            let view = |t: &wgpu::Texture| t.create_view(&Default::default());
            let views = [
                view(host.albedo),
                view(host.normal),
                host.depth.create_view(&wgpu::TextureViewDescriptor {
                    aspect: wgpu::TextureAspect::DepthOnly,
                    ..Default::default()
                }),
                view(host.triangle_id.unwrap_or(&self.no_ids)),
                view(&target.albedo),
                view(&target.normal),
                view(&target.depth),
                view(&target.triangle_id),
            ];
            let mut res = vec![self.params.as_entire_binding()];
            res.extend(views.iter().map(wgpu::BindingResource::TextureView));
            let bind = self
                .ctx
                .validated(|| self.passes[variant].bind(&self.ctx.device, &res))?;
            self.bound = Some((key, bind));
        }
        let (m22, m32, far) = depth.parts();
        let params = Params {
            m22,
            m32,
            far,
            flags: u32::from(depth.orthographic) | (u32::from(depth.reverse) << 1),
            width: w,
            height: h,
            pad: [0; 2],
        };
        self.writer
            .write(encoder, &self.params, 0, bytemuck::bytes_of(&params));
        self.writer.finish(encoder);
        let Some((_, bind)) = self.bound.as_ref() else {
            unreachable!("made above")
        };
        self.passes[variant].dispatch(encoder, bind, w, h, None);
        Ok(())
    }
}

/// A `width x height` `Depth32Float` texture holding `values` (row-major), drawn by a
/// full-screen triangle that writes `frag_depth` (depth textures cannot be written by
/// copies): what a test or an example needs to stand in for an engine's depth buffer. The
/// texture has `RENDER_ATTACHMENT | TEXTURE_BINDING` usage.
pub fn depth_texture_from(
    ctx: &GpuContext,
    width: u32,
    height: u32,
    values: &[f32],
) -> Result<wgpu::Texture, GpuError> {
    ctx.check_texture_size(width, height)?;
    if values.len() != width as usize * height as usize {
        return Err(GpuError::InvalidSize {
            width,
            height,
            reason: format!("{} depth values for {width}x{height} pixels", values.len()),
        });
    }
    let device = &ctx.device;
    let src = format!(
        "@group(0) @binding(0) var<storage, read> depth: array<f32>;
         @vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {{
             let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
             return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
         }}
         @fragment fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {{
             return depth[u32(p.y) * {width}u + u32(p.x)];
         }}"
    );
    ctx.validated(|| {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("depth texture from values"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("depth texture from values"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            multiview_mask: None,
            cache: None,
        });
        let buffer = ctx.storage_with(
            "depth values",
            bytemuck::cast_slice(values),
            wgpu::BufferUsages::empty(),
        );
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: buffer.as_entire_binding(),
            }],
        });
        let t = ctx.create_texture_2d(
            "depth from values",
            width,
            height,
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let view = t.create_view(&Default::default());
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: None,
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.5),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..3, 0..1);
        }
        ctx.queue.submit([encoder.finish()]);
        t
    })
}

#[cfg(test)]
mod tests {
    /// The parameters written from Rust have the layout naga gives `Params` in the shader.
    #[test]
    fn params_match_the_shader() {
        let module = super::HOST_GBUFFER.compose().unwrap();
        crate::check_layout!(
            &module,
            "Params",
            super::Params {
                m22,
                m32,
                far,
                flags,
                width,
                height,
                pad0: pad,
                pad1: pad + 4,
            }
        )
        .unwrap();
    }
}

/// An 8-bit sRGB code of a linear value in [0, 1] (the sRGB transfer function, rounded):
/// how an engine stores albedo in `Rgba8UnormSrgb`.
pub fn srgb8(linear: f32) -> u8 {
    let c = if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    };
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// A unit normal in the octahedral encoding as two half floats (`Rg16Float`), the compact
/// normal format engines keep and [`HostGBufferPass`] decodes; a zero or non-finite normal
/// (background) encodes as zeros.
pub fn octahedral_f16(n: glam::Vec3) -> [u16; 2] {
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    if !(l1 > 0.0 && l1.is_finite()) {
        return [0; 2];
    }
    let p = n / l1;
    let e = if p.z >= 0.0 {
        [p.x, p.y]
    } else {
        let s = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        [(1.0 - p.y.abs()) * s(p.x), (1.0 - p.x.abs()) * s(p.y)]
    };
    e.map(|x| half::f16::from_f32(x).to_bits())
}

/// An engine's G-buffer made from a toolkit [`crate::GBuffer`], standing in for an engine in
/// tests and examples: albedo, normals, the depth buffer (`Depth32Float`) in the engine's
/// convention with its clear value (1, or 0 reversed) where nothing is drawn, and triangle
/// ids when the engine has them. [`EngineGBuffer::compact`] keeps the compact formats
/// engines use, [`EngineGBuffer::float`] float ones. The textures are readable too, so a
/// test can check what was packed.
#[derive(Debug)]
pub struct EngineGBuffer {
    /// Albedo: `Rgba8UnormSrgb` (compact) or `Rgba32Float`.
    pub albedo: wgpu::Texture,
    /// Normals: `Rg16Float` octahedral (compact) or `Rgba32Float` `xyz`.
    pub normal: wgpu::Texture,
    /// `Depth32Float` depth in the engine's convention.
    pub depth: wgpu::Texture,
    /// `R32Uint` triangle ids, when kept.
    pub triangle_id: Option<wgpu::Texture>,
}

impl EngineGBuffer {
    /// `g` (seen by a view whose far plane is `far`) as an engine keeps it: 8-bit sRGB
    /// albedo, octahedral half-float normals, its depth written in `convention`
    /// ([`crate::View::from_host_matrices`]), no triangle ids.
    pub fn compact(
        ctx: &GpuContext,
        g: &crate::GBuffer,
        far: f32,
        convention: &DepthConvention,
    ) -> Result<Self, GpuError> {
        let albedo: Vec<[u8; 4]> = g
            .albedo
            .iter()
            .map(|a| [srgb8(a.x), srgb8(a.y), srgb8(a.z), 255])
            .collect();
        let normal: Vec<[u16; 2]> = g.normal.iter().map(|n| octahedral_f16(*n)).collect();
        Self::with(
            ctx,
            g,
            far,
            convention,
            [
                (
                    wgpu::TextureFormat::Rgba8UnormSrgb,
                    bytemuck::cast_slice(&albedo),
                ),
                (
                    wgpu::TextureFormat::Rg16Float,
                    bytemuck::cast_slice(&normal),
                ),
            ],
            false,
        )
    }

    /// `g` in float formats (`Rgba32Float` albedo and `xyz` normals) with its depth in
    /// `convention`, and its triangle ids when `ids`.
    pub fn float(
        ctx: &GpuContext,
        g: &crate::GBuffer,
        far: f32,
        convention: &DepthConvention,
        ids: bool,
    ) -> Result<Self, GpuError> {
        let normal: Vec<[f32; 4]> = g.normal.iter().map(|n| n.extend(0.0).to_array()).collect();
        Self::with(
            ctx,
            g,
            far,
            convention,
            [
                (
                    wgpu::TextureFormat::Rgba32Float,
                    bytemuck::cast_slice(&g.albedo),
                ),
                (
                    wgpu::TextureFormat::Rgba32Float,
                    bytemuck::cast_slice(&normal),
                ),
            ],
            ids,
        )
    }

    /// Uploads albedo and normal texels as given, the depth of `g` in `convention`, and
    /// with `ids` its triangle ids.
    fn with(
        ctx: &GpuContext,
        g: &crate::GBuffer,
        far: f32,
        convention: &DepthConvention,
        [(albedo_format, albedo), (normal_format, normal)]: [(wgpu::TextureFormat, &[u8]); 2],
        ids: bool,
    ) -> Result<Self, GpuError> {
        let (w, h) = (g.width, g.height);
        ctx.check_texture_size(w, h)?;
        let clear = if convention.reverse { 0.0 } else { 1.0 };
        let depth: Vec<f32> = (0..g.len())
            .map(|i| {
                if g.is_background(i) {
                    clear
                } else {
                    convention.depth(g.depth[i] * far)
                }
            })
            .collect();
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC;
        let upload =
            |label, format, bytes: &[u8]| ctx.texture_with(label, (w, h), format, usage, bytes);
        Ok(Self {
            albedo: upload("engine albedo", albedo_format, albedo),
            normal: upload("engine normals", normal_format, normal),
            depth: depth_texture_from(ctx, w, h, &depth)?,
            triangle_id: ids.then(|| {
                upload(
                    "engine triangle ids",
                    wgpu::TextureFormat::R32Uint,
                    bytemuck::cast_slice(&g.triangle_id),
                )
            }),
        })
    }

    /// The textures as [`HostGBufferPass`] reads them.
    pub fn host(&self) -> HostGBuffer<'_> {
        HostGBuffer {
            albedo: &self.albedo,
            normal: &self.normal,
            depth: &self.depth,
            triangle_id: self.triangle_id.as_ref(),
        }
    }
}
