//! Light-space senders (issue 50): the surfaces each light reaches first, seen from the
//! light, so that directly lit surfaces off screen, behind the camera or outside a pixel's
//! screen-space disk send their one bounce too. They are reflective shadow maps (Dachsbacher
//! and Stamminger 2005, "Reflective shadow maps"): one ray per texel of a map placed as the
//! light's shadow map is (an orthographic square over the scene for a directional light, a
//! cube around a point light or an emitter sample), its first hit keeping position, normal
//! and reflected power.
//!
//! **A sender.** A texel whose ray leaves the light with a perpendicular footprint
//! `A_perp` (orthographic: the texel's area; cube: `t^2 dw`, `dw` the texel's solid angle
//! `(2/res)^2 / |d|^3` for the unnormalised face direction `d`) lands on a surface of albedo
//! `rho` at angle `theta` to its normal. The surface patch it stands for has area
//! `A = A_perp / cos(theta)` and receives the light's unshadowed irradiance `E` (the light
//! set's own light model: [`Light::irradiance`](crate::Light::irradiance)); it reflects the
//! power `rho E A` (`cos(theta)` cancels: `rho E_perp A_perp`), a Lambertian disk of
//! radiance `L = rho E / pi`.
//!
//! **Directional lights share a map.** A sun and a sky's directions (scene-core turns a sky
//! into 64 of them) share one orthographic grid, sized by their joint power: each texel
//! takes one of them, drawn in proportion to its power by a low-discrepancy number (a
//! rank-1 lattice over the texel grid with the R2 sequence's generator), and its power is
//! divided by that probability, an
//! unbiased stand-in for all of them. Maps of their own would give each of a sky's 64
//! directions a sixty-fourth of the resolution (2x2 texels at 256 senders), too coarse to
//! find a window.
//!
//! **Gathering** (the screen-space senders' disk form factor, eq. 25 in its `Patch` form,
//! [`crate::Estimator::Patch`]): a receiver at `P` with normal `n_P` gets
//! `rho_P sum_s L_s cos_P cos_s A_s / (pi r^2 + A_s)` from the senders in front of it and
//! facing it, times each sender's light's frame factor
//! ([`Light::indirect`](crate::Light::indirect)). As for the screen-space senders there is
//! no visibility test between sender and receiver (unless
//! [`IsrSettings::light_sender_shadows`](crate::IsrSettings::light_sender_shadows) asks for
//! one ray per receiver and sender).
//!
//! **Visibility** (imperfect shadow maps, Ritschel et al. 2008, made exact for the few
//! directions they hold): each sender keeps a small depth map of the hemisphere over its
//! surface, [`DEPTH_RES`]^2 texels in a paraboloid projection (a direction `w` of local
//! coordinates `(x, y, z)`, `z` along the normal, lands at `(x, y) / (1 + z)` in the unit
//! disk), each texel the distance a ray from the sender travels before it hits the scene,
//! traced once when the senders are made. A receiver at `p` with normal `n_p`, in direction
//! `w` from the sender, is seen through a texel whose first hit (the sender's position plus
//! the texel's centre direction times its depth) is not in front of the receiver's tangent
//! plane, `(hit - p) . n_p <= 0.02 r`: the receiver's own surface and anything beyond it
//! pass, an occluder between them does not. Bilinearly weighted over the four texels
//! around `w` (percentage-closer filtering), so that walls between a sender and a receiver
//! stop its light: senders outside a room no longer light its inside. (A depth test with a
//! slope-scaled slack, `r (1 - slack) <= depth`, is what shadow maps do; a slack wide
//! enough for a receiver's own surface seen at a slant let light through a blind's slats
//! and the furniture of a room, +11 points over the Breakfast Room's lit surfaces against
//! exact rays, where this plane test reads as exact rays do.) One lookup
//! per receiver and sender, on the CPU and the GPU alike; [`LightSenders::visibility`] off
//! leaves it out (for measurements), and `shadowed` in [`LightSenders::gather`] casts an
//! exact ray instead.
//!
//! **Interleaved** (as the screen-space samples' 16 rotations are): each sender belongs to one
//! of 16 phases, by its texel's place in a 4x4 Bayer tile of its map (offset per light and
//! cube face, so that small maps spread over the phases too), and a coarse pixel at `(x, y)`
//! gathers only the senders of phase `(y mod 4) * 4 + x mod 4`, each weighted 16. Every
//! sender is thus counted, with its full weight, by one pixel in 16 of every 4x4 block, and
//! the blur that follows (a Gaussian of sigma 2 coarse pixels by default, which leaves under
//! 1 % of a pattern of period 4) averages the 16: a frame gathers a sixteenth of the
//! senders per pixel. [`LightSenders::interleaved`] off gathers every sender at every pixel
//! (for measurements).
//!
//! **Counted once.** A surface the camera sees inside the receiver's screen-space disk is
//! already a screen-space sender of that receiver, so a light-space sender is skipped for
//! that receiver when it is visible in the coarse G-buffer (its depth within 2 % of the
//! pixel's, normals within 60 degrees) and its pixel's centre lies in the receiver's disk
//! (`radiosity::Receiver::disk_holds`). Everything else (off screen, hidden, outside the
//! disk) comes from the light-space senders alone.
//!
//! **Further bounces** ([`LightSenders::with_bounces`], instant radiosity's light paths,
//! Keller 1997, started from the reflective shadow maps' points): as many paths as the
//! budget, each starting at a first sender drawn in proportion to its power (stratified
//! over the paths) and carrying `total / paths` of the first senders' power, continue by
//! cosine-distributed rays; at each surface a ray hits, a sender of the next bounce gets
//! `rho` times the carried power, its path's light (so a light's frame factor still scales
//! all of its light) and its bounce number; Russian roulette on the albedo (survival
//! `max(rho)`, at most 0.95, the power divided by it) or the bounce limit ends the path.
//! Their disks stand for the scene's surface (at most its bounds' box) shared by the paths,
//! the form factor's guard against `1/r^2`. The screen-space senders send direct light
//! only, so these senders are never left out for them ("counted once" applies to bounce 1
//! alone). Each path draws from its own random stream: the same senders whatever the
//! thread count.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use scene_core::ray::{Hit, RayQuery, RayScene, SurfacePoint, surface_at};
use scene_core::reference::Bounces;
use scene_core::reference::GpuPathTracer;
use scene_core::sampling::{Rng, cosine_hemisphere, mix64};
use scene_core::{GBuffer, Scene, View};

