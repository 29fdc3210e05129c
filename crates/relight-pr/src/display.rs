//! Display: element irradiance interpolated smoothly over a camera G-buffer. Elements are
//! welded into vertices (corners at the same place with the same normal); a vertex takes the
//! area-weighted mean irradiance of its elements; a pixel interpolates its element's three
//! vertices at its reconstructed position and multiplies by the G-buffer's (textured)
//! albedo, `L = albedo E / pi`, plus the element's emission times its light's direct
//! factor. The G-buffer must be of [`crate::Meshing::element_scene`], so that triangle ids
//! are element ids.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;
use scene_core::sampling::{hash_seed, r2};
use scene_core::shadowed_lights::esm::DEEP_SHADOW;
use scene_core::shadowed_lights::{LightKind, LightSet};
use scene_core::view::FrustumReconstruction;
use scene_core::{GBuffer, Image, View};

use crate::direct::{DirectGather, solid_angle};
use scene_core::ray::RayScene;

use crate::mesh::Meshing;

/// Elements welded into shared vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Welding {
    /// The vertex of each element corner, `3 j + c`.
    pub corner_vertex: Vec<u32>,
    /// Number of vertices.
    pub vertices: usize,
    /// Each vertex's corners in ascending order: `corners[starts[v]..starts[v + 1]]`
    /// (what lets [`Welding::vertex_values`] gather a vertex at a time, in parallel).
    starts: Vec<u32>,
    corners: Vec<u32>,
}

impl Welding {
    /// Welds corners closer than `1e-5` of `extent` with normals within about 25 degrees.
    pub fn new(meshing: &Meshing, extent: f32) -> Self {
        let cell = (extent * 1e-5).max(f32::MIN_POSITIVE);
        let mut map: HashMap<([i64; 3], [i8; 3]), u32> = HashMap::new();
        let mut corner_vertex = Vec::with_capacity(3 * meshing.elements.len());
        for e in &meshing.elements {
            let n = (e.normal * 2.0).round();
            let nk = [n.x as i8, n.y as i8, n.z as i8];
            for c in e.corners {
                let q = (c / cell).round();
                let key = ([q.x as i64, q.y as i64, q.z as i64], nk);
                let next = map.len() as u32;
                corner_vertex.push(*map.entry(key).or_insert(next));
            }
        }
        let vertices = map.len();
        let (starts, corners) = incidence(&corner_vertex, vertices);
        Self {
            corner_vertex,
            vertices,
            starts,
            corners,
        }
    }

    /// [`Welding::new`], then every element corner that its element's centre cannot reach
    /// over the surface (the segment from the centroid to the corner, both lifted by
    /// `1e-4` of `extent` along the element's normal, is blocked by `rays`) gets a vertex of
    /// its own: a corner under a wall (the floor's elements on either side of it meet
    /// there) then carries only its own element's value, and light does not spread through
    /// the wall by interpolation.
    pub fn with_visibility(meshing: &Meshing, extent: f32, rays: &RayScene) -> Self {
        let mut welding = Self::new(meshing, extent);
        let lift = 1e-4 * extent;
        let blocked: Vec<bool> = meshing
            .elements
            .par_iter()
            .flat_map_iter(|e| {
                let from = e.centroid + e.normal * lift;
                e.corners
                    .map(|c| crate::visibility::segment_blocked(rays, from, c + e.normal * lift))
            })
            .collect();
        for (corner, b) in welding.corner_vertex.iter_mut().zip(blocked) {
            if b {
                *corner = welding.vertices as u32;
                welding.vertices += 1;
            }
        }
        (welding.starts, welding.corners) = incidence(&welding.corner_vertex, welding.vertices);
        welding
    }

    /// Per-vertex area-weighted mean of per-element values: one per mesh element, or one
    /// per solution element ([`Meshing::slot`]). Each vertex sums its corners' elements in
    /// element order, a vertex per task (the same bits on any number of threads).
    pub fn vertex_values(&self, meshing: &Meshing, values: &[Vec3]) -> Vec<Vec3> {
        (0..self.vertices)
            .into_par_iter()
            .map(|v| self.vertex_value(v, meshing, values))
            .collect()
    }

