#import isr::common::{usable_normal, g}
#import scene_core::limits::{BACKGROUND, MAX_FINITE}
// Bilateral upsampling of the blurred coarse buffer to full resolution (thesis section 4.5,
// eqs. 27-28; mirrors crates/isr/src/upsample.rs).
//
// Weights w_i' = w_i^b w_i^z (w_i^n): bilinear, 1 / max(|z_p - z_i|, eps z_p) (the guarded
// eq. 27), and optionally max(n_p . n_i, 0)^k; background coarse samples get 0; normalised by
// eq. 28. When they all vanish, the non-background coarse sample of the surrounding 4x4 block
// nearest in depth is taken; with none, no indirect light and no occlusion.

// common.wgsl (isr::common) declares Globals, g (group 0, binding 0), the FLAG_* constants
// and the view helpers.

const VANISHED: f32 = 1e-30;

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