use crate::IsrError;
use crate::geometry::Screen;
use crate::light_set::esm::cube_direction;
use crate::light_set::{LightKind, LightSet};
use crate::radiosity::{BAYER4, Receiver};

/// The most light-space senders a light set may be asked for.
pub const MAX_LIGHT_SENDERS: u32 = 1 << 16;

/// Texels per side of each sender's visibility map (module docs).
pub const DEPTH_RES: u32 = 16;

/// The plane test's tolerance (module docs), as a share of the sender-receiver distance
/// `r`: a texel's first hit at most `PLANE_TOLERANCE r` in front of the receiver's tangent
/// plane counts as the receiver's own surface (or beyond it).
pub const PLANE_TOLERANCE: f32 = 0.02;

/// The local direction (`z` along the normal) through the centre of texel `(x, y)` of a
/// [`DEPTH_RES`]-sided paraboloid map; centres outside the unit disk are moved onto it
/// (just above the horizon).
fn map_direction(x: u32, y: u32) -> Vec3 {
    let n = DEPTH_RES as f32;
    let mut uv = Vec2::new(
        (x as f32 + 0.5) / n * 2.0 - 1.0,
        (y as f32 + 0.5) / n * 2.0 - 1.0,
    );
    let q = uv.length_squared();
    if q > 0.998 {
        uv *= (0.998 / q).sqrt();
    }
    let q = uv.length_squared();
    let z = (1.0 - q) / (1.0 + q);
    (uv * (1.0 + z)).extend(z)
}

/// [`map_direction`] of every texel, row by row (made once).
fn map_directions() -> &'static [Vec3] {
    static DIRECTIONS: std::sync::OnceLock<Vec<Vec3>> = std::sync::OnceLock::new();
    DIRECTIONS.get_or_init(|| {
        (0..DEPTH_RES * DEPTH_RES)
            .map(|k| map_direction(k % DEPTH_RES, k / DEPTH_RES))
            .collect()
    })
}

/// The visibility (0 to 1) of a receiver in unit direction `w` at distance `r` from a sender
/// with frame `(t, b, n)` and visibility map `depths`, the receiver's unit normal `n_p` at
/// cosine `cos_p` to `-w` (module docs): over the four texels around `w`, bilinearly
/// weighted, the share whose first hit is not in front of the receiver's tangent plane (by
/// more than [`PLANE_TOLERANCE`] `r`), or left the scene.
pub fn map_visibility(
    depths: &[f32],
    (t, b, n): (Vec3, Vec3, Vec3),
    w: Vec3,
    r: f32,
    n_p: Vec3,
    cos_p: f32,
) -> f32 {
    let z = n.dot(w).max(0.0);
    let uv = Vec2::new(t.dot(w), b.dot(w)) / (1.0 + z);
    let res = DEPTH_RES as f32;
    let f = (uv * 0.5 + 0.5) * res - 0.5;
    let base = f.floor();
    let a = f - base;
    // (hit - p) . n_p = (sender - p) . n_p + depth (l . (t, b, n) . n_p), `l` the texel's
    // local direction and (sender - p) . n_p = r cos_p: the frame's axes against the
    // receiver's normal are found once.
    let tolerance = r * (PLANE_TOLERANCE - cos_p);
    let axes = Vec3::new(t.dot(n_p), b.dot(n_p), n.dot(n_p));
    let directions = map_directions();
    let mut seen = 0.0;
    for (dx, dy, weight) in [
        (0, 0, (1.0 - a.x) * (1.0 - a.y)),
        (1, 0, a.x * (1.0 - a.y)),
        (0, 1, (1.0 - a.x) * a.y),
        (1, 1, a.x * a.y),
    ] {
        let x = (base.x as i32 + dx).clamp(0, DEPTH_RES as i32 - 1) as u32;
        let y = (base.y as i32 + dy).clamp(0, DEPTH_RES as i32 - 1) as u32;
        let k = (y * DEPTH_RES + x) as usize;
        let depth = depths[k];
        if depth >= f32::MAX || depth * directions[k].dot(axes) <= tolerance {
            seen += weight;
        }
    }
    seen
}

