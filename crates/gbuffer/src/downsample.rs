//! Coarse G-buffers: downsampling by 2 in each direction ("4 times smaller buffers",
//! thesis section 4.2), on the CPU ([`downsample`]) and the GPU ([`GpuDownsampler`],
//! shader `shaders/gbuffer/downsample.wgsl`, [`DOWNSAMPLE_WGSL`]), with the same results.
//!
//! Coarse pixel `(X, Y)` covers the fine block `(2X..2X+1, 2Y..2Y+1)`; for odd sizes the
//! coarse buffer is `ceil(w/2) x ceil(h/2)` and the last row or column of blocks has fewer
//! samples. Samples are visited in raster order. Three [`DownsampleMode`]s:
//!
//! * [`DownsampleMode::Average`], the thesis' choice: every channel averaged, normals
//!   renormalised. Across a silhouette it averages the depths of a near and a far surface
//!   (or of a surface and the background at depth 1) and so *invents* a surface that
//!   exists nowhere, with a normal that belongs to neither side.
//! * [`DownsampleMode::NearestToMedian`], a depth-aware choice: all channels of the one
//!   sample at the lower median of the block's depths. Every coarse pixel is a real
//!   surface sample; edges alias like a point-sampled half-resolution render.
//! * [`DownsampleMode::SurfaceAverage`]: the median sample's surface, averaged: samples
//!   that share its background status, lie within [`SURFACE_DEPTH_TOLERANCE`] of its depth
//!   (relative) and whose normals are within `acos(`[`SURFACE_NORMAL_COS`]`)` of its
//!   normal. Smooth inside surfaces, no averaging across silhouettes or creases.
//!
//! Normals whose sum cancels (shorter than `1e-6` per sample) take the representative
//! sample's normal, so no coarse normal is ever NaN; background stays zero.
//!
//! [`compare_with_direct`] measures a coarse buffer against a G-buffer rendered directly
//! at the coarse resolution; `docs/gbuffer.md` has the figures and the recommendation for
//! ISR.

use std::borrow::Cow;

use bytemuck::{Pod, Zeroable};
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use scene_core::gpu::{GpuContext, GpuError, GpuGBuffer};
use scene_core::{BACKGROUND_ID, GBuffer};
use wgpu::util::DeviceExt;

/// WGSL source of the downsampling pass.
pub const DOWNSAMPLE_WGSL: &str = include_str!("../../../shaders/gbuffer/downsample.wgsl");

/// Relative depth tolerance of [`DownsampleMode::SurfaceAverage`]: samples whose linear
/// depth differs from the representative's by more than 2 % of it are another surface.
pub const SURFACE_DEPTH_TOLERANCE: f32 = 0.02;
/// Minimum normal cosine of [`DownsampleMode::SurfaceAverage`] (about 25 degrees): a crease
/// sharper than that separates surfaces.
pub const SURFACE_NORMAL_COS: f32 = 0.9;
/// Normal sums shorter than this times the sample count count as cancelled.
const CANCEL: f32 = 1e-6;

/// How a 2x2 block becomes one coarse pixel (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DownsampleMode {
    /// The thesis: average every channel (invents surfaces at silhouettes).
    Average,
    /// Copy the sample at the lower median depth (invents nothing).
    NearestToMedian,
    /// Average the median sample's surface only.
    SurfaceAverage,
}

impl DownsampleMode {
    /// All modes, in shader order.
    pub const ALL: [DownsampleMode; 3] = [
        DownsampleMode::Average,
        DownsampleMode::NearestToMedian,
        DownsampleMode::SurfaceAverage,
    ];

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            DownsampleMode::Average => "average (thesis)",
            DownsampleMode::NearestToMedian => "nearest-to-median",
            DownsampleMode::SurfaceAverage => "surface-average",
        }
    }

    fn shader_code(self) -> u32 {
        match self {
            DownsampleMode::Average => 0,
            DownsampleMode::NearestToMedian => 1,
            DownsampleMode::SurfaceAverage => 2,
        }
    }
}

/// Size of the coarse buffer of a `width x height` one: `ceil(w/2) x ceil(h/2)`.
pub fn coarse_size(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(2), height.div_ceil(2))
}

#[derive(Clone, Copy)]
struct Sample {
    albedo: Vec4,
    normal: Vec3,
    depth: f32,
    id: u32,
}

