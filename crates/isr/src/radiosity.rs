//! The ISR + SSAO pass on the coarse buffers (section 4.4, listing 6): per pixel, `N`
//! neighbourhood samples, each neighbour a small patch in world space (figure 4.4), give
//! one-bounce indirect light (eq. 25) and ambient occlusion (eq. 26). Output per coarse
//! pixel: indirect radiance in `rgb`, accessibility (1 = unoccluded) in `a`.
//!
//! **Sample pattern.** The `N` samples lie on a Vogel (golden-angle) spiral filling the unit
//! disk evenly, `r_k = sqrt((k + 1/2) / N)`, `phi_k = k * 137.5 degrees`, scaled to the
//! screen-space disk that the world-space radius `R` subtends at the pixel's depth, and
//! rotated per pixel by one of 16 angles arranged in a 4x4 Bayer matrix; the blur then
//! averages the 16 rotations. The same samples serve both terms (listing 6 reads separate
//! ones; sharing halves the reads). A sample landing outside the image, on the background
//! or on the pixel itself contributes nothing but still counts in `N`.
//!
//! **Reading of the thesis' equations** (the extraction loses the Greek letters; `pi` and
//! `rho` are restored from the thesis' symbol font):
//! - eq. 6: `dF = cos(theta_i) cos(theta_j) dA_j / (pi r^2)`;
//! - eq. 25: `L_P(X) = rho_P (2 pi / N) F_PX L_X`. The text says `rho_P` is "sampled from the
//!   alpha channel of CLR_4", which holds the radiation mask (section 4.2). Taken literally,
//!   the indirect light would not be coloured by the receiver at all, since eq. 29 adds
//!   `L_ISR` without multiplying by `C_0`. The physically sound reading used here is
//!   `rho_P = albedo_P * mask_P` (the receiver's RGB albedo, zero where the mask is off);
//!   `tests::indirect_light_takes_the_receivers_colour` checks it.
//! - eq. 26: `SSAO_P(X) = (2 pi / N) (1 - sqrt(1 - (r / |PX|)^2)) max(n . PX / |PX|, 0)`, the
//!   spherical-cap occlusion of eq. 14 per sample. `SSAO` is the occlusion; eq. 29's
//!   `saturate(L_SSAO + 1 - k_SSAO)` only makes sense (occluded pixels darker, at most by
//!   `k_SSAO`) if `L_SSAO` is the accessibility `1 - occlusion`, which is what this pass
//!   stores. The occluder radius `r` is that of a sphere with the patch's area.
//!
//! See [`crate::Estimator`] for the two estimators; in `Patch` mode the AO of one sample is
//! `2 h cos(theta_P)` with `h` the cap fraction of eq. 14 and the sphere's cross-section the
//! patch's projected area `A_X |cos(theta_X)|`: for small occluders this is the patch's form
//! factor, so the occlusion is a projected-solid-angle fraction, and `h <= 1` keeps it bounded
//! when the occluder touches P.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use scene_core::GBuffer;

use crate::geometry::{Screen, normal_or_viewer, pixel_uv};
use crate::settings::{Estimator, IsrSettings, Sender};

/// The 4x4 Bayer matrix ordering the 16 per-pixel rotations.
pub(crate) const BAYER4: [u32; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];

/// The sample pattern: `N` offsets in the unit disk and 16 rotations `(cos, sin)`.
#[derive(Clone, Debug, PartialEq)]
pub struct SamplePattern {
    /// Offsets in the unit disk (Vogel spiral).
    pub offsets: Vec<Vec2>,
    /// Rotation of pixel `(x, y)` is `rotations[(y % 4) * 4 + x % 4]`, as `(cos, sin)`.
    pub rotations: [Vec2; 16],
}

