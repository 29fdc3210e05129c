//! # bench-harness
//!
//! Runs any `scene_core::Technique` against any `scene_core::Metric` on the built-in scenes and reports precomputation time, frame time and error against the reference path tracer.
//!
//! **Status: skeleton.** Nothing is implemented yet (see the project's issues); this crate compiles so the
//! workspace and its dependency rule hold. It composes nothing concrete itself: `xtask` plugs the techniques and metrics in.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(bench_harness::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