/// Phases of the interleaved gather (module docs): a 4x4 tile of coarse pixels.
pub const PHASES: usize = 16;

/// The phase of texel `(x, y)` of face `face` of light `light`'s map: its place in the 4x4
/// Bayer matrix that also orders the screen-space samples' rotations.
fn phase_of(light: usize, face: u32, x: u32, y: u32) -> u32 {
    (BAYER4[((y % 4) * 4 + x % 4) as usize] + 5 * light as u32 + 3 * face) % PHASES as u32
}

/// The phase a coarse pixel `(x, y)` gathers.
pub fn pixel_phase(x: u32, y: u32) -> usize {
    ((y % 4) * 4 + x % 4) as usize
}

/// One light-space sender: a surface patch a light reaches first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSender {
    /// Where the light's ray hit.
    pub position: Vec3,
    /// Unit shading normal on the lit side.
    pub normal: Vec3,
    /// Reflected power `rho E A` before the frame's factor on its light.
    pub power: Vec3,
    /// The patch's area `A`.
    pub area: f32,
    /// Index of its light in [`LightSet::lights`].
    pub light: u32,
    /// A unit tangent: the visibility map's `x` axis (`y` is `normal x tangent`).
    pub tangent: Vec3,
    /// The bounce this sender's light makes at a receiver: 1 for a surface its light reaches
    /// first, `k` for the end of a light path of `k - 1` reflections from such a surface
    /// (module docs, "Further bounces").
    pub bounce: u32,
}

impl LightSender {
    /// A sender on the surface point `s` (its position and shading normal, a tangent of
    /// that normal for its visibility map).
    fn on(s: &SurfacePoint, power: Vec3, area: f32, light: u32, bounce: u32) -> Self {
        Self {
            position: s.p,
            normal: s.ns,
            power,
            area,
            light,
            tangent: s.ns.any_orthonormal_vector(),
            bounce,
        }
    }
}

/// One light-space sender in the GPU layout (`LightSender` in
/// `shaders/isr/light_senders.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLightSender {
    /// Position; `w`: the patch's area.
    pub position_area: [f32; 4],
    /// Unit normal; `w`: the light's index, its bits.
    pub normal_light: [f32; 4],
    /// Reflected power before the frame's factor; `w` unused.
    pub power: [f32; 4],
    /// The visibility map's tangent; `w`: the sender's bounce ([`LightSender::bounce`]), as
    /// a float.
    pub tangent: [f32; 4],
}

/// Where [`LightSenders::traced`] traces the senders' rays: the first hits from the
/// lights, the further bounces' paths (in waves, one ray per path and wave) and the
/// visibility maps (most of the rays: [`DEPTH_RES`]^2 per sender).
#[derive(Clone, Copy, Debug)]
pub enum SenderRays<'a> {
    /// scene-core's CPU ray-query tree of the scene ([`RayScene::build`]).
    Cpu(&'a RayScene),
    /// The GPU path tracer's tree of the same scene
    /// ([`GpuPathTracer::closest_hits`]): the host's device traverses it, and the hits are
    /// read back, in batches, to be shaded and kept on the CPU as [`Cpu`](SenderRays::Cpu)
    /// keeps them. The senders equal the CPU's but where the two traversals' rounding
    /// differs at an edge.
    Gpu(&'a GpuPathTracer),
}

impl SenderRays<'_> {
    /// The closest hit of each ray, in order.
    fn closest_hits(&self, rays: &[RayQuery]) -> Result<Vec<Option<Hit>>, IsrError> {
        match self {
            SenderRays::Cpu(tree) => Ok(tree.closest_hits(rays)),
            SenderRays::Gpu(tracer) => Ok(tracer.closest_hits(rays)?),
        }
    }
}

/// The light-space senders of a scene's lights (module docs).
#[derive(Clone, Debug)]
pub struct LightSenders {
    /// Every sender, phase by phase (module docs), within a phase light by light, texel by
    /// texel.
    pub senders: Vec<LightSender>,
    /// Where each phase's senders begin in `senders` (and, last, their count).
    pub phase_offsets: [u32; PHASES + 1],
    /// Whether each coarse pixel gathers only its phase's senders, weighted 16 (true, the
    /// default), or every sender (module docs).
    pub interleaved: bool,
    /// Each sender's visibility map, [`DEPTH_RES`]^2 distances row by row, in the order of
    /// `senders` (module docs); a ray that leaves the scene keeps `f32::MAX`.
    pub depths: Vec<f32>,
    /// Whether the gather weighs each sender's light by its visibility map (true, the
    /// default) or counts every sender in front of a receiver as seen (module docs).
    pub visibility: bool,
    /// Texels per side of each light's map (per face for cubes), by light; the directional
    /// lights share one map (module docs), each listed with its side.
    pub resolutions: Vec<u32>,
    /// Leave out, per receiver, the senders its screen-space samples already see (true,
    /// the default). False counts those surfaces twice: for tests and measurements only.
    pub once: bool,
    /// The scene's triangles, for [`IsrSettings::light_sender_shadows`](crate::IsrSettings::light_sender_shadows).
    rays: Option<Arc<RayScene>>,
}

