#import isr::common::{FLAG_INDIRECT, FLAG_SSAO, FLAG_AO_INDIRECT_ONLY, PI, has_flag, pixel_uv, world, to_viewer, usable_normal, g}
#import scene_core::limits::{BACKGROUND, MAX_FINITE}
#import scene_core::light_set::{lights, irradiance, emission}
#import scene_core::shadow::{ShadowParams, visibility}
// The lighting phase (thesis section 4.5, eq. 29, listing 7; mirrors
// crates/isr/src/lighting.rs).
//
// Direct light C_0 / pi * sum_l E_l V_l over the light set (scene-core's light_set.wgsl), each light
// shadowed by its ESM (scene-core's shadow.wgsl). MODE_SENDERS writes the direct radiance (the Lit
// senders of the ISR pass); MODE_COMPOSE composes eq. 29 with the upsampled ISR/SSAO buffer
// (when HAS_ISR) and adds the emission of visible emitters (front side only).

// Pass options, one pipeline each (pipeline-overridable constants).
const MODE_SENDERS: u32 = 0u;
const MODE_COMPOSE: u32 = 1u;
override MODE: u32 = 1u;
override HAS_ISR: bool = true;

// The output: Rgba32Float, or Rgba16Float in the variant composed with OUTPUT_RGBA16F (WGSL
// cannot make a storage format overridable).
#ifdef OUTPUT_RGBA16F
@group(0) @binding(10) var out_tex: texture_storage_2d<rgba16float, write>;
#else
@group(0) @binding(10) var out_tex: texture_storage_2d<rgba32float, write>;
#endif

@group(0) @binding(1) var albedo_tex: texture_2d<f32>;
@group(0) @binding(2) var normal_tex: texture_2d<f32>;
@group(0) @binding(3) var depth_tex: texture_2d<f32>;
@group(0) @binding(4) var id_tex: texture_2d<u32>;
@group(0) @binding(5) var isr_tex: texture_2d<f32>;

// The shadowed irradiance at p (unit normal n) from all lights, each scaled by its factor
// for this pass: the direct factor when composing, the indirect one for the Lit senders.
fn shadowed_irradiance(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    var e = vec3<f32>(0.0);
    let count = g.config.z;
    let sp = ShadowParams(g.filters.w, g.shadow.x, g.shadow.y, g.forward_extent.w);
    for (var i = 0u; i < count; i++) {
        let l = lights[i];
        var factor = l.direct;
        if (MODE == MODE_SENDERS) {
            factor = l.indirect;
        }
        let li = irradiance(l, p, n) * factor;
        if (all(li == vec3<f32>(0.0))) {
            continue;
        }
        e += li * visibility(l, p, n, sp);
    }
    return e;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(depth_tex);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let id = textureLoad(id_tex, p, 0).x;
    if (id == BACKGROUND) {
        textureStore(out_tex, p, vec4<f32>(0.0, 0.0, 0.0, 1.0));
        return;
    }
    let uv = pixel_uv(p, size);
    let pos = world(uv, textureLoad(depth_tex, p, 0).x);
    let eye_dir = to_viewer(uv);
    let n = usable_normal(textureLoad(normal_tex, p, 0).xyz, eye_dir);
    let c0 = textureLoad(albedo_tex, p, 0).rgb;
    let e = shadowed_irradiance(pos, n);
    if (MODE == MODE_SENDERS) {
        textureStore(out_tex, p, vec4<f32>(c0 * (1.0 / PI) * e, 1.0));
        return;
    }
    let direct = c0 * (1.0 / PI) * e * g.k.x;
    let glow = emission(id, eye_dir);
    var v = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if (HAS_ISR) {
        v = textureLoad(isr_tex, p, 0);
    }
    var ao = 1.0;
    if (has_flag(FLAG_SSAO)) {
        ao = clamp(v.w + 1.0 - g.k.y, 0.0, 1.0);
    }
    var indirect = vec3<f32>(0.0);
    if (has_flag(FLAG_INDIRECT)) {
        indirect = v.rgb * g.k.z;
    }
    var out: vec3<f32>;
    if (has_flag(FLAG_AO_INDIRECT_ONLY)) {
        out = glow + direct + indirect * ao;
    } else {
        out = glow + direct * ao + indirect;
    }
    if (!all(abs(out) <= vec3<f32>(MAX_FINITE))) {
        out = vec3<f32>(0.0);
    }
    textureStore(out_tex, p, vec4<f32>(out, 1.0));
}
