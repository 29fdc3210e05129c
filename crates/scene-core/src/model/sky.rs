//! The sky: radiance arriving from infinitely far away, by direction, that lights a scene
//! through its openings (a courtyard, a window).
//!
//! A [`Sky`] is an equirectangular (latitude-longitude) map of radiance, +Y up: a uniform
//! sky ([`Sky::uniform`]) is a constant over the upper hemisphere and black below the
//! horizon; an environment map ([`Sky::from_image`]) is an EXR as it is read. Pixel `(x, y)`
//! of a `w x h` map covers the polar angles (from +Y) `theta` in `[y, y+1] pi / h` and the
//! azimuths `phi` in `[x, x+1] 2 pi / w`, where a direction is
//! `(sin theta sin phi, cos theta, -sin theta cos phi)`: the map's centre column looks
//! along -Z, glTF's forward. Lookups are nearest-pixel, so the map is exactly the
//! piecewise-constant function that [`Sky::sample`] draws from.
//!
//! The sky is one light source ([`crate::LightId::Sky`]): its light state recolours, dims
//! or switches it like any other light. It lights surfaces; it is not drawn as a
//! background (a pixel that sees no surface stays black in every method, the reference
//! included).
//!
//! How methods carry it:
//! - The reference path tracer integrates it exactly: next-event estimation that draws
//!   directions from the map (by each pixel's power, [`Sky::sample`]), weighted by multiple
//!   importance sampling against the cosine-weighted bounce that escapes the scene; a
//!   [`Sky::is_uniform`] sky is found by that bounce alone, which samples it as well.
//! - Every other method sees it as a set of directional lights ([`Sky::lights`]) found by
//!   the median cut of Debevec ("A median cut algorithm for light probe sampling", 2005):
//!   the map is split into regions of equal power, each becoming one directional light
//!   along the region's mean direction. Each light's irradiance is the length of the
//!   region's vector irradiance `sum L dw d`, so that a surface that sees the whole region
//!   above its horizon receives exactly the region's light. The count is the sky's
//!   [`Sky::directions`] (default [`DEFAULT_DIRECTIONS`]).

use glam::{DVec3, Vec3};

use crate::error::SceneError;
use crate::image::Image;
use crate::scene::{DirectionalLight, RADIOMETRIC_MAX};

/// Directional lights a sky becomes for the methods that do not integrate it
/// ([`Sky::lights`]) unless set otherwise.
pub const DEFAULT_DIRECTIONS: u32 = 64;

/// The most directional lights a sky may ask for.
pub const MAX_DIRECTIONS: u32 = 1024;

/// The map a uniform sky is held in: fine enough for the median cut to find
/// [`DEFAULT_DIRECTIONS`] regions, small enough to cost nothing.
const UNIFORM_MAP: (u32, u32) = (128, 64);

/// Radiance from infinitely far away, by direction (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// Name, used in messages (the file's, or "uniform sky").
    pub name: String,
    width: u32,
    height: u32,
    radiance: Vec<Vec3>,
    directions: u32,
    /// Derived: the median-cut directional lights.
    lights: Vec<DirectionalLight>,
    /// Derived: each light's region of the map, pixels `[x0, y0, x1, y1)`.
    regions: Vec<[u32; 4]>,
    /// Derived: each light's spread ([`Sky::spreads`]).
    spreads: Vec<f32>,
    /// Derived: cumulative sampling weight (power) per pixel, row-major, ending at 1.
    cdf: Vec<f64>,
    /// Derived: a guide to `cdf` (Chen and Asau's index table): entry `k` of `g` is the first
    /// pixel whose cumulative weight exceeds `k / g` of the total, so a draw starts its
    /// search there instead of bisecting the whole map.
    guide: Vec<u32>,
    /// Derived: `cos(pi y / height)` for `y` in `0..=height`, the polar bounds of the rows
    /// (two cosines per sample before).
    row_cos: Vec<f64>,
}

impl Sky {
    /// A sky of constant `radiance` (linear RGB, W/(m^2 sr)) over the upper hemisphere and
    /// black below the horizon: an unoccluded surface facing up receives `pi * radiance`.
    pub fn uniform(radiance: Vec3) -> Result<Sky, SceneError> {
        let (w, h) = UNIFORM_MAP;
        let pixels = (0..w * h)
            .map(|i| if i / w < h / 2 { radiance } else { Vec3::ZERO })
            .collect();
        Sky::from_map("uniform sky", w, h, pixels, DEFAULT_DIRECTIONS)
    }

    /// A sky from an equirectangular image (an EXR's linear radiance as read).
    pub fn from_image(name: &str, image: &Image) -> Result<Sky, SceneError> {
        Sky::from_map(
            name,
            image.width,
            image.height,
            image.pixels.clone(),
            DEFAULT_DIRECTIONS,
        )
    }