impl SamplePattern {
    /// The pattern for `n` samples.
    pub fn new(n: u32) -> Self {
        let golden = PI * (3.0 - 5f32.sqrt());
        let offsets = (0..n)
            .map(|k| {
                let r = ((k as f32 + 0.5) / n as f32).sqrt();
                let phi = k as f32 * golden;
                Vec2::new(r * phi.cos(), r * phi.sin())
            })
            .collect();
        let mut rotations = [Vec2::ZERO; 16];
        for (i, b) in BAYER4.iter().enumerate() {
            let a = TAU * (*b as f32 + 0.5) / 16.0;
            rotations[i] = Vec2::new(a.cos(), a.sin());
        }
        Self { offsets, rotations }
    }

    /// The GPU layout: 16 rotations, then the offsets, each a `vec4<f32>` (`xy` used).
    pub fn to_gpu(&self) -> Vec<[f32; 4]> {
        self.rotations
            .iter()
            .chain(&self.offsets)
            .map(|v| [v.x, v.y, 0.0, 0.0])
            .collect()
    }
}

/// Runs the ISR + SSAO pass (eqs. 25 and 26, listing 6) over the coarse buffer `coarse` seen through `screen`. `senders`
/// holds each coarse pixel's direct radiance for [`Sender::Lit`] (ignored for
/// [`Sender::Albedo`]); `radius` is in world units.
pub fn radiosity(
    screen: &Screen,
    coarse: &GBuffer,
    senders: Option<&[Vec3]>,
    settings: &IsrSettings,
    radius: f32,
) -> Vec<Vec4> {
    let pattern = SamplePattern::new(settings.samples);
    let (w, h) = (coarse.width, coarse.height);
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let pattern = &pattern;
            (0..w).map(move |x| gather(screen, coarse, senders, settings, radius, pattern, x, y))
        })
        .collect()
}

/// A coarse pixel as a receiver of the pass: its surface and the screen-space disk its
/// samples fall in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Receiver {
    /// World position.
    pub p: Vec3,
    /// Unit normal (towards the viewer where the G-buffer has none).
    pub n: Vec3,
    /// Reflectance: albedo times the radiation mask.
    pub rho: Vec3,
    /// The disk's radius on the image plane (tangent units or metres, as `Screen::span_u`).
    pub rp: f32,
    /// The disk's radii in pixels.
    pub radius_px: Vec2,
    /// The pixel's centre in pixels.
    pub centre: Vec2,
}

impl Receiver {
    /// Coarse pixel `(x, y)` of `g` with a world-space sample radius `radius`; `None` on
    /// the background or without a usable depth.
    pub(crate) fn at(screen: &Screen, g: &GBuffer, radius: f32, x: u32, y: u32) -> Option<Self> {
        let (w, h) = (g.width, g.height);
        let i = (y * w + x) as usize;
        if g.is_background(i) {
            return None;
        }
        let uv = pixel_uv(x, y, w, h);
        let z0 = g.depth[i];
        if z0.is_nan() || z0 <= 0.0 {
            return None;
        }
        // A disk wider than twice the image reaches every pixel from anywhere: clamp there.
        let rp = screen
            .plane_radius(z0, radius)
            .min(2.0 * screen.span_u.max(screen.span_v));
        Some(Self {
            p: screen.world(uv, z0),
            n: normal_or_viewer(g.normal[i], screen, uv),
            rho: g.albedo[i].truncate() * g.albedo[i].w,
            rp,
            radius_px: Vec2::new(rp / screen.span_u * w as f32, rp / screen.span_v * h as f32),
            centre: Vec2::new(x as f32 + 0.5, y as f32 + 0.5),
        })
    }

    /// Whether the screen-space samples can land on pixel `(sx, sy)`: its centre lies in
    /// the disk.
    pub(crate) fn disk_holds(&self, sx: u32, sy: u32) -> bool {
        let d = (Vec2::new(sx as f32 + 0.5, sy as f32 + 0.5) - self.centre) / self.radius_px;
        d.length_squared() <= 1.0
    }
}

