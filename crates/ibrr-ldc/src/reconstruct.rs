//! Reconstruction (paper section 5, figure 4 right): every camera pixel is unprojected
//! from its G-buffer depth, warped into the LDI most parallel to its normal, matched to a
//! layer by the plane test, and shaded `albedo x r` (here `albedo / pi x E`, the radiance
//! of a Lambertian surface under irradiance `E`; emissive surfaces add their emission).
//!
//! Three kernels ([`Lookup`]): the LDI pixel the point falls in; the paper's averaging
//! kernel; and bilinear interpolation over the four nearest LDI pixel centres, blended
//! across the LDIs a normal near their boundary belongs to (section 6.2). A pixel that finds
//! no matching layer searches rings of LDI pixels up to
//! [`crate::IbrrSettings::fallback_radius`]. A pixel that finds none there either is
//! filled from the camera pixels around it that did ([`Served::Filled`], the hole fill
//! below, beyond the paper), or, with none of its orientation within
//! [`crate::IbrrSettings::fill_radius`] camera pixels, black and counted
//! ([`Reconstruction::missing`]), never NaN.
//!
//! **The hole fill.** A pixel without a layer is a surface that no IRPL's render sampled
//! (the underside of a shelf no path reached, a sliver of wall behind a post whose layer
//! centres the camera sees hidden). Its direct light stays zero: the lights' own renders
//! (the exact sources) found nothing of its plane there, which is what a surface in shadow
//! gives (with the direct light alone, every shadow has no layer). Its indirect light,
//! smooth and zero only by the chance of which paths were drawn, is the mean of the
//! nearest ring of camera pixels around it served by a layer or the fallback,
//! whose normals match its own as layers match (`n' . n > 1 - eps_normal`)
//! and whose points lie on its plane (within twice the LDC's plane distance); where no ring
//! within the radius holds such a pixel, the nearest ring holding pixels of its
//! orientation on other planes; else the nearest ring holding pixels that face its side at
//! all (`n' . n > 0`: a post's cap, the only face of its orientation in sight). Only
//! pixels served by the LDC are read, never filled ones,
//! so the fill does not depend on the order pixels are visited in, and the GPU twin
//! (`fill` in `shaders/ibrr-ldc/reconstruct.wgsl`) reads the same rings.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use scene_core::lights::LightId;
use scene_core::view::{FrustumReconstruction, Projection, pixel_uv};
use scene_core::{GBuffer, Image, LightState, Scene, View};

use crate::ldc::{Ldc, LdcFrame, axes_of};
use crate::settings::{Lookup, Reading};

/// Irradiance read from the LDC for one view.
#[derive(Clone, Debug, PartialEq)]
pub struct Reconstruction {
    /// Per pixel, direct irradiance (zero on background and where nothing matched).
    pub direct: Vec<Vec3>,
    /// Per pixel, indirect irradiance.
    pub indirect: Vec<Vec3>,
    /// Pixels with geometry that found no matching layer even in the fallback search, and
    /// nothing of their orientation around them to fill from: black.
    pub missing: u64,
    /// Pixels served by the fallback search.
    pub fallback: u64,
    /// Pixels without a layer filled from the camera pixels around them.
    pub filled: u64,
    /// Per pixel, how it was served.
    pub served: Vec<Served>,
}

/// How a camera pixel found its light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Served {
    /// Background, or no normal: nothing to shade.
    Background,
    /// Layers of the pixel's plane around it, by the lookup kernel.
    Layer,
    /// The fallback: the nearest layer of its orientation in rings around it, or, as the
    /// last resort, a layer of its plane whose centre the camera does not see.
    Fallback,
    /// No layer of its orientation anywhere near: black.
    Missing,
    /// No layer, but served pixels of its orientation around it in the camera's image: no
    /// direct light and their indirect light's mean (the hole fill).
    Filled,
}

impl Served {
    /// Whether the LDC itself served the pixel (by its layers or the fallback): what the
    /// hole fill reads.
    pub fn from_ldc(self) -> bool {
        matches!(self, Served::Layer | Served::Fallback)
    }
}

/// How one lookup went.
enum Found {
    Direct((Vec3, Vec3)),
    Fallback((Vec3, Vec3)),
    Missing,
}