    /// A sky from `width x height` radiance values (row 0 at the zenith) that becomes
    /// `directions` directional lights. Refuses an empty map, a size that does not match,
    /// negative, non-finite or too large radiance ([`RADIOMETRIC_MAX`]), and a count of
    /// directions outside `1..=`[`MAX_DIRECTIONS`], each as [`SceneError::InvalidLight`]
    /// naming the sky and the fault.
    pub fn from_map(
        name: &str,
        width: u32,
        height: u32,
        radiance: Vec<Vec3>,
        directions: u32,
    ) -> Result<Sky, SceneError> {
        let fault = |reason: String| SceneError::InvalidLight {
            light: format!("sky '{name}'"),
            reason,
        };
        if width == 0 || height == 0 || radiance.len() as u64 != width as u64 * height as u64 {
            return Err(fault(format!(
                "a {width}x{height} map with {} values",
                radiance.len()
            )));
        }
        if let Some((i, c)) = radiance.iter().enumerate().find(|(_, c)| {
            !c.is_finite() || c.min_element() < 0.0 || c.max_element() > RADIOMETRIC_MAX
        }) {
            return Err(fault(format!(
                "pixel ({}, {}) has radiance {c}: negative, not finite or above {RADIOMETRIC_MAX:e}",
                i as u32 % width,
                i as u32 / width
            )));
        }
        if !(1..=MAX_DIRECTIONS).contains(&directions) {
            return Err(fault(format!(
                "{directions} directions: give 1 to {MAX_DIRECTIONS}"
            )));
        }
        let (width, height, radiance) = refined(width, height, radiance);
        let mut sky = Sky {
            name: name.to_string(),
            width,
            height,
            radiance,
            directions,
            lights: Vec::new(),
            regions: Vec::new(),
            spreads: Vec::new(),
            cdf: Vec::new(),
            guide: Vec::new(),
            row_cos: (0..=height)
                .map(|y| (std::f64::consts::PI * y as f64 / height as f64).cos())
                .collect(),
        };
        sky.derive();
        Ok(sky)
    }

    /// The same sky as `n` directional lights (errors as [`Sky::from_map`]).
    pub fn with_directions(&self, n: u32) -> Result<Sky, SceneError> {
        Sky::from_map(
            &self.name,
            self.width,
            self.height,
            self.radiance.clone(),
            n,
        )
    }

    /// The sky with every radiance multiplied by `factor` (non-negative, finite).
    pub fn scaled(&self, factor: Vec3) -> Result<Sky, SceneError> {
        Sky::from_map(
            &self.name,
            self.width,
            self.height,
            self.radiance.iter().map(|c| *c * factor).collect(),
            self.directions,
        )
    }

    /// Width and height of the map as held: a map narrower than 16 or lower than 8 pixels,
    /// or of odd height, is held refined by whole factors (the same radiance in every
    /// direction; at most 2^24 pixels) so that the median cut can split it.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The map's radiance values, row-major from the zenith.
    pub fn map(&self) -> &[Vec3] {
        &self.radiance
    }

    /// How many directional lights the sky asks to become.
    pub fn directions(&self) -> u32 {
        self.directions
    }

    /// The median-cut directional lights (at most [`Sky::directions`]; fewer when the map
    /// has fewer lit pixels). Empty for a black sky.
    pub fn lights(&self) -> &[DirectionalLight] {
        &self.lights
    }

    /// Each light's spread ([`Sky::lights`], in order): the tangent of the half-angle of
    /// the cone of directions its region of the map stands for, so that a shadow map can
    /// give the light the penumbra its region casts (a blocker `d` in front of a receiver
    /// blurs its edge over `spread * d` each side). The cone is the one whose mean cosine
    /// to its axis is the region's: a uniform cone of half-angle `a` averages
    /// `(1 + cos a) / 2`, so `cos a = 2 |mean direction| - 1` where the mean direction is
    /// the power-weighted mean of the region's unit directions (the light's irradiance
    /// over its power). At most [`MAX_SPREAD`] (a region as wide as a hemisphere).
    pub fn spreads(&self) -> &[f32] {
        &self.spreads
    }

    /// True when no direction carries light.
    pub fn is_black(&self) -> bool {
        self.cdf.is_empty()
    }

    /// True when the sky is one radiance over the whole upper hemisphere: every pixel of
    /// the rows wholly above the horizon (there must be one) carries the same non-zero
    /// radiance, and every other row is all that radiance or all black ([`Sky::uniform`], or
    /// a constant over the whole sphere). For such a sky, drawing directions from the map
    /// follows a constant, where the cosine-weighted bounce follows the cosine (neither
    /// knows what blocks the sky), so the reference path tracer gives it no next-event
    /// estimate of its own and lets the bounce find it (docs/reference.md, "What it
    /// computes": the same noise for 22 % less time with all bounces on a real interior).
    pub fn is_uniform(&self) -> bool {
        let w = self.width as usize;
        let Some(&l) = self.radiance.first() else {
            return false;
        };
        // Row y ends at polar angle (y + 1) pi / height: wholly above the horizon while
        // that is at most pi / 2.
        let above = self.height as usize / 2;
        above > 0
            && l != Vec3::ZERO
            && self.radiance.chunks(w.max(1)).enumerate().all(|(y, row)| {
                row.iter().all(|c| *c == l) || (y >= above && row.iter().all(|c| *c == Vec3::ZERO))
            })
    }

    /// Radiance arriving from unit direction `towards_sky` (pointing away from the scene).
    pub fn radiance(&self, towards_sky: Vec3) -> Vec3 {
        self.radiance[self.pixel_of(towards_sky)]
    }

    /// A direction towards the sky drawn by power from three uniform numbers (the pixel,
    /// then a uniform point of its patch of sphere), with its solid-angle density and its
    /// radiance; `None` for a black sky.
    pub fn sample(&self, u: Vec3) -> Option<(Vec3, f32, Vec3)> {
        let last = *self.cdf.last()?;
        let pick = (f64::from(u.x) * last).min(last);
        let i = self.pixel_at(pick, last);
        let pdf = self.pixel_pdf(i);
        if !(pdf.is_finite() && pdf > 0.0) {
            return None;
        }
        Some((self.point_in_pixel(i, u).0, pdf, self.radiance[i]))
    }

