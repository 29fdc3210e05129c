//! Lights with exponential shadow maps, shared by every method that shades direct light per
//! pixel from a G-buffer: ISR's lighting phase and its `dl` technique (ISR thesis section
//! 4.5, listing 7; shadows section 4.6, eq. 30, listing 8, in [`esm`]) and relighting's
//! per-frame direct light.
//!
//! A [`LightSet`] holds lights (point, spot, directional, the sky's directions, and point
//! samples standing in for emissive triangles), their shadow maps and a table of emissive
//! triangles, prepared once from a [`Scene`] ([`LightSet::new`]) or from an engine's own
//! light list and shadow-casting triangles ([`LightSet::from_lights`]). Per frame, a
//! [`LightState`] scales each light's direct and indirect light ([`LightSet::apply`])
//! without rebuilding anything. The WGSL twins are `shaders/scene-core/light_set.wgsl`
//! (`scene_core::light_set`) and `shaders/scene-core/shadow.wgsl` (`scene_core::shadow`);
//! [`gpu`] packs a set for them.

use crate::lights::{Emitters, LightId, LightState, SpotRamp};
use crate::ray::RayScene;
use crate::sampling::{r2, uniform_triangle};
use crate::{Bounds, BudgetExceeded, Scene};
use glam::{Vec2, Vec3};

pub mod esm;
#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "gpu")]
pub mod gpu_maps;

use esm::{MapKind, ShadowMap};

/// Why a [`LightSet`] could not be built.
#[derive(Debug, thiserror::Error)]
pub enum LightSetError {
    /// A [`ShadowSettings`] field is out of range.
    #[error("invalid shadow setting {name} = {value}: {reason}")]
    InvalidSetting {
        /// The field.
        name: &'static str,
        /// Its value.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A light or shadow caster is not usable (not finite, no direction), named.
    #[error("{0}")]
    BadScene(String),
    /// The shadow maps do not fit [`ShadowSettings::max_texels`].
    #[error("budget exceeded: {0}")]
    Budget(BudgetExceeded),
}

/// The exponential shadow maps (eq. 30, listing 8), built once per scene by
/// [`LightSet::new`]: they do not depend on the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowSettings {
    /// Shadows on; off, every light reaches every surface facing it.
    pub enabled: bool,
    /// Texels per side of a directional light's orthographic map. The most: above the
    /// default (2 048), where the maps would not fit [`ShadowSettings::max_texels`], the
    /// suns' maps are halved first, down to the default ([`LightSet::directional_resolution`]
    /// is the one used).
    pub directional_resolution: u32,
    /// Texels per side of the orthographic map of each of the sky's directions
    /// ([`crate::sky::Sky::lights`]): many, each carrying a small share of soft light,
    /// so coarser than a sun's. The most: where the maps would not fit
    /// [`ShadowSettings::max_texels`], the sky's are halved first (down to 64 texels, many
    /// directions at 512 would be gigabytes), then the cubes ([`LightSet::sky_resolution`]
    /// is the one used).
    pub sky_resolution: u32,
    /// Texels per side of each cube-map face of a point light.
    pub cube_resolution: u32,
    /// Point samples standing in for the emissive triangles (0: emitters light nothing, they
    /// are only seen).
    pub emitter_samples: u32,
    /// Texels per side of each cube-map face of an emitter sample.
    pub emitter_cube_resolution: u32,
    /// The ESM exponent `c` of eq. 30, applied to depths measured in units of the scene's
    /// extent (so the softness does not depend on the scene's unit). Maps are filtered in
    /// log space and every exponential is of a non-positive argument, so no value of `c`
    /// can overflow f32 (the thesis' `exp(90 z)` of a stored depth `z` near 1 would).
    ///
    /// A receiver `delta` behind its occluder is lit by `exp(-c delta / extent)` on an
    /// unfiltered map: the default 4 000 lets through 1/e at a 4 000th of the extent
    /// (1.7 mm in a 6.7 m room), where 200 let through 55 % of the sun between a blind's
    /// slats 2 cm apart (docs/isr.md, "Lighting and shadows").
    pub esm_exponent: f32,
    /// Taps on each side of the log-space Gaussian prefilter of the cube maps (point lights
    /// and emitter samples; 0: none); at most 4. The thesis prefilters its maps (section
    /// 4.6); on the cube maps it keeps the band just below an emitter's plane lit (without
    /// it DL's direct light on the Cornell box reads 1.3 points darker, 4.2 points with
    /// maps of 32 texels a side).
    pub filter_radius: u32,
    /// The same prefilter's taps on the orthographic maps (suns, a sky's directions): 0, the
    /// default, leaves them unfiltered. In log space the filtered depth tends to the
    /// window's farthest, so a receiver within a texel of an edge beyond which the map sees
    /// a farther surface reads lit: with `c` 4 000, radius 1 read DL +90 % over the
    /// reference's lit surfaces on a window-lit room's main view where 0 reads +1 %
    /// (docs/isr.md).
    pub directional_filter_radius: u32,
    /// Receivers are moved this many shadow-map texels along their normal before the lookup
    /// (against self-shadowing).
    pub normal_offset: f32,
    /// Constant depth bias in shadow-map texels.
    pub depth_bias: f32,
    /// Penumbrae for directional lights with a spread ([`Light::radius`]; the sky's
    /// directions carry their regions' cones, [`crate::sky::Sky::spreads`]): their maps
    /// are looked up softly ([`esm::ShadowMap::spread`], percentage-closer soft shadows),
    /// each direction casting the penumbra of its region. Off by default: in the
    /// sun-and-sky window room of `tests/tests/sky.rs` relighting's maps read 0.142 off
    /// the reference with them and 0.171 without (the gather 0.164), but on the Breakfast
    /// Room they changed nothing (0.07342 against 0.07341) and cost DL's new view 3x
    /// (162.7 against 54.5 ms at 128 x 96 on 2 cores): ten texels searched per lookup,
    /// sixteen more on a third of them, where a hard lookup reads four (docs/scene-core.md).
    pub penumbrae: bool,
    /// Budget of shadow-map texels over all maps. Cube maps are halved in resolution (down to
    /// 16 texels) until they fit; beyond that [`LightSet::new`] fails.
    pub max_texels: u64,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            directional_resolution: 2048,
            sky_resolution: 512,
            cube_resolution: 256,
            emitter_samples: 16,
            emitter_cube_resolution: 128,
            esm_exponent: 4000.0,
            filter_radius: 1,
            directional_filter_radius: 0,
            normal_offset: 1.5,
            depth_bias: 1.0,
            penumbrae: false,
            max_texels: 1 << 25,
        }
    }
}

