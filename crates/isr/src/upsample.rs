//! Bilateral upsampling of the blurred coarse buffer to full resolution (section 4.5,
//! eqs. 27-28).
//!
//! For a target pixel `p` and the 2x2 block of coarse samples around it, eq. 27's weights
//! are `w_i' = w_i^b w_i^z` with bilinear `w_i^b` and `w_i^z = 1 / |z_p - z_i|`, normalised by
//! eq. 28. Beyond the thesis:
//! - the singularity at equal depths is guarded: `w_i^z = 1 / max(|z_p - z_i|, eps z_p)` with
//!   `eps` relative to the target's depth ([`crate::IsrSettings::upsample_epsilon`]), so equal
//!   depths give a large finite weight and the guard means the same at any scale;
//! - background coarse samples get weight 0;
//! - an optional normal weight `max(n_p . n_i, 0)^k`;
//! - when all four weights vanish (the case the thesis set aside: background or
//!   opposite-facing samples, zero bilinear weights), the non-background coarse sample of
//!   the surrounding 4x4 block nearest in depth is taken; with none, the pixel gets no
//!   indirect light and no occlusion.

use glam::{Vec2, Vec4};
use rayon::prelude::*;
use scene_core::GBuffer;

use crate::geometry::usable_normal;
use crate::settings::IsrSettings;

/// Below this sum the weights of eq. 28 count as vanished.
pub const VANISHED: f32 = 1e-30;

/// Upsamples `coarse_values` (one per pixel of `coarse`) to the size of `full`.
pub fn upsample(
    full: &GBuffer,
    coarse: &GBuffer,
    coarse_values: &[Vec4],
    settings: &IsrSettings,
) -> Vec<Vec4> {
    let (w, h) = (full.width, full.height);
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| upsample_pixel(full, coarse, coarse_values, settings, x, y))
        })
        .collect()
}

/// No indirect light, no occlusion.
const NOTHING: Vec4 = Vec4::new(0.0, 0.0, 0.0, 1.0);

/// One full-resolution pixel: eq. 27's guarded weights normalised by eq. 28, or the
/// nearest-depth fallback.
fn upsample_pixel(
    full: &GBuffer,
    coarse: &GBuffer,
    values: &[Vec4],
    settings: &IsrSettings,
    x: u32,
    y: u32,
) -> Vec4 {
    let (w, h) = (full.width, full.height);
    let (cw, ch) = (coarse.width, coarse.height);
    let i = (y * w + x) as usize;
    if full.is_background(i) {
        return NOTHING;
    }
    let zp = full.depth[i];
    let np = usable_normal(full.normal[i], glam::Vec3::ZERO);
    // Position in the coarse grid (texel centres at integers).
    let c = Vec2::new(
        (x as f32 + 0.5) * cw as f32 / w as f32 - 0.5,
        (y as f32 + 0.5) * ch as f32 / h as f32 - 0.5,
    );
    let i0 = c.floor();
    let f = c - i0;
    let (ix, iy) = (i0.x as i32, i0.y as i32);
    let at = |dx: i32, dy: i32| {
        let cx = (ix + dx).clamp(0, cw as i32 - 1) as u32;
        let cy = (iy + dy).clamp(0, ch as i32 - 1) as u32;
        (cy * cw + cx) as usize
    };
    let bilinear = [
        (1.0 - f.x) * (1.0 - f.y),
        f.x * (1.0 - f.y),
        (1.0 - f.x) * f.y,
        f.x * f.y,
    ];
    let guard = settings.upsample_epsilon * zp;
    let mut sum = Vec4::ZERO;
    let mut total = 0.0f32;
    for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
        let j = at(dx, dy);
        if coarse.is_background(j) {
            continue;
        }
        // Eq. 27 with the guarded depth weight.
        let mut wt = bilinear[k] / (zp - coarse.depth[j]).abs().max(guard);
        if settings.upsample_normal_power > 0.0 {
            let nc = usable_normal(coarse.normal[j], glam::Vec3::ZERO);
            if np != glam::Vec3::ZERO && nc != glam::Vec3::ZERO {
                wt *= np.dot(nc).max(0.0).powf(settings.upsample_normal_power);
            }
        }
        sum += values[j] * wt;
        total += wt;
    }
    if total > VANISHED && total.is_finite() {
        // Eq. 28.
        return sum / total;
    }
    // Fallback: nearest depth in the surrounding 4x4 block.
    let mut best: Option<(f32, usize)> = None;
    for dy in -1..=2 {
        for dx in -1..=2 {
            let j = at(dx, dy);
            if coarse.is_background(j) {
                continue;
            }
            let d = (zp - coarse.depth[j]).abs();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, j));
            }
        }
    }
    best.map_or(NOTHING, |(_, j)| values[j])
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn flat(w: u32, h: u32, z: f32) -> GBuffer {
        let mut g = GBuffer::background(w, h);
        for i in 0..g.len() {
            g.depth[i] = z;
            g.normal[i] = Vec3::Z;
            g.triangle_id[i] = 0;
            g.albedo[i] = Vec4::ONE;
        }
        g
    }

    #[test]
    fn equal_depths_give_bilinear_interpolation() {
        let full = flat(4, 4, 0.5);
        let coarse = flat(2, 2, 0.5);
        let values = vec![Vec4::ZERO, Vec4::ONE, Vec4::ZERO, Vec4::ONE];
        let out = upsample(&full, &coarse, &values, &IsrSettings::default());
        assert!(out.iter().all(|v| v.is_finite()));
        // Column 1 (coarse x = 0.25): bilinear 0.25.
        assert!((out[1].x - 0.25).abs() < 1e-6, "{}", out[1]);
        assert!((out[0].x - 0.0).abs() < 1e-6);
        assert!((out[3].x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn vanished_weights_fall_back_to_the_nearest_depth() {
        let mut full = flat(2, 2, 0.5);
        full.normal = vec![Vec3::Z; 4];
        let mut coarse = flat(1, 1, 0.5);
        coarse.normal[0] = -Vec3::Z;
        let values = vec![Vec4::new(0.3, 0.2, 0.1, 0.7)];
        let settings = IsrSettings {
            upsample_normal_power: 4.0,
            ..Default::default()
        };
        let out = upsample(&full, &coarse, &values, &settings);
        assert!(out.iter().all(|v| *v == values[0]), "{out:?}");
        // All coarse samples background: nothing.
        let bg = GBuffer::background(1, 1);
        let out = upsample(&full, &bg, &values, &settings);
        assert!(out.iter().all(|v| *v == NOTHING));
    }
}