    /// The first pixel whose cumulative weight exceeds `pick` (the last pixel when none
    /// does): a walk from the guide table's entry for `pick`, back while the pixel before
    /// already exceeds it (rounding can put the entry one past), then on while this one does
    /// not. The same pixel as a search of the whole table, in about one step on average.
    fn pixel_at(&self, pick: f64, last: f64) -> usize {
        let n = self.cdf.len();
        let g = self.guide.len();
        let mut i =
            (self.guide[((pick / last * g as f64) as usize).min(g - 1)] as usize).min(n - 1);
        while i > 0 && self.cdf[i - 1] > pick {
            i -= 1;
        }
        while i < n - 1 && self.cdf[i] <= pick {
            i += 1;
        }
        i
    }

    /// The solid-angle density [`Sky::sample`] draws unit direction `towards_sky` with.
    pub fn pdf(&self, towards_sky: Vec3) -> f32 {
        self.pixel_pdf(self.pixel_of(towards_sky))
    }

    /// [`Sky::radiance`] and [`Sky::pdf`] of one direction, its pixel found once (what a
    /// bounce that leaves the scene needs for its MIS weight).
    pub fn radiance_and_pdf(&self, towards_sky: Vec3) -> (Vec3, f32) {
        let i = self.pixel_of(towards_sky);
        (self.radiance[i], self.pixel_pdf(i))
    }

    /// Per pixel of the map, row-major: its radiance, the solid-angle density
    /// [`Sky::sample`] draws its directions with, and the probability that it picks the
    /// pixel (what a sampler of its own, such as the GPU path tracer's alias table, needs);
    /// empty for a black sky.
    pub fn pixel_table(&self) -> Vec<(Vec3, f32, f64)> {
        let Some(&last) = self.cdf.last() else {
            return Vec::new();
        };
        (0..self.cdf.len())
            .map(|i| {
                let before = if i == 0 { 0.0 } else { self.cdf[i - 1] };
                (
                    self.radiance[i],
                    self.pixel_pdf(i),
                    (self.cdf[i] - before) / last,
                )
            })
            .collect()
    }

    /// The solid-angle density of directions in pixel `i` (0 for a black sky).
    fn pixel_pdf(&self, i: usize) -> f32 {
        let Some(&last) = self.cdf.last() else {
            return 0.0;
        };
        let before = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let (phi0, phi1, c0, c1) = self.bounds(i as u32 % self.width, i as u32 / self.width);
        (((self.cdf[i] - before) / last) / ((phi1 - phi0) * (c0 - c1))) as f32
    }

    /// Irradiance on an unoccluded surface of unit normal `n`, by a sum over the map's
    /// pixels (each integrated exactly where it lies wholly above the surface's horizon):
    /// the analytic check of the other sky integrals.
    pub fn irradiance(&self, n: Vec3) -> Vec3 {
        let n = n.as_dvec3();
        let mut e = DVec3::ZERO;
        for y in 0..self.height {
            for x in 0..self.width {
                let l = self.radiance[(y * self.width + x) as usize];
                if l == Vec3::ZERO {
                    continue;
                }
                let (phi0, phi1, c0, c1) = self.bounds(x, y);
                // A patch wholly above the horizon integrates exactly as one (the cosine is
                // linear in the direction), one wholly below gives nothing: every point is
                // within `r` (half its polar span plus half its azimuth span) of its centre.
                let r = 0.5 * (c1.clamp(-1.0, 1.0).acos() - c0.clamp(-1.0, 1.0).acos())
                    + 0.5 * (phi1 - phi0);
                let (theta_mid, phi_mid) = (
                    0.5 * (c0.clamp(-1.0, 1.0).acos() + c1.clamp(-1.0, 1.0).acos()),
                    0.5 * (phi0 + phi1),
                );
                let centre = DVec3::new(
                    theta_mid.sin() * phi_mid.sin(),
                    theta_mid.cos(),
                    -theta_mid.sin() * phi_mid.cos(),
                );
                let side = n.dot(centre);
                if r < std::f64::consts::FRAC_PI_2 && side.abs() > r.sin() {
                    if side > 0.0 {
                        e += l.as_dvec3() * n.dot(mean_direction(phi0, phi1, c0, c1));
                    }
                    continue;
                }
                // Cut by the horizon: split it finely so that the part below is cut off.
                let k = 8;
                let mut cos_sum = 0.0;
                for i in 0..k {
                    for j in 0..k {
                        let p0 = phi0 + (phi1 - phi0) * i as f64 / k as f64;
                        let p1 = phi0 + (phi1 - phi0) * (i + 1) as f64 / k as f64;
                        let a = c0 + (c1 - c0) * j as f64 / k as f64;
                        let b = c0 + (c1 - c0) * (j + 1) as f64 / k as f64;
                        cos_sum += n.dot(mean_direction(p0, p1, a, b)).max(0.0);
                    }
                }
                e += l.as_dvec3() * cos_sum;
            }
        }
        e.as_vec3()
    }

    /// The pixel index of unit direction `d`.
    fn pixel_of(&self, d: Vec3) -> usize {
        let d = d.as_dvec3();
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let mut phi = d.x.atan2(-d.z);
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        let x = ((phi / std::f64::consts::TAU * self.width as f64) as u32).min(self.width - 1);
        let y = ((theta / std::f64::consts::PI * self.height as f64) as u32).min(self.height - 1);
        (y * self.width + x) as usize
    }

