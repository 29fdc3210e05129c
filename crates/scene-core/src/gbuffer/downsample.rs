//! Coarse G-buffers: downsampling by 2 in each direction ("4 times smaller buffers",
//! thesis section 4.2), on the CPU ([`downsample`]) and the GPU ([`GpuDownsampler`],
//! shader `shaders/scene-core/downsample.wgsl`, [`DOWNSAMPLE`]), with the same results.
//! The one downsampling of the toolkit: the gbuffer crate re-exports it and ISR's coarse
//! buffers come from it ([`DownsampleMode::NearestSurface`] by default).
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
//! * [`DownsampleMode::NearestSurface`], ISR's default: the nearest geometry sample of the
//!   block represents it, and the geometry samples within [`NEAREST_DEPTH_TOLERANCE`] of its
//!   depth (relative) are averaged. Across a silhouette it keeps the foreground (what the
//!   viewer sees in front is what bounces light to its neighbours); a block with any
//!   geometry is geometry.
//!
//! Normals whose sum cancels (shorter than `1e-6` per sample) take the representative
//! sample's normal, so no coarse normal is ever NaN; background stays zero.
//!
//! The gbuffer crate's `compare_with_direct` measures a coarse buffer against a G-buffer
//! rendered directly at the coarse resolution; `docs/gbuffer.md` has the figures and the
//! recommendation for ISR.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::gbuffer::{BACKGROUND_ID, GBuffer};

/// The downsampling pass (the mode is its overridable constant `MODE`).
#[cfg(feature = "gpu")]
pub const DOWNSAMPLE: crate::gpu::shader::ShaderPass = crate::gpu::shader::ShaderPass::new(
    "scene-core/downsample",
    crate::wgsl_file!("scene-core", "downsample.wgsl"),
    &[crate::gpu::shader::LIMITS],
);

/// Relative depth tolerance of [`DownsampleMode::NearestSurface`]: samples whose linear
/// depth differs from the nearest sample's by more than 5 % of it are another surface.
pub const NEAREST_DEPTH_TOLERANCE: f32 = 0.05;

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
    /// Average the nearest sample's surface only (ISR's default).
    NearestSurface,
}

impl DownsampleMode {
    /// All modes, in shader order.
    pub const ALL: [DownsampleMode; 4] = [
        DownsampleMode::Average,
        DownsampleMode::NearestToMedian,
        DownsampleMode::SurfaceAverage,
        DownsampleMode::NearestSurface,
    ];

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            DownsampleMode::Average => "average (thesis)",
            DownsampleMode::NearestToMedian => "nearest-to-median",
            DownsampleMode::SurfaceAverage => "surface-average",
            DownsampleMode::NearestSurface => "nearest-surface",
        }
    }

    /// The value of the shader's `MODE` constant.
    pub fn shader_code(self) -> u32 {
        match self {
            DownsampleMode::Average => 0,
            DownsampleMode::NearestToMedian => 1,
            DownsampleMode::SurfaceAverage => 2,
            DownsampleMode::NearestSurface => 3,
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
            surface_average(s, rep, |i, q| {
                let same = (q.id == BACKGROUND_ID) == is_bg;
                if is_bg || i == rep {
                    return same;
                }
                same && (q.depth - r.depth).abs() <= SURFACE_DEPTH_TOLERANCE * r.depth
                    && q.normal.dot(r.normal) >= SURFACE_NORMAL_COS
            })
        }
        DownsampleMode::NearestSurface => {
            // The nearest geometry sample (ties: the first in raster order).
            let mut near: Option<usize> = None;
            for (i, q) in s.iter().enumerate() {
                if q.id != BACKGROUND_ID && near.is_none_or(|k| q.depth < s[k].depth) {
                    near = Some(i);
                }
            }
            let Some(k) = near else {
                return Sample {
                    albedo: Vec4::ZERO,
                    normal: Vec3::ZERO,
                    depth: 1.0,
                    id: BACKGROUND_ID,
                };
            };
            let z = s[k].depth;
            surface_average(s, k, |_, q| {
                q.id != BACKGROUND_ID && (q.depth - z).abs() <= NEAREST_DEPTH_TOLERANCE * z
            })
        }
    }
}