fn renormalise(sum: Vec3, count: f32, fallback: Vec3) -> Vec3 {
    let len = sum.dot(sum).sqrt();
    if len <= CANCEL * count {
        fallback
    } else {
        sum * (1.0 / len)
    }
}

/// One coarse pixel from its 1, 2 or 4 samples (raster order).
fn reduce(s: &[Sample], mode: DownsampleMode) -> Sample {
    let n = s.len();
    let count = n as f32;
    let want = (n - 1) / 2;
    let mut rep = 0;
    for i in 0..n {
        let before = (0..n)
            .filter(|&j| s[j].depth < s[i].depth || (s[j].depth == s[i].depth && j < i))
            .count();
        if before == want {
            rep = i;
        }
    }
    match mode {
        DownsampleMode::NearestToMedian => s[rep],
        DownsampleMode::Average => {
            let mut a = Vec4::ZERO;
            let mut nsum = Vec3::ZERO;
            let mut dsum = 0.0f32;
            for q in s {
                a += q.albedo;
                nsum += q.normal;
                dsum += q.depth;
            }
            let depth = dsum / count;
            let mut best = 0;
            for i in 1..n {
                if (s[i].depth - depth).abs() < (s[best].depth - depth).abs() {
                    best = i;
                }
            }
            Sample {
                albedo: a / count,
                normal: renormalise(nsum, count, s[best].normal),
                depth,
                id: s[best].id,
            }
        }
        DownsampleMode::SurfaceAverage => {
            let r = s[rep];
            let is_bg = r.id == BACKGROUND_ID;
            let mut a = Vec4::ZERO;
            let mut nsum = Vec3::ZERO;
            let mut dsum = 0.0f32;
            let mut m = 0.0f32;
            for (i, q) in s.iter().enumerate() {
                let mut same = (q.id == BACKGROUND_ID) == is_bg;
                if !is_bg && i != rep {
                    same = same
                        && (q.depth - r.depth).abs() <= SURFACE_DEPTH_TOLERANCE * r.depth
                        && q.normal.dot(r.normal) >= SURFACE_NORMAL_COS;
                }
                if same {
                    a += q.albedo;
                    nsum += q.normal;
                    dsum += q.depth;
                    m += 1.0;
                }
            }
            Sample {
                albedo: a / m,
                normal: renormalise(nsum, m, r.normal),
                depth: dsum / m,
                id: r.id,
            }
        }
    }
}

/// Downsamples `fine` by 2 in each direction on the CPU (rayon over coarse rows). A 1x1
/// buffer stays 1x1; an empty one stays empty.
pub fn downsample(fine: &GBuffer, mode: DownsampleMode) -> GBuffer {
    let (cw, ch) = coarse_size(fine.width, fine.height);
    let mut out = GBuffer::background(cw, ch);
    if out.is_empty() {
        return out;
    }
    let (fw, fh) = (fine.width as usize, fine.height as usize);
    let cw_us = cw as usize;
    out.albedo
        .par_chunks_mut(cw_us)
        .zip(out.normal.par_chunks_mut(cw_us))
        .zip(out.depth.par_chunks_mut(cw_us))
        .zip(out.triangle_id.par_chunks_mut(cw_us))
        .enumerate()
        .for_each(|(y, (((albedo, normal), depth), ids))| {
            let mut samples = Vec::with_capacity(4);
            for x in 0..cw_us {
                samples.clear();
                for dy in 0..2 {
                    for dx in 0..2 {
                        let (fx, fy) = (2 * x + dx, 2 * y + dy);
                        if fx < fw && fy < fh {
                            let i = fy * fw + fx;
                            samples.push(Sample {
                                albedo: fine.albedo[i],
                                normal: fine.normal[i],
                                depth: fine.depth[i],
                                id: fine.triangle_id[i],
                            });
                        }
                    }
                }
                let s = reduce(&samples, mode);
                albedo[x] = s.albedo;
                normal[x] = s.normal;
                depth[x] = s.depth;
                ids[x] = s.id;
            }
        });
    out
}

/// The uniform of `downsample.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Params {
    mode: u32,
    depth_tolerance: f32,
    normal_cos: f32,
    pad: u32,
}