/// One coarse pixel of the pass: eq. 25 (indirect light, with eq. 6's form factor or the
/// disk form factor) and eq. 26 (spherical-occluder AO, eq. 14 per sample) over the
/// pattern's samples.
#[allow(clippy::too_many_arguments)]
fn gather(
    screen: &Screen,
    g: &GBuffer,
    senders: Option<&[Vec3]>,
    settings: &IsrSettings,
    radius: f32,
    pattern: &SamplePattern,
    x: u32,
    y: u32,
) -> Vec4 {
    let (w, h) = (g.width, g.height);
    let i = (y * w + x) as usize;
    let Some(Receiver {
        p: p0,
        n: n0,
        rho,
        rp,
        radius_px,
        centre,
    }) = Receiver::at(screen, g, radius, x, y)
    else {
        return Vec4::new(0.0, 0.0, 0.0, 1.0);
    };
    let n = settings.samples as f32;
    let disk_share = PI * rp * rp / n;
    let rot = pattern.rotations[((y % 4) * 4 + x % 4) as usize];
    let thesis = settings.estimator == Estimator::Thesis;
    let mut gi = Vec3::ZERO;
    let mut occlusion = 0.0f32;
    for o in &pattern.offsets {
        let r = Vec2::new(o.x * rot.x - o.y * rot.y, o.x * rot.y + o.y * rot.x);
        let s = (centre + r * radius_px).floor();
        // Written to reject NaN too.
        if !(s.x >= 0.0 && s.y >= 0.0 && s.x < w as f32 && s.y < h as f32) {
            continue;
        }
        let (sx, sy) = (s.x as u32, s.y as u32);
        let k = (sy * w + sx) as usize;
        if k == i || g.is_background(k) {
            continue;
        }
        let uvk = pixel_uv(sx, sy, w, h);
        let zk = g.depth[k];
        if zk.is_nan() || zk <= 0.0 {
            continue;
        }
        let xk = screen.world(uvk, zk);
        let nk = normal_or_viewer(g.normal[k], screen, uvk);
        let d = xk - p0;
        let r2 = d.length_squared();
        if !(r2 > 0.0 && r2.is_finite()) {
            continue;
        }
        let dir = d / r2.sqrt();
        let cos_p = n0.dot(dir);
        if cos_p <= 0.0 {
            continue;
        }
        let cos_x = -nk.dot(dir);
        let area = if thesis {
            screen.pixel_area(zk, w, h)
        } else {
            screen.footprint(uvk, zk, nk, disk_share)
        };
        if settings.indirect && cos_x > 0.0 {
            let l = match (settings.sender, senders) {
                (Sender::Lit, Some(s)) => s[k],
                (Sender::Lit, None) => Vec3::ZERO,
                (Sender::Albedo, _) => g.albedo[k].truncate(),
            };
            // Eq. 6 (thesis, r^2 >= A) or the disk form factor (patch); both include 1/pi.
            let f = if thesis {
                cos_p * cos_x * area / (PI * r2.max(area))
            } else {
                cos_p * cos_x * area / (PI * r2 + area)
            };
            gi += l * f;
        }
        if settings.ssao {
            // Eq. 26: the occluder is a sphere of the patch's (projected) area.
            let sphere = if thesis {
                area / PI
            } else {
                area * cos_x.abs() / PI
            };
            let cap = 1.0 - (1.0 - (sphere / r2).min(1.0)).sqrt();
            occlusion += cap * cos_p;
        }
    }
    let (gi, occlusion) = if thesis {
        // Eq. 25's and eq. 26's 2 pi / N.
        (gi * (TAU / n), occlusion * (TAU / n))
    } else {
        (gi, 2.0 * occlusion)
    };
    let gi = if settings.indirect {
        rho * gi
    } else {
        Vec3::ZERO
    };
    let access = if settings.ssao {
        (1.0 - occlusion).clamp(0.0, 1.0)
    } else {
        1.0
    };
    gi.extend(access)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene_core::View;

    /// A camera at the origin looking down -Z, 90 degree fov, far 10.
    fn view() -> View {
        View {
            eye: Vec3::ZERO,
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: scene_core::Projection::Perspective {
                left: -1.0,
                right: 1.0,
                bottom: -1.0,
                top: 1.0,
            },
            near: 0.01,
            far: 10.0,
        }
    }

    /// A floor (y = -1) and a back wall (z = -3) seen by [`view`], `n x n` pixels, with
    /// albedos `floor` and `wall`.
    pub(crate) fn corner(n: u32, floor: Vec3, wall: Vec3) -> GBuffer {
        let v = view();
        let mut g = GBuffer::background(n, n);
        for y in 0..n {
            for x in 0..n {
                let uv = pixel_uv(x, y, n, n);
                let (o, d) = v.ray(uv);
                let t_wall = (-3.0 - o.z) / d.z;
                let t_floor = if d.y < 0.0 {
                    (-1.0 - o.y) / d.y
                } else {
                    f32::INFINITY
                };
                let (t, nrm, a, id) = if t_floor < t_wall {
                    (t_floor, Vec3::Y, floor, 0)
                } else {
                    (t_wall, Vec3::Z, wall, 1)
                };
                let p = o + d * t;
                let i = (y * n + x) as usize;
                g.depth[i] = v.linear_depth(p);
                g.normal[i] = nrm;
                g.albedo[i] = a.extend(1.0);
                g.triangle_id[i] = id;
            }
        }
        g
    }

    #[test]
    fn indirect_light_takes_the_receivers_colour() {
        let g = corner(32, Vec3::new(0.8, 0.1, 0.1), Vec3::ONE * 0.9);
        let s = Screen::new(&view());
        for estimator in [Estimator::Thesis, Estimator::Patch] {
            let settings = IsrSettings {
                estimator,
                sender: Sender::Albedo,
                samples: 48,
                ssao: true,
                ..Default::default()
            };
            let out = radiosity(&s, &g, None, &settings, 2.0);
            // A floor pixel near the wall: red, lit by the white wall.
            let i = (30 * 32 + 16) as usize;
            assert_eq!(g.triangle_id[i], 0);
            let c = out[i];
            assert!(c.x > 0.0 && c.x > 4.0 * c.y, "{estimator:?}: {c}");
            assert!(c.w < 1.0 && c.w >= 0.0, "{estimator:?}: AO {}", c.w);
            assert!(out.iter().all(|v| v.is_finite()));
        }
    }

    /// The form factor from a differential element at `p` with unit normal `n` to a planar
    /// polygon (no occlusion), by Lambert's contour formula:
    /// `F = 1/(2 pi) |sum_i angle(r_i, r_i+1) n . unit(r_i x r_i+1)|`, `r_i = v_i - p`.
    fn polygon_form_factor(p: Vec3, n: Vec3, polygon: &[Vec3]) -> f64 {
        let mut sum = 0.0f64;
        for (i, a) in polygon.iter().enumerate() {
            let b = polygon[(i + 1) % polygon.len()];
            let (ra, rb) = ((*a - p).as_dvec3(), (b - p).as_dvec3());
            let angle = ra.normalize().dot(rb.normalize()).clamp(-1.0, 1.0).acos();
            sum += angle * n.as_dvec3().dot(ra.cross(rb).normalize());
        }
        sum.abs() / std::f64::consts::TAU
    }

    /// A floor (y = -1, id 0) and a 1 m square patch of wall (z = -3, x in [-1/2, 1/2],
    /// y in [-1, 0], standing on the floor, id 1) seen by [`view`]; elsewhere background.
    fn floor_and_patch(n: u32) -> GBuffer {
        let v = view();
        let mut g = GBuffer::background(n, n);
        for y in 0..n {
            for x in 0..n {
                let (o, d) = v.ray(pixel_uv(x, y, n, n));
                let t_patch = (-3.0 - o.z) / d.z;
                let q = o + d * t_patch;
                let on_patch = q.x.abs() <= 0.5 && (-1.0..=0.0).contains(&q.y);
                let t_floor = if d.y < 0.0 {
                    (-1.0 - o.y) / d.y
                } else {
                    f32::INFINITY
                };
                let hit = match (on_patch, t_floor.is_finite()) {
                    (true, _) if t_patch <= t_floor => Some((t_patch, Vec3::Z, 1)),
                    (_, true) => Some((t_floor, Vec3::Y, 0)),
                    _ => None,
                };
                if let Some((t, nrm, id)) = hit {
                    let i = (y * n + x) as usize;
                    g.depth[i] = v.linear_depth(o + d * t);
                    g.normal[i] = nrm;
                    g.albedo[i] = Vec4::new(0.5, 0.5, 0.5, 1.0);
                    g.triangle_id[i] = id;
                }
            }
        }
        g
    }

    #[test]
    fn patch_estimator_converges_to_the_analytic_form_factor_of_a_wall_patch() {
        // Floor points (normal +Y) 0.75 to 1.25 m in front of a 1 m square patch standing
        // on the floor. The sample disk (1.5 m, 0.6 to 0.75 of the image plane's half-span
        // at these depths) holds the patch's whole image; every other sender is floor
        // (coplanar, cos 0) or background, so the estimator integrates over the patch
        // alone and must converge to its form factor, given exactly by Lambert's contour
        // formula. Unit lit senders and albedo 1/2: the output is F / 2.
        let n = 128u32;
        let g = floor_and_patch(n);
        let s = Screen::new(&view());
        let settings = IsrSettings {
            estimator: Estimator::Patch,
            sender: Sender::Lit,
            samples: 256,
            ssao: false,
            ..Default::default()
        };
        let senders = vec![Vec3::ONE; g.len()];
        let out = radiosity(&s, &g, Some(&senders), &settings, 1.5);
        let patch = [
            Vec3::new(-0.5, -1.0, -3.0),
            Vec3::new(0.5, -1.0, -3.0),
            Vec3::new(0.5, 0.0, -3.0),
            Vec3::new(-0.5, 0.0, -3.0),
        ];
        let mut errors = Vec::new();
        let mut exact_sum = 0.0;
        for y in 0..n {
            for x in 0..n {
                let i = (y * n + x) as usize;
                let p = s.world(pixel_uv(x, y, n, n), g.depth[i]);
                if g.triangle_id[i] != 0 || !(-2.25..=-1.75).contains(&p.z) || p.x.abs() > 0.25 {
                    continue;
                }
                let exact = polygon_form_factor(p, Vec3::Y, &patch);
                errors.push(f64::from(out[i].x) / 0.5 - exact);
                exact_sum += exact;
            }
        }
        let count = errors.len() as f64;
        assert!(count >= 100.0, "{count} pixels");
        let exact_mean = exact_sum / count;
        let bias = errors.iter().sum::<f64>() / count;
        let spread = (errors.iter().map(|e| (e - bias).powi(2)).sum::<f64>() / count).sqrt();
        // Each pixel's 256-sample estimate scatters (spread) around the exact value; the
        // mean over the pixels must lie within 4 standard errors, plus 3 % of the value for
        // the estimator's bias (each sample's footprint A in pi r^2 + A: about 0.03 m^2
        // against pi r^2 of 2 to 5 m^2 here, under 2 %).
        let allowed = 4.0 * spread / count.sqrt() + 0.03 * exact_mean;
        assert!(
            bias.abs() < allowed,
            "mean estimate off the exact {exact_mean:.4} by {bias:+.4} (allowed {allowed:.4}, \
             per-pixel spread {spread:.4} over {count} pixels)"
        );
        eprintln!("exact {exact_mean:.4}, bias {bias:+.5}, spread {spread:.4}, {count} pixels");
    }
}
