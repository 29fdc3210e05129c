//! The lighting phase (section 4.5, eq. 29, listing 7) with exponential shadow maps (section
//! 4.6, eq. 30, listing 8).
//!
//! Per pixel: the direct light `C_0 / pi * sum_l E_l V_l` from point lights (inverse square or
//! eq. 16), directional lights and the emitter samples, each shadowed by its ESM with PCF
//! ([`crate::shadow`]); then eq. 29,
//! `L = C_0 k_dl E / pi * saturate(L_SSAO + 1 - k_SSAO) + k_ISR L_ISR`, or, with
//! [`crate::IsrSettings::ao_indirect_only`], the AO factor on the indirect term instead;
//! plus the emission of directly visible emitters (front side only).
//!
//! The same pass, run on the coarse buffer in [`Mode::Senders`], gives the direct radiance
//! `C_0 / pi * E` each coarse pixel reflects: the senders of [`crate::Sender::Lit`].

use std::f32::consts::FRAC_1_PI;

use glam::{Vec3, Vec4};
use rayon::prelude::*;
use scene_core::{GBuffer, Image};

use crate::geometry::{Screen, normal_or_viewer, pixel_uv, usable_normal};
use crate::light_set::{LightSet, Part};
use crate::settings::IsrSettings;

/// What the lighting pass computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Direct radiance `C_0 / pi * E` only (no emission, no `k_dl`): the `Lit` senders.
    Senders,
    /// The final composition of eq. 29.
    Compose,
}

/// The direct radiance each pixel of `g` reflects (the coarse senders), each light scaled
/// by its indirect factor ([`Part::Indirect`]): the bounce it feeds is its indirect light.
pub fn senders(scene: &LightSet, screen: &Screen, g: &GBuffer) -> Vec<Vec3> {
    let (w, h) = (g.width, g.height);
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let i = (y * w + x) as usize;
                if g.is_background(i) {
                    return Vec3::ZERO;
                }
                let uv = pixel_uv(x, y, w, h);
                let p = screen.world(uv, g.depth[i]);
                let n = normal_or_viewer(g.normal[i], screen, uv);
                g.albedo[i].truncate() * FRAC_1_PI * scene.irradiance(p, n, Part::Indirect)
            })
        })
        .collect()
}

/// Eq. 29 over the full-resolution buffer `g`. `isr` is the upsampled ISR/SSAO buffer
/// (indirect `rgb`, accessibility `a`), `None` for direct light only.
pub fn compose(
    scene: &LightSet,
    screen: &Screen,
    g: &GBuffer,
    isr: Option<&[Vec4]>,
    settings: &IsrSettings,
) -> Image {
    let (w, h) = (g.width, g.height);
    let pixels = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let i = (y * w + x) as usize;
                if g.is_background(i) {
                    return Vec3::ZERO;
                }
                let uv = pixel_uv(x, y, w, h);
                let p = screen.world(uv, g.depth[i]);
                let to_viewer = screen.to_viewer(uv);
                let n = usable_normal(g.normal[i], to_viewer);
                let c0 = g.albedo[i].truncate();
                let direct = c0 * FRAC_1_PI * scene.irradiance(p, n, Part::Direct) * settings.k_dl;
                let emission = scene.emitters.emission(g.triangle_id[i], to_viewer);
                let v = isr.map_or(Vec4::new(0.0, 0.0, 0.0, 1.0), |b| b[i]);
                let ao = if settings.ssao {
                    (v.w + 1.0 - settings.k_ssao).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                let indirect = if settings.indirect {
                    v.truncate() * settings.k_isr
                } else {
                    Vec3::ZERO
                };
                let out = if settings.ao_indirect_only {
                    emission + direct + indirect * ao
                } else {
                    emission + direct * ao + indirect
                };
                if out.is_finite() { out } else { Vec3::ZERO }
            })
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels,
    }
}
