#define_import_path relight_pr::common
// The packed k x n solution of radiosity relighting and eq. 1 over it (mirrors
// crates/relight-pr/src/packed.rs): item-major, then source by source, the six scalars
// direct.rgb, indirect.rgb as 32-bit words, f32 bits or two halves per word (F16).
// Both relight-pr passes import it (`relight_pr::common`); their own bindings start at 3.
// `f16` says the words hold halves (each pass has the pipeline constant F16 and passes it).

// The packed solution (elements for the relight pass, welded vertices for the display).
@group(0) @binding(1) var<storage, read> words: array<u32>;
// Per source m: factors[2m] its direct factor, factors[2m + 1] its indirect factor (rgb).
@group(0) @binding(2) var<storage, read> factors: array<vec4<f32>>;

// Eq. 1 at one item: sum_m d_m D_jm + i_m I_jm (without the constant term); the direct
// part left out unless with_direct.
fn relit(item: u32, k: u32, with_direct: bool, f16: bool) -> vec3<f32> {
    let dm = select(0.0, 1.0, with_direct);
    var e = vec3<f32>(0.0);
    for (var m = 0u; m < k; m++) {
        var v: array<f32, 6>;
        if f16 {
            let w = (item * k + m) * 3u;
            let a = unpack2x16float(words[w]);
            let b = unpack2x16float(words[w + 1u]);
            let c = unpack2x16float(words[w + 2u]);
            v = array<f32, 6>(a.x, a.y, b.x, b.y, c.x, c.y);
        } else {
            let w = (item * k + m) * 6u;
            for (var c = 0u; c < 6u; c++) {
                v[c] = bitcast<f32>(words[w + c]);
            }
        }
        e += vec3<f32>(v[0], v[1], v[2]) * factors[2u * m].xyz * dm
            + vec3<f32>(v[3], v[4], v[5]) * factors[2u * m + 1u].xyz;
    }
    return e;
}
