//! # relight-pr
//!
//! Radiosity relighting: progressive-refinement radiosity whose energy is tagged with the emitting light, so k single-light solutions are computed at once and relit in real time as B_j = sum_m B_jm E_m.
//!
//! **Status: skeleton.** Nothing is implemented yet (see the project's issues); this crate compiles so the
//! workspace and its dependency rule hold. It integrates hemicube G-buffers (any `scene_core::GBufferRenderer`) by triangle id into form factors and implements `scene_core::Technique`.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(relight_pr::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
