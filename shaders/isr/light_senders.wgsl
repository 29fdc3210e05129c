#import isr::common::{PI, pixel_uv, world, receiver_disk, normal_or_viewer, g}
#import scene_core::limits::{BACKGROUND, MAX_FINITE}
#import scene_core::light_set::lights
// The light-space senders' gather (issue 50; mirrors crates/isr/src/light_senders.rs'
// `LightSenders::gather`, which documents the estimator): after the ISR + SSAO pass, per
// coarse pixel P, the one-bounce light of every light-space sender S in front of P and
// facing it,
//   rho_P sum_S power_S f_l cos_P cos_S / (pi (pi r^2 + A_S)),
// f_l the frame's indirect factor of S's light, added to the pass' indirect radiance
// (accessibility kept). Interleaved (g.senders.z), a pixel gathers only the senders of its
// place in the 4x4 tile, each weighted 16, and the blur averages the 16 phases. With once on (g.senders.y), a sender the coarse G-buffer shows
// (depth within 2 %, normals within 60 degrees) at a pixel whose centre lies in P's
// screen-space disk is left out: P's screen-space samples already stand for it.

struct LightSender {
    // xyz: where the light's ray hit; w: the patch's area A_S.
    position_area: vec4<f32>,
    // xyz: unit normal on the lit side; w: the light's index (its bits).
    normal_light: vec4<f32>,
    // rgb: reflected power before the frame's factor.
    power: vec4<f32>,
    // xyz: the visibility map's tangent (its bitangent is normal x tangent).
    tangent: vec4<f32>,
}

// Texels per side of a sender's visibility map and the plane test's tolerance
// (light_senders.rs' DEPTH_RES, PLANE_TOLERANCE).
const DEPTH_RES: u32 = 16u;
const PLANE_TOLERANCE: f32 = 0.02;

@group(0) @binding(1) var<storage, read> senders: array<LightSender>;
@group(0) @binding(2) var albedo_tex: texture_2d<f32>;
@group(0) @binding(3) var normal_tex: texture_2d<f32>;
@group(0) @binding(4) var depth_tex: texture_2d<f32>;
@group(0) @binding(5) var id_tex: texture_2d<u32>;
// (binding 6: the light set's lights, scene_core::light_set)
// The ISR + SSAO pass' output: indirect rgb, accessibility a.
@group(0) @binding(7) var radiosity_tex: texture_2d<f32>;
@group(0) @binding(10) var out_tex: texture_storage_2d<rgba32float, write>;
// Each sender's visibility map: DEPTH_RES^2 distances, row by row.
@group(0) @binding(11) var<storage, read> depths: array<f32>;

// The local direction (z along the normal) through the centre of texel (x, y) of a
// sender's paraboloid map, centres outside the unit disk moved onto it (light_senders.rs'
// `map_direction`).
fn map_direction(x: u32, y: u32) -> vec3<f32> {
    let res = f32(DEPTH_RES);
    var uv = vec2<f32>((f32(x) + 0.5) / res * 2.0 - 1.0, (f32(y) + 0.5) / res * 2.0 - 1.0);
    let q0 = dot(uv, uv);
    if (q0 > 0.998) {
        uv = uv * sqrt(0.998 / q0);
    }
    let q = dot(uv, uv);
    let z = (1.0 - q) / (1.0 + q);
    return vec3<f32>(uv * (1.0 + z), z);
}

// The visibility (0 to 1) of a receiver in unit direction w at distance r from sender k,
// its unit normal n0 at cosine cos_p to -w (light_senders.rs' `map_visibility`: paraboloid
// map, the plane test, bilinear percentage-closer weights).
fn map_visibility(k: u32, s: LightSender, w: vec3<f32>, r: f32, n0: vec3<f32>, cos_p: f32) -> f32 {
    let n = s.normal_light.xyz;
    let t = s.tangent.xyz;
    let b = cross(n, t);
    let z = max(dot(n, w), 0.0);
    let uv = vec2<f32>(dot(t, w), dot(b, w)) / (1.0 + z);
    let f = (uv * 0.5 + vec2<f32>(0.5)) * f32(DEPTH_RES) - vec2<f32>(0.5);
    let base = floor(f);
    let a = f - base;
    // (hit - p0) . n0 = (sender - p0) . n0 + depth (l . (t, b, n) . n0), l the texel's local
    // direction and (sender - p0) . n0 = r cos_p: the frame's axes against the receiver's
    // normal are found once.
    let tolerance = r * (PLANE_TOLERANCE - cos_p);
    let axes = vec3<f32>(dot(t, n0), dot(b, n0), dot(n, n0));
    let first = k * DEPTH_RES * DEPTH_RES;
    let last = i32(DEPTH_RES) - 1;
    var seen = 0.0;
    for (var c = 0u; c < 4u; c++) {
        let dx = i32(c & 1u);
        let dy = i32(c >> 1u);
        let weight = select(1.0 - a.x, a.x, dx == 1) * select(1.0 - a.y, a.y, dy == 1);
        let x = u32(clamp(i32(base.x) + dx, 0, last));
        let y = u32(clamp(i32(base.y) + dy, 0, last));
        let depth = depths[first + y * DEPTH_RES + x];
        if (depth >= MAX_FINITE || depth * dot(map_direction(x, y), axes) <= tolerance) {
            seen += weight;
        }
    }
    return seen;
}

