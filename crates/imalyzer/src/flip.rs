//! FLIP (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström and Fairchild 2020, "FLIP: A
//! Difference Evaluator for Alternating Images") and HDR-FLIP (Andersson et al. 2021,
//! "Visualizing Errors in Rendered High Dynamic Range Images"), written from the papers.
//!
//! **LDR-FLIP** compares two images as a viewer at [`FlipOptions::ppd`] pixels per degree
//! sees them when flipping between them:
//!
//! 1. *Colour pipeline.* Both images go to the opponent space YyCxCz (linear in XYZ
//!    relative to the D65 white of sRGB: `Yy = 116 Y - 16`, `Cx = 500 (X - Y)`,
//!    `Cz = 200 (Y - Z)`), each channel is filtered by its contrast sensitivity function
//!    (a Gaussian in the spatial domain for the achromatic and red-green channels, a sum
//!    of two for blue-yellow), and the result returns to linear RGB, is clamped to
//!    [0, 1], and goes to CIELAB with Hunt's adjustment (`a, b` scaled by `0.01 L`). The
//!    colour difference is the HyAB distance `|dL| + sqrt(da^2 + db^2)` raised to
//!    `q_c = 0.7` and remapped so that the largest difference (green against blue) is 1,
//!    with the lower 40% of that range compressed into [0, 0.95).
//! 2. *Feature pipeline.* On the normalised achromatic channel `(Yy + 16) / 116` of the
//!    unfiltered images, edges are the first and points the second derivatives of a
//!    Gaussian of standard deviation `0.5 * 0.082` degrees (weights normalised so that
//!    positive ones sum to 1 and negative ones to -1). The feature difference is
//!    `(max(| |e1| - |e2| |, | |p1| - |p2| |) / sqrt 2)^0.5` (`q_f = 0.5`).
//! 3. The error is `dE_c^(1 - dE_f)`, in [0, 1]; its mean over the pixels is FLIP.
//!
//! Filters repeat the edge pixels outside the image. LDR inputs are linear RGB (the sRGB
//! decoding of an 8-bit file happens when it is read) clamped to [0, 1].
//!
//! **HDR-FLIP** tone-maps both images with the ACES curve fitted by Narkowicz
//! (`t(x) = (0.9036 x^2 + 0.018 x) / (0.8748 x^2 + 0.354 x + 0.14)`, clamped to [0, 1]) at
//! exposures `2^c` for `c` evenly spaced from `c_start` to `c_stop`, computes LDR-FLIP at
//! each, and keeps the largest error per pixel. Unless given, `c_start = log2(x85 /
//! Y_max)` and `c_stop = log2(x85 / Y_median)`, where `t(x85) = 0.85`, `Y` is the
//! luminance `0.2126 R + 0.7152 G + 0.0722 B` of the reference, `Y_median` is the element at rank
//! `floor(n / 2)` of the sorted luminances and both are at least `f32::EPSILON`; the number
//! of exposures is `max(2, ceil(c_stop - c_start))`. Negative inputs are clamped to 0.

use std::f32::consts::PI;
use std::sync::OnceLock;

use rayon::prelude::*;
use scene_core::Image;
use scene_core::glam::{DMat3, DVec3, Mat3, Vec3};

use crate::error::CompareError;
use crate::filter::{Border, horizontal, separable, vertical};
use crate::input::Pair;

/// Pixels per degree of the default viewer: a 0.7 m wide monitor with 3840 pixels across,
/// 0.7 m away (about 67.02).
pub const DEFAULT_PPD: f32 = (0.7 * (3840.0 / 0.7) * std::f64::consts::PI / 180.0) as f32;

/// Exponent of the colour difference, `q_c`.
const QC: f32 = 0.7;
/// Share of the largest colour difference below which differences are compressed, `p_c`.
const PC: f32 = 0.4;
/// The error that share maps to, `p_t`.
const PT: f32 = 0.95;
/// Width of the feature detectors, in degrees.
const FEATURE_WIDTH: f32 = 0.082;
/// Tone-mapped value the brightest (start) and median (stop) luminance map to.
const EXPOSURE_TARGET: f64 = 0.85;

/// The contrast sensitivity function of one opponent channel in the spatial domain:
/// `a1 sqrt(pi / b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi / b2) exp(-pi^2 x^2 / b2)`, with `x` in
/// degrees.
#[derive(Clone, Copy)]
struct Csf {
    a1: f32,
    b1: f32,
    a2: f32,
    b2: f32,
}