impl PartialEq for LightSenders {
    /// The same senders, maps and counting (the ray-query tree is the scene's either way).
    fn eq(&self, other: &Self) -> bool {
        self.senders == other.senders
            && self.phase_offsets == other.phase_offsets
            && self.interleaved == other.interleaved
            && self.depths == other.depths
            && self.visibility == other.visibility
            && self.resolutions == other.resolutions
            && self.once == other.once
    }
}

impl Default for LightSenders {
    fn default() -> Self {
        Self {
            senders: Vec::new(),
            phase_offsets: [0; PHASES + 1],
            interleaved: true,
            depths: Vec::new(),
            visibility: true,
            resolutions: Vec::new(),
            once: true,
            rays: None,
        }
    }
}

impl LightSenders {
    /// About `budget` senders over `lights`' lights (each light a share of texels in
    /// proportion to the power it sends into the scene, at least 2x2 per map or face; the
    /// directional lights share one map, each texel one of them drawn by power),
    /// traced against `scene` (the scene the light set was made from). Rays that leave the scene, and hits on degenerate triangles, make no
    /// sender.
    ///
    /// Errors when `budget` is above [`MAX_LIGHT_SENDERS`].
    pub fn new(scene: &Scene, lights: &LightSet, budget: u32) -> Result<Self, IsrError> {
        Self::with_bounces(scene, lights, budget, Bounces::Limited(1))
    }

    /// [`LightSenders::new`] with the light of `bounces` bounces (module docs, "Further
    /// bounces"): `Limited(1)` (or 0) makes the first senders alone, as `new` does; `Limited(k)`
    /// adds the ends of light paths of up to `k - 1` further reflections, `Unlimited` paths
    /// that Russian roulette ends (at most [`MAX_PATH_BOUNCES`] bounces). About `budget`
    /// paths are traced for them.
    pub fn with_bounces(
        scene: &Scene,
        lights: &LightSet,
        budget: u32,
        bounces: Bounces,
    ) -> Result<Self, IsrError> {
        Self::with_rays(scene, None, lights, budget, bounces)
    }

    /// [`LightSenders::with_bounces`] traced through `rays`, the ray-query tree of `scene`
    /// ([`RayScene::build`]) when the caller has one (the light set's, as
    /// [`crate::IsrTechnique`] shares it); `None` builds it.
    pub fn with_rays(
        scene: &Scene,
        rays: Option<Arc<RayScene>>,
        lights: &LightSet,
        budget: u32,
        bounces: Bounces,
    ) -> Result<Self, IsrError> {
        if nothing_to_trace(scene, lights, budget) {
            // Checks the budget and makes no tree.
            return Self::traced(scene, None, lights, budget, bounces);
        }
        let rays = rays.unwrap_or_else(|| Arc::new(RayScene::build(scene)));
        let mut senders =
            Self::traced(scene, Some(SenderRays::Cpu(&rays)), lights, budget, bounces)?;
        senders.rays = Some(rays);
        Ok(senders)
    }

    /// [`LightSenders::with_bounces`] with its rays traced on the GPU by `tracer`, the
    /// [`GpuPathTracer`] of `scene` (any light state: only its tree and shading data are
    /// read): for a host that remakes the senders when a light moves and holds the scene
    /// on its device. The senders equal [`LightSenders::with_bounces`]' but where the GPU's
    /// traversal rounds an edge differently; they carry no CPU tree, so a frame that asks
    /// for [`IsrSettings::light_sender_shadows`](crate::IsrSettings::light_sender_shadows)
    /// with them is refused.
    pub fn on_gpu(
        scene: &Scene,
        tracer: &GpuPathTracer,
        lights: &LightSet,
        budget: u32,
        bounces: Bounces,
    ) -> Result<Self, IsrError> {
        Self::traced(
            scene,
            Some(SenderRays::Gpu(tracer)),
            lights,
            budget,
            bounces,
        )
    }

