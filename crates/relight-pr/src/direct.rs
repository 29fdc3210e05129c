//! Direct light at a point, shared by the solver's first shots and the display's
//! per-pixel gather.
//!
//! The solver shoots point and directional lights analytically onto the elements' receiver
//! points (figure 2's first step, with ray-cast visibility); the same functions evaluated at
//! each pixel's reconstructed position give the direct light at full image resolution
//! ([`DirectLight::PerPixel`]). The solution keeps direct and indirect apart (section 2.4),
//! so the display can take the direct part per pixel and the indirect part from the
//! elements: the finite-element mesh then only carries the smooth, low-frequency light,
//! and shadow edges and hot spots are exact. This goes beyond the paper, whose display
//! interpolates the whole radiosity; `docs/relight-pr.md` measures both.

use glam::Vec3;
use scene_core::lights::{LightId, falloff};
use scene_core::{DirectionalLight, PointLight, Scene};

use crate::form_factor::point_to_triangle;
use crate::mesh::Meshing;
use crate::solver::Source;
pub use crate::visibility::{Occlusion, WithDynamic, sees_surface_point, segment_blocked};

/// How the display gets the direct light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectLight {
    /// From the elements, interpolated like the indirect light (the paper's display).
    Elements,
    /// Gathered at every pixel, averaged over `subpixels` stratified points of the pixel's
    /// footprint on its surface's plane (what a pixel of the reference averages; a point
    /// light's hot spot is narrower than a pixel). At each point: one shadow ray per point
    /// or directional light; for each emissive source, the closed-form form factor of each
    /// emitting patch times the visible fraction of `emitter_rays` rays shared among its
    /// patches (at least one each). Computed once per view; a relight at the same view
    /// only reweights.
    PerPixel {
        /// Points per pixel footprint.
        subpixels: u32,
        /// Visibility rays per footprint point for each emissive source.
        emitter_rays: u32,
    },
    /// Evaluated at every pixel of every frame from scene-core's shadow-mapped lights
    /// ([`scene_core::shadowed_lights`], the exponential shadow maps ISR's direct light
    /// uses), averaged over the pixel's footprint as the reference averages a pixel
    /// ([`crate::display::pixel_direct_shadowed`]): point, spot and directional lights and
    /// the sky's directions each have their map; an emissive source is `emitter_samples`
    /// point samples drawn by power over its triangles, each with a cube map. The maps are
    /// view-independent and built once; nothing is reused from one view to the next, so a
    /// moving camera costs what a still one does, on the CPU and on the GPU
    /// ([`crate::gpu::GpuRelight::encode_display_shadowed`]).
    ShadowMaps {
        /// Point samples standing in for the emissive triangles
        /// ([`scene_core::shadowed_lights::ShadowSettings::emitter_samples`]).
        emitter_samples: u32,
        /// Points per side of the grid over each pixel's footprint (1 to
        /// [`crate::display::MAX_FOOTPRINT`]; 1 evaluates the pixel's centre only).
        footprint: u32,
        /// Soft lookups for the sky's directions, each casting its region's penumbra
        /// ([`scene_core::shadowed_lights::ShadowSettings::penumbrae`]; off by default).
        penumbrae: bool,
    },
}

impl DirectLight {
    /// [`DirectLight::ShadowMaps`] with scene-core's default emitter samples and a 3 x 3
    /// footprint grid.
    pub fn shadow_maps() -> Self {
        DirectLight::ShadowMaps {
            emitter_samples: scene_core::shadowed_lights::ShadowSettings::default().emitter_samples,
            footprint: 3,
            penumbrae: false,
        }
    }

    /// [`DirectLight::shadow_maps`] with soft lookups for the sky's directions (each
    /// casting its region's penumbra).
    pub fn soft_shadow_maps() -> Self {
        match Self::shadow_maps() {
            DirectLight::ShadowMaps {
                emitter_samples,
                footprint,
                ..
            } => DirectLight::ShadowMaps {
                emitter_samples,
                footprint,
                penumbrae: true,
            },
            other => other,
        }
    }

    /// Whether the display adds a per-pixel direct light (the elements then carry the
    /// indirect light only).
    pub fn is_per_pixel(&self) -> bool {
        !matches!(self, DirectLight::Elements)
    }
}