/// Achromatic, red-green and blue-yellow channels (the paper's table of CSF parameters).
const CSF: [Csf; 3] = [
    Csf {
        a1: 1.0,
        b1: 0.0047,
        a2: 0.0,
        b2: 1e-5,
    },
    Csf {
        a1: 1.0,
        b1: 0.0053,
        a2: 0.0,
        b2: 1e-5,
    },
    Csf {
        a1: 34.1,
        b1: 0.04,
        a2: 13.5,
        b2: 0.025,
    },
];

/// ACES filmic curve of Narkowicz with its 0.6 pre-exposure folded in:
/// `(a x^2 + b x + c) / (d x^2 + e x + f)`.
const ACES: [f64; 6] = [
    0.6 * 0.6 * 2.51,
    0.6 * 0.03,
    0.0,
    0.6 * 0.6 * 2.43,
    0.6 * 0.59,
    0.14,
];

/// Settings of FLIP.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlipOptions {
    /// Pixels per degree of visual angle of the viewer ([`DEFAULT_PPD`]).
    pub ppd: f32,
    /// HDR-FLIP: first exposure `c_start` (stops); computed from the reference when `None`.
    pub start_exposure: Option<f32>,
    /// HDR-FLIP: last exposure `c_stop` (stops); computed from the reference when `None`.
    pub stop_exposure: Option<f32>,
    /// HDR-FLIP: number of exposures; `max(2, ceil(c_stop - c_start))` when `None`.
    pub exposures: Option<usize>,
}

impl Default for FlipOptions {
    fn default() -> Self {
        Self {
            ppd: DEFAULT_PPD,
            start_exposure: None,
            stop_exposure: None,
            exposures: None,
        }
    }
}

/// The outcome of FLIP.
#[derive(Clone, Debug, PartialEq)]
pub struct Flip {
    /// Mean error over the pixels in use, in [0, 1]; 0 for identical images.
    pub mean: f64,
    /// Error per pixel, row-major, in [0, 1] (NaN where a pixel is excluded).
    pub map: Vec<f32>,
    /// HDR-FLIP only: the exposures (stops) evaluated, from `c_start` to `c_stop`.
    pub exposures: Vec<f32>,
}

/// Colour-space constants derived once from the sRGB primaries and the D65 white point.
struct Colour {
    /// Linear RGB to XYZ relative to the white point (`X / Xw, Y / Yw, Z / Zw`).
    rgb_to_xyz_w: Mat3,
    /// The inverse.
    xyz_w_to_rgb: Mat3,
    /// The largest colour difference, HyAB(green, blue)^q_c in Hunt-adjusted CIELAB.
    cmax: f32,
}

/// The sRGB-to-XYZ matrix from the chromaticities of the sRGB primaries (0.64, 0.33),
/// (0.30, 0.60), (0.15, 0.06) and of D65 (0.3127, 0.3290), so that RGB white maps to the
/// white point with Y = 1.
fn srgb_to_xyz() -> DMat3 {
    let xyz = |x: f64, y: f64| DVec3::new(x / y, 1.0, (1.0 - x - y) / y);
    let primaries = DMat3::from_cols(xyz(0.64, 0.33), xyz(0.30, 0.60), xyz(0.15, 0.06));
    let scale = primaries.inverse() * xyz(0.3127, 0.3290);
    DMat3::from_cols(
        primaries.x_axis * scale.x,
        primaries.y_axis * scale.y,
        primaries.z_axis * scale.z,
    )
}

fn colour() -> &'static Colour {
    static C: OnceLock<Colour> = OnceLock::new();
    C.get_or_init(|| {
        let m = srgb_to_xyz();
        // Fold the division by the white point into the matrices (in f64).
        let white = m * DVec3::ONE;
        let relative = DMat3::from_diagonal(white.recip()) * m;
        let mut c = Colour {
            rgb_to_xyz_w: relative.as_mat3(),
            xyz_w_to_rgb: relative.inverse().as_mat3(),
            cmax: 0.0,
        };
        let green = c.hunt_lab(Vec3::Y);
        let blue = c.hunt_lab(Vec3::Z);
        c.cmax = hyab(green, blue).powf(QC);
        c
    })
}

