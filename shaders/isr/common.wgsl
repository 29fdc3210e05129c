#define_import_path isr::common
#import scene_core::limits::MAX_FINITE
#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
// Declarations shared by every ISR shader in this directory (blur, radiosity, upsample,
// lighting), the module `isr::common`: each pass imports what it uses
// (crates/isr/src/shaders.rs lists the passes; scene-core's shader composer joins them).

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
    // Eq. 24's vectors (scene_core::reconstruct).
    frustum: FrustumReconstruction,
    // World to clip space (the light-space senders' projection onto the coarse buffer).
    view_proj: mat4x4<f32>,
    // Light-space senders: count, once (1: leave out those a receiver's disk shows),
    // interleaved (1: a pixel gathers its phase's senders, weighted 16), visibility maps (1:
    // on).
    senders: vec4<u32>,
    // Where each of the 16 phases' senders begin (the 17th: their count), four to a vector.
    sender_phases: array<vec4<u32>, 5>,
}

const FLAG_INDIRECT: u32 = 1u;
const FLAG_SSAO: u32 = 2u;
const FLAG_AO_INDIRECT_ONLY: u32 = 4u;
const FLAG_EDGE_AWARE: u32 = 8u;
const FLAG_THESIS: u32 = 16u;
const FLAG_LIT: u32 = 32u;

const PI: f32 = 3.14159265358979;
const MIN_NORMAL_LEN_SQ: f32 = 1e-12;
const MIN_FOOTPRINT_COS: f32 = 0.1;
const MIN_POSITIVE: f32 = 1.17549435e-38;

fn has_flag(f: u32) -> bool {
    return (g.config.y & f) != 0u;
}

fn is_ortho() -> bool {
    return g.corner_ortho.w > 0.5;
}

fn pixel_uv(p: vec2<i32>, size: vec2<u32>) -> vec2<f32> {
    return (vec2<f32>(p) + vec2<f32>(0.5)) / vec2<f32>(size);
}

// Eq. 24: world position from image coordinates and linear depth (scene-core's one
// reconstruction).
fn world(uv: vec2<f32>, depth: f32) -> vec3<f32> {
    return reconstruct(g.frustum, uv, depth);
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
    let len_sq = dot(n, n);
    if (len_sq > MIN_NORMAL_LEN_SQ && len_sq <= MAX_FINITE) {
        return n / sqrt(len_sq);
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
// The screen-space disk of a coarse pixel at linear depth z0 in a buffer of `size`
// (radiosity.rs' `Receiver::at`): x, its radius on the image plane (tangent units or
// metres; a disk wider than twice the image reaches every pixel from anywhere, so it is
// clamped there); yz, its radii in pixels.
fn receiver_disk(z0: f32, size: vec2<u32>) -> vec3<f32> {
    let span = vec2<f32>(g.du_span.w, g.dv_span.w);
    let rp = min(g.k.w / max(view_scale(z0), MIN_POSITIVE), 2.0 * max(span.x, span.y));
    return vec3<f32>(rp, rp / span.x * f32(size.x), rp / span.y * f32(size.y));
}

// The normal if usable, else the direction to the viewer (computed only then).
fn normal_or_viewer(n: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    let len_sq = dot(n, n);
    if (len_sq > MIN_NORMAL_LEN_SQ && len_sq <= MAX_FINITE) {
        return n / sqrt(len_sq);
    }
    return to_viewer(uv);
}

@group(0) @binding(0) var<uniform> g: Globals;