impl Default for DirectLight {
    fn default() -> Self {
        DirectLight::PerPixel {
            subpixels: 8,
            emitter_rays: 4,
        }
    }
}

/// Irradiance at `x` (unit normal `n`) from point light `l`: `I cos / d^2` (or the windowed
/// falloff) times a spot's cone attenuation towards `x`, zero behind the surface or when
/// the segment to the light is blocked.
pub fn from_point<O: Occlusion + ?Sized>(l: &PointLight, rays: &O, x: Vec3, n: Vec3) -> Vec3 {
    let d = l.position - x;
    let dist = d.length();
    if dist.is_nan() || dist <= 0.0 {
        return Vec3::ZERO;
    }
    let w = d / dist;
    let cos = n.dot(w);
    if cos.is_nan() || cos <= 0.0 {
        return Vec3::ZERO;
    }
    let cone = l.attenuation(-w);
    if cone <= 0.0 {
        return Vec3::ZERO;
    }
    let eps = 1e-4 * dist.max(1e-6);
    if rays.occluded(x + n * eps, w, eps, dist - eps) {
        return Vec3::ZERO;
    }
    l.intensity * (falloff(l.radius, dist) * cos * cone)
}

/// `integral over t's solid angle of cone.attenuation`, seen from `p`: triangle `t` cut
/// `depth` times at its edges' midpoints (4^depth pieces), each piece's solid angle times
/// the attenuation towards its centroid.
fn cone_weighted_solid_angle(
    p: Vec3,
    t: &[Vec3; 3],
    cone: &scene_core::lights::SpotRamp,
    depth: u32,
) -> f32 {
    if depth == 0 {
        let c = (t[0] + t[1] + t[2]) / 3.0 - p;
        let w = c.normalize_or_zero();
        let a = cone.attenuation(w);
        return if a > 0.0 { solid_angle(p, t) * a } else { 0.0 };
    }
    let [a, b, c] = *t;
    let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        .iter()
        .map(|s| cone_weighted_solid_angle(p, s, cone, depth - 1))
        .sum()
}

/// The solid angle of triangle `t` seen from `p` (Van Oosterom and Strackee's formula),
/// in steradians; zero for a degenerate triangle or `p` in its plane.
pub fn solid_angle(p: Vec3, t: &[Vec3; 3]) -> f32 {
    // In f64, with the triple product `a . (b x c)` taken as `a . ((b - a) x (c - a))` (the
    // same determinant): from a point far from the triangle the corners' vectors are nearly
    // parallel and `b x c` cancels, and their lengths' product overflows f32 (a light at
    // 1e38 saw every element under pi / 2).
    let p = p.as_dvec3();
    let (a, b, c) = (
        t[0].as_dvec3() - p,
        t[1].as_dvec3() - p,
        t[2].as_dvec3() - p,
    );
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot((b - a).cross(c - a)).abs();
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    let omega = (2.0 * num.atan2(den)) as f32;
    if omega.is_finite() {
        omega.max(0.0)
    } else {
        0.0
    }
}

