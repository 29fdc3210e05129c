// The viewer's resolve pass: one of a method's textures (a frame target, or one of ISR's
// intermediate buffers, at any size) into the frame-sized buffer every view composes from,
// nearest texel per pixel. `channel` 0 copies the colour, 1 shows the fourth channel
// (ISR's ambient accessibility) as grey. With TO_TEXTURE, the result is a frame target
// texture instead (the ISR buffer views, crates/viewer/src/frame.rs `IsrBufferView`), whose
// size replaces `width` and `height`.

struct Params {
    width: u32,
    height: u32,
    channel: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var source: texture_2d<f32>;
#ifdef TO_TEXTURE
@group(0) @binding(2) var result: texture_storage_2d<rgba32float, write>;
#else
@group(0) @binding(2) var<storage, read_write> result: array<vec4<f32>>;
#endif

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
#ifdef TO_TEXTURE
    let size = textureDimensions(result);
    let width = size.x;
    let height = size.y;
#else
    let width = params.width;
    let height = params.height;
#endif
    if id.x >= width || id.y >= height {
        return;
    }
    let dims = textureDimensions(source);
    // Nearest texel of the pixel centre; f32 keeps large sizes from overflowing.
    let sx = min(u32((f32(id.x) + 0.5) * f32(dims.x) / f32(width)), dims.x - 1u);
    let sy = min(u32((f32(id.y) + 0.5) * f32(dims.y) / f32(height)), dims.y - 1u);
    let v = textureLoad(source, vec2<u32>(sx, sy), 0);
    var c = v.xyz;
    if params.channel == 1u {
        c = vec3<f32>(v.w);
    }
#ifdef TO_TEXTURE
    textureStore(result, vec2<u32>(id.xy), vec4<f32>(c, 1.0));
#else
    result[id.y * width + id.x] = vec4<f32>(c, 1.0);
#endif
}
