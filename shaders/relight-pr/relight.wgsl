#import relight_pr::common::{relit}
// Eq. 1 of the radiosity relighting paper at every element: B_j = base + sum_m d_m D_jm +
// i_m I_jm, one thread per element (mirrors Packed::relight_into). The dispatch is
// (min(groups, 32768), ceil(groups / 32768)) workgroups of 64.

// The packed words hold halves (Precision::F16).
override F16: bool = false;

struct RelightParams {
    n: u32,
    k: u32,
    pad0: u32,
    pad1: u32,
    base: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: RelightParams;
@group(0) @binding(3) var<storage, read_write> irradiance: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x + gid.y * (32768u * 64u);
    if j >= params.n {
        return;
    }
    irradiance[j] = vec4<f32>(params.base.xyz + relit(j, params.k, true, F16), 0.0);
}