/// The mean irradiance over a planar surface piece (the triangles `piece`, unit normal
/// `n`, total area `area`) from point light `l`: for the inverse-square falloff, exactly
/// `I Omega / A` (the power an isotropic source sends through the piece's solid angle,
/// cosines included), times the fraction of `points` (on the piece) that see the light;
/// for a windowed falloff, the mean of [`from_point`] at `points`. The closed form keeps a
/// light a few millimetres from a wall from losing (or inventing) the energy of its hot
/// spot between sample points. For a spot the solid angle is weighted by the cone's
/// attenuation: the piece is cut into 64 triangles (three midpoint subdivisions), each
/// contributing its solid angle times the attenuation towards its centroid, so that a
/// cone's edge crossing a large element delivers the energy it should rather than what
/// four points guess. Used for elements (the solver's first shot) and for pixel
/// footprints (the display).
pub fn mean_from_point<O: Occlusion + ?Sized>(
    l: &PointLight,
    rays: &O,
    piece: &[[Vec3; 3]],
    n: Vec3,
    area: f32,
    points: &[Vec3],
) -> Vec3 {
    if points.is_empty() {
        return Vec3::ZERO;
    }
    if l.radius.is_some() {
        return points
            .iter()
            .map(|&x| from_point(l, rays, x, n))
            .sum::<Vec3>()
            / points.len() as f32;
    }
    let centre = piece[0].iter().sum::<Vec3>() / 3.0;
    if n.dot(l.position - centre) <= 0.0 || area.is_nan() || area <= 0.0 {
        return Vec3::ZERO;
    }
    let seen = points
        .iter()
        .filter(|&&x| {
            let d = l.position - x;
            let dist = d.length();
            let eps = 1e-4 * dist.max(1e-6);
            dist > 0.0 && !rays.occluded(x + n * eps, d / dist, eps, dist - eps)
        })
        .count();
    let omega: f32 = match &l.cone {
        None => piece.iter().map(|t| solid_angle(l.position, t)).sum(),
        Some(cone) => {
            let ramp = cone.ramp();
            piece
                .iter()
                .map(|t| cone_weighted_solid_angle(l.position, t, &ramp, 3))
                .sum()
        }
    };
    let e = l.intensity * (omega / area * seen as f32 / points.len() as f32);
    if e.is_finite() { e } else { Vec3::ZERO }
}

/// Irradiance at `x` (unit normal `n`) from directional light `l` in a scene of size
/// `extent`: `E cos`, zero when the ray towards the light hits anything.
pub fn from_directional<O: Occlusion + ?Sized>(
    l: &DirectionalLight,
    rays: &O,
    x: Vec3,
    n: Vec3,
    extent: f32,
) -> Vec3 {
    let w = -l.direction.normalize_or_zero();
    let cos = n.dot(w);
    if cos.is_nan() || cos <= 0.0 || w == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let eps = 1e-4 * extent;
    if rays.occluded(x + n * eps, w, eps, 4.0 * extent) {
        return Vec3::ZERO;
    }
    l.irradiance * cos
}

/// Irradiance at `x` (unit normal `n`) from the sky: one direction drawn within each of
/// its median-cut regions ([`scene_core::sky::Sky::sample_light`], numbers from `seed`),
/// each shadowed by a ray. Unbiased; its noise is that of stratified sampling with one
/// sample per region.
pub fn sky_at<O: Occlusion + ?Sized>(
    sky: &scene_core::sky::Sky,
    rays: &O,
    x: Vec3,
    n: Vec3,
    extent: f32,
    seed: u64,
) -> Vec3 {
    let eps = 1e-4 * extent;
    let mut e = Vec3::ZERO;
    for k in 0..sky.lights().len() {
        let mut rng = scene_core::sampling::Rng::new(seed, k as u64);
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let Some((w, weight)) = sky.sample_light(k, u) else {
            continue;
        };
        let cos = n.dot(w);
        if cos > 0.0 && !rays.occluded(x + n * eps, w, eps, 4.0 * extent) {
            e += weight * cos;
        }
    }
    e
}

/// The mean irradiance over element `e` from point light `l` (the solver's first shot):
/// [`mean_from_point`] over the element's triangle, visibility at its open receiver points
/// through `rays` (zero for a hidden element).
pub fn element_from_point<O: Occlusion + ?Sized>(
    l: &PointLight,
    rays: &O,
    e: &crate::mesh::Element,
) -> Vec3 {
    let (points, count) = e.open_receiver_points();
    let points: [Vec3; 4] = points.map(|(_, x)| x);
    mean_from_point(l, rays, &[e.corners], e.normal, e.area, &points[..count])
}

/// An element's mean irradiance from one analytic light of `scene` (a point or spot light,
/// a directional light, or the sky as its median-cut directions); zero for an emissive
/// mesh, whose light is shot by the solve. `extent` is the scene's ([`Scene::extent`]).
pub fn element_from_analytic<O: Occlusion + ?Sized>(
    scene: &Scene,
    id: LightId,
    rays: &O,
    e: &crate::mesh::Element,
    extent: f32,
) -> Vec3 {
    match id {
        LightId::Point(i) => element_from_point(&scene.point_lights[i as usize], rays, e),
        LightId::Directional(i) => {
            element_from_directional(&scene.directional_lights[i as usize], rays, e, extent)
        }
        // The fixed directions: drawing within their regions at the four receiver points
        // (`sky_at`) measured no better for the elements (0.260 against 0.257 in the window
        // room of tests/tests/sky.rs), only noisier.
        LightId::Sky => scene.sky.as_ref().map_or(Vec3::ZERO, |sky| {
            sky.lights()
                .iter()
                .map(|l| element_from_directional(l, rays, e, extent))
                .sum()
        }),
        LightId::Emissive(_) => Vec3::ZERO,
    }
}

