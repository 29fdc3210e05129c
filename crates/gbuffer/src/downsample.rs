//! Coarse G-buffers: scene-core's 2x downsampling on the CPU and the GPU
//! (`scene_core::gbuffer::downsample`, which ISR and this crate share), re-exported, and
//! what only this crate's measurements use: [`compare_with_direct`], a coarse buffer
//! measured against its fine source and a G-buffer rendered directly at the coarse size
//! (`cargo xtask bench gbuffer`; in scene-core until 2026-11-27).

pub use scene_core::gbuffer::downsample::*;

use scene_core::GBuffer;

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