impl Colour {
    /// Linear RGB to YyCxCz.
    #[inline]
    fn ycxcz(&self, rgb: Vec3) -> Vec3 {
        let v = self.rgb_to_xyz_w * rgb;
        Vec3::new(116.0 * v.y - 16.0, 500.0 * (v.x - v.y), 200.0 * (v.y - v.z))
    }

    /// YyCxCz to linear RGB.
    #[inline]
    fn rgb_from_ycxcz(&self, c: Vec3) -> Vec3 {
        let y = (c.x + 16.0) * (1.0 / 116.0);
        let v = Vec3::new(c.y * (1.0 / 500.0) + y, y, y - c.z * (1.0 / 200.0));
        self.xyz_w_to_rgb * v
    }

    /// Linear RGB to CIELAB with Hunt's adjustment of the chroma (`a, b` times `0.01 L`).
    #[inline]
    fn hunt_lab(&self, rgb: Vec3) -> Vec3 {
        const D: f32 = 6.0 / 29.0;
        let f = |t: f32| {
            if t > D * D * D {
                t.cbrt()
            } else {
                t * (1.0 / (3.0 * D * D)) + 4.0 / 29.0
            }
        };
        let v = self.rgb_to_xyz_w * rgb;
        let (fx, fy, fz) = (f(v.x), f(v.y), f(v.z));
        let l = 116.0 * fy - 16.0;
        let hunt = 0.01 * l;
        Vec3::new(l, hunt * 500.0 * (fx - fy), hunt * 200.0 * (fy - fz))
    }
}

/// HyAB distance: `|dL| + sqrt(da^2 + db^2)`.
#[inline]
fn hyab(p: Vec3, q: Vec3) -> f32 {
    let d = p - q;
    d.x.abs() + (d.y * d.y + d.z * d.z).sqrt()
}

/// A 1D kernel from a profile over `-r..=r`.
fn kernel(r: usize, f: impl Fn(f32) -> f32) -> Vec<f32> {
    (0..=2 * r).map(|i| f(i as f32 - r as f32)).collect()
}

fn normalised(mut k: Vec<f32>) -> Vec<f32> {
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k
}

/// Scales positive weights to sum to 1 and negative ones to sum to -1.
fn balanced(mut k: Vec<f32>) -> Vec<f32> {
    let pos: f32 = k.iter().filter(|v| **v > 0.0).sum();
    let neg: f32 = -k.iter().filter(|v| **v < 0.0).sum::<f32>();
    k.iter_mut().for_each(|v| {
        if *v > 0.0 {
            *v /= pos
        } else if *v < 0.0 {
            *v /= neg
        }
    });
    k
}

/// The filters of one viewing distance.
struct Filters {
    /// Per opponent channel: (weight, 1D kernel) terms, each applied separably; the
    /// weights sum to 1, so each channel's 2D filter sums to 1.
    csf: [Vec<(f32, Vec<f32>)>; 3],
    /// Normalised Gaussian of the feature detectors.
    gauss: Vec<f32>,
    /// Its first derivative (edges).
    edge: Vec<f32>,
    /// Its second derivative (points).
    point: Vec<f32>,
}

impl Filters {
    fn new(ppd: f32) -> Self {
        // CSF: one radius for all channels, three standard deviations of the widest term.
        let b_max = CSF.iter().flat_map(|c| [c.b1, c.b2]).fold(0.0f32, f32::max);
        let r = (3.0 * (b_max / (2.0 * PI * PI)).sqrt() * ppd).ceil() as usize;
        let dx = 1.0 / ppd;
        let csf = CSF.map(|c| {
            let terms: Vec<(f32, Vec<f32>)> = [(c.a1, c.b1), (c.a2, c.b2)]
                .into_iter()
                .filter(|&(a, _)| a > 0.0)
                .map(|(a, b)| {
                    let g = kernel(r, |x| (-PI * PI * (x * dx) * (x * dx) / b).exp());
                    let sum: f32 = g.iter().sum();
                    // This term's share of the 2D filter's total weight.
                    (a * (PI / b).sqrt() * sum * sum, normalised(g))
                })
                .collect();
            let total: f32 = terms.iter().map(|t| t.0).sum();
            terms.into_iter().map(|(w, k)| (w / total, k)).collect()
        });
        let sigma = 0.5 * FEATURE_WIDTH * ppd;
        let r = (3.0 * sigma).ceil() as usize;
        let g = |x: f32| (-x * x / (2.0 * sigma * sigma)).exp();
        Self {
            csf,
            gauss: normalised(kernel(r, g)),
            edge: balanced(kernel(r, |x| -x * g(x))),
            point: balanced(kernel(r, |x| (x * x / (sigma * sigma) - 1.0) * g(x))),
        }
    }
}

