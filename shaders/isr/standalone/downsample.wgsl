// Depth-aware 2x2 downsampling of a G-buffer into the coarse buffers of the ISR pass
// (thesis section 4.2; mirrors crates/isr/src/downsample.rs).
//
// Each coarse texel takes the nearest non-background sample of its 2x2 block as its
// representative and averages the samples within DEPTH_TOLERANCE (relative) of its depth:
// the thesis' average inside a surface, the foreground across a silhouette. Normals that
// cancel fall back to the representative's. A block without geometry is background.
//
// In standalone/ so that ../common.wgsl is not prepended: its textures start at binding 0.

@group(0) @binding(0) var full_albedo: texture_2d<f32>;
@group(0) @binding(1) var full_normal: texture_2d<f32>;
@group(0) @binding(2) var full_depth: texture_2d<f32>;
@group(0) @binding(3) var full_id: texture_2d<u32>;
@group(0) @binding(4) var out_albedo: texture_storage_2d<rgba32float, write>;
@group(0) @binding(5) var out_normal: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var out_depth: texture_storage_2d<r32float, write>;
@group(0) @binding(7) var out_id: texture_storage_2d<r32uint, write>;

const BACKGROUND: u32 = 0xffffffffu;
const DEPTH_TOLERANCE: f32 = 0.05;
const MIN_NORMAL_LEN2: f32 = 1e-12;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let csize = textureDimensions(out_depth);
    if (gid.x >= csize.x || gid.y >= csize.y) {
        return;
    }
    let size = vec2<i32>(textureDimensions(full_depth));
    let c = vec2<i32>(gid.xy);
    // Gather the non-background samples in row-major order.
    var idx: array<vec2<i32>, 4>;
    var n = 0;
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let p = 2 * c + vec2<i32>(dx, dy);
            if (p.x < size.x && p.y < size.y) {
                if (textureLoad(full_id, p, 0).x != BACKGROUND) {
                    idx[n] = p;
                    n++;
                }
            }
        }
    }
    if (n == 0) {
        textureStore(out_albedo, c, vec4<f32>(0.0));
        textureStore(out_normal, c, vec4<f32>(0.0));
        textureStore(out_depth, c, vec4<f32>(1.0, 0.0, 0.0, 0.0));
        textureStore(out_id, c, vec4<u32>(BACKGROUND, 0u, 0u, 0u));
        return;
    }
    // The nearest sample (ties: the first).
    var rep = idx[0];
    var z0 = textureLoad(full_depth, rep, 0).x;
    for (var k = 1; k < n; k++) {
        let z = textureLoad(full_depth, idx[k], 0).x;
        if (z < z0) {
            rep = idx[k];
            z0 = z;
        }
    }
    var a = vec4<f32>(0.0);
    var nrm = vec3<f32>(0.0);
    var z = 0.0;
    var count = 0.0;
    for (var k = 0; k < n; k++) {
        let zk = textureLoad(full_depth, idx[k], 0).x;
        if (abs(zk - z0) <= DEPTH_TOLERANCE * z0) {
            a += textureLoad(full_albedo, idx[k], 0);
            nrm += textureLoad(full_normal, idx[k], 0).xyz;
            z += zk;
            count += 1.0;
        }
    }
    let l2 = dot(nrm, nrm);
    var out_n = textureLoad(full_normal, rep, 0).xyz;
    if (l2 > MIN_NORMAL_LEN2 * count * count) {
        out_n = nrm / sqrt(l2);
    }
    textureStore(out_albedo, c, a / count);
    textureStore(out_normal, c, vec4<f32>(out_n, 0.0));
    textureStore(out_depth, c, vec4<f32>(z / count, 0.0, 0.0, 0.0));
    textureStore(out_id, c, vec4<u32>(textureLoad(full_id, rep, 0).x, 0u, 0u, 0u));
}
