#define_import_path scene_core::shadow
#import scene_core::limits::MAX_FINITE
#import scene_core::light_set::{NO_MAP, MAP_CUBE, Light}
// Exponential shadow maps with PCF (ISR thesis section 4.6, eq. 30, listing 8; mirrors
// crates/scene-core/src/shadowed_lights/esm.rs): V = bilinear PCF of exp(-c max(r - o, 0))
// over the four nearest texels of a light's log-space-filtered map (cube or orthographic).

const MIN_POSITIVE: f32 = 1.17549435e-38;

// Below this a shadow factor is deep shadow (esm.rs DEEP_SHADOW): every PCF texel has
// c d above 69.1.
const DEEP_SHADOW: f32 = 1e-30;

// The lookup's parameters; crates/scene-core/src/shadowed_lights/gpu.rs `ShadowParams`.
struct ShadowParams {
    // The ESM exponent c of eq. 30.
    esm_exponent: f32,
    // Receivers move this many texels along their normal.
    normal_offset: f32,
    // Constant depth bias in texels.
    depth_bias: f32,
    // The scene's extent, the unit of the maps' depths.
    extent: f32,
}

// Every map's texels, concatenated (Light.map_offset is a map's first texel).
@group(0) @binding(7) var<storage, read> shadow_texels: array<f32>;

// Eq. 30 at one texel, never of a positive argument.
fn esm(c: f32, receiver: f32, occluder: f32) -> f32 {
    let d = receiver - occluder;
    if (d <= 0.0) {
        return 1.0;
    }
    // Capped at 80 (exp(-80) is still a normal f32), as esm.rs.
    return exp(-min(c * d, 80.0));
}

// Bilinear PCF of eq. 30 over the four texels around uv of the face starting at `start`.
fn pcf(start: u32, res: u32, uv: vec2<f32>, c: f32, receiver: f32) -> f32 {
    let t = clamp(uv * f32(res) - vec2<f32>(0.5), vec2<f32>(-1.0), vec2<f32>(f32(res)));
    let corner_f = floor(t);
    let f = t - corner_f;
    let corner = vec2<i32>(corner_f);
    let last = i32(res) - 1;
    var v: array<f32, 4>;
    for (var k = 0; k < 4; k++) {
        let x = u32(clamp(corner.x + (k & 1), 0, last));
        let y = u32(clamp(corner.y + (k >> 1u), 0, last));
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
fn visibility(l: Light, p: vec3<f32>, n: vec3<f32>, s: ShadowParams) -> f32 {
    if (l.map_offset == NO_MAP) {
        return 1.0;
    }
    let res = l.map_res;
    let c = s.esm_exponent;
    let extent = s.extent;
    if (l.map_kind == MAP_CUBE) {
        let dist = length(p - l.position);
        let texel = 2.0 * dist / f32(res);
        let q = p + n * (s.normal_offset * texel);
        let d = q - l.position;
        let len = length(d);
        if (!(len > 0.0 && len <= MAX_FINITE)) {
            return 1.0;
        }
        let f = cube_face(d);
        let face_len = res * res;
        let receiver = (len - s.depth_bias * texel) / extent;
        return pcf(l.map_offset + u32(f.z) * face_len, res, f.xy, c, receiver);
    }
    let texel = 2.0 * l.half_extent / f32(res);
    let q = p + n * (s.normal_offset * texel);
    let rel = q - l.eye;
    let uv = vec2<f32>(
        0.5 * (dot(rel, l.right) / l.half_extent + 1.0),
        0.5 * (1.0 - dot(rel, l.up) / l.half_extent),
    );
    let receiver = (dot(rel, l.forward) - s.depth_bias * texel) / extent;
    return pcf(l.map_offset, res, uv, c, receiver);
}

