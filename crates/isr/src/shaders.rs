//! The ISR passes' WGSL (`shaders/isr/`, reached through the crate's `shaders` link), as
//! scene-core's shader composer joins them: `common.wgsl` is the module `isr::common`
//! (importing `scene_core::reconstruct`), the lighting pass imports scene-core's light set
//! (`scene_core::light_set`) and shadow maps (`scene_core::shadow`), the WGSL twins of
//! [`crate::light_set`] and [`crate::shadow`].

use scene_core::gpu::shader::{LIMITS, RECONSTRUCT, ShaderPass, Wgsl};
use scene_core::wgsl_file;

/// Globals, flags and view helpers of every ISR pass (`isr::common`).
pub const COMMON: Wgsl = wgsl_file!("isr", "common.wgsl");
pub use scene_core::shadowed_lights::gpu::{LIGHT_SET, SHADOW};

/// What every ISR pass may import.
const LIBRARY: &[Wgsl] = &[RECONSTRUCT, LIMITS, COMMON, LIGHT_SET, SHADOW];

/// The lighting pass writing `Rgba32Float` (eq. 29).
pub const LIGHTING: ShaderPass =
    ShaderPass::new("isr/lighting", wgsl_file!("isr", "lighting.wgsl"), LIBRARY);
/// The lighting pass writing `Rgba16Float` (WGSL cannot make a storage format overridable:
/// the variant is composed with the shader def `OUTPUT_RGBA16F`).
pub const LIGHTING_RGBA16F: ShaderPass =
    LIGHTING.with_defs("isr/lighting (rgba16f)", &["OUTPUT_RGBA16F"]);
/// The ISR + SSAO pass on the coarse buffers.
pub const RADIOSITY: ShaderPass = ShaderPass::new(
    "isr/radiosity",
    wgsl_file!("isr", "radiosity.wgsl"),
    LIBRARY,
);
/// One direction of the separable blur.
pub const BLUR: ShaderPass = ShaderPass::new("isr/blur", wgsl_file!("isr", "blur.wgsl"), LIBRARY);
/// Bilateral upsampling of the blurred coarse buffer.
pub const UPSAMPLE: ShaderPass =
    ShaderPass::new("isr/upsample", wgsl_file!("isr", "upsample.wgsl"), LIBRARY);

/// Every ISR shader pass, as `cargo xtask shaders` validates them.
pub const SHADER_PASSES: &[ShaderPass] = &[LIGHTING, LIGHTING_RGBA16F, RADIOSITY, BLUR, UPSAMPLE];
