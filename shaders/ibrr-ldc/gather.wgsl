#import scene_core::limits::MAX_FINITE
#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
// The exact mode's gather on the GPU, one invocation per LDC layer; mirrors
// crates/ibrr-ldc/src/construct.rs (`unoccluded`) and irpl.rs (`irradiance_clamped`): the
// layer's centre on its plane, the IRPL's (clamped, compensated) irradiance there, times
// the share of that centre the IRPL's renders see (bilinear over the four pixels around it,
// each either free or blocked by a surface between the IRPL and the centre). The CPU
// keeps the values of layers no sample of this IRPL reached.

struct Params {
    // xyz: the LDC's origin; w: its side.
    origin: vec4<f32>,
    // xyz: position; w: kind (0 point source, 1 directional source, 2 path node).
    irpl_position: vec4<f32>,
    // xyz: normal (path nodes), direction of travel (directional) or a spot's axis (point
    // source); w: falloff radius of a point source (0: inverse square).
    irpl_normal: vec4<f32>,
    // xyz: power, intensity or irradiance; w: the clamp's g_max (or a huge number).
    irpl_power: vec4<f32>,
    resolution: u32,
    layers: u32,
    renders: u32,
    groups_x: u32,
    eps_distance: f32,
    eps_normal: f32,
    scale: f32,
    has_radius: u32,
    // A point source's spot ramp: attenuation saturate(dot(axis, w) * spot_scale +
    // spot_offset)^2 (scale 0, offset 1: no cone).
    spot_scale: f32,
    spot_offset: f32,
    pad_a: u32,
    pad_b: u32,
}

struct Render {
    view_projection: mat4x4<f32>,
    frustum: FrustumReconstruction,
    // xyz: eye; w: 1 perspective, 0 orthographic.
    eye: vec4<f32>,
    // xyz: forward; w: pixel width (tangent units or world units).
    forward: vec4<f32>,
    // width, height, first pixel in `pixels`, unused.
    size: vec4<u32>,
}

@group(0) @binding(0) var<uniform> params: Params;
// Per layer: its plane; the LDI pixel in `layer_pixels`.
@group(0) @binding(1) var<storage, read> layer_planes: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> layer_pixels: array<u32>;
@group(0) @binding(3) var<storage, read> renders: array<Render>;
// Per render pixel: normal in xyz, linear depth in w (negative on background).
@group(0) @binding(4) var<storage, read> pixels: array<vec4<f32>>;
// Per layer: irradiance in rgb, w = 1 when lit.
@group(0) @binding(5) var<storage, read_write> out_values: array<vec4<f32>>;

const PI_INV: f32 = 0.31830988618379067;

fn irradiance(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let kind = u32(params.irpl_position.w);
    let power = params.irpl_power.xyz;
    if kind == 1u {
        return power * max(-dot(n, params.irpl_normal.xyz), 0.0);
    }
    if kind == 0u {
        let d = params.irpl_position.xyz - p;
        let r = length(d);
        if r <= 0.0 {
            return vec3<f32>(0.0);
        }
        let cos_x = max(dot(n, d) / r, 0.0);
        var falloff = 0.0;
        if params.has_radius != 0u {
            let r0 = params.irpl_normal.w;
            if r0 > 0.0 {
                falloff = clamp(1.0 - (r / r0) * (r / r0), 0.0, 1.0);
            }
        } else {
            let d2 = r * r;
            if d2 > 0.0 {
                falloff = min(1.0 / d2, MAX_FINITE);
            }
        }
        let a = clamp(
            dot(params.irpl_normal.xyz, -d / r) * params.spot_scale + params.spot_offset,
            0.0,
            1.0,
        );
        return power * (falloff * cos_x * a * a);
    }
    let d = p - params.irpl_position.xyz;
    let r2 = dot(d, d);
    if r2 <= 0.0 {
        return vec3<f32>(0.0);
    }
    let r = sqrt(r2);
    let cos_i = max(dot(params.irpl_normal.xyz, d) / r, 0.0);
    let cos_x = max(-dot(n, d) / r, 0.0);
    let g = min(cos_i * cos_x * PI_INV / r2, params.irpl_power.w);
    return power * g;
}

