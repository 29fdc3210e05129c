//! # imalyzer
//!
//! Image comparison for renderers: every error figure of the diffuse-GI toolkit goes through
//! this crate. It holds the thesis' Imalyzer measures (chapter 3: luminance eq. 17,
//! difference image eq. 18, mean error eq. 19, Pearson's correlation eq. 20, the quality
//! function eq. 21 and the pixel-level comparison), the measures renderers report today
//! (RMSE, PSNR, relMSE, SMAPE, SSIM, LDR- and HDR-FLIP) and a statistical test of a noisy
//! render against a reference with known variance.
//!
//! ```
//! use imalyzer::{Pair, quality};
//! use imalyzer::scene_core::{Image, glam::Vec3};
//!
//! let reference = Image::filled(32, 24, Vec3::new(0.2, 0.4, 0.6));
//! let mut test = reference.clone();
//! test.set(3, 4, Vec3::new(0.5, 0.4, 0.6));
//!
//! let pair = Pair::new(&reference, &test)?;
//! // Eq. 19: one channel of one pixel is off by 0.3.
//! assert!((pair.mean_error() - 0.3 / (3.0 * 32.0 * 24.0)).abs() < 1e-9);
//! assert!(pair.ssim().mean < 1.0 && pair.flip().mean > 0.0);
//! assert_eq!(Pair::new(&reference, &reference)?.flip().mean, 0.0);
//!
//! // Eq. 21: the reference itself is closer to the model than `test`.
//! assert_eq!(quality(&reference, &reference, &test)?.linear.f_q, 1);
//! # Ok::<(), imalyzer::CompareError>(())
//! ```
//!
//! Images are [`scene_core::Image`]s: linear RGB f32, row-major. Every measure works on a
//! [`Pair`], which checks the sizes once and applies the [`NonFinite`] policy (NaN and
//! infinite values are refused unless excluded explicitly). Free functions ([`mean_error`],
//! [`ssim()`], [`flip()`]...) build the pair for one-off use. [`MeasureMetric`] plugs any
//! [`Measure`] into the bench harness as a [`scene_core::Metric`]. The `imalyzer` binary
//! (feature `cli`, on by default) compares PNG and EXR files from the command line.
//!
//! Conventions (see `docs/imalyzer.md`): sums are accumulated in f64 in fixed chunks, so a
//! result is bit-identical for any thread count; the 8-bit scale is the nearest 8-bit sRGB
//! code of the clamped linear value ([`srgb8`]); SSIM runs on the eq. 17 luminance with
//! data range 1 and scikit-image's conventions; FLIP follows the paper and agrees with
//! NVIDIA's `flip-evaluator` to 1e-3 on its mean.

mod error;
mod filter;
pub mod flip;
mod input;
mod measure;
mod pointwise;
pub mod ssim;
pub mod stats;
mod thesis;

pub use error::CompareError;
pub use flip::{Flip, FlipOptions, flip, hdr_flip};
pub use input::{NonFinite, Pair};
pub use measure::{Evaluation, Measure, MeasureMetric, Settings};
pub use pointwise::{psnr, relmse, rmse, smape};
pub use scene_core;
pub use scene_core::luminance;
pub use ssim::{Ssim, SsimOptions, ssim};
pub use stats::{Estimate, ZTest, ZTestOptions, z_test, z_test_noisy_reference};
pub use thesis::{
    EXCLUDED_COLOUR, Quality, QualityOnScale, difference, linear_from_srgb8, mean_error,
    mean_error_8bit, negative_difference, negative_difference_image, pearson, quality,
    quality_with, srgb8,
};
