#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
#import relight_pr::common::{factors, relit}
#import relight_pr::element::Element
// The paper's "hardware" display: per-light radiosity at the welded vertices combined with
// the light factors per pixel in one pass (mirrors crates/relight-pr/src/display.rs'
// compose with smooth shading). A pixel finds its element by the G-buffer's triangle id,
// its barycentrics at the reconstructed position, interpolates eq. 1 over the element's
// three vertices, optionally adds its own per-pixel direct light, and returns
// albedo E / pi + the element's glow.

override PER_PIXEL_DIRECT: bool = false;
// The packed words hold halves (Precision::F16).
override F16: bool = false;

struct DisplayParams {
    frustum: FrustumReconstruction,
    width: u32,
    height: u32,
    k: u32,
    elements: u32,
    base: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: DisplayParams;
@group(0) @binding(3) var<storage, read> elements: array<Element>;
// Per pixel and source: direct irradiance (rgb), pixel-major; read with PER_PIXEL_DIRECT.
@group(0) @binding(4) var<storage, read> pixel_direct: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(6) var g_albedo: texture_2d<f32>;
@group(0) @binding(7) var g_depth: texture_2d<f32>;
@group(0) @binding(8) var g_id: texture_2d<u32>;

// Barycentric coordinates of p projected into triangle (a, b, c), clamped to it
// (display::barycentric).
fn barycentric(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let d = p - a;
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let d1 = dot(d, e1);
    let d2 = dot(d, e2);
    let den = d11 * d22 - d12 * d12;
    if !(den != 0.0) {
        return vec3<f32>(1.0 / 3.0);
    }
    var v = clamp((d22 * d1 - d12 * d2) / den, 0.0, 1.0);
    var w = clamp((d11 * d2 - d12 * d1) / den, 0.0, 1.0);
    let s = max(v + w, 1.0);
    v = v / s;
    w = w / s;
    return vec3<f32>(1.0 - v - w, v, w);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let i = gid.y * params.width + gid.x;
    let xy = vec2<i32>(gid.xy);
    let id = textureLoad(g_id, xy, 0).x;
    let albedo = textureLoad(g_albedo, xy, 0);
    if id >= params.elements {
        image[i] = vec4<f32>(0.0);
        return;
    }
    let el = elements[id];
    let uv = (vec2<f32>(gid.xy) + 0.5) / vec2<f32>(f32(params.width), f32(params.height));
    let p = reconstruct(params.frustum, uv, textureLoad(g_depth, xy, 0).x);
    let bc = barycentric(el.a.xyz, el.b.xyz, el.c.xyz, p);
    var e = params.base.xyz
        + relit(el.vertex.x, params.k, !PER_PIXEL_DIRECT, F16) * bc.x
        + relit(el.vertex.y, params.k, !PER_PIXEL_DIRECT, F16) * bc.y
        + relit(el.vertex.z, params.k, !PER_PIXEL_DIRECT, F16) * bc.z;
    if PER_PIXEL_DIRECT {
        for (var m = 0u; m < params.k; m++) {
            e += pixel_direct[i * params.k + m].xyz * factors[2u * m].xyz;
        }
    }
    var glow = vec3<f32>(0.0);
    let source = u32(el.a.w);
    if source > 0u {
        glow = el.emission.xyz * factors[2u * (source - 1u)].xyz;
    }
    let out = albedo.xyz * e * 0.31830988618379067 + glow;
    // No NaN or infinity leaves the pass (display::compose does the same).
    let finite = all(out == out) && all(abs(out) <= vec3<f32>(3.4e38));
    image[i] = vec4<f32>(select(vec3<f32>(0.0), out, finite), 1.0);
}
