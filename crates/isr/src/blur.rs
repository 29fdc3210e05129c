//! Separable blur of the coarse ISR/SSAO buffer (section 4.2, listing 3: `BlurHorizontal`,
//! `BlurVertical`), Gaussian as in the thesis or edge-aware.
//!
//! Both variants leave background pixels (the stencil mask) out: they are neither blurred
//! nor blurred into their neighbours (their black indirect light would darken silhouettes).
//! The edge-aware variant also weights each tap by `exp(-(d / (EDGE_PLANE_SIGMA s))^2)`,
//! where `d` is the tap's distance from the centre pixel's tangent plane and `s` the centre's
//! view depth, and by `max(n_c . n_t, 0)^2`, so light does not bleed across depth
//! discontinuities or creases. The centre tap always has weight 1.

use glam::Vec4;
use rayon::prelude::*;
use scene_core::GBuffer;

use crate::geometry::{Screen, normal_or_viewer, pixel_uv};
use crate::settings::{Blur, IsrSettings};

/// Tangent-plane distance, relative to the view depth, at which an edge-aware tap's weight
/// falls to `1/e`.
pub const EDGE_PLANE_SIGMA: f32 = 0.05;

/// The normalised Gaussian weights `w[k]` for taps `k = 0..=radius` (symmetric).
pub fn gaussian_weights(radius: u32, sigma: f32) -> Vec<f32> {
    (0..=radius)
        .map(|k| (-((k * k) as f32) / (2.0 * sigma * sigma)).exp())
        .collect()
}

/// Blurs `input` (one value per coarse pixel) horizontally then vertically.
pub fn blur(
    screen: &Screen,
    coarse: &GBuffer,
    input: &[Vec4],
    settings: &IsrSettings,
) -> Vec<Vec4> {
    if settings.blur_radius == 0 {
        return input.to_vec();
    }
    let tmp = blur_pass(screen, coarse, input, settings, true);
    blur_pass(screen, coarse, &tmp, settings, false)
}

/// One direction of the separable blur.
pub fn blur_pass(
    screen: &Screen,
    g: &GBuffer,
    input: &[Vec4],
    settings: &IsrSettings,
    horizontal: bool,
) -> Vec<Vec4> {
    let weights = gaussian_weights(settings.blur_radius, settings.blur_sigma);
    let (w, h) = (g.width, g.height);
    let edge = settings.blur == Blur::EdgeAware;
    let r = settings.blur_radius as i32;
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let weights = &weights;
            (0..w).map(move |x| {
                let i = (y * w + x) as usize;
                if g.is_background(i) {
                    return input[i];
                }
                let uv = pixel_uv(x, y, w, h);
                let (pc, nc, scale) = if edge {
                    (
                        screen.world(uv, g.depth[i]),
                        normal_or_viewer(g.normal[i], screen, uv),
                        screen.scale(g.depth[i]) * EDGE_PLANE_SIGMA,
                    )
                } else {
                    (glam::Vec3::ZERO, glam::Vec3::ZERO, 1.0)
                };
                let mut sum = Vec4::ZERO;
                let mut total = 0.0f32;
                for k in -r..=r {
                    let (tx, ty) = if horizontal {
                        (x as i32 + k, y as i32)
                    } else {
                        (x as i32, y as i32 + k)
                    };
                    if tx < 0 || ty < 0 || tx >= w as i32 || ty >= h as i32 {
                        continue;
                    }
                    let t = (ty as u32 * w + tx as u32) as usize;
                    if g.is_background(t) {
                        continue;
                    }
                    let mut wt = weights[k.unsigned_abs() as usize];
                    if edge && k != 0 {
                        let uvt = pixel_uv(tx as u32, ty as u32, w, h);
                        let pt = screen.world(uvt, g.depth[t]);
                        let nt = normal_or_viewer(g.normal[t], screen, uvt);
                        let d = nc.dot(pt - pc) / scale.max(f32::MIN_POSITIVE);
                        let cn = nc.dot(nt).max(0.0);
                        wt *= (-(d * d)).exp() * cn * cn;
                    }
                    sum += input[t] * wt;
                    total += wt;
                }
                if total > 0.0 { sum / total } else { input[i] }
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn constant_input_is_unchanged_and_background_does_not_bleed() {
        let mut g = GBuffer::background(8, 1);
        for i in 0..4 {
            g.depth[i] = 0.5;
            g.normal[i] = Vec3::Z;
            g.triangle_id[i] = 0;
        }
        let view = scene_core::View::orthographic_fit(Vec3::ZERO, Vec3::NEG_Z, 1.0);
        let s = Screen::new(&view);
        let input: Vec<Vec4> = (0..8)
            .map(|i| {
                if i < 4 {
                    Vec4::new(1.0, 2.0, 3.0, 0.5)
                } else {
                    Vec4::new(0.0, 0.0, 0.0, 1.0)
                }
            })
            .collect();
        for blur in [Blur::Gaussian, Blur::EdgeAware] {
            let settings = IsrSettings {
                blur,
                ..Default::default()
            };
            let out = super::blur(&s, &g, &input, &settings);
            for i in 0..4 {
                assert!(
                    (out[i] - input[i]).abs().max_element() < 1e-6,
                    "{blur:?} {i}"
                );
            }
        }
    }

    #[test]
    fn edge_aware_blur_keeps_a_depth_step() {
        let mut g = GBuffer::background(8, 1);
        for i in 0..8 {
            g.depth[i] = if i < 4 { 0.2 } else { 0.8 };
            g.normal[i] = Vec3::Z;
            g.triangle_id[i] = 0;
        }
        let view = scene_core::View {
            eye: Vec3::ZERO,
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: scene_core::Projection::Perspective {
                left: -1.0,
                right: 1.0,
                bottom: -0.1,
                top: 0.1,
            },
            near: 0.1,
            far: 10.0,
        };
        let s = Screen::new(&view);
        let input: Vec<Vec4> = (0..8)
            .map(|i| if i < 4 { Vec4::ONE } else { Vec4::ZERO })
            .collect();
        let gauss = super::blur(&s, &g, &input, &IsrSettings::default());
        let edge = super::blur(
            &s,
            &g,
            &input,
            &IsrSettings {
                blur: Blur::EdgeAware,
                ..Default::default()
            },
        );
        assert!(gauss[3].x < 0.9, "the Gaussian bleeds: {}", gauss[3]);
        assert!(
            edge[3].x > 0.999 && edge[4].x < 1e-3,
            "{} {}",
            edge[3],
            edge[4]
        );
    }
}
