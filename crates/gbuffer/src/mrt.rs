//! The GPU G-buffer: a wgpu render pipeline writing albedo + radiation mask, world normal,
//! linear depth and triangle id in one pass with multiple render targets (thesis figure
//! 4.1), plus the depth attachment. Shader: `shaders/gbuffer/mrt.wgsl` ([`MRT`]).
//!
//! The result stays on the GPU as a [`GpuGBuffer`] (formats in
//! [`GpuGBuffer::COLOR_FORMATS`]); reading it back is the separate, explicit step
//! [`GpuGBuffer::read_back`]. The [`GBufferRenderer`] implementation of [`GpuRasterizer`]
//! does both, for callers that want a CPU [`GBuffer`].
//!
//! Scenes are uploaded once into a [`GpuPreparedScene`] (the flattened vertex buffer of
//! [`GpuScene`], per-triangle geometric normals for the two-sided flip, and
//! the albedo textures as one texel buffer sampled bilinearly in the shader exactly like
//! [`scene_core::Texture::sample`]). The trait implementation keeps the last
//! prepared scene ([`GBufferRenderer::prepare`]) and renders every view of it with no
//! further upload or hashing.

use std::sync::Arc;

use crate::scene_upload::{GpuScene, GpuVertex, upload_scene};
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use scene_core::gpu::shader::ShaderPass;
use scene_core::gpu::{GpuContext, GpuError, GpuGBuffer, Keyed};
use scene_core::view::Projection;
use scene_core::{Error, GBuffer, GBufferRenderer, Scene, View, ViewTarget};

use crate::raster::check_target;

/// The G-buffer geometry pass (`shaders/gbuffer/mrt.wgsl`, vertex and fragment stages).
pub const MRT: ShaderPass = ShaderPass::new(
    "gbuffer/mrt",
    scene_core::wgsl_file!("gbuffer", "mrt.wgsl"),
    &[scene_core::gpu::shader::TEXTURE_WRAP],
);

/// The view uniform of `mrt.wgsl` (96 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ViewUniform {
    view_proj: [f32; 16],
    eye: [f32; 3],
    inv_far: f32,
    forward: [f32; 3],
    orthographic: u32,
}

impl ViewUniform {
    fn new(view: &View) -> Self {
        Self {
            view_proj: view.view_projection().to_cols_array(),
            eye: view.eye.to_array(),
            inv_far: 1.0 / view.far,
            forward: view.forward.to_array(),
            orthographic: u32::from(matches!(view.projection, Projection::Orthographic { .. })),
        }
    }
}

/// Where one texture lies in the texel buffer (16 bytes, `TextureInfo` in `mrt.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct TextureInfo {
    offset: u32,
    width: u32,
    height: u32,
    /// [`scene_core::Sampler::bits`].
    sampler: u32,
}

/// A scene uploaded for [`GpuRasterizer`].
#[derive(Debug)]
pub struct GpuPreparedScene {
    /// The flattened vertices and materials ([`upload_scene`]).
    pub geometry: GpuScene,
    /// One unit geometric normal per triangle (`vec4`, `w` = 0), by global triangle id.
    pub face_normals: wgpu::Buffer,
    /// Offset and size of each albedo texture in `texels`.
    pub texture_infos: wgpu::Buffer,
    /// Every texture's linear RGB texels (`vec4`, `w` = alpha, 1 without), one texture after
    /// another.
    pub texels: wgpu::Buffer,
}

