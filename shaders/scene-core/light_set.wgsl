#define_import_path scene_core::light_set
#import scene_core::limits::MAX_FINITE
// The set of lights a pass shades with (mirrors crates/scene-core/src/shadowed_lights/mod.rs):
// point lights (1/d^2 or eq. 16's window, and a spot's cone), directional lights and point samples of emissive
// triangles (cosine profile, disk form factor), each with the frame's direct and indirect
// factors, and the table of emissive triangles for directly visible emitters.
//
// The module `scene_core::light_set`, imported by `scene_core::shadow`, ISR's lighting pass
// and relighting's direct pass. Its storage buffers sit at bindings 6, 8 and 9 of group 0
// (crates/scene-core/src/shadowed_lights/gpu.rs).

const PI: f32 = 3.14159265358979;

const KIND_POINT: u32 = 0u;
const KIND_DIRECTIONAL: u32 = 1u;
const KIND_EMITTER: u32 = 2u;
const NO_MAP: u32 = 0xffffffffu;
const MAP_CUBE: u32 = 0u;

// One light; crates/scene-core/src/shadowed_lights/gpu.rs `GpuLight` writes it.
struct Light {
    position: vec3<f32>,
    kind: u32,
    // Intensity (point), irradiance (directional) or radiance (emitter sample).
    color: vec3<f32>,
    // Eq. 16's radius of a point light, 0 for inverse square. A directional light's cone
    // (gpu.rs GpuLight): above 0 its map's spread (shadow.wgsl soft_pcf), below 0 minus
    // the spread of a light looked up hard, 0 for a light without a cone.
    radius: f32,
    // Travel direction (directional) or emitting normal (emitter sample).
    direction: vec3<f32>,
    // Emitter area the sample stands for.
    area: f32,
    // Orthographic map frame.
    right: vec3<f32>,
    half_extent: f32,
    up: vec3<f32>,
    map_res: u32,
    eye: vec3<f32>,
    // First texel of the map in shadow_texels, NO_MAP without one.
    map_offset: u32,
    forward: vec3<f32>,
    map_kind: u32,
    // The frame's factor on its direct light (LightState), and on the light it sends on to
    // be reflected (the Lit senders).
    direct: vec3<f32>,
    // A spot's cone (point lights; `direction` is its axis): the attenuation towards a
    // point is saturate(dot(axis, w) * spot_scale + spot_offset)^2 (scale 0, offset 1: none).
    spot_scale: f32,
    indirect: vec3<f32>,
    spot_offset: f32,
}

@group(0) @binding(6) var<storage, read> lights: array<Light>;
// Per global triangle id: index of its emitter entry, or 0xffffffff.
@group(0) @binding(8) var<storage, read> emitter_of: array<u32>;
// Two texels per emitter: (radiance times the frame's direct factor, 0), (unit normal of
// the emitting side, 0).
@group(0) @binding(9) var<storage, read> emitters: array<vec4<f32>>;

fn falloff(radius: f32, d: f32) -> f32 {
    if (radius > 0.0) {
        return clamp(1.0 - (d / radius) * (d / radius), 0.0, 1.0);
    }
    let dist_sq = d * d;
    if (dist_sq > 0.0) {
        return min(1.0 / dist_sq, MAX_FINITE);
    }
    return 0.0;
}

// Unshadowed irradiance of light l at p with unit normal n.
fn irradiance(l: Light, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if (l.kind == KIND_POINT) {
        let to = l.position - p;
        let d = length(to);
        if (!(d > 0.0)) {
            return vec3<f32>(0.0);
        }
        let c = dot(n, to / d);
        if (c <= 0.0) {
            return vec3<f32>(0.0);
        }
        let a = clamp(dot(l.direction, -to / d) * l.spot_scale + l.spot_offset, 0.0, 1.0);
        return l.color * (falloff(l.radius, d) * c * a * a);
    }
    if (l.kind == KIND_DIRECTIONAL) {
        let c = -dot(n, l.direction);
        if (c <= 0.0) {
            return vec3<f32>(0.0);
        }
        return l.color * c;
    }
    let to = l.position - p;
    let dist_sq = dot(to, to);
    if (!(dist_sq > 0.0)) {
        return vec3<f32>(0.0);
    }
    let w = to / sqrt(dist_sq);
    let c = dot(n, w);
    let cl = -dot(l.direction, w);
    if (c <= 0.0 || cl <= 0.0) {
        return vec3<f32>(0.0);
    }
    return l.color * (l.area * cl * c / (dist_sq + l.area * (1.0 / PI)));
}

fn emission(id: u32, to_eye: vec3<f32>) -> vec3<f32> {
    if (id >= arrayLength(&emitter_of)) {
        return vec3<f32>(0.0);
    }
    let e = emitter_of[id];
    if (e == 0xffffffffu || 2u * e + 1u >= arrayLength(&emitters)) {
        return vec3<f32>(0.0);
    }
    if (dot(emitters[2u * e + 1u].xyz, to_eye) > 0.0) {
        return emitters[2u * e].xyz;
    }
    return vec3<f32>(0.0);
}

