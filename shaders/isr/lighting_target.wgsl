// The lighting pass' output, Rgba32Float (lighting_target16.wgsl declares the Rgba16Float
// one; WGSL cannot make a storage format overridable, so the pass is composed with one or
// the other).
@group(0) @binding(10) var out_tex: texture_storage_2d<rgba32float, write>;
