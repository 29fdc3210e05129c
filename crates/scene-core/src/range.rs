//! Stated ranges for the numbers a user sets (command-line arguments, replay scripts,
//! settings): each is checked before any allocation or loop it sizes, and a value outside
//! its range is refused with an error naming the argument, the value and the range.

use std::fmt::Debug;
use std::ops::RangeInclusive;

/// A number outside its stated range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{what} = {value} is outside its range [{min}, {max}]")]
pub struct OutOfRange {
    /// What the number is (an argument's name, a setting's field).
    pub what: String,
    /// The value given, as written.
    pub value: String,
    /// The smallest accepted value.
    pub min: String,
    /// The largest accepted value.
    pub max: String,
}

/// `value` when it lies in `range` (both ends included; NaN never does), else
/// [`OutOfRange`] naming `what` (numbers written as Rust's `{:?}` writes them, so a huge or
/// tiny float stays short: `-1e308`).
///
/// ```
/// use scene_core::range::check;
/// assert_eq!(check("--spp", 64u32, 1..=65536), Ok(64));
/// let e = check("--exposure", f32::NAN, -20.0..=20.0).unwrap_err();
/// assert_eq!(e.to_string(), "--exposure = NaN is outside its range [-20.0, 20.0]");
/// ```
pub fn check<T: PartialOrd + Debug + Copy>(
    what: &str,
    value: T,
    range: RangeInclusive<T>,
) -> Result<T, OutOfRange> {
    if range.contains(&value) {
        Ok(value)
    } else {
        Err(OutOfRange {
            what: what.to_string(),
            value: format!("{value:?}"),
            min: format!("{:?}", range.start()),
            max: format!("{:?}", range.end()),
        })
    }
}

/// [`check`] for an optional value: `None` passes.
pub fn check_opt<T: PartialOrd + Debug + Copy>(
    what: &str,
    value: Option<T>,
    range: RangeInclusive<T>,
) -> Result<Option<T>, OutOfRange> {
    value.map(|v| check(what, v, range)).transpose()
}

/// The widest image side any command renders (pixels).
pub const IMAGE_SIDE: RangeInclusive<u32> = 1..=8192;
/// Samples per pixel of a reference render.
pub const SPP: RangeInclusive<u32> = 1..=65536;
/// An exposure in stops.
pub const EXPOSURE: RangeInclusive<f32> = -20.0..=20.0;
