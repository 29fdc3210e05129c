// Shadow maps rendered on the GPU from an engine's own vertex and index buffers
// (crates/scene-core/src/shadowed_lights/gpu_maps.rs `ShadowMapPass`, docs/engine.md): the
// same maps scene-core's CPU ray cast makes (crates/scene-core/src/shadowed_lights/esm.rs),
// texel for texel, into the storage buffer the lighting passes read
// (`LightSet::shadow_texels` layout: each map from its first texel, a cube's six faces
// +X, -X, +Y, -Y, +Z, -Z one after the other, rows from the top).
//
// Per face, the raster (vs_main, fs_main) stores at each texel centre the distance to the
// nearest caster in scene extents: from the cube's centre (Euclidean), or from the
// orthographic map's plane along the light (a texel's ray), capped at the map's miss depth
// and cleared to it. Then two compute passes apply the ESM prefilter of section 4.6 in log
// space (esm.rs `log_filter`): filter_h from the face's texture into `scratch`, filter_v from
// `scratch` into the map's texels, each tap clamped to the face.

struct Face {
    view_proj: mat4x4<f32>,
    // Cube centre or orthographic eye (xyz).
    origin: vec4<f32>,
    // Orthographic forward (xyz); unused for cubes.
    forward: vec4<f32>,
    // 0 cube, 1 orthographic.
    mode: u32,
    inv_extent: f32,
    miss: f32,
    resolution: u32,
    // Index in `texels` of the face's first texel.
    offset: u32,
    radius: u32,
    esm_exponent: f32,
    pad: u32,
    // The filter's normalised Gaussian weights, tap -radius first (at most 9).
    weights: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> face: Face;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

@vertex
fn vs_main(@location(0) position: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = face.view_proj * vec4<f32>(position, 1.0);
    out.world = position;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) f32 {
    let to = in.world - face.origin.xyz;
    var d: f32;
    if face.mode == 0u {
        d = length(to);
    } else {
        d = dot(to, face.forward.xyz);
    }
    return min(d * face.inv_extent, face.miss);
}

@group(0) @binding(1) var depth_face: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> scratch: array<f32>;
@group(0) @binding(3) var<storage, read_write> texels: array<f32>;

fn weight(k: u32) -> f32 {
    return face.weights[k / 4u][k % 4u];
}

// The log-space filter of the taps along one axis at texel (x, y): o_max + ln(sum w
// exp(c (o - o_max))) / c, its exponentials of non-positive arguments.
fn filtered(x: i32, y: i32, horizontal: bool) -> f32 {
    let r = i32(face.radius);
    let last = i32(face.resolution) - 1;
    var o_max = -3.4e38;
    for (var k = -r; k <= r; k++) {
        o_max = max(o_max, tap(x, y, k, horizontal, last));
    }
    var sum = 0.0;
    for (var k = -r; k <= r; k++) {
        sum += weight(u32(k + r)) * exp(face.esm_exponent * (tap(x, y, k, horizontal, last) - o_max));
    }
    return o_max + log(max(sum, 1.17549435e-38)) / face.esm_exponent;
}

fn tap(x: i32, y: i32, k: i32, horizontal: bool, last: i32) -> f32 {
    if horizontal {
        return textureLoad(depth_face, vec2<i32>(clamp(x + k, 0, last), y), 0).x;
    }
    let n = i32(face.resolution);
    return scratch[clamp(y + k, 0, last) * n + x];
}

@compute @workgroup_size(8, 8)
fn filter_h(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = face.resolution;
    if gid.x >= n || gid.y >= n {
        return;
    }
    scratch[gid.y * n + gid.x] = filtered(i32(gid.x), i32(gid.y), true);
}

@compute @workgroup_size(8, 8)
fn filter_v(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = face.resolution;
    if gid.x >= n || gid.y >= n {
        return;
    }
    texels[face.offset + gid.y * n + gid.x] = filtered(i32(gid.x), i32(gid.y), false);
}