/// Workgroup edge of the downsampling shader.
const WORKGROUP: u32 = 8;

/// The GPU downsampling pass (a compute shader from one [`GpuGBuffer`] into another of
/// [`coarse_size`]; the coarse buffer's depth-stencil attachment is not written).
#[derive(Debug)]
pub struct GpuDownsampler {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl GpuDownsampler {
    /// Compiles the pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let (layout, pipeline) = ctx.validated(|| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("downsample.wgsl"),
                source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(DOWNSAMPLE_WGSL)),
            });
            use scene_core::gpu::layout::{float_texture, storage_texture, texture, uniform};
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("gbuffer downsample"),
                entries: &[
                    float_texture(0),
                    float_texture(1),
                    float_texture(2),
                    texture(3, wgpu::TextureSampleType::Uint),
                    storage_texture(4, GpuGBuffer::ALBEDO_FORMAT),
                    storage_texture(5, GpuGBuffer::NORMAL_FORMAT),
                    storage_texture(6, GpuGBuffer::DEPTH_FORMAT),
                    storage_texture(7, GpuGBuffer::TRIANGLE_ID_FORMAT),
                    uniform(8),
                ],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("gbuffer downsample"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("gbuffer downsample"),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
            (layout, pipeline)
        })?;
        Ok(Self {
            ctx: ctx.clone(),
            layout,
            pipeline,
        })
    }

    /// Records the pass from `fine` into `coarse` (which must have [`coarse_size`]).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        fine: &GpuGBuffer,
        coarse: &GpuGBuffer,
        mode: DownsampleMode,
    ) -> Result<(), GpuError> {
        let (cw, ch) = coarse_size(fine.width, fine.height);
        if (coarse.width, coarse.height) != (cw, ch) {
            return Err(GpuError::InvalidSize {
                width: coarse.width,
                height: coarse.height,
                reason: format!(
                    "the coarse buffer of a {}x{} G-buffer is {cw}x{ch}",
                    fine.width, fine.height
                ),
            });
        }
        let device = &self.ctx.device;
        self.ctx.validated(|| {
            let params = Params {
                mode: mode.shader_code(),
                depth_tolerance: SURFACE_DEPTH_TOLERANCE,
                normal_cos: SURFACE_NORMAL_COS,
                pad: 0,
            };
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("downsample params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let textures = [
                &fine.albedo,
                &fine.normal,
                &fine.depth,
                &fine.triangle_id,
                &coarse.albedo,
                &coarse.normal,
                &coarse.depth,
                &coarse.triangle_id,
            ];
            let views = textures.map(|t| t.create_view(&Default::default()));
            let mut entries: Vec<wgpu::BindGroupEntry<'_>> = views
                .iter()
                .enumerate()
                .map(|(i, v)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: wgpu::BindingResource::TextureView(v),
                })
                .collect();
            entries.push(wgpu::BindGroupEntry {
                binding: 8,
                resource: uniform.as_entire_binding(),
            });
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("gbuffer downsample"),
                layout: &self.layout,
                entries: &entries,
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("gbuffer downsample"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(cw.div_ceil(WORKGROUP), ch.div_ceil(WORKGROUP), 1);
        })
    }

    /// Creates the coarse buffer, records and submits the pass (without waiting).
    pub fn run(&self, fine: &GpuGBuffer, mode: DownsampleMode) -> Result<GpuGBuffer, GpuError> {
        let (cw, ch) = coarse_size(fine.width, fine.height);
        let coarse = GpuGBuffer::new(&self.ctx, cw, ch)?;
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gbuffer downsample"),
            });
        self.encode(&mut encoder, fine, &coarse, mode)?;
        self.ctx
            .validated(|| self.ctx.queue.submit([encoder.finish()]))?;
        Ok(coarse)
    }
}