    /// Vertex `v`'s value of [`Welding::vertex_values`] alone (the same bits): what the
    /// display computes for the corners of the elements a frame shows, instead of every
    /// vertex of the scene.
    pub fn vertex_value(&self, v: usize, meshing: &Meshing, values: &[Vec3]) -> Vec3 {
        let (mut sum, mut weight) = (Vec3::ZERO, 0.0f32);
        for &q in &self.corners[self.starts[v] as usize..self.starts[v + 1] as usize] {
            let j = q as usize / 3;
            let w = vertex_weight(&meshing.elements[j]);
            sum += values[meshing.slot(j, values.len())] * w;
            weight += w;
        }
        if weight > 0.0 {
            sum / weight
        } else {
            Vec3::ZERO
        }
    }
}

/// Each vertex's corners, ascending (a counting sort of `corner_vertex`): the start of
/// each vertex's run (`vertices + 1` entries) and the runs.
fn incidence(corner_vertex: &[u32], vertices: usize) -> (Vec<u32>, Vec<u32>) {
    let mut starts = vec![0u32; vertices + 1];
    for &v in corner_vertex {
        starts[v as usize + 1] += 1;
    }
    for v in 0..vertices {
        starts[v + 1] += starts[v];
    }
    let mut next = starts.clone();
    let mut corners = vec![0u32; corner_vertex.len()];
    for (q, &v) in corner_vertex.iter().enumerate() {
        corners[next[v as usize] as usize] = q as u32;
        next[v as usize] += 1;
    }
    (starts, corners)
}

impl Welding {
    /// The per-source solution at the welded vertices (each the area-weighted mean of its
    /// elements' values, source by source), vertex-major `v * k + m` like
    /// [`crate::Solution`]: what the hardware display interpolates per light
    /// ([`crate::gpu::GpuRelight::display`]). Direct and indirect apart.
    pub fn vertex_solution(
        &self,
        meshing: &Meshing,
        solution: &crate::Solution,
    ) -> (Vec<Vec3>, Vec<Vec3>) {
        let k = solution.k();
        let mut direct = vec![Vec3::ZERO; self.vertices * k];
        let mut indirect = vec![Vec3::ZERO; self.vertices * k];
        let mut weight = vec![0.0f32; self.vertices];
        for (j, e) in meshing.elements.iter().enumerate() {
            let w = vertex_weight(e);
            let s = solution.slot(meshing, j);
            for c in 0..3 {
                let v = self.corner_vertex[3 * j + c] as usize;
                for m in 0..k {
                    direct[v * k + m] += solution.direct[s * k + m] * w;
                    indirect[v * k + m] += solution.indirect[s * k + m] * w;
                }
                weight[v] += w;
            }
        }
        for (v, w) in weight.iter().enumerate() {
            let inv = if *w > 0.0 { 1.0 / *w } else { 0.0 };
            for m in 0..k {
                direct[v * k + m] *= inv;
                indirect[v * k + m] *= inv;
            }
        }
        (direct, indirect)
    }
}

/// An element's weight in the averages at its vertices: its area, or a millionth of it
/// when it is hidden ([`crate::mesh::Element::hidden`]), so that a vertex on the edge of a
/// box resting on the floor takes the open floor's value, and one with only hidden
/// elements still has one.
fn vertex_weight(e: &crate::mesh::Element) -> f32 {
    if e.hidden { e.area * 1e-6 } else { e.area }
}

/// How element values reach the pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// Interpolated between welded vertices (the default).
    #[default]
    Smooth,
    /// One value per element.
    Flat,
}

/// Direct light gathered per pixel, to be weighted per source.
#[derive(Clone, Copy, Debug)]
pub struct PixelDirect<'a> {
    /// Irradiance from each source at each pixel, pixel-major: `values[i * k + m]`
    /// ([`pixel_direct`]).
    pub values: &'a [Vec3],
    /// Each source's direct factor under the frame's light state.
    pub factors: &'a [Vec3],
}

