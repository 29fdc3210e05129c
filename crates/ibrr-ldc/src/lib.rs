//! # ibrr-ldc
//!
//! Image-based radiosity representation: instant-radiosity point lights from particle walks, hemicube G-buffers from each, accumulated in a layered depth cube whose pixels are planes; reconstruction warps the camera view into the cube.
//!
//! **Status: skeleton.** Nothing is implemented yet (see the project's issues); this crate compiles so the
//! workspace and its dependency rule hold. It takes any `scene_core::GBufferRenderer` for its hemicube renders and implements `scene_core::Technique`.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(ibrr_ldc::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
