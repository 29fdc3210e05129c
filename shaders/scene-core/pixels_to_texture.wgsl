// A method's pixel buffer (one vec4<f32> per pixel, row-major, radiance in rgb) written
// into a frame target texture, alpha 1: how the methods that produce a buffer (relighting's
// display, the IBRR's reconstruction) meet the frame contract's texture target
// (crates/scene-core/src/gpu/frame.rs `PixelsToTexture`). The target's size is the frame's.

@group(0) @binding(0) var<storage, read> pixels: array<vec4<f32>>;
#ifdef OUTPUT_RGBA16F
@group(0) @binding(1) var target_tex: texture_storage_2d<rgba16float, write>;
#else
@group(0) @binding(1) var target_tex: texture_storage_2d<rgba32float, write>;
#endif

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(target_tex);
    if gid.x >= size.x || gid.y >= size.y {
        return;
    }
    let i = gid.y * size.x + gid.x;
    if i >= arrayLength(&pixels) {
        return;
    }
    textureStore(target_tex, vec2<i32>(gid.xy), vec4<f32>(pixels[i].xyz, 1.0));
}
