//! A [`LightSet`] packed for the WGSL twins (`shaders/scene-core/light_set.wgsl`, module
//! `scene_core::light_set`, and `shadow.wgsl`, `scene_core::shadow`): one [`GpuLight`] per
//! light, the shadow maps' texels as they are ([`LightSet::shadow_texels`]) and the emitter
//! table ([`gpu_emitters`]). The modules declare their storage buffers at fixed bindings of
//! group 0, which a pass importing them leaves free: lights at 6, shadow texels at 7, the
//! emitter index per triangle at 8 and the emitter table at 9.

use bytemuck::{Pod, Zeroable};

use super::esm::MapKind;
use super::{LightKind, LightSet};

/// The light set's WGSL (`scene_core::light_set`): lights, their irradiance, visible emitters.
pub const LIGHT_SET: crate::gpu::shader::Wgsl = crate::wgsl_file!("scene-core", "light_set.wgsl");
/// Exponential shadow maps with PCF (`scene_core::shadow`, eq. 30 and listing 8).
pub const SHADOW: crate::gpu::shader::Wgsl = crate::wgsl_file!("scene-core", "shadow.wgsl");

/// The shadow lookup's parameters (`ShadowParams` in `shadow.wgsl`): the ESM exponent, the
/// normal offset and depth bias in texels, and the scene's extent (the unit of map depths).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadowParams {
    /// [`super::ShadowSettings::esm_exponent`].
    pub esm_exponent: f32,
    /// [`super::ShadowSettings::normal_offset`].
    pub normal_offset: f32,
    /// [`super::ShadowSettings::depth_bias`].
    pub depth_bias: f32,
    /// [`LightSet::extent`].
    pub extent: f32,
}

impl ShadowParams {
    /// The parameters of `set`.
    pub fn of(set: &LightSet) -> Self {
        Self {
            esm_exponent: set.shadows.esm_exponent,
            normal_offset: set.shadows.normal_offset,
            depth_bias: set.shadows.depth_bias,
            extent: set.extent,
        }
    }
}

/// One light in the light storage buffer (`Light` in `light_set.wgsl`, 144 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    /// Position.
    pub position: [f32; 3],
    /// 0 point, 1 directional, 2 emitter sample.
    pub kind: u32,
    /// Intensity, irradiance or radiance.
    pub color: [f32; 3],
    /// Eq. 16's radius (0: inverse square) of a point light. A directional light's cone:
    /// its map's spread where the lookup is soft ([`super::esm::ShadowMap::spread`],
    /// above 0), else minus the light's own spread ([`super::Light::radius`]: below 0, a
    /// hard lookup of a light that stands for a cone, which relighting looks up at a
    /// pixel's centre alone), 0 for a light without a cone.
    pub radius: f32,
    /// Travel direction or emitting normal.
    pub direction: [f32; 3],
    /// Emitter area of a sample.
    pub area: f32,
    /// Orthographic map: right vector.
    pub right: [f32; 3],
    /// Orthographic map: half width.
    pub half_extent: f32,
    /// Orthographic map: up vector.
    pub up: [f32; 3],
    /// Texels per side.
    pub map_res: u32,
    /// Orthographic map: eye.
    pub eye: [f32; 3],
    /// First texel, or `u32::MAX` without a map.
    pub map_offset: u32,
    /// Orthographic map: direction.
    pub forward: [f32; 3],
    /// 0 cube, 1 orthographic.
    pub map_kind: u32,
    /// The frame's factor on its direct light.
    pub direct: [f32; 3],
    /// A spot's ramp scale (0 for every other light).
    pub spot_scale: f32,
    /// The frame's factor on the light it sends on (the `Lit` senders).
    pub indirect: [f32; 3],
    /// A spot's ramp offset (1 for every other light).
    pub spot_offset: f32,
}

/// The emitter table in the GPU layout: two texels per emitter, (radiance times the frame's
/// direct factor, 0) and (unit normal of the emitting side, 0).
pub fn gpu_emitters(scene: &LightSet) -> Vec<[f32; 4]> {
    let e = &scene.emitters;
    let mut table = Vec::with_capacity(2 * e.entries.len());
    for (k, (l, n)) in e.entries.iter().enumerate() {
        let f = e.direct.get(k).copied().unwrap_or(glam::Vec3::ONE);
        table.push((*l * f).extend(0.0).to_array());
        table.push(n.extend(0.0).to_array());
    }
    table
}

/// The lights of `scene` in the GPU layout.
pub fn gpu_lights(scene: &LightSet) -> Vec<GpuLight> {
    scene
        .lights
        .iter()
        .map(|l| {
            let mut g = GpuLight {
                position: l.position.to_array(),
                kind: match l.kind {
                    LightKind::Point => 0,
                    LightKind::Directional => 1,
                    LightKind::EmitterSample => 2,
                },
                color: l.color.to_array(),
                radius: if l.kind == LightKind::Directional {
                    -l.radius.clamp(0.0, crate::sky::MAX_SPREAD)
                } else {
                    l.radius
                },
                direction: l.direction.to_array(),
                area: l.area,
                map_offset: u32::MAX,
                direct: l.direct.to_array(),
                indirect: l.indirect.to_array(),
                spot_scale: l.spot.scale,
                spot_offset: l.spot.offset,
                ..Default::default()
            };
            if let (Some(map), true) = (&l.shadow, scene.shadows.enabled) {
                g.map_res = map.resolution;
                g.map_offset = map.offset as u32;
                let (eye, right, up, forward, half_extent) = map.frame();
                g.map_kind = u32::from(matches!(map.kind, MapKind::Ortho { .. }));
                g.eye = eye.to_array();
                g.right = right.to_array();
                g.up = up.to_array();
                g.forward = forward.to_array();
                g.half_extent = half_extent;
                if l.kind == LightKind::Directional && map.spread > 0.0 {
                    g.radius = map.spread;
                }
            }
            g
        })
        .collect()
}
