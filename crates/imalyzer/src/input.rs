//! Checking the images handed to a measure: equal sizes, no empty images, and what to do
//! with NaN and infinite values.

use rayon::prelude::*;
use scene_core::Image;
use scene_core::glam::Vec3;
use serde::Serialize;

use crate::error::CompareError;

/// What a measure does with pixels that hold a NaN or infinite value in any channel of
/// any input image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NonFinite {
    /// Refuse the comparison with [`CompareError::NonFinite`], naming the image and the
    /// first pixel at fault (the default: a NaN in a render is a bug to see, not to hide).
    #[default]
    Reject,
    /// Leave such pixels out of every mean, sum and count. Spatial measures (SSIM, FLIP)
    /// still need a value there for their filters: the pixel takes the other image's value
    /// (black when both are non-finite), so it adds no difference to its neighbours, and
    /// it is left out of the pooled mean; its entry in the error map is NaN.
    Exclude,
}

/// Pixels per reduction chunk. Sums are formed per chunk, then the chunks in order, so a
/// result is bit-identical whatever the thread count.
pub(crate) const CHUNK: usize = 16 * 1024;

/// Images checked against each other: one size, not empty, with the set of pixels every
/// measure uses.
#[derive(Clone, Debug)]
pub(crate) struct Checked {
    pub width: u32,
    pub height: u32,
    /// `Some(mask)` when pixels are excluded: `mask[i]` is true for a pixel in use.
    pub mask: Option<Vec<bool>>,
    /// Pixels with a non-finite channel, per image.
    pub non_finite: Vec<usize>,
    /// Pixels in use.
    pub used: usize,
}

impl Checked {
    /// Checks `images` (label, image) under `policy`.
    pub fn new(images: &[(&str, &Image)], policy: NonFinite) -> Result<Self, CompareError> {
        let (first_label, first) = images[0];
        for &(label, img) in images {
            if img.width == 0 || img.height == 0 {
                return Err(CompareError::Empty {
                    image: label.to_string(),
                    width: img.width,
                    height: img.height,
                });
            }
            if img.pixels.len() != img.width as usize * img.height as usize {
                return Err(CompareError::BadLength {
                    image: label.to_string(),
                    width: img.width,
                    height: img.height,
                    found: img.pixels.len(),
                });
            }
            if (img.width, img.height) != (first.width, first.height) {
                return Err(CompareError::SizeMismatch {
                    a: first_label.to_string(),
                    a_size: (first.width, first.height),
                    b: label.to_string(),
                    b_size: (img.width, img.height),
                });
            }
        }
        let n = first.pixels.len();
        let mut non_finite = Vec::with_capacity(images.len());
        for &(label, img) in images {
            let count = img.pixels.par_iter().filter(|p| !p.is_finite()).count();
            if count > 0 && policy == NonFinite::Reject {
                let i = img.pixels.iter().position(|p| !p.is_finite()).unwrap_or(0);
                return Err(CompareError::NonFinite {
                    image: label.to_string(),
                    pixels: count,
                    first: (
                        (i % img.width as usize) as u32,
                        (i / img.width as usize) as u32,
                    ),
                });
            }
            non_finite.push(count);
        }
        let (mask, used) = if non_finite.iter().all(|&c| c == 0) {
            (None, n)
        } else {
            let mask: Vec<bool> = (0..n)
                .into_par_iter()
                .map(|i| images.iter().all(|(_, img)| img.pixels[i].is_finite()))
                .collect();
            let used = mask.iter().filter(|&&m| m).count();
            (Some(mask), used)
        };
        if used == 0 {
            return Err(CompareError::NothingLeft);
        }
        Ok(Self {
            width: first.width,
            height: first.height,
            mask,
            non_finite,
            used,
        })
    }

    /// Whether pixel `i` is in use.
    #[inline]
    pub fn is_used(&self, i: usize) -> bool {
        self.mask.as_ref().is_none_or(|m| m[i])
    }

    /// Pixel count (used or not).
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// `f(range)` for each reduction chunk of pixel indices, in parallel, results in chunk
    /// order (for reductions that need more than one pass over a chunk).
    pub fn per_chunk<A, F>(&self, f: F) -> Vec<A>
    where
        A: Send,
        F: Fn(std::ops::Range<usize>) -> A + Sync,
    {
        let n = self.len();
        (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| f(c * CHUNK..((c + 1) * CHUNK).min(n)))
            .collect()
    }

