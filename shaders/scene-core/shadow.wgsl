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
    return bilinear(start, res, t, c, receiver, vec2<f32>(0.0));
}

// The receiver's plane at texel xy's centre: depth `receiver` at t, `grad` per texel.
fn receiver_plane(receiver: f32, grad: vec2<f32>, t: vec2<f32>, xy: vec2<i32>) -> f32 {
    return receiver + grad.x * (f32(xy.x) - t.x) + grad.y * (f32(xy.y) - t.y);
}

// Listing 8's bilinear PCF around texel coordinates t (a texel's centre at its index),
// each texel against the receiver's plane at its centre: depth `receiver` at t, changing
// by `grad` per texel (zero for pcf: every texel against `receiver`, to the bit).
fn bilinear(start: u32, res: u32, t: vec2<f32>, c: f32, receiver: f32, grad: vec2<f32>) -> f32 {
    let corner = vec2<i32>(floor(t));
    let f = t - floor(t);
    var v: array<f32, 4>;
    for (var k = 0; k < 4; k++) {
        let x = corner.x + (k & 1);
        let y = corner.y + (k >> 1u);
        v[k] = esm(c, receiver_plane(receiver, grad, t, vec2<i32>(x, y)), map_texel(start, res, x, y));
    }
    let top = v[0] + (v[1] - v[0]) * f.x;
    let bottom = v[2] + (v[3] - v[2]) * f.x;
    return top + (bottom - top) * f.y;
}

// Soft lookups (esm.rs soft_pcf): blocker-search taps per side besides the receiver's
// texel, the filter's taps, the widest penumbra in texels, the depths of the scene's
// near and far sides in an orthographic map (extents) and the steepest receiver plane.
const SEARCH_TAPS: u32 = 3u;
// The filter's taps on the unit disk: Vogel's spiral (esm.rs FILTER_DISK).
const FILTER_DISK = array<vec2<f32>, 16>(
    vec2<f32>(0.1767767, 0.0),
    vec2<f32>(-0.2257722, 0.2068258),
    vec2<f32>(0.0345581, -0.3937712),
    vec2<f32>(0.2845712, 0.3711728),
    vec2<f32>(-0.5222232, -0.0923739),
    vec2<f32>(0.4946954, -0.3146847),
    vec2<f32>(-0.1654659, 0.615525),
    vec2<f32>(-0.3155615, -0.6075944),
    vec2<f32>(0.6846422, 0.2500302),
    vec2<f32>(-0.7122561, 0.294009),
    vec2<f32>(0.3433545, -0.7337286),
    vec2<f32>(0.2537302, 0.808932),
    vec2<f32>(-0.7647459, -0.4431859),
    vec2<f32>(0.897134, -0.1972324),
    vec2<f32>(-0.5475069, 0.7787722),
    vec2<f32>(-0.1264868, -0.9760897),
);
const MAX_PENUMBRA: f32 = 32.0;
const NEAR_DEPTH: f32 = 0.5;
const FAR_DEPTH: f32 = 1.501;
const MAX_SLOPE: f32 = 8.0;
// esm(c, r, o) at the cap, as esm.rs CAPPED.
const CAPPED: f32 = 1.8048513e-35;

// Texel (x, y) of the face starting at `start`, clamped to the face.
fn map_texel(start: u32, res: u32, x: i32, y: i32) -> f32 {
    let last = i32(res) - 1;
    return shadow_texels[start + u32(clamp(y, 0, last)) * res + u32(clamp(x, 0, last))];
}

// A tap's texel: floor(x + 1/2), as esm.rs (round would tie to even).
fn tap_texel(p: vec2<f32>) -> vec2<i32> {
    return vec2<i32>(floor(p + vec2<f32>(0.5)));
}

