// The viewer's resolve pass: one of a method's textures (ISR's output or one of its
// intermediate buffers, at any size) into the frame-sized buffer every view composes from,
// nearest texel per pixel. `channel` 0 copies the colour, 1 shows the fourth channel
// (ISR's ambient accessibility) as grey.

struct Params {
    width: u32,
    height: u32,
    channel: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var source: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> result: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let dims = textureDimensions(source);
    // Nearest texel of the pixel centre; f32 keeps large sizes from overflowing.
    let sx = min(u32((f32(id.x) + 0.5) * f32(dims.x) / f32(params.width)), dims.x - 1u);
    let sy = min(u32((f32(id.y) + 0.5) * f32(dims.y) / f32(params.height)), dims.y - 1u);
    let v = textureLoad(source, vec2<u32>(sx, sy), 0);
    var c = v.xyz;
    if params.channel == 1u {
        c = vec3<f32>(v.w);
    }
    result[id.y * params.width + id.x] = vec4<f32>(c, 1.0);
}
