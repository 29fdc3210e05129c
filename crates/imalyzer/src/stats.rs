//! A statistical test of a noisy render against a reference, as Mitsuba's render tests do,
//! so that renderers can be tested without hand-tuned tolerances.
//!
//! Each pixel-channel of a Monte Carlo render is a mean of `spp` samples of per-sample
//! variance `var`. Against an exact reference the standard score of a pixel-channel is
//!
//! `z = |mean - ref| sqrt(spp / max(var, v_min))`, with `v_min = 1e-4`,
//!
//! and against a reference that is itself a Monte Carlo mean the two variances of the
//! means add: `z = |mean - ref| / sqrt(max(var, v_min) / spp + max(var_ref, v_min) /
//! spp_ref)`. The two-sided p-value is `erfc(z / sqrt 2)`. With `N` pixel-channels tested
//! at significance `alpha` (0.01), Šidák's correction makes each channel's level
//! `1 - (1 - alpha)^(1 / N)`; a channel passes when its p-value is above it, and the render
//! passes when at least 99.75% of its channels pass.

use scene_core::Image;
use scene_core::reference::ReferenceOutput;
use serde::Serialize;

use crate::error::CompareError;
use crate::input::{Checked, NonFinite};

/// A Monte Carlo estimate: the mean image, the per-pixel, per-channel variance of one
/// sample, and the number of samples per pixel.
#[derive(Clone, Copy, Debug)]
pub struct Estimate<'a> {
    /// The mean of the samples.
    pub image: &'a Image,
    /// The variance of one sample (divide by `spp` for the variance of the mean).
    pub variance: &'a Image,
    /// Samples per pixel.
    pub spp: u32,
}

impl<'a> From<&'a ReferenceOutput> for Estimate<'a> {
    fn from(out: &'a ReferenceOutput) -> Self {
        Self {
            image: &out.image,
            variance: &out.variance,
            spp: out.spp,
        }
    }
}

/// Settings of the test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZTestOptions {
    /// Significance level of the whole image, before Šidák's correction (0.01).
    pub significance: f64,
    /// Floor of the per-sample variance, `v_min` (1e-4): pixels that happen to have zero
    /// variance must not fail on rounding.
    pub min_variance: f64,
    /// Share of pixel-channels that must pass (0.9975).
    pub pass_fraction: f64,
    /// What to do with NaN and infinite values.
    pub non_finite: NonFinite,
}

impl Default for ZTestOptions {
    fn default() -> Self {
        Self {
            significance: 0.01,
            min_variance: 1e-4,
            pass_fraction: 0.9975,
            non_finite: NonFinite::Reject,
        }
    }
}

/// The outcome of the test.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ZTest {
    /// Pixel-channels tested.
    pub channels: usize,
    /// Pixel-channels whose p-value is at or below the corrected level (whose standard
    /// score is at or above `z_critical`).
    pub failed: usize,
    /// Share of pixel-channels that passed.
    pub passed_fraction: f64,
    /// Šidák-corrected level of one channel, `1 - (1 - alpha)^(1 / N)`.
    pub channel_level: f64,
    /// The standard score a channel fails above.
    pub z_critical: f64,
    /// The largest standard score.
    pub max_z: f64,
    /// Where it is: `(x, y, channel)`.
    pub worst: (u32, u32, usize),
    /// Relative difference of the channel sums, `sum(test) / sum(reference) - 1` (a
    /// brightness bias shows here; 0 when the reference sums to 0).
    pub relative_bias: f64,
    /// Whether the render passes.
    pub passed: bool,
}

/// Tests a noisy `test` render against an exact `reference`.
pub fn z_test(
    reference: &Image,
    test: &Estimate<'_>,
    options: &ZTestOptions,
) -> Result<ZTest, CompareError> {
    run(reference, None, test, options)
}

/// Tests a noisy `test` render against a noisy `reference` render (both variances count).
pub fn z_test_noisy_reference(
    reference: &Estimate<'_>,
    test: &Estimate<'_>,
    options: &ZTestOptions,
) -> Result<ZTest, CompareError> {
    run(reference.image, Some(reference), test, options)
}

