//! # imalyzer
//!
//! Image comparison: the thesis' Imalyzer measures (difference image eq. 18, mean error eq. 19, Pearson correlation eq. 20, quality function eq. 21) and RMSE, PSNR, relMSE, SMAPE, SSIM, FLIP and a statistical test of noisy renders.
//!
//! **Status: skeleton.** Nothing is implemented yet (see issue 3); this crate compiles so the
//! workspace and its dependency rule hold. It implements `scene_core::Metric`; every error figure of the project goes through it.
//!
//! What it will consume already exists in `scene-core`:
//!
//! ```
//! use scene_core::{builtin, View};
//!
//! let scene = builtin::scene("cornell").unwrap();
//! let view = View::from_camera(&scene.cameras[0]);
//! assert!(view.frustum_corners().is_some());
//! assert_eq!(imalyzer::STATUS, "skeleton");
//! ```

/// Implementation status of this crate.
pub const STATUS: &str = "skeleton";

pub use scene_core;
