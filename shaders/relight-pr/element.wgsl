#define_import_path relight_pr::element
// One row of the display's element table (relight_pr::gpu's GpuElement, 80 bytes), which
// the display pass and the direct pass both read.

struct Element {
    // Corners in xyz; a.w the element's source index + 1 (0: not an emitter).
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    // Emitted radiance in rgb.
    emission: vec4<f32>,
    // Welded vertex of each corner.
    vertex: vec4<u32>,
}