#[derive(Clone, Copy)]
struct Sums {
    failed: usize,
    max_z: f64,
    worst: usize,
    sum_ref: f64,
    sum_test: f64,
}

fn run(
    reference: &Image,
    reference_noise: Option<&Estimate<'_>>,
    test: &Estimate<'_>,
    options: &ZTestOptions,
) -> Result<ZTest, CompareError> {
    let o = options;
    let valid_level = o.significance > 0.0 && o.significance < 1.0;
    let valid_floor = o.min_variance > 0.0 && o.min_variance.is_finite();
    if !(valid_level && valid_floor) {
        return Err(CompareError::InvalidArgument(format!(
            "z-test needs 0 < significance < 1 and a positive variance floor, got {} and {}",
            o.significance, o.min_variance
        )));
    }
    if !(0.0..=1.0).contains(&o.pass_fraction) {
        return Err(CompareError::InvalidArgument(format!(
            "z-test pass fraction must be in [0, 1], got {}",
            o.pass_fraction
        )));
    }
    let mut images = vec![
        ("reference", reference),
        ("test", test.image),
        ("test variance", test.variance),
    ];
    if let Some(r) = reference_noise {
        images.push(("reference variance", r.variance));
    }
    let checked = Checked::new(&images, o.non_finite)?;
    // A variance is never negative: one that is would be floored silently below and the
    // test would run on an image that is not a variance.
    for &(label, im) in &images[2..] {
        if let Some((i, p)) = im
            .pixels
            .iter()
            .enumerate()
            .find(|(_, p)| p.to_array().iter().any(|&v| v < 0.0))
        {
            let w = im.width.max(1) as usize;
            return Err(CompareError::InvalidArgument(format!(
                "{label} is negative at pixel ({}, {}): {:?}; a variance image holds values \
                 >= 0",
                i % w,
                i / w,
                p.to_array()
            )));
        }
    }
    for (label, spp) in
        std::iter::once(("test", test.spp)).chain(reference_noise.map(|r| ("reference", r.spp)))
    {
        if spp == 0 {
            return Err(CompareError::InvalidArgument(format!(
                "{label} has 0 samples per pixel"
            )));
        }
    }
    let n = 3 * checked.used;
    // Šidák: 1 - (1 - alpha)^(1/N), computed without cancellation.
    let level = -((-o.significance).ln_1p() / n as f64).exp_m1();
    let z_critical = z_for_p(level);
    let floor = o.min_variance;
    let variance_of_mean = |v: f32, spp: u32| (v as f64).max(floor) / spp as f64;
    let s = checked.fold(
        Sums {
            failed: 0,
            max_z: 0.0,
            worst: 0,
            sum_ref: 0.0,
            sum_test: 0.0,
        },
        |acc, i| {
            let r = reference.pixels[i].to_array();
            let t = test.image.pixels[i].to_array();
            let v = test.variance.pixels[i].to_array();
            for c in 0..3 {
                let mut var = variance_of_mean(v[c], test.spp);
                if let Some(rn) = reference_noise {
                    var += variance_of_mean(rn.variance.pixels[i][c], rn.spp);
                }
                let z = (t[c] as f64 - r[c] as f64).abs() / var.sqrt();
                // p <= level exactly when z >= z_critical (p falls as z grows).
                if z >= z_critical {
                    acc.failed += 1;
                }
                if z > acc.max_z {
                    acc.max_z = z;
                    acc.worst = 3 * i + c;
                }
                acc.sum_ref += r[c] as f64;
                acc.sum_test += t[c] as f64;
            }
        },
        |a, b| Sums {
            failed: a.failed + b.failed,
            max_z: a.max_z.max(b.max_z),
            worst: if b.max_z > a.max_z { b.worst } else { a.worst },
            sum_ref: a.sum_ref + b.sum_ref,
            sum_test: a.sum_test + b.sum_test,
        },
    );
    let passed_fraction = (n - s.failed) as f64 / n as f64;
    let w = checked.width as usize;
    let pixel = s.worst / 3;
    Ok(ZTest {
        channels: n,
        failed: s.failed,
        passed_fraction,
        channel_level: level,
        z_critical,
        max_z: s.max_z,
        worst: ((pixel % w) as u32, (pixel / w) as u32, s.worst % 3),
        relative_bias: if s.sum_ref != 0.0 {
            s.sum_test / s.sum_ref - 1.0
        } else {
            0.0
        },
        passed: passed_fraction >= o.pass_fraction,
    })
}