/// The mean irradiance over element `e` from directional light `l` in a scene of size
/// `extent`: [`from_directional`] averaged over its open receiver points (zero for a
/// hidden element).
pub fn element_from_directional<O: Occlusion + ?Sized>(
    l: &DirectionalLight,
    rays: &O,
    e: &crate::mesh::Element,
    extent: f32,
) -> Vec3 {
    let (points, count) = e.open_receiver_points();
    points[..count]
        .iter()
        .map(|&(_, x)| from_directional(l, rays, x, e.normal, extent))
        .sum::<Vec3>()
        / count.max(1) as f32
}

/// One emitting patch: its triangle, the normal of its emitting side and its radiosity
/// (`pi` times its emitted radiance).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Emitter {
    corners: [Vec3; 3],
    normal: Vec3,
    radiosity: Vec3,
}

/// The direct light of every source of a solution, ready to be evaluated at any point.
#[derive(Clone, Debug)]
pub struct DirectGather {
    /// Per source: its point lights, directional lights and emitting patches.
    sources: Vec<(Vec<PointLight>, Vec<DirectionalLight>, Vec<Emitter>)>,
    /// The sky, for the source that holds it (its index): at each point one direction is
    /// drawn within each of its median-cut regions ([`scene_core::sky::Sky::sample_light`]),
    /// so its shadows are soft as the sky's are, not 64 sharp copies.
    sky: Option<(usize, scene_core::sky::Sky)>,
    /// Each element's geometric normal (the plane its corners span, turned to the side of
    /// its shading normal): the plane a pixel's footprint lies on
    /// ([`DirectGather::plane_normal`]).
    planes: Vec<Vec3>,
    extent: f32,
    samples: u32,
}

impl DirectGather {
    /// The direct light of `sources` in `scene` (emitters as `meshing`'s patches), with
    /// `samples` visibility rays per point for each emissive source (at least one per
    /// emitting patch).
    pub fn new(scene: &Scene, meshing: &Meshing, sources: &[Source], samples: u32) -> Self {
        let sky = scene.sky.as_ref().and_then(|sky| {
            let m = sources
                .iter()
                .position(|s| s.lights.contains(&LightId::Sky))?;
            Some((m, sky.clone()))
        });
        let sources = sources
            .iter()
            .map(|s| {
                let mut points = Vec::new();
                let mut suns = Vec::new();
                let mut emitters = Vec::new();
                for &id in &s.lights {
                    match id {
                        LightId::Point(i) => points.push(scene.point_lights[i as usize].clone()),
                        LightId::Directional(i) => {
                            suns.push(scene.directional_lights[i as usize].clone())
                        }
                        // Drawn per point in `mean_over`.
                        LightId::Sky => {}
                        LightId::Emissive(_) => {
                            for p in meshing.patches.iter().filter(|p| p.light == Some(id)) {
                                let e = meshing.elements[p.first_element as usize].emission;
                                emitters.push(Emitter {
                                    corners: p.corners,
                                    normal: p.normal,
                                    radiosity: e * std::f32::consts::PI,
                                });
                            }
                        }
                    }
                }
                (points, suns, emitters)
            })
            .collect();
        let planes = meshing.plane_normals();
        Self {
            sources,
            sky,
            planes,
            extent: scene.extent(),
            samples: samples.max(1),
        }
    }

    /// The plane normal of element `element` of the meshing (a triangle id of its element
    /// scene, [`crate::Meshing::element_scene`]): its corners' plane, which the shading
    /// normal the element scene's G-buffer holds tilts away from where the scene's normals
    /// are not the faces' (a non-planar quad such as the Cornell box's red wall, a smooth
    /// mesh). `None` for an id that names no element (the background).
    pub fn plane_normal(&self, element: u32) -> Option<Vec3> {
        self.planes.get(element as usize).copied()
    }