/// The direct irradiance from every source of `gather` at every pixel of `g` (a G-buffer of
/// the meshing's element scene seen from `view`), averaged over `subpixels` stratified
/// points of the pixel's footprint (the pixel's sub-rays met with the plane of its surface:
/// through its surface point, normal to its element's corners,
/// [`DirectGather::plane_normal`]; a sub-ray nearly parallel to the plane keeps the centre
/// point), pixel-major (`i * k + m`); zero on background. The irradiance's cosine is the
/// G-buffer's (shading) normal. Deterministic: a pixel's sample pattern is seeded by its
/// index.
///
/// The footprint lies on the element's own plane, not on the plane of the shading normal:
/// where the two differ (the Cornell box's red wall is a non-planar quad whose second
/// triangle carries the first one's normal, 0.47 degrees off), points on the shading plane
/// sit behind the surface a few footprint widths out, their visibility rays meet their
/// own wall, and the wall came out 14-24 % dark in a band at 64 x 64 (issue 49).
pub fn pixel_direct<O: crate::visibility::Occlusion + ?Sized>(
    gather: &DirectGather,
    rays: &O,
    g: &GBuffer,
    view: &View,
    subpixels: u32,
) -> Vec<Vec3> {
    let k = gather.k();
    let (w, h) = (g.width, g.height);
    let mut out = vec![Vec3::ZERO; g.len() * k];
    if k == 0 {
        return out;
    }
    let subpixels = subpixels.max(1) as usize;
    let pixel = glam::Vec2::new(1.0 / w as f32, 1.0 / h as f32);
    let frustum = FrustumReconstruction::new(view);
    out.par_chunks_mut(k).enumerate().for_each_init(
        || Vec::with_capacity(subpixels),
        |points, (i, o)| {
            if g.is_background(i) {
                return;
            }
            let centre_uv = scene_core::view::pixel_uv(i as u32 % w, i as u32 / w, w, h);
            let centre = frustum.world(centre_uv, g.depth[i]);
            let n = g.normal[i];
            let plane = gather.plane_normal(g.triangle_id[i]).unwrap_or(n);
            let offset = r2(hash_seed(i as u64, 0xd1ec7, 0), glam::Vec2::ZERO);
            points.clear();
            points.push(centre);
            if subpixels > 1 {
                points.clear();
                for s in 0..subpixels {
                    let uv = centre_uv + (r2(s as u64, offset) - 0.5) * pixel;
                    points.push(on_pixel_plane(&frustum, uv, centre, plane).unwrap_or(centre));
                }
            }
            let quad = (subpixels > 1)
                .then(|| footprint_quad(&frustum, centre_uv, pixel, centre, plane))
                .flatten();
            gather.mean_over(rays, points, quad.as_ref().map(|q| &q[..]), n, i as u64, o);
        },
    );
    out
}

/// Which of `sources` holds each light of `set` (its slot in the per-pixel direct light),
/// `None` for a light no source holds.
pub fn light_slots(set: &LightSet, sources: &[crate::solver::Source]) -> Vec<Option<usize>> {
    set.lights
        .iter()
        .map(|l| sources.iter().position(|s| s.lights.contains(&l.id)))
        .collect()
}

/// Where the ray through image point `uv` of a view (`frustum`, its reconstruction, made
/// once a frame) meets the plane through `centre` with unit normal `n`: `None` when the
/// ray is within a cosine of 1e-3 of parallel to the plane or meets it behind its origin.
/// The ray is the line through the points [`View::reconstruct_world`] gives at linear
/// depths 0 and 1, as the GPU direct pass builds it from the same reconstruction.
pub fn on_pixel_plane(
    frustum: &FrustumReconstruction,
    uv: glam::Vec2,
    centre: Vec3,
    n: Vec3,
) -> Option<Vec3> {
    let o = frustum.world(uv, 0.0);
    let d = (frustum.world(uv, 1.0) - o).normalize_or_zero();
    let den = n.dot(d);
    let t = n.dot(centre - o) / den;
    (den.abs() > 1e-3 && t.is_finite() && t > 0.0).then(|| o + d * t)
}

