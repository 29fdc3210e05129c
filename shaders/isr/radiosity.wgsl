#import isr::common::{FLAG_INDIRECT, FLAG_SSAO, FLAG_THESIS, FLAG_LIT, PI, MIN_FOOTPRINT_COS, has_flag, pixel_uv, world, ray_q, view_scale, receiver_disk, normal_or_viewer, g}
#import scene_core::limits::{BACKGROUND, MAX_FINITE}
// The ISR + SSAO pass on the coarse buffers (thesis section 4.4, listing 6; mirrors
// crates/isr/src/radiosity.rs, which documents the readings of the equations).
//
// Per coarse pixel P: N samples of a Vogel spiral in the screen-space disk that the world
// radius R subtends at P's depth, rotated per pixel (4x4 Bayer rotations). Each sample X is a
// patch (figure 4.4) and gives
//   indirect light, eq. 25:  thesis  rho_P (2 pi / N) cos_P cos_X A_X / (pi max(r^2, A_X)),
//                                    A_X the fronto-parallel pixel footprint at X's depth;
//                            patch   rho_P L_X cos_P cos_X A_X / (pi r^2 + A_X),
//                                    A_X = 1/N of the disk projected onto X's surface;
//   occlusion, eq. 26:       (2 pi / N or 2) (1 - sqrt(1 - min(r_s^2 / r^2, 1))) cos_P,
//                            r_s the radius of a sphere of the patch's (projected) area.
// Output: indirect radiance in rgb, accessibility (1 - occlusion) in a.

// common.wgsl (isr::common) declares Globals, g (group 0, binding 0), the FLAG_* constants
// and the view helpers.

// 16 per-pixel rotations (cos, sin), then the N unit-disk offsets, in xy.
@group(0) @binding(1) var<storage, read> pattern: array<vec4<f32>>;
@group(0) @binding(2) var albedo_tex: texture_2d<f32>;
@group(0) @binding(3) var normal_tex: texture_2d<f32>;
@group(0) @binding(4) var depth_tex: texture_2d<f32>;
@group(0) @binding(5) var id_tex: texture_2d<u32>;
// Direct radiance of each coarse pixel (the Lit senders); a dummy in Albedo mode.
@group(0) @binding(6) var sender_tex: texture_2d<f32>;
@group(0) @binding(7) var out_tex: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(depth_tex);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let nothing = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if (textureLoad(id_tex, p, 0).x == BACKGROUND) {
        textureStore(out_tex, p, nothing);
        return;
    }
    let uv = pixel_uv(p, size);
    let z0 = textureLoad(depth_tex, p, 0).x;
    if (!(z0 > 0.0)) {
        textureStore(out_tex, p, nothing);
        return;
    }
    let p0 = world(uv, z0);
    let n0 = normal_or_viewer(textureLoad(normal_tex, p, 0).xyz, uv);
    let a0 = textureLoad(albedo_tex, p, 0);
    let rho = a0.rgb * a0.a;
    let samples = g.config.x;
    let n = f32(samples);
    let disk = receiver_disk(z0, size);
    let rp = disk.x;
    let radius_px = disk.yz;
    let span = vec2<f32>(g.du_span.w, g.dv_span.w);
    let disk_share = PI * rp * rp / n;
    let rot = pattern[(gid.y % 4u) * 4u + gid.x % 4u].xy;
    let centre = vec2<f32>(p) + vec2<f32>(0.5);
    let thesis = has_flag(FLAG_THESIS);
    let indirect = has_flag(FLAG_INDIRECT);
    let ssao = has_flag(FLAG_SSAO);
    let lit = has_flag(FLAG_LIT);
    let pixel_plane = (span.x / f32(size.x)) * (span.y / f32(size.y));
    var gi = vec3<f32>(0.0);
    var occlusion = 0.0;
    for (var k = 0u; k < samples; k++) {
        let o = pattern[16u + k].xy;
        let r = vec2<f32>(o.x * rot.x - o.y * rot.y, o.x * rot.y + o.y * rot.x);
        let s = floor(centre + r * radius_px);
        if (!(s.x >= 0.0 && s.y >= 0.0 && s.x < f32(size.x) && s.y < f32(size.y))) {
            continue;
        }
        let sp = vec2<i32>(s);
        if (all(sp == p) || textureLoad(id_tex, sp, 0).x == BACKGROUND) {
            continue;
        }
        let uvk = pixel_uv(sp, size);
        let zk = textureLoad(depth_tex, sp, 0).x;
        if (!(zk > 0.0)) {
            continue;
        }
        let xk = world(uvk, zk);
        let nk = normal_or_viewer(textureLoad(normal_tex, sp, 0).xyz, uvk);
        let d = xk - p0;
        let r2 = dot(d, d);
        if (!(r2 > 0.0 && r2 <= MAX_FINITE)) {
            continue;
        }
        let dir = d / sqrt(r2);
        let cos_p = dot(n0, dir);
        if (cos_p <= 0.0) {
            continue;
        }
        let cos_x = -dot(nk, dir);
        let sk = view_scale(zk);
        var area: f32;
        if (thesis) {
            area = sk * sk * pixel_plane;
        } else {
            let c = max(abs(dot(nk, ray_q(uvk))), MIN_FOOTPRINT_COS);
            area = sk * sk * disk_share / c;
        }
        if (indirect && cos_x > 0.0) {
            var l: vec3<f32>;
            if (lit) {
                l = textureLoad(sender_tex, sp, 0).rgb;
            } else {
                l = textureLoad(albedo_tex, sp, 0).rgb;
            }
            var f: f32;
            if (thesis) {
                f = cos_p * cos_x * area / (PI * max(r2, area));
            } else {
                f = cos_p * cos_x * area / (PI * r2 + area);
            }
            gi += l * f;
        }
        if (ssao) {
            var sphere: f32;
            if (thesis) {
                sphere = area / PI;
            } else {
                sphere = area * abs(cos_x) / PI;
            }
            let cap = 1.0 - sqrt(1.0 - min(sphere / r2, 1.0));
            occlusion += cap * cos_p;
        }
    }
    if (thesis) {
        gi = gi * (2.0 * PI / n);
        occlusion = occlusion * (2.0 * PI / n);
    } else {
        occlusion = 2.0 * occlusion;
    }
    var out_gi = vec3<f32>(0.0);
    if (indirect) {
        out_gi = rho * gi;
    }
    var access = 1.0;
    if (ssao) {
        access = clamp(1.0 - occlusion, 0.0, 1.0);
    }
    textureStore(out_tex, p, vec4<f32>(out_gi, access));
}