/// Two-sided p-value of a standard score: `P(|N(0, 1)| >= z) = erfc(z / sqrt 2)`.
pub fn two_sided_p(z: f64) -> f64 {
    erfc(z.abs() / std::f64::consts::SQRT_2)
}

/// The standard score whose two-sided p-value is `p` (bisection; `p` in (0, 1]).
pub fn z_for_p(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if two_sided_p(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The complementary error function, accurate to about 1e-14 relative for `x >= 0` (and
/// `2 - erfc(-x)` below 0): the Maclaurin series of erf below 2.5, Laplace's continued
/// fraction above.
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    let two_over_sqrt_pi = std::f64::consts::FRAC_2_SQRT_PI;
    if x < 2.5 {
        // erf(x) = 2/sqrt(pi) sum_n (-1)^n x^(2n+1) / (n! (2n+1))
        let x2 = x * x;
        let (mut term, mut sum) = (x, x);
        for n in 1..200 {
            term *= -x2 / n as f64;
            let add = term / (2 * n + 1) as f64;
            sum += add;
            if add.abs() < 1e-17 * sum.abs() {
                break;
            }
        }
        1.0 - two_over_sqrt_pi * sum
    } else if x > 27.0 {
        0.0
    } else {
        // erfc(x) = exp(-x^2)/sqrt(pi) * 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + 2/(x + ...)))))
        let mut f = x;
        for k in (1..=120).rev() {
            f = x + (k as f64 / 2.0) / f;
        }
        0.5 * two_over_sqrt_pi * (-x * x).exp() / f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erfc_matches_tabulated_values() {
        let table = [
            (0.0, 1.0),
            (0.5, 0.479_500_122_186_953_5),
            (1.0, 0.157_299_207_050_285_1),
            (2.0, 4.677_734_981_047_266e-3),
            (2.5, 4.069_520_174_449_59e-4),
            (3.0, 2.209_049_699_858_544e-5),
            (5.0, 1.537_459_794_428_035e-12),
            (10.0, 2.088_487_583_762_545e-45),
        ];
        for (x, want) in table {
            let got = erfc(x);
            assert!(
                ((got - want) / want).abs() < 1e-12,
                "erfc({x}) = {got}, want {want}"
            );
        }
        assert!((erfc(-1.0) - (2.0 - 0.157_299_207_050_285_1)).abs() < 1e-15);
    }

    #[test]
    fn a_negative_variance_is_refused_naming_the_pixel() {
        use scene_core::glam::Vec3;
        let reference = Image::filled(4, 3, Vec3::splat(1.0));
        let variance = Image::filled(4, 3, Vec3::splat(0.5));
        let ok = Estimate {
            image: &reference,
            variance: &variance,
            spp: 16,
        };
        assert!(z_test(&reference, &ok, &ZTestOptions::default()).is_ok());
        let mut negative = variance.clone();
        negative.pixels[6] = Vec3::new(0.5, -0.25, 0.5);
        let bad = Estimate {
            image: &reference,
            variance: &negative,
            spp: 16,
        };
        let e = z_test(&reference, &bad, &ZTestOptions::default()).unwrap_err();
        assert!(
            e.to_string()
                .contains("test variance is negative at pixel (2, 1)"),
            "{e}"
        );
        let e = z_test_noisy_reference(&bad, &ok, &ZTestOptions::default()).unwrap_err();
        assert!(
            e.to_string().contains("reference variance is negative"),
            "{e}"
        );
    }

    #[test]
    fn critical_scores_are_the_normal_quantiles() {
        assert!((z_for_p(0.05) - 1.959_963_984_540_054).abs() < 1e-9);
        assert!((z_for_p(0.01) - 2.575_829_303_548_901).abs() < 1e-9);
        assert!((two_sided_p(1.959_963_984_540_054) - 0.05).abs() < 1e-12);
    }
}
