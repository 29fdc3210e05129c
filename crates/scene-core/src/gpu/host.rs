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
    &[super::shader::LIMITS],
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
    bound: super::Keyed<Key, wgpu::BindGroup>,
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
            bound: super::Keyed::new(),
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
        self.bound.get_or_try_make(key, |_| {
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
            self.ctx
                .validated(|| self.passes[variant].bind(&self.ctx.device, &res))
        })?;
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
        let Some(bind) = self.bound.value() else {
            unreachable!("made above")
        };
        self.passes[variant].dispatch(encoder, bind, w, h, None);
        Ok(())
    }
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