    /// The senders of `budget` (module docs) with their rays traced by `rays` (`None`
    /// only where there is nothing to trace: no budget, light or triangle).
    pub fn traced(
        scene: &Scene,
        rays: Option<SenderRays<'_>>,
        lights: &LightSet,
        budget: u32,
        bounces: Bounces,
    ) -> Result<Self, IsrError> {
        if budget > MAX_LIGHT_SENDERS {
            return Err(IsrError::InvalidSetting {
                name: "light_senders",
                value: budget.to_string(),
                reason: format!("at most {MAX_LIGHT_SENDERS}"),
            });
        }
        if nothing_to_trace(scene, lights, budget) {
            return Ok(Self::default());
        }
        let Some(rays) = rays else {
            return Err(IsrError::InvalidSetting {
                name: "light_senders",
                value: budget.to_string(),
                reason: "senders of a lit scene need a ray-query tree to trace them".into(),
            });
        };
        let offsets = scene.mesh_offsets();
        let center = lights.bounds.center();
        // Half the bounds' diagonal: a square of twice this side covers the scene from any
        // direction.
        let reach = (0.5 * (lights.bounds.max - lights.bounds.min).length()).max(1e-6);
        // Each light's share of the budget follows the power it sends into the scene.
        let power: Vec<f64> = lights
            .lights
            .iter()
            .map(|l| {
                let c = f64::from(l.color.element_sum().max(0.0));
                match l.kind {
                    LightKind::Directional => c * f64::from(2.0 * reach).powi(2),
                    LightKind::Point => c * 4.0 * std::f64::consts::PI,
                    LightKind::EmitterSample => c * std::f64::consts::PI * f64::from(l.area),
                }
            })
            .collect();
        let total: f64 = power.iter().sum();
        let share = |p: f64| {
            if total > 0.0 && total.is_finite() {
                p / total
            } else {
                1.0 / lights.lights.len() as f64
            }
        };
        let eps = 1e-4 * lights.extent;
        // Every texel to trace: origin, direction, footprint (an area, or a solid angle for
        // cubes), phase, light, and the weight of its light's choice (1 / its probability).
        let mut texels: Vec<(Vec3, Vec3, f32, u32, usize, f32)> = Vec::new();
        let mut resolutions = vec![0; lights.lights.len()];
        // The directional lights (a sun, a sky's directions) share one grid over the scene:
        // each texel takes one of them, chosen in proportion to its power by a
        // low-discrepancy number, and stands for it weighted by the inverse of that choice's
        // probability. A sky's 64 directions then share the grid's whole resolution, where
        // maps of their own would each get a 64th of it.
        let directional: Vec<usize> = (0..lights.lights.len())
            .filter(|&i| lights.lights[i].kind == LightKind::Directional)
            .collect();
        if !directional.is_empty() {
            let group: f64 = directional.iter().map(|&i| power[i]).sum();
            let res = ((f64::from(budget) * share(group)).sqrt().floor() as u32).max(2);
            // The choice: a cumulative distribution over the group's powers (uniform when
            // they carry none).
            let weights: Vec<f64> = if group > 0.0 && group.is_finite() {
                directional.iter().map(|&i| power[i] / group).collect()
            } else {
                vec![1.0 / directional.len() as f64; directional.len()]
            };
            let cdf: Vec<f64> = weights
                .iter()
                .scan(0.0, |acc, w| {
                    *acc += w;
                    Some(*acc)
                })
                .collect();
            let side = 2.0 * reach / res as f32;
            for k in 0..res * res {
                let (x, y) = (k % res, k / res);
                // The texel's light, through the CDF: a rank-1 lattice over the texel grid
                // with the R2 sequence's generator (scene-core's `sampling::r2` indexes
                // texels in a row instead; measured in the sky-lit room of
                // tests/tests/sky.rs at 1 024 senders, 0.623 / 0.652 off the reference
                // under a uniform / one-pixel sky against this lattice's 0.599 / 0.626).
                let u = (0.5
                    + 0.754_877_666_246_692_7 * f64::from(x)
                    + 0.569_840_290_998_053_2 * f64::from(y))
                .fract();
                let pick = cdf.partition_point(|&c| c <= u).min(directional.len() - 1);
                if weights[pick] <= 0.0 {
                    continue;
                }
                let index = directional[pick];
                let d = lights.lights[index].direction;
                let right = d.any_orthonormal_vector();
                let up = d.cross(right);
                let sx = -reach + side * (x as f32 + 0.5);
                let sy = -reach + side * (y as f32 + 0.5);
                texels.push((
                    center - d * (2.0 * reach) + right * sx + up * sy,
                    d,
                    side * side,
                    phase_of(0, 0, x, y),
                    index,
                    (1.0 / weights[pick]) as f32,
                ));
            }
            for &i in &directional {
                resolutions[i] = res;
            }
        }
        for (index, light) in lights.lights.iter().enumerate() {
            if light.kind == LightKind::Directional {
                continue;
            }
            let res = ((f64::from(budget) * share(power[index]) / 6.0)
                .sqrt()
                .floor() as u32)
                .max(2);
            resolutions[index] = res;
            let texel = 2.0 / res as f32;
            for k in 0..6 * res * res {
                let face = (k / (res * res)) as usize;
                let (x, y) = (k % res, (k / res) % res);
                let uv = Vec2::new((x as f32 + 0.5) / res as f32, (y as f32 + 0.5) / res as f32);
                let raw = cube_direction(face, uv);
                let len = raw.length();
                let d = raw / len;
                let mut o = light.position;
                if light.kind == LightKind::EmitterSample {
                    // One-sided: only the emitting side, leaving from just above it.
                    if d.dot(light.direction) <= 0.0 {
                        continue;
                    }
                    o += light.direction * eps;
                }
                // The solid angle: A_perp = t^2 dw once the hit is known.
                texels.push((
                    o,
                    d,
                    texel * texel / (len * len * len),
                    phase_of(index, face as u32, x, y),
                    index,
                    1.0,
                ));
            }
        }
        let queries: Vec<RayQuery> = texels
            .iter()
            .map(|&(origin, direction, ..)| RayQuery {
                origin,
                direction,
                t_min: 0.0,
                t_max: f32::INFINITY,
            })
            .collect();
        let hits = rays.closest_hits(&queries)?;
        let mut senders: Vec<(u32, LightSender)> = texels
            .par_iter()
            .zip(hits)
            .filter_map(|(&(o, d, footprint, phase, index, weight), hit)| {
                let light = &lights.lights[index];
                let hit = hit?;
                let s = surface_at(scene, &offsets, &hit, o, d)?;
                let cos = s.ns.dot(-d).max(s.ng.dot(-d)).max(1e-2);
                let a_perp = if light.kind == LightKind::Directional {
                    footprint
                } else {
                    hit.t * hit.t * footprint
                };
                let area = a_perp / cos;
                let power = s.albedo * light.irradiance(s.p, s.ns) * area * weight;
                (power.max_element() > 0.0 && power.is_finite() && area.is_finite())
                    .then_some((phase, LightSender::on(&s, power, area, index as u32, 1)))
            })
            .collect();
        // Further bounces: light paths continued from the first senders.
        if let Some(last) = match bounces {
            Bounces::Limited(n) if n >= 2 => Some(n.min(MAX_PATH_BOUNCES)),
            Bounces::Limited(_) => None,
            Bounces::Unlimited => Some(MAX_PATH_BOUNCES),
        } {
            let deep = deep_senders(scene, &offsets, &rays, &senders, budget, last, eps, lights)?;
            senders.extend(deep);
        }
        // Phase by phase (a stable sort: within a phase, the order of the lights and texels).
        senders.sort_by_key(|(phase, _)| *phase);
        let mut phase_offsets = [0u32; PHASES + 1];
        for (phase, _) in &senders {
            phase_offsets[*phase as usize + 1] += 1;
        }
        for p in 0..PHASES {
            phase_offsets[p + 1] += phase_offsets[p];
        }
        let senders: Vec<LightSender> = senders.into_iter().map(|(_, s)| s).collect();
        // Each sender's visibility map: one ray per texel, from just above its surface, for
        // a thousand senders at a time (a million rays, 32 MB of queries).
        let directions = map_directions();
        let mut depths: Vec<f32> = Vec::with_capacity(senders.len() * directions.len());
        for chunk in senders.chunks(1024) {
            let queries: Vec<RayQuery> = chunk
                .par_iter()
                .flat_map_iter(|s| {
                    let (t, b, n) = (s.tangent, s.normal.cross(s.tangent), s.normal);
                    let origin = s.position + n * eps;
                    directions.iter().map(move |l| RayQuery {
                        origin,
                        direction: (t * l.x + b * l.y + n * l.z).normalize_or_zero(),
                        t_min: 0.0,
                        t_max: f32::INFINITY,
                    })
                })
                .collect();
            depths.extend(
                rays.closest_hits(&queries)?
                    .into_iter()
                    .map(|h| h.map_or(f32::MAX, |h| h.t)),
            );
        }
        Ok(Self {
            senders,
            phase_offsets,
            interleaved: true,
            depths,
            visibility: true,
            resolutions,
            once: true,
            rays: None,
        })
    }