    /// Pixel `(x, y)`'s azimuth range and the cosines of its polar range (top, bottom).
    fn bounds(&self, x: u32, y: u32) -> (f64, f64, f64, f64) {
        let w = self.width as f64;
        let tau = std::f64::consts::TAU;
        (
            tau * x as f64 / w,
            tau * (x + 1) as f64 / w,
            self.row_cos[y as usize],
            self.row_cos[y as usize + 1],
        )
    }

    /// Sampling table and median-cut lights from the map.
    fn derive(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        // Per pixel: sampling weight (power) and vector irradiance sum L dw d, exactly.
        let mut weight = vec![0.0f64; w * h];
        let mut vector = vec![DVec3::ZERO; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let l = self.radiance[i];
                if l == Vec3::ZERO {
                    continue;
                }
                let (phi0, phi1, c0, c1) = self.bounds(x as u32, y as u32);
                let omega = (phi1 - phi0) * (c0 - c1);
                weight[i] = crate::lights::sampling_weight(l) * omega;
                vector[i] = mean_direction(phi0, phi1, c0, c1);
            }
        }
        let mut acc = 0.0;
        let cdf: Vec<f64> = weight
            .iter()
            .map(|v| {
                acc += v;
                acc
            })
            .collect();
        self.cdf = if acc > 0.0 && acc.is_finite() {
            cdf
        } else {
            Vec::new()
        };
        let g = self.cdf.len();
        self.guide = (0..g)
            .map(|k| {
                let at = k as f64 / g as f64 * acc;
                self.cdf.partition_point(|c| *c <= at) as u32
            })
            .collect();
        let cut = if self.cdf.is_empty() {
            Vec::new()
        } else {
            median_cut(self, &weight, &vector)
        };
        self.spreads = cut.iter().map(|(_, _, spread)| *spread).collect();
        (self.lights, self.regions) = cut.into_iter().map(|(l, r, _)| (l, r)).unzip();
    }

    /// A direction within the map region of light `k` ([`Sky::lights`]), drawn by power
    /// from three uniform numbers, with the estimate's weight (radiance times solid angle
    /// over probability, RGB): `weight * f(d)` averages to the region's integral of
    /// `L f dw`, so summing one draw per light estimates the whole sky without bias. A
    /// method that casts its own visibility rays uses it to soften the sharp shadows of
    /// [`Sky::lights`]' fixed directions. `None` for `k` out of range.
    pub fn sample_light(&self, k: usize, u: Vec3) -> Option<(Vec3, Vec3)> {
        let [x0, y0, x1, y1] = *self.regions.get(k)?;
        let w = self.width as usize;
        let before = |i: usize| if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let row = |y: u32| {
            let (a, b) = (y as usize * w + x0 as usize, y as usize * w + x1 as usize);
            (before(a), self.cdf[b - 1])
        };
        let total: f64 = (y0..y1).map(|y| row(y).1 - row(y).0).sum();
        if total <= 0.0 {
            return None;
        }
        // The row, then the pixel in it, by the cumulative weights.
        let mut pick = f64::from(u.x) * total;
        let mut y = y1 - 1;
        for r in y0..y1 {
            let (a, b) = row(r);
            if pick < b - a {
                y = r;
                break;
            }
            pick -= b - a;
        }
        let (a, b) = row(y);
        let target = (a + pick).min(b);
        let lo = y as usize * w + x0 as usize;
        let hi = y as usize * w + x1 as usize;
        let i = (lo + self.cdf[lo..hi].partition_point(|c| *c <= target)).min(hi - 1);
        let p = (self.cdf[i] - before(i)) / total;
        if p <= 0.0 {
            return None;
        }
        let (d, omega) = self.point_in_pixel(i, u);
        let weight = self.radiance[i].as_dvec3() * (omega / p);
        Some((d, weight.as_vec3()))
    }

    /// A direction uniform over pixel `i`'s patch of sphere from `u.y` (azimuth) and `u.z`
    /// (cosine of the polar angle), and the patch's solid angle.
    fn point_in_pixel(&self, i: usize, u: Vec3) -> (Vec3, f64) {
        let (phi0, phi1, c0, c1) = self.bounds(i as u32 % self.width, i as u32 / self.width);
        let phi = phi0 + (phi1 - phi0) * f64::from(u.y);
        let cos_t = c0 + (c1 - c0) * f64::from(u.z);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let d = DVec3::new(sin_t * phi.sin(), cos_t, -sin_t * phi.cos());
        (d.as_vec3(), (phi1 - phi0) * (c0 - c1))
    }
}

/// The finest map the median cut needs at least: this many columns and rows.
const CUT_GRID: (u32, u32) = (16, 8);

/// The most pixels a map is refined to (a larger map is held as given).
const REFINED_MAX: u64 = 1 << 24;

