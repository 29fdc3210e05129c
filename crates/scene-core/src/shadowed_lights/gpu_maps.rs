//! Shadow maps rendered on the GPU from the engine's own meshes (issue 30, docs/engine.md):
//! [`ShadowMapPass`] rasterises the shadow casters held in the engine's vertex (and index)
//! buffers into every map of a [`LightSet::planned`] light set, and prefilters them as the
//! CPU does (`shaders/scene-core/shadow_maps.wgsl`), into a storage buffer laid out as
//! [`LightSet::shadow_texels`]. Record it when a light or a caster has moved, never per
//! frame; the methods' GPU passes then take the texels by a buffer copy in the same encoder
//! (`isr::GpuIsr::copy_shadow_texels`, `relight_pr::gpu::GpuRelight::copy_shadow_texels`), or
//! [`ShadowMapPass::read_texels`] hands them to the CPU twins.
//!
//! The raster samples each texel at its centre, as the CPU does (a ray per texel of a cube
//! map, [`super::esm::render_cube`]; a raster of the orthographic ones,
//! [`super::esm::raster_ortho`]), so the two agree texel for
//! texel except where a caster's edge passes within rounding of a texel centre, and to
//! float rounding elsewhere (the GPU's `exp` and `log` in the filter are not correctly
//! rounded).

use std::sync::Mutex;

use glam::{Mat4, Vec3, Vec4};

use super::esm::MapKind;
use super::{LightSet, PlannedMap};
use crate::gpu::{FrameWriter, GpuContext, GpuError};

/// The pass (raster and filter entry points in one file).
pub const SHADOW_MAPS: crate::gpu::shader::ShaderPass = crate::gpu::shader::ShaderPass::new(
    "scene-core/shadow_maps",
    crate::wgsl_file!("scene-core", "shadow_maps.wgsl"),
    &[],
);

/// Where the casters' positions are in the engine's vertex buffer: three `f32` at `offset`
/// bytes into each vertex of `stride` bytes (the vertex layout is part of the pipeline, so
/// it is fixed when the pass is made).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CasterLayout {
    /// Bytes from one vertex to the next.
    pub stride: u64,
    /// Bytes from a vertex's start to its position.
    pub offset: u64,
}

/// The engine's shadow casters for one [`ShadowMapPass::encode`]: its vertex buffer
/// (`VERTEX` usage) in the pass' [`CasterLayout`], and either an index buffer (`INDEX`
/// usage) of `count` indices or `count` vertices drawn in order, as a triangle list.
#[derive(Clone, Copy, Debug)]
pub struct Casters<'a> {
    /// The vertex buffer.
    pub vertices: &'a wgpu::Buffer,
    /// The index buffer and its format, if indexed.
    pub indices: Option<(&'a wgpu::Buffer, wgpu::IndexFormat)>,
    /// Indices (or vertices, without an index buffer) to draw: a multiple of 3.
    pub count: u32,
}

/// Shadow casters held as corner lists (an engine's, or a `Scene`'s
/// [`crate::Scene::triangle_corners`]) uploaded as a vertex buffer of positions in
/// [`CasterVertices::LAYOUT`]: what [`ShadowMapPass`] draws when the host has no vertex
/// buffer of its own to hand over, and the casters' bounds for [`LightSet::planned`].
#[derive(Debug)]
pub struct CasterVertices {
    vertices: wgpu::Buffer,
    count: u32,
    bounds: crate::Bounds,
}

impl CasterVertices {
    /// Three `f32` per vertex, nothing else.
    pub const LAYOUT: CasterLayout = CasterLayout {
        stride: 12,
        offset: 0,
    };

    /// Uploads `triangles` (three vertices each, in order). Refused by name when they are
    /// too many to draw.
    pub fn new(ctx: &GpuContext, triangles: &[[Vec3; 3]]) -> Result<Self, GpuError> {
        let count = u32::try_from(triangles.len() * 3).map_err(|_| {
            GpuError::Validation(format!(
                "{} caster triangles are too many to draw",
                triangles.len()
            ))
        })?;
        let positions: Vec<[f32; 3]> = triangles.iter().flatten().map(|p| p.to_array()).collect();
        let vertices = ctx.validated(|| {
            ctx.buffer_with(
                "shadow casters",
                bytemuck::cast_slice(&positions),
                wgpu::BufferUsages::VERTEX,
            )
        })?;
        Ok(Self {
            vertices,
            count,
            bounds: crate::Bounds::around(triangles.iter().flatten().copied()),
        })
    }

