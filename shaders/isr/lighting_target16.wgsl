// The lighting pass' output, Rgba16Float (lighting_target.wgsl declares the Rgba32Float
// one; WGSL cannot make a storage format overridable, so the pass is composed with one or
// the other).
@group(0) @binding(10) var out_tex: texture_storage_2d<rgba16float, write>;
