//! Test and example support (feature `testing`, not in the default API): a GPU context for
//! tests that skips or fails by `REQUIRE_GPU` ([`gpu_test_context`]), and an engine's
//! G-buffer made from a toolkit one ([`EngineGBuffer`], with [`depth_texture_from`],
//! [`srgb8`] and [`octahedral_f16`]), which the engine examples and the frame-contract
//! tests of every method stand on, and the host those examples share ([`ExampleHost`]: the
//! engine's device, camera, G-buffer and frame loop), and Khronos' glTF validator run on
//! what the toolkit exports ([`gltf_validator`], with the `gltf` feature). (In `scene_core::gpu` until 2026-11-27.)
//!
//! A crate's tests turn it on through their dev-dependency:
//! `scene-core = { version = "0.1", features = ["testing"] }`.

use crate::DepthConvention;
use crate::gpu::shader::ShaderPass;
use crate::gpu::{GpuContext, GpuError, HostGBuffer};

mod example_host;
pub use example_host::{ExampleError, ExampleHost, LIGHT_CYCLE};
#[cfg(feature = "gltf")]
pub mod gltf_validator;

/// The pass of [`depth_texture_from`] (`shaders/scene-core/depth_from_values.wgsl`).
pub const DEPTH_FROM_VALUES: ShaderPass = ShaderPass::new(
    "scene-core/depth_from_values",
    crate::wgsl_file!("scene-core", "depth_from_values.wgsl"),
    &[],
);

/// A context for GPU tests of any crate of the workspace.
///
/// Returns `Some` when an adapter exists. When none does: if the environment variable
/// `REQUIRE_GPU` is set to a non-empty value other than `0` (as CI does) it panics with the
/// [`GpuError`] message, so a missing driver fails loudly; otherwise it prints
/// `skipping GPU test: <reason>` to stderr and returns `None`, and the test should return
/// early. An adapter that exists but fails to create a device always panics.
///
/// Nothing is cached: each call creates a fresh device, which takes about 15-25 ms on Mesa's
/// lavapipe (the first one in a process about 55 ms), so tests simply call it each time.
///
/// ```no_run
/// let Some(ctx) = scene_core::testing::gpu_test_context() else { return };
/// println!("testing on {}", ctx.adapter_summary());
/// ```
pub fn gpu_test_context() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) => {
            let required = std::env::var("REQUIRE_GPU").is_ok_and(|v| !v.is_empty() && v != "0");
            if required {
                panic!("REQUIRE_GPU is set but no GPU context could be created: {e}");
            }
            if !e.is_missing_adapter() {
                panic!("a GPU adapter exists but the context failed: {e}");
            }
            eprintln!("skipping GPU test: {e}");
            None
        }
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
    let module = DEPTH_FROM_VALUES.create_module(device)?;
    ctx.validated(|| {
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
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &[("WIDTH", f64::from(width))],
                    ..Default::default()
                },
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
/// normal format engines keep and [`HostGBufferPass`](crate::gpu::HostGBufferPass) decodes; a zero or non-finite normal
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

    /// An engine's G-buffer from its own `width x height` texels (row-major): albedo as
    /// 8-bit sRGB, normals octahedral in half floats ([`octahedral_f16`]), depth in its
    /// convention with its clear value where nothing is drawn; no ids. Fails, naming the
    /// buffer, when a length is not the pixel count.
    pub fn from_texels(
        ctx: &GpuContext,
        (width, height): (u32, u32),
        albedo: &[[u8; 4]],
        normal: &[[u16; 2]],
        depth: &[f32],
    ) -> Result<Self, GpuError> {
        let pixels = width as usize * height as usize;
        for (what, len) in [("albedo", albedo.len()), ("normal", normal.len())] {
            if len != pixels {
                return Err(GpuError::InvalidSize {
                    width,
                    height,
                    reason: format!("{len} {what} texels for {width}x{height} pixels"),
                });
            }
        }
        Self::upload(
            ctx,
            (width, height),
            [
                (
                    wgpu::TextureFormat::Rgba8UnormSrgb,
                    bytemuck::cast_slice(albedo),
                ),
                (wgpu::TextureFormat::Rg16Float, bytemuck::cast_slice(normal)),
            ],
            depth,
            None,
        )
    }

    /// Uploads albedo and normal texels as given, the depth of `g` in `convention`, and
    /// with `ids` its triangle ids.
    fn with(
        ctx: &GpuContext,
        g: &crate::GBuffer,
        far: f32,
        convention: &DepthConvention,
        colours: [(wgpu::TextureFormat, &[u8]); 2],
        ids: bool,
    ) -> Result<Self, GpuError> {
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
        let ids = ids.then_some(g.triangle_id.as_slice());
        Self::upload(ctx, (g.width, g.height), colours, &depth, ids)
    }

    /// Uploads the colour texels as given, `depth` as a depth texture and the ids.
    fn upload(
        ctx: &GpuContext,
        (w, h): (u32, u32),
        [(albedo_format, albedo), (normal_format, normal)]: [(wgpu::TextureFormat, &[u8]); 2],
        depth: &[f32],
        ids: Option<&[u32]>,
    ) -> Result<Self, GpuError> {
        ctx.check_texture_size(w, h)?;
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC;
        let upload =
            |label, format, bytes: &[u8]| ctx.texture_with(label, (w, h), format, usage, bytes);
        Ok(Self {
            depth: depth_texture_from(ctx, w, h, depth)?,
            albedo: upload("engine albedo", albedo_format, albedo),
            normal: upload("engine normals", normal_format, normal),
            triangle_id: ids.map(|ids| {
                upload(
                    "engine triangle ids",
                    wgpu::TextureFormat::R32Uint,
                    bytemuck::cast_slice(ids),
                )
            }),
        })
    }

    /// The textures as [`HostGBufferPass`](crate::gpu::HostGBufferPass) reads them.
    pub fn host(&self) -> HostGBuffer<'_> {
        HostGBuffer {
            albedo: &self.albedo,
            normal: &self.normal,
            depth: &self.depth,
            triangle_id: self.triangle_id.as_ref(),
        }
    }
}

/// The oracle of the GPU shadow maps, shared by the methods that shade with them (ISR and
/// relighting): a method's frame with maps rendered on the GPU (`got`) equals its frame with
/// the CPU's maps (`expected`) within 1e-4 of the image's light, while the same frame
/// without the GPU maps copied in (`unshadowed`) differs by more than 1 % (so the shadows
/// show and the check can fail). Images are RGBA texels as read back; alpha is ignored.
/// Prints both differences as shares of the image and panics naming the one that fails.
pub fn assert_gpu_shadow_maps_match(
    expected: &[[f32; 4]],
    unshadowed: &[[f32; 4]],
    got: &[[f32; 4]],
) {
    let diff = |a: &[[f32; 4]], b: &[[f32; 4]]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (0..3).map(|c| f64::from((p[c] - q[c]).abs())).sum::<f64>())
            .sum::<f64>()
    };
    assert_eq!(expected.len(), got.len(), "images of different sizes");
    assert_eq!(
        expected.len(),
        unshadowed.len(),
        "images of different sizes"
    );
    let total: f64 = expected.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum();
    let (d, before) = (diff(got, expected), diff(unshadowed, expected));
    eprintln!(
        "GPU maps: {:.2e} of the image; before the copy (unshadowed): {:.2e}",
        d / total,
        before / total
    );
    assert!(
        before > 1e-2 * total,
        "the shadows do not show: {before} of {total}"
    );
    assert!(d <= 1e-4 * total, "GPU maps off by {d} of {total}");
}
