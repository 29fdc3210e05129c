// Per-pixel luminance of a linear RGB image, thesis eq. 17:
//
//     Y = 0.27 R + 0.67 G + 0.06 B
//
// Input: an rgba32float texture (alpha ignored), read with textureLoad (no sampler, so the
// unfilterable float format is fine). Output: an r32float storage texture of the same size.
// One invocation per pixel, 8x8 workgroups; invocations outside the image (the last
// workgroup row and column of an image whose size is not a multiple of 8) return early.
//
// The sum is written term by term, in the same order as `scene_core::image::luminance`, so
// the GPU result matches the CPU one to a few ulps (exactly, unless the driver fuses a
// multiply-add).

@group(0) @binding(0) var src: texture_2d<f32>;
@group(0) @binding(1) var dst: texture_storage_2d<r32float, write>;

const WEIGHT_R: f32 = 0.27;
const WEIGHT_G: f32 = 0.67;
const WEIGHT_B: f32 = 0.06;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(src);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let c = textureLoad(src, p, 0).rgb;
    let y = WEIGHT_R * c.r + WEIGHT_G * c.g + WEIGHT_B * c.b;
    textureStore(dst, p, vec4<f32>(y, 0.0, 0.0, 1.0));
}
