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
