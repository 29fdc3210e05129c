//! The thesis' measures (chapter 3): the difference image (eq. 18) and its negative
//! rendering (figure 5.5), the mean error (eq. 19) on linear values and on the 8-bit sRGB
//! scale, Pearson's correlation (eq. 20), the quality function (eq. 21) and the pixel-level
//! comparison ("99.05% of pixels improved").

use std::sync::OnceLock;

use rayon::prelude::*;
use scene_core::Image;
use scene_core::glam::Vec3;
use scene_core::image::srgb_to_linear;
use serde::Serialize;

use crate::error::CompareError;
use crate::input::{Checked, NonFinite, Pair};

/// Thresholds and a start table for [`srgb8`].
struct Srgb8Table {
    /// `thresholds[k]`: the smallest f32 whose code is `k + 1`, i.e. the linear value of
    /// the sRGB level `(k + 1/2) / 255` rounded up to the next f32.
    thresholds: [f32; 255],
    /// `start[i]`: the code of the smallest positive f32 whose bits shifted right by 16
    /// are `i` (for `x` in (0, 1)); the code of `x` is at most a few steps above it.
    start: Vec<u8>,
}

fn srgb8_table() -> &'static Srgb8Table {
    static TABLE: OnceLock<Srgb8Table> = OnceLock::new();
    TABLE.get_or_init(|| {
        let thresholds: [f32; 255] = std::array::from_fn(|k| {
            let s = (k as f64 + 0.5) / 255.0;
            let exact = if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            };
            let f = exact as f32;
            if (f as f64) < exact { f.next_up() } else { f }
        });
        let start = (0..=(1.0f32.to_bits() >> 16))
            .map(|i| {
                let x = f32::from_bits(i << 16);
                thresholds.partition_point(|&t| t <= x) as u8
            })
            .collect();
        Srgb8Table { thresholds, start }
    })
}

/// The 8-bit sRGB code of a linear value: the nearest code of the sRGB-encoded value,
/// after clamping to [0, 1] (NaN gives 0). This is the code a PNG written by
/// [`Image::write_png`] at exposure 0 holds, and reading that PNG back and encoding again
/// gives the same code.
pub fn srgb8(x: f32) -> u8 {
    // Code k is the number of thresholds T_1..T_255 at or below x.
    if x.is_nan() || x <= 0.0 {
        return 0;
    }
    if x >= 1.0 {
        return 255;
    }
    let t = srgb8_table();
    let mut k = t.start[(x.to_bits() >> 16) as usize];
    while k < 255 && t.thresholds[k as usize] <= x {
        k += 1;
    }
    k
}

/// The linear value whose 8-bit sRGB code is `code`: `srgb_to_linear(code / 255)`.
pub fn linear_from_srgb8(code: u8) -> f32 {
    srgb_to_linear(code as f32 / 255.0)
}

/// Difference image of eq. 18: `D = |I1 - I2|` per channel (linear values; a non-finite
/// input gives a non-finite entry).
pub fn difference(a: &Image, b: &Image) -> Result<Image, CompareError> {
    check_size(a, b)?;
    Ok(Image {
        width: a.width,
        height: a.height,
        pixels: a
            .pixels
            .par_iter()
            .zip(&b.pixels)
            .map(|(p, q)| (*p - *q).abs())
            .collect(),
    })
}

/// Colour of an excluded pixel in [`negative_difference`] (magenta: "no data").
pub const EXCLUDED_COLOUR: [u8; 3] = [255, 0, 255];

/// The negative of the difference image as the thesis drew it (figure 5.5): per channel
/// `255 - |c1 - c2|` on the 8-bit sRGB codes ([`srgb8`]) of both images, so white means
/// "no difference". Pixels with a non-finite value are drawn [`EXCLUDED_COLOUR`].
///
/// The result is an 8-bit raster, row-major, top row first. [`negative_difference_image`]
/// gives it as an [`Image`] ready for [`Image::write_png`].
pub fn negative_difference(a: &Image, b: &Image) -> Result<Vec<[u8; 3]>, CompareError> {
    check_size(a, b)?;
    Ok(a.pixels
        .par_iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            if !(p.is_finite() && q.is_finite()) {
                return EXCLUDED_COLOUR;
            }
            let (p, q) = (p.to_array(), q.to_array());
            std::array::from_fn(|c| 255 - srgb8(p[c]).abs_diff(srgb8(q[c])))
        })
        .collect())
}