// A light's cone penumbra on an orthographic map (esm.rs soft_pcf): t the receiver in
// texel coordinates (a texel's centre at its index), receiver its biased depth, grad its
// plane's depth change per texel, spread_texels the penumbra's half-width in texels per
// extent between blocker and receiver.
fn soft_pcf(start: u32, res: u32, t: vec2<f32>, c: f32, receiver: f32, grad: vec2<f32>, spread_texels: f32) -> f32 {
    let search = clamp(spread_texels * (receiver - NEAR_DEPTH), 0.0, MAX_PENUMBRA);
    var sum = 0.0;
    var blockers = 0u;
    var misses = 0u;
    var deep = true;
    let taps = SEARCH_TAPS * SEARCH_TAPS + 1u;
    for (var k = 0u; k < taps; k++) {
        var p = t;
        if (k > 0u) {
            let i = (k - 1u) % SEARCH_TAPS;
            let j = (k - 1u) / SEARCH_TAPS;
            let step = vec2<f32>(f32(i), f32(j)) / f32(SEARCH_TAPS - 1u) * 2.0 - vec2<f32>(1.0);
            p = t + step * search;
        }
        let xy = tap_texel(p);
        let o = map_texel(start, res, xy.x, xy.y);
        let r = receiver_plane(receiver, grad, t, xy);
        if (o >= FAR_DEPTH) {
            misses += 1u;
        }
        if (o < r) {
            sum += o;
            blockers += 1u;
            deep = deep && esm(c, r, o) < DEEP_SHADOW;
        }
    }
    if (blockers == 0u) {
        return 1.0;
    }
    if (deep && blockers + misses == taps) {
        return CAPPED;
    }
    let width = clamp(spread_texels * (receiver - sum / f32(blockers)), 0.0, MAX_PENUMBRA);
    if (width >= 0.5) {
        var lit = 0.0;
        var seen = 0.0;
        var disk = FILTER_DISK;
        for (var k = 0u; k < 16u; k++) {
            let xy = tap_texel(t + disk[k] * width);
            let o = map_texel(start, res, xy.x, xy.y);
            if (o < FAR_DEPTH) {
                let r = receiver_plane(receiver, grad, t, xy);
                lit += esm(c, r, o);
                seen += 1.0;
            }
        }
        if (seen > 0.0) {
            return lit / seen;
        }
    }
    return bilinear(start, res, t, c, receiver, grad);
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
// The width of a texel of light l's map at p (esm.rs ShadowMap::texel_at): 2 d / res at a
// distance d from a cube map's centre, the orthographic view's width over res otherwise;
// -1 without a map.
fn texel_at(l: Light, p: vec3<f32>) -> f32 {
    if (l.map_offset == NO_MAP) {
        return -1.0;
    }
    if (l.map_kind == MAP_CUBE) {
        return 2.0 * length(p - l.position) / f32(l.map_res);
    }
    return 2.0 * l.half_extent / f32(l.map_res);
}

fn visibility(l: Light, p: vec3<f32>, n: vec3<f32>, s: ShadowParams) -> f32 {
    if (l.map_offset == NO_MAP) {
        return 1.0;
    }
    let res = l.map_res;
    let c = s.esm_exponent;
    let extent = s.extent;
    let texel = texel_at(l, p);
    if (l.map_kind == MAP_CUBE) {
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
    let q = p + n * (s.normal_offset * texel);
    let rel = q - l.eye;
    let uv = vec2<f32>(
        0.5 * (dot(rel, l.right) / l.half_extent + 1.0),
        0.5 * (1.0 - dot(rel, l.up) / l.half_extent),
    );
    let receiver = (dot(rel, l.forward) - s.depth_bias * texel) / extent;
    // A directional light's radius is its spread (a cone's penumbra, esm.rs visibility).
    if (l.radius > 0.0) {
        let nf = dot(n, l.forward);
        let per_texel = texel / extent;
        let limit = MAX_SLOPE * per_texel;
        var grad = vec2<f32>(0.0);
        if (nf != 0.0) {
            grad = clamp(vec2<f32>(-dot(n, l.right), dot(n, l.up)) * (per_texel / nf), vec2<f32>(-limit), vec2<f32>(limit));
        }
        if (!all(abs(grad) <= vec2<f32>(MAX_FINITE))) {
            grad = vec2<f32>(0.0);
        }
        let t = clamp(uv * f32(res) - vec2<f32>(0.5), vec2<f32>(-1.0), vec2<f32>(f32(res)));
        return soft_pcf(l.map_offset, res, t, c, receiver, grad, l.radius / per_texel);
    }
    return pcf(l.map_offset, res, uv, c, receiver);
}

