// The lighting phase (thesis section 4.5, eq. 29, listing 7) with exponential shadow maps and
// PCF (section 4.6, eq. 30, listing 8); mirrors crates/isr/src/lighting.rs, lights.rs and
// shadow.rs.
//
// Direct light C_0 / pi * sum_l E_l V_l from point lights (1/d^2 or eq. 16's window),
// directional lights and point samples of emissive triangles (cosine profile, disk form
// factor), each shadowed by its log-space-filtered ESM: V = bilinear PCF of
// exp(-c max(r - o, 0)) over the four nearest texels. Mode 0 writes the direct radiance (the
// Lit senders of the ISR pass); mode 1 composes eq. 29 with the upsampled ISR/SSAO buffer and
// adds the emission of visible emitters (front side only).

// common.wgsl, prepended, declares Globals, g (group 0, binding 0), the FLAG_* constants
// and the view helpers.

const KIND_POINT: u32 = 0u;
const KIND_DIRECTIONAL: u32 = 1u;
const KIND_EMITTER: u32 = 2u;
const NO_MAP: u32 = 0xffffffffu;
const MAP_CUBE: u32 = 0u;

// One light; crates/isr/src/gpu.rs `GpuLight` writes it.
struct Light {
    position: vec3<f32>,
    kind: u32,
    // Intensity (point), irradiance (directional) or radiance (emitter sample).
    color: vec3<f32>,
    // Eq. 16's radius, 0 for inverse square.
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
}

struct PassParams {
    // x: 0 senders, 1 compose; y: 1 when isr_tex holds the upsampled ISR/SSAO buffer.
    mode: vec4<u32>,
}

@group(0) @binding(1) var<uniform> params: PassParams;
@group(0) @binding(2) var albedo_tex: texture_2d<f32>;
@group(0) @binding(3) var normal_tex: texture_2d<f32>;
@group(0) @binding(4) var depth_tex: texture_2d<f32>;
@group(0) @binding(5) var id_tex: texture_2d<u32>;
@group(0) @binding(6) var isr_tex: texture_2d<f32>;
@group(0) @binding(7) var<storage, read> lights: array<Light>;
@group(0) @binding(8) var<storage, read> shadow_texels: array<f32>;
// Per global triangle id: index of its emitter entry, or 0xffffffff.
@group(0) @binding(9) var<storage, read> emitter_of: array<u32>;
// Two texels per emitter: (radiance, 0), (unit normal of the emitting side, 0).
@group(0) @binding(10) var<storage, read> emitters: array<vec4<f32>>;
@group(0) @binding(11) var out_tex: texture_storage_2d<rgba32float, write>;

fn falloff(radius: f32, d: f32) -> f32 {
    if (radius > 0.0) {
        return clamp(1.0 - (d / radius) * (d / radius), 0.0, 1.0);
    }
    let d2 = d * d;
    if (d2 > 0.0) {
        return min(1.0 / d2, MAX_FINITE);
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
        return l.color * (falloff(l.radius, d) * c);
    }
    if (l.kind == KIND_DIRECTIONAL) {
        let c = -dot(n, l.direction);
        if (c <= 0.0) {
            return vec3<f32>(0.0);
        }
        return l.color * c;
    }
    let to = l.position - p;
    let d2 = dot(to, to);
    if (!(d2 > 0.0)) {
        return vec3<f32>(0.0);
    }
    let w = to / sqrt(d2);
    let c = dot(n, w);
    let cl = -dot(l.direction, w);
    if (c <= 0.0 || cl <= 0.0) {
        return vec3<f32>(0.0);
    }
    return l.color * (l.area * cl * c / (d2 + l.area * (1.0 / PI)));
}

// Eq. 30 at one texel, never of a positive argument.
fn esm(c: f32, receiver: f32, occluder: f32) -> f32 {
    let d = receiver - occluder;
    if (d <= 0.0) {
        return 1.0;
    }
    return exp(-min(c * d, 100.0));
}

// Bilinear PCF of eq. 30 over the four texels around uv of the face starting at `start`.
fn pcf(start: u32, res: u32, uv: vec2<f32>, c: f32, receiver: f32) -> f32 {
    let t = clamp(uv * f32(res) - vec2<f32>(0.5), vec2<f32>(-1.0), vec2<f32>(f32(res)));
    let i0f = floor(t);
    let f = t - i0f;
    let i0 = vec2<i32>(i0f);
    let last = i32(res) - 1;
    var v: array<f32, 4>;
    for (var k = 0; k < 4; k++) {
        let x = u32(clamp(i0.x + (k & 1), 0, last));
        let y = u32(clamp(i0.y + (k >> 1u), 0, last));
        v[k] = esm(c, receiver, shadow_texels[start + y * res + x]);
    }
    let top = v[0] + (v[1] - v[0]) * f.x;
    let bottom = v[2] + (v[3] - v[2]) * f.x;
    return top + (bottom - top) * f.y;
}