fn unoccluded(q: vec3<f32>, n: vec3<f32>) -> f32 {
    for (var k = 0u; k < params.renders; k++) {
        let rd = renders[k];
        let clip = rd.view_projection * vec4<f32>(q, 1.0);
        if clip.w <= 0.0 {
            continue;
        }
        let u = clip.x / clip.w * 0.5 + 0.5;
        let v = 0.5 - clip.y / clip.w * 0.5;
        if u < 0.0 || u >= 1.0 || v < 0.0 || v >= 1.0 {
            continue;
        }
        let perspective = rd.eye.w != 0.0;
        if perspective && dot(q - rd.eye.xyz, rd.forward.xyz) <= 0.0 {
            continue;
        }
        var origin = rd.eye.xyz;
        if !perspective {
            origin = q - rd.forward.xyz * dot(q - rd.eye.xyz, rd.forward.xyz);
        }
        let dq = q - origin;
        let len = length(dq);
        if len <= 0.0 {
            return 0.0;
        }
        let dir = dq / len;
        let w = rd.size.x;
        let h = rd.size.y;
        let fx = u * f32(w) - 0.5;
        let fy = v * f32(h) - 0.5;
        let x0 = i32(floor(fx));
        let y0 = i32(floor(fy));
        let tx = fx - f32(x0);
        let ty = fy - f32(y0);
        var seen = 0.0;
        for (var c = 0; c < 4; c++) {
            let x = u32(clamp(x0 + (c & 1), 0, i32(w) - 1));
            let y = u32(clamp(y0 + (c >> 1u), 0, i32(h) - 1));
            var wx = 1.0 - tx;
            if (c & 1) == 1 {
                wx = tx;
            }
            var wy = 1.0 - ty;
            if (c >> 1u) == 1 {
                wy = ty;
            }
            let wt = wx * wy;
            let px = pixels[rd.size.z + y * w + x];
            if px.w < 0.0 {
                seen += wt;
                continue;
            }
            let np = px.xyz;
            let uv = (vec2<f32>(f32(x), f32(y)) + 0.5) / vec2<f32>(f32(w), f32(h));
            let pp = reconstruct(rd.frustum, uv, px.w);
            if dot(np, n) > 1.0 - params.eps_normal && abs(dot(q - pp, np)) < params.eps_distance {
                seen += wt;
                continue;
            }
            let denom = dot(dq, np);
            if abs(denom) <= 1e-12 * len {
                seen += wt;
                continue;
            }
            let s = dot(pp - origin, np) / denom;
            if s <= 0.0 || s >= 1.0 - params.eps_distance / len {
                seen += wt;
                continue;
            }
            let cross_at = origin + dq * s;
            var along = rd.forward.w;
            if perspective {
                along = length(pp - origin) * rd.forward.w;
            }
            let reach = 2.0 * along / max(abs(dot(np, dir)), 0.1);
            if length(cross_at - pp) >= reach {
                seen += wt;
            }
        }
        return seen;
    }
    return 0.0;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let l = gid.y * params.groups_x * 64u + gid.x;
    if l >= params.layers {
        return;
    }
    out_values[l] = vec4<f32>(0.0);
    let plane = layer_planes[l];
    let n = plane.xyz;
    let k = layer_pixels[l];
    let rr = params.resolution * params.resolution;
    let axis = k / rr;
    let rest = k % rr;
    let i = rest % params.resolution;
    let j = rest / params.resolution;
    if abs(n[axis]) < 1e-6 {
        return;
    }
    let a = vec2<u32>((axis + 1u) % 3u, (axis + 2u) % 3u);
    let hpx = params.origin.w / f32(params.resolution);
    var q = vec3<f32>(0.0);
    q[a.x] = params.origin[a.x] + (f32(i) + 0.5) * hpx;
    q[a.y] = params.origin[a.y] + (f32(j) + 0.5) * hpx;
    q[axis] = (plane.w - n[a.x] * q[a.x] - n[a.y] * q[a.y]) / n[axis];
    let e = irradiance(q, n) * params.scale;
    let m = max(e.x, max(e.y, e.z));
    // NaN and infinity fail `m < 3.4e38`.
    if !(m > 0.0 && m < MAX_FINITE) {
        return;
    }
    let seen = unoccluded(q, n);
    if seen > 0.0 {
        out_values[l] = vec4<f32>(e * seen, 1.0);
    }
}