/// A pixel's footprint on the plane of its surface point `centre` (unit normal `n`) as two
/// triangles: the pixel's corners (`uv` plus or minus half of `pixel`) met with the plane
/// ([`on_pixel_plane`]); `None` when a corner's ray grazes it. Shared by the per-pixel
/// gather and the shadow-map direct light (whose WGSL twin builds the same quad).
pub fn footprint_quad(
    frustum: &FrustumReconstruction,
    uv: glam::Vec2,
    pixel: glam::Vec2,
    centre: Vec3,
    n: Vec3,
) -> Option<[[Vec3; 3]; 2]> {
    match [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .map(|(a, b)| on_pixel_plane(frustum, uv + glam::Vec2::new(a, b) * pixel, centre, n))
    {
        [Some(a), Some(b), Some(c), Some(d)] => Some([[a, b, c], [a, c, d]]),
        _ => None,
    }
}

/// Largest [`DirectLight::ShadowMaps`] footprint grid (16 points a pixel).
///
/// [`DirectLight::ShadowMaps`]: crate::direct::DirectLight::ShadowMaps
pub const MAX_FOOTPRINT: u32 = 4;

/// The direct irradiance from every source at every pixel of `g` (a G-buffer seen from
/// `view`) from the shadow-mapped lights of `set` ([`DirectLight::ShadowMaps`]), averaged
/// over the pixel's footprint as a pixel of the reference is: `footprint` x `footprint`
/// points on a regular grid over the pixel, met with the plane through its surface point
/// ([`on_pixel_plane`]; a point whose ray grazes the plane keeps the centre): with
/// `planes` (per element of the G-buffer's triangle ids, [`crate::mesh::Element::plane_normal`])
/// the element's own plane, as the per-pixel gather's footprint, else the G-buffer
/// normal's. Each light's irradiance (its cosine at the G-buffer normal) times its shadow
/// factor (eq. 30 of the ISR thesis,
/// [`LightSet::light_irradiance`]) averaged over them. A point light with the
/// inverse-square falloff (and a footprint over 1 whose four corners meet the plane) is
/// integrated in closed form instead, as the per-pixel gather does: `I Omega / A` over the
/// footprint quad (cosines included, so a hot spot narrower than a pixel keeps its
/// energy), times a spot's attenuation towards the footprint's centre and the points' mean
/// shadow factor. Where a light's shadow factor at the pixel's centre and at the grid's
/// four corners is deep shadow ([`DEEP_SHADOW`]: all four texels of each PCF at least 69/c
/// of the extent behind their occluders), the light is taken as hidden from the whole
/// footprint (or where the centre is deep and the footprint lies within half a texel of
/// the light's map around it, `FOOTPRINT_IN_TEXEL`: a lamp behind a wall seen from afar
/// costs one lookup a pixel, not five or nine). (The centre alone
/// decided until 2026-12-03: a pixel whose centre lay just inside a shadow lost the lit
/// part of its footprint while the opposite pixel kept its shadowed part, so every shadow
/// edge was dark on one side. On the Breakfast Room's sun striped by the blind that made
/// the maps 3-5 % darker than the gather on two of three views, more the finer the map:
/// 1.6 % at 1 024 texels, 5.4 % at 8 192; with the corners +0.4 %, docs/relight-pr.md.)
/// (Taking a centre seen in full for the whole footprint too cost cornell 2 points of
/// error at the panel's shadow edges, past the 1.2x bound of `tests/reference.rs`.) A directional light that stands for a cone of directions (the
/// sky's, whose [`scene_core::shadowed_lights::Light::radius`] is their region's spread)
/// is looked up at the centre alone: in the sun-and-sky window room of `tests/tests/sky.rs`
/// (1 024 elements, 48 x 36) that read 0.171 off the reference where nine points read
/// 0.208 (the gather 0.164), and with soft lookups
/// ([`scene_core::shadowed_lights::ShadowSettings::penumbrae`]) 0.142 where nine read 0.168 (with an earlier filter), in half the
/// time; on the Breakfast Room the same error as nine points (0.07341 against 0.07350)
/// in 80.7 ms a new view instead of 104.5. Each light is added to its source's slot (`slots`, [`light_slots`]),
/// pixel-major (`i * k + m`), before the frame's factors; zero on background. The CPU twin
/// of relighting's GPU direct pass (`shaders/relight-pr/direct.wgsl`).
///
/// [`DirectLight::ShadowMaps`]: crate::direct::DirectLight::ShadowMaps
pub fn pixel_direct_shadowed(
    set: &LightSet,
    slots: &[Option<usize>],
    k: usize,
    g: &GBuffer,
    view: &View,
    footprint: u32,
    planes: Option<&[Vec3]>,
) -> Vec<Vec3> {
    let (w, h) = (g.width, g.height);
    let mut out = vec![Vec3::ZERO; g.len() * k];
    if k == 0 {
        return out;
    }
    let m = footprint.clamp(1, MAX_FOOTPRINT);
    let pixel = glam::Vec2::new(1.0 / w as f32, 1.0 / h as f32);
    let middle = (m > 1 && m % 2 == 1).then_some((m * m / 2) as usize);
    let band = (DIRECT_TILE * w) as usize;
    let frustum = FrustumReconstruction::new(view);
    // Bands of tile rows in parallel; in a band, tile by tile, and in a tile light by light,
    // so that one light's lookups from neighbouring pixels share the cache lines of its map
    // (a sky's 64 maps, 64 MB, read pixel by pixel went to memory for nearly every lookup).
    // Each pixel still adds its lights in their order: the same bits as pixel by pixel.
    out.par_chunks_mut(band * k).enumerate().for_each_init(
        Vec::new,
        |tile: &mut Vec<Footprint>, (by, o)| {
            let rows = o.len() / k / w as usize;
            for x0 in (0..w).step_by(DIRECT_TILE as usize) {
                tile.clear();
                for ly in 0..rows {
                    for x in x0..(x0 + DIRECT_TILE).min(w) {
                        let local = ly * w as usize + x as usize;
                        let i = by * band + local;
                        if !g.is_background(i) {
                            tile.push(Footprint::of(g, &frustum, i, local, m, pixel, planes));
                        }
                    }
                }
                for (j, slot) in slots.iter().enumerate() {
                    let Some(s) = slot.filter(|s| *s < k) else {
                        continue;
                    };
                    for f in tile.iter() {
                        if let Some(e) = f.light(set, j, middle) {
                            o[f.local * k + s] += e;
                        }
                    }
                }
                for f in tile.iter() {
                    for v in &mut o[f.local * k..f.local * k + k] {
                        if !v.is_finite() {
                            *v = Vec3::ZERO;
                        }
                    }
                }
            }
        },
    );
    out
}

/// A footprint whose points lie within this many texels of its centre (in the light's
/// map at the centre, [`scene_core::shadowed_lights::LightSet::light_texel`]) is deep in a
/// light's shadow wherever its centre is: the map resolves no edge inside it, and its
/// points' lookups read the texels around the centre's. A lamp behind a wall seen from
/// afar costs one lookup a pixel, not five (the corners, [`grid_corners`]).
const FOOTPRINT_IN_TEXEL: f32 = 0.5;

/// The indices of the four corner points of a square footprint grid of `count` points
/// (row-major; `count` a square, the grid of [`pixel_direct_shadowed`]). Twin: the corner
/// test of `shaders/relight-pr/direct.wgsl`.
fn grid_corners(count: usize) -> [usize; 4] {
    let m = count.isqrt().max(1);
    [0, m - 1, m * (m - 1), m * m - 1]
}

/// The side of the pixel tiles whose lights [`pixel_direct_shadowed`] takes one at a time.
const DIRECT_TILE: u32 = 8;

/// One pixel's footprint for the shadow-mapped direct light ([`pixel_direct_shadowed`]).
struct Footprint {
    /// The pixel's index in its band.
    local: usize,
    /// The surface point at the pixel's centre and its shading normal.
    c: Vec3,
    n: Vec3,
    /// The footprint's grid points on the element's plane (the centre where a point's ray
    /// grazes it; the odd grid's middle point is the centre itself).
    points: [Vec3; (MAX_FOOTPRINT * MAX_FOOTPRINT) as usize],
    count: usize,
    /// The footprint quad and its area (the closed form of inverse-square point lights).
    quad: Option<([[Vec3; 3]; 2], f32)>,
    /// The farthest of its grid's corners from the centre.
    reach: f32,
}

impl Footprint {
    /// Pixel `i` of `g` (`local` in its band) with an `m` x `m` grid.
    #[allow(clippy::too_many_arguments)]
    fn of(
        g: &GBuffer,
        frustum: &FrustumReconstruction,
        i: usize,
        local: usize,
        m: u32,
        pixel: glam::Vec2,
        planes: Option<&[Vec3]>,
    ) -> Self {
        let uv =
            scene_core::view::pixel_uv(i as u32 % g.width, i as u32 / g.width, g.width, g.height);
        let c = frustum.world(uv, g.depth[i]);
        let n = g.normal[i];
        // The footprint on the element's own plane, the cosines at its shading normal.
        let plane = planes
            .and_then(|p| p.get(g.triangle_id[i] as usize))
            .copied()
            .unwrap_or(n);
        let mut points = [c; (MAX_FOOTPRINT * MAX_FOOTPRINT) as usize];
        let mut count = 0;
        for sy in 0..m {
            for sx in 0..m {
                let at = |s: u32| (s as f32 + 0.5) / m as f32 - 0.5;
                let q = uv + glam::Vec2::new(at(sx), at(sy)) * pixel;
                // The middle of an odd grid is the centre itself (its lookup is the
                // deep-shadow test's, made once).
                points[count] = if m == 1 || (m % 2 == 1 && sx == m / 2 && sy == m / 2) {
                    c
                } else {
                    on_pixel_plane(frustum, q, c, plane).unwrap_or(c)
                };
                count += 1;
            }
        }
        // The footprint quad and its area, once a pixel (the closed form of every
        // inverse-square point light uses them).
        let quad = (m > 1)
            .then(|| footprint_quad(frustum, uv, pixel, c, plane))
            .flatten()
            .map(|tris| {
                let area: f32 = tris
                    .iter()
                    .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
                    .sum();
                (tris, area)
            });
        let reach = grid_corners(count)
            .iter()
            .map(|&q| (points[q] - c).length())
            .fold(0.0, f32::max);
        Self {
            local,
            c,
            n,
            points,
            count,
            quad,
            reach,
        }
    }

    /// Light `j` of `set` over this footprint (`middle`: the odd grid's middle point, whose
    /// lookup is the centre's); `None` where it adds nothing.
    fn light(&self, set: &LightSet, j: usize, middle: Option<usize>) -> Option<Vec3> {
        let (c, n, points) = (self.c, self.n, &self.points[..self.count]);
        let light = &set.lights[j];
        // A directional light that stands for a cone (the sky's directions): its lookup at
        // the centre alone (its penumbra, where the maps give one, is mostly wider than the
        // footprint).
        if light.kind == LightKind::Directional && light.radius > 0.0 {
            return Some(set.light_irradiance(j, c, n));
        }
        // One lookup at the centre; the footprint's points unless the centre and the
        // grid's four corners are deep in shadow (a footprint of one point is the centre
        // itself), the centre's lookup standing for the grid's middle point.
        let centre = (points.len() > 1).then(|| set.light_visibility(j, c, n));
        if centre.is_some_and(|v| v < DEEP_SHADOW)
            && (set
                .light_texel(j, c)
                .is_some_and(|t| self.reach < FOOTPRINT_IN_TEXEL * t)
                || grid_corners(points.len())
                    .iter()
                    .all(|&q| set.light_visibility(j, points[q], n) < DEEP_SHADOW))
        {
            return None;
        }
        let seen_at = |q: usize, p: Vec3| match (centre, middle) {
            (Some(v), Some(mid)) if q == mid => v,
            _ => set.light_visibility(j, p, n),
        };
        let inv = 1.0 / points.len() as f32;
        Some(match &self.quad {
            Some((tris, area)) if light.kind == LightKind::Point && light.radius == 0.0 => {
                let (to, area) = (light.position - c, *area);
                if n.dot(to) <= 0.0 || area.is_nan() || area <= 0.0 {
                    return None;
                }
                // The shadow first: a lamp behind a wall (most of a house's lamps from any
                // one room) costs its map's lookup, not the closed form.
                let seen: f32 = points.iter().enumerate().map(|(q, &p)| seen_at(q, p)).sum();
                if seen <= 0.0 {
                    return None;
                }
                let cone = light.spot.attenuation(-to.normalize_or_zero());
                if cone <= 0.0 {
                    return None;
                }
                let omega: f32 = tris.iter().map(|t| solid_angle(light.position, t)).sum();
                light.color * (omega / area * cone * (seen * inv))
            }
            _ => {
                points
                    .iter()
                    .enumerate()
                    .map(|(q, &p)| match light.irradiance(p, n) {
                        Vec3::ZERO => Vec3::ZERO,
                        e => e * seen_at(q, p),
                    })
                    .sum::<Vec3>()
                    * inv
            }
        })
    }
}

/// The image of `g` (a G-buffer of the element scene seen from `view`): see the module
/// documentation. `irradiance` is per solution element or per mesh element
/// ([`Meshing::slot`]); `glow` gives each shown mesh element's emission. With
/// [`Shading::Smooth`] each pixel interpolates its element's three welded vertices
/// ([`Welding::vertex_value`], computed for the pixels' own vertices where the frame has
/// fewer pixel corners than the scene has vertices, else [`Welding::vertex_values`] once:
/// the same bits). With `direct`, the element values must hold
/// the indirect light only, and each pixel adds its own direct light.
#[allow(clippy::too_many_arguments)]
pub fn compose(
    meshing: &Meshing,
    welding: &Welding,
    g: &GBuffer,
    view: &View,
    irradiance: &[Vec3],
    glow: &crate::relight::Glow<'_>,
    shading: Shading,
    direct: Option<PixelDirect<'_>>,
) -> Image {
    let (w, h) = (g.width, g.height);
    let frustum = FrustumReconstruction::new(view);
    // A pixel's three vertices are computed where it needs them, unless the frame has as
    // many pixel corners as the scene has vertices (a large image of a small mesh): then
    // once each, in one pass (the same bits either way).
    let all = (shading == Shading::Smooth && 3 * g.len() >= welding.vertices)
        .then(|| welding.vertex_values(meshing, irradiance));
    let vertex = |v: usize| match &all {
        Some(values) => values[v],
        None => welding.vertex_value(v, meshing, irradiance),
    };
    let pixels = (0..g.len())
        .into_par_iter()
        .map(|i| {
            let id = g.triangle_id[i] as usize;
            if g.is_background(i) || id >= meshing.elements.len() {
                return Vec3::ZERO;
            }
            let mut e = match shading {
                Shading::Flat => irradiance[meshing.slot(id, irradiance.len())],
                Shading::Smooth => {
                    let uv = scene_core::view::pixel_uv(i as u32 % w, i as u32 / w, w, h);
                    let p = frustum.world(uv, g.depth[i]);
                    let b = barycentric(&meshing.elements[id].corners, p);
                    (0..3)
                        .map(|c| {
                            let v = welding.corner_vertex[3 * id + c] as usize;
                            vertex(v) * b[c]
                        })
                        .sum()
                }
            };
            if let Some(d) = direct {
                let k = d.factors.len();
                for (v, f) in d.values[i * k..i * k + k].iter().zip(d.factors) {
                    e += *v * *f;
                }
            }
            let out = g.albedo[i].truncate() * e * std::f32::consts::FRAC_1_PI + glow.at(id);
            if out.is_finite() { out } else { Vec3::ZERO }
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// Barycentric coordinates of `p` (projected into the triangle's plane) in `t`, clamped
/// to the triangle and summing to 1.
pub fn barycentric(t: &[Vec3; 3], p: Vec3) -> [f32; 3] {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let den = d11 * d22 - d12 * d12;
    if den.is_nan() || den == 0.0 {
        return [1.0 / 3.0; 3];
    }
    let v = ((d22 * d1 - d12 * d2) / den).clamp(0.0, 1.0);
    let w = ((d11 * d2 - d12 * d1) / den).clamp(0.0, 1.0);
    let s = (v + w).max(1.0);
    let (v, w) = (v / s, w / s);
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;

    /// The per-vertex gather gives the bits of a scatter over the elements in their order
    /// (what the display computed before), with visibility splits and on two threads.
    #[test]
    fn vertex_values_equal_the_scatter_over_elements() {
        let scene = scene_core::builtin::scene("corridor").unwrap();
        let meshing = Meshing::new(&scene, &MeshSettings::elements(1024), 1).unwrap();
        let rays = RayScene::build(&scene);
        let welding = Welding::with_visibility(&meshing, scene.extent(), &rays);
        let n = meshing.elements.len();
        let values: Vec<Vec3> = (0..n)
            .map(|j| Vec3::new(j as f32 * 0.37 % 5.0, (j % 7) as f32, 1.0 / (j + 1) as f32))
            .collect();
        let mut sum = vec![Vec3::ZERO; welding.vertices];
        let mut weight = vec![0.0f32; welding.vertices];
        for (j, e) in meshing.elements.iter().enumerate() {
            let w = vertex_weight(e);
            for c in 0..3 {
                let v = welding.corner_vertex[3 * j + c] as usize;
                sum[v] += values[j] * w;
                weight[v] += w;
            }
        }
        let scatter: Vec<Vec3> = sum
            .iter()
            .zip(&weight)
            .map(|(s, w)| if *w > 0.0 { *s / *w } else { Vec3::ZERO })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let gathered = pool.install(|| welding.vertex_values(&meshing, &values));
        assert_eq!(gathered.len(), scatter.len());
        for (v, (a, b)) in gathered.iter().zip(&scatter).enumerate() {
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
                "vertex {v}"
            );
        }
        // The visibility splits gave some corners vertices of their own.
        assert!(welding.vertices > Welding::new(&meshing, scene.extent()).vertices);
    }

    /// Where a footprint is taken as hidden from a light (its centre deep in shadow, and
    /// its corners too or the footprint within half a texel of the map), the light its
    /// points would have received is a negligible part of the frame's direct light: in the
    /// building's rooms, where most lamps are behind walls, with cube maps coarser and finer
    /// than the footprints (16 and 256 texels a face), under 1e-4 of it (measured: 6.4e-5
    /// and 5.6e-5; with the centre alone deciding, 1.6e-2 at 16 texels).
    #[test]
    fn footprints_taken_as_hidden_lose_no_light() {
        use scene_core::gbuffer::{GBufferRenderer, RayCastRenderer, ViewTarget};
        use scene_core::shadowed_lights::ShadowSettings;
        let scene = scene_core::builtin::scene("building 2x1").unwrap();
        let meshing = Meshing::new(&scene, &MeshSettings::elements(1024), 1).unwrap();
        let elements = std::sync::Arc::new(meshing.element_scene(&scene));
        let mut raster = RayCastRenderer::new();
        raster.prepare(elements.clone()).unwrap();
        let view = View::from_camera(&elements.cameras[0]);
        let (w, h) = (48, 36);
        let g = raster
            .render_views(&[ViewTarget::new(view, w, h)])
            .unwrap()
            .remove(0);
        let frustum = FrustumReconstruction::new(&view);
        let planes = meshing.plane_normals();
        let pixel = glam::Vec2::new(1.0 / w as f32, 1.0 / h as f32);
        let mut hidden = 0;
        for cube in [16, 256] {
            let shadows = ShadowSettings {
                cube_resolution: cube,
                ..Default::default()
            };
            let set = LightSet::new(&scene, &shadows).unwrap();
            let (mut lost, mut total) = (0.0f64, 0.0f64);
            for i in (0..g.len()).filter(|&i| !g.is_background(i)) {
                let f = Footprint::of(&g, &frustum, i, i, 3, pixel, Some(&planes));
                for j in 0..set.lights.len() {
                    let light = &set.lights[j];
                    if light.kind == LightKind::Directional && light.radius > 0.0 {
                        continue;
                    }
                    if let Some(e) = f.light(&set, j, Some(4)) {
                        total += f64::from(e.element_sum());
                        continue;
                    }
                    if set.light_visibility(j, f.c, f.n) >= DEEP_SHADOW {
                        // Nothing added for another reason (facing away, outside a cone).
                        continue;
                    }
                    hidden += 1;
                    let points = &f.points[..f.count];
                    let missed: Vec3 = points
                        .iter()
                        .map(|&p| set.light_irradiance(j, p, f.n))
                        .sum::<Vec3>()
                        / points.len() as f32;
                    lost += f64::from(missed.element_sum());
                }
            }
            eprintln!("cube maps at {cube}: light lost {lost:.3e} of {total:.3e}");
            assert!(total > 0.0);
            assert!(
                lost <= 1e-4 * total,
                "cube maps at {cube}: hidden footprints would have received {lost:.3e}, \
                 {:.2e} of the frame's {total:.3e}",
                lost / total
            );
        }
        assert!(
            hidden > 1000,
            "only {hidden} hidden footprints: the test shows nothing"
        );
    }
}