impl ShadowSettings {
    /// The prefilter's taps on each side for a map of `kind` (at most 4):
    /// [`ShadowSettings::filter_radius`] for cube maps,
    /// [`ShadowSettings::directional_filter_radius`] for orthographic ones.
    pub fn filter_radius_of(&self, kind: &MapKind) -> u32 {
        match kind {
            MapKind::Cube { .. } => self.filter_radius,
            MapKind::Ortho { .. } => self.directional_filter_radius,
        }
        .min(4)
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), LightSetError> {
        let bad = |name: &'static str, value: String, reason: &str| {
            Err(LightSetError::InvalidSetting {
                name,
                value,
                reason: reason.into(),
            })
        };
        for (name, r) in [
            ("directional_resolution", self.directional_resolution),
            ("sky_resolution", self.sky_resolution),
            ("cube_resolution", self.cube_resolution),
            ("emitter_cube_resolution", self.emitter_cube_resolution),
        ] {
            if !(1..=8192).contains(&r) {
                return bad(name, r.to_string(), "must be in 1..=8192");
            }
        }
        if self.emitter_samples > 4096 {
            return bad(
                "emitter_samples",
                self.emitter_samples.to_string(),
                "at most 4096",
            );
        }
        if !(self.esm_exponent.is_finite() && self.esm_exponent > 0.0) {
            return bad(
                "esm_exponent",
                self.esm_exponent.to_string(),
                "must be positive and finite",
            );
        }
        if self.filter_radius > 4 {
            return bad("filter_radius", self.filter_radius.to_string(), "at most 4");
        }
        if self.directional_filter_radius > 4 {
            return bad(
                "directional_filter_radius",
                self.directional_filter_radius.to_string(),
                "at most 4",
            );
        }
        for (name, v) in [
            ("normal_offset", self.normal_offset),
            ("depth_bias", self.depth_bias),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v.to_string(), "must be finite and >= 0");
            }
        }
        Ok(())
    }
}

/// What kind of light a [`Light`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightKind {
    /// A point light: irradiance `I falloff(d) cos` (inverse square, or eq. 16's window).
    Point,
    /// A directional light: irradiance `E cos`.
    Directional,
    /// A point sample of an emissive triangle with a cosine profile (one-sided):
    /// irradiance `L A cos_l cos / (d^2 + A / pi)`, the disk form factor, which stays finite
    /// on the emitter itself.
    EmitterSample,
}

/// Which part of a light's contribution a sum is for: what reaches a surface straight from
/// the light (the lighting pass) or what it then reflects on as a sender of the ISR bounce.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// Direct light: scaled by [`Light::direct`].
    Direct,
    /// Light that goes on to be reflected (the `Lit` senders): scaled by [`Light::indirect`].
    Indirect,
}

/// One light of the lighting phase.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Light {
    /// Its kind.
    pub kind: LightKind,
    /// Position (point lights and emitter samples).
    pub position: Vec3,
    /// Unit direction the light travels (directional) or the emitting side's unit normal
    /// (emitter samples).
    pub direction: Vec3,
    /// Intensity (point), irradiance (directional) or emitted radiance (emitter sample).
    pub color: Vec3,
    /// Point lights: the radius of eq. 16's windowed falloff (0 for inverse square).
    /// Directional lights: the light's spread, the tangent of the half-angle of the cone
    /// of directions it arrives from (0, the default, a hard shadow): its shadow map gives
    /// it the penumbra that cone casts ([`esm::visibility`]). The sky's directions carry
    /// their regions' spreads ([`crate::sky::Sky::spreads`]).
    pub radius: f32,
    /// The emitter area the sample stands for (emitter samples only).
    pub area: f32,
    /// Its shadow map, when shadows are on.
    pub shadow: Option<ShadowMap>,
    /// The frame's factor on its direct light (from a [`LightState`]; 1 by default).
    pub direct: Vec3,
    /// The frame's factor on the light it sends on to be reflected (1 by default).
    pub indirect: Vec3,
    /// The light source it belongs to (an emitter sample: its emissive mesh). Engines
    /// number their own lights with [`LightId::Point`] and [`LightId::Directional`].
    pub id: LightId,
    /// A spot's cone ramp ([`Light::spot`]; point lights only, its axis also in
    /// `direction` for the shaders): the intensity towards `w` is scaled by
    /// [`SpotRamp::attenuation`]. [`SpotRamp::NONE`] for every other light.
    pub spot: SpotRamp,
}

impl Light {
    /// A point light of `intensity` at `position`, inverse-square falloff (set
    /// [`Light::radius`] for eq. 16's window), no shadow map yet.
    pub fn point(id: LightId, position: Vec3, intensity: Vec3) -> Self {
        Self {
            id,
            kind: LightKind::Point,
            position,
            direction: Vec3::ZERO,
            color: intensity,
            radius: 0.0,
            area: 0.0,
            shadow: None,
            direct: Vec3::ONE,
            indirect: Vec3::ONE,
            spot: SpotRamp::NONE,
        }
    }

