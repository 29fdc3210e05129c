//! # isr
//!
//! Image-space radiosity (the thesis' chapter 4) as a post-process on any G-buffer: one
//! bounce of indirect light from neighbouring pixels treated as patches (eq. 25),
//! spherical-occluder SSAO (eq. 26), a Gaussian or edge-aware blur, bilateral upsampling
//! (eqs. 27-28) and the lighting phase (eq. 29) with exponential shadow maps and PCF (eq. 30),
//! on the CPU (rayon) and the GPU (wgpu compute, one shader per pass in `shaders/isr/`).
//!
//! ```
//! use isr::{DownsampleMode, IsrInputs, LightSet, IsrSettings, ShadowSettings, downsample, render_cpu};
//! use scene_core::{GBufferRenderer, View, builtin, gbuffer::RayCastRenderer};
//!
//! let scene = builtin::scene("cornell-point").unwrap();
//! let view = View::from_camera(&scene.cameras[0].with_aspect(32.0 / 24.0));
//! // Any G-buffer will do; here primary rays give it.
//! let full = RayCastRenderer::new().render(&scene, &view, 32, 24).unwrap();
//! let coarse = downsample(&full, DownsampleMode::NearestSurface);
//! // Lights and shadow maps, once per scene.
//! let prepared = LightSet::new(&scene, &ShadowSettings { cube_resolution: 32, ..Default::default() }).unwrap();
//! let isr = render_cpu(&prepared, &IsrInputs { full: &full, coarse: &coarse, view: &view },
//!                      &IsrSettings::screen_space()).unwrap();
//! let dl = render_cpu(&prepared, &IsrInputs { full: &full, coarse: &coarse, view: &view },
//!                     &IsrSettings::dl()).unwrap();
//! // ISR adds the indirect bounce that direct lighting lacks.
//! assert!(isr.image.mean().element_sum() > dl.image.mean().element_sum());
//! assert_eq!(isr.image.non_finite_count(), 0);
//! ```
//!
//! The pieces:
//! - [`LightSet`]: lights (point, directional, point samples of emissive triangles), their
//!   shadow maps and the emissive-triangle table, built once per scene;
//! - [`IsrInputs`] + [`IsrSettings`] -> [`render_cpu`]: one frame on the CPU;
//! - [`GpuIsr`]: the same frame on the GPU from a [`scene_core::gpu::GpuGBuffer`] into a
//!   caller-provided texture, without readback;
//! - [`IsrTechnique`] and [`DlTechnique`]: [`scene_core::Technique`]s holding any
//!   [`scene_core::GBufferRenderer`].
//!
//! The passes, each a CPU module here with the paper's equations, a shader in
//! `shaders/isr/` and a GPU pipeline in [`passes`]: [`lighting`] (also the `Lit` senders on
//! the coarse buffer; its shader is `lighting.wgsl` importing scene-core's
//! `light_set.wgsl` and `shadow.wgsl`), [`radiosity`] (ISR + SSAO), [`blur`], [`upsample`].
//! A GPU frame reads, in order: [`gpu_frame`] (the frame contract), [`gpu`] (`GpuIsr`: the
//! passes recorded in order, their bind groups kept), [`passes`].
//! The coarse buffers come from scene-core's downsampling ([`downsample()`],
//! `shaders/scene-core/downsample.wgsl`). The lights and their exponential shadow maps are
//! scene-core's [`shadowed_lights`](scene_core::shadowed_lights), shared with relighting's
//! per-frame direct light and re-exported here as [`light_set`] and [`shadow`]; the maps
//! are built on the CPU (they are view-independent).
//! `docs/isr.md` has the design decisions, the readings of the thesis' equations and the
//! measured errors and timings.

pub mod blur;
pub mod frame;
pub mod geometry;
pub mod gpu;
pub mod gpu_frame;
pub mod light_senders;
pub mod lighting;
pub mod passes;
pub mod radiosity;
pub mod settings;
pub mod technique;
pub mod upsample;

