//! SSIM (Wang, Bovik, Sheikh and Simoncelli 2004) on the luminance of eq. 17.
//!
//! Conventions, chosen to agree with scikit-image's `structural_similarity(..,
//! gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=L)`:
//!
//! - the signal is the luminance `0.27 R + 0.67 G + 0.06 B` of the linear values, not
//!   clamped, with data range `L` = [`SsimOptions::data_range`] (1 by default: linear
//!   values whose display range is [0, 1]);
//! - local statistics come from a Gaussian window of standard deviation 1.5 truncated at
//!   3.5 sigma (11 x 11 taps, normalised), applied separably with mirrored borders
//!   (`c b a | a b c`);
//! - population (co)variances: `var = E[x^2] - E[x]^2`;
//! - `SSIM = (2 mx my + C1)(2 cov + C2) / ((mx^2 + my^2 + C1)(vx + vy + C2))` with
//!   `C1 = (0.01 L)^2`, `C2 = (0.03 L)^2`;
//! - the map covers every pixel; the mean leaves out the 5-pixel border where the window
//!   reaches outside the image (as the reference MATLAB code and scikit-image do). Images
//!   narrower or lower than 11 pixels have no such interior: their mean is taken over the
//!   whole map.

use rayon::prelude::*;
use scene_core::Image;
use scene_core::glam::Vec3;

use crate::error::CompareError;
use crate::filter::{Border, separable};
use crate::input::Pair;

/// Standard deviation of the Gaussian window, in pixels.
pub const SIGMA: f64 = 1.5;
/// Half-width of the window: `trunc(3.5 sigma + 0.5)` = 5, so 11 x 11 taps.
pub const RADIUS: usize = 5;
/// The constant of the luminance term, `C1 = (K1 L)^2`.
pub const K1: f64 = 0.01;
/// The constant of the contrast-structure term, `C2 = (K2 L)^2`.
pub const K2: f64 = 0.03;

/// Settings of [`Pair::ssim_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsimOptions {
    /// The dynamic range `L` of the luminance values (1 for linear values displayed in
    /// [0, 1]).
    pub data_range: f64,
}

impl Default for SsimOptions {
    fn default() -> Self {
        Self { data_range: 1.0 }
    }
}

/// The outcome of SSIM: the mean and the per-pixel map.
#[derive(Clone, Debug, PartialEq)]
pub struct Ssim {
    /// Mean SSIM over the interior (see the module documentation), in [-1, 1]; 1 for
    /// identical images.
    pub mean: f64,
    /// SSIM per pixel, row-major (NaN where a pixel is excluded).
    pub map: Vec<f32>,
}

/// The normalised 1D Gaussian window.
fn window() -> [f64; 2 * RADIUS + 1] {
    let mut w: [f64; 2 * RADIUS + 1] = std::array::from_fn(|i| {
        let x = i as f64 - RADIUS as f64;
        (-0.5 * x * x / (SIGMA * SIGMA)).exp()
    });
    let sum: f64 = w.iter().sum();
    w.iter_mut().for_each(|v| *v /= sum);
    w
}

impl Pair<'_> {
    /// SSIM with the default options (data range 1).
    pub fn ssim(&self) -> Ssim {
        self.ssim_with(&SsimOptions::default())
            .expect("the default options are valid")
    }

    /// SSIM with `options`; errors when the data range is not positive and finite.
    pub fn ssim_with(&self, options: &SsimOptions) -> Result<Ssim, CompareError> {
        let l = options.data_range;
        if !(l > 0.0 && l.is_finite()) {
            return Err(CompareError::InvalidArgument(format!(
                "SSIM data range must be positive and finite, got {l}"
            )));
        }
        let (w, h) = (self.width() as usize, self.height() as usize);
        let (a, b) = self.filled_for_filters();
        // Eq. 17 in f64, so that values near f32::MAX stay finite.
        let lum = |p: &Vec3| {
            let p = p.as_dvec3();
            0.27 * p.x + 0.67 * p.y + 0.06 * p.z
        };
        let x: Vec<f64> = a.par_iter().map(lum).collect();
        let y: Vec<f64> = b.par_iter().map(lum).collect();
        let k = window();
        let blur = |v: &[f64]| separable(v, w, &k, &k, Border::Reflect);
        let mx = blur(&x);
        let my = blur(&y);
        let mxx = blur(&x.iter().map(|v| v * v).collect::<Vec<_>>());
        let myy = blur(&y.iter().map(|v| v * v).collect::<Vec<_>>());
        let mxy = blur(&x.iter().zip(&y).map(|(p, q)| p * q).collect::<Vec<_>>());
        let (c1, c2) = ((K1 * l).powi(2), (K2 * l).powi(2));
        let s: Vec<f64> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (ux, uy) = (mx[i], my[i]);
                let vx = mxx[i] - ux * ux;
                let vy = myy[i] - uy * uy;
                let cov = mxy[i] - ux * uy;
                ((2.0 * ux * uy + c1) * (2.0 * cov + c2))
                    / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
            })
            .collect();
        let interior = w > 2 * RADIUS && h > 2 * RADIUS;
        let (mut sum, mut count) = (0.0f64, 0usize);
        for yy in 0..h {
            if interior && (yy < RADIUS || yy >= h - RADIUS) {
                continue;
            }
            for xx in 0..w {
                let i = yy * w + xx;
                if (interior && (xx < RADIUS || xx >= w - RADIUS)) || !self.is_used(i) {
                    continue;
                }
                sum += s[i];
                count += 1;
            }
        }
        if count == 0 {
            // Every interior pixel is excluded: fall back on all the pixels in use.
            for (i, v) in s.iter().enumerate() {
                if self.is_used(i) {
                    sum += v;
                    count += 1;
                }
            }
        }
        let map = s
            .iter()
            .enumerate()
            .map(|(i, &v)| if self.is_used(i) { v as f32 } else { f32::NAN })
            .collect();
        Ok(Ssim {
            mean: sum / count as f64,
            map,
        })
    }
}

/// Mean SSIM of two images (data range 1); refuses non-finite values.
pub fn ssim(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.ssim().mean)
}