    /// A spot light: [`Light::point`] limited to `cone` (glTF's cone falloff).
    pub fn spot(
        id: LightId,
        position: Vec3,
        intensity: Vec3,
        cone: &crate::lights::SpotCone,
    ) -> Self {
        let spot = cone.ramp();
        Self {
            direction: spot.axis,
            spot,
            ..Self::point(id, position, intensity)
        }
    }

    /// A directional light of `irradiance` travelling along `direction` (normalised here).
    pub fn directional(id: LightId, direction: Vec3, irradiance: Vec3) -> Self {
        Self {
            kind: LightKind::Directional,
            direction: direction.normalize_or_zero(),
            ..Self::point(id, Vec3::ZERO, irradiance)
        }
    }

    /// The factor of `part`.
    pub fn factor(&self, part: Part) -> Vec3 {
        match part {
            Part::Direct => self.direct,
            Part::Indirect => self.indirect,
        }
    }

    /// Unshadowed irradiance at `p` on a surface of unit normal `n` (two-sided surfaces:
    /// `n` faces the viewer): the `k_dl` factor of listing 7 before shadowing, with eq. 16's
    /// falloff for point lights that have a radius and the cone of spots.
    pub fn irradiance(&self, p: Vec3, n: Vec3) -> Vec3 {
        match self.kind {
            LightKind::Point => {
                let to = self.position - p;
                let d = to.length();
                if d.is_nan() || d <= 0.0 {
                    return Vec3::ZERO;
                }
                let cos = n.dot(to / d);
                if cos <= 0.0 {
                    return Vec3::ZERO;
                }
                let a = self.spot.attenuation(-to / d);
                self.color * (falloff(self.radius, d) * cos * a)
            }
            LightKind::Directional => {
                let cos = -n.dot(self.direction);
                if cos <= 0.0 {
                    return Vec3::ZERO;
                }
                self.color * cos
            }
            LightKind::EmitterSample => {
                let to = self.position - p;
                let d2 = to.length_squared();
                if d2.is_nan() || d2 <= 0.0 {
                    return Vec3::ZERO;
                }
                let w = to / d2.sqrt();
                let cos = n.dot(w);
                let cos_l = -self.direction.dot(w);
                if cos <= 0.0 || cos_l <= 0.0 {
                    return Vec3::ZERO;
                }
                self.color
                    * (self.area * cos_l * cos / (d2 + self.area * std::f32::consts::FRAC_1_PI))
            }
        }
    }
}

/// The distance falloff of a point light whose eq. 16 radius is `radius` (0: inverse
/// square): scene-core's [`crate::lights::falloff`].
pub fn falloff(radius: f32, d: f32) -> f32 {
    crate::lights::falloff((radius > 0.0).then_some(radius), d)
}

/// Emissive triangles, for the emission of directly visible emitters.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EmitterTable {
    /// Per global triangle id: index into `entries`, or `u32::MAX` for non-emitters.
    pub per_triangle: Vec<u32>,
    /// `(emitted radiance, unit geometric normal of the emitting side)`.
    pub entries: Vec<(Vec3, Vec3)>,
    /// The light source (emissive mesh) of each entry.
    pub ids: Vec<LightId>,
    /// The frame's factor on each entry's emission seen directly (1 by default).
    pub direct: Vec<Vec3>,
}

impl EmitterTable {
    /// The radiance a triangle sends towards `to_viewer` (unit): its emission on the
    /// winding's front side, zero elsewhere and for unknown ids.
    pub fn emission(&self, triangle: u32, to_viewer: Vec3) -> Vec3 {
        match self.per_triangle.get(triangle as usize) {
            Some(&e) if e != u32::MAX => {
                let (l, n) = self.entries[e as usize];
                if n.dot(to_viewer) > 0.0 {
                    l * self.direct.get(e as usize).copied().unwrap_or(Vec3::ONE)
                } else {
                    Vec3::ZERO
                }
            }
            _ => Vec3::ZERO,
        }
    }
}

/// One shadow map of a plan ([`LightSet::planned`]): the light it belongs to (index into
/// [`LightSet::lights`]), its placement, and the depth (in scene extents) it stores where
/// nothing is hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedMap {
    /// Index of the light.
    pub light: usize,
    /// The map's kind, resolution and first texel.
    pub map: ShadowMap,
    /// The depth of a texel that sees nothing.
    pub miss: f32,
}

/// Lights, their shadow maps and the emissive triangles. View-independent: build it once per
/// scene (the methods' [`Technique::prepare`](crate::Technique::prepare) does) or once per
/// engine light rig, and [`LightSet::apply`] each frame's [`LightState`].
#[derive(Clone, Debug, PartialEq)]
pub struct LightSet {
    /// The scene's extent (diagonal of its bounds; 1 when empty): the unit of relative
    /// radii and of shadow-map depths.
    pub extent: f32,
    /// All lights, emitter samples included.
    pub lights: Vec<Light>,
    /// All shadow maps' texels, concatenated (see [`ShadowMap::offset`]).
    pub shadow_texels: Vec<f32>,
    /// Emissive triangles.
    pub emitters: EmitterTable,
    /// The shadow settings the maps were built with.
    pub shadows: ShadowSettings,
    /// The cube-map resolution actually used after fitting [`ShadowSettings::max_texels`]
    /// (point lights, emitter samples).
    pub cube_resolutions: (u32, u32),
    /// The sky maps' resolution actually used after fitting [`ShadowSettings::max_texels`]
    /// (at most [`ShadowSettings::sky_resolution`]).
    pub sky_resolution: u32,
    /// The suns' (directional lights other than the sky's) map resolution actually used
    /// after fitting [`ShadowSettings::max_texels`] (at most
    /// [`ShadowSettings::directional_resolution`]).
    pub directional_resolution: u32,
    /// The bounds the shadow maps cover (the scene's, or the engine's casters and lights).
    pub bounds: Bounds,
}