    /// Number of sources.
    pub fn k(&self) -> usize {
        self.sources.len()
    }

    /// The mean irradiance from each source over a surface piece with unit normal `n`,
    /// written to `out` (length k): `points` are stratified points on the piece, and
    /// `piece`, when given, its exact outline as triangles (point lights then use
    /// [`mean_from_point`]'s closed form). `seed` fixes the sample pattern on the emitters.
    pub fn mean_over<O: Occlusion + ?Sized>(
        &self,
        rays: &O,
        points: &[Vec3],
        piece: Option<&[[Vec3; 3]]>,
        n: Vec3,
        seed: u64,
        out: &mut [Vec3],
    ) {
        // Off the surface by the reconstruction's rounding, relative to the scene.
        let lift = n * (2e-5 * self.extent);
        let inv = 1.0 / points.len().max(1) as f32;
        for (m, (lights, suns, emitters)) in self.sources.iter().enumerate() {
            let mut e = Vec3::ZERO;
            for l in lights {
                e += match piece {
                    Some(piece) => {
                        let area: f32 = piece
                            .iter()
                            .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
                            .sum();
                        let lifted: Vec<[Vec3; 3]> =
                            piece.iter().map(|t| t.map(|c| c + lift)).collect();
                        let at: Vec<Vec3> = points.iter().map(|&x| x + lift).collect();
                        mean_from_point(l, rays, &lifted, n, area, &at)
                    }
                    None => {
                        points
                            .iter()
                            .map(|&x| from_point(l, rays, x + lift, n))
                            .sum::<Vec3>()
                            * inv
                    }
                };
            }
            for (s, &x) in points.iter().enumerate() {
                let x = x + lift;
                for l in suns {
                    e += from_directional(l, rays, x, n, self.extent) * inv;
                }
                if let Some((_, sky)) = self.sky.as_ref().filter(|(k, _)| *k == m) {
                    e += sky_at(sky, rays, x, n, self.extent, seed ^ ((s as u64) << 40)) * inv;
                }
                if !emitters.is_empty() {
                    let per = (self.samples as usize).div_ceil(emitters.len()) as u32;
                    for (q, em) in emitters.iter().enumerate() {
                        let f = point_to_triangle(
                            x,
                            n,
                            &em.corners,
                            em.normal,
                            Some(rays),
                            per,
                            seed.wrapping_mul(0x9e37_79b9_7f4a_7c15)
                                ^ ((s as u64) << 32)
                                ^ q as u64,
                        );
                        e += em.radiosity * (f * inv);
                    }
                }
            }
            out[m] = if e.is_finite() { e } else { Vec3::ZERO };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solid angle of a triangle seen along its normal from distance `d` tends to
    /// `A / d^2`; from a light near f32's limit it is (nearly) zero, never the pi / 2 that
    /// overflowing f32 products gave.
    #[test]
    fn solid_angles_from_far_away_fall_as_the_inverse_square() {
        let t = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let centroid = (t[0] + t[1] + t[2]) / 3.0;
        for d in [100.0f32, 1e3, 1e6, 1e12, 1e18] {
            let omega = solid_angle(centroid + Vec3::Z * d, &t);
            let expected = 0.5 / (d * d);
            assert!(
                ((omega - expected) / expected).abs() < 1e-3,
                "from {d:e}: {omega:e} against {expected:e}"
            );
        }
        for far in [1e30f32, 1e38, f32::MAX] {
            for p in [
                Vec3::splat(far),
                Vec3::new(far, 0.0, 1.0),
                -Vec3::splat(far),
            ] {
                let omega = solid_angle(p, &t);
                assert!((0.0..1e-30).contains(&omega), "from {p}: {omega:e}");
            }
        }
        // Close above the centroid: nearly the whole hemisphere.
        let near = solid_angle(centroid + Vec3::Z * 1e-6, &t);
        assert!((near - std::f32::consts::TAU).abs() < 1e-3, "{near}");
    }
}