    /// The senders in the GPU layout ([`crate::GpuIsr::set_light_senders`] uploads them).
    pub fn to_gpu(&self) -> Vec<GpuLightSender> {
        self.senders
            .iter()
            .map(|s| GpuLightSender {
                position_area: s.position.extend(s.area).to_array(),
                normal_light: s.normal.extend(f32::from_bits(s.light)).to_array(),
                power: s.power.extend(0.0).to_array(),
                tangent: s.tangent.extend(s.bounce as f32).to_array(),
            })
            .collect()
    }

    /// The senders coarse pixel `(x, y)` gathers and the weight of each: its phase's,
    /// weighted [`PHASES`], or all of them, weighted 1 ([`LightSenders::interleaved`]).
    pub fn gathered_by(&self, x: u32, y: u32) -> (std::ops::Range<usize>, f32) {
        if self.interleaved {
            let p = pixel_phase(x, y);
            (
                self.phase_offsets[p] as usize..self.phase_offsets[p + 1] as usize,
                PHASES as f32,
            )
        } else {
            (0..self.senders.len(), 1.0)
        }
    }

    /// Whether the senders keep the scene's CPU ray-query tree, which
    /// [`IsrSettings::light_sender_shadows`](crate::IsrSettings::light_sender_shadows)
    /// traces (those made on the GPU do not).
    pub fn has_rays(&self) -> bool {
        self.rays.is_some()
    }

    /// Whether there is no sender.
    pub fn is_empty(&self) -> bool {
        self.senders.is_empty()
    }

