//! Light sources with stable ids, the per-frame state of each ([`LightState`]), and the
//! emissive-triangle power table that light sampling uses ([`Emitters`]).
//!
//! Every point light, every directional light and every emissive mesh (a mesh with at
//! least one triangle whose material emits) is a light source with a [`LightId`]. Ids are
//! positions in the scene's arrays, so they are stable as long as the scene's lights and
//! meshes are: the same file imported twice gives the same ids.
//!
//! A [`LightState`] says, per light, whether it is on, a colour multiplier (recolour and
//! dim), and separate multipliers for its direct and its indirect light (what engine
//! users ask of baked lighting). Every technique and the reference path tracer honour it;
//! the default state (everything on, every multiplier 1) renders the scene as it is.
//!
//! ```
//! use scene_core::{builtin, lights::{LightId, LightState, light_ids}};
//! let scene = builtin::scene("corridor").unwrap();
//! let ids = light_ids(&scene);
//! assert_eq!(ids.len(), 4); // four point lights, no emissive mesh
//! let mut state = LightState::default();
//! state.set_color(LightId::Point(0), glam::Vec3::new(1.0, 0.2, 0.2)); // recolour
//! state.set_enabled(LightId::Point(1), false); // switch off
//! let one = LightState::only(&scene, LightId::Point(2)); // one light alone
//! assert!(!one.get(LightId::Point(0)).enabled && one.get(LightId::Point(2)).enabled);
//! ```

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};

use crate::image::luminance;
use crate::scene::Scene;

/// The stable id of a light source.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LightId {
    /// `scene.point_lights[i]`.
    Point(u32),
    /// `scene.directional_lights[i]`.
    Directional(u32),
    /// `scene.sky` (as one source, whichever form a method gives it).
    Sky,
    /// The emissive triangles of `scene.meshes[i]`, as one source.
    Emissive(u32),
}

impl LightId {
    /// A label for messages and reports: `"point light #0 'key'"`.
    pub fn label(&self, scene: &Scene) -> String {
        let (kind, name) = match *self {
            LightId::Point(i) => (
                "point light",
                scene.point_lights.get(i as usize).map(|l| l.name.as_str()),
            ),
            LightId::Directional(i) => (
                "directional light",
                scene
                    .directional_lights
                    .get(i as usize)
                    .map(|l| l.name.as_str()),
            ),
            LightId::Emissive(i) => (
                "emissive mesh",
                scene.meshes.get(i as usize).map(|m| m.name.as_str()),
            ),
            LightId::Sky => {
                return match &scene.sky {
                    Some(s) if !s.name.is_empty() => format!("sky '{}'", s.name),
                    _ => "sky".to_string(),
                };
            }
        };
        let i = match *self {
            LightId::Point(i) | LightId::Directional(i) | LightId::Emissive(i) => i,
            LightId::Sky => 0,
        };
        match name {
            Some(n) if !n.is_empty() => format!("{kind} #{i} '{n}'"),
            _ => format!("{kind} #{i}"),
        }
    }
}

impl LightId {
    /// The id as command lines and replay files write it: `point:N`, `directional:N`,
    /// `sky` or `emissive:N` (N a mesh index).
    pub fn key(&self) -> String {
        match *self {
            LightId::Point(i) => format!("point:{i}"),
            LightId::Directional(i) => format!("directional:{i}"),
            LightId::Emissive(m) => format!("emissive:{m}"),
            LightId::Sky => "sky".to_string(),
        }
    }

    /// The light of `scene` whose [`LightId::key`] is `key`; the error names the key and
    /// lists the scene's lights.
    pub fn find(scene: &Scene, key: &str) -> Result<LightId, UnknownLight> {
        let ids = light_ids(scene);
        ids.iter()
            .copied()
            .find(|id| id.key() == key)
            .ok_or_else(|| UnknownLight {
                key: key.to_string(),
                scene: scene.name.clone(),
                known: ids.iter().map(LightId::key).collect(),
            })
    }
}

/// [`LightId::find`] found no light of that key: the key, the scene, and the keys of the
/// scene's lights (for a caller to offer them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownLight {
    /// The key asked for.
    pub key: String,
    /// The scene's name.
    pub scene: String,
    /// The keys of the scene's lights ([`light_ids`]' order).
    pub known: Vec<String>,
}

impl std::fmt::Display for UnknownLight {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "no light '{}' in scene '{}' (its lights: {})",
            self.key,
            self.scene,
            if self.known.is_empty() {
                "none".to_string()
            } else {
                self.known.join(", ")
            }
        )
    }
}

impl std::error::Error for UnknownLight {}

/// [`LightState::check`] found a setting no method can apply: which light (its id and
/// label) and the setting.
#[derive(Clone, Debug, PartialEq)]
pub struct InvalidLightSetting {
    /// The light.
    pub light: LightId,
    /// Its label in the scene ([`LightId::label`]).
    pub label: String,
    /// The offending setting.
    pub setting: LightSetting,
    /// What is wrong with it.
    pub reason: String,
}

impl std::fmt::Display for InvalidLightSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: light setting {:?} {}",
            self.label, self.setting, self.reason
        )
    }
}

impl std::error::Error for InvalidLightSetting {}