/// The layer values of `ldc` at `p` with normal `n` (every neighbouring layer on the plane
/// counts; [`reconstruct()`] also checks that the camera sees them).
pub fn lookup(
    ldc: &Ldc,
    p: Vec3,
    n: Vec3,
    mode: Lookup,
    fallback_radius: u32,
) -> Option<(Vec3, Vec3)> {
    match lookup_inner(ldc, p, n, mode, fallback_radius, &|_, _| true, &|_, _| true) {
        Found::Direct(v) | Found::Fallback(v) => Some(v),
        Found::Missing => None,
    }
}

/// Whether the point `q` of a neighbouring LDI pixel's layer (normal `n`) may shade a
/// camera pixel.
type Visible<'a> = dyn Fn(Vec3, Vec3) -> bool + Sync + 'a;

/// Whether each of the four camera pixels around the projection of the point `q` of a
/// layer (normal `n`) sees that layer's own plane or a surface behind `q` (the last
/// resort's test of a layer centre the camera does not see on its plane; one pixel alone
/// let a floor's layer behind a wall through at the wall's foot).
type Unhidden<'a> = dyn Fn(Vec3, Vec3) -> bool + Sync + 'a;

fn lookup_inner(
    ldc: &Ldc,
    p: Vec3,
    n: Vec3,
    mode: Lookup,
    fallback_radius: u32,
    visible: &Visible,
    unhidden: &Unhidden,
) -> Found {
    let frame = &ldc.frame;
    let mut sum = (Vec3::ZERO, Vec3::ZERO);
    let mut total = 0.0f32;
    let mut dominant = (0usize, -1.0f32);
    for (axis, w_axis) in axes_of(n, frame.band) {
        if w_axis <= 0.0 {
            continue;
        }
        if w_axis > dominant.1 {
            dominant = (axis, w_axis);
        }
        if let Some((v, w)) = in_ldi(ldc, frame, axis, p, n, mode, visible) {
            sum.0 += v.0 * w_axis;
            sum.1 += v.1 * w_axis;
            total += w_axis * w;
        }
    }
    if total > 0.0 {
        return Found::Direct((sum.0 / total, sum.1 / total));
    }
    // Fallback: the nearest matching layer in rings around the point, dominant LDI.
    let axis = dominant.0;
    let c = frame.pixel_coords(axis, p);
    let (ci, cj) = (c.x.floor() as i64, c.y.floor() as i64);
    // The nearest ring layer whose centre the camera does not see (for the last resort).
    let mut hidden: Option<usize> = None;
    for r in 1..=fallback_radius as i64 {
        let mut best: Option<(f32, usize)> = None;
        let mut hidden_best: Option<(f32, usize)> = None;
        for j in cj - r..=cj + r {
            for i in ci - r..=ci + r {
                if (i - ci).abs() != r && (j - cj).abs() != r {
                    continue;
                }
                let Some(index) = frame.pixel_index(axis, i, j) else {
                    continue;
                };
                // Relaxed distance: the layer's plane at its own pixel, not at p.
                for l in ldc.range(index) {
                    let plane = ldc.planes[l];
                    if n.dot(plane.truncate()) <= 1.0 - frame.eps_normal {
                        continue;
                    }
                    let Some(q) = frame.point_on_plane(axis, i, j, plane) else {
                        continue;
                    };
                    let d2 = (q - p).length_squared();
                    if (p.dot(plane.truncate()) - plane.w).abs()
                        < frame.eps_distance * (r as f32 + 1.0)
                        && best.is_none_or(|(b, _)| d2 < b)
                    {
                        if visible(q, plane.truncate()) {
                            best = Some((d2, l));
                        } else if hidden_best.is_none_or(|(b, _)| d2 < b)
                            && unhidden(q, plane.truncate())
                        {
                            hidden_best = Some((d2, l));
                        }
                    }
                }
            }
        }
        if let Some((_, l)) = best {
            return Found::Fallback((ldc.direct[l], ldc.indirect[l]));
        }
        if hidden.is_none() {
            hidden = hidden_best.map(|(_, l)| l);
        }
    }
    // Last resort: the layer of the point's own plane in its own LDI pixel, else the
    // nearest in the rings, although the camera does not see that pixel's centre on it,
    // provided nothing the camera sees lies in front of that centre. A surface narrower
    // than an LDI pixel (a post, a board's edge) has its layers' centres off the surface,
    // where the camera sees past it to what lies behind; the layer still holds the light
    // of that plane there. A centre behind a wall stays refused (the leak test).
    let home = frame
        .pixel_index(axis, ci, cj)
        .and_then(|index| ldc.find(index, p, n))
        .filter(|&l| {
            frame
                .point_on_plane(axis, ci, cj, ldc.planes[l])
                .is_some_and(|q| unhidden(q, ldc.planes[l].truncate()))
        });
    match home.or(hidden) {
        Some(l) => Found::Fallback((ldc.direct[l], ldc.indirect[l])),
        None => Found::Missing,
    }
}