/// The map held refined by whole factors where it is too coarse for the median cut (the
/// same piecewise-constant function, so radiance, sampling density and irradiance are
/// unchanged): at least [`CUT_GRID`] columns and rows, and an even number of rows so that a
/// row boundary lies on the horizon. A 1x1 map is one pixel over the whole sphere, whose
/// vector irradiance cancels, and a one-row map is one row centred on the horizon: cut as
/// they are, they would give lights of no irradiance, or horizontal ones.
fn refined(width: u32, height: u32, radiance: Vec<Vec3>) -> (u32, u32, Vec<Vec3>) {
    let (wd, hd) = (u64::from(width), u64::from(height));
    let kx = u64::from(CUT_GRID.0).div_ceil(wd).max(1);
    let mut ky = u64::from(CUT_GRID.1).div_ceil(hd).max(1);
    if (hd * ky) % 2 == 1 {
        ky += 1;
    }
    let (kx, ky) = if wd * kx * hd * ky <= REFINED_MAX {
        (kx, ky)
    } else if hd % 2 == 1 && wd * hd * 2 <= REFINED_MAX {
        // Only the horizon's row boundary.
        (1, 2)
    } else {
        (1, 1)
    };
    if kx == 1 && ky == 1 {
        return (width, height, radiance);
    }
    // Both sides are at most REFINED_MAX here.
    let (w, h) = ((wd * kx) as u32, (hd * ky) as u32);
    let (kx, ky) = (kx as u32, ky as u32);
    let map = (0..h)
        .flat_map(|y| (0..w).map(move |x| ((y / ky) * width + x / kx) as usize))
        .map(|i| radiance[i])
        .collect();
    (w, h, map)
}

/// The integral of the unit direction over the patch `phi0..phi1`, `cos theta` from `c0`
/// down to `c1` (a vector whose length is at most the patch's solid angle).
fn mean_direction(phi0: f64, phi1: f64, c0: f64, c1: f64) -> DVec3 {
    // theta from acos(c0) to acos(c1); with dw = sin t dt dphi:
    // x: int sin^2 t dt * int sin phi = (t/2 - sin 2t / 4) * (cos phi0 - cos phi1)
    // y: int cos t sin t dt * (phi1 - phi0) = (sin^2 t1 - sin^2 t0)/2 * dphi
    // z: -int sin^2 t dt * int cos phi = -(..) * (sin phi1 - sin phi0)
    let (t0, t1) = (c0.clamp(-1.0, 1.0).acos(), c1.clamp(-1.0, 1.0).acos());
    let s2 = |t: f64| t / 2.0 - (2.0 * t).sin() / 4.0;
    let sin2 = s2(t1) - s2(t0);
    let y = ((1.0 - c1 * c1) - (1.0 - c0 * c0)) / 2.0 * (phi1 - phi0);
    DVec3::new(
        sin2 * (phi0.cos() - phi1.cos()),
        y,
        -sin2 * (phi1.sin() - phi0.sin()),
    )
}

/// The widest spread a sky's light is given ([`Sky::spreads`]): tan 80 degrees.
pub const MAX_SPREAD: f32 = 5.67;

/// The spread (tangent of the half-angle) of the uniform cone whose mean cosine to its
/// axis is `mean`, the length of a region's power-weighted mean unit direction:
/// `cos a = 2 mean - 1`, capped at [`MAX_SPREAD`].
fn cone_spread(mean: f64) -> f32 {
    let cos = (2.0 * mean - 1.0).clamp(-1.0, 1.0);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    if cos * f64::from(MAX_SPREAD) <= sin {
        MAX_SPREAD
    } else {
        (sin / cos) as f32
    }
}

