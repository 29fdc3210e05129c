//! Exponential shadow maps with PCF (section 4.6, eq. 30, listing 8).
//!
//! The maps do not depend on the camera, so [`super::LightSet::new`] builds them once per
//! scene, on the CPU: an orthographic map for each directional light (and each of the sky's
//! directions), rasterised at the texel centres ([`raster_ortho`]), and a six-face cube map
//! for each point light and each emitter sample, a ray per texel through the scene's BVH
//! ([`render_cube`]): both the depth of the nearest surface at the texel centre. Depths are
//! stored in units of the scene's extent, so the ESM exponent means the same at every scale.
//! The GPU lighting passes read the same texels from a storage buffer, so both paths see
//! identical maps ([`super::gpu_maps`] renders them on the GPU instead, for an engine's
//! meshes).
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
    /// An orthographic map's spread: the tangent of the half-angle of its light's cone of
    /// directions ([`super::Light::radius`]); above 0 the lookup gives the cone's penumbra
    /// ([`visibility`]). 0 for a hard shadow and for cube maps.
    pub spread: f32,
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

impl MapKind {
    /// An orthographic map's frame: `(eye, right, up, forward, half_extent)`; `None` for
    /// a cube.
    pub fn ortho_frame(&self) -> Option<(Vec3, Vec3, Vec3, Vec3, f32)> {
        match *self {
            MapKind::Ortho {
                eye,
                right,
                up,
                forward,
                half_extent,
            } => Some((eye, right, up, forward, half_extent)),
            MapKind::Cube { .. } => None,
        }
    }
}