impl LightSet {
    /// Prepares `scene` (which should be validated): resolves lights, places
    /// `shadows.emitter_samples` stratified point samples on the emissive triangles (each
    /// sample picks a triangle by the stratum `(k + 1/2)/S` of the power distribution and a
    /// point in it by the R2 sequence), and renders and filters the shadow maps.
    ///
    /// Errors on invalid settings, non-finite light data, or shadow maps that do not fit
    /// `shadows.max_texels` even at 16 texels per cube face.
    pub fn new(scene: &Scene, shadows: &ShadowSettings) -> Result<Self, LightSetError> {
        Self::from_scene(scene, shadows, || Box::new(RayScene::build(scene)))
    }

    /// [`LightSet::new`] with the cube maps cast through `rays`, the caller's ray-query tree
    /// of `scene` ([`RayScene::build`]), so that a method that traces the scene too builds
    /// one tree, not two.
    pub fn with_rays(
        scene: &Scene,
        shadows: &ShadowSettings,
        rays: &RayScene,
    ) -> Result<Self, LightSetError> {
        Self::from_scene(scene, shadows, || rays)
    }

    fn from_scene<R: std::ops::Deref<Target = RayScene>>(
        scene: &Scene,
        shadows: &ShadowSettings,
        rays: impl FnOnce() -> R,
    ) -> Result<Self, LightSetError> {
        shadows.validate()?;
        let extent = scene.extent();
        let mut lights = Vec::new();
        for (i, l) in scene.point_lights.iter().enumerate() {
            if !(l.position.is_finite() && l.intensity.is_finite()) {
                return Err(LightSetError::BadScene(format!(
                    "point light #{i} '{}' is not finite",
                    l.name
                )));
            }
            lights.push(Light {
                radius: l
                    .radius
                    .filter(|r| *r > 0.0 && r.is_finite())
                    .unwrap_or(0.0),
                ..match &l.cone {
                    Some(cone) => Light::spot(
                        LightId::Point(i as u32),
                        l.position,
                        l.intensity.max(Vec3::ZERO),
                        cone,
                    ),
                    None => Light::point(
                        LightId::Point(i as u32),
                        l.position,
                        l.intensity.max(Vec3::ZERO),
                    ),
                }
            });
        }
        // The scene's directional lights, then the sky as its median-cut directions, each
        // with its region's spread.
        let mut spreads = scene
            .sky
            .iter()
            .flat_map(|sky| sky.spreads().iter().copied());
        for (id, l) in crate::lights::directional_sources(scene) {
            let d = l.direction.normalize_or_zero();
            if d == Vec3::ZERO || !l.irradiance.is_finite() {
                return Err(LightSetError::BadScene(format!(
                    "{}: directional light '{}' has no direction or a non-finite irradiance",
                    id.label(scene),
                    l.name
                )));
            }
            let spread = match id {
                LightId::Sky => spreads.next().unwrap_or(0.0),
                _ => 0.0,
            };
            lights.push(Light {
                radius: spread,
                ..Light::directional(id, d, l.irradiance.max(Vec3::ZERO))
            });
        }
        let (emitters, samples) = emitters(scene, shadows.emitter_samples, extent);
        lights.extend(samples);

        let mut this = Self {
            extent,
            lights,
            shadow_texels: Vec::new(),
            emitters,
            shadows: *shadows,
            cube_resolutions: (shadows.cube_resolution, shadows.emitter_cube_resolution),
            sky_resolution: shadows.sky_resolution,
            directional_resolution: shadows.directional_resolution,
            bounds: scene.bounds(),
        };
        if shadows.enabled && !this.lights.is_empty() {
            let cutouts = crate::cutout::Cutouts::of(scene);
            this.build_shadow_maps(&scene.triangle_corners(), &cutouts, rays)?;
        }
        Ok(this)
    }

    /// A light set from an engine's own lights (made with [`Light::point`] and
    /// [`Light::directional`]; [`LightKind::EmitterSample`]s are accepted too) and the
    /// triangles that cast their shadows, with no [`Scene`]. The shadow maps are rendered
    /// over `casters` (orthographic maps rasterised, cube maps by a ray per texel); with no casters, or with
    /// `shadows.enabled` off, the lights are unshadowed. The extent (the unit of relative
    /// radii and of shadow depths) is the diagonal of the bounds of the casters and
    /// the point lights.
    ///
    /// Errors on invalid settings, a non-finite light or caster, a directional light with
    /// no direction, and shadow maps over `shadows.max_texels`.
    pub fn from_lights(
        lights: Vec<Light>,
        casters: &[[Vec3; 3]],
        shadows: &ShadowSettings,
    ) -> Result<Self, LightSetError> {
        let mut this = Self::engine(lights, casters, Bounds::EMPTY, shadows)?;
        if shadows.enabled && !casters.is_empty() && !this.lights.is_empty() {
            let none = crate::cutout::Cutouts::default();
            this.build_shadow_maps(casters, &none, || {
                Box::new(RayScene::from_triangles(casters))
            })?;
        } else {
            this.shadows.enabled = false;
        }
        Ok(this)
    }