/// Kernel-weighted values in one LDI: `((direct, indirect) already divided by the weight
/// of matches, fraction of the kernel's weight that matched > 0)`.
fn in_ldi(
    ldc: &Ldc,
    frame: &LdcFrame,
    axis: usize,
    p: Vec3,
    n: Vec3,
    mode: Lookup,
    visible: &Visible,
) -> Option<((Vec3, Vec3), f32)> {
    let c = frame.pixel_coords(axis, p);
    let mut acc = (Vec3::ZERO, Vec3::ZERO);
    let mut wsum = 0.0f32;
    let add = |i: i64, j: i64, w: f32, acc: &mut (Vec3, Vec3), wsum: &mut f32| {
        if w <= 0.0 {
            return;
        }
        if let Some(index) = frame.pixel_index(axis, i, j)
            && let Some(l) = ldc.find(index, p, n)
            && frame
                .point_on_plane(axis, i, j, ldc.planes[l])
                .is_none_or(|q| visible(q, n))
        {
            acc.0 += ldc.direct[l] * w;
            acc.1 += ldc.indirect[l] * w;
            *wsum += w;
        }
    };
    match mode {
        Lookup::Nearest => add(
            c.x.floor() as i64,
            c.y.floor() as i64,
            1.0,
            &mut acc,
            &mut wsum,
        ),
        Lookup::Average { radius } => {
            let (ci, cj) = (c.x.floor() as i64, c.y.floor() as i64);
            let r = radius as i64;
            for j in cj - r..=cj + r {
                for i in ci - r..=ci + r {
                    add(i, j, 1.0, &mut acc, &mut wsum);
                }
            }
        }
        Lookup::Bilinear => {
            let f = c - Vec2::splat(0.5);
            let (i0, j0) = (f.x.floor() as i64, f.y.floor() as i64);
            let t = f - Vec2::new(i0 as f32, j0 as f32);
            add(i0, j0, (1.0 - t.x) * (1.0 - t.y), &mut acc, &mut wsum);
            add(i0 + 1, j0, t.x * (1.0 - t.y), &mut acc, &mut wsum);
            add(i0, j0 + 1, (1.0 - t.x) * t.y, &mut acc, &mut wsum);
            add(i0 + 1, j0 + 1, t.x * t.y, &mut acc, &mut wsum);
        }
    }
    (wsum > 0.0).then(|| ((acc.0 / wsum, acc.1 / wsum), 1.0))
}

