#define_import_path scene_core::limits
// Values every pass shares, imported rather than written out in each shader
// (crates/scene-core/src/gpu/shader.rs, `LIMITS`).

// The triangle id of a pixel where no surface is (`scene_core::BACKGROUND_ID`).
const BACKGROUND: u32 = 0xffffffffu;
// The largest finite f32 (`f32::MAX`): a value above it in magnitude is infinite, and a
// comparison with it is false for NaN.
const MAX_FINITE: f32 = 3.40282347e38;
