//! # gbuffer
//!
//! Deferred G-buffers on the CPU and the GPU (thesis figure 4.1): albedo + radiation mask, world normal, linear depth / far, triangle id; coarse (2x downsampled) buffers and position reconstruction from linear depth (eqs. 23-24).
//!
//! **Status: skeleton.** Nothing is implemented yet (see issue 4); this crate compiles so the
//! workspace and its dependency rule hold. It will implement `scene_core::GBufferRenderer` twice (a tiled rayon rasteriser and a wgpu multiple-render-target pipeline) so that `isr`, `ibrr-ldc` and `relight-pr` can take either.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(gbuffer::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
