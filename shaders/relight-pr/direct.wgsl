#import scene_core::limits::MAX_FINITE
#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
#import scene_core::light_set::{KIND_DIRECTIONAL, KIND_POINT, Light, lights, irradiance}
#import scene_core::shadow::{DEEP_SHADOW, ShadowParams, texel_at, visibility}
#import relight_pr::element::Element
// Relighting's per-frame direct light from scene-core's shadow-mapped lights (mirrors
// crates/relight-pr/src/display.rs `pixel_direct_shadowed` step for step): at each pixel of
// the element scene's G-buffer, every light's irradiance times its exponential-shadow-map
// factor (eq. 30 of the ISR thesis) averaged over a grid of points on the pixel's
// footprint, an inverse-square point light integrated over the footprint quad in closed
// form (I Omega / A), added to its source's slot, pixel-major, before the frame's factors.
// The display pass reads the result as its per-pixel direct light. The light set sits at
// bindings 6 (lights) and 7 (shadow texels). (No field here is named like an imported
// item: the composer renames such names everywhere, field accesses included.)

const MAX_FOOTPRINT: u32 = 4u;

struct DirectParams {
    frustum: FrustumReconstruction,
    width: u32,
    height: u32,
    k: u32,
    light_count: u32,
    shadow_params: ShadowParams,
    // Points per side of the footprint grid (1 to MAX_FOOTPRINT).
    footprint: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: DirectParams;
// Per light: the slot of the source that holds it, or 0xffffffff.
@group(0) @binding(1) var<storage, read> slot_of: array<u32>;
// Per pixel and source: direct irradiance (rgb), pixel-major.
@group(0) @binding(2) var<storage, read_write> direct: array<vec4<f32>>;
@group(0) @binding(3) var g_normal: texture_2d<f32>;
@group(0) @binding(4) var g_depth: texture_2d<f32>;
@group(0) @binding(5) var g_id: texture_2d<u32>;

// The display's element table: the corners give each element's own plane, where a
// pixel's footprint lies (Element::plane_normal).
@group(0) @binding(8) var<storage, read> elements: array<Element>;

// The unit normal of element id's plane turned to n's side, or n (Element::plane_normal,
// and n where the id names no element or the plane faces away from it).
fn plane_normal(id: u32, n: vec3<f32>) -> vec3<f32> {
    if id >= arrayLength(&elements) {
        return n;
    }
    let e = elements[id];
    let g = cross(e.b.xyz - e.a.xyz, e.c.xyz - e.a.xyz);
    let len = length(g);
    if !(len > 0.0) {
        return n;
    }
    let d = dot(g / len, n);
    if d > 0.0 {
        return g / len;
    }
    if d < 0.0 {
        return -g / len;
    }
    return n;
}

// Where the ray through uv meets the plane through c with unit normal n (w = 1), or c
// (w = 0) when the ray grazes the plane or meets it behind its origin (on_pixel_plane).
fn on_plane(uv: vec2<f32>, c: vec3<f32>, n: vec3<f32>) -> vec4<f32> {
    let o = reconstruct(params.frustum, uv, 0.0);
    let along = reconstruct(params.frustum, uv, 1.0) - o;
    let len = length(along);
    if !(len > 0.0) {
        return vec4<f32>(c, 0.0);
    }
    let d = along / len;
    let den = dot(n, d);
    let t = dot(n, c - o) / den;
    if abs(den) > 1e-3 && t > 0.0 && t <= MAX_FINITE {
        return vec4<f32>(o + d * t, 1.0);
    }
    return vec4<f32>(c, 0.0);
}

// The solid angle of triangle (a, b, c) seen from p (Van Oosterom and Strackee), as
// relight_pr::direct::solid_angle.
fn solid_angle(p: vec3<f32>, a0: vec3<f32>, b0: vec3<f32>, c0: vec3<f32>) -> f32 {
    let a = a0 - p;
    let b = b0 - p;
    let c = c0 - p;
    let la = length(a);
    let lb = length(b);
    let lc = length(c);
    let num = abs(dot(a, cross(b, c)));
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    let omega = 2.0 * atan2(num, den);
    if omega >= 0.0 && omega <= MAX_FINITE {
        return omega;
    }
    return 0.0;
}

// No footprint point.
const NO_POINT: u32 = 0xffffffffu;

// A footprint within this many of its light's texels of its centre is deep in shadow
// wherever its centre is (display.rs FOOTPRINT_IN_TEXEL).
const FOOTPRINT_IN_TEXEL: f32 = 0.5;

// Light l's shadow factor at footprint point p (index q): the centre's, already looked up,
// at the grid's middle point (display.rs).
fn seen_at(l: Light, q: u32, middle: u32, centre: f32, p: vec3<f32>, n: vec3<f32>) -> f32 {
    if q == middle {
        return centre;
    }
    return visibility(l, p, n, params.shadow_params);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let i = gid.y * params.width + gid.x;
    let k = params.k;
    for (var m = 0u; m < k; m++) {
        direct[i * k + m] = vec4<f32>(0.0);
    }
    let xy = vec2<i32>(gid.xy);
    let id = textureLoad(g_id, xy, 0).x;
    if id == 0xffffffffu {
        return;
    }
    let size = vec2<f32>(f32(params.width), f32(params.height));
    let pixel = 1.0 / size;
    let uv = (vec2<f32>(gid.xy) + 0.5) / size;
    let c = reconstruct(params.frustum, uv, textureLoad(g_depth, xy, 0).x);
    let n = textureLoad(g_normal, xy, 0).xyz;
    // The footprint on the element's plane; the cosines at n.
    let plane = plane_normal(id, n);
    let m = clamp(params.footprint, 1u, MAX_FOOTPRINT);
    var points: array<vec3<f32>, 16>;
    var count = 0u;
    for (var sy = 0u; sy < m; sy++) {
        for (var sx = 0u; sx < m; sx++) {
            let at = (vec2<f32>(f32(sx), f32(sy)) + 0.5) / f32(m) - 0.5;
            // The middle of an odd grid is the centre itself (display.rs).
            if m == 1u || (m % 2u == 1u && sx == m / 2u && sy == m / 2u) {
                points[count] = c;
            } else {
                points[count] = on_plane(uv + at * pixel, c, plane).xyz;
            }
            count++;
        }
    }
    let q0 = on_plane(uv + vec2<f32>(-0.5, -0.5) * pixel, c, plane);
    let q1 = on_plane(uv + vec2<f32>(0.5, -0.5) * pixel, c, plane);
    let q2 = on_plane(uv + vec2<f32>(0.5, 0.5) * pixel, c, plane);
    let q3 = on_plane(uv + vec2<f32>(-0.5, 0.5) * pixel, c, plane);
    let quad = m > 1u && q0.w > 0.0 && q1.w > 0.0 && q2.w > 0.0 && q3.w > 0.0;
    let area = 0.5 * length(cross(q1.xyz - q0.xyz, q2.xyz - q0.xyz))
        + 0.5 * length(cross(q2.xyz - q0.xyz, q3.xyz - q0.xyz));
    let inv = 1.0 / f32(count);
    // The farthest of the grid's corners from the centre (display.rs Footprint::reach).
    var reach = 0.0;
    if m > 1u {
        reach = max(
            max(length(points[0] - c), length(points[m - 1u] - c)),
            max(length(points[m * (m - 1u)] - c), length(points[m * m - 1u] - c)),
        );
    }
    // The grid's middle point, the centre itself, in an odd grid of more than one point.
    var middle = NO_POINT;
    if m > 1u && m % 2u == 1u {
        middle = m * m / 2u;
    }
    for (var j = 0u; j < params.light_count; j++) {
        let s = slot_of[j];
        if s >= k {
            continue;
        }
        let l = lights[j];
        var e = vec3<f32>(0.0);
        // A directional light that stands for a cone (the sky's directions; its radius
        // is not 0, light_set.wgsl): looked up at the centre alone (display.rs).
        if l.kind == KIND_DIRECTIONAL && l.radius != 0.0 {
            let ir = irradiance(l, c, n);
            if any(ir != vec3<f32>(0.0)) {
                direct[i * k + s] += vec4<f32>(ir * visibility(l, c, n, params.shadow_params), 0.0);
            }
            continue;
        }
        // One lookup at the centre; the footprint's points unless the centre and the
        // grid's four corners are deep in shadow (display.rs; DEEP_SHADOW from
        // scene_core::shadow), the centre's lookup standing for the grid's middle point.
        var centre = 1.0;
        if count > 1u {
            centre = visibility(l, c, n, params.shadow_params);
            if centre < DEEP_SHADOW && reach < FOOTPRINT_IN_TEXEL * texel_at(l, c) {
                continue;
            }
            if centre < DEEP_SHADOW
                && visibility(l, points[0], n, params.shadow_params) < DEEP_SHADOW
                && visibility(l, points[m - 1u], n, params.shadow_params) < DEEP_SHADOW
                && visibility(l, points[m * (m - 1u)], n, params.shadow_params) < DEEP_SHADOW
                && visibility(l, points[m * m - 1u], n, params.shadow_params) < DEEP_SHADOW {
                continue;
            }
        }
        if quad && l.kind == KIND_POINT && l.radius == 0.0 {
            let to = l.position - c;
            if dot(n, to) <= 0.0 || !(area > 0.0) {
                continue;
            }
            let omega = solid_angle(l.position, q0.xyz, q1.xyz, q2.xyz)
                + solid_angle(l.position, q0.xyz, q2.xyz, q3.xyz);
            let to_len = length(to);
            var w = vec3<f32>(0.0);
            if to_len > 0.0 {
                w = -to / to_len;
            }
            let ramp = clamp(dot(l.direction, w) * l.spot_scale + l.spot_offset, 0.0, 1.0);
            var seen = 0.0;
            for (var p = 0u; p < count; p++) {
                seen += seen_at(l, p, middle, centre, points[p], n);
            }
            // As display.rs: nothing seen or outside the cone adds nothing (not even a NaN
            // of the closed form, which would clear the pixel's other lights).
            if seen <= 0.0 || ramp <= 0.0 {
                continue;
            }
            e = l.color * (omega / area * (ramp * ramp) * (seen * inv));
        } else {
            for (var p = 0u; p < count; p++) {
                let ir = irradiance(l, points[p], n);
                if any(ir != vec3<f32>(0.0)) {
                    e += ir * seen_at(l, p, middle, centre, points[p], n);
                }
            }
            e = e * inv;
        }
        direct[i * k + s] += vec4<f32>(e, 0.0);
    }
    // No NaN or infinity leaves the pass (pixel_direct_shadowed does the same).
    for (var s = 0u; s < k; s++) {
        let v = direct[i * k + s].xyz;
        let finite = all(v == v) && all(abs(v) <= vec3<f32>(MAX_FINITE));
        direct[i * k + s] = vec4<f32>(select(vec3<f32>(0.0), v, finite), 0.0);
    }
}
