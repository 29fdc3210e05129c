//! Triangle ids a method renders for itself (issue 30, docs/engine.md; in scene-core until
//! 2026-11-27, relighting is its one user): an engine's G-buffer
//! rarely has ids, and those it has are of the engine's triangles, not of a method's own
//! (relighting's elements). [`TriangleIdPass`] rasterises a fixed list of world-space
//! triangles for the frame's view into an `R32Uint` texture of global ids
//! (`shaders/relight-pr/triangle_ids.wgsl`), recorded into the frame's encoder, and
//! [`TriangleIdPass::gbuffer`] puts that texture beside the host's albedo, normal and depth.
//!
//! The raster uses the G-buffer pass's conventions (`shaders/gbuffer/mrt.wgsl`): the
//! clip space of [`View::view_projection`] (depth in [0, 1], tested `Less`), pixel
//! centres sampled, no culling. A pixel's id is therefore the triangle nearest the eye
//! through the pixel's centre, what scene-core's ray caster puts there, up to a triangle's
//! edge passing within rounding of a centre. With the host's depth given, a triangle counts
//! only where the host sees a surface at its depth (within 1e-3 of it), so a masked surface
//! the host sees through (alpha-masked leaves: the pass does not read textures) or geometry
//! the host does not draw cannot claim the pixel.

use std::sync::Mutex;

use glam::Vec3;

use scene_core::View;
use scene_core::gpu::{FrameWriter, GpuContext, GpuError, GpuGBuffer, layout, raster, shader};

/// The pass (its vertex and fragment stages in one file).
pub const TRIANGLE_IDS: shader::ShaderPass = shader::ShaderPass::new(
    "relight-pr/triangle_ids",
    scene_core::wgsl_file!("relight-pr", "triangle_ids.wgsl"),
    &[],
);

/// The id a pixel gets where no triangle covers it.
pub const NO_TRIANGLE: u32 = u32::MAX;

struct Targets {
    ids: wgpu::Texture,
    ids_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

/// `Params` in `triangle_ids.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    view_proj: [f32; 16],
    eye: [f32; 3],
    inv_far: f32,
    forward: [f32; 3],
    match_depth: u32,
}

/// Rasterises a fixed list of triangles' global ids for a view (module docs). The triangles
/// are uploaded once by [`TriangleIdPass::new`], which also compiles the pipeline; each
/// [`TriangleIdPass::encode`] records one render pass and writes the view's matrix through
/// the frame's encoder. The id and depth textures are made on the first frame of a size and
/// kept: a steady stream of frames creates no GPU object.
pub struct TriangleIdPass {
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
    corners: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    /// A 1 x 1 depth for frames without the host's.
    no_depth: wgpu::Texture,
    /// The bind group and the depth texture it was made over.
    bind: Mutex<scene_core::gpu::Keyed<wgpu::Texture, wgpu::BindGroup>>,
    vertices: u32,
    writer: FrameWriter,
    targets: Mutex<Option<Targets>>,
    ctx: GpuContext,
}

impl std::fmt::Debug for TriangleIdPass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleIdPass")
            .field("triangles", &self.triangles())
            .finish_non_exhaustive()
    }
}

impl TriangleIdPass {
    /// Format of the id texture.
    pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