impl ShadowMap {
    /// A map of `kind` with `resolution` texels per side starting at texel `offset`.
    pub fn new(offset: usize, resolution: u32, kind: MapKind) -> Self {
        let (origin, right, up, forward, half_extent) = match kind {
            MapKind::Cube { center } => (center, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0.0),
            MapKind::Ortho { .. } => {
                kind.ortho_frame()
                    .unwrap_or((Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0.0))
            }
        };
        Self {
            origin,
            right,
            up,
            forward,
            half_extent,
            offset,
            resolution,
            spread: 0.0,
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

    /// The width in the scene of one of the map's texels at `p`: `2 d / resolution` at a
    /// distance `d` from a cube map's centre (a face spans 90 degrees), the orthographic
    /// view's width over its resolution otherwise; what [`visibility`]'s normal offset and
    /// depth bias are measured in.
    pub fn texel_at(&self, p: Vec3) -> f32 {
        match self.kind {
            MapKind::Cube { .. } => 2.0 * (p - self.origin).length() / self.resolution as f32,
            MapKind::Ortho { .. } => 2.0 * self.half_extent / self.resolution as f32,
        }
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

/// Renders an orthographic map by a ray per texel: per texel the distance from the map plane
/// through `eye` to the nearest surface along `forward`, in units of `extent`. The light
/// sets draw these maps with [`raster_ortho`] (the same depths, a fraction of the cost);
/// this is its reference.
pub fn render_ortho(rays: &RayScene, kind: &MapKind, res: u32, extent: f32) -> Vec<f32> {
    let Some((eye, right, up, forward, half_extent)) = kind.ortho_frame() else {
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

/// A triangle as [`raster_ortho`] draws it: the barycentric weight of each corner as a
/// plane over texel coordinates, the corners' depths, and the first and last texel centre
/// its bounds hold on each axis (none when first > last).
struct Projected {
    w: [[f64; 3]; 3],
    t: [f64; 3],
    x: (f64, f64),
    y: (f64, f64),
}

/// Rows of an orthographic map one task of [`raster_ortho`] fills: the triangles are binned
/// by these bands once, then each band is drawn alone.
const RASTER_BAND: usize = 16;

/// [`render_ortho`]'s map drawn by rasterising `triangles` instead of casting a ray per
/// texel: per texel centre the nearest triangle covering it, its depth interpolated along
/// `forward` (exact in an orthographic projection), kept where a ray would take it (`t` in
/// `[0, 4 half_extent)`), passed over where the triangle's alpha mask cuts a hole at that
/// point (`cutouts`, by triangle index, as the ray cast's any-hit test). The same depths as
/// the ray cast but where a triangle's edge passes within rounding of a texel centre, in a
/// cost of the texels plus the triangles' coverage instead of a BVH traversal per texel:
/// a 64-direction sky's maps at 512 texels are 16.7 million texels.
///
/// A triangle whose projection is degenerate (seen edge-on) or not finite covers nothing,
/// as a ray would meet it nowhere. Bands of rows are drawn in parallel; a texel keeps the
/// least depth whatever the order, so the map does not depend on the thread count.
pub fn raster_ortho(
    triangles: &[[Vec3; 3]],
    cutouts: &crate::cutout::Cutouts,
    kind: &MapKind,
    res: u32,
    extent: f32,
) -> Vec<f32> {
    let Some((eye, right, up, forward, half_extent)) = kind.ortho_frame() else {
        return Vec::new();
    };
    let miss = 4.0 * half_extent / extent;
    let n = res as usize;
    let far = 4.0 * half_extent;
    // Each corner in texel coordinates (texel x's centre at x + 1/2, rows downward) and its
    // depth along `forward`, in f64 so that the coverage tests are not a source of cracks.
    let scale = 0.5 * f64::from(res) / f64::from(half_extent);
    let project = |p: Vec3| {
        let d = p - eye;
        let (u, v, t) = (d.dot(right), d.dot(up), d.dot(forward));
        [
            (f64::from(u) + f64::from(half_extent)) * scale,
            (f64::from(half_extent) - f64::from(v)) * scale,
            f64::from(t),
        ]
    };
    let bands = n.div_ceil(RASTER_BAND);
    let mut binned: Vec<Vec<u32>> = vec![Vec::new(); bands];
    // Per triangle, once: the barycentric weight of each corner as a plane over texel
    // coordinates (`w_k = a_k x + b_k y + d_k`), the corners' depths and the texel bounds.
    let projected: Vec<Option<Projected>> = triangles
        .par_iter()
        .with_min_len(1024)
        .map(|tri| {
            let c = tri.map(project);
            let area = (c[1][0] - c[0][0]) * (c[2][1] - c[0][1])
                - (c[1][1] - c[0][1]) * (c[2][0] - c[0][0]);
            let finite = c.iter().flatten().all(|x| x.is_finite());
            if !finite || area == 0.0 {
                return None;
            }
            let plane = |k: usize| {
                let (p, q) = (c[(k + 1) % 3], c[(k + 2) % 3]);
                let (a, b) = (-(q[1] - p[1]) / area, (q[0] - p[0]) / area);
                [a, b, -(a * p[0] + b * p[1])]
            };
            // Texel centres x + 1/2 within the corners' span on axis `i`.
            let span = |i: usize| {
                let lo = c[0][i].min(c[1][i]).min(c[2][i]);
                let hi = c[0][i].max(c[1][i]).max(c[2][i]);
                (
                    (lo - 0.5).ceil().max(0.0),
                    (hi - 0.5).floor().min(n as f64 - 1.0),
                )
            };
            Some(Projected {
                w: [plane(0), plane(1), plane(2)],
                t: [c[0][2], c[1][2], c[2][2]],
                x: span(0),
                y: span(1),
            })
        })
        .collect();
    for (i, p) in projected.iter().enumerate() {
        let Some(p) = p else { continue };
        let (first, last) = p.y;
        if first > last || p.x.0 > p.x.1 {
            continue;
        }
        let bands = first as usize / RASTER_BAND..=last as usize / RASTER_BAND;
        for members in &mut binned[bands] {
            members.push(i as u32);
        }
    }
    let mut map = vec![miss; n * n];
    map.par_chunks_mut(RASTER_BAND * n)
        .zip(binned.par_iter())
        .enumerate()
        .for_each(|(band, (rows, members))| {
            let y0 = band * RASTER_BAND;
            let y1 = y0 + rows.len() / n.max(1);
            let mut depth = vec![f64::INFINITY; rows.len()];
            for &i in members {
                let Some(p) = &projected[i as usize] else {
                    continue;
                };
                let (w, (xs, xe)) = (&p.w, p.x);
                let ys = p.y.0.max(y0 as f64);
                let ye = p.y.1.min(y1 as f64 - 1.0);
                if ys > ye {
                    continue;
                }
                for y in ys as usize..=ye as usize {
                    let py = y as f64 + 0.5;
                    let row = w.map(|[_, b, d]| b * py + d);
                    // The span of texel centres where every weight is non-negative (each
                    // texel is tested again below: the span only saves the empty ones).
                    let (mut from, mut to) = (xs, xe);
                    for k in 0..3 {
                        let a = w[k][0];
                        if a > 0.0 {
                            from = from.max((-row[k] / a - 0.5).ceil() - 1.0);
                        } else if a < 0.0 {
                            to = to.min((-row[k] / a - 0.5).floor() + 1.0);
                        }
                    }
                    if from > to {
                        continue;
                    }
                    for x in from as usize..=to as usize {
                        let px = x as f64 + 0.5;
                        let (w0, w1, w2) = (
                            w[0][0] * px + row[0],
                            w[1][0] * px + row[1],
                            w[2][0] * px + row[2],
                        );
                        if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                            continue;
                        }
                        let t = w0 * p.t[0] + w1 * p.t[1] + w2 * p.t[2];
                        let k = (y - y0) * n + x;
                        if !(t >= 0.0 && t < f64::from(far) && t < depth[k]) {
                            continue;
                        }
                        if !cutouts.is_empty()
                            && !cutouts.opaque(i, Vec2::new(w1 as f32, w2 as f32))
                        {
                            continue;
                        }
                        depth[k] = t;
                    }
                }
            }
            for (texel, &t) in rows.iter_mut().zip(&depth) {
                if t.is_finite() {
                    *texel = (t as f32 / extent).min(miss);
                }
            }
        });
    map
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
    // Shortcuts that give the same bits as the sum they skip (most of a map is flat: the
    // texels nothing is behind, a wall seen square on): `exp(0)` is exactly 1, so taps all
    // equal to their maximum give `o_max + ln(sum of the weights) / c`; and an exponential
    // of an argument below -105 rounds to 0 in f32.
    const EXP_UNDERFLOW: f32 = -105.0;
    let flat_offset = weights
        .iter()
        .fold(0.0f32, |s, w| s + w)
        .max(f32::MIN_POSITIVE)
        .ln()
        / c;
    let n = res as usize;
    let len = (faces * n * n).min(map.len());
    let r = radius as i32;
    let mut src = vec![0.0f32; len];
    for horizontal in [true, false] {
        src.copy_from_slice(&map[..len]);
        // One task per output row of every face (a one-face map is filtered by every
        // thread too); each texel is computed alone, so the result does not depend on the
        // thread count.
        map[..len]
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(row, out)| {
                let (f, y) = (row / n, row % n);
                let base = &src[f * n * n..(f + 1) * n * n];
                for (x, texel) in out.iter_mut().enumerate() {
                    let tap = |k: i32| {
                        let (tx, ty) = if horizontal {
                            ((x as i32 + k).clamp(0, n as i32 - 1) as usize, y)
                        } else {
                            (x, (y as i32 + k).clamp(0, n as i32 - 1) as usize)
                        };
                        base[ty * n + tx]
                    };
                    let mut o_max = f32::NEG_INFINITY;
                    let mut flat = true;
                    for k in -r..=r {
                        o_max = o_max.max(tap(k));
                        flat &= tap(k) == tap(-r);
                    }
                    if flat {
                        *texel = o_max + flat_offset;
                        continue;
                    }
                    let mut sum = 0.0f32;
                    for k in -r..=r {
                        let x = c * (tap(k) - o_max);
                        let w = weights[(k + r) as usize];
                        sum += if x == 0.0 {
                            w
                        } else if x < EXP_UNDERFLOW {
                            0.0
                        } else {
                            w * x.exp()
                        };
                    }
                    *texel = o_max + sum.max(f32::MIN_POSITIVE).ln() / c;
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
    let x = c * d;
    if x >= ESM_MAX_EXPONENT || x.is_nan() {
        // Deep in shadow (a lamp behind a wall): the cap's value, the same bits as the exp
        // of the capped argument, without an exp.
        return CAPPED;
    }
    (-x).exp()
}

/// `exp(-ESM_MAX_EXPONENT)`, what [`esm`] gives deep in shadow.
const CAPPED: f32 = 1.804_851_3e-35;

/// A shadow factor ([`visibility`]) below this is deep shadow: every texel of its PCF has
/// `c d` above ln(1e30) = 69.1, the receiver that far behind its occluder (1.7 % of the
/// scene's extent at the default `c` of 4000; the cap, [`ESM_MAX_EXPONENT`], gives
/// 1.8e-35). Callers that average a light over several points may take one such point as
/// hidden from them all (relighting's footprint). Twin: `DEEP_SHADOW` of
/// `scene_core::shadow` (WGSL).
pub const DEEP_SHADOW: f32 = 1e-30;

/// Bilinear PCF of eq. 30 over the four texels around image coordinates `uv` of one face
/// (listing 8), texels clamped to the face.
fn pcf(face: &[f32], res: u32, uv: Vec2, c: f32, receiver: f32) -> f32 {
    // Clamped first, so that receivers far outside the map index safely.
    let t = (uv * res as f32 - Vec2::splat(0.5)).clamp(Vec2::splat(-1.0), Vec2::splat(res as f32));
    bilinear(face, res, t, c, |_, _| receiver)
}

/// Listing 8's bilinear PCF of eq. 30 around texel coordinates `t` (texel `x`'s centre at
/// `x`), texels clamped to the face, each texel `(x, y)` compared with the receiver depth
/// `receiver(x, y)` (one depth for [`pcf`], the receiver's plane for [`soft_pcf`]).
fn bilinear(face: &[f32], res: u32, t: Vec2, c: f32, receiver: impl Fn(i32, i32) -> f32) -> f32 {
    let i0 = t.floor();
    let f = t - i0;
    let (x, y) = (i0.x as i32, i0.y as i32);
    let at = |dx: i32, dy: i32| {
        esm(
            c,
            receiver(x + dx, y + dy),
            texel(face, res, x + dx, y + dy),
        )
    };
    let (v00, v10, v01, v11) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
    let top = v00 + (v10 - v00) * f.x;
    let bottom = v01 + (v11 - v01) * f.x;
    top + (bottom - top) * f.y
}

/// Texel `(x, y)` of a face of `res` texels a side, clamped to the face.
fn texel(face: &[f32], res: u32, x: i32, y: i32) -> f32 {
    let last = res as i32 - 1;
    face[y.clamp(0, last) as usize * res as usize + x.clamp(0, last) as usize]
}

/// The texel nearest `p` in texel coordinates: `floor(p + 1/2)` (as the WGSL twin, whose
/// `round` would tie to even).
fn nearest(p: Vec2) -> (i32, i32) {
    ((p.x + 0.5).floor() as i32, (p.y + 0.5).floor() as i32)
}

/// Blocker-search taps per side of a soft lookup's square ([`soft_pcf`]), besides the
/// texel under the receiver.
const SEARCH_TAPS: usize = 3;

/// A soft lookup's filter taps ([`soft_pcf`]), each the nearest texel, on the unit disk:
/// Vogel's spiral, tap `k` at radius `sqrt((k + 1/2) / 16)` and angle `k` times the golden
/// angle, so that the taps cover the disk evenly and a straight edge at any angle meets
/// them in up to 16 steps (a square grid meets an edge along its rows in 4). Nearest
/// texels measured as accurate as bilinear PCFs on a 3 x 3 grid (0.142 against 0.143 off
/// the reference in the sun-and-sky window room, in 44 ms against 51). Twin:
/// `FILTER_DISK` of `scene_core::shadow` (WGSL).
const FILTER_DISK: [[f32; 2]; 16] = [
    [0.1767767, 0.0],
    [-0.2257722, 0.2068258],
    [0.0345581, -0.3937712],
    [0.2845712, 0.3711728],
    [-0.5222232, -0.0923739],
    [0.4946954, -0.3146847],
    [-0.1654659, 0.615525],
    [-0.3155615, -0.6075944],
    [0.6846422, 0.2500302],
    [-0.7122561, 0.294009],
    [0.3433545, -0.7337286],
    [0.2537302, 0.808932],
    [-0.7647459, -0.4431859],
    [0.897134, -0.1972324],
    [-0.5475069, 0.7787722],
    [-0.1264868, -0.9760897],
];

/// The widest penumbra a soft lookup gives, in texels each side (the private `soft_pcf`): 32 texels
/// of a sky map at 512 are 3 % of the scene's extent. A blocker farther from its receiver
/// than this penumbra's spread allows is still found where it covers the search's taps,
/// and blurs over this width.
pub const MAX_PENUMBRA: f32 = 32.0;

/// The depth (in extents) of the scene's side nearest an orthographic map's plane: the
/// plane lies one extent before the scene's centre ([`crate::View::orthographic_fit`]),
/// and nothing of the scene more than half an extent from the centre.
const NEAR_DEPTH: f32 = 0.5;

/// The steepest receiver plane a soft lookup follows, in depth texels per texel (a
/// receiver within 7 degrees of the light's direction).
const MAX_SLOPE: f32 = 8.0;

/// A soft lookup (percentage-closer soft shadows, beyond the thesis) of one orthographic
/// map for a light whose directions fill a cone ([`ShadowMap::spread`]): a blocker at
/// depth `o` in front of a receiver at depth `r` hides a part of the cone from the points
/// within `spread (r - o)` of its shadow's edge. The lookup
/// 1. searches a square as wide as a blocker at the scene's near side would blur (at most
///    [`MAX_PENUMBRA`] texels each side): [`SEARCH_TAPS`]² texels on a grid and the one
///    under the receiver, each compared with the receiver's plane at that texel's centre
///    (the receiver's depth plus its slope from `grad`, per texel along x and y, so that
///    a receiver does not shadow itself over the square);
/// 2. returns lit where none is in front of the plane, and the capped shadow of eq. 30
///    where every tap that sees something is deep in shadow ([`DEEP_SHADOW`]);
/// 3. else averages eq. 30 against the plane over the 16 texels of [`FILTER_DISK`] on the
///    disk of radius `spread (r - mean blocker depth)` (at most [`MAX_PENUMBRA`]), the
///    cone's own shape, or listing 8's bilinear PCF where that is under half a texel.
///
/// Texels that see nothing (deeper than the scene's far side, [`FAR_DEPTH`]) are left out
/// of the search's verdict and of the filter's average: a floor inside a closed room, near
/// the room's outline in the map, has such texels beside it, and counted as lit they let
/// the cone's light through the walls (measured: the sun-and-sky window room of
/// `tests/tests/sky.rs` read +33 % in blue; a receiver beside the edge of an open floor
/// loses nothing, the floor's own texels being lit).
///
/// `t` is the receiver in texel coordinates (texel `x`'s centre at `x`), `receiver` its
/// depth (extents, biased) and `spread_texels` the penumbra's half-width in texels per
/// extent of depth between blocker and receiver. Twin: `soft_pcf` of `scene_core::shadow`
/// (WGSL); both take a tap's texel as `floor(x + 1/2)` (WGSL's `round` ties to even).
#[allow(clippy::too_many_arguments)]
fn soft_pcf(
    face: &[f32],
    res: u32,
    t: Vec2,
    c: f32,
    receiver: f32,
    grad: Vec2,
    spread_texels: f32,
) -> f32 {
    let texel = |x: i32, y: i32| texel(face, res, x, y);
    let plane = |x: i32, y: i32| receiver + grad.x * (x as f32 - t.x) + grad.y * (y as f32 - t.y);
    let search = (spread_texels * (receiver - NEAR_DEPTH)).clamp(0.0, MAX_PENUMBRA);
    let (mut sum, mut blockers, mut deep, mut misses) = (0.0f32, 0usize, true, 0usize);
    let mut visit = |p: Vec2| {
        let (x, y) = nearest(p);
        let (o, r) = (texel(x, y), plane(x, y));
        misses += usize::from(o >= FAR_DEPTH);
        if o < r {
            sum += o;
            blockers += 1;
            deep &= esm(c, r, o) < DEEP_SHADOW;
        }
    };
    visit(t);
    let step = |i: usize, taps: usize| (i as f32 / (taps - 1) as f32) * 2.0 - 1.0;
    for j in 0..SEARCH_TAPS {
        for i in 0..SEARCH_TAPS {
            visit(t + Vec2::new(step(i, SEARCH_TAPS), step(j, SEARCH_TAPS)) * search);
        }
    }
    if blockers == 0 {
        return 1.0;
    }
    if deep && blockers + misses == SEARCH_TAPS * SEARCH_TAPS + 1 {
        return CAPPED;
    }
    let width = (spread_texels * (receiver - sum / blockers as f32)).clamp(0.0, MAX_PENUMBRA);
    if width < 0.5 {
        return bilinear(face, res, t, c, plane);
    }
    let (mut lit, mut seen) = (0.0f32, 0.0f32);
    for [x, y] in FILTER_DISK {
        let (x, y) = nearest(t + Vec2::new(x, y) * width);
        let o = texel(x, y);
        if o < FAR_DEPTH {
            lit += esm(c, plane(x, y), o);
            seen += 1.0;
        }
    }
    if seen > 0.0 {
        lit / seen
    } else {
        bilinear(face, res, t, c, plane)
    }
}

/// The depth (in extents) of the scene's far side in an orthographic map: a texel deeper
/// sees nothing ([`NEAR_DEPTH`]; misses are stored at 2).
const FAR_DEPTH: f32 = 1.5 + 1e-3;

/// The shadow factor of `map` for a receiver at `p` with unit normal `n` (1 lit, 0 in
/// shadow): eq. 30 with listing 8's bilinear PCF, after the normal offset; an orthographic
/// map with a spread gives its cone's penumbra (a soft lookup, the private `soft_pcf`: a
/// blocker search over the receiver's plane, then 16 taps on a disk as wide as the cone
/// projects from the mean blocker; docs/scene-core.md).
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
    let texel = map.texel_at(p);
    if matches!(map.kind, MapKind::Cube { .. }) {
        let center = map.origin;
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
    let q = p + n * (settings.normal_offset * texel);
    let rel = q - map.origin;
    let uv = Vec2::new(
        0.5 * (rel.dot(map.right) / half_extent + 1.0),
        0.5 * (1.0 - rel.dot(map.up) / half_extent),
    );
    let receiver = (rel.dot(map.forward) - settings.depth_bias * texel) / extent;
    let face = &texels[map.offset..map.offset + face_len];
    if map.spread > 0.0 {
        // The receiver's plane: its depth's change (extents) per texel along x (right) and
        // y (rows run down), from its normal, clamped to MAX_SLOPE.
        let nf = n.dot(map.forward);
        let per_texel = texel / extent;
        let limit = MAX_SLOPE * per_texel;
        let grad = if nf != 0.0 {
            (Vec2::new(-n.dot(map.right), n.dot(map.up)) * (per_texel / nf))
                .clamp(Vec2::splat(-limit), Vec2::splat(limit))
        } else {
            Vec2::ZERO
        };
        let grad = if grad.is_finite() { grad } else { Vec2::ZERO };
        let t =
            (uv * res as f32 - Vec2::splat(0.5)).clamp(Vec2::splat(-1.0), Vec2::splat(res as f32));
        return soft_pcf(face, res, t, c, receiver, grad, map.spread / per_texel);
    }
    pcf(face, res, uv, c, receiver)
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
    fn deep_shadow_is_the_capped_exp_to_the_bit() {
        assert_eq!(CAPPED.to_bits(), (-ESM_MAX_EXPONENT).exp().to_bits());
        // Deep shadow is c d beyond 69.1: a texel at 69 is above it, one at 69.2 below.
        const { assert!(CAPPED < DEEP_SHADOW) };
        assert!(esm(1.0, 69.0, 0.0) > DEEP_SHADOW && esm(1.0, 69.2, 0.0) < DEEP_SHADOW);
        assert_eq!(esm(4000.0, 1.0, 0.0), (-ESM_MAX_EXPONENT).exp());
        assert_eq!(esm(f32::INFINITY, 1.0, 0.5), CAPPED);
        assert_eq!(esm(4000.0, 0.5, 0.5), 1.0);
        let penumbra = esm(4000.0, 0.5001, 0.5);
        assert_eq!(penumbra, (-(4000.0f32 * (0.5001f32 - 0.5))).exp());
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
