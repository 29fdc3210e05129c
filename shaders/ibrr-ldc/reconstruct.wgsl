#import scene_core::limits::BACKGROUND
#import scene_core::reconstruct::{FrustumReconstruction, reconstruct}
// IBRR reconstruction (paper section 5) over the flattened LDC, one invocation per camera
// pixel; mirrors crates/ibrr-ldc/src/reconstruct.rs (`reconstruct` then `shade`) step for
// step: unproject the pixel, pick the LDIs its normal belongs to (blended near their
// boundaries), read the matching layers with the nearest / average / bilinear kernel (a
// neighbouring layer only if the camera's G-buffer sees its centre on its plane), fall back
// to rings of LDI pixels (`main`, into `irradiance`); then fill the pixels without a layer
// from the camera pixels around them and shade albedo / pi x E plus the glow of emitters
// seen from their emitting side (`fill`, into `image`).

// 0 nearest, 1 average, 2 bilinear.
override LOOKUP: u32 = 2u;
override AVERAGE_RADIUS: i32 = 1;

struct Params {
    frustum: FrustumReconstruction,
    view_projection: mat4x4<f32>,
    // xyz: the LDC's origin; w: its side.
    origin: vec4<f32>,
    // xyz: the eye (perspective) or the view direction (orthographic); w: 1 perspective.
    eye: vec4<f32>,
    width: u32,
    height: u32,
    resolution: u32,
    fallback_radius: u32,
    eps_distance: f32,
    eps_normal: f32,
    band: f32,
    triangles: u32,
    fill_radius: u32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

struct Triangle {
    // Emitted radiance times its light's direct factor (zero for non-emitters).
    glow: vec4<f32>,
    // Geometric normal of the emitting side.
    normal: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> offsets: array<u32>;
@group(0) @binding(2) var<storage, read> planes: array<vec4<f32>>;
// Per layer: direct irradiance at 2 l, indirect at 2 l + 1.
@group(0) @binding(3) var<storage, read> values: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> triangles: array<Triangle>;
// rgb: radiance; w: 0 found, 1 fallback, 2 no layer, 3 background, 4 filled.
@group(0) @binding(5) var<storage, read_write> image: array<vec4<f32>>;
// Written by `main`, read by `fill`: at 2 i the direct irradiance and in w the status as in
// `image` (0 to 3), at 2 i + 1 the indirect irradiance.
@group(0) @binding(6) var<storage, read_write> irradiance: array<vec4<f32>>;
@group(0) @binding(7) var g_albedo: texture_2d<f32>;
@group(0) @binding(8) var g_normal: texture_2d<f32>;
@group(0) @binding(9) var g_depth: texture_2d<f32>;
@group(0) @binding(10) var g_id: texture_2d<u32>;

const NO_LAYER: u32 = 0xffffffffu;

fn image_axes(axis: u32) -> vec2<u32> {
    return vec2<u32>((axis + 1u) % 3u, (axis + 2u) % 3u);
}

fn pixel_size() -> f32 {
    return params.origin.w / f32(params.resolution);
}

fn pixel_coords(axis: u32, p: vec3<f32>) -> vec2<f32> {
    let a = image_axes(axis);
    let inv = f32(params.resolution) / params.origin.w;
    return vec2<f32>((p[a.x] - params.origin[a.x]) * inv, (p[a.y] - params.origin[a.y]) * inv);
}

// The pixel's index, or NO_LAYER outside the LDI.
fn pixel_index(axis: u32, i: i32, j: i32) -> u32 {
    let r = i32(params.resolution);
    if i < 0 || j < 0 || i >= r || j >= r {
        return NO_LAYER;
    }
    return axis * params.resolution * params.resolution + u32(j) * params.resolution + u32(i);
}

// The plane's point through the pixel centre along the axis; w = 0 when the plane is
// parallel to the axis.
fn point_on_plane(axis: u32, i: i32, j: i32, plane: vec4<f32>) -> vec4<f32> {
    let n = plane.xyz;
    if abs(n[axis]) < 1e-6 {
        return vec4<f32>(0.0);
    }
    let a = image_axes(axis);
    let h = pixel_size();
    var p = vec3<f32>(0.0);
    p[a.x] = params.origin[a.x] + (f32(i) + 0.5) * h;
    p[a.y] = params.origin[a.y] + (f32(j) + 0.5) * h;
    p[axis] = (plane.w - n[a.x] * p[a.x] - n[a.y] * p[a.y]) / n[axis];
    return vec4<f32>(p, 1.0);
}

// The best matching layer of pixel `index` (smallest plane distance), or NO_LAYER.
fn find(index: u32, p: vec3<f32>, n: vec3<f32>) -> u32 {
    var best = NO_LAYER;
    var best_d = 0.0;
    for (var l = offsets[index]; l < offsets[index + 1u]; l++) {
        let plane = planes[l];
        let d = abs(dot(p, plane.xyz) - plane.w);
        if d < params.eps_distance && dot(n, plane.xyz) > 1.0 - params.eps_normal {
            if best == NO_LAYER || d < best_d {
                best = l;
                best_d = d;
            }
        }
    }
    return best;
}

fn world_at(x: u32, y: u32) -> vec3<f32> {
    let uv = (vec2<f32>(f32(x), f32(y)) + 0.5) / vec2<f32>(f32(params.width), f32(params.height));
    return reconstruct(params.frustum, uv, textureLoad(g_depth, vec2<i32>(i32(x), i32(y)), 0).x);
}

// Whether camera pixel (x, y) (clamped) sees q on the plane with normal n.
fn sees(x: i32, y: i32, q: vec3<f32>, n: vec3<f32>) -> bool {
    let cx = u32(clamp(x, 0, i32(params.width) - 1));
    let cy = u32(clamp(y, 0, i32(params.height) - 1));
    let xy = vec2<i32>(i32(cx), i32(cy));
    if textureLoad(g_id, xy, 0).x == BACKGROUND {
        return false;
    }
    let np = textureLoad(g_normal, xy, 0).xyz;
    let pp = world_at(cx, cy);
    return dot(np, n) > 1.0 - params.eps_normal && abs(dot(q - pp, np)) < 2.0 * params.eps_distance;
}

// The camera's own visibility test of a layer centre (construct::render_sees, centres off
// screen or behind the camera count as seen).
fn visible(q: vec3<f32>, n: vec3<f32>) -> bool {
    let clip = params.view_projection * vec4<f32>(q, 1.0);
    if clip.w <= 0.0 {
        return true;
    }
    let u = clip.x / clip.w * 0.5 + 0.5;
    let v = 0.5 - clip.y / clip.w * 0.5;
    if u < 0.0 || u >= 1.0 || v < 0.0 || v >= 1.0 {
        return true;
    }
    let fx = u * f32(params.width) - 0.5;
    let fy = v * f32(params.height) - 0.5;
    let x0 = i32(floor(fx));
    let y0 = i32(floor(fy));
    return sees(x0, y0, q, n) && sees(x0 + 1, y0, q, n) && sees(x0, y0 + 1, q, n) && sees(x0 + 1, y0 + 1, q, n);
}

// The last resort's test of a layer centre: each of the four camera pixels around q's
// projection sees q's own plane or a surface behind q (twin of reconstruct's `unhidden`).
// A centre beside a thin post passes (the camera sees past it); one behind a wall, or at
// a wall's foot, does not.
fn unhidden(q: vec3<f32>, n: vec3<f32>) -> bool {
    let clip = params.view_projection * vec4<f32>(q, 1.0);
    if clip.w <= 0.0 {
        return false;
    }
    let u = clip.x / clip.w * 0.5 + 0.5;
    let v = 0.5 - clip.y / clip.w * 0.5;
    if u < 0.0 || u >= 1.0 || v < 0.0 || v >= 1.0 {
        return false;
    }
    let x0 = i32(floor(u * f32(params.width) - 0.5));
    let y0 = i32(floor(v * f32(params.height) - 0.5));
    let tol = 2.0 * params.eps_distance;
    for (var k = 0; k < 4; k++) {
        let cx = u32(clamp(x0 + (k & 1), 0, i32(params.width) - 1));
        let cy = u32(clamp(y0 + (k >> 1u), 0, i32(params.height) - 1));
        if textureLoad(g_id, vec2<i32>(i32(cx), i32(cy)), 0).x == BACKGROUND {
            continue;
        }
        let pp = world_at(cx, cy);
        // The layer's own plane, seen at a grazing angle, hides nothing.
        let np = textureLoad(g_normal, vec2<i32>(i32(cx), i32(cy)), 0).xyz;
        if dot(np, n) > 1.0 - params.eps_normal && abs(dot(q - pp, n)) < tol {
            continue;
        }
        var nearer = false;
        if params.eye.w != 0.0 {
            nearer = length(pp - params.eye.xyz) < length(q - params.eye.xyz) - tol;
        } else {
            nearer = dot(pp - q, params.eye.xyz) < -tol;
        }
        if nearer {
            return false;
        }
    }
    return true;
}

struct Acc {
    direct: vec3<f32>,
    indirect: vec3<f32>,
    weight: f32,
}

fn add(acc: ptr<function, Acc>, axis: u32, i: i32, j: i32, w: f32, p: vec3<f32>, n: vec3<f32>) {
    if w <= 0.0 {
        return;
    }
    let index = pixel_index(axis, i, j);
    if index == NO_LAYER {
        return;
    }
    let l = find(index, p, n);
    if l == NO_LAYER {
        return;
    }
    let q = point_on_plane(axis, i, j, planes[l]);
    if q.w != 0.0 && !visible(q.xyz, n) {
        return;
    }
    (*acc).direct += values[2u * l].xyz * w;
    (*acc).indirect += values[2u * l + 1u].xyz * w;
    (*acc).weight += w;
}

fn in_ldi(axis: u32, p: vec3<f32>, n: vec3<f32>) -> Acc {
    var acc = Acc(vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    let c = pixel_coords(axis, p);
    if LOOKUP == 0u {
        add(&acc, axis, i32(floor(c.x)), i32(floor(c.y)), 1.0, p, n);
    } else if LOOKUP == 1u {
        let ci = i32(floor(c.x));
        let cj = i32(floor(c.y));
        for (var j = cj - AVERAGE_RADIUS; j <= cj + AVERAGE_RADIUS; j++) {
            for (var i = ci - AVERAGE_RADIUS; i <= ci + AVERAGE_RADIUS; i++) {
                add(&acc, axis, i, j, 1.0, p, n);
            }
        }
    } else {
        let f = c - vec2<f32>(0.5);
        let i0 = i32(floor(f.x));
        let j0 = i32(floor(f.y));
        let t = f - vec2<f32>(f32(i0), f32(j0));
        add(&acc, axis, i0, j0, (1.0 - t.x) * (1.0 - t.y), p, n);
        add(&acc, axis, i0 + 1, j0, t.x * (1.0 - t.y), p, n);
        add(&acc, axis, i0, j0 + 1, (1.0 - t.x) * t.y, p, n);
        add(&acc, axis, i0 + 1, j0 + 1, t.x * t.y, p, n);
    }
    if acc.weight > 0.0 {
        acc.direct /= acc.weight;
        acc.indirect /= acc.weight;
        acc.weight = 1.0;
    }
    return acc;
}

// ldc::axes_of: the blend weight of each LDI for normal n.
fn axis_weights(n: vec3<f32>) -> vec3<f32> {
    let a = abs(n);
    let m = max(a.x, max(a.y, a.z));
    if params.band > 0.0 {
        return clamp((a - vec3<f32>(m - params.band)) / params.band, vec3<f32>(0.0), vec3<f32>(1.0));
    }
    if a.x == m {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    if a.y == m {
        return vec3<f32>(0.0, 1.0, 0.0);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let pixel = gid.y * params.width + gid.x;
    let xy = vec2<i32>(gid.xy);
    let id = textureLoad(g_id, xy, 0).x;
    let n = textureLoad(g_normal, xy, 0).xyz;
    if id == BACKGROUND || all(n == vec3<f32>(0.0)) {
        irradiance[2u * pixel] = vec4<f32>(0.0, 0.0, 0.0, 3.0);
        irradiance[2u * pixel + 1u] = vec4<f32>(0.0);
        return;
    }
    let p = world_at(gid.x, gid.y);
    let weights = axis_weights(n);
    var direct = vec3<f32>(0.0);
    var indirect = vec3<f32>(0.0);
    var total = 0.0;
    var dominant = 0u;
    var dominant_w = -1.0;
    for (var axis = 0u; axis < 3u; axis++) {
        let w_axis = weights[axis];
        if w_axis <= 0.0 {
            continue;
        }
        if w_axis > dominant_w {
            dominant = axis;
            dominant_w = w_axis;
        }
        let a = in_ldi(axis, p, n);
        if a.weight > 0.0 {
            direct += a.direct * w_axis;
            indirect += a.indirect * w_axis;
            total += w_axis * a.weight;
        }
    }
    var status = 0.0;
    if total > 0.0 {
        direct /= total;
        indirect /= total;
    } else {
        // Rings of LDI pixels around the point in the dominant LDI.
        status = 2.0;
        let c = pixel_coords(dominant, p);
        let ci = i32(floor(c.x));
        let cj = i32(floor(c.y));
        var hidden = NO_LAYER;
        for (var r = 1; r <= i32(params.fallback_radius); r++) {
            var best = NO_LAYER;
            var best_d2 = 0.0;
            var hidden_best = NO_LAYER;
            var hidden_d2 = 0.0;
            for (var j = cj - r; j <= cj + r; j++) {
                for (var i = ci - r; i <= ci + r; i++) {
                    if abs(i - ci) != r && abs(j - cj) != r {
                        continue;
                    }
                    let index = pixel_index(dominant, i, j);
                    if index == NO_LAYER {
                        continue;
                    }
                    for (var l = offsets[index]; l < offsets[index + 1u]; l++) {
                        let plane = planes[l];
                        if dot(n, plane.xyz) <= 1.0 - params.eps_normal {
                            continue;
                        }
                        let q = point_on_plane(dominant, i, j, plane);
                        if q.w == 0.0 {
                            continue;
                        }
                        let d2 = dot(q.xyz - p, q.xyz - p);
                        if abs(dot(p, plane.xyz) - plane.w) < params.eps_distance * (f32(r) + 1.0)
                            && (best == NO_LAYER || d2 < best_d2) {
                            if visible(q.xyz, plane.xyz) {
                                best = l;
                                best_d2 = d2;
                            } else if (hidden_best == NO_LAYER || d2 < hidden_d2) && unhidden(q.xyz, plane.xyz) {
                                hidden_best = l;
                                hidden_d2 = d2;
                            }
                        }
                    }
                }
            }
            if best != NO_LAYER {
                direct = values[2u * best].xyz;
                indirect = values[2u * best + 1u].xyz;
                status = 1.0;
                break;
            }
            if hidden == NO_LAYER {
                hidden = hidden_best;
            }
        }
        // Last resort: the point's own plane in its own LDI pixel, else the nearest in the
        // rings, its centre unseen (a surface narrower than an LDI pixel).
        if status == 2.0 {
            var l = NO_LAYER;
            let index = pixel_index(dominant, ci, cj);
            if index != NO_LAYER {
                l = find(index, p, n);
                if l != NO_LAYER {
                    let q = point_on_plane(dominant, ci, cj, planes[l]);
                    if q.w == 0.0 || !unhidden(q.xyz, planes[l].xyz) {
                        l = NO_LAYER;
                    }
                }
            }
            if l == NO_LAYER {
                l = hidden;
            }
            if l != NO_LAYER {
                direct = values[2u * l].xyz;
                indirect = values[2u * l + 1u].xyz;
                status = 1.0;
            }
        }
    }
    irradiance[2u * pixel] = vec4<f32>(direct, status);
    irradiance[2u * pixel + 1u] = vec4<f32>(indirect, 0.0);
}

// The hole fill (reconstruct.rs, `fill_holes`): no direct light, and the mean indirect
// irradiance of the nearest ring of camera pixels served by the LDC (status 0 or 1) of the
// pixel's orientation on its plane, else of its orientation on another plane, else facing
// its side. Reads only served pixels.
fn filled(x: i32, y: i32, p: vec3<f32>, n: vec3<f32>) -> vec4<f32> {
    var other = vec4<f32>(0.0);
    var facing = vec4<f32>(0.0);
    let w = i32(params.width);
    let h = i32(params.height);
    for (var r = 1; r <= i32(params.fill_radius); r++) {
        var plane = vec4<f32>(0.0);
        var off = vec4<f32>(0.0);
        var side = vec4<f32>(0.0);
        for (var v = y - r; v <= y + r; v++) {
            if v < 0 || v >= h {
                continue;
            }
            // The ring's row: whole at its top and bottom, its two ends between.
            var step = 2 * r;
            if abs(v - y) == r {
                step = 1;
            }
            for (var u = x - r; u <= x + r; u += step) {
                if u < 0 || u >= w {
                    continue;
                }
                let k = u32(v * w + u);
                if irradiance[2u * k].w > 1.5 {
                    continue;
                }
                let e = irradiance[2u * k + 1u];
                let cos = dot(n, textureLoad(g_normal, vec2<i32>(u, v), 0).xyz);
                if cos <= 0.0 {
                    continue;
                }
                if cos <= 1.0 - params.eps_normal {
                    side += vec4<f32>(e.xyz, 1.0);
                } else if abs(dot(world_at(u32(u), u32(v)) - p, n)) < 2.0 * params.eps_distance {
                    plane += vec4<f32>(e.xyz, 1.0);
                } else {
                    off += vec4<f32>(e.xyz, 1.0);
                }
            }
        }
        if plane.w > 0.0 {
            return vec4<f32>(plane.xyz / plane.w, 1.0);
        }
        if other.w == 0.0 && off.w > 0.0 {
            other = off;
        }
        if facing.w == 0.0 && side.w > 0.0 {
            facing = side;
        }
    }
    if other.w > 0.0 {
        return vec4<f32>(other.xyz / other.w, 1.0);
    }
    if facing.w > 0.0 {
        return vec4<f32>(facing.xyz / facing.w, 1.0);
    }
    return vec4<f32>(0.0);
}

@compute @workgroup_size(8, 8)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let pixel = gid.y * params.width + gid.x;
    let xy = vec2<i32>(gid.xy);
    let d = irradiance[2u * pixel];
    if d.w == 3.0 {
        image[pixel] = vec4<f32>(0.0, 0.0, 0.0, 3.0);
        return;
    }
    let id = textureLoad(g_id, xy, 0).x;
    let p = world_at(gid.x, gid.y);
    var status = d.w;
    var e = d.xyz + irradiance[2u * pixel + 1u].xyz;
    if status == 2.0 {
        let f = filled(xy.x, xy.y, p, textureLoad(g_normal, xy, 0).xyz);
        if f.w > 0.0 {
            e = f.xyz;
            status = 4.0;
        }
    }
    let albedo = textureLoad(g_albedo, xy, 0).xyz;
    var radiance = albedo * 0.31830988618379067 * e;
    if id < params.triangles {
        let t = triangles[id];
        var towards = params.eye.xyz;
        if params.eye.w != 0.0 {
            towards = p - params.eye.xyz;
        }
        if any(t.glow.xyz > vec3<f32>(0.0)) && dot(t.normal.xyz, towards) < 0.0 {
            radiance += t.glow.xyz;
        }
    }
    image[pixel] = vec4<f32>(radiance, status);
}