    /// The one-bounce radiance the senders give each pixel of the coarse buffer `coarse`
    /// seen through `view` (module docs), with the frame factors of `lights` (the set the
    /// senders were made from) and the screen-space disk of world radius `radius`; `once`
    /// leaves out, per receiver, the senders its screen-space samples already see;
    /// `shadowed` casts one occlusion ray from each receiver to each sender it would count
    /// (a measurement of what the missing visibility costs: its time grows with pixels
    /// times senders).
    pub fn gather(
        &self,
        view: &View,
        coarse: &GBuffer,
        lights: &LightSet,
        radius: f32,
        once: bool,
        shadowed: bool,
    ) -> Vec<Vec3> {
        let rays = self.rays.as_deref().filter(|_| shadowed);
        let texels = (DEPTH_RES * DEPTH_RES) as usize;
        let maps = (self.visibility && self.depths.len() == self.senders.len() * texels)
            .then_some(self.depths.as_slice());
        // Off the receiver's surface, past the coarse depth's error.
        let eps = 1e-3 * lights.extent;
        let screen = Screen::new(view);
        let (w, h) = (coarse.width, coarse.height);
        let factors: Vec<Vec3> = lights.lights.iter().map(|l| l.indirect).collect();
        // Per sender: its power this frame, the coarse pixel that shows it, if any, and its
        // visibility map's frame (made once here, not per receiver).
        let prepared: Vec<Prepared> = self
            .senders
            .par_iter()
            .map(|s| {
                let power = s.power * factors.get(s.light as usize).copied().unwrap_or(Vec3::ZERO);
                (
                    power,
                    // Only the light of a first bounce is what the screen-space senders send.
                    (once && s.bounce == 1)
                        .then(|| shown_at(view, coarse, s))
                        .flatten(),
                    (s.tangent, s.normal.cross(s.tangent), s.normal),
                )
            })
            .collect();
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let prepared = &prepared;
                let screen = &screen;
                (0..w).map(move |x| {
                    let Some(r) = Receiver::at(screen, coarse, radius, x, y) else {
                        return Vec3::ZERO;
                    };
                    let mut sum = Vec3::ZERO;
                    let (range, weight) = self.gathered_by(x, y);
                    for k in range {
                        let (s, (power, shown, frame)) = (&self.senders[k], &prepared[k]);
                        if shown.is_some_and(|(sx, sy)| r.disk_holds(sx, sy)) {
                            continue;
                        }
                        let d = s.position - r.p;
                        let r2 = d.length_squared();
                        if !(r2 > 0.0 && r2.is_finite()) {
                            continue;
                        }
                        let dir = d / r2.sqrt();
                        let cos_p = r.n.dot(dir);
                        let cos_s = -s.normal.dot(dir);
                        if cos_p <= 0.0 || cos_s <= 0.0 {
                            continue;
                        }
                        let r_len = r2.sqrt();
                        let seen = match rays {
                            Some(rays) => {
                                if rays.occluded(r.p + r.n * eps, dir, 0.0, r_len - 2.0 * eps) {
                                    continue;
                                }
                                1.0
                            }
                            None => maps.map_or(1.0, |maps| {
                                map_visibility(
                                    &maps[k * texels..(k + 1) * texels],
                                    *frame,
                                    -dir,
                                    r_len,
                                    r.n,
                                    cos_p,
                                )
                            }),
                        };
                        // L A cos cos / (pi r^2 + A) with L = power / (pi A).
                        sum += *power * (seen * cos_p * cos_s / (PI * (PI * r2 + s.area)));
                    }
                    r.rho * sum * weight
                })
            })
            .collect()
    }

    /// [`LightSenders::gather`] added to the ISR pass' output `radiosity` (indirect in
    /// `rgb`), counting each surface once unless [`LightSenders::once`] is off.
    pub fn add_to(
        &self,
        radiosity: &mut [Vec4],
        view: &View,
        coarse: &GBuffer,
        lights: &LightSet,
        radius: f32,
        shadowed: bool,
    ) {
        let light = self.gather(view, coarse, lights, radius, self.once, shadowed);
        for (r, l) in radiosity.iter_mut().zip(light) {
            *r += l.extend(0.0);
        }
    }
}

/// Whether `budget` senders of `lights` in `scene` are none at all: no budget, no light or
/// no triangle (no ray to trace, no tree to build).
fn nothing_to_trace(scene: &Scene, lights: &LightSet, budget: u32) -> bool {
    budget == 0 || lights.lights.is_empty() || scene.triangle_count() == 0
}

/// The most bounces a light path of [`LightSenders::with_bounces`] makes.
pub const MAX_PATH_BOUNCES: u32 = 64;

/// Seed of the further bounces' light paths (module docs, "Further bounces").
const PATH_SEED: u64 = 0x15_0050;