/// Every light source of `scene`, in a fixed order: point lights, directional lights, the
/// sky, then emissive meshes by mesh index.
pub fn light_ids(scene: &Scene) -> Vec<LightId> {
    let mut ids: Vec<LightId> = (0..scene.point_lights.len() as u32)
        .map(LightId::Point)
        .chain((0..scene.directional_lights.len() as u32).map(LightId::Directional))
        .collect();
    if scene.sky.is_some() {
        ids.push(LightId::Sky);
    }
    for (i, mesh) in scene.meshes.iter().enumerate() {
        let emits = mesh.material_ids.iter().any(|&m| {
            scene
                .materials
                .get(m as usize)
                .is_some_and(|m| m.is_emissive())
        });
        if emits {
            ids.push(LightId::Emissive(i as u32));
        }
    }
    ids
}

/// How one light shines in a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSetting {
    /// Off: the light gives neither direct nor indirect light, and an emissive mesh does
    /// not glow.
    pub enabled: bool,
    /// Multiplies the light's emission (intensity, irradiance or emitted radiance) per
    /// channel: recolouring and dimming.
    pub color: Vec3,
    /// Multiplies the light's direct light: emission seen directly and light arriving at a
    /// surface straight from the light.
    pub direct: f32,
    /// Multiplies the light's indirect light: everything that reached a surface after one
    /// or more reflections.
    pub indirect: f32,
}

impl Default for LightSetting {
    fn default() -> Self {
        Self {
            enabled: true,
            color: Vec3::ONE,
            direct: 1.0,
            indirect: 1.0,
        }
    }
}

impl LightSetting {
    /// The factor on the light's direct contribution (zero when off).
    pub fn direct_factor(&self) -> Vec3 {
        if self.enabled {
            self.color * self.direct
        } else {
            Vec3::ZERO
        }
    }

    /// The factor on the light's indirect contribution (zero when off).
    pub fn indirect_factor(&self) -> Vec3 {
        if self.enabled {
            self.color * self.indirect
        } else {
            Vec3::ZERO
        }
    }

    /// True when the light contributes nothing at all.
    pub fn is_dark(&self) -> bool {
        self.direct_factor() == Vec3::ZERO && self.indirect_factor() == Vec3::ZERO
    }

    fn is_finite(&self) -> bool {
        self.color.is_finite() && self.direct.is_finite() && self.indirect.is_finite()
    }
}

/// The per-frame state of every light of a scene. Lights not mentioned shine as the scene
/// describes them ([`LightSetting::default`]), so the default state is the scene itself.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightState {
    settings: BTreeMap<LightId, LightSetting>,
}

impl LightState {
    /// The default state: every light as the scene describes it.
    pub const fn new() -> Self {
        Self {
            settings: BTreeMap::new(),
        }
    }

    /// Every light of `scene` off but `id`.
    pub fn only(scene: &Scene, id: LightId) -> Self {
        let mut s = Self::default();
        for other in light_ids(scene) {
            s.set_enabled(other, other == id);
        }
        s
    }

    /// The setting of `id`.
    pub fn get(&self, id: LightId) -> LightSetting {
        self.settings.get(&id).copied().unwrap_or_default()
    }

    /// Replaces the setting of `id`.
    pub fn set(&mut self, id: LightId, setting: LightSetting) {
        if setting == LightSetting::default() {
            self.settings.remove(&id);
        } else {
            self.settings.insert(id, setting);
        }
    }

    /// Switches `id` on or off.
    pub fn set_enabled(&mut self, id: LightId, enabled: bool) {
        let s = self.get(id);
        self.set(id, LightSetting { enabled, ..s });
    }

    /// Sets the colour multiplier of `id`.
    pub fn set_color(&mut self, id: LightId, color: Vec3) {
        let s = self.get(id);
        self.set(id, LightSetting { color, ..s });
    }

    /// True when every light shines as the scene describes it.
    pub fn is_default(&self) -> bool {
        self.settings.is_empty()
    }

    /// The lights whose setting differs from the default, in id order.
    pub fn changed(&self) -> impl Iterator<Item = (LightId, LightSetting)> + '_ {
        self.settings.iter().map(|(k, v)| (*k, *v))
    }

    /// Checks every multiplier is finite and non-negative, and that the light's power times
    /// the product of its multipliers (colour, direct or indirect) stays within
    /// [`RADIOMETRIC_MAX`](crate::scene::RADIOMETRIC_MAX), the bound a scene's own lights
    /// keep: past it, sums of the light overflow f32 and a method renders infinity or NaN.
    /// The error names the light and what is wrong.
    pub fn check(&self, scene: &Scene) -> Result<(), InvalidLightSetting> {
        for (id, s) in &self.settings {
            let fail = |reason: String| InvalidLightSetting {
                light: *id,
                label: id.label(scene),
                setting: *s,
                reason,
            };
            if !s.is_finite() || s.color.min_element() < 0.0 || s.direct < 0.0 || s.indirect < 0.0 {
                return Err(fail("has a negative or non-finite multiplier".into()));
            }
            // A scene's lights are within the bound: only multipliers above 1 can leave it.
            let gain = f64::from(s.color.max_element()) * f64::from(s.direct.max(s.indirect));
            if gain <= 1.0 {
                continue;
            }
            let power = light_power_bound(scene, *id);
            let product = gain * f64::from(power);
            let max = f64::from(crate::scene::RADIOMETRIC_MAX);
            if product > max {
                return Err(fail(format!(
                    "times the light's {power:e} gives {product:e}, above {max:e}: f32 sums of \
                     its light would overflow"
                )));
            }
        }
        Ok(())
    }

    /// A hash of the state (bit patterns of every changed setting), for cache keys.
    pub fn fingerprint(&self) -> u64 {
        let mut h = crate::hash::Fnv::default();
        for (id, s) in &self.settings {
            let (kind, i) = match *id {
                LightId::Point(i) => (0, i),
                LightId::Directional(i) => (1, i),
                LightId::Emissive(i) => (2, i),
                LightId::Sky => (3, 0),
            };
            h.u64(kind)
                .u64(u64::from(i))
                .u64(u64::from(s.enabled))
                .f32s([s.color.x, s.color.y, s.color.z, s.direct, s.indirect]);
        }
        h.finish()
    }
}

