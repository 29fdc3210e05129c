//! Depth-aware 2x2 downsampling of a G-buffer into the coarse buffers of the ISR pass
//! (section 4.2: `CLR_4, NRM_4, DPT_4`).
//!
//! The thesis averages the four samples. Averaging across a silhouette invents a surface
//! floating between foreground and background (its depth, normal and colour belong to
//! neither), which the ISR pass then lights and the bilateral upsampling cannot match. Here
//! each coarse pixel takes the nearest non-background sample as its representative and
//! averages only the samples within [`DEPTH_TOLERANCE`] of its depth: inside a surface this is
//! the thesis' average, across a silhouette it keeps the foreground. Normals are averaged
//! and renormalised; if they cancel (a crease seen edge-on), the representative's normal is
//! kept. A block with no geometry is background.
//!
//! The `Technique` implementations use this rather than a second, half-resolution render:
//! it costs one pass instead of a scene traversal, and every coarse sample is one of the
//! full-resolution surfaces, which is what the bilateral upsampling matches against.

use glam::{Vec3, Vec4};
use rayon::prelude::*;
use scene_core::{BACKGROUND_ID, GBuffer};

use crate::geometry::MIN_NORMAL_LEN2;

/// Samples whose linear depth differs from the representative's by more than this fraction
/// of it are left out of the average.
pub const DEPTH_TOLERANCE: f32 = 0.05;

/// The coarse size for a full-resolution size: half, rounded up (so a 1x1 image stays 1x1).
pub fn coarse_size(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(2), height.div_ceil(2))
}

/// Downsamples `full` by two in each direction (see the module documentation).
pub fn downsample(full: &GBuffer) -> GBuffer {
    let (w, h) = (full.width as usize, full.height as usize);
    let (cw, ch) = coarse_size(full.width, full.height);
    let texels: Vec<(Vec4, Vec3, f32, u32)> = (0..ch as usize)
        .into_par_iter()
        .flat_map_iter(|cy| {
            (0..cw as usize).map(move |cx| {
                let mut idx = [0usize; 4];
                let mut n = 0;
                for dy in 0..2 {
                    for dx in 0..2 {
                        let (x, y) = (2 * cx + dx, 2 * cy + dy);
                        if x < w && y < h {
                            let i = y * w + x;
                            if !full.is_background(i) {
                                idx[n] = i;
                                n += 1;
                            }
                        }
                    }
                }
                block(full, &idx[..n])
            })
        })
        .collect();
    let mut out = GBuffer::background(cw, ch);
    for (i, (a, nrm, z, id)) in texels.into_iter().enumerate() {
        out.albedo[i] = a;
        out.normal[i] = nrm;
        out.depth[i] = z;
        out.triangle_id[i] = id;
    }
    out
}

/// One coarse texel (section 4.2's `DownsampleBuffer`) from the non-background samples
/// `idx` of its block.
fn block(full: &GBuffer, idx: &[usize]) -> (Vec4, Vec3, f32, u32) {
    let Some(&first) = idx.first() else {
        return (Vec4::ZERO, Vec3::ZERO, 1.0, BACKGROUND_ID);
    };
    // The nearest sample (ties: the first in row-major order).
    let mut rep = first;
    for &i in idx {
        if full.depth[i] < full.depth[rep] {
            rep = i;
        }
    }
    let z0 = full.depth[rep];
    let (mut a, mut nrm, mut z, mut count) = (Vec4::ZERO, Vec3::ZERO, 0.0f32, 0.0f32);
    for &i in idx {
        if (full.depth[i] - z0).abs() <= DEPTH_TOLERANCE * z0 {
            a += full.albedo[i];
            nrm += full.normal[i];
            z += full.depth[i];
            count += 1.0;
        }
    }
    let l2 = nrm.length_squared();
    let nrm = if l2 > MIN_NORMAL_LEN2 * count * count {
        nrm / l2.sqrt()
    } else {
        full.normal[rep]
    };
    (a / count, nrm, z / count, full.triangle_id[rep])
}

/// WGSL source of the GPU pass (`shaders/isr/standalone/downsample.wgsl`).
pub const WGSL: &str = include_str!("../../../shaders/isr/standalone/downsample.wgsl");

/// The GPU pass: reads a full [`scene_core::gpu::GpuGBuffer`], writes the colour textures of
/// a coarse one.
pub(crate) struct GpuPass {
    pub pipeline: crate::gpu::Pipeline,
}

impl GpuPass {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        use crate::gpu::{storage_texture_entry, texture_entry};
        use scene_core::gpu::GpuGBuffer;
        Self {
            pipeline: crate::gpu::Pipeline::new(
                device,
                "isr downsample",
                WGSL,
                &[
                    texture_entry(0, false),
                    texture_entry(1, false),
                    texture_entry(2, false),
                    texture_entry(3, true),
                    storage_texture_entry(4, GpuGBuffer::ALBEDO_FORMAT),
                    storage_texture_entry(5, GpuGBuffer::NORMAL_FORMAT),
                    storage_texture_entry(6, GpuGBuffer::DEPTH_FORMAT),
                    storage_texture_entry(7, GpuGBuffer::TRIANGLE_ID_FORMAT),
                ],
            ),
        }
    }

    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        full: &scene_core::gpu::GpuGBuffer,
        coarse: &scene_core::gpu::GpuGBuffer,
    ) -> wgpu::BindGroup {
        self.pipeline.bind_buffers_then_textures(
            device,
            &[],
            &[
                &full.albedo,
                &full.normal,
                &full.depth,
                &full.triangle_id,
                &coarse.albedo,
                &coarse.normal,
                &coarse.depth,
                &coarse.triangle_id,
            ],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gbuffer(w: u32, h: u32) -> GBuffer {
        GBuffer::background(w, h)
    }

    #[test]
    fn silhouettes_keep_the_foreground_and_flat_blocks_average() {
        let mut g = gbuffer(4, 2);
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
        let c = downsample(&g);
        assert_eq!((c.width, c.height), (2, 1));
        assert_eq!(c.depth[0], 0.2);
        assert_eq!(c.albedo[0].x, 0.2);
        assert!((c.depth[1] - 0.505).abs() < 1e-6);
        assert_eq!(c.triangle_id[1], 7);
    }

    #[test]
    fn cancelled_normals_fall_back_and_odd_sizes_work() {
        let mut g = gbuffer(3, 1);
        g.depth[0] = 0.5;
        g.depth[1] = 0.5;
        g.normal[0] = Vec3::X;
        g.normal[1] = -Vec3::X;
        g.triangle_id[0] = 1;
        g.triangle_id[1] = 2;
        g.albedo[0] = Vec4::ONE;
        g.albedo[1] = Vec4::ONE;
        let c = downsample(&g);
        assert_eq!((c.width, c.height), (2, 1));
        assert_eq!(c.normal[0], Vec3::X);
        assert!(c.is_background(1));
        let one = downsample(&gbuffer(1, 1));
        assert_eq!((one.width, one.height), (1, 1));
        assert!(one.is_background(0));
    }
}
