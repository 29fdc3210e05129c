#import scene_core::texture_wrap::{texel_taps, blend_taps}

// The G-buffer geometry pass: one render pass writing four colour targets at once
// (multiple render targets, thesis figure 4.1) plus the depth attachment:
//
//   location 0  albedo      rgba32float  linear RGB albedo (factor x texture x vertex colour),
//                                        a = radiation mask (1 on geometry)
//   location 1  normal      rgba32float  unit world normal facing the viewer, w = 0
//   location 2  depth       r32float     linear depth: view-space distance along the view
//                                        direction / far (thesis section 4.3)
//   location 3  triangle id r32uint      global triangle id
//   depth attachment        depth32float clip-space z, test Less, cleared to 1
//
// The Rust side (crates/gbuffer/src/mrt.rs) clears the targets to the background values
// (albedo 0, normal 0, depth 1, id 0xffffffff) and draws the scene's flattened vertex buffer
// (scene_core::gpu::GpuVertex) as a non-indexed triangle list with no culling: triangles
// are two-sided.
//
// Conventions shared with the CPU rasteriser (crates/gbuffer/src/raster.rs):
// * the shading normal is the interpolated vertex normal, renormalised, or the geometric
//   normal where it cancels; it is flipped when the triangle's geometric normal faces away
//   from the eye (sign of ng . (p0 - eye) in perspective, ng . forward in orthographic
//   views), decided once per triangle at its first (provoking) vertex;
// * the albedo texture lookup mirrors scene_core::Texture::sample (the texture's wrap per
//   axis and bilinear or nearest filter, texel centres at half-integers, uv (0, 0) the
//   top-left corner).
//   top-left corner); a masked material (alpha_cutoff > 0) discards the fragment where the
//   texture alpha falls below its cutoff, as scene_core::Scene::opaque_at decides.

struct ViewUniform {
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    inv_far: f32,
    forward: vec3<f32>,
    // 1 for orthographic views, 0 for perspective ones.
    orthographic: u32,
}

struct Material {
    albedo: vec3<f32>,
    texture: i32,
    emission: vec3<f32>,
    // scene_core::Material::alpha_cutoff (0 when opaque): the fragment is discarded where
    // the texture's alpha (texel w) falls below it.
    alpha_cutoff: f32,
}

struct TextureInfo {
    // First texel in `texels`.
    offset: u32,
    width: u32,
    height: u32,
    // scene_core::Sampler::bits: bits 0-1 the u wrap (0 repeat, 1 clamp to edge, 2
    // mirrored repeat), 2-3 the v wrap, bit 4 nearest.
    sampler: u32,
}

@group(0) @binding(0) var<uniform> view: ViewUniform;
@group(0) @binding(1) var<storage, read> materials: array<Material>;
// Unit geometric normal of each triangle (xyz), by global triangle id.
@group(0) @binding(2) var<storage, read> face_normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> texture_infos: array<TextureInfo>;
// All textures' linear RGB texels (w = alpha, 1 without), top row first, one after the
// other.
@group(0) @binding(4) var<storage, read> texels: array<vec4<f32>>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) triangle_id: u32,
    @location(2) normal: vec3<f32>,
    @location(3) material_id: u32,
    @location(4) uv: vec2<f32>,
    @location(5) has_uv: u32,
    // Vertex colour (scene_core::Mesh::colors; white without), multiplying the albedo.
    @location(6) color: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Linear depth (perspective-correct interpolation).
    @location(0) depth: f32,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) triangle_id: u32,
    @location(4) @interpolate(flat) material_id: u32,
    @location(5) @interpolate(flat) has_uv: u32,
    // Geometric normal in xyz; w = -1 when the shading normal must be flipped, else 1.
    @location(6) @interpolate(flat) face: vec4<f32>,
    @location(7) color: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    let rel = v.position - view.eye;
    out.depth = dot(rel, view.forward) * view.inv_far;
    out.normal = v.normal;
    out.uv = v.uv;
    out.triangle_id = v.triangle_id;
    out.material_id = v.material_id;
    out.has_uv = v.has_uv;
    out.color = v.color;
    let ng = face_normals[v.triangle_id].xyz;
    var facing = dot(ng, rel);
    if (view.orthographic != 0u) {
        facing = dot(ng, view.forward);
    }
    out.face = vec4<f32>(ng, select(1.0, -1.0, facing > 0.0));
    return out;
}

// The texture's lookup by its sampler (bilinear or nearest, each axis wrapped by its mode),
// as scene_core::Texture::sample (rgb) and Texture::sample_alpha (a).
fn sample_texture(index: u32, uv_in: vec2<f32>) -> vec4<f32> {
    let info = texture_infos[index];
    if (info.width == 0u || info.height == 0u) {
        return vec4<f32>(0.0);
    }
    let t = texel_taps(vec4<u32>(info.offset, info.width, info.height, info.sampler), uv_in);
    return blend_taps(texels[t.top_left], texels[t.top_right], texels[t.bottom_left], texels[t.bottom_right], t.f);
}

struct GBufferOut {
    @location(0) albedo: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) depth: f32,
    @location(3) triangle_id: u32,
}

@fragment
fn fs_main(in: VertexOut) -> GBufferOut {
    var out: GBufferOut;
    let m = materials[in.material_id];
    var albedo = m.albedo;
    // Alpha 1 without coordinates or a texture, as scene_core::Scene::opaque_at reads it.
    var alpha = 1.0;
    if (in.has_uv != 0u && m.texture >= 0 && u32(m.texture) < arrayLength(&texture_infos)) {
        let c = sample_texture(u32(m.texture), in.uv);
        albedo = albedo * c.xyz;
        alpha = c.w;
    }
    albedo = albedo * in.color;
    // Alpha masking: a hole where the alpha falls below the material's cutoff.
    if (m.alpha_cutoff > 0.0 && alpha < m.alpha_cutoff) {
        discard;
    }
    out.albedo = vec4<f32>(albedo, 1.0);
    var n = in.face.xyz;
    let len2 = dot(in.normal, in.normal);
    if (len2 > 0.0) {
        n = in.normal * (1.0 / sqrt(len2));
    }
    out.normal = vec4<f32>(n * in.face.w, 0.0);
    out.depth = in.depth;
    out.triangle_id = in.triangle_id;
    return out;
}
