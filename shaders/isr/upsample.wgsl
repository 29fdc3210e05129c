// Bilateral upsampling of the blurred coarse buffer to full resolution (thesis section 4.5,
// eqs. 27-28; mirrors crates/isr/src/upsample.rs).
//
// Weights w_i' = w_i^b w_i^z (w_i^n): bilinear, 1 / max(|z_p - z_i|, eps z_p) (the guarded
// eq. 27), and optionally max(n_p . n_i, 0)^k; background coarse samples get 0; normalised by
// eq. 28. When they all vanish, the non-background coarse sample of the surrounding 4x4 block
// nearest in depth is taken; with none, no indirect light and no occlusion.

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

const VANISHED: f32 = 1e-30;

@group(0) @binding(0) var<uniform> g: Globals;
@group(0) @binding(1) var full_normal: texture_2d<f32>;
@group(0) @binding(2) var full_depth: texture_2d<f32>;
@group(0) @binding(3) var full_id: texture_2d<u32>;
@group(0) @binding(4) var coarse_normal: texture_2d<f32>;
@group(0) @binding(5) var coarse_depth: texture_2d<f32>;
@group(0) @binding(6) var coarse_id: texture_2d<u32>;
@group(0) @binding(7) var coarse_values: texture_2d<f32>;
@group(0) @binding(8) var out_tex: texture_storage_2d<rgba32float, write>;

fn coarse_at(i0: vec2<i32>, d: vec2<i32>, csize: vec2<u32>) -> vec2<i32> {
    return clamp(i0 + d, vec2<i32>(0), vec2<i32>(csize) - vec2<i32>(1));
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(full_depth);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let nothing = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if (textureLoad(full_id, p, 0).x == BACKGROUND) {
        textureStore(out_tex, p, nothing);
        return;
    }
    let csize = textureDimensions(coarse_depth);
    let zp = textureLoad(full_depth, p, 0).x;
    let np = usable_normal(textureLoad(full_normal, p, 0).xyz, vec3<f32>(0.0));
    let c = (vec2<f32>(p) + vec2<f32>(0.5)) * vec2<f32>(csize) / vec2<f32>(size) - vec2<f32>(0.5);
    let i0f = floor(c);
    let f = c - i0f;
    let i0 = vec2<i32>(i0f);
    let bilinear = array<f32, 4>(
        (1.0 - f.x) * (1.0 - f.y),
        f.x * (1.0 - f.y),
        (1.0 - f.x) * f.y,
        f.x * f.y,
    );
    let offsets = array<vec2<i32>, 4>(vec2<i32>(0, 0), vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(1, 1));
    let guard = g.filters.y * zp;
    let power = g.filters.z;
    var sum = vec4<f32>(0.0);
    var total = 0.0;
    for (var k = 0; k < 4; k++) {
        let j = coarse_at(i0, offsets[k], csize);
        if (textureLoad(coarse_id, j, 0).x == BACKGROUND) {
            continue;
        }
        var wt = bilinear[k] / max(abs(zp - textureLoad(coarse_depth, j, 0).x), guard);
        if (power > 0.0) {
            let nc = usable_normal(textureLoad(coarse_normal, j, 0).xyz, vec3<f32>(0.0));
            if (any(np != vec3<f32>(0.0)) && any(nc != vec3<f32>(0.0))) {
                wt *= pow(max(dot(np, nc), 0.0), power);
            }
        }
        sum += textureLoad(coarse_values, j, 0) * wt;
        total += wt;
    }
    if (total > VANISHED && total <= MAX_FINITE) {
        textureStore(out_tex, p, sum / total);
        return;
    }
    // Fallback: nearest depth in the surrounding 4x4 block.
    var best = -1.0;
    var value = nothing;
    for (var dy = -1; dy <= 2; dy++) {
        for (var dx = -1; dx <= 2; dx++) {
            let j = coarse_at(i0, vec2<i32>(dx, dy), csize);
            if (textureLoad(coarse_id, j, 0).x == BACKGROUND) {
                continue;
            }
            let d = abs(zp - textureLoad(coarse_depth, j, 0).x);
            if (best < 0.0 || d < best) {
                best = d;
                value = textureLoad(coarse_values, j, 0);
            }
        }
    }
    textureStore(out_tex, p, value);
}
