//! Exponential shadow maps with PCF (section 4.6, eq. 30, listing 8).
//!
//! The maps do not depend on the camera, so [`super::LightSet::new`] builds them once per
//! scene, on the CPU, by casting one ray per texel through the scene's BVH (the depth a
//! rasteriser would store at the texel centre): an orthographic map for each directional
//! light and a six-face cube map for each point light and each emitter sample. Depths are
//! stored in units of the scene's extent, so the ESM exponent means the same at every scale.
//! There is no GPU pass for building them: the GPU lighting pass reads the same texels from
//! a storage buffer, so both paths see identical maps.
//!
//! **Log-space filtering.** ESM prefilters `exp(c o)` linearly; stored as is, `exp(c o)`
//! overflows f32 once `c o > 88.7` (the thesis' `c = 90` with a depth near 1 already does).
//! The maps here keep the filtered value in log space,
//! `o_f = o_max + ln(sum_i w_i exp(c (o_i - o_max))) / c`, whose exponentials have
//! non-positive arguments, and the lookup evaluates eq. 30 as
//! `exp(-c max(r - o_f, 0))`, again of a non-positive argument: no finite `c` overflows.
//!
//! **Lookup (listing 8).** The receiver is moved along its normal by `normal_offset`
//! texels (the world size of a texel where it lies), projected into the map, and eq. 30 is
//! evaluated at the four nearest texels and blended bilinearly (PCF).

use crate::ray::RayScene;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::ShadowSettings;

/// The kind and placement of one shadow map inside [`super::LightSet::shadow_texels`].
///
/// Besides [`MapKind`], the map keeps its frame in plain fields that are always written
/// (zero where a kind has no use for them), and [`visibility`] reads only those: reading a
/// cube map's centre out of the enum let the compiler load 16 bytes, the last 4 of them the
/// enum's unwritten padding, whose garbage sometimes squared to a subnormal float and cost
/// a microcode assist per shaded light (measured: twice the CPU lighting time).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct ShadowMap {
    origin: Vec3,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    half_extent: f32,
    /// Index of the first texel.
    pub offset: usize,
    /// Texels per side (of each face for cube maps).
    pub resolution: u32,
    /// The projection.
    pub kind: MapKind,
}

/// How a shadow map projects the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MapKind {
    /// Six faces around a point (see [`cube_face`]); texels hold the distance from the point
    /// to the nearest surface, in scene extents.
    Cube {
        /// The centre of projection.
        center: Vec3,
    },
    /// A square orthographic view along `forward`; texels hold the distance from the
    /// view's plane through `eye` to the nearest surface, in scene extents.
    Ortho {
        /// A point on the view plane (its centre).
        eye: Vec3,
        /// Unit right vector of the map.
        right: Vec3,
        /// Unit up vector of the map.
        up: Vec3,
        /// Unit direction of the light.
        forward: Vec3,
        /// Half the width of the map, in metres.
        half_extent: f32,
    },
}

impl ShadowMap {
    /// A map of `kind` with `resolution` texels per side starting at texel `offset`.
    pub fn new(offset: usize, resolution: u32, kind: MapKind) -> Self {
        let (origin, right, up, forward, half_extent) = match kind {
            MapKind::Cube { center } => (center, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0.0),
            MapKind::Ortho {
                eye,
                right,
                up,
                forward,
                half_extent,
            } => (eye, right, up, forward, half_extent),
        };
        Self {
            origin,
            right,
            up,
            forward,
            half_extent,
            offset,
            resolution,
            kind,
        }
    }

    /// The map's frame: the cube's centre or the orthographic view's eye, then the
    /// orthographic right, up and forward vectors and half width (zero for cube maps).
    pub fn frame(&self) -> (Vec3, Vec3, Vec3, Vec3, f32) {
        (
            self.origin,
            self.right,
            self.up,
            self.forward,
            self.half_extent,
        )
    }

    /// Number of texels.
    pub fn len(&self) -> usize {
        let face = self.resolution as usize * self.resolution as usize;
        match self.kind {
            MapKind::Cube { .. } => 6 * face,
            MapKind::Ortho { .. } => face,
        }
    }

    /// True for a zero-size map (never built).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Frames `(forward, right, up)` of the six cube faces: +X, -X, +Y, -Y, +Z, -Z.
const FACES: [[Vec3; 3]; 6] = [
    [Vec3::X, Vec3::NEG_Z, Vec3::Y],
    [Vec3::NEG_X, Vec3::Z, Vec3::Y],
    [Vec3::Y, Vec3::X, Vec3::NEG_Z],
    [Vec3::NEG_Y, Vec3::X, Vec3::Z],
    [Vec3::Z, Vec3::X, Vec3::Y],
    [Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y],
];

/// The face of a cube map that direction `d` (non-zero) falls on and its image coordinates
/// in [0, 1]² (major axis; ties go to X, then Y).
pub fn cube_face(d: Vec3) -> (usize, Vec2) {
    let a = d.abs();
    let face = if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 { 0 } else { 1 }
    } else if a.y >= a.z {
        if d.y >= 0.0 { 2 } else { 3 }
    } else if d.z >= 0.0 {
        4
    } else {
        5
    };
    let [f, r, u] = FACES[face];
    let m = d.dot(f).max(f32::MIN_POSITIVE);
    let uv = Vec2::new(0.5 * (d.dot(r) / m + 1.0), 0.5 * (1.0 - d.dot(u) / m));
    (face, uv)
}