    /// Folds `f(acc, pixel index)` over the used pixels chunk by chunk in parallel, then
    /// merges the chunk results in order with `merge`: deterministic for any thread count.
    pub fn fold<A, F, M>(&self, init: A, f: F, merge: M) -> A
    where
        A: Clone + Send + Sync,
        F: Fn(&mut A, usize) + Sync,
        M: Fn(A, A) -> A,
    {
        let n = self.len();
        let parts: Vec<A> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let mut acc = init.clone();
                let end = ((c + 1) * CHUNK).min(n);
                match &self.mask {
                    None => (c * CHUNK..end).for_each(|i| f(&mut acc, i)),
                    Some(m) => (c * CHUNK..end)
                        .filter(|&i| m[i])
                        .for_each(|i| f(&mut acc, i)),
                }
                acc
            })
            .collect();
        parts.into_iter().fold(init, merge)
    }
}

/// A reference image and a test image, checked once and compared by any measure.
///
/// Building a `Pair` checks that both images have the same, non-zero size and applies the
/// [`NonFinite`] policy; every measure method then works on the pixels in use.
///
/// ```
/// use imalyzer::{NonFinite, Pair};
/// use imalyzer::scene_core::{Image, glam::Vec3};
///
/// let a = Image::filled(4, 4, Vec3::splat(0.5));
/// let mut b = a.clone();
/// b.set(0, 0, Vec3::new(f32::NAN, 0.0, 0.0));
/// assert!(Pair::new(&a, &b).is_err());
/// let pair = Pair::with_policy(&a, &b, NonFinite::Exclude).unwrap();
/// assert_eq!(pair.excluded_pixels(), 1);
/// assert_eq!(pair.mean_error(), 0.0);
/// ```
#[derive(Clone, Debug)]
pub struct Pair<'a> {
    pub(crate) reference: &'a Image,
    pub(crate) test: &'a Image,
    pub(crate) checked: Checked,
}

impl<'a> Pair<'a> {
    /// Checks `reference` and `test`, refusing non-finite values ([`NonFinite::Reject`]).
    pub fn new(reference: &'a Image, test: &'a Image) -> Result<Self, CompareError> {
        Self::with_policy(reference, test, NonFinite::Reject)
    }

    /// Checks `reference` and `test` under `policy`.
    pub fn with_policy(
        reference: &'a Image,
        test: &'a Image,
        policy: NonFinite,
    ) -> Result<Self, CompareError> {
        let checked = Checked::new(&[("reference", reference), ("test", test)], policy)?;
        Ok(Self {
            reference,
            test,
            checked,
        })
    }

    /// The reference image.
    pub fn reference(&self) -> &'a Image {
        self.reference
    }

    /// The test image.
    pub fn test(&self) -> &'a Image {
        self.test
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.checked.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.checked.height
    }

    /// Pixels compared (all of them unless some were excluded).
    pub fn used_pixels(&self) -> usize {
        self.checked.used
    }

    /// Pixels left out because a channel of either image is NaN or infinite.
    pub fn excluded_pixels(&self) -> usize {
        self.checked.len() - self.checked.used
    }

    /// Pixels with a NaN or infinite channel in `[reference, test]`.
    pub fn non_finite_pixels(&self) -> [usize; 2] {
        [self.checked.non_finite[0], self.checked.non_finite[1]]
    }

    /// Whether pixel `i` (row-major index) is compared.
    pub fn is_used(&self, i: usize) -> bool {
        self.checked.is_used(i)
    }

    /// The two images with excluded pixels replaced for spatial filters: each takes the
    /// other image's value, or black when both are non-finite.
    pub(crate) fn filled_for_filters(&self) -> (Vec<Vec3>, Vec<Vec3>) {
        fill_excluded(self.reference, self.test, &self.checked)
    }
}

/// See [`Pair::filled_for_filters`].
pub(crate) fn fill_excluded(a: &Image, b: &Image, checked: &Checked) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut fa = a.pixels.clone();
    let mut fb = b.pixels.clone();
    if checked.mask.is_some() {
        for i in 0..fa.len() {
            if !checked.is_used(i) {
                let (pa, pb) = (a.pixels[i], b.pixels[i]);
                let v = if pa.is_finite() {
                    pa
                } else if pb.is_finite() {
                    pb
                } else {
                    Vec3::ZERO
                };
                fa[i] = v;
                fb[i] = v;
            }
        }
    }
    (fa, fb)
}