// Whether the coarse G-buffer shows the point q (unit normal nq) at a pixel whose centre
// lies in the disk of pixel radii radius_px around centre (light_senders.rs' `shown_at`
// and `Receiver::disk_holds`).
fn shown_in_disk(
    q: vec3<f32>,
    nq: vec3<f32>,
    size: vec2<u32>,
    centre: vec2<f32>,
    radius_px: vec2<f32>,
) -> bool {
    let clip = g.view_proj * vec4<f32>(q, 1.0);
    if (!(clip.w > 0.0)) {
        return false;
    }
    let ndc = clip.xy / clip.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    if (!(uv.x >= 0.0 && uv.y >= 0.0 && uv.x < 1.0 && uv.y < 1.0)) {
        return false;
    }
    let px = min(vec2<u32>(uv * vec2<f32>(size)), size - vec2<u32>(1u));
    let d = (vec2<f32>(px) + vec2<f32>(0.5) - centre) / radius_px;
    if (!(dot(d, d) <= 1.0)) {
        return false;
    }
    let pi = vec2<i32>(px);
    if (textureLoad(id_tex, pi, 0).x == BACKGROUND) {
        return false;
    }
    let zq = dot(q - g.eye_far.xyz, g.forward_extent.xyz) / g.eye_far.w;
    let zg = textureLoad(depth_tex, pi, 0).x;
    return abs(zq - zg) <= 0.02 * zg && dot(textureLoad(normal_tex, pi, 0).xyz, nq) >= 0.5;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(depth_tex);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let base = textureLoad(radiosity_tex, p, 0);
    if (textureLoad(id_tex, p, 0).x == BACKGROUND) {
        textureStore(out_tex, p, base);
        return;
    }
    let z0 = textureLoad(depth_tex, p, 0).x;
    if (!(z0 > 0.0)) {
        textureStore(out_tex, p, base);
        return;
    }
    // The receiver (radiosity.rs' `Receiver::at`, as the ISR + SSAO pass sets it up).
    let uv = pixel_uv(p, size);
    let p0 = world(uv, z0);
    let n0 = normal_or_viewer(textureLoad(normal_tex, p, 0).xyz, uv);
    let a0 = textureLoad(albedo_tex, p, 0);
    let rho = a0.rgb * a0.a;
    let radius_px = receiver_disk(z0, size).yz;
    let centre = vec2<f32>(p) + vec2<f32>(0.5);
    // Interleaved: this pixel's phase of the 4x4 tile, each of its senders weighted 16.
    var first = 0u;
    var end = g.senders.x;
    var weight = 1.0;
    if (g.senders.z != 0u) {
        let phase = (gid.y % 4u) * 4u + gid.x % 4u;
        first = g.sender_phases[phase / 4u][phase % 4u];
        end = g.sender_phases[(phase + 1u) / 4u][(phase + 1u) % 4u];
        weight = 16.0;
    }
    let once = g.senders.y != 0u;
    let visibility = g.senders.w != 0u;
    let light_count = arrayLength(&lights);
    var sum = vec3<f32>(0.0);
    for (var k = first; k < end; k++) {
        let s = senders[k];
        let d = s.position_area.xyz - p0;
        let r2 = dot(d, d);
        if (!(r2 > 0.0 && r2 <= MAX_FINITE)) {
            continue;
        }
        let dir = d / sqrt(r2);
        let cos_p = dot(n0, dir);
        let cos_s = -dot(s.normal_light.xyz, dir);
        if (cos_p <= 0.0 || cos_s <= 0.0) {
            continue;
        }
        let light = bitcast<u32>(s.normal_light.w);
        if (light >= light_count) {
            continue;
        }
        // Only a first bounce's sender (tangent.w 1) is what the screen-space senders send.
        if (once && s.tangent.w < 1.5 && shown_in_disk(s.position_area.xyz, s.normal_light.xyz, size, centre, radius_px)) {
            continue;
        }
        var seen = 1.0;
        if (visibility) {
            seen = map_visibility(k, s, -dir, sqrt(r2), n0, cos_p);
        }
        let power = s.power.rgb * lights[light].indirect;
        sum += power * (seen * cos_p * cos_s / (PI * (PI * r2 + s.position_area.w)));
    }
    textureStore(out_tex, p, vec4<f32>(base.rgb + rho * sum * weight, base.a));
}
