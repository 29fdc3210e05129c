//! # isr
//!
//! Image-space radiosity (thesis chapter 4): one-bounce indirect light from neighbouring G-buffer pixels treated as patches (eq. 25), spherical-occluder SSAO (eq. 26), Gaussian blur, bilateral upsampling (eqs. 27-28), final lighting (eq. 29) and exponential shadow maps with PCF (eq. 30), on the CPU and the GPU.
//!
//! **Status: skeleton.** Nothing is implemented yet (see issue 5); this crate compiles so the
//! workspace and its dependency rule hold. It consumes a `scene_core::GBuffer` (or `GpuGBuffer`) and implements `scene_core::Technique`.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(isr::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