/// The senders of bounces 2 to `last` (module docs, "Further bounces"): `paths` light paths,
/// each starting at one of the first senders `first` drawn in proportion to its power
/// (stratified over the paths), continued by cosine-distributed rays, one sender at each
/// surface they hit, ended by Russian roulette on the albedo. Each path's phase is a hash
/// of its index. Traced in waves (one ray of every living path per wave, so that a GPU
/// answers them together); deterministic whatever the thread count or the tracer: path `k`
/// draws from its own stream, and its senders come in the order of the paths.
#[allow(clippy::too_many_arguments)]
fn deep_senders(
    scene: &Scene,
    offsets: &[u32],
    rays: &SenderRays<'_>,
    first: &[(u32, LightSender)],
    paths: u32,
    last: u32,
    eps: f32,
    lights: &LightSet,
) -> Result<Vec<(u32, LightSender)>, IsrError> {
    let weights: Vec<f64> = first
        .iter()
        .map(|(_, s)| f64::from(s.power.element_sum()))
        .collect();
    let cdf: Vec<f64> = weights
        .iter()
        .scan(0.0, |acc, w| {
            *acc += w;
            Some(*acc)
        })
        .collect();
    let total = cdf.last().copied().unwrap_or(0.0);
    if paths == 0 || !(total > 0.0 && total.is_finite()) {
        return Ok(Vec::new());
    }
    // The area each path's sender stands for (the disk form factor's guard against the
    // 1/r^2 singularity): the scene's surface, at most its bounds' box, shared by the paths.
    let surface: f64 = scene
        .meshes
        .iter()
        .flat_map(|m| {
            m.indices.iter().map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
        })
        .sum();
    let size = (lights.bounds.max - lights.bounds.min).as_dvec3();
    let box_area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
    let area = (surface.min(box_area) / f64::from(paths)) as f32;
    if !(area > 0.0 && area.is_finite()) {
        return Ok(Vec::new());
    }
    // The ray a path leaves `p` by, along a cosine-distributed direction about `n`.
    let next_ray = |rng: &mut Rng, p: Vec3, n: Vec3| RayQuery {
        origin: p + n * eps,
        direction: cosine_hemisphere(n, rng.next_vec2()),
        t_min: 0.0,
        t_max: f32::INFINITY,
    };
    let mut walks: Vec<Walk> = (0..paths)
        .into_par_iter()
        .map(|k| {
            let mut rng = Rng::new(PATH_SEED, u64::from(k));
            let u = (f64::from(k) + rng.next_f64()) / f64::from(paths) * total;
            let i = cdf.partition_point(|&c| c <= u).min(first.len() - 1);
            let parent = first[i].1;
            let ray = next_ray(&mut rng, parent.position, parent.normal);
            Walk {
                rng,
                phase: (mix64(u64::from(k)) % PHASES as u64) as u32,
                light: parent.light,
                // The power this path carries out of its first sender.
                flux: parent.power * (total / (f64::from(paths) * weights[i])) as f32,
                ray: Some(ray),
                out: Vec::new(),
            }
        })
        .collect();
    for bounce in 2..=last {
        let queries: Vec<RayQuery> = walks.iter().filter_map(|w| w.ray).collect();
        if queries.is_empty() {
            break;
        }
        let hits = rays.closest_hits(&queries)?;
        let living: Vec<&mut Walk> = walks.iter_mut().filter(|w| w.ray.is_some()).collect();
        living.into_par_iter().zip(hits).for_each(|(w, hit)| {
            let Some(ray) = w.ray.take() else {
                return;
            };
            let Some(s) =
                hit.and_then(|h| surface_at(scene, offsets, &h, ray.origin, ray.direction))
            else {
                return;
            };
            let power = w.flux * s.albedo;
            if !(power.max_element() > 0.0 && power.is_finite()) {
                return;
            }
            w.out
                .push((w.phase, LightSender::on(&s, power, area, w.light, bounce)));
            let survive = s.albedo.max_element().min(0.95);
            if bounce == last || w.rng.next_f32() >= survive {
                return;
            }
            w.flux = power / survive;
            w.ray = Some(next_ray(&mut w.rng, s.p, s.ns));
        });
    }
    Ok(walks.into_iter().flat_map(|w| w.out).collect())
}

/// One light path of [`deep_senders`] between waves.
struct Walk {
    rng: Rng,
    phase: u32,
    light: u32,
    /// The power it carries out of its last vertex.
    flux: Vec3,
    /// The ray it leaves its last vertex by; `None` once it has ended.
    ray: Option<RayQuery>,
    /// Its senders, in the order of their bounces.
    out: Vec<(u32, LightSender)>,
}

/// A sender as one frame's gather reads it: its power under the frame's factors, the
/// coarse pixel that shows it (if any), and its visibility map's frame (tangent,
/// bitangent, normal).
type Prepared = (Vec3, Option<(u32, u32)>, (Vec3, Vec3, Vec3));

/// The coarse pixel of `g` seen through `view` that shows sender `s`, if it is visible there:
/// the pixel is not background, its depth is within 2 % of the sender's and its normal
/// within 60 degrees of the sender's.
fn shown_at(view: &View, g: &GBuffer, s: &LightSender) -> Option<(u32, u32)> {
    let uv = view.project_uv(s.position)?;
    if !(uv.x >= 0.0 && uv.y >= 0.0 && uv.x < 1.0 && uv.y < 1.0) {
        return None;
    }
    let (x, y) = (
        ((uv.x * g.width as f32) as u32).min(g.width - 1),
        ((uv.y * g.height as f32) as u32).min(g.height - 1),
    );
    let k = (y * g.width + x) as usize;
    if g.is_background(k) {
        return None;
    }
    let z = view.linear_depth(s.position);
    let zg = g.depth[k];
    ((z - zg).abs() <= 0.02 * zg && g.normal[k].dot(s.normal) >= 0.5).then_some((x, y))
}