impl GpuPreparedScene {
    /// Uploads `scene`. Errors when a buffer exceeds the device's buffer or storage-binding
    /// size limits (about 2.8 million triangles per 128 MiB vertex buffer at 48 bytes per
    /// vertex; per-triangle normals are 16 bytes).
    pub fn new(ctx: &GpuContext, scene: &Scene) -> Result<Self, GpuError> {
        let limits = ctx.device.limits();
        let triangles = scene.triangle_count() as u64;
        let too_big = |what: &str, bytes: u64, limit: u64| {
            if bytes > limit {
                Err(GpuError::Validation(format!(
                    "scene '{}': {what} needs {bytes} bytes, the device allows {limit}",
                    scene.name
                )))
            } else {
                Ok(())
            }
        };
        too_big(
            "the vertex buffer",
            triangles * 3 * std::mem::size_of::<GpuVertex>() as u64,
            limits.max_buffer_size,
        )?;
        too_big(
            "the face-normal buffer",
            triangles * 16,
            limits.max_storage_buffer_binding_size,
        )?;
        let texel_count: u64 = scene
            .textures
            .iter()
            .map(|t| t.width as u64 * t.height as u64)
            .sum();
        too_big(
            "the texel buffer",
            texel_count * 16,
            limits.max_storage_buffer_binding_size,
        )?;

        let mut normals: Vec<[f32; 4]> = Vec::with_capacity(triangles as usize);
        for mesh in &scene.meshes {
            let part: Vec<[f32; 4]> = mesh
                .indices
                .par_iter()
                .with_min_len(4096)
                .map(|idx| {
                    let p = idx.map(|i| {
                        mesh.positions
                            .get(i as usize)
                            .copied()
                            .unwrap_or(glam::Vec3::ZERO)
                    });
                    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
                    [n.x, n.y, n.z, 0.0]
                })
                .collect();
            normals.extend(part);
        }
        let mut infos = Vec::with_capacity(scene.textures.len());
        let mut texels: Vec<[f32; 4]> = Vec::with_capacity(texel_count as usize);
        for t in &scene.textures {
            let n = t.width as usize * t.height as usize;
            infos.push(TextureInfo {
                offset: texels.len() as u32,
                width: if t.texels.len() == n { t.width } else { 0 },
                height: if t.texels.len() == n { t.height } else { 0 },
                sampler: t.sampler.bits(),
            });
            let alpha = |i: usize| {
                t.alpha
                    .as_ref()
                    .and_then(|a| a.get(i))
                    .copied()
                    .unwrap_or(1.0)
            };
            texels.extend(
                t.texels
                    .iter()
                    .take(n)
                    .enumerate()
                    .map(|(i, c)| [c.x, c.y, c.z, alpha(i)]),
            );
        }
        let geometry = ctx.validated(|| upload_scene(ctx, scene))?;
        let storage = |label: &str, bytes: &[u8], dummy: &[u8]| {
            // Empty storage bindings are invalid: upload a placeholder.
            let bytes = if bytes.is_empty() { dummy } else { bytes };
            ctx.storage_with(label, bytes, wgpu::BufferUsages::COPY_DST)
        };
        let dummy4 = [0u8; 16];
        let (face_normals, texture_infos, texels) = ctx.validated(|| {
            (
                storage("face normals", bytemuck::cast_slice(&normals), &dummy4),
                storage("texture infos", bytemuck::cast_slice(&infos), &dummy4),
                storage("texels", bytemuck::cast_slice(&texels), &dummy4),
            )
        })?;
        Ok(Self {
            geometry,
            face_normals,
            texture_infos,
            texels,
        })
    }
}

/// The wgpu MRT G-buffer renderer.
///
/// ```no_run
/// use gbuffer::GpuRasterizer;
/// use scene_core::{builtin, gpu::GpuContext, View};
///
/// let ctx = GpuContext::new().unwrap();
/// let scene = builtin::scene("cornell").unwrap();
/// let view = View::from_camera(&scene.cameras[0]);
/// let rast = GpuRasterizer::new(&ctx).unwrap();
/// let prepared = rast.upload(&scene).unwrap();
/// let target = rast.render_gpu(&prepared, &view, 512, 512).unwrap(); // stays on the GPU
/// let cpu_copy = target.read_back(&ctx).unwrap(); // the explicit readback
/// assert_eq!(cpu_copy.len(), 512 * 512);
/// ```
#[derive(Debug)]
pub struct GpuRasterizer {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    prepared: Option<(Arc<Scene>, GpuPreparedScene)>,
    /// The view's uniform, written by a copy in each pass' encoder
    /// ([`scene_core::gpu::FrameWriter`]): several views recorded into one encoder each see
    /// their own.
    view_uniform: wgpu::Buffer,
    writer: scene_core::gpu::FrameWriter,
    /// The bind group of the last scene drawn (keyed by its materials buffer).
    bound: std::sync::Mutex<Keyed<wgpu::Buffer, wgpu::BindGroup>>,
    /// The attachment views of the last target drawn into (keyed by its textures).
    views: std::sync::Mutex<Keyed<[wgpu::Texture; 5], TargetViews>>,
}