    /// A light set from an engine's own lights whose shadow maps the GPU renders from the
    /// engine's vertex and index buffers ([`gpu_maps::ShadowMapPass`], with the `gpu` feature):
    /// the maps are placed as [`LightSet::from_lights`] would place them over casters
    /// within `caster_bounds`, and their texels hold the depth of an empty map (every
    /// receiver lit) until the pass has run and its texels are read back or copied in.
    /// Returns the maps in texel order too. With `shadows.enabled` off, or no lights, no map
    /// is placed and the lights are unshadowed.
    ///
    /// Errors as [`LightSet::from_lights`], and on `caster_bounds` that are not finite.
    pub fn planned(
        lights: Vec<Light>,
        caster_bounds: Bounds,
        shadows: &ShadowSettings,
    ) -> Result<(Self, Vec<PlannedMap>), LightSetError> {
        let finite = caster_bounds.min.is_finite() && caster_bounds.max.is_finite();
        if !caster_bounds.is_empty() && !finite {
            return Err(LightSetError::BadScene(
                "the shadow casters' bounds are not finite".into(),
            ));
        }
        let mut this = Self::engine(lights, &[], caster_bounds, shadows)?;
        if !shadows.enabled || this.lights.is_empty() {
            this.shadows.enabled = false;
            return Ok((this, Vec::new()));
        }
        let planned = this.plan_shadow_maps()?;
        let mut texels = Vec::with_capacity(planned.iter().map(|p| p.map.len()).sum());
        for p in &planned {
            texels.resize(texels.len() + p.map.len(), p.miss);
        }
        this.shadow_texels = texels;
        Ok((this, planned))
    }

    /// The lights of an engine checked and the bounds (of `casters`, `extra` and the point
    /// lights) measured; no shadow map yet.
    fn engine(
        lights: Vec<Light>,
        casters: &[[Vec3; 3]],
        extra: Bounds,
        shadows: &ShadowSettings,
    ) -> Result<Self, LightSetError> {
        shadows.validate()?;
        let mut bounds = extra;
        for (i, l) in lights.iter().enumerate() {
            let finite = l.position.is_finite()
                && l.direction.is_finite()
                && l.color.is_finite()
                && l.radius.is_finite()
                && l.area.is_finite();
            if !finite {
                return Err(LightSetError::BadScene(format!(
                    "light #{i} ({:?}) is not finite",
                    l.id
                )));
            }
            if l.kind == LightKind::Directional && l.direction == Vec3::ZERO {
                return Err(LightSetError::BadScene(format!(
                    "directional light #{i} ({:?}) has no direction",
                    l.id
                )));
            }
            if l.kind != LightKind::Directional {
                bounds.grow(l.position);
            }
        }
        for (i, t) in casters.iter().enumerate() {
            if !t.iter().all(|p| p.is_finite()) {
                return Err(LightSetError::BadScene(format!(
                    "shadow caster #{i} is not finite"
                )));
            }
            t.iter().for_each(|p| bounds.grow(*p));
        }
        let extent = if bounds.is_empty() {
            1.0
        } else {
            bounds.diagonal().max(f32::MIN_POSITIVE)
        };
        Ok(Self {
            extent,
            lights: lights
                .into_iter()
                .map(|l| Light {
                    color: l.color.max(Vec3::ZERO),
                    direction: l.direction.normalize_or_zero(),
                    shadow: None,
                    ..l
                })
                .collect(),
            shadow_texels: Vec::new(),
            emitters: EmitterTable::default(),
            shadows: *shadows,
            cube_resolutions: (shadows.cube_resolution, shadows.emitter_cube_resolution),
            sky_resolution: shadows.sky_resolution,
            directional_resolution: shadows.directional_resolution,
            bounds,
        })
    }

    /// Sets every light's direct and indirect factors from `state` (lights it does not
    /// mention: 1). Cheap (no shadow map is touched): call it every frame.
    pub fn apply(&mut self, state: &LightState) {
        for l in &mut self.lights {
            let s = state.get(l.id);
            l.direct = s.direct_factor();
            l.indirect = s.indirect_factor();
        }
        self.emitters.direct = self
            .emitters
            .ids
            .iter()
            .map(|id| state.get(*id).direct_factor())
            .collect();
    }

    /// Places every light's shadow map (kind, resolution, first texel; the cube resolutions
    /// fitted to [`ShadowSettings::max_texels`]) without rendering any: what the CPU's ray
    /// cast ([`LightSet::new`], [`LightSet::from_lights`]) and the GPU's raster
    /// ([`LightSet::planned`], `gpu_maps`) then fill. Sets each light's
    /// [`Light::shadow`] and returns the maps in texel order with the depth each stores
    /// where nothing is hit.
    fn plan_shadow_maps(&mut self) -> Result<Vec<PlannedMap>, LightSetError> {
        let s = &self.shadows;
        let count = |kind: LightKind| self.lights.iter().filter(|l| l.kind == kind).count() as u64;
        let (n_point, n_dir, n_emit) = (
            count(LightKind::Point),
            count(LightKind::Directional),
            count(LightKind::EmitterSample),
        );
        let (mut cube, mut emit) = (s.cube_resolution, s.emitter_cube_resolution);
        let n_sky = self
            .lights
            .iter()
            .filter(|l| l.kind == LightKind::Directional && l.id == LightId::Sky)
            .count() as u64;
        let (mut sun, mut sky) = (s.directional_resolution, s.sky_resolution);
        let dir_texels = |sun: u32, sky: u32| {
            (n_dir - n_sky) * (sun as u64).pow(2) + n_sky * (sky as u64).pow(2)
        };
        let cubes = 6 * n_point * (cube as u64).pow(2) + 6 * n_emit * (emit as u64).pow(2);
        // Suns finer than the default give way first, down to it (a caller that asks for
        // more, as relighting does, gets it where the budget holds it beside the rest).
        let sun_floor = ShadowSettings::default().directional_resolution.min(sun);
        while n_dir > n_sky && dir_texels(sun, sky) + cubes > s.max_texels && sun > sun_floor {
            sun = (sun / 2).max(sun_floor);
        }
        // Then the sky's many maps, down to 64 texels (or their setting if less).
        while n_sky > 0 && dir_texels(sun, sky) + cubes > s.max_texels && sky > 64 {
            sky = (sky / 2).max(64);
        }
        let total = |c: u32, e: u32| {
            dir_texels(sun, sky) + 6 * n_point * (c as u64).pow(2) + 6 * n_emit * (e as u64).pow(2)
        };
        while total(cube, emit) > s.max_texels && (cube > 16 || emit > 16) {
            cube = (cube / 2).max(16.min(cube));
            emit = (emit / 2).max(16.min(emit));
        }
        if total(cube, emit) > s.max_texels {
            return Err(LightSetError::Budget(BudgetExceeded {
                what: "shadow maps at 16 texels per cube face".into(),
                needed: total(cube, emit),
                limit: s.max_texels,
                unit: "texels",
                hint: "ShadowSettings::max_texels; lower directional_resolution or sky_resolution, or raise it".into(),
            }));
        }
        self.cube_resolutions = (cube, emit);
        self.sky_resolution = sky;
        self.directional_resolution = sun;
        let bounds = self.bounds;
        let extent = self.extent;
        let center = if bounds.is_empty() {
            Vec3::ZERO
        } else {
            bounds.center()
        };
        let half = 0.5 * extent;
        let mut offset = 0;
        let mut planned = Vec::with_capacity(self.lights.len());
        for (index, light) in self.lights.iter_mut().enumerate() {
            let (kind, res) = match light.kind {
                LightKind::Directional => {
                    let view = crate::View::orthographic_fit(center, light.direction, half);
                    (
                        MapKind::Ortho {
                            eye: view.eye,
                            right: view.right(),
                            up: view.up,
                            forward: view.forward,
                            half_extent: half,
                        },
                        if light.id == LightId::Sky { sky } else { sun },
                    )
                }
                LightKind::Point => (
                    MapKind::Cube {
                        center: light.position,
                    },
                    cube,
                ),
                LightKind::EmitterSample => (
                    MapKind::Cube {
                        center: light.position,
                    },
                    emit,
                ),
            };
            let miss = match kind {
                MapKind::Cube { center: p } => {
                    // Farther than anything in the scene.
                    let far = if bounds.is_empty() {
                        1.0
                    } else {
                        (p - bounds.min).abs().max((p - bounds.max).abs()).length()
                    };
                    far / extent + 1.0
                }
                MapKind::Ortho { half_extent, .. } => 4.0 * half_extent / extent,
            };
            let mut map = ShadowMap::new(offset, res, kind);
            if light.kind == LightKind::Directional && s.penumbrae {
                map.spread = light.radius.clamp(0.0, crate::sky::MAX_SPREAD);
            }
            offset += map.len();
            light.shadow = Some(map);
            planned.push(PlannedMap {
                light: index,
                map,
                miss,
            });
        }
        Ok(planned)
    }

