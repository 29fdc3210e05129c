#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
// World-space position reconstruction from a G-buffer's depth (thesis section 4.3),
// mirroring crates/gbuffer/src/reconstruct.rs. Three entry points, one per method, so a
// micro-benchmark can time them apart:
//
//   frustum_main     linear depth d (depth / far) and the frustum-corner vectors of eqs.
//                    23-24: p = base(uv) + ray(uv) * d, with base = eye, ray = f_o + u f_u
//                    + v f_v for perspective views (base varies and ray is constant for
//                    orthographic ones). Six multiply-adds.
//   inverse_main     linear depth, then an inverse matrix: the vector (x_ndc a, y_ndc a,
//                    b, c) rebuilt from d, times the inverse of the linear-depth clip
//                    transform, divided by its w (a 4x4 product and a division).
//   inverse_hw_main  the thesis' "more intuitive" comparison: the hardware depth buffer's
//                    z_ndc, p = M^-1 (x_ndc, y_ndc, z_ndc, 1), divided by w.
//
// Each invocation reconstructs `taps` positions around its pixel (the first at the pixel
// itself, the others on a fixed pattern of neighbours within 4 pixels, clamped to the
// image, as an ISR or SSAO pass would) and writes their mean to `out_pos` (w = 1). With
// taps = 1 the output is the pixel's own position.

struct Params {
    // Eq. 24's vectors (scene_core::reconstruct).
    frustum: FrustumReconstruction,
    // Inverse of the linear-depth clip transform (see InverseMatrixReconstruction).
    inv_linear: mat4x4<f32>,
    // Inverse of the standard view-projection matrix.
    inv_view_proj: mat4x4<f32>,
    // The input vector of inverse_main is (x_ndc a, y_ndc a, b, c) with
    // a = lin_a.x + lin_a.y d, b = lin_a.z + lin_a.w d, c = lin_c.x + lin_c.y d.
    lin_a: vec4<f32>,
    lin_c: vec2<f32>,
    taps: u32,
    pad: u32,
}

@group(0) @binding(0) var linear_depth: texture_2d<f32>;
@group(0) @binding(1) var hw_depth: texture_depth_2d;
@group(0) @binding(2) var out_pos: texture_storage_2d<rgba32float, write>;
@group(0) @binding(3) var<uniform> params: Params;

const MAX_TAPS: u32 = 24u;
const TAP_OFFSETS: array<vec2<i32>, 24> = array<vec2<i32>, 24>(
    vec2<i32>(0, 0), vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(-1, 0),
    vec2<i32>(0, -1), vec2<i32>(2, 1), vec2<i32>(-1, 2), vec2<i32>(-2, -1),
    vec2<i32>(1, -2), vec2<i32>(3, 0), vec2<i32>(0, 3), vec2<i32>(-3, 0),
    vec2<i32>(0, -3), vec2<i32>(2, 3), vec2<i32>(-3, 2), vec2<i32>(-2, -3),
    vec2<i32>(3, -2), vec2<i32>(4, 1), vec2<i32>(-1, 4), vec2<i32>(-4, -1),
    vec2<i32>(1, -4), vec2<i32>(4, 4), vec2<i32>(-4, 4), vec2<i32>(4, -4),
);

fn tap(center: vec2<i32>, k: u32, size: vec2<i32>) -> vec2<i32> {
    return clamp(center + TAP_OFFSETS[k], vec2<i32>(0), size - vec2<i32>(1));
}

fn uv_of(p: vec2<i32>, size: vec2<i32>) -> vec2<f32> {
    return (vec2<f32>(p) + vec2<f32>(0.5)) / vec2<f32>(size);
}

// Eq. 24, generalised to orthographic views (scene-core's one WGSL reconstruction).
fn reconstruct_frustum(uv: vec2<f32>, d: f32) -> vec3<f32> {
    return reconstruct(params.frustum, uv, d);
}

fn reconstruct_inverse(uv: vec2<f32>, d: f32) -> vec3<f32> {
    let a = params.lin_a.x + params.lin_a.y * d;
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let v = vec4<f32>(ndc * a, params.lin_a.z + params.lin_a.w * d, params.lin_c.x + params.lin_c.y * d);
    let p = params.inv_linear * v;
    return p.xyz / p.w;
}

fn reconstruct_inverse_hw(uv: vec2<f32>, z: f32) -> vec3<f32> {
    let ndc = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, z, 1.0);
    let p = params.inv_view_proj * ndc;
    return p.xyz / p.w;
}

fn taps() -> u32 {
    return clamp(params.taps, 1u, MAX_TAPS);
}

// The three entry points repeat the same loop on purpose: each is a micro-benchmark of one
// reconstruction method, so the method is inlined rather than chosen by a branch per tap.
@compute @workgroup_size(8, 8, 1)
fn frustum_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<i32>(textureDimensions(linear_depth));
    let c = vec2<i32>(gid.xy);
    if (c.x >= size.x || c.y >= size.y) {
        return;
    }
    let n = taps();
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k++) {
        let p = tap(c, k, size);
        sum += reconstruct_frustum(uv_of(p, size), textureLoad(linear_depth, p, 0).x);
    }
    textureStore(out_pos, c, vec4<f32>(sum / f32(n), 1.0));
}

@compute @workgroup_size(8, 8, 1)
fn inverse_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<i32>(textureDimensions(linear_depth));
    let c = vec2<i32>(gid.xy);
    if (c.x >= size.x || c.y >= size.y) {
        return;
    }
    let n = taps();
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k++) {
        let p = tap(c, k, size);
        sum += reconstruct_inverse(uv_of(p, size), textureLoad(linear_depth, p, 0).x);
    }
    textureStore(out_pos, c, vec4<f32>(sum / f32(n), 1.0));
}

@compute @workgroup_size(8, 8, 1)
fn inverse_hw_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<i32>(textureDimensions(hw_depth));
    let c = vec2<i32>(gid.xy);
    if (c.x >= size.x || c.y >= size.y) {
        return;
    }
    let n = taps();
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k++) {
        let p = tap(c, k, size);
        sum += reconstruct_inverse_hw(uv_of(p, size), textureLoad(hw_depth, p, 0));
    }
    textureStore(out_pos, c, vec4<f32>(sum / f32(n), 1.0));
}