/// How a coarse buffer compares with its fine source and with a G-buffer rendered
/// directly at the coarse resolution (same view).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DownsampleStats {
    /// Coarse pixels.
    pub pixels: usize,
    /// Coarse geometry pixels whose depth is farther than [`INVENTED_DEPTH_TOLERANCE`]
    /// (relative) from the depth of every sample of their fine block: surfaces that exist
    /// nowhere in the fine G-buffer.
    pub invented_depth: usize,
    /// Coarse geometry pixels whose normal is more than [`INVENTED_NORMAL_DEGREES`] away
    /// from the normal of every geometry sample of their block.
    pub invented_normal: usize,
    /// Pixels where the coarse buffer and the direct render disagree on background.
    pub background_mismatch: usize,
    /// Pixels that are geometry in both the coarse buffer and the direct render (the
    /// denominator of the means below).
    pub geometry_pixels: usize,
    /// Pixels, geometry in both, whose depths differ by more than
    /// [`INVENTED_DEPTH_TOLERANCE`] (relative).
    pub depth_mismatch: usize,
    /// Pixels, geometry in both, whose triangle ids differ.
    pub id_mismatch: usize,
    /// Mean angle in degrees between coarse and direct normals, geometry in both.
    pub mean_normal_error_deg: f64,
    /// Mean absolute albedo difference (RGB average), geometry in both.
    pub mean_albedo_error: f64,
}

/// Relative depth difference beyond which a coarse depth is "another surface" (5 %).
pub const INVENTED_DEPTH_TOLERANCE: f32 = 0.05;
/// Normal angle beyond which a coarse normal is "invented" (30 degrees).
pub const INVENTED_NORMAL_DEGREES: f32 = 30.0;

/// Measures `coarse` (a downsampling of `fine`) against `direct` (a G-buffer of the same
/// view rendered at the coarse size; its pixel centres are the centres of the fine
/// blocks). Panics if the sizes do not fit together.
pub fn compare_with_direct(coarse: &GBuffer, direct: &GBuffer, fine: &GBuffer) -> DownsampleStats {
    assert_eq!(
        (coarse.width, coarse.height),
        (direct.width, direct.height),
        "coarse and direct sizes differ"
    );
    assert_eq!(
        (coarse.width, coarse.height),
        coarse_size(fine.width, fine.height),
        "coarse is not the downsampling size of fine"
    );
    let cos_tol = INVENTED_NORMAL_DEGREES.to_radians().cos();
    let (cw, fw, fh) = (
        coarse.width as usize,
        fine.width as usize,
        fine.height as usize,
    );
    let mut s = DownsampleStats {
        pixels: coarse.len(),
        ..Default::default()
    };
    let (mut nsum, mut asum, mut both) = (0.0f64, 0.0f64, 0usize);
    for i in 0..coarse.len() {
        let (x, y) = (i % cw, i / cw);
        let c_bg = coarse.is_background(i);
        let d_bg = direct.is_background(i);
        if !c_bg {
            let block: Vec<usize> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                .iter()
                .map(|&(dx, dy)| (2 * x + dx, 2 * y + dy))
                .filter(|&(fx, fy)| fx < fw && fy < fh)
                .map(|(fx, fy)| fy * fw + fx)
                .collect();
            let d = coarse.depth[i];
            if block
                .iter()
                .all(|&j| (d - fine.depth[j]).abs() > INVENTED_DEPTH_TOLERANCE * fine.depth[j])
            {
                s.invented_depth += 1;
            }
            let n = coarse.normal[i];
            if block
                .iter()
                .filter(|&&j| !fine.is_background(j))
                .all(|&j| n.dot(fine.normal[j]) < cos_tol)
            {
                s.invented_normal += 1;
            }
        }
        if c_bg != d_bg {
            s.background_mismatch += 1;
            continue;
        }
        if c_bg {
            continue;
        }
        both += 1;
        let (dc, dd) = (coarse.depth[i], direct.depth[i]);
        if (dc - dd).abs() > INVENTED_DEPTH_TOLERANCE * dd {
            s.depth_mismatch += 1;
        }
        if coarse.triangle_id[i] != direct.triangle_id[i] {
            s.id_mismatch += 1;
        }
        let cos = coarse.normal[i].dot(direct.normal[i]).clamp(-1.0, 1.0);
        nsum += (cos as f64).acos().to_degrees();
        asum += ((coarse.albedo[i] - direct.albedo[i]).truncate().abs())
            .to_array()
            .iter()
            .map(|&v| v as f64)
            .sum::<f64>()
            / 3.0;
    }
    s.geometry_pixels = both;
    if both > 0 {
        s.mean_normal_error_deg = nsum / both as f64;
        s.mean_albedo_error = asum / both as f64;
    }
    s
}
