#define_import_path scene_core::reconstruct
// World positions from linear depth: eq. 24 (thesis section 4.3), generalised to
// orthographic views. The one WGSL reconstruction of the toolkit, mirroring scene-core's
// `FrustumReconstruction` (crates/scene-core/src/view.rs), the module
// `scene_core::reconstruct` that the gbuffer crate's reconstruction benchmark, every ISR
// pass, the IBRR and relighting import.
//
// p(u, v, d) = base(u, v) + ray(u, v) d, with base = base_o + u base_u + v base_v and
// ray = ray_o + u ray_u + v ray_v (w components unused). Perspective views: base = eye and
// ray = f_o + u f_u + v f_v; orthographic views: base is the view's corner plane and
// ray = far * forward.

struct FrustumReconstruction {
    base_o: vec4<f32>,
    base_u: vec4<f32>,
    base_v: vec4<f32>,
    ray_o: vec4<f32>,
    ray_u: vec4<f32>,
    ray_v: vec4<f32>,
}

fn reconstruct(f: FrustumReconstruction, uv: vec2<f32>, d: f32) -> vec3<f32> {
    let base = f.base_o.xyz + uv.x * f.base_u.xyz + uv.y * f.base_v.xyz;
    let ray = f.ray_o.xyz + uv.x * f.ray_u.xyz + uv.y * f.ray_v.xyz;
    return base + ray * d;
}