/// The (unnormalised) direction through image coordinates `uv` of cube face `face`.
pub fn cube_direction(face: usize, uv: Vec2) -> Vec3 {
    let [f, r, u] = FACES[face];
    f + r * (2.0 * uv.x - 1.0) + u * (1.0 - 2.0 * uv.y)
}

/// Renders a cube map around `center`: per texel the distance to the nearest surface in
/// units of `extent`, `miss` where nothing is hit.
pub fn render_cube(rays: &RayScene, center: Vec3, res: u32, extent: f32, miss: f32) -> Vec<f32> {
    let n = res as usize;
    (0..6 * n)
        .into_par_iter()
        .flat_map_iter(|row| {
            let face = row / n;
            let y = row % n;
            (0..n).map(move |x| {
                let uv = Vec2::new((x as f32 + 0.5) / res as f32, (y as f32 + 0.5) / res as f32);
                let d = cube_direction(face, uv).normalize();
                match rays.closest_hit(center, d, 0.0, f32::INFINITY) {
                    Some(h) => (h.t / extent).min(miss),
                    None => miss,
                }
            })
        })
        .collect()
}

/// Renders an orthographic map: per texel the distance from the map plane through `eye` to
/// the nearest surface along `forward`, in units of `extent`.
pub fn render_ortho(rays: &RayScene, kind: &MapKind, res: u32, extent: f32) -> Vec<f32> {
    let MapKind::Ortho {
        eye,
        right,
        up,
        forward,
        half_extent,
    } = *kind
    else {
        return Vec::new();
    };
    let miss = 4.0 * half_extent / extent;
    let n = res as usize;
    (0..n)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..n).map(move |x| {
                let sx = half_extent * (2.0 * (x as f32 + 0.5) / res as f32 - 1.0);
                let sy = half_extent * (1.0 - 2.0 * (y as f32 + 0.5) / res as f32);
                let o = eye + right * sx + up * sy;
                match rays.closest_hit(o, forward, 0.0, 4.0 * half_extent) {
                    Some(h) => (h.t / extent).min(miss),
                    None => miss,
                }
            })
        })
        .collect()
}

/// The ESM prefilter of section 4.6 ("filter (blur) the shadow map"), for eq. 30: a
/// separable log-space Gaussian of `faces` square faces of `res` texels (clamped at
/// face edges): each texel becomes `o_max + ln(sum w_i exp(c (o_i - o_max))) / c` over its
/// taps, the logarithm of the linear ESM filter of `exp(c o)` without ever forming it.
pub fn log_filter(map: &mut [f32], res: u32, faces: usize, radius: u32, c: f32) {
    if radius == 0 || res == 0 {
        return;
    }
    let weights: Vec<f32> = (-(radius as i32)..=radius as i32)
        .map(|i| {
            let s = 0.5 * radius as f32 + 0.5;
            (-(i * i) as f32 / (2.0 * s * s)).exp()
        })
        .collect();
    let total: f32 = weights.iter().sum();
    let weights: Vec<f32> = weights.iter().map(|w| w / total).collect();
    let n = res as usize;
    for horizontal in [true, false] {
        let src = map.to_vec();
        map.par_chunks_mut(n * n)
            .take(faces)
            .enumerate()
            .for_each(|(f, face)| {
                let base = &src[f * n * n..(f + 1) * n * n];
                for y in 0..n {
                    for x in 0..n {
                        let tap = |k: i32| {
                            let (tx, ty) = if horizontal {
                                ((x as i32 + k).clamp(0, n as i32 - 1) as usize, y)
                            } else {
                                (x, (y as i32 + k).clamp(0, n as i32 - 1) as usize)
                            };
                            base[ty * n + tx]
                        };
                        let r = radius as i32;
                        let mut o_max = f32::NEG_INFINITY;
                        for k in -r..=r {
                            o_max = o_max.max(tap(k));
                        }
                        let mut sum = 0.0f32;
                        for k in -r..=r {
                            sum += weights[(k + r) as usize] * (c * (tap(k) - o_max)).exp();
                        }
                        face[y * n + x] = o_max + sum.max(f32::MIN_POSITIVE).ln() / c;
                    }
                }
            });
    }
}