/// A G-buffer target's attachment views.
#[derive(Debug)]
struct TargetViews {
    colour: [wgpu::TextureView; 4],
    depth: wgpu::TextureView,
}

/// Bytes per sample of the four colour targets (16 + 16 + 4 + 4).
const MRT_BYTES_PER_SAMPLE: u32 = 40;

impl GpuRasterizer {
    /// Compiles the pipeline on `ctx`'s device. Errors when the device cannot write the
    /// four colour targets in one pass (its `max_color_attachment_bytes_per_sample` is
    /// below 40; Vulkan, DX12 and recent Metal devices allow 64 or more).
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let limit = ctx.device.limits().max_color_attachment_bytes_per_sample;
        if limit < MRT_BYTES_PER_SAMPLE {
            return Err(GpuError::Validation(format!(
                "the device allows {limit} bytes of colour attachments per sample; the \
                 G-buffer pass writes {MRT_BYTES_PER_SAMPLE} (albedo, normal, depth, id)"
            )));
        }
        let device = &ctx.device;
        let module = MRT.create_module(device)?;
        let (layout, pipeline) = ctx.validated(|| {
            let storage =
                |binding: u32, visibility: wgpu::ShaderStages| wgpu::BindGroupLayoutEntry {
                    binding,
                    visibility,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                };
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("gbuffer mrt"),
                entries: &[
                    wgpu::BindGroupLayoutEntry {
                        binding: 0,
                        visibility: wgpu::ShaderStages::VERTEX,
                        ty: wgpu::BindingType::Buffer {
                            ty: wgpu::BufferBindingType::Uniform,
                            has_dynamic_offset: false,
                            min_binding_size: wgpu::BufferSize::new(
                                std::mem::size_of::<ViewUniform>() as u64,
                            ),
                        },
                        count: None,
                    },
                    storage(1, wgpu::ShaderStages::FRAGMENT),
                    storage(2, wgpu::ShaderStages::VERTEX),
                    storage(3, wgpu::ShaderStages::FRAGMENT),
                    storage(4, wgpu::ShaderStages::FRAGMENT),
                ],
            });
            let targets = GpuGBuffer::COLOR_FORMATS.map(|format| {
                Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })
            });
            let pipeline = scene_core::gpu::raster::depth_tested_pipeline(
                device,
                "gbuffer mrt",
                &layout,
                &module,
                &[Some(GpuVertex::buffer_layout())],
                &targets,
            );
            (layout, pipeline)
        })?;
        Ok(Self {
            view_uniform: ctx.frame_buffer(
                "gbuffer view",
                std::mem::size_of::<ViewUniform>() as u64,
                wgpu::BufferUsages::UNIFORM,
            ),
            writer: scene_core::gpu::FrameWriter::new(device, 256),
            bound: std::sync::Mutex::new(Keyed::new()),
            views: std::sync::Mutex::new(Keyed::new()),
            ctx: ctx.clone(),
            layout,
            pipeline,
            prepared: None,
        })
    }

    /// The context the pipeline lives on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Uploads a scene for [`GpuRasterizer::encode`] and friends (the
    /// [`GBufferRenderer::prepare`] of the trait keeps one such upload for its renders).
    pub fn upload(&self, scene: &Scene) -> Result<GpuPreparedScene, GpuError> {
        GpuPreparedScene::new(&self.ctx, scene)
    }

    /// Records the G-buffer pass for `view` into `encoder`, rendering into `target`
    /// (cleared first). Nothing runs until the encoder is submitted; several views can be
    /// recorded into one encoder (each view's uniform is copied in before its pass). Once a
    /// scene and a target have been seen, nothing is created.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuPreparedScene,
        view: &View,
        target: &GpuGBuffer,
    ) -> Result<(), Error> {
        check_target(view, target.width, target.height)?;
        let depth_attachment = target.depth_attachment()?;
        let device = &self.ctx.device;
        self.ctx.validated(|| {
            self.writer.write(
                encoder,
                &self.view_uniform,
                0,
                bytemuck::bytes_of(&ViewUniform::new(view)),
            );
            self.writer.finish(encoder);
            let mut bound = self.bound.lock().unwrap_or_else(|e| e.into_inner());
            let bind_group = bound
                .get_or_make(scene.geometry.materials.clone(), |_| {
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("gbuffer mrt"),
                        layout: &self.layout,
                        entries: &[
                            wgpu::BindGroupEntry {
                                binding: 0,
                                resource: self.view_uniform.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 1,
                                resource: scene.geometry.materials.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 2,
                                resource: scene.face_normals.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 3,
                                resource: scene.texture_infos.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 4,
                                resource: scene.texels.as_entire_binding(),
                            },
                        ],
                    })
                })
                .clone();
            drop(bound);
            let key = [
                target.albedo.clone(),
                target.normal.clone(),
                target.depth.clone(),
                target.triangle_id.clone(),
                depth_attachment.clone(),
            ];
            let mut kept = self.views.lock().unwrap_or_else(|e| e.into_inner());
            let target_views = kept.get_or_make(key, |key| TargetViews {
                colour: [0, 1, 2, 3].map(|i| key[i].create_view(&Default::default())),
                depth: key[4].create_view(&Default::default()),
            });
            let views = &target_views.colour;
            let clears = [
                wgpu::Color::TRANSPARENT,
                wgpu::Color::TRANSPARENT,
                wgpu::Color {
                    r: 1.0,
                    g: 0.0,
                    b: 0.0,
                    a: 0.0,
                },
                wgpu::Color {
                    r: scene_core::BACKGROUND_ID as f64,
                    g: 0.0,
                    b: 0.0,
                    a: 0.0,
                },
            ];
            let targets: Vec<(&wgpu::TextureView, wgpu::Color)> =
                views.iter().zip(clears).collect();
            // The depth is stored: `reconstruct` reads the hardware depth back.
            let mut pass = scene_core::gpu::raster::depth_tested_pass(
                encoder,
                "gbuffer mrt",
                &targets,
                &target_views.depth,
                wgpu::StoreOp::Store,
            );
            let count = scene.geometry.vertex_count;
            if count > 0 {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.set_vertex_buffer(0, scene.geometry.vertices.slice(..));
                pass.draw(0..count, 0..1);
            }
        })?;
        Ok(())
    }

    /// Renders `view` into `target` and submits (returns without waiting for the GPU).
    pub fn render_to(
        &self,
        scene: &GpuPreparedScene,
        view: &View,
        target: &GpuGBuffer,
    ) -> Result<(), Error> {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer"),
            });
        self.encode(&mut encoder, scene, view, target)?;
        self.ctx
            .validated(|| self.ctx.queue.submit([encoder.finish()]))?;
        Ok(())
    }

    /// Creates a `width x height` [`GpuGBuffer`], renders `view` into it and submits.
    pub fn render_gpu(
        &self,
        scene: &GpuPreparedScene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GpuGBuffer, Error> {
        check_target(view, width, height)?;
        let target = GpuGBuffer::new(&self.ctx, width, height)?;
        self.render_to(scene, view, &target)?;
        Ok(target)
    }

    /// Renders the five faces of the hemicube of `resolution` at `point` with `normal`
    /// (views and sizes as [`crate::hemicube`]) into new GPU G-buffers, recorded into one
    /// command buffer and submitted once (without waiting).
    #[allow(clippy::too_many_arguments)]
    pub fn render_hemicube_gpu(
        &self,
        scene: &GpuPreparedScene,
        point: glam::Vec3,
        normal: glam::Vec3,
        resolution: u32,
        near: f32,
        far: f32,
    ) -> Result<Vec<(scene_core::HemicubeFace, View, GpuGBuffer)>, Error> {
        scene_core::gbuffer::check_hemicube(point, normal, resolution)?;
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer hemicube"),
            });
        let mut faces = Vec::with_capacity(5);
        for (face, view) in crate::hemicube::hemicube_views(point, normal, near, far) {
            let (w, h) = face.size(resolution);
            check_target(&view, w, h)?;
            let target = GpuGBuffer::new(&self.ctx, w, h)?;
            self.encode(&mut encoder, scene, &view, &target)?;
            faces.push((face, view, target));
        }
        self.ctx
            .validated(|| self.ctx.queue.submit([encoder.finish()]))?;
        Ok(faces)
    }

    /// Blocks until all submitted work has finished (for timing).
    pub fn wait(&self) -> Result<(), GpuError> {
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(format!("device poll failed: {e}")))
    }

    /// Records every view of `views` into one command buffer, each into a new
    /// [`GpuGBuffer`], and submits once (without waiting).
    pub fn render_batch_gpu(
        &self,
        scene: &GpuPreparedScene,
        views: &[ViewTarget],
    ) -> Result<Vec<GpuGBuffer>, Error> {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer batch"),
            });
        let mut targets = Vec::with_capacity(views.len());
        for t in views {
            check_target(&t.view, t.width, t.height)?;
            let target = GpuGBuffer::new(&self.ctx, t.width, t.height)?;
            self.encode(&mut encoder, scene, &t.view, &target)?;
            targets.push(target);
        }
        self.ctx
            .validated(|| self.ctx.queue.submit([encoder.finish()]))?;
        Ok(targets)
    }

    fn prepared_upload(&self) -> Result<&GpuPreparedScene, Error> {
        self.prepared
            .as_ref()
            .map(|p| &p.1)
            .ok_or_else(|| Error::NotPrepared("the GPU rasteriser".into()))
    }
}