/// Reads `ldc` for every pixel of `g` (seen from `view`).
///
/// Beyond the paper: a neighbouring LDI pixel's layer shades a camera pixel only if the
/// camera sees that layer's pixel centre on the layer's plane (the camera's G-buffer is
/// its own visibility test, asked of the four pixels around the centre's projection), so
/// a kernel never reaches through a wall thinner than an LDI pixel to the same plane on
/// its other side. Centres off screen or behind the camera count as seen.
pub fn reconstruct(ldc: &Ldc, g: &GBuffer, view: &View, reading: Reading) -> Reconstruction {
    let Reading {
        lookup: mode,
        fallback_radius,
        fill_radius,
    } = reading;
    let recon = FrustumReconstruction::new(view);
    let (w, h) = (g.width, g.height);
    let vp = view.view_projection();
    let eps_d = 2.0 * ldc.frame.eps_distance;
    let eps_n = ldc.frame.eps_normal;
    let visible = move |q: Vec3, n: Vec3| -> bool {
        crate::construct::render_sees(&vp, &recon, g, q, n, eps_d, eps_n).unwrap_or(true)
    };
    let perspective = matches!(view.projection, Projection::Perspective { .. });
    let (eye, forward) = (view.eye, view.forward);
    let unhidden = move |q: Vec3, n: Vec3| -> bool {
        let clip = vp * q.extend(1.0);
        if clip.w <= 0.0 {
            return false;
        }
        let (u, v) = (clip.x / clip.w * 0.5 + 0.5, 0.5 - clip.y / clip.w * 0.5);
        if !(0.0..1.0).contains(&u) || !(0.0..1.0).contains(&v) {
            return false;
        }
        let x0 = (u * w as f32 - 0.5).floor() as i64;
        let y0 = (v * h as f32 - 0.5).floor() as i64;
        (0..4).all(|k| {
            let x = (x0 + (k & 1)).clamp(0, i64::from(w) - 1) as u32;
            let y = (y0 + (k >> 1)).clamp(0, i64::from(h) - 1) as u32;
            let i = (y * w + x) as usize;
            if g.is_background(i) {
                return true;
            }
            let pp = recon.world(pixel_uv(x, y, w, h), g.depth[i]);
            // The layer's own plane, seen at a grazing angle, hides nothing.
            if g.normal[i].dot(n) > 1.0 - eps_n && (q - pp).dot(n).abs() < eps_d {
                return true;
            }
            if perspective {
                (pp - eye).length() >= (q - eye).length() - eps_d
            } else {
                (pp - q).dot(forward) >= -eps_d
            }
        })
    };
    let found: Vec<(Vec3, Vec3, Served)> = (0..g.len())
        .into_par_iter()
        .map(|i| {
            if g.is_background(i) || g.normal[i] == Vec3::ZERO {
                return (Vec3::ZERO, Vec3::ZERO, Served::Background);
            }
            let (x, y) = (i as u32 % w, i as u32 / w);
            let p = recon.world(pixel_uv(x, y, w, h), g.depth[i]);
            match lookup_inner(
                ldc,
                p,
                g.normal[i],
                mode,
                fallback_radius,
                &visible,
                &unhidden,
            ) {
                Found::Direct((d, ind)) => (d, ind, Served::Layer),
                Found::Fallback((d, ind)) => (d, ind, Served::Fallback),
                Found::Missing => (Vec3::ZERO, Vec3::ZERO, Served::Missing),
            }
        })
        .collect();
    let mut r = Reconstruction {
        direct: Vec::with_capacity(found.len()),
        indirect: Vec::with_capacity(found.len()),
        missing: 0,
        fallback: 0,
        filled: 0,
        served: Vec::with_capacity(found.len()),
    };
    for (d, ind, k) in found {
        r.direct.push(d);
        r.indirect.push(ind);
        r.served.push(k);
    }
    fill_holes(ldc, g, view, fill_radius, &mut r);
    r
}

/// The hole fill (module docs) of `r`, the reconstruction of `g` seen from `view`:
/// every [`Served::Missing`] pixel keeps no direct light and takes as its indirect light
/// the mean of the nearest ring (up to `radius`
/// camera pixels) of LDC-served pixels of its orientation on its plane (within twice the
/// LDC's plane distance), else of its orientation on any plane, else facing its side; the
/// counts are taken again. [`reconstruct()`] calls it; it is public for tests that make
/// holes of their own.
pub fn fill_holes(ldc: &Ldc, g: &GBuffer, view: &View, radius: u32, r: &mut Reconstruction) {
    if radius > 0 && r.served.contains(&Served::Missing) {
        let recon = FrustumReconstruction::new(view);
        let eps_d = 2.0 * ldc.frame.eps_distance;
        fill_rings(r, g, &recon, radius, eps_d, ldc.frame.eps_normal);
    }
    (r.missing, r.fallback, r.filled) = (0, 0, 0);
    for k in &r.served {
        match k {
            Served::Fallback => r.fallback += 1,
            Served::Missing => r.missing += 1,
            Served::Filled => r.filled += 1,
            _ => {}
        }
    }
}