// The cube face of direction d (major axis; ties to X, then Y) with its image coordinates,
// as (u, v, face).
fn cube_face(d: vec3<f32>) -> vec3<f32> {
    let a = abs(d);
    var face: u32;
    var m: f32;
    var r: f32;
    var u: f32;
    if (a.x >= a.y && a.x >= a.z) {
        if (d.x >= 0.0) {
            face = 0u; m = d.x; r = -d.z; u = d.y;
        } else {
            face = 1u; m = -d.x; r = d.z; u = d.y;
        }
    } else if (a.y >= a.z) {
        if (d.y >= 0.0) {
            face = 2u; m = d.y; r = d.x; u = -d.z;
        } else {
            face = 3u; m = -d.y; r = d.x; u = d.z;
        }
    } else if (d.z >= 0.0) {
        face = 4u; m = d.z; r = d.x; u = d.y;
    } else {
        face = 5u; m = -d.z; r = -d.x; u = d.y;
    }
    m = max(m, MIN_POSITIVE);
    return vec3<f32>(0.5 * (r / m + 1.0), 0.5 * (1.0 - u / m), f32(face));
}

// The shadow factor of l's map for a receiver at p with unit normal n.
fn visibility(l: Light, p: vec3<f32>, n: vec3<f32>) -> f32 {
    if (l.map_offset == NO_MAP) {
        return 1.0;
    }
    let res = l.map_res;
    let c = g.filters.w;
    let extent = g.forward_extent.w;
    if (l.map_kind == MAP_CUBE) {
        let dist = length(p - l.position);
        let texel = 2.0 * dist / f32(res);
        let q = p + n * (g.shadow.x * texel);
        let d = q - l.position;
        let len = length(d);
        if (!(len > 0.0 && len <= MAX_FINITE)) {
            return 1.0;
        }
        let f = cube_face(d);
        let face_len = res * res;
        let receiver = (len - g.shadow.y * texel) / extent;
        return pcf(l.map_offset + u32(f.z) * face_len, res, f.xy, c, receiver);
    }
    let texel = 2.0 * l.half_extent / f32(res);
    let q = p + n * (g.shadow.x * texel);
    let rel = q - l.eye;
    let uv = vec2<f32>(
        0.5 * (dot(rel, l.right) / l.half_extent + 1.0),
        0.5 * (1.0 - dot(rel, l.up) / l.half_extent),
    );
    let receiver = (dot(rel, l.forward) - g.shadow.y * texel) / extent;
    return pcf(l.map_offset, res, uv, c, receiver);
}

fn shadowed_irradiance(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    var e = vec3<f32>(0.0);
    let count = g.config.z;
    for (var i = 0u; i < count; i++) {
        let l = lights[i];
        let li = irradiance(l, p, n);
        if (all(li == vec3<f32>(0.0))) {
            continue;
        }
        e += li * visibility(l, p, n);
    }
    return e;
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

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(depth_tex);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let id = textureLoad(id_tex, p, 0).x;
    if (id == BACKGROUND) {
        textureStore(out_tex, p, vec4<f32>(0.0, 0.0, 0.0, 1.0));
        return;
    }
    let uv = pixel_uv(p, size);
    let pos = world(uv, textureLoad(depth_tex, p, 0).x);
    let eye_dir = to_viewer(uv);
    let n = usable_normal(textureLoad(normal_tex, p, 0).xyz, eye_dir);
    let c0 = textureLoad(albedo_tex, p, 0).rgb;
    let e = shadowed_irradiance(pos, n);
    if (params.mode.x == 0u) {
        textureStore(out_tex, p, vec4<f32>(c0 * (1.0 / PI) * e, 1.0));
        return;
    }
    let direct = c0 * (1.0 / PI) * e * g.k.x;
    let glow = emission(id, eye_dir);
    var v = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if (params.mode.y == 1u) {
        v = textureLoad(isr_tex, p, 0);
    }
    var ao = 1.0;
    if (has_flag(FLAG_SSAO)) {
        ao = clamp(v.w + 1.0 - g.k.y, 0.0, 1.0);
    }
    var indirect = vec3<f32>(0.0);
    if (has_flag(FLAG_INDIRECT)) {
        indirect = v.rgb * g.k.z;
    }
    var out: vec3<f32>;
    if (has_flag(FLAG_AO_INDIRECT_ONLY)) {
        out = glow + direct + indirect * ao;
    } else {
        out = glow + direct * ao + indirect;
    }
    if (!all(abs(out) <= vec3<f32>(MAX_FINITE))) {
        out = vec3<f32>(0.0);
    }
    textureStore(out_tex, p, vec4<f32>(out, 1.0));
}
