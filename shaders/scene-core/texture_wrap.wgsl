#define_import_path scene_core::texture_wrap

// Texel index `i` of a row of `n` under wrap `mode` (scene_core::Wrap::texel; the codes of
// scene_core::Wrap::code: 0 repeat, 1 clamp to edge, 2 mirrored repeat).
fn wrap_texel(i: i32, n: i32, mode: u32) -> i32 {
    if (i >= 0 && i < n) {
        return i;
    }
    if (mode == 1u) {
        return clamp(i, 0, n - 1);
    }
    if (mode == 2u) {
        let m = ((i % (2 * n)) + 2 * n) % (2 * n);
        return select(2 * n - 1 - m, m, m < n);
    }
    return ((i % n) + n) % n;
}

// `t` brought into the range wrap `mode` repeats over (scene_core::Wrap::reduce).
fn wrap_reduce(t: f32, mode: u32) -> f32 {
    if (mode == 1u) {
        return clamp(t, 0.0, 1.0);
    }
    if (mode == 2u) {
        return t - 2.0 * floor(t * 0.5);
    }
    return t - floor(t);
}

// The texels a lookup at `uv` blends (scene_core::Texture::sample, nearest or bilinear by
// the sampler, texel centres at half-integers, uv (0, 0) the top-left corner): their indices
// from the start of the texture's texels (`info` = offset, width, height and
// scene_core::Sampler::bits, a non-empty texture), top-left, top-right, bottom-left,
// bottom-right, and the horizontal and vertical weights. A nearest lookup gives one texel
// four times with weights 0, which `blend_taps` returns exactly.
struct Taps {
    top_left: u32,
    top_right: u32,
    bottom_left: u32,
    bottom_right: u32,
    f: vec2<f32>,
}

fn texel_taps(info: vec4<u32>, uv: vec2<f32>) -> Taps {
    let mode_u = info.w & 3u;
    let mode_v = (info.w >> 2u) & 3u;
    let x = wrap_reduce(uv.x, mode_u) * f32(info.y);
    let y = wrap_reduce(uv.y, mode_v) * f32(info.z);
    let nearest = (info.w & 16u) != 0u;
    let first_x = select(floor(x - 0.5), floor(x), nearest);
    let first_y = select(floor(y - 0.5), floor(y), nearest);
    let f = select(vec2<f32>(x - 0.5 - first_x, y - 0.5 - first_y), vec2<f32>(0.0), nearest);
    let step = select(1, 0, nearest);
    let left = u32(wrap_texel(i32(first_x), i32(info.y), mode_u));
    let right = u32(wrap_texel(i32(first_x) + step, i32(info.y), mode_u));
    let top = info.x + u32(wrap_texel(i32(first_y), i32(info.z), mode_v)) * info.y;
    let bottom = info.x + u32(wrap_texel(i32(first_y) + step, i32(info.z), mode_v)) * info.y;
    return Taps(top + left, top + right, bottom + left, bottom + right, f);
}

// The bilinear blend of four taps' texels with the weights of `texel_taps`.
fn blend_taps(top_left: vec4<f32>, top_right: vec4<f32>, bottom_left: vec4<f32>, bottom_right: vec4<f32>, f: vec2<f32>) -> vec4<f32> {
    return mix(mix(top_left, top_right, f.x), mix(bottom_left, bottom_right, f.x), f.y);
}