    /// The casters to draw.
    pub fn casters(&self) -> Casters<'_> {
        Casters {
            vertices: &self.vertices,
            indices: None,
            count: self.count,
        }
    }

    /// Their bounds.
    pub fn bounds(&self) -> crate::Bounds {
        self.bounds
    }
}

/// `Face` in `shadow_maps.wgsl` (176 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct FaceRecord {
    view_proj: [f32; 16],
    origin: [f32; 4],
    forward: [f32; 4],
    mode: u32,
    inv_extent: f32,
    miss: f32,
    resolution: u32,
    offset: u32,
    radius: u32,
    esm_exponent: f32,
    pad: u32,
    weights: [[f32; 4]; 3],
}

/// A face's target of one resolution: the distance texture, its depth buffer, and the
/// filter's bind group over them.
struct FaceTarget {
    resolution: u32,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    filter_bind: wgpu::BindGroup,
}

/// Renders a planned light set's shadow maps on the GPU (module docs). Made once per light
/// rig (its maps' placements and resolutions); a light that moves keeps its map's place, so
/// [`ShadowMapPass::encode`] takes the light set each time and rewrites the faces' matrices
/// through the encoder. Nothing is created per call.
pub struct ShadowMapPass {
    raster: wgpu::RenderPipeline,
    filter_h: wgpu::ComputePipeline,
    filter_v: wgpu::ComputePipeline,
    faces: wgpu::Buffer,
    face_stride: u64,
    face_count: usize,
    raster_bind: wgpu::BindGroup,
    targets: Vec<FaceTarget>,
    texels: wgpu::Buffer,
    texel_count: usize,
    plan: Vec<PlannedMap>,
    writer: FrameWriter,
    // The last records written, to skip rewriting an unchanged rig.
    written: Mutex<Option<Vec<u8>>>,
}

impl std::fmt::Debug for ShadowMapPass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShadowMapPass")
            .field("maps", &self.plan.len())
            .field("faces", &self.face_count)
            .field("texels", &self.texel_count)
            .finish_non_exhaustive()
    }
}

/// The six faces' view matrices of a cube map around `center`: rows right, up and -forward
/// of `super::esm`'s face frames, so that texel `(x, y)` of face `f` holds the direction
/// `cube_direction(f, ((x + 1/2) / n, (y + 1/2) / n))`. (Some frames are mirrored; the
/// raster does not cull, so handedness does not matter.)
fn cube_view(face: usize, center: Vec3) -> Mat4 {
    let f = super::esm::cube_direction(face, glam::Vec2::splat(0.5)).normalize();
    let r = super::esm::cube_direction(face, glam::Vec2::new(1.0, 0.5)) - f;
    let u = super::esm::cube_direction(face, glam::Vec2::new(0.5, 0.0)) - f;
    rows_at(r.normalize(), u.normalize(), f, center)
}

