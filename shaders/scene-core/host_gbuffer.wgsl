#import scene_core::limits::BACKGROUND
// An engine's G-buffer in its own formats turned into the toolkit's (GpuGBuffer), one
// invocation per pixel (8x8 workgroups); mirrors crates/scene-core/src/gpu/host.rs.
//
// In:  albedo  any float-sampled colour format (Rgba8UnormSrgb decodes to linear on load),
//      normal  xyz (Rgba16Float, Rgba32Float) or octahedral xy (Rg16Snorm, Rg16Float; the
//              overridable constant OCTAHEDRAL), unit world-space normals,
//      depth   the engine's Depth32Float depth buffer in its convention,
//      ids     the engine's R32Uint triangle ids, or none (HAS_IDS 0).
// Out: albedo rgba32float (w = 1 on geometry), normal rgba32float, linear depth r32float
//      (distance / the view's far plane, 1 on background), ids r32uint (the engine's, or
//      SURFACE_WITHOUT_ID on geometry; BACKGROUND where the depth is the clear value).
//
// The depth convention (View::from_host_matrices): distance t of hardware depth d is
// m32 / (d + m22) in perspective and (m32 - d) / m22 orthographic. Background is the clear
// value: d >= 1 in the standard convention, d <= 0 reversed.

struct Params {
    m22: f32,
    m32: f32,
    far: f32,
    // Bit 0 orthographic, bit 1 reversed.
    flags: u32,
    width: u32,
    height: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var src_albedo: texture_2d<f32>;
@group(0) @binding(2) var src_normal: texture_2d<f32>;
@group(0) @binding(3) var src_depth: texture_depth_2d;
@group(0) @binding(4) var src_id: texture_2d<u32>;
@group(0) @binding(5) var dst_albedo: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var dst_normal: texture_storage_2d<rgba32float, write>;
@group(0) @binding(7) var dst_depth: texture_storage_2d<r32float, write>;
@group(0) @binding(8) var dst_id: texture_storage_2d<r32uint, write>;

override OCTAHEDRAL: u32 = 0u;
override HAS_IDS: u32 = 0u;

const SURFACE_WITHOUT_ID: u32 = 0xfffffffeu;

// The unit vector of octahedral coordinates e in [-1, 1]^2.
fn octahedral(e: vec2<f32>) -> vec3<f32> {
    var n = vec3<f32>(e.x, e.y, 1.0 - abs(e.x) - abs(e.y));
    if n.z < 0.0 {
        let s = select(vec2<f32>(-1.0), vec2<f32>(1.0), n.xy >= vec2<f32>(0.0));
        n = vec3<f32>((1.0 - abs(n.yx)) * s, n.z);
    }
    return normalize(n);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let d = textureLoad(src_depth, p, 0);
    let ortho = (params.flags & 1u) != 0u;
    let reversed = (params.flags & 2u) != 0u;
    let background = select(d >= 1.0, d <= 0.0, reversed);
    if background {
        textureStore(dst_albedo, p, vec4<f32>(0.0));
        textureStore(dst_normal, p, vec4<f32>(0.0));
        textureStore(dst_depth, p, vec4<f32>(1.0, 0.0, 0.0, 0.0));
        textureStore(dst_id, p, vec4<u32>(BACKGROUND, 0u, 0u, 0u));
        return;
    }
    var t: f32;
    if ortho {
        t = (params.m32 - d) / params.m22;
    } else {
        t = params.m32 / (d + params.m22);
    }
    let linear = clamp(t / params.far, 0.0, 1.0);
    let albedo = textureLoad(src_albedo, p, 0).xyz;
    let raw = textureLoad(src_normal, p, 0);
    var n: vec3<f32>;
    if OCTAHEDRAL != 0u {
        n = octahedral(clamp(raw.xy, vec2<f32>(-1.0), vec2<f32>(1.0)));
    } else {
        n = raw.xyz;
        let l = length(n);
        n = select(vec3<f32>(0.0), n / l, l > 0.0);
    }
    var id = SURFACE_WITHOUT_ID;
    if HAS_IDS != 0u {
        id = textureLoad(src_id, p, 0).x;
    }
    textureStore(dst_albedo, p, vec4<f32>(albedo, 1.0));
    textureStore(dst_normal, p, vec4<f32>(n, 0.0));
    textureStore(dst_depth, p, vec4<f32>(linear, 0.0, 0.0, 0.0));
    textureStore(dst_id, p, vec4<u32>(id, 0u, 0u, 0u));
}