fn fill_rings(
    r: &mut Reconstruction,
    g: &GBuffer,
    recon: &FrustumReconstruction,
    radius: u32,
    eps_d: f32,
    eps_n: f32,
) {
    let (w, h) = (g.width, g.height);
    let point = |i: usize| recon.world(pixel_uv(i as u32 % w, i as u32 / w, w, h), g.depth[i]);
    let holes: Vec<usize> = (0..r.served.len())
        .filter(|&i| r.served[i] == Served::Missing)
        .collect();
    let fills: Vec<Option<Vec3>> = holes
        .par_iter()
        .map(|&i| {
            let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
            let (p, n) = (point(i), g.normal[i]);
            // Sums over the ring of the pixels on the plane, and the first ring's of the
            // pixels of the orientation on other planes and of those facing its side.
            let mut other: Option<(Vec3, f32)> = None;
            let mut facing: Option<(Vec3, f32)> = None;
            for rr in 1..=i64::from(radius) {
                let mut plane = (Vec3::ZERO, 0.0f32);
                let mut off = (Vec3::ZERO, 0.0f32);
                let mut side = (Vec3::ZERO, 0.0f32);
                for v in y - rr..=y + rr {
                    if v < 0 || v >= i64::from(h) {
                        continue;
                    }
                    // The ring's row: whole at its top and bottom, its two ends between
                    // (in raster order, as the GPU reads it).
                    let step = if (v - y).abs() == rr {
                        1
                    } else {
                        2 * rr as usize
                    };
                    for u in (x - rr..=x + rr).step_by(step) {
                        if u < 0 || u >= i64::from(w) {
                            continue;
                        }
                        let k = (v * i64::from(w) + u) as usize;
                        let cos = n.dot(g.normal[k]);
                        if !r.served[k].from_ldc() || cos <= 0.0 {
                            continue;
                        }
                        let sum = if cos <= 1.0 - eps_n {
                            &mut side
                        } else if (point(k) - p).dot(n).abs() < eps_d {
                            &mut plane
                        } else {
                            &mut off
                        };
                        sum.0 += r.indirect[k];
                        sum.1 += 1.0;
                    }
                }
                if plane.1 > 0.0 {
                    return Some(plane.0 / plane.1);
                }
                if other.is_none() && off.1 > 0.0 {
                    other = Some(off);
                }
                if facing.is_none() && side.1 > 0.0 {
                    facing = Some(side);
                }
            }
            other.or(facing).map(|(ind, c)| ind / c)
        })
        .collect();
    for (&i, f) in holes.iter().zip(fills) {
        if let Some(ind) = f {
            r.direct[i] = Vec3::ZERO;
            r.indirect[i] = ind;
            r.served[i] = Served::Filled;
        }
    }
}

/// The displayed radiance: `albedo / pi x (direct + indirect)` plus the emission of
/// emissive surfaces seen directly from their emitting side (times their light's direct
/// factor under `lights`), as the reference path tracer counts it.
pub fn shade(
    scene: &Scene,
    g: &GBuffer,
    view: &View,
    r: &Reconstruction,
    lights: &LightState,
) -> Image {
    let offsets = scene.mesh_offsets();
    let recon = FrustumReconstruction::new(view);
    let mut img = Image::new(g.width, g.height);
    for i in 0..g.len() {
        if g.is_background(i) {
            continue;
        }
        let albedo = g.albedo[i].truncate();
        let mut l = albedo * std::f32::consts::FRAC_1_PI * (r.direct[i] + r.indirect[i]);
        if let Some(t) = scene.triangle_ref(&offsets, g.triangle_id[i]) {
            let mesh = &scene.meshes[t.mesh as usize];
            let m = mesh.material_ids[t.local as usize];
            // Only emitters need their winding and the pixel's position.
            if scene
                .materials
                .get(m as usize)
                .is_some_and(|m| m.is_emissive())
            {
                let tri = mesh.indices[t.local as usize].map(|k| mesh.positions[k as usize]);
                let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                let uv = pixel_uv(i as u32 % g.width, i as u32 / g.width, g.width, g.height);
                let (eye, _) = view.ray(uv);
                if ng.dot(recon.world(uv, g.depth[i]) - eye) < 0.0 {
                    let le = scene.triangle_emission(t.mesh as usize, t.local as usize);
                    l += le * lights.get(LightId::Emissive(t.mesh)).direct_factor();
                }
            }
        }
        img.pixels[i] = if l.is_finite() { l } else { Vec3::ZERO };
    }
    img
}