pub use scene_core::shadowed_lights as light_set;
pub use scene_core::shadowed_lights::esm as shadow;

pub use frame::{Frame, IsrInputs, PassTimings, render_cpu, render_cpu_with, render_image};
pub use gpu::{GpuIsr, GpuIsrInputs, Intermediate};
pub use gpu_frame::IsrFrame;
pub use light_senders::{GpuLightSender, LightSender, LightSenders, SenderRays};
pub use light_set::{Light, LightKind, LightSet, Part};
pub use scene_core::gbuffer::downsample::{DownsampleMode, coarse_size, downsample};
pub use settings::{
    Blur, DEFAULT_LIGHT_SENDERS, Estimator, IsrSettings, Radius, Sender, ShadowSettings,
};
pub use technique::{Backend, DlTechnique, IsrTechnique};

/// Every shader pass of ISR, as `cargo xtask shaders` validates them (see [`passes`]).
pub use passes::SHADER_PASSES;
pub use scene_core;
/// The wgpu this crate's GPU path is built on (use it for the textures you hand in).
pub use wgpu;

/// An error of the ISR crate.
#[derive(Debug, thiserror::Error)]
pub enum IsrError {
    /// A parameter is out of range.
    #[error("invalid ISR setting {name} = {value}: {reason}")]
    InvalidSetting {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A buffer has zero width or height.
    #[error("the {which} buffer has zero size ({width}x{height})")]
    ZeroSize {
        /// Which buffer ("full", "coarse", "output").
        which: &'static str,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// A G-buffer channel does not have one element per pixel.
    #[error("the {which} G-buffer's {channel} has {found} elements, expected {expected}")]
    BadLength {
        /// Which buffer.
        which: &'static str,
        /// Which channel.
        channel: &'static str,
        /// Pixels.
        expected: usize,
        /// Elements found.
        found: usize,
    },
    /// A G-buffer holds NaN or infinity on a non-background pixel.
    #[error("the {which} G-buffer's {channel} is not finite at pixel ({x}, {y})")]
    NonFinite {
        /// Which buffer.
        which: &'static str,
        /// Which channel.
        channel: &'static str,
        /// Column.
        x: u32,
        /// Row.
        y: u32,
    },
    /// Sizes that must agree do not.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
    /// The scene's light data cannot be used.
    #[error("bad scene: {0}")]
    BadScene(String),
    /// A budget (shadow-map texels, GPU buffer size) would be exceeded.
    #[error("budget exceeded: {0}")]
    Budget(scene_core::BudgetExceeded),
    /// The GPU failed, or a texture has the wrong format or usage.
    #[error(transparent)]
    Gpu(#[from] scene_core::gpu::GpuError),
    /// An error of the shared layer (G-buffer rendering).
    #[error(transparent)]
    Core(#[from] Box<scene_core::Error>),
}

/// The light set's errors keep their ISR names (ISR built its own light set before it moved
/// to scene-core).
impl From<scene_core::shadowed_lights::LightSetError> for IsrError {
    fn from(e: scene_core::shadowed_lights::LightSetError) -> Self {
        use scene_core::shadowed_lights::LightSetError as E;
        match e {
            E::InvalidSetting {
                name,
                value,
                reason,
            } => IsrError::InvalidSetting {
                name,
                value,
                reason,
            },
            E::BadScene(s) => IsrError::BadScene(s),
            E::Budget(b) => IsrError::Budget(b),
        }
    }
}

/// Keeps the error's kind across the [`scene_core::Technique`] boundary: GPU and shared-layer
/// errors become theirs, everything else travels whole as [`scene_core::Error::Method`]
/// (recover it with `error.method_error::<IsrError>()`).
impl From<IsrError> for scene_core::Error {
    fn from(e: IsrError) -> Self {
        match e {
            IsrError::Gpu(g) => scene_core::Error::Gpu(g),
            IsrError::Core(c) => *c,
            other => scene_core::Error::method("isr", other),
        }
    }
}
