//! The traits the bench harness composes: a [`Technique`] renders images, a [`Metric`]
//! compares them.

use crate::Error;
use crate::image::Image;
use crate::scene::{Camera, Scene};

/// A global-illumination method. Precomputation ([`Technique::prepare`]) is timed apart from
/// one frame ([`Technique::render`]).
pub trait Technique {
    /// A short name for reports.
    fn name(&self) -> &str;
    /// View-independent precomputation for `scene` (form factors, LDC, shadow maps...).
    fn prepare(&mut self, scene: &Scene) -> Result<(), Error>;
    /// Renders one frame of `scene` from `camera` at `width x height`.
    fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Image, Error>;
}

/// The outcome of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricValue {
    /// The scalar value.
    pub value: f64,
    /// An optional per-pixel map (row-major, the images' size).
    pub map: Option<Vec<f32>>,
}

/// An image comparison measure.
pub trait Metric {
    /// A short name for reports ("mean-error", "ssim"...).
    fn name(&self) -> &str;
    /// True when smaller values mean closer images.
    fn lower_is_better(&self) -> bool;
    /// Compares `test` against `reference` (the same size).
    fn compare(&self, reference: &Image, test: &Image) -> Result<MetricValue, Error>;
}