/// The largest radiometric value light `id` has in `scene` (intensity, irradiance, an
/// emissive mesh's largest emission factor, the sky's brightest radiance); 0 for a light
/// the scene does not have.
fn light_power_bound(scene: &Scene, id: LightId) -> f32 {
    match id {
        LightId::Point(i) => scene
            .point_lights
            .get(i as usize)
            .map_or(0.0, |l| l.intensity.max_element()),
        LightId::Directional(i) => scene
            .directional_lights
            .get(i as usize)
            .map_or(0.0, |l| l.irradiance.max_element()),
        LightId::Emissive(i) => scene.meshes.get(i as usize).map_or(0.0, |m| {
            m.material_ids
                .iter()
                .filter_map(|&id| scene.materials.get(id as usize))
                .map(|mat| mat.emission.max_element())
                .fold(0.0, f32::max)
        }),
        LightId::Sky => scene.sky.as_ref().map_or(0.0, |sky| {
            sky.map()
                .iter()
                .map(|c| c.max_element())
                .fold(0.0, f32::max)
        }),
    }
}

/// Every directional light a method that does not integrate the sky must shade, with the
/// source it belongs to: the scene's directional lights ([`LightId::Directional`]), then
/// the sky's median-cut directions ([`crate::sky::Sky::lights`], all [`LightId::Sky`]).
pub fn directional_sources(scene: &Scene) -> Vec<(LightId, &crate::scene::DirectionalLight)> {
    let own = scene.directional_lights.iter().enumerate();
    let mut out: Vec<_> = own
        .map(|(i, l)| (LightId::Directional(i as u32), l))
        .collect();
    if let Some(sky) = &scene.sky {
        out.extend(sky.lights().iter().map(|l| (LightId::Sky, l)));
    }
    out
}

/// The distance falloff of a point light (thesis eq. 16 when `radius` is given): `1/d^2`,
/// or `saturate(1 - (d/r)^2)` for `radius` `Some(r)` (0 for `r <= 0`, which validation
/// refuses). Never infinite: 0 at zero distance, at most `f32::MAX` for tiny distances.
/// [`crate::PointLight::falloff`], the reference and ISR all use this one function.
pub fn falloff(radius: Option<f32>, distance: f32) -> f32 {
    match radius {
        Some(r) if r > 0.0 => (1.0 - (distance / r).powi(2)).clamp(0.0, 1.0),
        Some(_) => 0.0,
        None => {
            let d2 = distance * distance;
            if d2 > 0.0 {
                (1.0 / d2).min(f32::MAX)
            } else {
                0.0
            }
        }
    }
}

/// The cone of a spot light, as `KHR_lights_punctual` defines it: full intensity within
/// `inner` of the axis, none beyond `outer`, and between them glTF's smooth ramp
/// `saturate((cos_a - cos_outer) / (cos_inner - cos_outer))^2`, where `a` is the angle
/// between the axis and the direction towards the lit point (the extension's recommended
/// attenuation; the difference of cosines is floored at 1e-3, so `inner == outer` gives a
/// hard edge one thousandth of a cosine wide). A [`crate::PointLight`] with a cone is a
/// spot light; every method and the reference multiply its intensity by the cone's
/// attenuation, evaluated by its [`SpotRamp`] ([`SpotCone::ramp`], computed once per light
/// where it is evaluated many times).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotCone {
    /// Direction of the axis: where the light points (any length; used normalised).
    pub direction: Vec3,
    /// Angle from the axis, in radians, within which the intensity is full (glTF's
    /// `innerConeAngle`, default 0). At least 0 and at most `outer`.
    pub inner: f32,
    /// Angle from the axis, in radians, beyond which no light leaves (glTF's
    /// `outerConeAngle`, default pi/4). Above 0 and at most pi/2.
    pub outer: f32,
}

impl SpotCone {
    /// The smallest difference `cos(inner) - cos(outer)` the ramp divides by.
    pub const MIN_RAMP: f32 = 1e-3;

    /// The cone's ramp with its cosines and unit axis computed: what the methods evaluate
    /// (the shaders take its three numbers).
    pub fn ramp(&self) -> SpotRamp {
        let (ci, co) = (self.inner.cos(), self.outer.cos());
        let scale = 1.0 / (ci - co).max(Self::MIN_RAMP);
        SpotRamp {
            axis: self.axis(),
            scale,
            offset: -co * scale,
        }
    }

    /// The unit axis (zero for a zero direction, which validation refuses).
    pub fn axis(&self) -> Vec3 {
        self.direction.normalize_or_zero()
    }