/// The average of the samples of `s` that `in_surface(index, sample)` accepts (the
/// representative `rep` among them), with `rep`'s id and, if the normals cancel, its normal.
fn surface_average(
    s: &[Sample],
    rep: usize,
    in_surface: impl Fn(usize, &Sample) -> bool,
) -> Sample {
    let mut a = Vec4::ZERO;
    let mut nsum = Vec3::ZERO;
    let mut dsum = 0.0f32;
    let mut m = 0.0f32;
    for (i, q) in s.iter().enumerate() {
        if in_surface(i, q) {
            a += q.albedo;
            nsum += q.normal;
            dsum += q.depth;
            m += 1.0;
        }
    }
    Sample {
        albedo: a / m,
        normal: renormalise(nsum, m, s[rep].normal),
        depth: dsum / m,
        id: s[rep].id,
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

#[cfg(feature = "gpu")]
pub use gpu_pass::GpuDownsampler;

#[cfg(feature = "gpu")]
mod gpu_pass {
    use std::sync::OnceLock;

    use super::{
        DOWNSAMPLE, DownsampleMode, NEAREST_DEPTH_TOLERANCE, SURFACE_DEPTH_TOLERANCE,
        SURFACE_NORMAL_COS, coarse_size,
    };
    use crate::gpu::layout::{float_texture, storage_texture, texture};
    use crate::gpu::{ComputePass, GpuContext, GpuError, GpuGBuffer};

    /// The GPU downsampling pass (a compute shader from one [`GpuGBuffer`] into another of
    /// [`coarse_size`]; the coarse buffer's depth-stencil attachment is not written). One
    /// pipeline per [`DownsampleMode`], compiled when first used.
    pub struct GpuDownsampler {
        ctx: GpuContext,
        module: wgpu::ShaderModule,
        passes: [OnceLock<ComputePass>; 4],
    }

    impl std::fmt::Debug for GpuDownsampler {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.debug_struct("GpuDownsampler").finish_non_exhaustive()
        }
    }

    impl GpuDownsampler {
        /// Compiles the shader module (pipelines follow per mode).
        pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
            let module = ctx.validated(|| DOWNSAMPLE.create_module(&ctx.device))??;
            Ok(Self {
                ctx: ctx.clone(),
                module,
                passes: Default::default(),
            })
        }

        fn pass(&self, mode: DownsampleMode) -> Result<&ComputePass, GpuError> {
            let slot = &self.passes[mode.shader_code() as usize];
            if let Some(p) = slot.get() {
                return Ok(p);
            }
            let pass = self.ctx.validated(|| {
                ComputePass::from_module(
                    &self.ctx.device,
                    "gbuffer downsample",
                    &self.module,
                    &[
                        float_texture(0),
                        float_texture(1),
                        float_texture(2),
                        texture(3, wgpu::TextureSampleType::Uint),
                        storage_texture(4, GpuGBuffer::ALBEDO_FORMAT),
                        storage_texture(5, GpuGBuffer::NORMAL_FORMAT),
                        storage_texture(6, GpuGBuffer::DEPTH_FORMAT),
                        storage_texture(7, GpuGBuffer::TRIANGLE_ID_FORMAT),
                    ],
                    &[
                        ("MODE", mode.shader_code() as f64),
                        ("SURFACE_DEPTH_TOLERANCE", SURFACE_DEPTH_TOLERANCE as f64),
                        ("SURFACE_NORMAL_COS", SURFACE_NORMAL_COS as f64),
                        ("NEAREST_DEPTH_TOLERANCE", NEAREST_DEPTH_TOLERANCE as f64),
                    ],
                )
            })?;
            Ok(slot.get_or_init(|| pass))
        }

        /// Records the pass from `fine` into `coarse` (which must have [`coarse_size`]),
        /// with optional timestamp writes around it.
        pub fn encode_timed(
            &self,
            encoder: &mut wgpu::CommandEncoder,
            fine: &GpuGBuffer,
            coarse: &GpuGBuffer,
            mode: DownsampleMode,
            timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
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
            let bind_group = self.bind(fine, coarse, mode)?;
            self.encode_bound(encoder, &bind_group, coarse, mode, timestamps)
        }

        /// Compiles every mode's pipeline now (each is otherwise compiled when first used),
        /// so that no frame compiles one.
        pub fn compile_all(&self) -> Result<(), GpuError> {
            for mode in DownsampleMode::ALL {
                self.pass(mode)?;
            }
            Ok(())
        }

        /// The bind group of a pass from `fine` into `coarse` in `mode`, for
        /// [`GpuDownsampler::encode_bound`]: a caller that keeps it records frames without
        /// creating any GPU object.
        pub fn bind(
            &self,
            fine: &GpuGBuffer,
            coarse: &GpuGBuffer,
            mode: DownsampleMode,
        ) -> Result<wgpu::BindGroup, GpuError> {
            let pass = self.pass(mode)?;
            self.ctx.validated(|| {
                pass.bind_buffers_then_textures(
                    &self.ctx.device,
                    &[],
                    &[
                        &fine.albedo,
                        &fine.normal,
                        &fine.depth,
                        &fine.triangle_id,
                        &coarse.albedo,
                        &coarse.normal,
                        &coarse.depth,
                        &coarse.triangle_id,
                    ],
                )
            })
        }

        /// Records the pass with a bind group from [`GpuDownsampler::bind`] (made for the
        /// same `coarse` buffer and `mode`).
        pub fn encode_bound(
            &self,
            encoder: &mut wgpu::CommandEncoder,
            bind_group: &wgpu::BindGroup,
            coarse: &GpuGBuffer,
            mode: DownsampleMode,
            timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
        ) -> Result<(), GpuError> {
            let pass = self.pass(mode)?;
            pass.dispatch(encoder, bind_group, coarse.width, coarse.height, timestamps);
            Ok(())
        }

        /// Records the pass from `fine` into `coarse` (which must have [`coarse_size`]).
        pub fn encode(
            &self,
            encoder: &mut wgpu::CommandEncoder,
            fine: &GpuGBuffer,
            coarse: &GpuGBuffer,
            mode: DownsampleMode,
        ) -> Result<(), GpuError> {
            self.encode_timed(encoder, fine, coarse, mode, None)
        }

        /// Creates the coarse buffer, records and submits the pass (without waiting).
        pub fn run(&self, fine: &GpuGBuffer, mode: DownsampleMode) -> Result<GpuGBuffer, GpuError> {
            let (cw, ch) = coarse_size(fine.width, fine.height);
            let coarse = GpuGBuffer::new(&self.ctx, cw, ch)?;
            let mut encoder =
                self.ctx
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_surface_keeps_the_foreground_and_averages_flat_blocks() {
        let mut g = GBuffer::background(4, 2);
        // Block 0: two foreground (depth 0.2), two background wall (depth 0.8).
        for (i, z) in [(0usize, 0.2f32), (1, 0.8), (4, 0.2), (5, 0.8)] {
            g.depth[i] = z;
            g.normal[i] = Vec3::Z;
            g.albedo[i] = Vec4::new(z, 0.0, 0.0, 1.0);
            g.triangle_id[i] = (z * 10.0) as u32;
        }
        // Block 1: a flat surface with slightly varying depth.
        for (i, z) in [(2usize, 0.5f32), (3, 0.51), (6, 0.5), (7, 0.51)] {
            g.depth[i] = z;
            g.normal[i] = Vec3::Y;
            g.albedo[i] = Vec4::new(0.5, 0.5, 0.5, 1.0);
            g.triangle_id[i] = 7;
        }
        let c = downsample(&g, DownsampleMode::NearestSurface);
        assert_eq!((c.width, c.height), (2, 1));
        assert_eq!(c.depth[0], 0.2);
        assert_eq!(c.albedo[0].x, 0.2);
        assert_eq!(c.triangle_id[0], 2);
        assert!((c.depth[1] - 0.505).abs() < 1e-6);
        assert_eq!(c.triangle_id[1], 7);
        // The thesis' average invents a surface between the two at block 0.
        let avg = downsample(&g, DownsampleMode::Average);
        assert!((avg.depth[0] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn nearest_surface_falls_back_on_cancelled_normals_and_keeps_geometry_over_background() {
        let mut g = GBuffer::background(3, 1);
        for (i, n) in [(0usize, Vec3::X), (1, -Vec3::X)] {
            g.depth[i] = 0.5;
            g.normal[i] = n;
            g.triangle_id[i] = i as u32 + 1;
            g.albedo[i] = Vec4::ONE;
        }
        let c = downsample(&g, DownsampleMode::NearestSurface);
        assert_eq!((c.width, c.height), (2, 1));
        // The normals cancel: the representative's (the first) is kept, never NaN.
        assert_eq!(c.normal[0], Vec3::X);
        assert_eq!(c.triangle_id[0], 1);
        // The odd column: a background-only block stays background.
        assert!(c.is_background(1));
        // One geometry sample among background makes the block geometry.
        let mut h = GBuffer::background(2, 2);
        h.depth[3] = 0.3;
        h.normal[3] = Vec3::Y;
        h.triangle_id[3] = 9;
        let c = downsample(&h, DownsampleMode::NearestSurface);
        assert_eq!((c.triangle_id[0], c.depth[0]), (9, 0.3));
    }
}