    /// Uploads `triangles` (world-space corners; a triangle's id is its index) to `ctx`'s
    /// device and compiles the pipeline. Refused before allocating, with
    /// [`GpuError::Budget`], when the corners exceed the adapter's storage binding limit;
    /// a corner that is not finite is refused by name.
    pub fn new(ctx: &GpuContext, triangles: &[[Vec3; 3]]) -> Result<Self, GpuError> {
        if let Some(t) = triangles
            .iter()
            .position(|t| t.iter().any(|c| !c.is_finite()))
        {
            return Err(GpuError::Validation(format!(
                "triangle {t} of the id pass has a corner that is not finite"
            )));
        }
        let bytes = triangles.len() as u64 * 48;
        let limit = ctx.storage_binding_limit();
        if bytes > limit {
            return Err(GpuError::Budget(scene_core::BudgetExceeded {
                what: format!(
                    "the corners of {} triangles to render ids of",
                    triangles.len()
                ),
                needed: bytes,
                limit,
                unit: "bytes",
                hint: "this adapter's storage binding limit; use fewer triangles".into(),
            }));
        }
        let vertices = u32::try_from(triangles.len() * 3).map_err(|_| {
            GpuError::Validation(format!(
                "{} triangles are too many to draw",
                triangles.len()
            ))
        })?;
        let mut corners: Vec<[f32; 4]> = triangles
            .iter()
            .flat_map(|t| t.map(|c| c.extend(0.0).to_array()))
            .collect();
        if corners.is_empty() {
            corners.push([0.0; 4]); // a binding may not be empty
        }
        let module = TRIANGLE_IDS.create_module(&ctx.device)?;
        ctx.validated(|| {
            let device = &ctx.device;
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("scene-core triangle ids"),
                entries: &[
                    wgpu::BindGroupLayoutEntry {
                        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                        ..layout::uniform(0)
                    },
                    wgpu::BindGroupLayoutEntry {
                        visibility: wgpu::ShaderStages::VERTEX,
                        ..layout::storage_buffer(1)
                    },
                    wgpu::BindGroupLayoutEntry {
                        visibility: wgpu::ShaderStages::FRAGMENT,
                        ..layout::float_texture(2)
                    },
                ],
            });
            let pipeline = raster::depth_tested_pipeline(
                device,
                "scene-core triangle ids",
                &layout,
                &module,
                &[],
                &[Some(Self::FORMAT.into())],
            );
            let params = ctx.frame_buffer(
                "triangle id view",
                std::mem::size_of::<Params>() as u64,
                wgpu::BufferUsages::UNIFORM,
            );
            let corners = ctx.storage_with(
                "triangle id corners",
                bytemuck::cast_slice(&corners),
                wgpu::BufferUsages::empty(),
            );
            let no_depth = ctx.create_texture_2d(
                "triangle id no depth",
                1,
                1,
                GpuGBuffer::DEPTH_FORMAT,
                wgpu::TextureUsages::TEXTURE_BINDING,
            );
            Self {
                pipeline,
                params,
                corners,
                layout,
                no_depth,
                bind: Mutex::new(scene_core::gpu::Keyed::new()),
                vertices,
                writer: FrameWriter::new(device, 256),
                targets: Mutex::new(None),
                ctx: ctx.clone(),
            }
        })
    }

    /// The triangles of `scene` in global triangle-id order (scene-core's, as
    /// `Scene::mesh_offsets` numbers them).
    pub fn for_scene(ctx: &GpuContext, scene: &scene_core::Scene) -> Result<Self, GpuError> {
        Self::new(ctx, &scene.triangle_corners())
    }

    /// Number of triangles.
    pub fn triangles(&self) -> u32 {
        self.vertices / 3
    }

    /// Records the id raster of `view` at `width x height` into `encoder` and returns the
    /// id texture it writes ([`TriangleIdPass::FORMAT`], [`NO_TRIANGLE`] where no triangle
    /// covers a pixel's centre; `TEXTURE_BINDING` usage). With `host_depth` (the frame's
    /// G-buffer's linear depth, [`GpuGBuffer::DEPTH_FORMAT`], of the same size), a triangle
    /// counts only where the host sees a surface at its depth (module docs). The texture is
    /// the same object from frame to frame while the size stays.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        view: &View,
        width: u32,
        height: u32,
        host_depth: Option<&wgpu::Texture>,
    ) -> Result<wgpu::Texture, GpuError> {
        if let Some(d) = host_depth {
            if d.format() != GpuGBuffer::DEPTH_FORMAT {
                return Err(GpuError::WrongFormat {
                    expected: "R32Float (the G-buffer's linear depth)",
                    found: d.format(),
                });
            }
            if (d.width(), d.height()) != (width, height) {
                return Err(GpuError::InvalidSize {
                    width: d.width(),
                    height: d.height(),
                    reason: format!("the host's depth must be the id raster's {width}x{height}"),
                });
            }
        }
        if width == 0 || height == 0 {
            return Err(GpuError::InvalidSize {
                width,
                height,
                reason: "the id raster needs at least one pixel".into(),
            });
        }
        let view_proj = view.view_projection();
        if !view_proj.is_finite() {
            return Err(GpuError::Validation(
                "the view's projection is not finite: no ids can be rasterised for it".into(),
            ));
        }
        let mut targets = self.targets.lock().unwrap_or_else(|e| e.into_inner());
        if targets
            .as_ref()
            .is_none_or(|t| (t.ids.width(), t.ids.height()) != (width, height))
        {
            let make = |label, format, usage| {
                self.ctx
                    .create_texture_2d(label, width, height, format, usage)
            };
            let ids = make(
                "triangle ids",
                Self::FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
            );
            let depth = make(
                "triangle id depth",
                GpuGBuffer::DEPTH_STENCIL_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            );
            *targets = Some(Targets {
                ids_view: ids.create_view(&Default::default()),
                depth_view: depth.create_view(&Default::default()),
                ids,
            });
        }
        let t = targets.as_ref().expect("made above");
        let params = Params {
            view_proj: view_proj.to_cols_array(),
            eye: view.eye.to_array(),
            inv_far: 1.0 / view.far,
            forward: view.forward.to_array(),
            match_depth: u32::from(host_depth.is_some()),
        };
        self.writer
            .write(encoder, &self.params, 0, bytemuck::bytes_of(&params));
        self.writer.finish(encoder);
        let depth = host_depth.unwrap_or(&self.no_depth);
        let mut bound = self.bind.lock().unwrap_or_else(|e| e.into_inner());
        let bind = bound
            .get_or_make(depth.clone(), |depth| {
                let depth_view = depth.create_view(&Default::default());
                self.ctx
                    .device
                    .create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("scene-core triangle ids"),
                        layout: &self.layout,
                        entries: &[
                            wgpu::BindGroupEntry {
                                binding: 0,
                                resource: self.params.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 1,
                                resource: self.corners.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 2,
                                resource: wgpu::BindingResource::TextureView(&depth_view),
                            },
                        ],
                    })
            })
            .clone();
        drop(bound);
        let mut pass = raster::one_target_pass(
            encoder,
            "scene-core triangle ids",
            &t.ids_view,
            f64::from(NO_TRIANGLE),
            &t.depth_view,
        );
        if self.vertices > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..self.vertices, 0..1);
        }
        drop(pass);
        Ok(t.ids.clone())
    }

    /// `g`'s albedo, normal and depth with `ids` (from [`TriangleIdPass::encode`]) as its
    /// triangle ids: no copy, no GPU object (the textures are shared).
    pub fn gbuffer(g: &GpuGBuffer, ids: wgpu::Texture) -> Result<GpuGBuffer, GpuError> {
        if (ids.width(), ids.height()) != (g.width, g.height) {
            return Err(GpuError::InvalidSize {
                width: ids.width(),
                height: ids.height(),
                reason: format!(
                    "the id texture must be the G-buffer's {}x{}",
                    g.width, g.height
                ),
            });
        }
        GpuGBuffer::from_textures(g.albedo.clone(), g.normal.clone(), g.depth.clone(), ids)
    }
}