impl GBufferRenderer for GpuRasterizer {
    fn name(&self) -> &str {
        "gpu"
    }

    /// Uploads `scene` ([`GpuPreparedScene::new`]); later renders draw it with no further
    /// upload.
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.prepared = None;
        let upload = GpuPreparedScene::new(&self.ctx, &scene)?;
        self.prepared = Some((scene, upload));
        Ok(())
    }

    fn prepared_scene(&self) -> Option<&Arc<Scene>> {
        self.prepared.as_ref().map(|p| &p.0)
    }

    /// All views recorded into one submission ([`GpuRasterizer::render_batch_gpu`]), then
    /// read back.
    fn render_views(&mut self, views: &[ViewTarget]) -> Result<Vec<GBuffer>, Error> {
        let targets = self.render_batch_gpu(self.prepared_upload()?, views)?;
        targets
            .iter()
            .map(|t| Ok(t.read_back(&self.ctx)?))
            .collect()
    }

    /// A one-off render: `scene` is uploaded for this call unless it is the prepared one.
    fn render(
        &mut self,
        scene: &Scene,
        view: &View,
        width: u32,
        height: u32,
    ) -> Result<GBuffer, Error> {
        check_target(view, width, height)?;
        let target = match self.prepared.as_ref() {
            Some((s, upload)) if std::ptr::eq(Arc::as_ptr(s), scene) => {
                self.render_gpu(upload, view, width, height)?
            }
            _ => {
                let upload = GpuPreparedScene::new(&self.ctx, scene)?;
                self.render_gpu(&upload, view, width, height)?
            }
        };
        Ok(target.read_back(&self.ctx)?)
    }

    fn render_views_gpu(&mut self, views: &[ViewTarget]) -> Result<Option<Vec<GpuGBuffer>>, Error> {
        Ok(Some(self.render_batch_gpu(self.prepared_upload()?, views)?))
    }
}

/// Every struct written for the shader has the layout naga gives its WGSL twin (a field
/// moved on one side fails here).
#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::scene_upload::GpuMaterial;
    use scene_core::check_layout;

    #[test]
    fn uniforms_and_tables_match_their_wgsl_structs() {
        let mrt = MRT.compose().unwrap();
        check_layout!(
            &mrt,
            "ViewUniform",
            ViewUniform {
                view_proj,
                eye,
                inv_far,
                forward,
                orthographic,
            }
        )
        .unwrap();
        check_layout!(
            &mrt,
            "TextureInfo",
            TextureInfo {
                offset,
                width,
                height,
                sampler
            }
        )
        .unwrap();
        check_layout!(
            &mrt,
            "Material",
            GpuMaterial {
                albedo,
                texture,
                emission,
                alpha_cutoff
            }
        )
        .unwrap();
    }
}