/// The largest `c d` eq. 30 is evaluated at: `exp(-80)` = 1.8e-35 is still a normal f32.
/// A larger cap (the first version used 100, 3.7e-44) makes fully shadowed texels
/// subnormal, and arithmetic on subnormals costs the CPU a microcode assist per operation:
/// measured, it made the CPU lighting pass twice as slow on the emitter-lit Cornell box.
pub const ESM_MAX_EXPONENT: f32 = 80.0;

/// Eq. 30 at one texel: `exp(-c max(r - o, 0))`, never of a positive argument (and the
/// argument capped at [`ESM_MAX_EXPONENT`], so `c d` may even be infinite).
pub fn esm(c: f32, receiver: f32, occluder: f32) -> f32 {
    let d = receiver - occluder;
    if d <= 0.0 {
        // Lit: the common case, without an exp.
        return 1.0;
    }
    (-(c * d).min(ESM_MAX_EXPONENT)).exp()
}

/// Bilinear PCF of eq. 30 over the four texels around image coordinates `uv` of one face
/// (listing 8), texels clamped to the face.
fn pcf(face: &[f32], res: u32, uv: Vec2, c: f32, receiver: f32) -> f32 {
    // Clamped first, so that receivers far outside the map index safely.
    let t = (uv * res as f32 - Vec2::splat(0.5)).clamp(Vec2::splat(-1.0), Vec2::splat(res as f32));
    let i0 = t.floor();
    let f = t - i0;
    let last = res as i32 - 1;
    let at = |dx: i32, dy: i32| {
        let x = (i0.x as i32 + dx).clamp(0, last) as usize;
        let y = (i0.y as i32 + dy).clamp(0, last) as usize;
        esm(c, receiver, face[y * res as usize + x])
    };
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * f.x;
    let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * f.x;
    top + (bottom - top) * f.y
}

/// The shadow factor of `map` for a receiver at `p` with unit normal `n` (1 lit, 0 in
/// shadow): eq. 30 with listing 8's bilinear PCF, after the normal offset.
pub fn visibility(
    texels: &[f32],
    map: &ShadowMap,
    p: Vec3,
    n: Vec3,
    extent: f32,
    settings: &ShadowSettings,
) -> f32 {
    let res = map.resolution;
    let c = settings.esm_exponent;
    let face_len = res as usize * res as usize;
    if matches!(map.kind, MapKind::Cube { .. }) {
        let center = map.origin;
        let dist = (p - center).length();
        let texel = 2.0 * dist / res as f32;
        let q = p + n * (settings.normal_offset * texel);
        let d = q - center;
        let len = d.length();
        if !(len > 0.0 && len.is_finite()) {
            return 1.0;
        }
        let (face, uv) = cube_face(d);
        let start = map.offset + face * face_len;
        let receiver = (len - settings.depth_bias * texel) / extent;
        return pcf(&texels[start..start + face_len], res, uv, c, receiver);
    }
    let half_extent = map.half_extent;
    let texel = 2.0 * half_extent / res as f32;
    let q = p + n * (settings.normal_offset * texel);
    let rel = q - map.origin;
    let uv = Vec2::new(
        0.5 * (rel.dot(map.right) / half_extent + 1.0),
        0.5 * (1.0 - rel.dot(map.up) / half_extent),
    );
    let receiver = (rel.dot(map.forward) - settings.depth_bias * texel) / extent;
    pcf(
        &texels[map.offset..map.offset + face_len],
        res,
        uv,
        c,
        receiver,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_faces_round_trip() {
        for face in 0..6 {
            for uv in [
                Vec2::new(0.1, 0.2),
                Vec2::new(0.5, 0.5),
                Vec2::new(0.9, 0.6),
            ] {
                let d = cube_direction(face, uv) * 3.7;
                let (f, back) = cube_face(d);
                assert_eq!(f, face);
                assert!((back - uv).length() < 1e-5, "{face} {uv} {back}");
            }
        }
    }

    #[test]
    fn log_filter_is_between_mean_and_max_and_never_overflows() {
        let res = 4;
        for c in [1.0f32, 88.72, 1e4, f32::MAX] {
            let mut map: Vec<f32> = (0..16).map(|i| (i % 5) as f32 * 0.5).collect();
            let orig = map.clone();
            log_filter(&mut map, res, 1, 1, c);
            let max = orig.iter().copied().fold(0.0f32, f32::max);
            for v in &map {
                assert!(v.is_finite(), "c = {c}: {v}");
                assert!(*v <= max + 1e-5);
            }
            // Eq. 30 with any exponent stays in [0, 1].
            for v in &map {
                let e = esm(c, 3.0, *v);
                assert!((0.0..=1.0).contains(&e), "{e}");
                assert_eq!(esm(c, 0.0, *v), 1.0);
            }
        }
        // A constant map is unchanged.
        let mut flat = vec![0.7f32; 16];
        log_filter(&mut flat, 4, 1, 2, 200.0);
        assert!(flat.iter().all(|v| (v - 0.7).abs() < 1e-5));
    }
}
