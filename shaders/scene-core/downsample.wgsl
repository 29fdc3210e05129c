#import scene_core::limits::BACKGROUND
// Coarse G-buffer: 2x downsampling in each direction ("4 times smaller", thesis section
// 4.2), mirroring crates/scene-core/src/gbuffer/downsample.rs sample for sample: the one
// downsampling of the toolkit (the gbuffer crate and ISR both use it).
//
// One invocation per coarse pixel (8x8 workgroups). Coarse pixel (X, Y) covers the fine
// block (2X..2X+1, 2Y..2Y+1), clipped at the fine buffer's edge for odd sizes, so a block
// has 1, 2 or 4 samples, visited in raster order (top-left, top-right, bottom-left,
// bottom-right).
//
// Modes (the pipeline-overridable constant MODE; one pipeline per mode):
//   0 AVERAGE         the thesis: every channel averaged over the block (background
//                     included), the normal renormalised; triangle id of the sample whose
//                     depth is nearest the mean depth.
//   1 NEAREST_MEDIAN  depth-aware choice: all channels of one sample, the lower median of
//                     the block's depths (ties broken by raster order). Invents nothing.
//   2 SURFACE_AVERAGE the lower-median sample's surface: the average of the samples that
//                     share its background status, lie within a relative depth tolerance
//                     and have normals within an angle of its normal.
//   3 NEAREST_SURFACE ISR's choice: the nearest non-background sample represents the block;
//                     the non-background samples within NEAREST_DEPTH_TOLERANCE of its
//                     depth (relative) are averaged. A block without geometry is
//                     background.
// Normals that cancel (sum shorter than CANCEL * samples) take the representative sample's
// normal (zero on background).

@group(0) @binding(0) var src_albedo: texture_2d<f32>;
@group(0) @binding(1) var src_normal: texture_2d<f32>;
@group(0) @binding(2) var src_depth: texture_2d<f32>;
@group(0) @binding(3) var src_id: texture_2d<u32>;
@group(0) @binding(4) var dst_albedo: texture_storage_2d<rgba32float, write>;
@group(0) @binding(5) var dst_normal: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var dst_depth: texture_storage_2d<r32float, write>;
@group(0) @binding(7) var dst_id: texture_storage_2d<r32uint, write>;

override MODE: u32 = 0u;
// Relative depth tolerance and minimum normal cosine of SURFACE_AVERAGE.
override SURFACE_DEPTH_TOLERANCE: f32 = 0.02;
override SURFACE_NORMAL_COS: f32 = 0.9;
// Relative depth tolerance of NEAREST_SURFACE.
override NEAREST_DEPTH_TOLERANCE: f32 = 0.05;

const CANCEL: f32 = 1e-6;

struct Sample {
    albedo: vec4<f32>,
    normal: vec3<f32>,
    depth: f32,
    id: u32,
}

fn load(p: vec2<i32>) -> Sample {
    var s: Sample;
    s.albedo = textureLoad(src_albedo, p, 0);
    s.normal = textureLoad(src_normal, p, 0).xyz;
    s.depth = textureLoad(src_depth, p, 0).x;
    s.id = textureLoad(src_id, p, 0).x;
    return s;
}

// Unit `sum`, or `fallback` when it (nearly) cancels.
fn renormalise(sum: vec3<f32>, count: f32, fallback: vec3<f32>) -> vec3<f32> {
    let len = sqrt(dot(sum, sum));
    if (len <= CANCEL * count) {
        return fallback;
    }
    return sum * (1.0 / len);
}

// Whether sample q (index i) belongs to the surface of the representative r (index rep):
// SURFACE_AVERAGE's or NEAREST_SURFACE's rule, by MODE.
fn in_surface(q: Sample, i: u32, r: Sample, rep: u32) -> bool {
    if (MODE == 3u) {
        return q.id != BACKGROUND && abs(q.depth - r.depth) <= NEAREST_DEPTH_TOLERANCE * r.depth;
    }
    let is_bg = r.id == BACKGROUND;
    let same = (q.id == BACKGROUND) == is_bg;
    if (is_bg || i == rep) {
        return same;
    }
    return same && abs(q.depth - r.depth) <= SURFACE_DEPTH_TOLERANCE * r.depth
        && dot(q.normal, r.normal) >= SURFACE_NORMAL_COS;
}