    /// Renders and filters the planned maps: the orthographic ones (suns, the sky) by
    /// rasterising `triangles` ([`esm::raster_ortho`], alpha holes from `cutouts`), the cube
    /// ones by a ray per texel through the tree `rays` makes (made only when a cube map is
    /// planned).
    fn build_shadow_maps<R: std::ops::Deref<Target = RayScene>>(
        &mut self,
        triangles: &[[Vec3; 3]],
        cutouts: &crate::cutout::Cutouts,
        rays: impl FnOnce() -> R,
    ) -> Result<(), LightSetError> {
        let planned = self.plan_shadow_maps()?;
        let rays = std::cell::LazyCell::new(rays);
        let extent = self.extent;
        let c = self.shadows.esm_exponent;
        let mut texels = Vec::with_capacity(planned.iter().map(|p| p.map.len()).sum());
        for p in &planned {
            let res = p.map.resolution;
            let (mut map, faces) = match p.map.kind {
                MapKind::Cube { center } => {
                    (esm::render_cube(&rays, center, res, extent, p.miss), 6)
                }
                MapKind::Ortho { .. } => (
                    esm::raster_ortho(triangles, cutouts, &p.map.kind, res, extent),
                    1,
                ),
            };
            let filter = self.shadows.filter_radius_of(&p.map.kind);
            esm::log_filter(&mut map, res, faces, filter, c);
            texels.extend_from_slice(&map);
        }
        self.shadow_texels = texels;
        Ok(())
    }

    /// True when the scene has any light: a light, an emitter sample or a visible emitter.
    /// Without any, nothing can be bounced (ISR then adds nothing, even with senders that do
    /// not depend on the lights).
    pub fn has_light(&self) -> bool {
        !self.lights.is_empty() || !self.emitters.entries.is_empty()
    }

    /// The shadowed irradiance at `p` (unit normal `n`) from all lights: listing 7's direct
    /// lighting times listing 8's shadow factor (eq. 30) per light, each light scaled by its
    /// factor for `part`.
    pub fn irradiance(&self, p: Vec3, n: Vec3, part: Part) -> Vec3 {
        (0..self.lights.len())
            .map(|i| self.light_irradiance(i, p, n) * self.lights[i].factor(part))
            .sum()
    }

    /// The shadowed irradiance at `p` (unit normal `n`) from light `index` alone, before its
    /// frame factors: what a caller that weighs lights itself (relighting's sources) sums.
    pub fn light_irradiance(&self, index: usize, p: Vec3, n: Vec3) -> Vec3 {
        let l = self.lights[index].irradiance(p, n);
        if l == Vec3::ZERO {
            return l;
        }
        l * self.light_visibility(index, p, n)
    }

    /// The width of a texel of light `index`'s shadow map at `p` ([`esm::ShadowMap::texel_at`]);
    /// `None` without a map or with shadows off.
    pub fn light_texel(&self, index: usize, p: Vec3) -> Option<f32> {
        match (&self.lights[index].shadow, self.shadows.enabled) {
            (Some(map), true) => Some(map.texel_at(p)),
            _ => None,
        }
    }

    /// The shadow factor of light `index` at `p` (unit normal `n`): eq. 30 with listing 8's
    /// PCF on its map, 1 without a map or with shadows off.
    pub fn light_visibility(&self, index: usize, p: Vec3, n: Vec3) -> f32 {
        match (&self.lights[index].shadow, self.shadows.enabled) {
            (Some(map), true) => {
                esm::visibility(&self.shadow_texels, map, p, n, self.extent, &self.shadows)
            }
            _ => 1.0,
        }
    }
}