/// [`negative_difference`] as a linear image whose PNG (exposure 0) holds exactly those
/// 8-bit codes.
pub fn negative_difference_image(a: &Image, b: &Image) -> Result<Image, CompareError> {
    let codes = negative_difference(a, b)?;
    Ok(Image {
        width: a.width,
        height: a.height,
        pixels: codes
            .into_iter()
            .map(|c| Vec3::from_array(c.map(linear_from_srgb8)))
            .collect(),
    })
}

fn check_size(a: &Image, b: &Image) -> Result<(), CompareError> {
    Checked::new(&[("reference", a), ("test", b)], NonFinite::Exclude)
        .map(|_| ())
        .or_else(|e| match e {
            // A difference image of two all-NaN images is still a difference image.
            CompareError::NothingLeft => Ok(()),
            e => Err(e),
        })
}

/// Count, means and centred second moments of a set of channel-value pairs.
#[derive(Clone, Copy, Debug, Default)]
struct Moments {
    n: f64,
    mx: f64,
    my: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
}

impl Moments {
    /// The moments of the union of two disjoint sets.
    fn merge(a: Moments, b: Moments) -> Moments {
        if a.n == 0.0 {
            return b;
        }
        if b.n == 0.0 {
            return a;
        }
        let n = a.n + b.n;
        let (dx, dy) = (b.mx - a.mx, b.my - a.my);
        let f = a.n * b.n / n;
        Moments {
            n,
            mx: a.mx + dx * (b.n / n),
            my: a.my + dy * (b.n / n),
            sxx: a.sxx + b.sxx + dx * dx * f,
            syy: a.syy + b.syy + dy * dy * f,
            sxy: a.sxy + b.sxy + dx * dy * f,
        }
    }
}

/// Sums of absolute channel differences of a set of pixels.
#[derive(Clone, Copy, Debug, Default)]
struct AbsSums {
    linear: f64,
    codes: u64,
}

