//! The one error type of the crate: what is wrong with the images handed to a measure.
//!
//! Errors name the image at fault by a label: `"reference"` and `"test"` for a pair,
//! `"model"`, `"image 1"`, `"image 2"` for the quality function. The command-line tool
//! swaps the labels for file names with [`CompareError::relabel`].

use scene_core::ImageError;

/// Why a comparison could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompareError {
    /// Two images that must have the same size do not.
    #[error("{a} is {}x{} but {b} is {}x{}: sizes differ", a_size.0, a_size.1, b_size.0, b_size.1)]
    SizeMismatch {
        /// Label of the first image.
        a: String,
        /// Its size.
        a_size: (u32, u32),
        /// Label of the second image.
        b: String,
        /// Its size.
        b_size: (u32, u32),
    },
    /// An image has no pixels.
    #[error("{image} is empty ({width}x{height})")]
    Empty {
        /// Label of the image.
        image: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
    /// The pixel buffer of an image does not match its size.
    #[error("{image} has {found} pixels for a {width}x{height} image")]
    BadLength {
        /// Label of the image.
        image: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// Pixels in the buffer.
        found: usize,
    },
    /// An image holds NaN or infinite values and the policy is [`crate::NonFinite::Reject`].
    #[error(
        "{image} has {pixels} pixel(s) with NaN or infinite values (first at x={}, y={}); \
         exclude them explicitly to compare the rest",
        first.0, first.1
    )]
    NonFinite {
        /// Label of the image.
        image: String,
        /// Number of pixels with at least one non-finite channel.
        pixels: usize,
        /// The first such pixel, `(x, y)`.
        first: (u32, u32),
    },
    /// Every pixel was excluded as non-finite: nothing is left to compare.
    #[error("every pixel has a NaN or infinite value in at least one image: nothing to compare")]
    NothingLeft,
    /// An argument is out of its range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

impl CompareError {
    /// The same error with every image label passed through `f` (the command-line tool maps
    /// `"reference"` to the file name it read).
    pub fn relabel(self, f: impl Fn(&str) -> String) -> Self {
        match self {
            CompareError::SizeMismatch {
                a,
                a_size,
                b,
                b_size,
            } => CompareError::SizeMismatch {
                a: f(&a),
                a_size,
                b: f(&b),
                b_size,
            },
            CompareError::Empty {
                image,
                width,
                height,
            } => CompareError::Empty {
                image: f(&image),
                width,
                height,
            },
            CompareError::BadLength {
                image,
                width,
                height,
                found,
            } => CompareError::BadLength {
                image: f(&image),
                width,
                height,
                found,
            },
            CompareError::NonFinite {
                image,
                pixels,
                first,
            } => CompareError::NonFinite {
                image: f(&image),
                pixels,
                first,
            },
            other => other,
        }
    }
}

impl From<CompareError> for scene_core::Error {
    fn from(e: CompareError) -> Self {
        match e {
            CompareError::SizeMismatch { a_size, b_size, .. } => {
                scene_core::Error::Image(ImageError::SizeMismatch {
                    a: a_size,
                    b: b_size,
                })
            }
            CompareError::Empty { width, height, .. } => {
                scene_core::Error::Image(ImageError::ZeroSize { width, height })
            }
            CompareError::BadLength {
                width,
                height,
                found,
                ..
            } => scene_core::Error::Image(ImageError::BadLength {
                width,
                height,
                found,
            }),
            other => scene_core::Error::InvalidArgument(other.to_string()),
        }
    }
}
