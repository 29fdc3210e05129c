#import scene_core::texture_wrap::{texel_taps, blend_taps}

// The GPU reference path tracer (scene_core::reference::gpu): the estimator of the CPU
// reference (crates/scene-core/src/rays/reference/tracer.rs) on the same four-wide BVH,
// one invocation per pixel, its samples in sample-index order.
//
// What it shares with the CPU tracer, decision for decision: Lambertian two-sided
// reflection, one-sided emission from the winding's side; next-event estimation of point
// and spot lights (inverse-square or eq. 16's windowed falloff of the ISR thesis), suns,
// a non-uniform sky drawn from its map, and emissive triangles picked by power (with an
// emission texture's pattern), the last two MIS-weighted (power heuristic) against the
// cosine-weighted bounce; Russian roulette from RR_START_DEPTH on, with survival equal to
// the throughput; alpha masks in every ray query; textures sampled as
// scene_core::Texture::sample does; the light state's direct and indirect factors. The
// pixel position and the first four vertices' emitter points and bounces come from the
// pixel's scrambled Sobol sequences (Burley 2020), as on the CPU.
//
// What differs: the random numbers (32-bit hashes instead of the CPU's 64-bit ones, so the
// two tracers' images agree in distribution, not bit for bit); an emitter, and a sky
// pixel, are picked from an alias table (Walker) rather than by bisecting a CDF, each
// with its exact probability; the mean and the variance are accumulated by Welford's
// update in f32 (stable, and the same whatever the split into dispatches).

const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.318309886183791;
const TAU: f32 = 6.28318530717959;
const NONE: u32 = 0xffffffffu;
const LEAF_BIT: u32 = 0x80000000u;
const STACK: u32 = 64u;
// 1 + 2 gamma(3) (Ize 2013), as bvh4.rs widens a box's far distance.
const FAR_WIDEN: f32 = 1.0000003576279;
// scene_core::reference::RR_START_DEPTH.
const RR_START_DEPTH: u32 = 4u;
// The decisions stratified per pixel, as on the CPU: the pixel position, then the emitter
// point and the bounce of each of the first STRATIFIED_VERTICES vertices.
const STRATIFIED_VERTICES: u32 = 4u;
const PAIRS: u32 = 9u;

const FLAG_SEES_EMISSION: u32 = 1u;
const FLAG_SKY: u32 = 2u;
const FLAG_SKY_NEE: u32 = 4u;
const FLAG_CUTOUTS: u32 = 8u;
// trace_rays answers the closest hit alone (GpuPathTracer::closest_hits): no occlusion query.
const FLAG_HITS_ONLY: u32 = 16u;

struct Params {
    // The camera ray through image point (u, v): origin o0 + ou u + ov v, direction
    // normalize(d0 + du u + dv v) (View::ray for both projections).
    cam_o0: vec4<f32>,
    cam_ou: vec4<f32>,
    cam_ov: vec4<f32>,
    cam_d0: vec4<f32>,
    cam_du: vec4<f32>,
    cam_dv: vec4<f32>,
    // The sky's light-state factors (direct, indirect).
    sky_direct: vec4<f32>,
    sky_indirect: vec4<f32>,
    width: u32,
    height: u32,
    first_sample: u32,
    samples: u32,
    // The last surface vertex that reflects (Bounces::Limited(n): n).
    max_vertex: u32,
    seed_lo: u32,
    seed_hi: u32,
    flags: u32,
    // RayScene's power-of-two scale of the tree's coordinates.
    scale: f32,
    eps: f32,
    far: f32,
    n_points: u32,
    n_dirs: u32,
    n_emitters: u32,
    sky_w: u32,
    sky_h: u32,
    // Offsets (in vec4s) of the sections of `data`.
    off_materials: u32,
    off_textures: u32,
    off_points: u32,
    off_dirs: u32,
    off_emitters: u32,
    off_patterns: u32,
    off_meshes: u32,
    off_sky: u32,
}

