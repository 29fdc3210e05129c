//! Every measure by name, and as a [`scene_core::Metric`] for the bench harness.

use scene_core::{Image, Metric, MetricValue};
use serde::Serialize;

use crate::error::CompareError;
use crate::flip::FlipOptions;
use crate::input::{NonFinite, Pair};
use crate::ssim::SsimOptions;

/// One measure of the crate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Measure {
    /// Mean error of eq. 19 on linear values ([`Pair::mean_error`]); map: `|D|` averaged
    /// over the channels.
    MeanError,
    /// Mean error of eq. 19 on 8-bit sRGB codes ([`Pair::mean_error_8bit`]).
    MeanError8bit,
    /// Pearson's correlation of eq. 20 ([`Pair::pearson`]).
    Pearson,
    /// Root mean squared error ([`Pair::rmse`]).
    Rmse,
    /// PSNR for peak 1, in dB ([`Pair::psnr`]).
    Psnr,
    /// Relative MSE ([`Pair::relmse`]).
    RelMse,
    /// Symmetric mean absolute percentage error ([`Pair::smape`]).
    Smape,
    /// Mean SSIM on luminance ([`Pair::ssim_with`]); map: SSIM per pixel.
    Ssim,
    /// LDR-FLIP ([`Pair::flip_with`]); map: FLIP per pixel.
    Flip,
    /// HDR-FLIP ([`Pair::hdr_flip_with`]); map: FLIP per pixel.
    HdrFlip,
}

impl Measure {
    /// Every measure, in report order.
    pub const ALL: [Measure; 10] = [
        Measure::MeanError,
        Measure::MeanError8bit,
        Measure::Pearson,
        Measure::Rmse,
        Measure::Psnr,
        Measure::RelMse,
        Measure::Smape,
        Measure::Ssim,
        Measure::Flip,
        Measure::HdrFlip,
    ];

    /// The measure's name in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Measure::MeanError => "mean-error",
            Measure::MeanError8bit => "mean-error-8bit",
            Measure::Pearson => "pearson",
            Measure::Rmse => "rmse",
            Measure::Psnr => "psnr",
            Measure::RelMse => "relmse",
            Measure::Smape => "smape",
            Measure::Ssim => "ssim",
            Measure::Flip => "flip",
            Measure::HdrFlip => "hdr-flip",
        }
    }

    /// The measure named `name` (its [`Measure::name`], or `mean` for the mean error and
    /// `mean8` for its 8-bit form; case-insensitive).
    pub fn parse(name: &str) -> Option<Measure> {
        let name = name.trim().to_ascii_lowercase();
        match name.as_str() {
            "mean" => Some(Measure::MeanError),
            "mean8" | "mean-8bit" => Some(Measure::MeanError8bit),
            "ldr-flip" => Some(Measure::Flip),
            _ => Measure::ALL.into_iter().find(|m| m.name() == name),
        }
    }

    /// True when smaller values mean closer images (false for Pearson, PSNR and SSIM).
    pub fn lower_is_better(self) -> bool {
        !matches!(self, Measure::Pearson | Measure::Psnr | Measure::Ssim)
    }
}

/// Settings shared by all measures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settings {
    /// What to do with NaN and infinite values.
    pub non_finite: NonFinite,
    /// SSIM settings.
    pub ssim: SsimOptions,
    /// FLIP settings (LDR and HDR).
    pub flip: FlipOptions,
}

/// The value of one measure.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// Which measure.
    pub measure: Measure,
    /// Its value.
    pub value: f64,
    /// Its per-pixel map, for the measures that have one.
    pub map: Option<Vec<f32>>,
    /// HDR-FLIP: the exposures evaluated (stops); empty otherwise.
    pub exposures: Vec<f32>,
}

impl Pair<'_> {
    /// Evaluates `measure` with `settings` (the pair's own non-finite policy applies; the
    /// one in `settings` is for [`MeasureMetric`]).
    pub fn evaluate(
        &self,
        measure: Measure,
        settings: &Settings,
    ) -> Result<Evaluation, CompareError> {
        let plain = |value: f64| Evaluation {
            measure,
            value,
            map: None,
            exposures: Vec::new(),
        };
        Ok(match measure {
            Measure::MeanError => Evaluation {
                map: Some(self.abs_map()),
                ..plain(self.mean_error())
            },
            Measure::MeanError8bit => plain(self.mean_error_8bit()),
            Measure::Pearson => plain(self.pearson()),
            Measure::Rmse => plain(self.rmse()),
            Measure::Psnr => plain(self.psnr()),
            Measure::RelMse => plain(self.relmse()),
            Measure::Smape => plain(self.smape()),
            Measure::Ssim => {
                let s = self.ssim_with(&settings.ssim)?;
                Evaluation {
                    map: Some(s.map),
                    ..plain(s.mean)
                }
            }
            Measure::Flip | Measure::HdrFlip => {
                let f = if measure == Measure::Flip {
                    self.flip_with(&settings.flip)?
                } else {
                    self.hdr_flip_with(&settings.flip)?
                };
                Evaluation {
                    map: Some(f.map),
                    exposures: f.exposures,
                    ..plain(f.mean)
                }
            }
        })
    }
}

/// A [`Measure`] with its settings, as a [`scene_core::Metric`].
///
/// ```
/// use imalyzer::{Measure, MeasureMetric};
/// use imalyzer::scene_core::{Image, Metric, glam::Vec3};
///
/// let metric = MeasureMetric::new(Measure::Ssim);
/// let a = Image::filled(16, 16, Vec3::splat(0.3));
/// let v = metric.compare(&a, &a).unwrap();
/// assert_eq!(metric.name(), "ssim");
/// assert!(!metric.lower_is_better());
/// assert!((v.value - 1.0).abs() < 1e-12);
/// assert_eq!(v.map.unwrap().len(), 256);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasureMetric {
    /// The measure.
    pub measure: Measure,
    /// Its settings.
    pub settings: Settings,
}

impl MeasureMetric {
    /// `measure` with the default settings.
    pub fn new(measure: Measure) -> Self {
        Self {
            measure,
            settings: Settings::default(),
        }
    }

    /// Every measure with the default settings.
    pub fn all() -> Vec<MeasureMetric> {
        Measure::ALL.into_iter().map(MeasureMetric::new).collect()
    }
}

impl Metric for MeasureMetric {
    fn name(&self) -> &str {
        self.measure.name()
    }

    fn lower_is_better(&self) -> bool {
        self.measure.lower_is_better()
    }

    fn compare(&self, reference: &Image, test: &Image) -> Result<MetricValue, scene_core::Error> {
        let pair = Pair::with_policy(reference, test, self.settings.non_finite)?;
        let e = pair.evaluate(self.measure, &self.settings)?;
        Ok(MetricValue {
            value: e.value,
            map: e.map,
        })
    }
}