impl Pair<'_> {
    /// The difference image of eq. 18 (`|reference - test|` per channel, linear).
    pub fn difference(&self) -> Image {
        difference(self.reference, self.test).expect("sizes checked")
    }

    /// The per-pixel map of `|D|` averaged over the three channels (linear; NaN where a
    /// pixel is excluded): the `abs` error map.
    pub fn abs_map(&self) -> Vec<f32> {
        (0..self.checked.len())
            .into_par_iter()
            .map(|i| {
                if self.is_used(i) {
                    let d = (self.reference.pixels[i] - self.test.pixels[i]).abs();
                    (d.x + d.y + d.z) / 3.0
                } else {
                    f32::NAN
                }
            })
            .collect()
    }

    fn abs_sums(&self, codes: bool) -> AbsSums {
        let (r, t) = (&self.reference.pixels, &self.test.pixels);
        self.checked.fold(
            AbsSums::default(),
            |acc, i| {
                let d = (r[i] - t[i]).abs().as_dvec3();
                acc.linear += d.x + d.y + d.z;
                if codes {
                    let (p, q) = (r[i].to_array(), t[i].to_array());
                    for c in 0..3 {
                        acc.codes += srgb8(p[c]).abs_diff(srgb8(q[c])) as u64;
                    }
                }
            },
            |a, b| AbsSums {
                linear: a.linear + b.linear,
                codes: a.codes + b.codes,
            },
        )
    }

    /// Mean error of eq. 19 on linear values: the mean of `|D|` over the pixels in use and
    /// the three channels.
    pub fn mean_error(&self) -> f64 {
        self.abs_sums(false).linear / (3 * self.used_pixels()) as f64
    }

    /// Mean error of eq. 19 on the thesis' 8-bit scale (0..255): the mean absolute
    /// difference of the 8-bit sRGB codes ([`srgb8`]) of both images, as between the PNGs
    /// the thesis compared.
    pub fn mean_error_8bit(&self) -> f64 {
        self.abs_sums(true).codes as f64 / (3 * self.used_pixels()) as f64
    }

    /// Pearson's product-moment correlation (eq. 20) over all channel values of the pixels
    /// in use (population form, in f64).
    ///
    /// Defined for constant images: when either image has zero variance the value is 1 if
    /// the two images are identical and 0 otherwise (no linear dependence can be measured).
    /// Identical images always give exactly 1.
    pub fn pearson(&self) -> f64 {
        let (r, t) = (&self.reference.pixels, &self.test.pixels);
        // One pass over memory: centred sums per chunk (two passes over a chunk that stays
        // in cache), merged in order with the pairwise update of Chan, Golub and LeVeque.
        let m = self
            .checked
            .per_chunk(|range| {
                let used = || range.clone().filter(|&i| self.is_used(i));
                let (mut n, mut sx, mut sy) = (0usize, 0.0f64, 0.0f64);
                for i in used() {
                    let (p, q) = (r[i].as_dvec3(), t[i].as_dvec3());
                    n += 3;
                    sx += p.x + p.y + p.z;
                    sy += q.x + q.y + q.z;
                }
                if n == 0 {
                    return Moments::default();
                }
                let (mx, my) = (sx / n as f64, sy / n as f64);
                let mut m = Moments {
                    n: n as f64,
                    mx,
                    my,
                    ..Moments::default()
                };
                for i in used() {
                    let p = r[i].as_dvec3() - mx;
                    let q = t[i].as_dvec3() - my;
                    m.sxx += p.length_squared();
                    m.syy += q.length_squared();
                    m.sxy += p.dot(q);
                }
                m
            })
            .into_iter()
            .fold(Moments::default(), Moments::merge);
        let (sxx, syy, sxy) = (m.sxx, m.syy, m.sxy);
        if sxx == sxy && syy == sxy && sxx > 0.0 {
            // Identical up to a shift: exactly 1 (the formula may round to 1 - 1e-16).
            return 1.0;
        }
        let denominator = sxx.sqrt() * syy.sqrt();
        if sxx == 0.0 || syy == 0.0 || denominator == 0.0 || !denominator.is_finite() {
            return if self.identical() { 1.0 } else { 0.0 };
        }
        (sxy / denominator).clamp(-1.0, 1.0)
    }

    /// Whether every used pixel is equal in both images.
    fn identical(&self) -> bool {
        let (r, t) = (&self.reference.pixels, &self.test.pixels);
        (0..self.checked.len())
            .into_par_iter()
            .all(|i| !self.is_used(i) || r[i] == t[i])
    }
}

/// Mean error (eq. 19, linear) of two images; refuses non-finite values.
pub fn mean_error(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.mean_error())
}

/// Mean error (eq. 19) on the 8-bit sRGB scale; refuses non-finite values.
pub fn mean_error_8bit(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.mean_error_8bit())
}

/// Pearson's correlation (eq. 20); refuses non-finite values. See [`Pair::pearson`] for the
/// value given to constant images.
pub fn pearson(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.pearson())
}

/// The quality comparison on one scale (linear values or 8-bit sRGB codes).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct QualityOnScale {
    /// Mean error (eq. 19) of image 1 against the model, `ε01`.
    pub mean_error_1: f64,
    /// Mean error of image 2 against the model, `ε02`.
    pub mean_error_2: f64,
    /// The quality function of eq. 21: `1` when image 1 is closer to the model
    /// (`ε01 < ε02`), `-1` when image 2 is closer, `0` when the errors are equal (exact
    /// comparison of the f64 sums: identical errors, or equal 8-bit sums).
    pub f_q: i8,
    /// Relative error reduction of image 2 over image 1, `(ε01 - ε02) / ε01` (the thesis'
    /// "quality gain"; `None` when `ε01 = 0`).
    pub gain: Option<f64>,
    /// Pixels of image 2 strictly closer to the model than image 1's (per-pixel distance:
    /// the sum over channels of `|D|`).
    pub closer: usize,
    /// Pixels of image 2 strictly farther from the model than image 1's.
    pub farther: usize,
    /// Pixels at equal distance.
    pub equal: usize,
}

impl QualityOnScale {
    /// Share of compared pixels where image 2 is closer to the model (the thesis' "99.05%
    /// of pixels improved").
    pub fn share_closer(&self) -> f64 {
        self.closer as f64 / (self.closer + self.farther + self.equal).max(1) as f64
    }
}