/// The emissive-triangle table and `count` stratified point samples of the emitters, drawn
/// from scene-core's power table ([`Emitters`], the one the reference samples too).
fn emitters(scene: &Scene, count: u32, extent: f32) -> (EmitterTable, Vec<Light>) {
    let power = Emitters::new(scene, &LightState::default());
    let table = EmitterTable {
        per_triangle: power.per_triangle.clone(),
        entries: power
            .triangles
            .iter()
            .map(|t| (t.emission, t.normal))
            .collect(),
        ids: power
            .triangles
            .iter()
            .map(|t| LightId::Emissive(t.mesh))
            .collect(),
        direct: vec![Vec3::ONE; power.triangles.len()],
    };
    let mut samples = Vec::new();
    if count == 0 || power.is_empty() {
        return (table, samples);
    }
    let cutouts = crate::cutout::Cutouts::of(scene);
    for k in 0..count {
        let u = (k as f64 + 0.5) / count as f64;
        let Some(i) = power.pick(u) else {
            break;
        };
        let t = &power.triangles[i];
        let p = t.corners;
        let b = uniform_triangle(r2(k as u64, Vec2::ZERO));
        // A sample where an alpha mask cuts the emitter away stands for no light (the
        // reference's next-event estimate does the same): the samples' sum stays an
        // unbiased estimate of the light of what exists.
        if !cutouts.opaque(t.triangle, b) {
            continue;
        }
        let q = p[0] * (1.0 - b.x - b.y) + p[1] * b.x + p[2] * b.y;
        // The sample stands for area * (total / w) / count of emitter, so that the sum over
        // samples is an unbiased estimate of the emitters' light.
        let share = (t.area as f64 * power.total_weight / t.weight / count as f64) as f32;
        samples.push(Light {
            id: LightId::Emissive(t.mesh),
            direct: Vec3::ONE,
            indirect: Vec3::ONE,
            kind: LightKind::EmitterSample,
            // Off the emitter's surface, so its own triangle does not shadow it.
            position: q + t.normal * (1e-4 * extent),
            direction: t.normal,
            color: t.emission,
            radius: 0.0,
            area: share,
            shadow: None,
            spot: SpotRamp::NONE,
        });
    }
    (table, samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    /// A directional light with a spread `s` (a uniform cone of half-angle `atan s`) over
    /// a floor, half of it under a plate `h` above: the soft lookup's shadow factor across
    /// the plate's shadow edge follows the share of the cone the plate leaves open, the
    /// analytic share of a disk of radius `s h` that a straight edge `x` from its centre
    /// cuts off (`1 - (acos(x/R) - (x/R) sqrt(1 - (x/R)^2)) / pi` lit). The lookup's
    /// 16 taps on a disk differ from that profile by under 0.1 (0.08 measured, a tap being
    /// 1/16); half is
    /// lit at the edge, nothing a penumbra's width inside, everything a width outside; a
    /// light without a spread keeps its hard edge; a slanted light moves the edge where
    /// its rays say; without [`ShadowSettings::penumbrae`] the spread is ignored.
    #[test]
    fn a_spread_gives_the_penumbra_of_its_cone() {
        let (h, spread) = (0.5f32, 0.2f32);
        let quad = |y: f32, x0: f32, x1: f32| {
            let c = [
                Vec3::new(x0, y, -1.0),
                Vec3::new(x1, y, -1.0),
                Vec3::new(x1, y, 1.0),
                Vec3::new(x0, y, 1.0),
            ];
            [[c[0], c[1], c[2]], [c[0], c[2], c[3]]]
        };
        let mut casters = quad(0.0, -1.0, 1.0).to_vec();
        casters.extend(quad(h, 0.0, 1.0));
        let lit_share = |x: f32, r: f32| {
            // x > 0: the receiver's cone centre is x outside the shadow.
            let u = (x / r).clamp(-1.0, 1.0);
            let cut = (u.acos() - u * (1.0 - u * u).sqrt()) / std::f32::consts::PI;
            1.0 - cut
        };
        for (direction, edge) in [(Vec3::NEG_Y, 0.0), (Vec3::new(0.3, -1.0, 0.0), 0.3 * h)] {
            let light = |radius: f32| Light {
                radius,
                ..Light::directional(LightId::Directional(0), direction, Vec3::ONE)
            };
            let set = LightSet::from_lights(
                vec![light(spread), light(0.0)],
                &casters,
                // 5.6 mm texels: the penumbra (10 cm) within MAX_PENUMBRA's 32 texels.
                &ShadowSettings {
                    directional_resolution: 512,
                    penumbrae: true,
                    ..Default::default()
                },
            )
            .unwrap();
            let d = direction.normalize();
            // The penumbra's radius across the light, then along the floor.
            let r = spread * h / -d.y / -d.y;
            let mut last = 1.0f32;
            for k in -12..=12 {
                let x = edge + r * k as f32 / 10.0;
                let p = Vec3::new(x, 0.0, 0.1);
                let soft = set.light_visibility(0, p, Vec3::Y);
                let hard = set.light_visibility(1, p, Vec3::Y);
                let expect = lit_share(edge - x, r);
                assert!(
                    (soft - expect).abs() < 0.1,
                    "{direction}: at {x} soft {soft}, the cone's share {expect}"
                );
                assert!(soft <= last + 1e-6, "{direction}: not monotonic at {x}");
                last = soft;
                if (x - edge).abs() > 0.01 {
                    assert_eq!(hard > 0.5, x < edge, "{direction}: hard edge at {x}");
                }
            }
            let at = |x: f32| set.light_visibility(0, Vec3::new(x, 0.0, 0.1), Vec3::Y);
            assert!((at(edge) - 0.5).abs() < 0.07, "{direction}: {}", at(edge));
            assert!(at(edge + 1.2 * r) < 1e-3 && at(edge - 1.2 * r) == 1.0);
            let hard = LightSet::from_lights(
                vec![light(spread)],
                &casters,
                &ShadowSettings {
                    directional_resolution: 512,
                    ..Default::default()
                },
            )
            .unwrap();
            let p = Vec3::new(edge - 0.5 * r, 0.0, 0.1);
            assert_eq!(hard.light_visibility(0, p, Vec3::Y), 1.0);
            assert!(at(edge - 0.5 * r) < 0.95);
        }
    }

    #[test]
    fn emitter_samples_carry_the_emitters_power() {
        let scene = builtin::scene("cornell").unwrap();
        let s = LightSet::new(
            &scene,
            &ShadowSettings {
                enabled: false,
                emitter_samples: 7,
                ..Default::default()
            },
        )
        .unwrap();
        let samples: Vec<&Light> = s
            .lights
            .iter()
            .filter(|l| l.kind == LightKind::EmitterSample)
            .collect();
        assert_eq!(samples.len(), 7);
        // Sum of sample areas = emitter area (one emission colour).
        let area: f32 = samples.iter().map(|l| l.area).sum();
        assert!((area - 0.13 * 0.105).abs() < 1e-3 * area, "{area}");
        // Far from the light the samples act like a point of intensity L A cos.
        let p = Vec3::new(0.278, -10.0, 0.28);
        let e = s.irradiance(p, Vec3::Y, Part::Direct);
        let d2 = (samples[0].position - p).length_squared();
        let expect = samples[0].color * area / d2;
        assert!((e - expect).abs().max_element() < 1e-2 * expect.max_element());
        assert!(s.emitters.entries.len() == 2);
    }

    #[test]
    fn point_light_shadows_in_the_cornell_box() {
        let scene = builtin::scene("cornell-point").unwrap();
        let s = LightSet::new(
            &scene,
            &ShadowSettings {
                cube_resolution: 64,
                ..Default::default()
            },
        )
        .unwrap();
        // Open floor is lit as without shadows; the floor enclosed by the tall block is dark.
        let open = Vec3::new(0.45, 0.0, 0.1);
        let lit = s.irradiance(open, Vec3::Y, Part::Direct);
        let unshadowed = s.lights[0].irradiance(open, Vec3::Y);
        assert!(
            (lit - unshadowed).abs().max_element() < 0.05 * unshadowed.max_element(),
            "{lit} vs {unshadowed}"
        );
        let under = s.irradiance(Vec3::new(0.37, 0.0, 0.35), Vec3::Y, Part::Direct);
        assert!(
            under.max_element() < 1e-3 * unshadowed.max_element(),
            "{under}"
        );
        let all_finite = s.shadow_texels.iter().all(|t| t.is_finite());
        assert!(all_finite);
    }

    /// A sky of 256 directions at the default 512 texels would need 67 M texels: its maps
    /// are halved to 256 (16.8 M with the sun's 4.2 M, under the 33.6 M default budget)
    /// rather than refused; 64 directions keep 512.
    #[test]
    fn budget_halves_sky_maps_first() {
        let mut scene = builtin::scene("primitives").unwrap();
        let sky = crate::sky::Sky::uniform(Vec3::splat(0.5)).unwrap();
        scene.sky = Some(sky.with_directions(64).unwrap());
        let s = LightSet::new(&scene, &ShadowSettings::default()).unwrap();
        assert_eq!(s.sky_resolution, 512);
        scene.sky = Some(sky.with_directions(256).unwrap());
        let s = LightSet::new(&scene, &ShadowSettings::default()).unwrap();
        assert_eq!(s.sky_resolution, 256);
        let sky_maps = s.lights.iter().filter(|l| l.id == LightId::Sky).count();
        assert_eq!(sky_maps, 256);
        assert!(s.shadow_texels.len() as u64 <= ShadowSettings::default().max_texels);
    }

    /// Suns asked finer than the default give way before the sky: a sun at 4 096 with 64
    /// sky directions at 512 is exactly the default budget; one texel less and the sun goes
    /// back to 2 048 while the sky keeps 512 (before, the sky was halved to 256).
    #[test]
    fn budget_halves_fine_suns_before_the_sky() {
        let mut scene = builtin::scene("primitives").unwrap();
        let sky = crate::sky::Sky::uniform(Vec3::splat(0.5)).unwrap();
        scene.sky = Some(sky.with_directions(64).unwrap());
        let fine = ShadowSettings {
            directional_resolution: 4096,
            ..ShadowSettings::default()
        };
        let s = LightSet::new(&scene, &fine).unwrap();
        assert_eq!((s.directional_resolution, s.sky_resolution), (4096, 512));
        let tight = ShadowSettings {
            max_texels: fine.max_texels - 1,
            ..fine
        };
        let s = LightSet::new(&scene, &tight).unwrap();
        assert_eq!((s.directional_resolution, s.sky_resolution), (2048, 512));
        let sun = s
            .lights
            .iter()
            .find(|l| l.kind == LightKind::Directional && l.id != LightId::Sky);
        assert_eq!(sun.and_then(|l| l.shadow).map(|m| m.resolution), Some(2048));
        assert!(s.shadow_texels.len() as u64 <= tight.max_texels);
    }

    #[test]
    fn budget_halves_cube_maps_then_errors() {
        let mut scene = builtin::scene("cornell-point").unwrap();
        let l = scene.point_lights[0].clone();
        for _ in 0..63 {
            scene.point_lights.push(l.clone());
        }
        let s = LightSet::new(
            &scene,
            &ShadowSettings {
                cube_resolution: 256,
                max_texels: 64 * 6 * 32 * 32,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(s.cube_resolutions.0, 32);
        let e = LightSet::new(
            &scene,
            &ShadowSettings {
                max_texels: 1000,
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(matches!(e, LightSetError::Budget(_)), "{e}");
    }
}