    /// The factor on the intensity towards unit direction `w` (from the light), in [0, 1]:
    /// [`SpotRamp::attenuation`] of [`SpotCone::ramp`], which this computes each call.
    pub fn attenuation(&self, w: Vec3) -> f32 {
        self.ramp().attenuation(w)
    }

    /// The solid angle the cone's attenuation integrates to, `integral attenuation dw`
    /// over the sphere (about 2 pi, a hemisphere, for `inner == outer == pi/2`): the
    /// light's power is its intensity times this. Closed form of the ramp: with
    /// `c_o = cos(outer)`, `w = max(cos(inner) - c_o, 1e-3)` and `t = min(c_o + w, 1)`,
    /// `2 pi ((t - c_o)^3 / (3 w^2) + 1 - t)`.
    pub fn solid_angle(&self) -> f32 {
        let co = self.outer.cos();
        let w = (self.inner.cos() - co).max(Self::MIN_RAMP);
        let t = (co + w).min(1.0);
        let ramp = (t - co).powi(3) / (3.0 * w * w);
        std::f32::consts::TAU * (ramp + (1.0 - t)).max(0.0)
    }

    /// The solid angle of the outer cone, `2 pi (1 - cos(outer))`: what uniform sampling of
    /// directions within it divides by.
    pub fn outer_solid_angle(&self) -> f32 {
        std::f32::consts::TAU * (1.0 - self.outer.cos())
    }

    /// Why the cone is unusable, if it is: a direction that is not finite or is zero, or
    /// angles that are not `0 <= inner <= outer <= pi/2` with `outer > 0`.
    pub fn fault(&self) -> Option<String> {
        if !self.direction.is_finite() || self.direction.length_squared() < 1e-12 {
            return Some(format!(
                "spot direction {} is zero or not finite",
                self.direction
            ));
        }
        let ok = self.inner >= 0.0
            && self.inner <= self.outer
            && self.outer > 0.0
            && self.outer <= std::f32::consts::FRAC_PI_2;
        (!ok).then(|| {
            format!(
                "spot cone angles inner {} and outer {} are not 0 <= inner <= outer <= pi/2 \
                 with outer above 0",
                self.inner, self.outer
            )
        })
    }
}

/// A spot cone's ramp, ready to evaluate: the attenuation towards unit direction `w` (from
/// the light) is `saturate(dot(axis, w) * scale + offset)^2`. [`SpotRamp::NONE`] (no cone)
/// gives 1 everywhere. The shaders evaluate the same three numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotRamp {
    /// The cone's unit axis (zero for no cone).
    pub axis: Vec3,
    /// The ramp's scale, `1 / max(cos inner - cos outer, 1e-3)` (0 for no cone).
    pub scale: f32,
    /// The ramp's offset, `-cos(outer) * scale` (1 for no cone).
    pub offset: f32,
}

impl SpotRamp {
    /// No cone: attenuation 1 in every direction.
    pub const NONE: SpotRamp = SpotRamp {
        axis: Vec3::ZERO,
        scale: 0.0,
        offset: 1.0,
    };

    /// The ramp of `cone`, or [`SpotRamp::NONE`].
    pub fn of(cone: Option<&SpotCone>) -> SpotRamp {
        cone.map_or(Self::NONE, SpotCone::ramp)
    }

    /// The factor on the intensity towards unit direction `w` (from the light), in [0, 1].
    #[inline]
    pub fn attenuation(&self, w: Vec3) -> f32 {
        let a = (self.axis.dot(w) * self.scale + self.offset).clamp(0.0, 1.0);
        a * a
    }
}

/// The weight that picks a light source by its (RGB) power: its luminance, floored at
/// 1e-3 of its brightest channel so that saturated colours keep some weight; 0 for
/// non-finite or non-positive power. [`Emitters`] and ibrr-ldc's particle walks use it.
pub fn sampling_weight(power: Vec3) -> f64 {
    let w = f64::from(luminance(power).max(power.max_element() * 1e-3));
    if w > 0.0 && w.is_finite() { w } else { 0.0 }
}

/// One emissive triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissiveTriangle {
    /// Global triangle id.
    pub triangle: u32,
    /// The mesh it belongs to (its light is [`LightId::Emissive`] of that mesh).
    pub mesh: u32,
    /// Corners.
    pub corners: [Vec3; 3],
    /// Unit geometric normal of the emitting side (from the winding; zero when degenerate).
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// Emitted radiance as the scene gives it (before any [`LightState`]); with an emission
    /// texture, its mean over the triangle ([`Scene::triangle_emission`]).
    pub emission: Vec3,
    /// Sampling weight: power under the state (`luminance x area`, with a floor of 1e-3 of
    /// the brightest channel so that saturated colours keep some weight); zero for a light
    /// that is off.
    pub weight: f64,
}

/// The emissive triangles of a scene and the power table that picks them for light
/// sampling (the reference's next-event estimation, ISR's emitter samples).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Emitters {
    /// Every emissive triangle (finite, positive emission), in global triangle order.
    pub triangles: Vec<EmissiveTriangle>,
    /// Cumulative distribution over `triangles` by weight (last entry 1; empty when no
    /// triangle has weight), in f64 so that tiny emitters keep a non-empty interval.
    pub cdf: Vec<f64>,
    /// Sum of the weights.
    pub total_weight: f64,
    /// Per global triangle id: index into `triangles`, or `u32::MAX`.
    pub per_triangle: Vec<u32>,
    /// Per entry of `triangles`: where an emission texture varies over the triangle, the
    /// distribution of light samples over its sub-triangles by their emitted power
    /// ([`Emitters::point_on`]); `None` samples the triangle uniformly by area.
    pub patterns: Vec<Option<EmissionPattern>>,
}

