#import isr::common::{FLAG_EDGE_AWARE, MIN_POSITIVE, has_flag, pixel_uv, world, view_scale, normal_or_viewer, g}
#import scene_core::limits::BACKGROUND
// One direction of the separable blur of the coarse ISR/SSAO buffer (thesis section 4.2,
// listing 3: BlurHorizontal, BlurVertical; mirrors crates/isr/src/blur.rs).
//
// Gaussian taps exp(-k^2 / (2 sigma^2)), k in [-R, R]; background pixels take no part. The
// edge-aware variant also weights a tap by exp(-(d / (EDGE_PLANE_SIGMA s))^2), d its distance
// from the centre pixel's tangent plane and s the centre's view depth, times
// max(n_c . n_t, 0)^2.

// common.wgsl (isr::common) declares Globals, g (group 0, binding 0), the FLAG_* constants
// and the view helpers.

const EDGE_PLANE_SIGMA: f32 = 0.05;

// The direction, one pipeline each (a pipeline-overridable constant).
override HORIZONTAL: bool = true;

@group(0) @binding(1) var normal_tex: texture_2d<f32>;
@group(0) @binding(2) var depth_tex: texture_2d<f32>;
@group(0) @binding(3) var id_tex: texture_2d<u32>;
@group(0) @binding(4) var in_tex: texture_2d<f32>;
@group(0) @binding(5) var out_tex: texture_storage_2d<rgba32float, write>;

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
    let horizontal = HORIZONTAL;
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