/// What the error needs of one image: its filtered Hunt-Lab colour and its feature
/// magnitudes.
struct Prepared {
    lab: Vec<Vec3>,
    edge: Vec<f32>,
    point: Vec<f32>,
}

fn prepare(rgb: &[Vec3], w: usize, filters: &Filters) -> Prepared {
    let c = colour();
    let ycc: Vec<Vec3> = rgb.par_iter().map(|&p| c.ycxcz(p)).collect();
    let planes: [Vec<f32>; 3] =
        std::array::from_fn(|ch| ycc.par_iter().map(|v| v[ch]).collect::<Vec<f32>>());
    let filtered: [Vec<f32>; 3] = std::array::from_fn(|ch| {
        let mut out = vec![0.0f32; rgb.len()];
        for (weight, k) in &filters.csf[ch] {
            let f = separable(&planes[ch], w, k, k, Border::Clamp);
            out.par_iter_mut()
                .zip(&f)
                .for_each(|(o, v)| *o += weight * v);
        }
        out
    });
    let lab: Vec<Vec3> = (0..rgb.len())
        .into_par_iter()
        .map(|i| {
            let v = Vec3::new(filtered[0][i], filtered[1][i], filtered[2][i]);
            c.hunt_lab(c.rgb_from_ycxcz(v).clamp(Vec3::ZERO, Vec3::ONE))
        })
        .collect();
    let gray: Vec<f32> = planes[0]
        .par_iter()
        .map(|y| (y + 16.0) * (1.0 / 116.0))
        .collect();
    let along_g = horizontal(&gray, w, &filters.gauss, Border::Clamp);
    let along_e = horizontal(&gray, w, &filters.edge, Border::Clamp);
    let along_p = horizontal(&gray, w, &filters.point, Border::Clamp);
    let ex = vertical(&along_e, w, &filters.gauss, Border::Clamp);
    let ey = vertical(&along_g, w, &filters.edge, Border::Clamp);
    let px = vertical(&along_p, w, &filters.gauss, Border::Clamp);
    let py = vertical(&along_g, w, &filters.point, Border::Clamp);
    let magnitude = |a: &[f32], b: &[f32]| -> Vec<f32> {
        a.par_iter()
            .zip(b)
            .map(|(x, y)| (x * x + y * y).sqrt())
            .collect()
    };
    Prepared {
        lab,
        edge: magnitude(&ex, &ey),
        point: magnitude(&px, &py),
    }
}

/// The LDR-FLIP map of two linear RGB rasters already in [0, 1].
fn ldr_map(reference: &[Vec3], test: &[Vec3], w: usize, filters: &Filters) -> Vec<f32> {
    let (r, t) = rayon::join(
        || prepare(reference, w, filters),
        || prepare(test, w, filters),
    );
    let cmax = colour().cmax;
    (0..reference.len())
        .into_par_iter()
        .map(|i| {
            let d = hyab(r.lab[i], t.lab[i]).powf(QC);
            let colour = if d < PC * cmax {
                d * PT / (PC * cmax)
            } else {
                PT + (d - PC * cmax) / (cmax - PC * cmax) * (1.0 - PT)
            };
            let edge = (r.edge[i] - t.edge[i]).abs();
            let point = (r.point[i] - t.point[i]).abs();
            // q_f = 0.5: a square root.
            let feature = (edge.max(point) / std::f32::consts::SQRT_2).sqrt();
            colour.powf(1.0 - feature)
        })
        .collect()
}

/// ACES tone mapping of one channel, clamped to [0, 1].
fn tone_map(x: f32) -> f32 {
    let [a, b, c, d, e, f] = ACES.map(|v| v as f32);
    // Beyond 1e15 the curve is flat at a / d > 1 (clamped to 1); x^2 must not overflow.
    let x = x.min(1e15);
    ((x * (a * x + b) + c) / (x * (d * x + e) + f)).clamp(0.0, 1.0)
}

