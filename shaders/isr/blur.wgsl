// One direction of the separable blur of the coarse ISR/SSAO buffer (thesis section 4.2,
// listing 3: BlurHorizontal, BlurVertical; mirrors crates/isr/src/blur.rs).
//
// Gaussian taps exp(-k^2 / (2 sigma^2)), k in [-R, R]; background pixels take no part. The
// edge-aware variant also weights a tap by exp(-(d / (EDGE_PLANE_SIGMA s))^2), d its distance
// from the centre pixel's tangent plane and s the centre's view depth, times
// max(n_c . n_t, 0)^2.

// ---- Shared declarations (the same text in every ISR shader but downsample.wgsl) ----

// Per-frame parameters; crates/isr/src/gpu.rs `Globals` writes them.
struct Globals {
    // Eye position; w: far plane distance.
    eye_far: vec4<f32>,
    // Perspective: f_o of eq. 24; orthographic: the view's top-left corner. w: 1 if ortho.
    corner_ortho: vec4<f32>,
    // f_u (or the ortho width vector); w: image-plane width (tangent units or metres).
    du_span: vec4<f32>,
    // f_v (or the ortho height vector); w: image-plane height.
    dv_span: vec4<f32>,
    // Unit view direction; w: the scene's extent.
    forward_extent: vec4<f32>,
    // Full-resolution width, height; coarse width, height.
    sizes: vec4<u32>,
    // Samples N, flags (FLAG_*), light count, blur radius.
    config: vec4<u32>,
    // k_dl, k_ssao, k_isr, world-space sampling radius.
    k: vec4<f32>,
    // Blur sigma, upsampling epsilon, upsampling normal power, ESM exponent c.
    filters: vec4<f32>,
    // Shadow normal offset and depth bias (texels); unused; unused.
    shadow: vec4<f32>,
}

const FLAG_INDIRECT: u32 = 1u;
const FLAG_SSAO: u32 = 2u;
const FLAG_AO_INDIRECT_ONLY: u32 = 4u;
const FLAG_EDGE_AWARE: u32 = 8u;
const FLAG_THESIS: u32 = 16u;
const FLAG_LIT: u32 = 32u;

const BACKGROUND: u32 = 0xffffffffu;
const PI: f32 = 3.14159265358979;
const MIN_NORMAL_LEN2: f32 = 1e-12;
const MIN_FOOTPRINT_COS: f32 = 0.1;
const MIN_POSITIVE: f32 = 1.17549435e-38;
const MAX_FINITE: f32 = 3.40282347e38;

fn has_flag(f: u32) -> bool {
    return (g.config.y & f) != 0u;
}

fn is_ortho() -> bool {
    return g.corner_ortho.w > 0.5;
}

fn pixel_uv(p: vec2<i32>, size: vec2<u32>) -> vec2<f32> {
    return (vec2<f32>(p) + vec2<f32>(0.5)) / vec2<f32>(size);
}

// Eq. 24: world position from image coordinates and linear depth.
fn world(uv: vec2<f32>, depth: f32) -> vec3<f32> {
    if (is_ortho()) {
        return g.corner_ortho.xyz + g.du_span.xyz * uv.x + g.dv_span.xyz * uv.y
            + g.forward_extent.xyz * (depth * g.eye_far.w);
    }
    return g.eye_far.xyz + (g.corner_ortho.xyz + g.du_span.xyz * uv.x + g.dv_span.xyz * uv.y) * depth;
}

// The view ray at uv, scaled to a unit component along the view direction.
fn ray_q(uv: vec2<f32>) -> vec3<f32> {
    if (is_ortho()) {
        return g.forward_extent.xyz;
    }
    return (g.corner_ortho.xyz + g.du_span.xyz * uv.x + g.dv_span.xyz * uv.y) / g.eye_far.w;
}

fn to_viewer(uv: vec2<f32>) -> vec3<f32> {
    let q = ray_q(uv);
    let rcp = 1.0 / length(q);
    if (rcp > 0.0 && rcp <= MAX_FINITE) {
        return -(q * rcp);
    }
    return -g.forward_extent.xyz;
}

fn usable_normal(n: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l2 = dot(n, n);
    if (l2 > MIN_NORMAL_LEN2 && l2 <= MAX_FINITE) {
        return n / sqrt(l2);
    }
    return fallback;
}

// Metres per unit of image-plane span at a linear depth.
fn view_scale(depth: f32) -> f32 {
    if (is_ortho()) {
        return 1.0;
    }
    return depth * g.eye_far.w;
}
// The normal if usable, else the direction to the viewer (computed only then).
fn normal_or_viewer(n: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    let l2 = dot(n, n);
    if (l2 > MIN_NORMAL_LEN2 && l2 <= MAX_FINITE) {
        return n / sqrt(l2);
    }
    return to_viewer(uv);
}

// ---- end of shared declarations ----

const EDGE_PLANE_SIGMA: f32 = 0.05;

struct PassParams {
    // x: 1 for horizontal, 0 for vertical.
    mode: vec4<u32>,
}

@group(0) @binding(0) var<uniform> g: Globals;
@group(0) @binding(1) var<uniform> params: PassParams;
@group(0) @binding(2) var normal_tex: texture_2d<f32>;
@group(0) @binding(3) var depth_tex: texture_2d<f32>;
@group(0) @binding(4) var id_tex: texture_2d<u32>;
@group(0) @binding(5) var in_tex: texture_2d<f32>;
@group(0) @binding(6) var out_tex: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(depth_tex);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let centre_value = textureLoad(in_tex, p, 0);
    if (textureLoad(id_tex, p, 0).x == BACKGROUND) {
        textureStore(out_tex, p, centre_value);
        return;
    }
    let horizontal = params.mode.x == 1u;
    let edge = has_flag(FLAG_EDGE_AWARE);
    let uv = pixel_uv(p, size);
    var pc = vec3<f32>(0.0);
    var nc = vec3<f32>(0.0);
    var plane_scale = 1.0;
    if (edge) {
        let zc = textureLoad(depth_tex, p, 0).x;
        pc = world(uv, zc);
        nc = normal_or_viewer(textureLoad(normal_tex, p, 0).xyz, uv);
        plane_scale = view_scale(zc) * EDGE_PLANE_SIGMA;
    }
    let radius = i32(g.config.w);
    let sigma = g.filters.x;
    var sum = vec4<f32>(0.0);
    var total = 0.0;
    for (var k = -radius; k <= radius; k++) {
        var t = p;
        if (horizontal) {
            t.x += k;
        } else {
            t.y += k;
        }
        if (t.x < 0 || t.y < 0 || t.x >= i32(size.x) || t.y >= i32(size.y)) {
            continue;
        }
        if (textureLoad(id_tex, t, 0).x == BACKGROUND) {
            continue;
        }
        let kk = u32(abs(k));
        var wt = exp(-f32(kk * kk) / (2.0 * sigma * sigma));
        if (edge && k != 0) {
            let uvt = pixel_uv(t, size);
            let pt = world(uvt, textureLoad(depth_tex, t, 0).x);
            let nt = normal_or_viewer(textureLoad(normal_tex, t, 0).xyz, uvt);
            let d = dot(nc, pt - pc) / max(plane_scale, MIN_POSITIVE);
            let cn = max(dot(nc, nt), 0.0);
            wt *= exp(-(d * d)) * cn * cn;
        }
        sum += textureLoad(in_tex, t, 0) * wt;
        total += wt;
    }
    if (total > 0.0) {
        textureStore(out_tex, p, sum / total);
    } else {
        textureStore(out_tex, p, centre_value);
    }
}
