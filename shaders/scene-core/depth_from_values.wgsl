// A depth texture holding given values (`scene_core::testing::depth_texture_from`): depth
// textures cannot be written by copies, so a full-screen triangle writes each pixel's value
// as its fragment depth (compare Always). Stands in for an engine's depth buffer in tests
// and examples.

// The image's width in pixels (row-major values).
override WIDTH: u32 = 1u;

@group(0) @binding(0) var<storage, read> depth: array<f32>;

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    return depth[u32(p.y) * WIDTH + u32(p.x)];
}