/// The sub-triangles per side of an emission-textured triangle's regular subdivision that
/// [`EmissionPattern`] weighs: `TEXEL_GRID^2 = 64` sub-triangles, the same ones whose
/// centroids give the triangle's mean emission ([`Scene::triangle_emission`]).
pub const TEXEL_GRID: u32 = 8;

/// How an emission-textured triangle's light samples are spread over it: a cumulative
/// distribution over the `TEXEL_GRID^2` sub-triangles of its regular subdivision (in the
/// order of [`crate::cutout::triangle_samples`]) by each one's emitted power, so that a lamp
/// drawn as an emissive map is sampled where its texels shine. Each sub-triangle's weight
/// is the largest emission found at its centroid and half way from the centroid to each
/// corner (so that a sub-triangle partly lit is not starved), floored at 1 % of the
/// triangle's largest weight (every point keeps a positive density).
#[derive(Clone, Debug, PartialEq)]
pub struct EmissionPattern {
    cdf: Vec<f32>,
}

impl EmissionPattern {
    /// The pattern of `weight` (a power at barycentric coordinates of vertices 1 and 2);
    /// `None` when the weights are uniform (sampling by area is then the same) or not
    /// positive.
    pub fn new(weight: impl Fn(Vec2) -> f64) -> Option<Self> {
        let n = TEXEL_GRID as f32;
        let w: Vec<f64> = (0..TEXEL_GRID * TEXEL_GRID)
            .map(|s| {
                let corners = sub_triangle(s).map(|c| c / n);
                let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
                corners
                    .iter()
                    .map(|&c| weight(0.5 * (centroid + c)))
                    .fold(weight(centroid), f64::max)
            })
            .map(|w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let max = w.iter().copied().fold(0.0, f64::max);
        if max <= 0.0 || w.iter().all(|&x| x == max) {
            return None;
        }
        let floored: Vec<f64> = w.iter().map(|&x| x.max(0.01 * max)).collect();
        let total: f64 = floored.iter().sum();
        let mut acc = 0.0;
        let mut cdf: Vec<f32> = floored
            .iter()
            .map(|&x| {
                acc += x;
                (acc / total) as f32
            })
            .collect();
        *cdf.last_mut()? = 1.0;
        Some(Self { cdf })
    }

    /// The cumulative distribution over the `TEXEL_GRID^2` sub-triangles (last entry 1).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    fn probability(&self, s: usize) -> f32 {
        self.cdf[s] - if s == 0 { 0.0 } else { self.cdf[s - 1] }
    }

    /// A point (barycentric coordinates of vertices 1 and 2) from `u_sub` in [0, 1), which
    /// picks the sub-triangle, and `b`, a point uniform by area over a whole triangle (which
    /// is placed in the sub-triangle); with its density relative to uniform sampling by
    /// area.
    pub fn point(&self, u_sub: f32, b: Vec2) -> (Vec2, f32) {
        let s = self
            .cdf
            .partition_point(|&c| c <= u_sub)
            .min(self.cdf.len() - 1);
        let [c0, c1, c2] = sub_triangle(s as u32);
        let p = (c0 + (c1 - c0) * b.x + (c2 - c0) * b.y) / TEXEL_GRID as f32;
        (p, self.density_of(s))
    }

    /// The density relative to uniform sampling by area at barycentric coordinates `b`.
    pub fn density(&self, b: Vec2) -> f32 {
        self.density_of(sub_triangle_at(b) as usize)
    }

    fn density_of(&self, s: usize) -> f32 {
        self.probability(s) * (TEXEL_GRID * TEXEL_GRID) as f32
    }
}

/// Corners, in grid units (barycentric coordinates of vertices 1 and 2 times
/// [`TEXEL_GRID`]), of sub-triangle `s` in the order of [`crate::cutout::triangle_samples`]:
/// row `i` holds the upward triangles `(i, j)` and the downward ones beside them,
/// alternating.
fn sub_triangle(s: u32) -> [Vec2; 3] {
    let n = TEXEL_GRID;
    // Row i starts at i (2n - i).
    let mut i = 0;
    while i + 1 < n && (i + 1) * (2 * n - (i + 1)) <= s {
        i += 1;
    }
    let k = s - i * (2 * n - i);
    let (j, down) = (k / 2, k % 2 == 1);
    let (x, y) = (i as f32, j as f32);
    if down {
        [
            Vec2::new(x + 1.0, y),
            Vec2::new(x, y + 1.0),
            Vec2::new(x + 1.0, y + 1.0),
        ]
    } else {
        [
            Vec2::new(x, y),
            Vec2::new(x + 1.0, y),
            Vec2::new(x, y + 1.0),
        ]
    }
}

