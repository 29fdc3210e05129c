// Global triangle ids rasterised for a view: what a method that needs ids of its own
// triangles (relighting's elements, an emitter's glow) renders itself when the host's
// G-buffer has none (crates/scene-core/src/gpu/ids.rs `TriangleIdPass`, docs/engine.md).
//
// `corners` holds three world-space corners per triangle (xyz, w unused), in triangle-id
// order; a non-indexed draw of 3 x n vertices gives each fragment its triangle's id
// (vertex_index / 3). The Rust side clears the id target to 0xffffffff (background) and the
// depth attachment (Depth32Float, test Less) to 1, with no culling: triangles are
// two-sided, as in the G-buffer pass (shaders/gbuffer/mrt.wgsl), and the clip-space
// convention is scene_core::View::view_projection's (depth in [0, 1], row 0 at the top).
//
// With `match_depth` set, a fragment counts only where the host's G-buffer sees a surface
// at its depth (the linear depth, distance along the view / far, of `host_depth`, within
// 1e-3 of it): the host's masked surfaces (alpha-masked leaves it sees through) and
// geometry the pass does not have cannot claim a pixel the host shows something else at.

struct Params {
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    inv_far: f32,
    forward: vec3<f32>,
    match_depth: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> corners: array<vec4<f32>>;
@group(0) @binding(2) var host_depth: texture_2d<f32>;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) id: u32,
    @location(1) world: vec3<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) v: u32) -> VertexOut {
    var out: VertexOut;
    let p = corners[v].xyz;
    out.clip = params.view_proj * vec4<f32>(p, 1.0);
    out.id = v / 3u;
    out.world = p;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) u32 {
    if params.match_depth != 0u {
        let host = textureLoad(host_depth, vec2<i32>(in.clip.xy), 0).x;
        let own = dot(in.world - params.eye, params.forward) * params.inv_far;
        if host >= 1.0 || abs(own - host) > 1e-3 * host {
            discard;
        }
    }
    return in.id;
}