/// The exposure `x` the tone mapper takes to [`EXPOSURE_TARGET`] (the positive root of
/// `t(x) = 0.85`).
fn exposure_at_target() -> f64 {
    let [a, b, c, d, e, f] = ACES;
    let (qa, qb, qc) = (
        a - EXPOSURE_TARGET * d,
        b - EXPOSURE_TARGET * e,
        c - EXPOSURE_TARGET * f,
    );
    (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa)
}

impl Pair<'_> {
    fn flip_check(&self, options: &FlipOptions) -> Result<Filters, CompareError> {
        if !(options.ppd > 0.0 && options.ppd.is_finite() && options.ppd < 1e4) {
            return Err(CompareError::InvalidArgument(format!(
                "FLIP pixels per degree must be in (0, 10000), got {}",
                options.ppd
            )));
        }
        Ok(Filters::new(options.ppd))
    }

    fn pooled(&self, map: Vec<f32>, exposures: Vec<f32>) -> Flip {
        let map: Vec<f32> = map
            .into_iter()
            .enumerate()
            .map(|(i, v)| if self.is_used(i) { v } else { f32::NAN })
            .collect();
        let sum = self
            .checked
            .fold(0.0f64, |acc, i| *acc += map[i] as f64, |a, b| a + b);
        Flip {
            mean: sum / self.used_pixels() as f64,
            map,
            exposures,
        }
    }

    /// LDR-FLIP with the default viewer (67 pixels per degree).
    pub fn flip(&self) -> Flip {
        self.flip_with(&FlipOptions::default())
            .expect("the default options are valid")
    }

    /// LDR-FLIP with `options` (the exposure fields are ignored). Linear values are clamped
    /// to [0, 1].
    pub fn flip_with(&self, options: &FlipOptions) -> Result<Flip, CompareError> {
        let filters = self.flip_check(options)?;
        let (a, b) = self.filled_for_filters();
        let clamp = |v: Vec<Vec3>| -> Vec<Vec3> {
            v.into_par_iter()
                .map(|p| p.clamp(Vec3::ZERO, Vec3::ONE))
                .collect()
        };
        let map = ldr_map(&clamp(a), &clamp(b), self.width() as usize, &filters);
        Ok(self.pooled(map, Vec::new()))
    }

    /// HDR-FLIP with the default viewer and exposures computed from the reference.
    pub fn hdr_flip(&self) -> Flip {
        self.hdr_flip_with(&FlipOptions::default())
            .expect("the default options are valid")
    }

    /// The exposure range HDR-FLIP uses: `(c_start, c_stop, count)`.
    pub fn hdr_exposures(&self, options: &FlipOptions) -> Result<(f32, f32, usize), CompareError> {
        // Rec. 709 luminance with its customary rounded weights (flip-evaluator's).
        // (in f64: values near f32::MAX must not overflow to infinity).
        let lum_row = DVec3::new(0.2126, 0.7152, 0.0722);
        let mut lum: Vec<f64> = (0..self.checked.len())
            .filter(|&i| self.is_used(i))
            .map(|i| lum_row.dot(self.reference.pixels[i].max(Vec3::ZERO).as_dvec3()))
            .collect();
        let mid = lum.len() / 2;
        let (_, &mut median, _) = lum.select_nth_unstable_by(mid, f64::total_cmp);
        let max = lum.iter().copied().fold(0.0f64, f64::max);
        let x85 = exposure_at_target();
        let eps = f32::EPSILON as f64;
        // What a user sets has a stated range, checked before any exposure is evaluated.
        for (what, v) in [
            ("HDR-FLIP start exposure", options.start_exposure),
            ("HDR-FLIP stop exposure", options.stop_exposure),
        ] {
            scene_core::range::check_opt(what, v, -64.0..=64.0)
                .map_err(|e| CompareError::InvalidArgument(e.to_string()))?;
        }
        scene_core::range::check_opt("HDR-FLIP exposures", options.exposures, 1..=64)
            .map_err(|e| CompareError::InvalidArgument(e.to_string()))?;
        let start = options
            .start_exposure
            .unwrap_or((x85 / max.max(eps)).log2() as f32);
        let stop = options
            .stop_exposure
            .unwrap_or((x85 / median.max(eps)).log2() as f32);
        if !(start.is_finite() && stop.is_finite() && start <= stop) {
            return Err(CompareError::InvalidArgument(format!(
                "HDR-FLIP exposures must be finite with start <= stop, got {start} and {stop}"
            )));
        }
        let count = match options.exposures {
            Some(0) => {
                return Err(CompareError::InvalidArgument(
                    "HDR-FLIP needs at least one exposure".into(),
                ));
            }
            Some(n) => n,
            None => ((stop - start).ceil() as usize).max(2),
        };
        Ok((start, stop, count))
    }

    /// HDR-FLIP with `options`: the largest LDR-FLIP error over exposures. When `c_start`
    /// equals `c_stop` (a black reference gives both from `f32::EPSILON`), every exposure
    /// is the same and one is evaluated.
    pub fn hdr_flip_with(&self, options: &FlipOptions) -> Result<Flip, CompareError> {
        let filters = self.flip_check(options)?;
        let (start, stop, count) = self.hdr_exposures(options)?;
        let count = if start == stop { 1 } else { count };
        let step = if count > 1 {
            (stop - start) / (count - 1) as f32
        } else {
            0.0
        };
        let exposures: Vec<f32> = (0..count).map(|i| start + i as f32 * step).collect();
        let (a, b) = self.filled_for_filters();
        let w = self.width() as usize;
        let mut map = vec![0.0f32; a.len()];
        for &c in &exposures {
            let scale = c.exp2();
            let expose = |v: &[Vec3]| -> Vec<Vec3> {
                v.par_iter()
                    .map(|p| (p.max(Vec3::ZERO) * scale).map(tone_map))
                    .collect()
            };
            let m = ldr_map(&expose(&a), &expose(&b), w, &filters);
            map.par_iter_mut().zip(&m).for_each(|(o, v)| *o = o.max(*v));
        }
        Ok(self.pooled(map, exposures))
    }
}