/// The sub-triangle (as [`sub_triangle`] numbers them) holding barycentric coordinates `b`.
fn sub_triangle_at(b: Vec2) -> u32 {
    let n = TEXEL_GRID;
    let g = (b * n as f32).max(Vec2::ZERO);
    let i = (g.x.floor() as u32).min(n - 1);
    let j = (g.y.floor() as u32).min(n - 1 - i);
    let down = g.x - i as f32 + g.y - j as f32 > 1.0 && i + j + 1 < n;
    i * (2 * n - i) + 2 * j + u32::from(down)
}

impl Emitters {
    /// The table of `scene` under `state` (an emissive mesh that is off, or whose colour
    /// is black, gets weight zero: it is never picked).
    pub fn new(scene: &Scene, state: &LightState) -> Self {
        let mut e = Emitters {
            per_triangle: Vec::with_capacity(scene.triangle_count()),
            ..Default::default()
        };
        let mut global = 0u32;
        for (mi, mesh) in scene.meshes.iter().enumerate() {
            let setting = state.get(LightId::Emissive(mi as u32));
            let scale = if setting.enabled {
                setting.color * setting.direct.max(setting.indirect)
            } else {
                Vec3::ZERO
            };
            for (local, (t, &m)) in mesh.indices.iter().zip(&mesh.material_ids).enumerate() {
                // The triangle's mean emission (an emission texture averaged over it).
                let le = if scene.materials.get(m as usize).is_some() {
                    scene.triangle_emission(mi, local)
                } else {
                    Vec3::ZERO
                };
                if le.max_element() > 0.0 && le.is_finite() {
                    let p = t.map(|i| mesh.positions[i as usize]);
                    let c = (p[1] - p[0]).cross(p[2] - p[0]);
                    let area = 0.5 * c.length();
                    let weight = sampling_weight(le * scale) * f64::from(area);
                    e.per_triangle.push(e.triangles.len() as u32);
                    e.patterns.push(emission_pattern(scene, mi, local, scale));
                    e.triangles.push(EmissiveTriangle {
                        triangle: global,
                        mesh: mi as u32,
                        corners: p,
                        normal: c.normalize_or_zero(),
                        area,
                        emission: le,
                        weight: if weight > 0.0 && weight.is_finite() {
                            weight
                        } else {
                            0.0
                        },
                    });
                } else {
                    e.per_triangle.push(u32::MAX);
                }
                global += 1;
            }
        }
        e.total_weight = e.triangles.iter().map(|t| t.weight).sum();
        if e.total_weight > 0.0 {
            let mut acc = 0.0f64;
            e.cdf = e
                .triangles
                .iter()
                .map(|t| {
                    acc += t.weight;
                    acc / e.total_weight
                })
                .collect();
            // The last positive-weight entry closes the distribution.
            if let Some(last) = e.triangles.iter().rposition(|t| t.weight > 0.0) {
                for c in &mut e.cdf[last..] {
                    *c = 1.0;
                }
            }
        }
        e
    }

    /// [`Emitters::pick`] and a number in [0, 1) left over from `u` for the next choice
    /// (where `u` fell within the picked triangle's interval), so that a pattern's
    /// sub-triangle costs no further random number.
    pub fn pick_with_rest(&self, u: f64) -> Option<(usize, f32)> {
        let k = self.pick(u)?;
        let before = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let p = self.pick_probability(k);
        let rest = if p > 0.0 { (u - before) / p } else { 0.0 };
        Some((k, (rest as f32).clamp(0.0, 1.0 - f32::EPSILON)))
    }

    /// A point on triangle `k` (barycentric coordinates of vertices 1 and 2) for light
    /// sampling, from `u_sub` in [0, 1) (the pattern's sub-triangle) and `b` (a point
    /// uniform by area over a triangle), with its density relative to uniform sampling by
    /// area: `b` itself and 1 where the triangle has no [`EmissionPattern`].
    pub fn point_on(&self, k: usize, u_sub: f32, b: Vec2) -> (Vec2, f32) {
        match self.patterns.get(k).and_then(Option::as_ref) {
            Some(p) => p.point(u_sub, b),
            None => (b, 1.0),
        }
    }

    /// The density [`Emitters::point_on`] gives barycentric coordinates `b` of global
    /// triangle `triangle`, relative to uniform sampling by area (1 without a pattern).
    pub fn density_on(&self, triangle: u32, b: Vec2) -> f32 {
        match self.per_triangle.get(triangle as usize) {
            Some(&k) if k != u32::MAX => self
                .patterns
                .get(k as usize)
                .and_then(Option::as_ref)
                .map_or(1.0, |p| p.density(b)),
            _ => 1.0,
        }
    }

    /// True when no triangle can be picked.
    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    /// The triangle (index into `triangles`) that `u` in [0, 1) picks.
    pub fn pick(&self, u: f64) -> Option<usize> {
        if self.cdf.is_empty() {
            return None;
        }
        Some(
            self.cdf
                .partition_point(|&c| c <= u)
                .min(self.triangles.len() - 1),
        )
    }

    /// The probability that [`Emitters::pick`] returns `k` (its interval of the stored
    /// CDF, so that what is drawn and what is divided by agree exactly).
    pub fn pick_probability(&self, k: usize) -> f64 {
        match self.cdf.get(k) {
            Some(&c) => c - if k == 0 { 0.0 } else { self.cdf[k - 1] },
            None => 0.0,
        }
    }

    /// [`Emitters::pick_probability`] of a global triangle id (0 for non-emitters).
    pub fn probability_of_triangle(&self, triangle: u32) -> f64 {
        match self.per_triangle.get(triangle as usize) {
            Some(&k) if k != u32::MAX => self.pick_probability(k as usize),
            _ => 0.0,
        }
    }
}

