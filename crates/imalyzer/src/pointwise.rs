//! The per-pixel measures renderers report: RMSE, PSNR, relMSE and SMAPE. Each is a mean
//! over the pixels in use and the three channels of linear values, `x` the test value and
//! `y` the reference value, accumulated in f64.

use scene_core::Image;

use crate::error::CompareError;
use crate::input::Pair;

/// The stabilising constant of relMSE and SMAPE.
const EPSILON: f64 = 0.01;

impl Pair<'_> {
    fn channel_mean(&self, f: impl Fn(f64, f64) -> f64 + Sync) -> f64 {
        let (r, t) = (&self.reference.pixels, &self.test.pixels);
        let sum = self.checked.fold(
            0.0f64,
            |acc, i| {
                let (y, x) = (r[i].as_dvec3(), t[i].as_dvec3());
                *acc += f(x.x, y.x) + f(x.y, y.y) + f(x.z, y.z);
            },
            |a, b| a + b,
        );
        sum / (3 * self.used_pixels()) as f64
    }

    /// Mean squared error, `mean((x - y)^2)`.
    pub fn mse(&self) -> f64 {
        self.channel_mean(|x, y| (x - y) * (x - y))
    }

    /// Root mean squared error, `sqrt(mean((x - y)^2))`.
    pub fn rmse(&self) -> f64 {
        self.mse().sqrt()
    }

    /// Peak signal-to-noise ratio in dB for a peak value of 1 (linear values in [0, 1]):
    /// `10 log10(1 / MSE)`; `+inf` for identical images.
    pub fn psnr(&self) -> f64 {
        self.psnr_with_peak(1.0)
    }

    /// PSNR for another peak value: `10 log10(peak^2 / MSE)`.
    pub fn psnr_with_peak(&self, peak: f64) -> f64 {
        let mse = self.mse();
        if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (peak * peak / mse).log10()
        }
    }

    /// Relative mean squared error, `0.5 mean((x - y)^2 / (y^2 + 0.01))`.
    pub fn relmse(&self) -> f64 {
        0.5 * self.channel_mean(|x, y| (x - y) * (x - y) / (y * y + EPSILON))
    }

    /// Symmetric mean absolute percentage error, `mean(|x - y| / (|x| + |y| + 0.01))`.
    pub fn smape(&self) -> f64 {
        self.channel_mean(|x, y| (x - y).abs() / (x.abs() + y.abs() + EPSILON))
    }
}

/// Root mean squared error; refuses non-finite values.
pub fn rmse(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.rmse())
}

/// PSNR (peak 1); refuses non-finite values.
pub fn psnr(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.psnr())
}

/// relMSE; refuses non-finite values.
pub fn relmse(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.relmse())
}

/// SMAPE; refuses non-finite values.
pub fn smape(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.smape())
}