/// Mean LDR-FLIP of two images (default viewer); refuses non-finite values.
pub fn flip(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.flip().mean)
}

/// Mean HDR-FLIP of two images (default viewer and exposures); refuses non-finite values.
pub fn hdr_flip(reference: &Image, test: &Image) -> Result<f64, CompareError> {
    Ok(Pair::new(reference, test)?.hdr_flip().mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_matrix_maps_white_to_d65_and_primaries_to_known_luminances() {
        let m = srgb_to_xyz();
        let white = m * DVec3::ONE;
        assert!((white.y - 1.0).abs() < 1e-12);
        assert!((white.x - 0.3127 / 0.3290).abs() < 1e-12);
        // The Y row is the Rec. 709 luminance 0.2126, 0.7152, 0.0722.
        let y = m.row(1);
        assert!((y - DVec3::new(0.2126, 0.7152, 0.0722)).abs().max_element() < 1e-4);
    }

    #[test]
    fn colour_round_trips_and_white_is_lab_100() {
        let c = colour();
        let p = Vec3::new(0.2, 0.5, 0.9);
        assert!((c.rgb_from_ycxcz(c.ycxcz(p)) - p).abs().max_element() < 1e-5);
        let white = c.hunt_lab(Vec3::ONE);
        assert!((white - Vec3::new(100.0, 0.0, 0.0)).abs().max_element() < 1e-3);
        // Green against blue is the largest difference; it is a fixed number.
        assert!(c.cmax > 10.0 && c.cmax < 100.0, "{}", c.cmax);
    }

    #[test]
    fn filters_sum_as_documented() {
        let f = Filters::new(DEFAULT_PPD);
        for ch in &f.csf {
            let total: f32 = ch
                .iter()
                .map(|(w, k)| w * k.iter().sum::<f32>().powi(2))
                .sum();
            assert!((total - 1.0).abs() < 1e-5);
            // Radius 10 at 67 ppd (three standard deviations of the widest term).
            assert_eq!(ch[0].1.len(), 21);
        }
        assert_eq!(f.csf[2].len(), 2);
        assert_eq!(f.gauss.len(), 19);
        for k in [&f.edge, &f.point] {
            let pos: f32 = k.iter().filter(|v| **v > 0.0).sum();
            let neg: f32 = k.iter().filter(|v| **v < 0.0).sum();
            assert!((pos - 1.0).abs() < 1e-5 && (neg + 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn tone_mapper_hits_its_target() {
        let x = exposure_at_target();
        assert!((tone_map(x as f32) - 0.85).abs() < 1e-5);
        assert_eq!(tone_map(0.0), 0.0);
        assert!(tone_map(1e30) <= 1.0);
    }
}