// bvh4.rs' Node: four children's boxes as lanes.
struct Node {
    lo_x: vec4<f32>,
    lo_y: vec4<f32>,
    lo_z: vec4<f32>,
    hi_x: vec4<f32>,
    hi_y: vec4<f32>,
    hi_z: vec4<f32>,
    child: vec4<u32>,
    used: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// bvh4.rs' Packet: four triangles as lanes (vertex and two edges, scaled coordinates).
struct Packet {
    v0_x: vec4<f32>,
    v0_y: vec4<f32>,
    v0_z: vec4<f32>,
    e1_x: vec4<f32>,
    e1_y: vec4<f32>,
    e1_z: vec4<f32>,
    e2_x: vec4<f32>,
    e2_y: vec4<f32>,
    e2_z: vec4<f32>,
    id: vec4<u32>,
}

// What shading needs of a triangle, by global id.
struct Tri {
    // Unit geometric normal (the winding's side); w: material.
    ng: vec4<f32>,
    // Vertex normals; w: the mesh, the emitter entry (NONE), the flags (1 uv, 2 colour).
    n0: vec4<f32>,
    n1: vec4<f32>,
    n2: vec4<f32>,
    uv01: vec4<f32>,
    uv2: vec4<f32>,
    c0: vec4<f32>,
    c1: vec4<f32>,
    c2: vec4<f32>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
@group(0) @binding(2) var<storage, read> packets: array<Packet>;
@group(0) @binding(3) var<storage, read> tris: array<Tri>;
// Sections at the offsets of Params (the Rust side documents each entry).
@group(0) @binding(4) var<storage, read> data: array<vec4<f32>>;
// All textures' linear RGB texels (w alpha), top row first, one after the other.
@group(0) @binding(5) var<storage, read> texels: array<vec4<f32>>;
// The running mean of every pixel (row-major), then every pixel's sum of squared
// deviations: the first half is a pixel buffer (PixelsToTexture shows it).
@group(0) @binding(6) var<storage, read_write> accum: array<vec4<f32>>;

fn as_u(x: f32) -> u32 {
    return bitcast<u32>(x);
}

// ---- random numbers ----

// A 32-bit integer hash (Wellons' "lowbias32": two multiply-xorshift rounds).
fn lowbias(v: u32) -> u32 {
    var x = v;
    x = x ^ (x >> 16u);
    x = x * 0x7feb352du;
    x = x ^ (x >> 15u);
    x = x * 0x846ca68bu;
    x = x ^ (x >> 16u);
    return x;
}

// A hash of two numbers, non-linear in both (so that nearby pairs give unrelated values).
fn hash2(a: u32, b: u32) -> u32 {
    return lowbias(lowbias(a ^ 0x2545f491u) ^ (b * 0x9e3779b9u + 0x7f4a7c15u));
}

// The sample's generator (a counter hashed with the sample's key: every sample has its own
// stream, the same on every adapter), and its pixel's sequence seed and sample index:
// private to the invocation, set before each sample.
var<private> rng_key: u32;
var<private> rng_count: u32;
var<private> draw_base: u32;
var<private> draw_sample: u32;

fn next_u32() -> u32 {
    rng_count = rng_count + 1u;
    return hash2(rng_key, rng_count);
}

fn unit(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

fn rand() -> f32 {
    return unit(next_u32());
}

// A uniform index in 0..n (n > 0), without modulo bias.
fn next_index(n: u32) -> u32 {
    let lim = (0u - n) % n;
    var x = next_u32();
    while (x < lim) {
        x = next_u32();
    }
    return x % n;
}

// The 32 bits of `x` in reverse order (WGSL's reverseBits, written out: the MSL versions
// naga targets lack it).
fn flip_bits(x: u32) -> u32 {
    var v = x;
    v = ((v >> 1u) & 0x55555555u) | ((v & 0x55555555u) << 1u);
    v = ((v >> 2u) & 0x33333333u) | ((v & 0x33333333u) << 2u);
    v = ((v >> 4u) & 0x0f0f0f0fu) | ((v & 0x0f0f0f0fu) << 4u);
    v = ((v >> 8u) & 0x00ff00ffu) | ((v & 0x00ff00ffu) << 8u);
    return (v >> 16u) | (v << 16u);
}

// scene_core::sampling::owen_scramble.
fn owen_scramble(x: u32, seed: u32) -> u32 {
    var v = flip_bits(x);
    v = v + seed;
    v = v ^ (v * 0x6c50b47cu);
    v = v ^ (v * 0xb82f1e52u);
    v = v ^ (v * 0xc7afe638u);
    v = v ^ (v * 0x8d22f6e6u);
    return flip_bits(v);
}

// Dimension 1 of Sobol's sequence (direction numbers of x + 1).
fn sobol_y(index: u32) -> u32 {
    var i = index;
    var v = 0x80000000u;
    var y = 0u;
    loop {
        if (i == 0u) {
            break;
        }
        if ((i & 1u) != 0u) {
            y = y ^ v;
        }
        i = i >> 1u;
        v = v ^ (v >> 1u);
    }
    return y;
}

// Point `index` of a pixel's scrambled Sobol sequence number `k` (scene_core::Sobol2d).
fn sobol_point(base: u32, k: u32, index: u32) -> vec2<f32> {
    let slot = hash2(base, k);
    let s0 = hash2(slot, 1u);
    let s1 = hash2(slot, 2u);
    let s2 = hash2(slot, 3u);
    let i = owen_scramble(index, s0);
    let x = owen_scramble(flip_bits(i), s1);
    let y = owen_scramble(sobol_y(i), s2);
    return vec2<f32>(unit(x), unit(y));
}

// The path's two-dimensional decision in slot `slot` (0 pixel, 1 + 2k emitter at vertex
// k, 2 + 2k bounce at vertex k): stratified for the first vertices, random after.
fn pair(slot: u32) -> vec2<f32> {
    if (slot < PAIRS) {
        return sobol_point(draw_base, slot, draw_sample);
    }
    let a = rand();
    let b = rand();
    return vec2<f32>(a, b);
}

// ---- sampling (scene_core::sampling) ----

// sin and cos of `t` in [-pi/4, pi/4] by their Taylor polynomials (errors below 4e-7):
// WGSL's sin and cos need only be within 2^-11 absolute (Vulkan's bound), where the CPU's
// are within an ulp.
fn sin_cos_quarter(t: f32) -> vec2<f32> {
    let t2 = t * t;
    let s = t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))));
    let c = 1.0 - t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))));
    return vec2<f32>(s, c);
}