/// The [`EmissionPattern`] of triangle `local` of mesh `mesh` under the state's colour
/// `scale`: `None` unless its material has an emission texture and the mesh coordinates.
fn emission_pattern(
    scene: &Scene,
    mesh: usize,
    local: usize,
    scale: Vec3,
) -> Option<EmissionPattern> {
    let m = &scene.meshes[mesh];
    let material = m.material_ids[local];
    let mat = scene.materials.get(material as usize)?;
    mat.emission_texture?;
    let uvs = m.uvs.as_ref()?;
    let t = m.indices[local].map(|i| uvs[i as usize]);
    EmissionPattern::new(|b| {
        let uv = t[0] * (1.0 - b.x - b.y) + t[1] * b.x + t[2] * b.y;
        sampling_weight(scene.emission_at(material, Some(uv)) * scale)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    #[test]
    fn multipliers_whose_product_with_the_light_overflows_are_refused() {
        let scene = builtin::scene("cornell-point").unwrap();
        let id = LightId::Point(0);
        let power = scene.point_lights[0].intensity.max_element();
        let mut state = LightState::default();
        // Large multipliers within the bound pass.
        let fine = (crate::scene::RADIOMETRIC_MAX / power).sqrt() * 0.5;
        state.set(
            id,
            LightSetting {
                color: Vec3::splat(fine),
                direct: fine,
                ..Default::default()
            },
        );
        assert_eq!(state.check(&scene), Ok(()));
        // Each finite, their product with the light's intensity past f32's range.
        state.set(
            id,
            LightSetting {
                color: Vec3::splat(1e30),
                indirect: 1e30,
                ..Default::default()
            },
        );
        let e = state.check(&scene).unwrap_err();
        assert_eq!(e.light, id);
        assert!(e.to_string().contains("overflow"), "{e}");
    }

    /// The sub-triangles tile the triangle in `triangle_samples`' order, each point maps back
    /// to the sub-triangle it was drawn in with the density it was drawn with, and the
    /// densities integrate to one.
    #[test]
    fn emission_patterns_sample_what_they_evaluate() {
        let n = TEXEL_GRID as f32;
        for (s, c) in crate::cutout::triangle_samples(TEXEL_GRID).enumerate() {
            let [a, b, d] = sub_triangle(s as u32).map(|p| p / n);
            assert!(((a + b + d) / 3.0 - c).length() < 1e-6, "sub-triangle {s}");
            assert_eq!(sub_triangle_at(c), s as u32);
            // Equal areas: an eighth of the grid's cell squared over two.
            let area = 0.5 * (b - a).perp_dot(d - a).abs();
            assert!(
                (area - 0.5 / (n * n)).abs() < 1e-6,
                "sub-triangle {s}: {area}"
            );
        }
        // A bright disc in one corner of the triangle, dark elsewhere.
        let weight = |b: Vec2| {
            if (b - Vec2::new(0.8, 0.1)).length() < 0.15 {
                1.0
            } else {
                0.0
            }
        };
        let p = EmissionPattern::new(weight).expect("a varying pattern");
        assert!(
            EmissionPattern::new(|_| 2.0).is_none(),
            "uniform weights need no pattern"
        );
        assert!(EmissionPattern::new(|_| 0.0).is_none());
        let total: f32 = (0..(TEXEL_GRID * TEXEL_GRID) as usize)
            .map(|s| p.density_of(s) / (n * n))
            .sum();
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let mut rng = crate::sampling::Rng::new(3, 0);
        let mut in_disc = 0;
        for _ in 0..4000 {
            let (u, v) = (rng.next_f32(), rng.next_vec2());
            let su = v.x.sqrt();
            let b = Vec2::new(su * (1.0 - v.y), su * v.y);
            let (q, density) = p.point(u, b);
            assert!(
                q.x >= -1e-6 && q.y >= -1e-6 && q.x + q.y <= 1.0 + 1e-6,
                "{q}"
            );
            assert!(
                (p.density(q) - density).abs() <= 1e-4 * density,
                "{q}: {density}"
            );
            in_disc += usize::from(weight(q) > 0.0);
        }
        // The disc covers 0.15^2 pi / 0.5 = 14 % of the triangle; most samples land on it.
        assert!(in_disc > 4000 * 6 / 10, "{in_disc} of 4000 in the disc");
    }

    /// The cone against glTF's formula at chosen angles, and its solid angle against a
    /// midpoint quadrature of `2 pi integral attenuation d(cos)` (1e6 steps), for a wide
    /// ramp, a hard edge, a narrow cone whose ramp passes the axis and a hemisphere.
    #[test]
    fn spot_cone_attenuation_and_solid_angle() {
        let cone = |inner: f32, outer: f32| SpotCone {
            direction: Vec3::new(0.0, -2.0, 0.0),
            inner,
            outer,
        };
        let towards = |a: f32| Vec3::new(a.sin(), -a.cos(), 0.0);
        let c = cone(0.3, 0.6);
        assert_eq!(c.attenuation(towards(0.0)), 1.0);
        assert!((c.attenuation(towards(0.3)) - 1.0).abs() < 1e-5);
        assert_eq!(c.attenuation(towards(0.61)), 0.0);
        assert_eq!(c.attenuation(Vec3::Y), 0.0);
        // Half way in cosine between the angles: (1/2)^2.
        let mid = ((0.3f32.cos() + 0.6f32.cos()) / 2.0).acos();
        assert!((c.attenuation(towards(mid)) - 0.25).abs() < 1e-4);
        for (inner, outer) in [(0.3, 0.6), (0.5, 0.5), (0.0, 0.01), (1.5707964, 1.5707964)] {
            let c = cone(inner, outer);
            let steps = 1_000_000;
            let integral: f64 = (0..steps)
                .map(|i| {
                    let cos = -1.0 + 2.0 * (i as f64 + 0.5) / steps as f64;
                    let sin = (1.0 - cos * cos).max(0.0).sqrt();
                    let w = Vec3::new(sin as f32, -cos as f32, 0.0);
                    c.attenuation(w) as f64 * 2.0 / steps as f64
                })
                .sum::<f64>()
                * std::f64::consts::TAU;
            let closed = c.solid_angle() as f64;
            assert!(
                (closed - integral).abs() < 1e-4 * integral.max(1e-3),
                "inner {inner} outer {outer}: {closed} vs {integral}"
            );
            assert!(c.fault().is_none());
        }
        assert!((cone(1.5707964, 1.5707964).solid_angle() - std::f32::consts::TAU).abs() < 0.01);
        for bad in [
            cone(0.5, 0.4),
            cone(-0.1, 0.4),
            cone(0.0, 0.0),
            cone(0.0, 1.6),
            cone(0.0, f32::NAN),
            SpotCone {
                direction: Vec3::ZERO,
                ..cone(0.1, 0.2)
            },
        ] {
            assert!(bad.fault().is_some(), "{bad:?}");
        }
    }

    #[test]
    fn ids_cover_every_light_and_only_them() {
        let cornell = builtin::scene("cornell").unwrap();
        let ids = light_ids(&cornell);
        assert_eq!(ids.len(), 1);
        assert!(matches!(ids[0], LightId::Emissive(_)));
        assert!(ids[0].label(&cornell).starts_with("emissive mesh #"));
        let prim = builtin::scene("primitives").unwrap();
        assert_eq!(light_ids(&prim), vec![LightId::Directional(0)]);
    }

    #[test]
    fn keys_name_each_light_and_find_it_again() {
        let scene = builtin::scene("corridor").unwrap();
        for id in light_ids(&scene) {
            assert_eq!(LightId::find(&scene, &id.key()), Ok(id));
        }
        assert_eq!(LightId::Directional(2).key(), "directional:2");
        let e = LightId::find(&scene, "point:99").unwrap_err();
        assert_eq!(e.key, "point:99");
        assert!(e.known.contains(&"point:0".to_string()));
        let e = e.to_string();
        assert!(
            e.contains("no light 'point:99'") && e.contains("point:0"),
            "{e}"
        );
        let e = LightId::find(&builtin::scene("primitives").unwrap(), "sun").unwrap_err();
        assert_eq!(e.known, vec!["directional:0".to_string()]);
        assert!(e.to_string().contains("its lights: directional:0"), "{e}");
    }

    #[test]
    fn state_defaults_and_only() {
        let scene = builtin::scene("corridor").unwrap();
        let mut s = LightState::default();
        assert!(s.is_default());
        s.set_color(LightId::Point(1), Vec3::new(2.0, 1.0, 0.5));
        assert!(!s.is_default());
        assert_eq!(
            s.get(LightId::Point(1)).direct_factor(),
            Vec3::new(2.0, 1.0, 0.5)
        );
        s.set_color(LightId::Point(1), Vec3::ONE);
        assert!(
            s.is_default(),
            "back to the default setting removes the entry"
        );
        let one = LightState::only(&scene, LightId::Point(3));
        for id in light_ids(&scene) {
            assert_eq!(one.get(id).enabled, id == LightId::Point(3));
        }
        assert_ne!(one.fingerprint(), LightState::default().fingerprint());
        let mut bad = LightState::default();
        bad.set_color(LightId::Point(0), Vec3::new(-1.0, 0.0, 0.0));
        let e = bad.check(&scene).unwrap_err();
        assert_eq!(e.light, LightId::Point(0));
        assert!(e.to_string().contains("point light #0"), "{e}");
    }

    #[test]
    fn emitter_table_picks_by_power_and_follows_the_state() {
        let scene = builtin::scene("cornell").unwrap();
        let e = Emitters::new(&scene, &LightState::default());
        assert_eq!(e.triangles.len(), 2);
        let sum: f64 = (0..e.triangles.len()).map(|k| e.pick_probability(k)).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        // Two triangles of one quad: probabilities proportional to area.
        let a: f64 = e.triangles.iter().map(|t| f64::from(t.area)).sum();
        for (k, t) in e.triangles.iter().enumerate() {
            assert!((e.pick_probability(k) - f64::from(t.area) / a).abs() < 1e-6);
            assert_eq!(e.probability_of_triangle(t.triangle), e.pick_probability(k));
        }
        let id = light_ids(&scene)[0];
        let mut off = LightState::default();
        off.set_enabled(id, false);
        let e = Emitters::new(&scene, &off);
        assert!(e.is_empty() && e.pick(0.5).is_none());
        assert_eq!(e.triangles.len(), 2, "still listed, never picked");
    }
}
