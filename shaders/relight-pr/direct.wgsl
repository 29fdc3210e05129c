#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
#import scene_core::light_set::{lights, irradiance}
#import scene_core::shadow::{ShadowParams, visibility}
// Relighting's per-frame direct light from scene-core's shadow-mapped lights (mirrors
// crates/relight-pr/src/display.rs `pixel_direct_shadowed`): at each pixel of the element
// scene's G-buffer, every light's irradiance times its exponential-shadow-map factor
// (eq. 30 of the ISR thesis) is added to its source's slot, pixel-major, before the frame's
// factors. The display pass reads the result as its per-pixel direct light. The light set
// sits at bindings 6 (lights) and 7 (shadow texels).

struct DirectParams {
    frustum: FrustumReconstruction,
    width: u32,
    height: u32,
    k: u32,
    lights: u32,
    shadow: ShadowParams,
}

@group(0) @binding(0) var<uniform> params: DirectParams;
// Per light: the slot of the source that holds it, or 0xffffffff.
@group(0) @binding(1) var<storage, read> slot_of: array<u32>;
// Per pixel and source: direct irradiance (rgb), pixel-major.
@group(0) @binding(2) var<storage, read_write> direct: array<vec4<f32>>;
@group(0) @binding(3) var g_normal: texture_2d<f32>;
@group(0) @binding(4) var g_depth: texture_2d<f32>;
@group(0) @binding(5) var g_id: texture_2d<u32>;

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
    if textureLoad(g_id, xy, 0).x == 0xffffffffu {
        return;
    }
    let uv = (vec2<f32>(gid.xy) + 0.5) / vec2<f32>(f32(params.width), f32(params.height));
    let p = reconstruct(params.frustum, uv, textureLoad(g_depth, xy, 0).x);
    let n = textureLoad(g_normal, xy, 0).xyz;
    for (var j = 0u; j < params.lights; j++) {
        let m = slot_of[j];
        if m >= k {
            continue;
        }
        let l = lights[j];
        let e = irradiance(l, p, n);
        if all(e == vec3<f32>(0.0)) {
            continue;
        }
        direct[i * k + m] += vec4<f32>(e * visibility(l, p, n, params.shadow), 0.0);
    }
    // No NaN or infinity leaves the pass (pixel_direct_shadowed does the same).
    for (var m = 0u; m < k; m++) {
        let v = direct[i * k + m].xyz;
        let finite = all(v == v) && all(abs(v) <= vec3<f32>(3.4e38));
        direct[i * k + m] = vec4<f32>(select(vec3<f32>(0.0), v, finite), 0.0);
    }
}
