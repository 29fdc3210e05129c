// The viewer's present pass: the composed frame stretched onto the window (nearest pixel;
// the frame is smaller than the window at a render scale below 1), scaled by 2^exposure and
// clamped to [0, 1]; the sRGB encoding is the surface format's, or done here (`encode` 1)
// when the surface is not an sRGB format, the same curve the toolkit's PNG writer uses.

struct Params {
    width: u32,
    height: u32,
    scale: f32,
    encode: u32,
    surface_width: u32,
    surface_height: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> frame: array<vec4<f32>>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the window.
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let low = c * 12.92;
    let high = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(high, low, c <= vec3<f32>(0.0031308));
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    // The frame's pixel under this one (the frame may be smaller than the window).
    let x = min(u32(p.x * f32(params.width) / f32(params.surface_width)), params.width - 1u);
    let y = min(u32(p.y * f32(params.height) / f32(params.surface_height)), params.height - 1u);
    var c = clamp(frame[y * params.width + x].xyz * params.scale, vec3<f32>(0.0), vec3<f32>(1.0));
    if params.encode == 1u {
        c = linear_to_srgb(c);
    }
    return vec4<f32>(c, 1.0);
}