/// The world-to-view matrix with rows `r`, `u`, `-f` and the eye at `eye`.
fn rows_at(r: Vec3, u: Vec3, f: Vec3, eye: Vec3) -> Mat4 {
    Mat4::from_cols(
        Vec4::new(r.x, u.x, -f.x, 0.0),
        Vec4::new(r.y, u.y, -f.y, 0.0),
        Vec4::new(r.z, u.z, -f.z, 0.0),
        Vec4::new(-r.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    )
}

impl ShadowMapPass {
    /// Compiles the raster (for casters in `layout`) and the filter, and makes the texel
    /// buffer and one face target per resolution of `set`'s plan (`plan` as
    /// [`LightSet::planned`] returned it). Refused before allocating with
    /// [`GpuError::Budget`] when the texels exceed the adapter's storage binding limit, and
    /// by name on a vertex layout the adapter cannot draw.
    pub fn new(
        ctx: &GpuContext,
        set: &LightSet,
        plan: &[PlannedMap],
        layout: CasterLayout,
    ) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let limits = device.limits();
        if layout.stride < 12
            || layout.offset + 12 > layout.stride
            || layout.stride > u64::from(limits.max_vertex_buffer_array_stride)
            || !layout.stride.is_multiple_of(4)
            || !layout.offset.is_multiple_of(4)
        {
            return Err(GpuError::Validation(format!(
                "caster vertex layout: a position of 12 bytes at offset {} in a stride of {} \
                 (multiples of 4, the stride at most {})",
                layout.offset, layout.stride, limits.max_vertex_buffer_array_stride
            )));
        }
        let texel_count = set.shadow_texels.len();
        let planned: usize = plan.iter().map(|p| p.map.len()).sum();
        if planned != texel_count {
            return Err(GpuError::BadLength {
                what: "the light set's shadow texels (for its plan)",
                expected: planned,
                found: texel_count,
            });
        }
        let limit = ctx.storage_binding_limit();
        if texel_count as u64 * 4 > limit {
            return Err(GpuError::Budget(crate::BudgetExceeded {
                what: format!("{texel_count} shadow-map texels"),
                needed: texel_count as u64 * 4,
                limit,
                unit: "bytes",
                hint: "this adapter's storage binding limit; ShadowSettings::max_texels".into(),
            }));
        }
        let face_count: usize = plan
            .iter()
            .map(|p| match p.map.kind {
                MapKind::Cube { .. } => 6,
                MapKind::Ortho { .. } => 1,
            })
            .sum();
        let align = u64::from(limits.min_uniform_buffer_offset_alignment).max(16);
        let face_stride = (std::mem::size_of::<FaceRecord>() as u64).next_multiple_of(align);
        let mut resolutions: Vec<u32> = plan.iter().map(|p| p.map.resolution).collect();
        resolutions.sort_unstable();
        resolutions.dedup();
        let largest = resolutions.last().copied().unwrap_or(1);
        let module = SHADOW_MAPS.create_module(device)?;
        ctx.validated(|| {
            let face_entry = |visibility| wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(
                        std::mem::size_of::<FaceRecord>() as u64
                    ),
                },
                count: None,
            };
            let raster_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("scene-core shadow maps raster"),
                entries: &[face_entry(
                    wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                )],
            });
            let filter_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("scene-core shadow maps filter"),
                entries: &[
                    face_entry(wgpu::ShaderStages::COMPUTE),
                    crate::gpu::layout::float_texture(1),
                    crate::gpu::layout::storage_buffer_rw(2),
                    crate::gpu::layout::storage_buffer_rw(3),
                ],
            });
            let pipeline_layout = |l: &wgpu::BindGroupLayout| {
                device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("scene-core shadow maps"),
                    bind_group_layouts: &[Some(l)],
                    immediate_size: 0,
                })
            };
            let attributes = [wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x3,
                offset: layout.offset,
                shader_location: 0,
            }];
            let raster = crate::gpu::raster::depth_tested_pipeline(
                device,
                "scene-core shadow maps raster",
                &raster_layout,
                &module,
                &[Some(wgpu::VertexBufferLayout {
                    array_stride: layout.stride,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
                &[Some(wgpu::TextureFormat::R32Float.into())],
            );
            let compute = |entry: &str| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("scene-core shadow maps filter"),
                    layout: Some(&pipeline_layout(&filter_layout)),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            let faces = ctx.frame_buffer(
                "shadow map faces",
                face_stride * face_count.max(1) as u64,
                wgpu::BufferUsages::UNIFORM,
            );
            let face_binding = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &faces,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<FaceRecord>() as u64),
            });
            let texels = ctx.storage_with(
                "shadow map texels",
                bytemuck::cast_slice(&set.shadow_texels),
                wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            );
            let scratch = ctx.frame_buffer(
                "shadow map scratch",
                u64::from(largest) * u64::from(largest) * 4,
                wgpu::BufferUsages::STORAGE,
            );
            let targets = resolutions
                .iter()
                .map(|&resolution| {
                    let make = |label, format, usage| {
                        ctx.create_texture_2d(label, resolution, resolution, format, usage)
                            .create_view(&Default::default())
                    };
                    let color_view = make(
                        "shadow map face",
                        wgpu::TextureFormat::R32Float,
                        wgpu::TextureUsages::RENDER_ATTACHMENT
                            | wgpu::TextureUsages::TEXTURE_BINDING,
                    );
                    let depth_view = make(
                        "shadow map face depth",
                        wgpu::TextureFormat::Depth32Float,
                        wgpu::TextureUsages::RENDER_ATTACHMENT,
                    );
                    let filter_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("scene-core shadow maps filter"),
                        layout: &filter_layout,
                        entries: &[
                            wgpu::BindGroupEntry {
                                binding: 0,
                                resource: face_binding.clone(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 1,
                                resource: wgpu::BindingResource::TextureView(&color_view),
                            },
                            wgpu::BindGroupEntry {
                                binding: 2,
                                resource: scratch.as_entire_binding(),
                            },
                            wgpu::BindGroupEntry {
                                binding: 3,
                                resource: texels.as_entire_binding(),
                            },
                        ],
                    });
                    FaceTarget {
                        resolution,
                        color_view,
                        depth_view,
                        filter_bind,
                    }
                })
                .collect();
            let raster_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("scene-core shadow maps raster"),
                layout: &raster_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: face_binding.clone(),
                }],
            });
            Self {
                raster,
                filter_h: compute("filter_h"),
                filter_v: compute("filter_v"),
                faces,
                face_stride,
                face_count,
                raster_bind,
                targets,
                texels,
                texel_count,
                plan: plan.to_vec(),
                writer: FrameWriter::new(device, 4096),
                written: Mutex::new(None),
            }
        })
    }

    /// The faces' records for `set` (whose maps must be where the plan put them).
    fn records(&self, set: &LightSet) -> Result<Vec<u8>, GpuError> {
        let s = &set.shadows;
        // The prefilter's normalised Gaussian weights for `r` taps a side, packed.
        let weights_of = |r: u32| {
            let sigma = 0.5 * r as f32 + 0.5;
            let mut weights: Vec<f32> = (-(r as i32)..=r as i32)
                .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
                .collect();
            let total: f32 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= total);
            let mut packed = [[0.0f32; 4]; 3];
            for (k, w) in weights.iter().enumerate() {
                packed[k / 4][k % 4] = *w;
            }
            packed
        };
        let mut bytes = vec![0u8; self.face_stride as usize * self.face_count];
        let mut face = 0;
        let mut finite = true;
        for p in &self.plan {
            let Some(map) = set
                .lights
                .get(p.light)
                .and_then(|l| l.shadow)
                .filter(|m| m.offset == p.map.offset && m.resolution == p.map.resolution)
            else {
                return Err(GpuError::Validation(format!(
                    "light #{} has no shadow map where the pass' plan put one (offset {}, \
                     {} texels a side): a light set of another rig",
                    p.light, p.map.offset, p.map.resolution
                )));
            };
            let res = map.resolution;
            let r = s.filter_radius_of(&map.kind);
            let inv_extent = 1.0 / set.extent;
            let base = FaceRecord {
                view_proj: [0.0; 16],
                origin: [0.0; 4],
                forward: [0.0; 4],
                mode: 0,
                inv_extent,
                miss: p.miss,
                resolution: res,
                offset: 0,
                radius: r,
                esm_exponent: s.esm_exponent,
                pad: 0,
                weights: weights_of(r),
            };
            let mut push = |record: FaceRecord| {
                finite &= record.view_proj.iter().all(|v| v.is_finite());
                let at = face * self.face_stride as usize;
                bytes[at..at + std::mem::size_of::<FaceRecord>()]
                    .copy_from_slice(bytemuck::bytes_of(&record));
                face += 1;
            };
            match map.kind {
                MapKind::Cube { center } => {
                    let far = p.miss * set.extent * 1.01;
                    let near = (set.extent * 1e-5).min(0.5 * far);
                    let proj = glam::camera::rh::proj::directx::perspective(
                        std::f32::consts::FRAC_PI_2,
                        1.0,
                        near,
                        far,
                    );
                    for f in 0..6 {
                        push(FaceRecord {
                            view_proj: (proj * cube_view(f, center)).to_cols_array(),
                            origin: center.extend(0.0).to_array(),
                            offset: (map.offset + f * (res as usize).pow(2)) as u32,
                            ..base
                        });
                    }
                }
                MapKind::Ortho {
                    eye,
                    right,
                    up,
                    forward,
                    half_extent: h,
                } => {
                    let proj =
                        glam::camera::rh::proj::directx::orthographic(-h, h, -h, h, 0.0, 4.0 * h);
                    push(FaceRecord {
                        view_proj: (proj * rows_at(right, up, forward, eye)).to_cols_array(),
                        origin: eye.extend(0.0).to_array(),
                        forward: forward.extend(0.0).to_array(),
                        mode: 1,
                        offset: map.offset as u32,
                        ..base
                    });
                }
            }
        }
        if !finite {
            return Err(GpuError::Validation(
                "a shadow map's placement is not finite".into(),
            ));
        }
        Ok(bytes)
    }

    /// Records the rendering and filtering of every map of `set` (the light set of the
    /// pass' rig, its lights where they are now) over `casters` into
    /// [`ShadowMapPass::texels`]. Record it when a light or a caster has moved; the
    /// methods then copy the texels in ([`ShadowMapPass::texels`]).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        set: &LightSet,
        casters: &Casters<'_>,
    ) -> Result<(), GpuError> {
        if !casters.count.is_multiple_of(3) {
            return Err(GpuError::Validation(format!(
                "{} caster indices: a triangle list needs a multiple of 3",
                casters.count
            )));
        }
        if !casters
            .vertices
            .usage()
            .contains(wgpu::BufferUsages::VERTEX)
            || casters
                .indices
                .is_some_and(|(b, _)| !b.usage().contains(wgpu::BufferUsages::INDEX))
        {
            return Err(GpuError::Validation(
                "the casters' vertex buffer needs VERTEX usage and their index buffer INDEX".into(),
            ));
        }
        if self.face_count == 0 {
            return Ok(());
        }
        let bytes = self.records(set)?;
        let mut written = self.written.lock().unwrap_or_else(|e| e.into_inner());
        if written.as_deref() != Some(bytes.as_slice()) {
            self.writer.write(encoder, &self.faces, 0, &bytes);
            self.writer.finish(encoder);
            *written = Some(bytes);
        }
        drop(written);
        let mut face = 0u32;
        for p in &self.plan {
            let res = p.map.resolution;
            let target = self
                .targets
                .iter()
                .find(|t| t.resolution == res)
                .expect("a target per planned resolution");
            let faces = match p.map.kind {
                MapKind::Cube { .. } => 6,
                MapKind::Ortho { .. } => 1,
            };
            for _ in 0..faces {
                let offset = [(u64::from(face) * self.face_stride) as u32];
                {
                    let mut pass = crate::gpu::raster::one_target_pass(
                        encoder,
                        "scene-core shadow map face",
                        &target.color_view,
                        f64::from(p.miss),
                        &target.depth_view,
                    );
                    if casters.count > 0 {
                        pass.set_pipeline(&self.raster);
                        pass.set_bind_group(0, &self.raster_bind, &offset);
                        pass.set_vertex_buffer(0, casters.vertices.slice(..));
                        match casters.indices {
                            Some((indices, format)) => {
                                pass.set_index_buffer(indices.slice(..), format);
                                pass.draw_indexed(0..casters.count, 0, 0..1);
                            }
                            None => pass.draw(0..casters.count, 0..1),
                        }
                    }
                }
                let groups = res.div_ceil(8);
                for pipeline in [&self.filter_h, &self.filter_v] {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("scene-core shadow map filter"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, &target.filter_bind, &offset);
                    pass.dispatch_workgroups(groups, groups, 1);
                }
                face += 1;
            }
        }
        Ok(())
    }

    /// The texels (`STORAGE | COPY_SRC | COPY_DST`), laid out as
    /// [`LightSet::shadow_texels`]: what a method's GPU pass copies in.
    pub fn texels(&self) -> &wgpu::Buffer {
        &self.texels
    }

    /// Number of texels.
    pub fn texel_count(&self) -> usize {
        self.texel_count
    }

    /// Waits for the GPU and returns the texels (after the encoder holding
    /// [`ShadowMapPass::encode`] was submitted): what [`LightSet::shadow_texels`] takes for
    /// the CPU twins.
    pub fn read_texels(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        let mut v: Vec<f32> = ctx.read_buffer_as(&self.texels)?;
        v.truncate(self.texel_count);
        Ok(v)
    }
}