// scene_core::sampling::concentric_disk (Shirley-Chiu), its angles within a quarter turn.
fn concentric_disk(u: vec2<f32>) -> vec2<f32> {
    let o = u * 2.0 - vec2<f32>(1.0);
    if (o.x == 0.0 && o.y == 0.0) {
        return vec2<f32>(0.0);
    }
    if (abs(o.x) > abs(o.y)) {
        let sc = sin_cos_quarter(0.785398163397448 * (o.y / o.x));
        return o.x * vec2<f32>(sc.y, sc.x);
    }
    // theta = pi/2 - t: cos(theta) = sin(t), sin(theta) = cos(t).
    let sc = sin_cos_quarter(0.785398163397448 * (o.x / o.y));
    return o.y * vec2<f32>(sc.x, sc.y);
}

fn orthonormal_basis(n: vec3<f32>) -> mat2x3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    return mat2x3<f32>(t, bt);
}

fn cosine_hemisphere(n: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let d = concentric_disk(u);
    let z = sqrt(max(1.0 - dot(d, d), 0.0));
    let tb = orthonormal_basis(n);
    return normalize(tb[0] * d.x + tb[1] * d.y + n * z);
}

fn uniform_triangle(u: vec2<f32>) -> vec2<f32> {
    let su = sqrt(u.x);
    return vec2<f32>(su * (1.0 - u.y), su * u.y);
}

fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    let s = a2 + b2;
    if (s > 0.0 && s <= 3.4e38) {
        return a2 / s;
    }
    if (a > 3.4e38) {
        return 1.0;
    }
    return 0.0;
}

// ---- textures (scene_core::Texture::sample, as shaders/gbuffer/mrt.wgsl) ----


// Texture `index`'s lookup at `uv`: (rgb, alpha); black and alpha 0 where it is empty or
// `uv` is not finite, as on the CPU.
fn sample_texture(index: u32, uv: vec2<f32>) -> vec4<f32> {
    let info = bitcast<vec4<u32>>(data[P.off_textures + index]);
    let finite = all(abs(uv) <= vec2<f32>(3.4e38));
    if (info.y == 0u || info.z == 0u || !finite) {
        return vec4<f32>(0.0);
    }
    let t = texel_taps(info, uv);
    return blend_taps(texels[t.top_left], texels[t.top_right], texels[t.bottom_left], texels[t.bottom_right], t.f);
}

// Material `m`: data[off + 3 m] = (albedo, albedo texture or NONE), + 1 = (emission,
// emission texture or NONE), + 2 = (alpha cutoff, 0, 0, 0).
fn tri_uv(t: Tri, b: vec2<f32>) -> vec2<f32> {
    return t.uv01.xy * (1.0 - b.x - b.y) + t.uv01.zw * b.x + t.uv2.xy * b.y;
}

fn has_uv(t: Tri) -> bool {
    return (as_u(t.n2.w) & 1u) != 0u;
}

// The unit shading normal at `b` (the vertex normals interpolated), on the side of `ng`,
// the geometric normal facing the incoming ray; `ng` itself where the normals vanish
// (scene_core::view::shading_normal).
fn shading_normal(t: Tri, b: vec2<f32>, ng: vec3<f32>) -> vec3<f32> {
    let ns = t.n0.xyz * (1.0 - b.x - b.y) + t.n1.xyz * b.x + t.n2.xyz * b.y;
    let len2 = dot(ns, ns);
    if (len2 > 0.0) {
        let unit = ns * inverseSqrt(len2);
        return select(unit, -unit, dot(unit, ng) < 0.0);
    }
    return ng;
}

fn albedo_at(t: Tri, b: vec2<f32>) -> vec3<f32> {
    let m = data[P.off_materials + 3u * as_u(t.ng.w)];
    var a = m.xyz;
    let tex = as_u(m.w);
    if (tex != NONE && has_uv(t)) {
        a = a * sample_texture(tex, tri_uv(t, b)).xyz;
    }
    if ((as_u(t.n2.w) & 2u) != 0u) {
        a = a * (t.c0.xyz * (1.0 - b.x - b.y) + t.c1.xyz * b.x + t.c2.xyz * b.y);
    }
    return a;
}

fn emission_at(t: Tri, b: vec2<f32>) -> vec3<f32> {
    let m = data[P.off_materials + 3u * as_u(t.ng.w) + 1u];
    let tex = as_u(m.w);
    if (tex != NONE && has_uv(t)) {
        return m.xyz * sample_texture(tex, tri_uv(t, b)).xyz;
    }
    return m.xyz;
}

// True where triangle `id` exists at barycentric `b` (scene_core::Cutouts::opaque).
fn exists(id: u32, b: vec2<f32>) -> bool {
    if ((P.flags & FLAG_CUTOUTS) == 0u) {
        return true;
    }
    let t = tris[id];
    let mi = P.off_materials + 3u * as_u(t.ng.w);
    let cutoff = data[mi + 2u].x;
    if (cutoff <= 0.0) {
        return true;
    }
    let tex = as_u(data[mi].w);
    var alpha = 1.0;
    if (tex != NONE && has_uv(t)) {
        alpha = sample_texture(tex, tri_uv(t, b)).w;
    }
    return alpha >= cutoff;
}

// ---- ray queries (bvh4.rs, in the tree's scaled coordinates) ----

struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
    inv: vec3<f32>,
    parallel: vec3<bool>,
    t_min: f32,
    t_max: f32,
}

fn prepare(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> Ray {
    var r: Ray;
    r.o = origin * P.scale;
    r.d = dir;
    r.parallel = abs(dir) <= vec3<f32>(1e-30);
    r.inv = select(vec3<f32>(1.0) / dir, vec3<f32>(0.0), r.parallel);
    r.t_min = t_min * P.scale;
    r.t_max = t_max * P.scale;
    return r;
}

// One axis of the slab test over four boxes.
fn slab(lo: vec4<f32>, hi: vec4<f32>, o: f32, inv: f32, parallel: bool,
        near: ptr<function, vec4<f32>>, far: ptr<function, vec4<f32>>,
        inside: ptr<function, vec4<bool>>) {
    if (parallel) {
        *inside = *inside & (lo <= vec4<f32>(o)) & (vec4<f32>(o) <= hi);
        return;
    }
    var n = lo;
    var f = hi;
    if (inv < 0.0) {
        n = hi;
        f = lo;
    }
    *near = max(*near, (n - vec4<f32>(o)) * inv);
    *far = min(*far, (f - vec4<f32>(o)) * inv);
}

struct BoxHits {
    mask: u32,
    near: vec4<f32>,
}

fn boxes(r: Ray, node: Node, t_max: f32) -> BoxHits {
    var near = vec4<f32>(r.t_min);
    var far = vec4<f32>(3.4e38);
    var inside = vec4<bool>(true);
    slab(node.lo_x, node.hi_x, r.o.x, r.inv.x, r.parallel.x, &near, &far, &inside);
    slab(node.lo_y, node.hi_y, r.o.y, r.inv.y, r.parallel.y, &near, &far, &inside);
    slab(node.lo_z, node.hi_z, r.o.z, r.inv.z, r.parallel.z, &near, &far, &inside);
    far = min(far * FAR_WIDEN, vec4<f32>(t_max));
    let hit = (near <= far) & inside;
    var mask = 0u;
    for (var l = 0u; l < 4u; l++) {
        if (hit[l]) {
            mask = mask | (1u << l);
        }
    }
    return BoxHits(mask & node.used, near);
}

struct Lanes {
    valid: vec4<bool>,
    t: vec4<f32>,
    u: vec4<f32>,
    v: vec4<f32>,
}

// Moeller-Trumbore on a packet's four triangles (bvh4.rs' PreparedRay::triangles).
fn triangles(r: Ray, p: Packet, t_max: f32) -> Lanes {
    let dx = vec4<f32>(r.d.x);
    let dy = vec4<f32>(r.d.y);
    let dz = vec4<f32>(r.d.z);
    let px = dy * p.e2_z - dz * p.e2_y;
    let py = dz * p.e2_x - dx * p.e2_z;
    let pz = dx * p.e2_y - dy * p.e2_x;
    let det = p.e1_x * px + p.e1_y * py + p.e1_z * pz;
    let inv = vec4<f32>(1.0) / det;
    let sx = vec4<f32>(r.o.x) - p.v0_x;
    let sy = vec4<f32>(r.o.y) - p.v0_y;
    let sz = vec4<f32>(r.o.z) - p.v0_z;
    let u = (sx * px + sy * py + sz * pz) * inv;
    let qx = sy * p.e1_z - sz * p.e1_y;
    let qy = sz * p.e1_x - sx * p.e1_z;
    let qz = sx * p.e1_y - sy * p.e1_x;
    let v = (dx * qx + dy * qy + dz * qz) * inv;
    let t = (p.e2_x * qx + p.e2_y * qy + p.e2_z * qz) * inv;
    let valid = (det != vec4<f32>(0.0)) & (abs(det) <= vec4<f32>(3.4e38))
        & (u >= vec4<f32>(0.0)) & (u <= vec4<f32>(1.0)) & (v >= vec4<f32>(0.0))
        & (u + v <= vec4<f32>(1.0)) & (t >= vec4<f32>(r.t_min))
        & (t < vec4<f32>(r.t_max)) & (t <= vec4<f32>(t_max));
    return Lanes(valid, t, u, v);
}

struct Hit {
    found: bool,
    id: u32,
    // Distance in world units.
    t: f32,
    b: vec2<f32>,
}

// The closest hit that exists (alpha masks), the lowest id among equally near ones.
fn closest_hit(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> Hit {
    var best: Hit;
    best.found = false;
    best.id = NONE;
    let r = prepare(origin, dir, t_min, t_max);
    var limit = r.t_max;
    var st_node: array<u32, 64>;
    var st_t: array<f32, 64>;
    var top = 0u;
    var current = 0u;
    loop {
        if ((current & LEAF_BIT) == 0u) {
            let node = nodes[current];
            let bh = boxes(r, node, limit);
            var m = bh.mask;
            let count = countOneBits(m);
            if (count == 1u) {
                current = node.child[firstTrailingBit(m)];
                continue;
            }
            if (count > 1u) {
                // Sort the hit children by entry distance (farthest first), push all but
                // the nearest and descend into it.
                var hc: array<u32, 4>;
                var ht: array<f32, 4>;
                var k = 0u;
                while (m != 0u) {
                    let lane = firstTrailingBit(m);
                    m = m & (m - 1u);
                    var j = k;
                    while (j > 0u && ht[j - 1u] < bh.near[lane]) {
                        hc[j] = hc[j - 1u];
                        ht[j] = ht[j - 1u];
                        j = j - 1u;
                    }
                    hc[j] = node.child[lane];
                    ht[j] = bh.near[lane];
                    k = k + 1u;
                }
                for (var i = 0u; i + 1u < k; i++) {
                    if (top < STACK) {
                        st_node[top] = hc[i];
                        st_t[top] = ht[i];
                        top = top + 1u;
                    }
                }
                current = hc[k - 1u];
                continue;
            }
        } else {
            let p = packets[current & ~LEAF_BIT];
            let lanes = triangles(r, p, limit);
            var m = 0u;
            for (var l = 0u; l < 4u; l++) {
                if (lanes.valid[l]) {
                    m = m | (1u << l);
                }
            }
            while (m != 0u) {
                // The nearest remaining lane (lowest id on ties).
                var lane = firstTrailingBit(m);
                var rest = m & (m - 1u);
                while (rest != 0u) {
                    let l = firstTrailingBit(rest);
                    rest = rest & (rest - 1u);
                    if (lanes.t[l] < lanes.t[lane] || (lanes.t[l] == lanes.t[lane] && p.id[l] < p.id[lane])) {
                        lane = l;
                    }
                }
                m = m & ~(1u << lane);
                let id = p.id[lane];
                let nearer = !best.found || lanes.t[lane] < best.t || (lanes.t[lane] == best.t && id < best.id);
                if (nearer && exists(id, vec2<f32>(lanes.u[lane], lanes.v[lane]))) {
                    best.found = true;
                    best.id = id;
                    best.t = lanes.t[lane];
                    best.b = vec2<f32>(lanes.u[lane], lanes.v[lane]);
                    limit = lanes.t[lane];
                    break;
                }
            }
        }
        // Next: the nearest pushed child the ray may still reach.
        var next = NONE;
        while (top > 0u) {
            top = top - 1u;
            if (st_t[top] <= limit) {
                next = st_node[top];
                break;
            }
        }
        if (next == NONE) {
            break;
        }
        current = next;
    }
    best.t = best.t / P.scale;
    return best;
}

// True when the segment meets a surface that exists.
fn occluded(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    let r = prepare(origin, dir, t_min, t_max);
    var stack: array<u32, 64>;
    var top = 0u;
    var current = 0u;
    loop {
        if ((current & LEAF_BIT) == 0u) {
            let node = nodes[current];
            var m = boxes(r, node, r.t_max).mask;
            if (m != 0u) {
                current = node.child[firstTrailingBit(m)];
                m = m & (m - 1u);
                while (m != 0u) {
                    if (top < STACK) {
                        stack[top] = node.child[firstTrailingBit(m)];
                        top = top + 1u;
                    }
                    m = m & (m - 1u);
                }
                continue;
            }
        } else {
            let p = packets[current & ~LEAF_BIT];
            let lanes = triangles(r, p, r.t_max);
            for (var l = 0u; l < 4u; l++) {
                if (lanes.valid[l] && exists(p.id[l], vec2<f32>(lanes.u[l], lanes.v[l]))) {
                    return true;
                }
            }
        }
        if (top == 0u) {
            return false;
        }
        top = top - 1u;
        current = stack[top];
    }
    return false;
}

// ---- lights ----

// Alias table entry `i` of a section: (threshold, alias) in the given vec4 lanes.
fn alias_pick(threshold: f32, other: u32, i: u32, u: f32) -> u32 {
    return select(other, i, u < threshold);
}

// The sky's map: data[off_sky + 2 i] = (radiance, pdf), + 1 = (threshold, alias, 0, 0).
// Row y's polar bounds: cos(pi y / h) and cos(pi (y + 1) / h), computed in f64 on the host.
fn sky_row_bounds(y: u32) -> vec2<f32> {
    return data[P.off_sky + 2u * y * P.sky_w + 1u].zw;
}

fn sky_pixel_of(d: vec3<f32>) -> u32 {
    // The row: the last whose upper bound the direction lies at or below (the polar angle
    // at or past the row's start), by bisection over the rows' bounds.
    var lo = 0u;
    var hi = P.sky_h;
    while (lo + 1u < hi) {
        let mid = (lo + hi) / 2u;
        if (d.y <= sky_row_bounds(mid).x) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    var phi = atan2(d.x, -d.z);
    if (phi < 0.0) {
        phi = phi + TAU;
    }
    let x = min(u32(max(phi / TAU * f32(P.sky_w), 0.0)), P.sky_w - 1u);
    return lo * P.sky_w + x;
}

// The sky light of throughput `beta` along `d` (which leaves the scene), drawn by a
// bounce of density `pdf` at a vertex whose light counts as `indirect`.
fn sky_light(beta: vec3<f32>, d: vec3<f32>, pdf: f32, indirect: bool) -> vec3<f32> {
    let s = data[P.off_sky + 2u * sky_pixel_of(d)];
    let factor = select(P.sky_direct.xyz, P.sky_indirect.xyz, indirect);
    if ((P.flags & FLAG_SKY_NEE) == 0u) {
        return beta * s.xyz * factor;
    }
    return beta * s.xyz * factor * power_heuristic(pdf, s.w);
}

// Irradiance at p (normal n) from every light by next-event estimation.
fn direct(p: vec3<f32>, n: vec3<f32>, indirect: bool, vertex: u32) -> vec3<f32> {
    var e = vec3<f32>(0.0);
    // Point and spot lights: data[off_points + 4 i] = (position, radius: < 0 none),
    // + 1 = (intensity x direct factor, 0), + 2 = (intensity x indirect factor, ramp
    // scale), + 3 = (ramp axis, ramp offset).
    for (var i = 0u; i < P.n_points; i++) {
        let o = P.off_points + 4u * i;
        let l0 = data[o];
        let intensity = select(data[o + 1u].xyz, data[o + 2u].xyz, indirect);
        let ramp = vec4<f32>(data[o + 3u].xyz, data[o + 2u].w);
        let to = l0.xyz - p;
        let dist = length(to);
        if (dist <= 0.0 || all(intensity == vec3<f32>(0.0))) {
            continue;
        }
        let w = to / dist;
        let cos = dot(n, w);
        var falloff: f32;
        if (l0.w > 0.0) {
            let q = dist / l0.w;
            falloff = clamp(1.0 - q * q, 0.0, 1.0);
        } else if (l0.w == 0.0) {
            falloff = 0.0;
        } else {
            falloff = min(1.0 / (dist * dist), 3.4028235e38);
        }
        let a = clamp(dot(ramp.xyz, -w) * ramp.w + data[o + 3u].w, 0.0, 1.0);
        let f = falloff * a * a;
        if (cos <= 0.0 || f <= 0.0) {
            continue;
        }
        if (!occluded(p, w, 0.0, dist * (1.0 - 1e-5))) {
            e = e + intensity * (f * cos);
        }
    }
    // Suns: data[off_dirs + 3 i] = (unit direction towards the sun, 0), + 1 = irradiance x
    // direct factor, + 2 = irradiance x indirect factor.
    for (var i = 0u; i < P.n_dirs; i++) {
        let o = P.off_dirs + 3u * i;
        let w = data[o].xyz;
        let irr = select(data[o + 1u].xyz, data[o + 2u].xyz, indirect);
        let cos = dot(n, w);
        if (cos <= 0.0 || all(irr == vec3<f32>(0.0))) {
            continue;
        }
        if (!occluded(p, w, 0.0, P.far)) {
            e = e + irr * cos;
        }
    }
    // The sky from its map.
    let sky_factor = select(P.sky_direct.xyz, P.sky_indirect.xyz, indirect);
    if ((P.flags & FLAG_SKY_NEE) != 0u && any(sky_factor != vec3<f32>(0.0))) {
        let n_px = P.sky_w * P.sky_h;
        let i = next_index(n_px);
        let t = data[P.off_sky + 2u * i + 1u];
        let px = alias_pick(t.x, as_u(t.y), i, rand());
        let s = data[P.off_sky + 2u * px];
        let x = px % P.sky_w;
        let y = px / P.sky_w;
        let phi = TAU * (f32(x) + rand()) / f32(P.sky_w);
        let bounds = sky_row_bounds(y);
        let c0 = bounds.x;
        let c1 = bounds.y;
        let ct = c0 + (c1 - c0) * rand();
        let st = sqrt(max(1.0 - ct * ct, 0.0));
        let w = vec3<f32>(st * sin(phi), ct, -st * cos(phi));
        let cos = dot(n, w);
        if (s.w > 0.0 && cos > 0.0) {
            if (!occluded(p, w, 0.0, P.far)) {
                let pb = cos * INV_PI;
                e = e + s.xyz * sky_factor * (cos / s.w * power_heuristic(s.w, pb));
            }
        }
    }
    // Emissive triangles: data[off_emitters + 5 k] = (corner 0, global triangle),
    // + 1 = (corner 1, alias), + 2 = (corner 2, area), + 3 = (unit normal, pick
    // probability), + 4 = (alias threshold, pattern offset or NONE, mesh, 0).
    if (P.n_emitters > 0u) {
        let i = next_index(P.n_emitters);
        let a = data[P.off_emitters + 5u * i + 4u];
        let a1 = data[P.off_emitters + 5u * i + 1u];
        let k = alias_pick(a.x, as_u(a1.w), i, rand());
        let o = P.off_emitters + 5u * k;
        let q0 = data[o];
        let q1 = data[o + 1u];
        let q2 = data[o + 2u];
        let q3 = data[o + 3u];
        let q4 = data[o + 4u];
        var b = uniform_triangle(pair(select(PAIRS, 1u + 2u * vertex, vertex < STRATIFIED_VERTICES)));
        var density = 1.0;
        let pattern = as_u(q4.y);
        if (pattern != NONE) {
            let pd = pattern_point(pattern, rand(), b);
            b = pd.xy;
            density = pd.z;
        }
        let q = q0.xyz * (1.0 - b.x - b.y) + q1.xyz * b.x + q2.xyz * b.y;
        let to = q - p;
        let d2 = dot(to, to);
        let factor = mesh_factor(as_u(q4.z), indirect);
        if (d2 > 0.0) {
            let dist = sqrt(d2);
            let w = to / dist;
            let cos = dot(n, w);
            let cos_l = dot(q3.xyz, -w);
            let id = as_u(q0.w);
            if (cos > 0.0 && cos_l > 0.0 && any(factor != vec3<f32>(0.0)) && exists(id, b)) {
                if (!occluded(p, w, 0.0, dist - 2.0 * P.eps)) {
                    let pdf_area = q3.w * density / q2.w;
                    let pl = pdf_area * d2 / cos_l;
                    let pb = cos * INV_PI;
                    let le = emission_at(tris[id], b);
                    e = e + le * factor * (cos / pl * power_heuristic(pl, pb));
                }
            }
        }
    }
    return e;
}

// Mesh `m`'s light-state factor (data[off_meshes + 2 m]: direct, + 1: indirect).
fn mesh_factor(m: u32, indirect: bool) -> vec3<f32> {
    return data[P.off_meshes + 2u * m + select(0u, 1u, indirect)].xyz;
}

// ---- emission patterns (scene_core::lights::EmissionPattern, TEXEL_GRID 8) ----

fn sub_triangle(s: u32) -> array<vec2<f32>, 3> {
    let n = 8u;
    var i = 0u;
    while (i + 1u < n && (i + 1u) * (2u * n - (i + 1u)) <= s) {
        i = i + 1u;
    }
    let k = s - i * (2u * n - i);
    let j = k / 2u;
    let x = f32(i);
    let y = f32(j);
    if (k % 2u == 1u) {
        return array<vec2<f32>, 3>(vec2<f32>(x + 1.0, y), vec2<f32>(x, y + 1.0), vec2<f32>(x + 1.0, y + 1.0));
    }
    return array<vec2<f32>, 3>(vec2<f32>(x, y), vec2<f32>(x + 1.0, y), vec2<f32>(x, y + 1.0));
}

fn sub_triangle_at(b: vec2<f32>) -> u32 {
    let n = 8u;
    let g = max(b * 8.0, vec2<f32>(0.0));
    let i = min(u32(floor(g.x)), n - 1u);
    let j = min(u32(floor(g.y)), n - 1u - i);
    let down = g.x - f32(i) + g.y - f32(j) > 1.0 && i + j + 1u < n;
    return i * (2u * n - i) + 2u * j + select(0u, 1u, down);
}

// Entry `s` of the pattern's CDF (64 floats from data[off_patterns + offset]).
fn pattern_cdf(offset: u32, s: u32) -> f32 {
    return data[P.off_patterns + offset + s / 4u][s % 4u];
}

fn pattern_density(offset: u32, s: u32) -> f32 {
    var before = 0.0;
    if (s > 0u) {
        before = pattern_cdf(offset, s - 1u);
    }
    return (pattern_cdf(offset, s) - before) * 64.0;
}

// A point of the pattern's sub-triangle picked by `u_sub`, placed by `b`; z: its density
// relative to sampling by area.
fn pattern_point(offset: u32, u_sub: f32, b: vec2<f32>) -> vec3<f32> {
    var s = 0u;
    while (s < 63u && pattern_cdf(offset, s) <= u_sub) {
        s = s + 1u;
    }
    let c = sub_triangle(s);
    let q = (c[0] + (c[1] - c[0]) * b.x + (c[2] - c[0]) * b.y) / 8.0;
    return vec3<f32>(q, pattern_density(offset, s));
}

// ---- the path ----

fn radiance(origin: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    var l = vec3<f32>(0.0);
    var beta = vec3<f32>(1.0);
    var o = origin;
    var d = dir;
    var prev_pdf = -1.0;
    let sees_emission = (P.flags & FLAG_SEES_EMISSION) != 0u;
    let sky = (P.flags & FLAG_SKY) != 0u;
    var k = 0u;
    loop {
        let indirect = k > 1u;
        if (k > P.max_vertex && !sees_emission) {
            // The last ray: only the sky can add light.
            if (sky && prev_pdf >= 0.0 && !occluded(o, d, 0.0, 3.4e38)) {
                l = l + sky_light(beta, d, prev_pdf, indirect);
            }
            break;
        }
        let hit = closest_hit(o, d, 0.0, 3.4e38);
        if (!hit.found) {
            if (sky && prev_pdf >= 0.0) {
                l = l + sky_light(beta, d, prev_pdf, indirect);
            }
            break;
        }
        let tri = tris[hit.id];
        let b = hit.b;
        let x = o + d * hit.t;
        let ng0 = tri.ng.xyz;
        let cos_l = dot(ng0, -d);
        let mesh = as_u(tri.n0.w);
        let factor = mesh_factor(mesh, indirect);
        let mat1 = data[P.off_materials + 3u * as_u(tri.ng.w) + 1u];
        let emissive = max(max(mat1.x, mat1.y), mat1.z) > 0.0;
        if (emissive && cos_l > 0.0 && any(factor != vec3<f32>(0.0))) {
            var w = 1.0;
            if (prev_pdf >= 0.0) {
                let ei = as_u(tri.n1.w);
                var pl = 0.0;
                if (ei != NONE) {
                    let q2 = data[P.off_emitters + 5u * ei + 2u];
                    let q3 = data[P.off_emitters + 5u * ei + 3u];
                    let q4 = data[P.off_emitters + 5u * ei + 4u];
                    var density = 1.0;
                    let pattern = as_u(q4.y);
                    if (pattern != NONE) {
                        density = pattern_density(pattern, sub_triangle_at(b));
                    }
                    pl = q3.w * density / q2.w * hit.t * hit.t / cos_l;
                }
                w = power_heuristic(prev_pdf, pl);
            }
            l = l + beta * emission_at(tri, b) * factor * w;
        }
        if (k > P.max_vertex) {
            break;
        }
        // Surface frame, flipped towards the incoming ray (two-sided reflection).
        let ng = select(-ng0, ng0, dot(ng0, d) < 0.0);
        let ns = shading_normal(tri, b, ng);
        let albedo = albedo_at(tri, b);
        let p = x + ng * P.eps;
        l = l + beta * albedo * INV_PI * direct(p, ns, k > 0u, k);
        let nd = cosine_hemisphere(ns, pair(select(PAIRS, 2u + 2u * k, k < STRATIFIED_VERTICES)));
        let cos = dot(nd, ns);
        if (dot(nd, ng) <= 0.0 || cos <= 0.0) {
            break;
        }
        beta = beta * albedo;
        if (k + 1u >= RR_START_DEPTH) {
            let q = min(max(max(beta.x, beta.y), beta.z), 1.0);
            if (q <= 0.0 || rand() >= q) {
                break;
            }
            beta = beta / q;
        }
        prev_pdf = cos * INV_PI;
        o = p;
        d = nd;
        k = k + 1u;
    }
    return l;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= P.width || gid.y >= P.height) {
        return;
    }
    let pixel = gid.y * P.width + gid.x;
    let seeded = hash2(hash2(P.seed_lo, P.seed_hi), pixel);
    let base = hash2(seeded, 0x5eed50b0u);
    let stream = hash2(seeded, 0x1b873593u);
    let pixels = P.width * P.height;
    var mean = accum[pixel].xyz;
    var m2 = accum[pixels + pixel].xyz;
    // The host dispatches one sample at a time (P.samples = 1): several samples in one
    // invocation's loop came out wrong on lavapipe (gpu.rs, SAMPLES_PER_SUBMIT).
    for (var s = P.first_sample; s < P.first_sample + P.samples; s++) {
        draw_base = base;
        draw_sample = s;
        rng_key = hash2(stream, s);
        rng_count = 0u;
        let jitter = pair(0u);
        let u = (f32(gid.x) + jitter.x) / f32(P.width);
        let v = (f32(gid.y) + jitter.y) / f32(P.height);
        let origin = P.cam_o0.xyz + P.cam_ou.xyz * u + P.cam_ov.xyz * v;
        let dir = normalize(P.cam_d0.xyz + P.cam_du.xyz * u + P.cam_dv.xyz * v);
        var l = radiance(origin, dir);
        if (!all(abs(l) <= vec3<f32>(3.4028235e38))) {
            l = vec3<f32>(0.0);
        }
        // Welford's update: sample index s is the (s + 1)-th.
        let delta = l - mean;
        mean = mean + delta / f32(s + 1u);
        m2 = m2 + delta * (l - mean);
    }
    accum[pixel] = vec4<f32>(mean, 1.0);
    accum[pixels + pixel] = vec4<f32>(m2, 0.0);
}

// The tree's ray queries alone, and what shading reads at the hit (GpuPathTracer::trace_rays,
// what the tests compare with the CPU's): ray i reads accum[4 i] = (origin, t_min) and
// accum[4 i + 1] = (unit direction, t_max) in world units, and writes accum[4 i] = (found,
// triangle id bits, t, occluded), accum[4 i + 1] = (u, v, 0, 0), accum[4 i + 2] = (albedo
// at the hit, 0) and accum[4 i + 3] = (unit shading normal, facing the geometric normal
// that faces the ray, 0). P.width rays. With FLAG_HITS_ONLY the occlusion query is left out
// (`occluded` then repeats `found`) and so is the shading (albedo and normal read 0).
@compute @workgroup_size(64, 1, 1)
fn trace_rays(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= P.width) {
        return;
    }
    let a = accum[4u * i];
    let b = accum[4u * i + 1u];
    let h = closest_hit(a.xyz, b.xyz, a.w, b.w);
    var blocked = h.found;
    if ((P.flags & FLAG_HITS_ONLY) == 0u) {
        blocked = occluded(a.xyz, b.xyz, a.w, b.w);
    }
    accum[4u * i] = vec4<f32>(select(0.0, 1.0, h.found), bitcast<f32>(h.id), h.t, select(0.0, 1.0, blocked));
    accum[4u * i + 1u] = vec4<f32>(h.b, 0.0, 0.0);
    // Hits alone: no shading read back (GpuPathTracer::closest_hits).
    if (!h.found || (P.flags & FLAG_HITS_ONLY) != 0u) {
        accum[4u * i + 2u] = vec4<f32>(0.0);
        accum[4u * i + 3u] = vec4<f32>(0.0);
        return;
    }
    let tri = tris[h.id];
    let ng0 = tri.ng.xyz;
    let ng = select(-ng0, ng0, dot(ng0, b.xyz) < 0.0);
    accum[4u * i + 2u] = vec4<f32>(albedo_at(tri, h.b), 0.0);
    accum[4u * i + 3u] = vec4<f32>(shading_normal(tri, h.b, ng), 0.0);
}