/// Splits the map into up to `sky.directions` regions of equal power (always the most
/// powerful splittable region, across its longer angular side, at its power median) and
/// makes each a directional light.
fn median_cut(
    sky: &Sky,
    weight: &[f64],
    vector: &[DVec3],
) -> Vec<(DirectionalLight, [u32; 4], f32)> {
    let (w, h) = (sky.width as usize, sky.height as usize);
    // Summed-area table of the weights.
    let mut sat = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += weight[y * w + x];
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let sum = |r: [usize; 4]| {
        let [x0, y0, x1, y1] = r;
        sat[y1 * (w + 1) + x1] - sat[y0 * (w + 1) + x1] - sat[y1 * (w + 1) + x0]
            + sat[y0 * (w + 1) + x0]
    };
    // The two hemispheres apart from the start when both carry light (the map has an even
    // number of rows): a region across the horizon would give a surface facing up or down
    // the light of both halves along one mean direction, whose vertical parts cancel.
    let halves = [[0, 0, w, h / 2], [0, h / 2, w, h]];
    let mut regions: Vec<[usize; 4]> =
        if sky.directions >= 2 && h % 2 == 0 && halves.iter().all(|r| sum(*r) > 0.0) {
            halves.to_vec()
        } else {
            vec![[0, 0, w, h]]
        };
    let mut done: Vec<[usize; 4]> = Vec::new();
    while regions.len() + done.len() < sky.directions as usize {
        // The most powerful region still open (ties to the first: deterministic).
        let Some((k, _)) = regions.iter().enumerate().map(|(k, r)| (k, sum(*r))).fold(
            None,
            |best: Option<(usize, f64)>, (k, e)| match best {
                Some((_, b)) if b >= e => best,
                _ => Some((k, e)),
            },
        ) else {
            break;
        };
        let r = regions.swap_remove(k);
        let [x0, y0, x1, y1] = r;
        if (x1 - x0) * (y1 - y0) <= 1 || sum(r) <= 0.0 {
            done.push(r);
            continue;
        }
        // The longer side as an angle: azimuth span times the sine at the middle row.
        let mid_theta = std::f64::consts::PI * (y0 + y1) as f64 / (2.0 * h as f64);
        let across = std::f64::consts::TAU * (x1 - x0) as f64 / w as f64 * mid_theta.sin();
        let down = std::f64::consts::PI * (y1 - y0) as f64 / h as f64;
        let split_x = (across >= down && x1 - x0 > 1) || y1 - y0 == 1;
        let total = sum(r);
        let (a, b) = if split_x {
            let c = (x0 + 1..x1)
                .find(|&c| sum([x0, y0, c, y1]) >= total / 2.0)
                .unwrap_or(x1 - 1);
            ([x0, y0, c, y1], [c, y0, x1, y1])
        } else {
            let c = (y0 + 1..y1)
                .find(|&c| sum([x0, y0, x1, c]) >= total / 2.0)
                .unwrap_or(y1 - 1);
            ([x0, y0, x1, c], [x0, c, x1, y1])
        };
        // A part without light carries no light: it is dropped, not counted.
        regions.extend([a, b].into_iter().filter(|r| sum(*r) > 0.0));
    }
    done.extend(regions);
    // A fixed order whatever the splitting order: by region corner.
    done.sort_unstable();
    done.iter()
        .filter_map(|&[x0, y0, x1, y1]| {
            let mut power = DVec3::ZERO;
            let mut dir = DVec3::ZERO;
            let mut wsum = 0.0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let i = y * w + x;
                    if weight[i] <= 0.0 {
                        continue;
                    }
                    let (phi0, phi1, c0, c1) = sky.bounds(x as u32, y as u32);
                    let solid = (phi1 - phi0) * (c0 - c1);
                    power += sky.radiance[i].as_dvec3() * solid;
                    let lum = weight[i] / solid;
                    dir += vector[i] * lum;
                    wsum += lum * solid;
                }
            }
            let len = dir.length();
            if wsum <= 0.0 || len <= 0.0 {
                return None;
            }
            let light = DirectionalLight {
                name: format!("{} {}", sky.name, x0 * h + y0),
                direction: (-dir / len).as_vec3(),
                irradiance: (power * (len / wsum)).as_vec3(),
            };
            Some((
                light,
                [x0, y0, x1, y1].map(|v| v as u32),
                cone_spread(len / wsum),
            ))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The guide table's search picks the pixel a search of the whole table picks, on a map
    /// with a bright spot, dark runs and a black lower half, at random picks and at every
    /// cumulative value exactly (the boundaries, where rounding could mislead the guide).
    #[test]
    fn the_guided_search_equals_the_full_search() {
        let (w, h) = (40u32, 20u32);
        let mut rng = crate::sampling::Rng::new(3, 0);
        let map: Vec<Vec3> = (0..w * h)
            .map(|i| match (i / w, i % w) {
                (y, _) if y >= h / 2 => Vec3::ZERO,
                (_, x) if x % 7 < 3 => Vec3::ZERO,
                (3, 5) => Vec3::splat(5e4),
                _ => Vec3::splat(rng.next_f32()),
            })
            .collect();
        let sky = Sky::from_map("test", w, h, map, 16).unwrap();
        let last = *sky.cdf.last().unwrap();
        let full = |pick: f64| {
            sky.cdf
                .partition_point(|c| *c <= pick)
                .min(sky.cdf.len() - 1)
        };
        let picks = (0..20_000)
            .map(|_| f64::from(rng.next_f32()) * last)
            .chain(sky.cdf.iter().copied())
            .chain([0.0, last]);
        for pick in picks {
            assert_eq!(sky.pixel_at(pick, last), full(pick), "pick {pick}");
        }
    }

    #[test]
    fn only_a_constant_over_the_upper_hemisphere_is_uniform() {
        let l = Vec3::new(0.5, 0.6, 0.8);
        assert!(Sky::uniform(l).unwrap().is_uniform());
        assert!(
            Sky::uniform(l)
                .unwrap()
                .scaled(Vec3::splat(2.0))
                .unwrap()
                .is_uniform()
        );
        // The whole sphere at one radiance.
        assert!(
            Sky::from_map("sphere", 8, 4, vec![l; 32], 4)
                .unwrap()
                .is_uniform()
        );
        // One pixel above the horizon differs, or one is dark.
        for (i, c) in [(0, l * 1.0001), (9, Vec3::ZERO)] {
            let mut map = Sky::uniform(l).unwrap().map().to_vec();
            map[i] = c;
            let (w, h) = Sky::uniform(l).unwrap().size();
            assert!(!Sky::from_map("uneven", w, h, map, 8).unwrap().is_uniform());
        }
        // A lit band below the horizon of another radiance.
        let mut map = vec![l; 32];
        map[31] = l * 0.5;
        assert!(!Sky::from_map("band", 8, 4, map, 4).unwrap().is_uniform());
        // An odd height is held with a row boundary on the horizon: the middle row's upper
        // half is sky above the horizon, so it must be lit like the rows above it...
        let mut map = vec![l; 8 * 3];
        map[16..].fill(Vec3::ZERO);
        assert!(
            Sky::from_map("odd", 8, 3, map.clone(), 4)
                .unwrap()
                .is_uniform()
        );
        // ... and wholly: partly lit, or dark (the sky then ends 60 degrees from the zenith).
        map[8..12].fill(Vec3::ZERO);
        assert!(
            !Sky::from_map("odd", 8, 3, map.clone(), 4)
                .unwrap()
                .is_uniform()
        );
        map[8..16].fill(Vec3::ZERO);
        assert!(!Sky::from_map("odd", 8, 3, map, 4).unwrap().is_uniform());
        // One row: half of the azimuths lit is not uniform; one radiance over the whole
        // sphere is.
        assert!(
            !Sky::from_map("one row", 2, 1, vec![l, Vec3::ZERO], 1)
                .unwrap()
                .is_uniform()
        );
        assert!(
            Sky::from_map("one row", 2, 1, vec![l; 2], 1)
                .unwrap()
                .is_uniform()
        );
    }

    #[test]
    fn a_uniform_sky_gives_pi_radiance_to_a_floor_and_nothing_below() {
        let l = Vec3::new(1.0, 0.5, 0.25);
        let sky = Sky::uniform(l).unwrap();
        let e = sky.irradiance(Vec3::Y);
        assert!(
            (e - l * std::f32::consts::PI).abs().max_element() < 1e-4,
            "{e}"
        );
        assert_eq!(sky.irradiance(-Vec3::Y), Vec3::ZERO);
        // A wall: half the floor's (the upper half of its hemisphere is sky).
        let wall = sky.irradiance(Vec3::X);
        assert!(
            (wall - l * std::f32::consts::FRAC_PI_2).abs().max_element() < 2e-3,
            "{wall}"
        );
        assert_eq!(sky.radiance(Vec3::new(0.3, 0.9, 0.1).normalize()), l);
        assert_eq!(sky.radiance(-Vec3::Y), Vec3::ZERO);
    }

    #[test]
    fn the_median_cut_lights_give_a_floor_and_a_tilted_roof_their_irradiance() {
        let sky = Sky::uniform(Vec3::ONE).unwrap();
        assert_eq!(sky.lights().len(), DEFAULT_DIRECTIONS as usize);
        let by_lights = |n: Vec3| -> Vec3 {
            sky.lights()
                .iter()
                .map(|l| l.irradiance * n.dot(-l.direction).max(0.0))
                .sum()
        };
        // Wholly above the floor's horizon: exact by construction.
        let floor = by_lights(Vec3::Y);
        assert!(
            (floor - sky.irradiance(Vec3::Y)).abs().max_element() < 1e-4,
            "{floor}"
        );
        // Regions cut by a tilted roof's horizon: close, not exact.
        for n in [Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.2, 1.0, -0.7), Vec3::X] {
            let n = n.normalize();
            let (a, b) = (by_lights(n), sky.irradiance(n));
            assert!(
                (a - b).abs().max_element() < 0.03 * b.max_element(),
                "{n}: {a} {b}"
            );
        }
        // The greedy cut splits the most powerful region until the count is reached: no
        // direction carries much more than its share of the hemisphere's 2 pi L.
        let share = std::f32::consts::TAU / sky.lights().len() as f32;
        let hi = sky
            .lights()
            .iter()
            .map(|l| l.irradiance.x)
            .fold(0.0, f32::max);
        assert!(hi < 1.5 * share, "{hi} against a share of {share}");
    }

    /// Each light's spread is its region's cone: under a uniform sky the regions have equal
    /// solid angles `2 pi / n` (equal power), and a cone of that solid angle has
    /// `cos a = 1 - 1/n`; the spreads' median over 64 and 256 regions is within 25 % of
    /// that cone's tangent (the cut's regions are rectangles of sides up to 2:1, whose
    /// mean cosine is that of a disk 14 % wider than one of their area), none is below
    /// 0.6 of it or non-finite, and the four times
    /// smaller regions of 256 directions have half the spread. The cone of a mean
    /// direction: 1 gives 0, 1/2 (a hemisphere's uniform cone, mean cosine 1/2) the cap.
    #[test]
    fn each_light_spreads_over_its_regions_cone() {
        let mut medians = Vec::new();
        for n in [64u32, 256] {
            let sky = Sky::uniform(Vec3::splat(0.5))
                .unwrap()
                .with_directions(n)
                .unwrap();
            let spreads = sky.spreads().to_vec();
            assert_eq!(spreads.len(), sky.lights().len());
            let cos = 1.0 - 1.0 / n as f32;
            let cone = (1.0 - cos * cos).sqrt() / cos;
            let mut sorted = spreads.clone();
            sorted.sort_by(f32::total_cmp);
            let median = sorted[sorted.len() / 2];
            assert!(
                (median / cone - 1.0).abs() < 0.25,
                "{n}: median {median}, cone {cone}"
            );
            assert!(
                sorted
                    .iter()
                    .all(|s| s.is_finite() && *s >= 0.6 * cone && *s <= MAX_SPREAD),
                "{n}: {sorted:?}"
            );
            medians.push(median);
        }
        assert!((medians[0] / medians[1] - 2.0).abs() < 0.3, "{medians:?}");
        assert_eq!(cone_spread(1.0), 0.0);
        assert_eq!(cone_spread(0.5), MAX_SPREAD);
        assert_eq!(cone_spread(0.0), MAX_SPREAD);
        assert!((cone_spread(0.75) - 3f32.sqrt()).abs() < 1e-5);
    }

    #[test]
    fn degenerate_maps_give_their_lights_the_irradiance_of_the_map() {
        // One pixel, one row (short, odd, very wide), one column (odd), each constant or
        // uneven: the lights give an open floor and ceiling what the map gives them, and
        // walls what it gives within the median cut's error (5 % at 64 lights over both
        // hemispheres). Cut as given, a 1x1 map gave a floor about 1e-16 of its light and a
        // one-row map gave it nothing.
        let l = Vec3::new(1.0, 0.5, 0.25);
        let ramp = |n: u32| -> Vec<Vec3> {
            (0..n)
                .map(|i| l * (0.2 + 1.8 * i as f32 / n.max(2) as f32))
                .collect()
        };
        let maps: [(u32, u32, Vec<Vec3>); 8] = [
            (1, 1, vec![l]),
            (5, 1, vec![l; 5]),
            (5, 1, ramp(5)),
            (4096, 1, ramp(4096)),
            (1, 3, vec![l; 3]),
            (1, 3, ramp(3)),
            (1, 6, ramp(6)),
            (3, 5, ramp(15)),
        ];
        let mut worst = 0.0f32;
        for (w, h, map) in maps {
            for directions in [2, 16, 64] {
                let sky = Sky::from_map("degenerate", w, h, map.clone(), directions).unwrap();
                let by_lights = |n: Vec3| -> Vec3 {
                    sky.lights()
                        .iter()
                        .map(|x| x.irradiance * n.dot(-x.direction).max(0.0))
                        .sum()
                };
                for n in [Vec3::Y, -Vec3::Y] {
                    let (a, b) = (by_lights(n), sky.irradiance(n));
                    assert!(
                        b.max_element() > 0.1
                            && (a - b).abs().max_element() < 1e-4 * b.max_element(),
                        "{w}x{h}, {directions} lights, normal {n}: {a} against {b}"
                    );
                }
                // Walls and a tilted roof at the default count: regions cut by their
                // horizon. The uniform sky's 64 lights over one hemisphere give walls 3 %
                // (the_median_cut_lights_give_a_floor_and_a_tilted_roof_...); these maps
                // light both hemispheres, 32 lights each.
                if directions < DEFAULT_DIRECTIONS {
                    continue;
                }
                for n in [Vec3::X, -Vec3::Z, Vec3::new(0.3, 1.0, 0.5).normalize()] {
                    let (a, b) = (by_lights(n), sky.irradiance(n));
                    let e = (a - b).abs().max_element() / b.max_element();
                    worst = worst.max(e);
                    assert!(
                        e < 0.05,
                        "{w}x{h}, {directions} lights, normal {n}: {a} against {b}"
                    );
                }
            }
        }
        eprintln!(
            "walls and a tilted roof at 64 lights: worst {:.2} %",
            worst * 100.0
        );
    }

    /// A 16x8 map of `sky` with a `sun` pixel high in it and a blue one below the horizon,
    /// as `directions` lights.
    fn uneven(sky: Vec3, sun: Vec3, directions: u32) -> Sky {
        let (w, h) = (16u32, 8u32);
        let mut map = vec![sky; (w * h) as usize];
        map[(2 * w + 5) as usize] = sun;
        map[(6 * w + 1) as usize] = Vec3::new(0.0, 0.0, 3.0);
        Sky::from_map("test", w, h, map, directions).unwrap()
    }

    #[test]
    fn sampling_draws_each_pixel_by_its_power_with_the_density_it_reports() {
        // A map with a bright patch: the sampled directions' histogram follows L dw and
        // pdf() agrees with sample()'s density; the estimator of the floor's irradiance
        // (L cos / pdf) converges to the sum.
        let sky = uneven(Vec3::splat(0.1), Vec3::splat(50.0), 16);
        let mut rng = crate::sampling::Rng::new(7, 0);
        let n = 400_000;
        let mut e = DVec3::ZERO;
        for _ in 0..n {
            let (d, pdf, l) = sky
                .sample(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
                .unwrap();
            assert!(
                (sky.pdf(d) - pdf).abs() <= 1e-3 * pdf,
                "{} {pdf}",
                sky.pdf(d)
            );
            assert_eq!(sky.radiance(d), l);
            e += (l * d.y.max(0.0) / pdf).as_dvec3();
        }
        let e = (e / n as f64).as_vec3();
        let exact = sky.irradiance(Vec3::Y);
        assert!(
            (e - exact).abs().max_element() < 0.01 * exact.max_element(),
            "{e} {exact}"
        );
    }

    #[test]
    fn one_draw_per_light_region_estimates_the_whole_sky() {
        // The uneven map's floor irradiance from one draw per region, averaged: unbiased.
        let sky = uneven(Vec3::new(0.1, 0.2, 0.3), Vec3::new(50.0, 20.0, 5.0), 12);
        let mut rng = crate::sampling::Rng::new(9, 0);
        let n = 40_000;
        let mut e = DVec3::ZERO;
        for _ in 0..n {
            for k in 0..sky.lights().len() {
                let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let (d, weight) = sky.sample_light(k, u).unwrap();
                e += (weight * d.y.max(0.0)).as_dvec3();
            }
        }
        let e = (e / n as f64).as_vec3();
        let exact = sky.irradiance(Vec3::Y);
        assert!(
            (e - exact).abs().max_element() < 0.01 * exact.max_element(),
            "{e} {exact}"
        );
        assert!(sky.sample_light(sky.lights().len(), Vec3::ZERO).is_none());
    }

    #[test]
    fn bad_skies_are_refused_by_name() {
        for (map, n) in [
            (vec![Vec3::ONE; 3], 8),
            (vec![Vec3::new(1.0, f32::NAN, 0.0); 4], 8),
            (vec![Vec3::new(-1.0, 0.0, 0.0); 4], 8),
            (vec![Vec3::splat(1e13); 4], 8),
            (vec![Vec3::ONE; 4], 0),
            (vec![Vec3::ONE; 4], MAX_DIRECTIONS + 1),
        ] {
            let e = Sky::from_map("bad", 2, 2, map, n).unwrap_err();
            assert!(e.to_string().contains("sky 'bad'"), "{e}");
        }
        let black = Sky::from_map("black", 2, 2, vec![Vec3::ZERO; 4], 8).unwrap();
        assert!(black.is_black() && black.lights().is_empty());
        assert!(black.sample(Vec3::splat(0.5)).is_none());
    }
}
