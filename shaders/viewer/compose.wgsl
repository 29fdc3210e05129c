// The viewer's compose pass: the frame shown (and saved by a screenshot) from the buffers
// of the methods on screen. Arrangement 0 shows `a`; 1 shows `a` left of the divider column and
// `b` right of it; 2 shows the error of `a` against the reference `r`: the mean over the
// three channels of |a - r| (the per-pixel term of the thesis' eq. 19), divided by
// `error_scale` and mapped through a perceptual colour map (viridis' anchors, piecewise
// linear, decoded from sRGB so the saved frame shows the map's own colours).

struct Params {
    width: u32,
    height: u32,
    arrangement: u32,
    divider: u32,
    error_scale: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> a: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> b: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> r: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> frame: array<vec4<f32>>;

// Zero for a non-finite channel (by its exponent bits: NaN compares are not reliable
// after optimisation), so nothing undefined reaches the screen.
fn finite(v: vec3<f32>) -> vec3<f32> {
    let bits = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return select(v, vec3<f32>(0.0), bits == vec3<u32>(0x7f800000u));
}

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let low = c / 12.92;
    let high = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(high, low, c <= vec3<f32>(0.04045));
}

// Viridis at 0, 1/8, ..., 1 (sRGB, 0..255).
const MAP = array<vec3<f32>, 9>(
    vec3<f32>(68.0, 1.0, 84.0),
    vec3<f32>(71.0, 44.0, 122.0),
    vec3<f32>(59.0, 81.0, 139.0),
    vec3<f32>(44.0, 113.0, 142.0),
    vec3<f32>(33.0, 144.0, 141.0),
    vec3<f32>(39.0, 173.0, 129.0),
    vec3<f32>(92.0, 200.0, 99.0),
    vec3<f32>(170.0, 220.0, 50.0),
    vec3<f32>(253.0, 231.0, 37.0),
);

fn colour_map(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0) * 8.0;
    let i = min(u32(floor(x)), 7u);
    let f = x - f32(i);
    let c = mix(MAP[i], MAP[i + 1u], f) / 255.0;
    return srgb_to_linear(c);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let i = id.y * params.width + id.x;
    var c = finite(a[i].xyz);
    if params.arrangement == 1u && id.x >= params.divider {
        c = finite(b[i].xyz);
    } else if params.arrangement == 2u {
        let d = abs(c - finite(r[i].xyz));
        let e = (d.x + d.y + d.z) / 3.0;
        c = colour_map(e / max(params.error_scale, 1e-30));
    }
    frame[i] = vec4<f32>(c, 1.0);
}