// The average of the n samples in the representative's surface (in_surface), with its id
// and, if the normals cancel, its normal.
fn surface_average(s: array<Sample, 4>, n: u32, rep: u32) -> Sample {
    let r = s[rep];
    var a = vec4<f32>(0.0);
    var nsum = vec3<f32>(0.0);
    var dsum = 0.0;
    var m = 0.0;
    for (var i = 0u; i < n; i++) {
        if (in_surface(s[i], i, r, rep)) {
            a += s[i].albedo;
            nsum += s[i].normal;
            dsum += s[i].depth;
            m += 1.0;
        }
    }
    var out: Sample;
    out.albedo = a / m;
    out.normal = renormalise(nsum, m, r.normal);
    out.depth = dsum / m;
    out.id = r.id;
    return out;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let coarse = textureDimensions(dst_depth);
    if (gid.x >= coarse.x || gid.y >= coarse.y) {
        return;
    }
    let fine = vec2<i32>(textureDimensions(src_depth));
    let base = vec2<i32>(gid.xy) * 2;
    var s: array<Sample, 4>;
    var n = 0u;
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let p = base + vec2<i32>(dx, dy);
            if (p.x < fine.x && p.y < fine.y) {
                s[n] = load(p);
                n++;
            }
        }
    }
    let count = f32(n);

    // The lower median of the depths: the sample with exactly `(n - 1) / 2` samples before
    // it in (depth, index) order.
    let want = (n - 1u) / 2u;
    var rep = 0u;
    for (var i = 0u; i < n; i++) {
        var before = 0u;
        for (var j = 0u; j < n; j++) {
            if (s[j].depth < s[i].depth || (s[j].depth == s[i].depth && j < i)) {
                before++;
            }
        }
        if (before == want) {
            rep = i;
        }
    }

    var albedo = s[rep].albedo;
    var normal = s[rep].normal;
    var depth = s[rep].depth;
    var id = s[rep].id;

    if (MODE == 0u) {
        var a = vec4<f32>(0.0);
        var nsum = vec3<f32>(0.0);
        var dsum = 0.0;
        for (var i = 0u; i < n; i++) {
            a += s[i].albedo;
            nsum += s[i].normal;
            dsum += s[i].depth;
        }
        depth = dsum / count;
        var best = 0u;
        for (var i = 1u; i < n; i++) {
            if (abs(s[i].depth - depth) < abs(s[best].depth - depth)) {
                best = i;
            }
        }
        albedo = a / count;
        id = s[best].id;
        normal = renormalise(nsum, count, s[best].normal);
    } else if (MODE == 2u) {
        let r = surface_average(s, n, rep);
        albedo = r.albedo;
        normal = r.normal;
        depth = r.depth;
    } else if (MODE == 3u) {
        // The nearest geometry sample (ties: the first in raster order).
        var near = n;
        for (var i = 0u; i < n; i++) {
            if (s[i].id != BACKGROUND && (near == n || s[i].depth < s[near].depth)) {
                near = i;
            }
        }
        if (near == n) {
            albedo = vec4<f32>(0.0);
            normal = vec3<f32>(0.0);
            depth = 1.0;
            id = BACKGROUND;
        } else {
            let r = surface_average(s, n, near);
            albedo = r.albedo;
            normal = r.normal;
            depth = r.depth;
            id = r.id;
        }
    }

    let c = vec2<i32>(gid.xy);
    textureStore(dst_albedo, c, albedo);
    textureStore(dst_normal, c, vec4<f32>(normal, 0.0));
    textureStore(dst_depth, c, vec4<f32>(depth, 0.0, 0.0, 0.0));
    textureStore(dst_id, c, vec4<u32>(id, 0u, 0u, 0u));
}