/// The quality function of eq. 21 and the pixel-level comparison of two images against a
/// model image, on linear values and on 8-bit sRGB codes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Quality {
    /// On linear values.
    pub linear: QualityOnScale,
    /// On 8-bit sRGB codes (what the thesis compared).
    pub srgb8: QualityOnScale,
    /// Pixels compared.
    pub pixels: usize,
    /// Pixels left out for non-finite values.
    pub excluded: usize,
}

#[derive(Clone, Copy, Default)]
struct QualitySums {
    e1: f64,
    e2: f64,
    c1: u64,
    c2: u64,
    counts: [usize; 3],
    counts8: [usize; 3],
}

/// Which of `image1` and `image2` is closer to `model` (eq. 21), with the pixel-level
/// comparison; refuses non-finite values.
///
/// ```
/// use imalyzer::quality;
/// use imalyzer::scene_core::{Image, glam::Vec3};
///
/// let model = Image::filled(2, 1, Vec3::splat(0.5));
/// let far = Image::filled(2, 1, Vec3::splat(0.2));
/// let near = Image::filled(2, 1, Vec3::splat(0.4));
/// let q = quality(&model, &far, &near).unwrap();
/// assert_eq!(q.linear.f_q, -1); // image 2 is closer
/// assert_eq!(q.linear.share_closer(), 1.0);
/// ```
pub fn quality(model: &Image, image1: &Image, image2: &Image) -> Result<Quality, CompareError> {
    quality_with(model, image1, image2, NonFinite::Reject)
}

/// [`quality`] under a [`NonFinite`] policy.
pub fn quality_with(
    model: &Image,
    image1: &Image,
    image2: &Image,
    policy: NonFinite,
) -> Result<Quality, CompareError> {
    let checked = Checked::new(
        &[("model", model), ("image 1", image1), ("image 2", image2)],
        policy,
    )?;
    let (m, a, b) = (&model.pixels, &image1.pixels, &image2.pixels);
    let s = checked.fold(
        QualitySums::default(),
        |acc, i| {
            let d1 = (m[i] - a[i]).abs().as_dvec3();
            let d2 = (m[i] - b[i]).abs().as_dvec3();
            let (l1, l2) = (d1.x + d1.y + d1.z, d2.x + d2.y + d2.z);
            acc.e1 += l1;
            acc.e2 += l2;
            acc.counts[rank(l2.partial_cmp(&l1))] += 1;
            let (pm, pa, pb) = (m[i].to_array(), a[i].to_array(), b[i].to_array());
            let (mut c1, mut c2) = (0u64, 0u64);
            for c in 0..3 {
                let cm = srgb8(pm[c]);
                c1 += cm.abs_diff(srgb8(pa[c])) as u64;
                c2 += cm.abs_diff(srgb8(pb[c])) as u64;
            }
            acc.c1 += c1;
            acc.c2 += c2;
            acc.counts8[rank(c2.partial_cmp(&c1))] += 1;
        },
        |x, y| QualitySums {
            e1: x.e1 + y.e1,
            e2: x.e2 + y.e2,
            c1: x.c1 + y.c1,
            c2: x.c2 + y.c2,
            counts: std::array::from_fn(|k| x.counts[k] + y.counts[k]),
            counts8: std::array::from_fn(|k| x.counts8[k] + y.counts8[k]),
        },
    );
    let n = (3 * checked.used) as f64;
    let scale = |e1: f64, e2: f64, counts: [usize; 3]| QualityOnScale {
        mean_error_1: e1 / n,
        mean_error_2: e2 / n,
        f_q: match e1.partial_cmp(&e2) {
            Some(std::cmp::Ordering::Less) => 1,
            Some(std::cmp::Ordering::Greater) => -1,
            _ => 0,
        },
        gain: (e1 > 0.0).then(|| (e1 - e2) / e1),
        closer: counts[0],
        farther: counts[2],
        equal: counts[1],
    };
    Ok(Quality {
        linear: scale(s.e1, s.e2, s.counts),
        srgb8: scale(s.c1 as f64, s.c2 as f64, s.counts8),
        pixels: checked.used,
        excluded: checked.len() - checked.used,
    })
}

/// 0 = closer, 1 = equal, 2 = farther.
fn rank(o: Option<std::cmp::Ordering>) -> usize {
    match o {
        Some(std::cmp::Ordering::Less) => 0,
        Some(std::cmp::Ordering::Greater) => 2,
        _ => 1,
    }
}
