//! The layered depth cube (paper section 3): three layered depth images on the scene's
//! bounding cube, one per axis, whose pixels are planes (section 3.1).
//!
//! A surface sample goes to the LDI whose axis is most parallel to its normal (figure 2),
//! and, when its normal lies near the boundary between two or three LDIs (within
//! [`LdcFrame::band`] of the dominant component), to each of them, so that a lookup can
//! blend across LDIs without a seam (the interpolation "across different LDIs" of section
//! 6.2). Within an LDI pixel a sample is matched against the layers already there by the
//! plane test of section 3.1,
//!
//! `|p' . n - d| < eps_d` and `n' . n > 1 - eps_n`,
//!
//! and accumulated into the matching layer, else inserted as a new layer. The paper uses
//! one `eps` for both conditions; a distance and a cosine have different units, so here
//! they are two thresholds: `eps_d` a fraction of the LDI pixel size (which follows the
//! scene's extent), `eps_n` a pure number.
//!
//! [`LdcBuilder`] grows the layers in an arena with a linked list per pixel; [`Ldc`] is the
//! compact layout for lookup (per pixel a range into flat arrays of planes and values).

use glam::{Vec2, Vec3, Vec4};

use crate::error::IbrrError;

/// Bytes per layer of the compact [`Ldc`] before its per-source values: a plane (4 x f32)
/// and the direct and indirect irradiance under the light state applied (2 x 3 x f32).
pub const LAYER_BYTES: u64 = 40;

/// Bytes per layer while building before its per-source accumulators (plane, list link,
/// pixel, per-IRPL stamp and scratch).
pub const BUILD_LAYER_BYTES: u64 = 16 + 4 + 4 + 4 + 16 + 4;

/// Bytes per layer and light source of the accumulators while building (direct and
/// indirect, 2 x 3 x f32).
pub const BUILD_SOURCE_BYTES: u64 = 24;

/// How the compact [`Ldc`] stores each layer's irradiance per light source (the relighting
/// paper's tagging applied to the layers: one direct and one indirect value per source).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SourcePrecision {
    /// 2 x 3 x f32: 24 bytes a layer and source.
    #[default]
    F32,
    /// 2 x 3 x f16: 12 bytes a layer and source (relative rounding about 5e-4), each
    /// source's values stored over a power-of-two scale of its own (4 bytes a source), so
    /// that a light of any brightness keeps f16's precision instead of saturating at 65504;
    /// values below 2^-26 of the source's brightest round to zero.
    F16,
}

impl SourcePrecision {
    /// Bytes per layer and source.
    pub fn bytes(self) -> u64 {
        match self {
            SourcePrecision::F32 => 24,
            SourcePrecision::F16 => 12,
        }
    }
}

/// The geometry of an LDC: its cube, resolution and matching thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LdcFrame {
    /// The cube's minimum corner.
    pub origin: Vec3,
    /// The cube's side.
    pub side: f32,
    /// Pixels along each side of every LDI.
    pub resolution: u32,
    /// Plane-distance threshold `eps_d` (world units).
    pub eps_distance: f32,
    /// Normal threshold `eps_n`: layers match when `n' . n > 1 - eps_n`.
    pub eps_normal: f32,
    /// Normals whose component along an axis is within `band` of the largest component
    /// also go to that axis' LDI.
    pub band: f32,
}

/// Which LDIs a normal goes to, with blend weights (1 for the dominant axis, falling
/// linearly to 0 at `band` below it).
pub fn axes_of(n: Vec3, band: f32) -> [(usize, f32); 3] {
    let a = n.abs();
    let m = a.max_element();
    let mut out = [(0usize, 0.0f32); 3];
    for (k, o) in out.iter_mut().enumerate() {
        let w = if band > 0.0 {
            ((a[k] - (m - band)) / band).clamp(0.0, 1.0)
        } else if a[k] == m {
            1.0
        } else {
            0.0
        };
        *o = (k, w);
    }
    // Exactly one axis when the band is zero and components tie: keep the first.
    if band <= 0.0 {
        let mut seen = false;
        for o in &mut out {
            if o.1 > 0.0 {
                if seen {
                    o.1 = 0.0;
                }
                seen = true;
            }
        }
    }
    out
}

impl LdcFrame {
    /// The frame of a cube around `min..max` (a margin of 1e-3 of the side on every face)
    /// at `resolution`, with thresholds `eps_distance_px` (in LDI pixels), `eps_normal` and
    /// `band`. An empty or degenerate box gets a unit cube.
    pub fn around(
        min: Vec3,
        max: Vec3,
        resolution: u32,
        eps_distance_px: f32,
        eps_normal: f32,
        band: f32,
    ) -> Self {
        let size = max - min;
        let valid = min.is_finite() && max.is_finite() && size.min_element() >= 0.0;
        let (centre, mut side) = if valid {
            ((min + max) * 0.5, size.max_element())
        } else {
            (Vec3::ZERO, 1.0)
        };
        if side <= 0.0 || !side.is_finite() {
            side = 1.0;
        }
        side *= 1.0 + 2e-3;
        let pixel = side / resolution.max(1) as f32;
        Self {
            origin: centre - Vec3::splat(side * 0.5),
            side,
            resolution: resolution.max(1),
            eps_distance: eps_distance_px * pixel,
            eps_normal,
            band,
        }
    }

    /// The side of an LDI pixel (world units).
    pub fn pixel_size(&self) -> f32 {
        self.side / self.resolution as f32
    }

    /// The two axes spanning LDI `axis`' image plane.
    #[inline]
    pub fn image_axes(axis: usize) -> (usize, usize) {
        ((axis + 1) % 3, (axis + 2) % 3)
    }

    /// Continuous pixel coordinates of `p` in LDI `axis` (pixel `(i, j)` covers
    /// `[i, i+1) x [j, j+1)`).
    #[inline]
    pub fn pixel_coords(&self, axis: usize, p: Vec3) -> Vec2 {
        let (u, v) = Self::image_axes(axis);
        let inv = self.resolution as f32 / self.side;
        Vec2::new((p[u] - self.origin[u]) * inv, (p[v] - self.origin[v]) * inv)
    }

    /// Index of pixel `(i, j)` of LDI `axis`, if inside.
    #[inline]
    pub fn pixel_index(&self, axis: usize, i: i64, j: i64) -> Option<usize> {
        let r = self.resolution as i64;
        (i >= 0 && j >= 0 && i < r && j < r).then(|| (axis as i64 * r * r + j * r + i) as usize)
    }

    /// Number of pixels over the three LDIs.
    pub fn pixel_count(&self) -> usize {
        3 * self.resolution as usize * self.resolution as usize
    }

    /// The point of `plane` (`n . x = d`) seen along LDI `axis` through the centre of pixel
    /// `(i, j)`; `None` when the plane is parallel to the axis.
    pub fn point_on_plane(&self, axis: usize, i: i64, j: i64, plane: Vec4) -> Option<Vec3> {
        let n = plane.truncate();
        if n[axis].abs() < 1e-6 {
            return None;
        }
        let (u, v) = Self::image_axes(axis);
        let h = self.pixel_size();
        let mut p = Vec3::ZERO;
        p[u] = self.origin[u] + (i as f32 + 0.5) * h;
        p[v] = self.origin[v] + (j as f32 + 0.5) * h;
        p[axis] = (plane.w - n[u] * p[u] - n[v] * p[v]) / n[axis];
        Some(p)
    }

    /// The plane test of section 3.1 between a stored `plane` and a point `p` with normal
    /// `n`: `Some(distance)` when they match.
    #[inline]
    pub fn matches(&self, plane: Vec4, p: Vec3, n: Vec3) -> Option<f32> {
        let dist = (p.dot(plane.truncate()) - plane.w).abs();
        (dist < self.eps_distance && n.dot(plane.truncate()) > 1.0 - self.eps_normal)
            .then_some(dist)
    }
}

/// One layer while building.
#[derive(Clone, Copy, Debug)]
struct BuildLayer {
    plane: Vec4,
    next: u32,
    /// The LDI pixel it lies in.
    pixel: u32,
    /// The IRPL (plus one) whose splats are held in `scratch`.
    stamp: u32,
    /// Per-IRPL splat accumulation: weighted value and weight (Gaussian) or the value and
    /// the distance of the nearest sample so far (nearest).
    scratch: Vec4,
    scratch_w: f32,
}

const NONE: u32 = u32::MAX;

/// Where an IRPL's light goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Direct light computed exactly once (point and directional lights).
    Exact,
    /// Direct light from one emitter sample of one path.
    Direct,
    /// Light after one or more reflections, from one path.
    Indirect,
}

/// How splats from one IRPL combine in a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Combine {
    /// The sample nearest the pixel centre wins (the paper's nearest-neighbour copies).
    Nearest,
    /// Weighted mean (Gaussian kernel, section 6.2).
    Weighted,
}

/// An LDC under construction.
#[derive(Debug)]
pub struct LdcBuilder {
    /// Its geometry.
    pub frame: LdcFrame,
    heads: Vec<u32>,
    layers: Vec<BuildLayer>,
    /// Light sources the values are kept apart for.
    sources: usize,
    /// Per layer and source, `[direct, indirect]`: the direct slot holds exact light for
    /// point and directional lights and a sum over paths for emitters (see `exact`), the
    /// indirect slot a sum over paths.
    values: Vec<[Vec3; 2]>,
    /// Per source, whether its direct light is exact (not divided by the path count).
    exact: Vec<bool>,
    /// Layers below this index take no light (a catch-up pass lights only the layers a
    /// later round founded).
    min_layer: usize,
    touched: Vec<u32>,
    stamp: u32,
    max_bytes: u64,
}

impl LdcBuilder {
    /// An empty LDC keeping the light of `sources` sources apart (at least 1). Errors with
    /// [`IbrrError::Budget`] when the per-pixel heads alone (4 bytes a pixel) exceed
    /// `max_bytes`, before allocating them.
    pub fn new(frame: LdcFrame, max_bytes: u64, sources: usize) -> Result<Self, IbrrError> {
        let sources = sources.max(1);
        let heads = frame.pixel_count() as u64 * 4;
        if heads > max_bytes {
            return Err(IbrrError::Budget {
                needed: heads,
                limit: max_bytes,
                what: format!(
                    "per-pixel layer lists of 3 x {0} x {0} LDIs",
                    frame.resolution
                ),
            });
        }
        Ok(Self {
            frame,
            heads: vec![NONE; frame.pixel_count()],
            layers: Vec::new(),
            sources,
            values: Vec::new(),
            exact: vec![false; sources],
            min_layer: 0,
            touched: Vec::new(),
            stamp: 0,
            max_bytes,
        })
    }

    /// Bytes a layer takes while building.
    pub fn layer_bytes(&self) -> u64 {
        BUILD_LAYER_BYTES + self.sources as u64 * BUILD_SOURCE_BYTES
    }

    /// Bytes held now (heads plus layers at their building size).
    pub fn bytes(&self) -> u64 {
        self.heads.len() as u64 * 4 + self.layers.len() as u64 * self.layer_bytes()
    }

    /// Number of light sources kept apart.
    pub fn sources(&self) -> usize {
        self.sources
    }

    /// Number of layers.
    pub fn layer_count(&self) -> usize {
        self.layers.len()
    }

    /// The layers being built that a point `p` with normal `n` reads with the bilinear
    /// kernel ([`Ldc::layer_weights`]'s, on the builder's layer indices).
    pub(crate) fn layer_weights(&self, p: Vec3, n: Vec3, out: &mut Vec<(usize, f32)>) {
        bilinear_layers(&self.frame, p, n, out, |index| {
            self.best_match(index, p, n).map(|l| l as usize)
        });
    }

    /// The light the current IRPL gives layer `layer` (its splats combined, or its
    /// gathered value), before [`LdcBuilder::finish`] adds it; `None` where it gave none.
    pub(crate) fn current(&self, layer: usize) -> Option<Vec3> {
        let l = self.layers.get(layer)?;
        (l.stamp == self.stamp && l.scratch.w > 0.0).then(|| l.scratch.truncate() / l.scratch.w)
    }

    /// Starts the splats of a new IRPL.
    pub fn begin(&mut self) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            for l in &mut self.layers {
                l.stamp = 0;
            }
            self.stamp = 1;
        }
        self.touched.clear();
    }

    /// The layer of pixel `index` matching `(p, n)` best (smallest plane distance).
    fn best_match(&self, index: usize, p: Vec3, n: Vec3) -> Option<u32> {
        let mut best: Option<(u32, f32)> = None;
        let mut l = self.heads[index];
        while l != NONE {
            let layer = &self.layers[l as usize];
            if let Some(d) = self.frame.matches(layer.plane, p, n)
                && best.is_none_or(|(_, b)| d < b)
            {
                best = Some((l, d));
            }
            l = layer.next;
        }
        best.map(|(l, _)| l)
    }

    /// Finds the layer of pixel `index` matching `(p, n)`, inserting one with `plane` when
    /// none does (only when `insert`).
    fn find_or_insert(
        &mut self,
        index: usize,
        p: Vec3,
        n: Vec3,
        plane: Vec4,
        insert: bool,
    ) -> Result<Option<u32>, IbrrError> {
        if let Some(l) = self.best_match(index, p, n) {
            return Ok(Some(l));
        }
        if !insert {
            return Ok(None);
        }
        let needed = self.bytes() + self.layer_bytes();
        if needed > self.max_bytes {
            return Err(IbrrError::Budget {
                needed,
                limit: self.max_bytes,
                what: format!("layer {} of the LDC", self.layers.len() + 1),
            });
        }
        let id = self.layers.len() as u32;
        self.values
            .extend(std::iter::repeat_n([Vec3::ZERO; 2], self.sources));
        self.layers.push(BuildLayer {
            plane,
            next: self.heads[index],
            pixel: index as u32,
            stamp: 0,
            scratch: Vec4::ZERO,
            scratch_w: 0.0,
        });
        self.heads[index] = id;
        Ok(Some(id))
    }

    /// The layer at pixel `(i, j)` of LDI `axis` for the surface through `p` with normal
    /// `n`, founded unless one matches already (`None` outside the LDI). Alone, the
    /// founding pass of the exact mode: layers only, no light.
    pub fn found(
        &mut self,
        axis: usize,
        i: i64,
        j: i64,
        p: Vec3,
        n: Vec3,
    ) -> Result<Option<u32>, IbrrError> {
        let Some(index) = self.frame.pixel_index(axis, i, j) else {
            return Ok(None);
        };
        self.find_or_insert(index, p, n, n.extend(p.dot(n)), true)
    }

    /// Clears every layer's light and the splat stamps, keeping the layers (between the
    /// exact mode's founding and lighting passes).
    pub fn reset_values(&mut self) {
        self.values.fill([Vec3::ZERO; 2]);
        self.exact.fill(false);
        self.reset_scratch();
    }

    /// Only layers from index `first` on take light from now on (`0`: every layer): a
    /// catch-up pass gives the layers a later round founded the light of earlier IRPLs.
    pub fn light_only_from(&mut self, first: usize) {
        self.min_layer = first;
    }

    /// Clears the splat stamps and scratch, keeping the layers and their light.
    pub fn reset_scratch(&mut self) {
        for l in &mut self.layers {
            l.stamp = 0;
            l.scratch = Vec4::ZERO;
            l.scratch_w = 0.0;
        }
        self.stamp = 0;
        self.touched.clear();
    }

    /// The layer of pixel `(i, j)` of LDI `axis` matching `(p, n)` if the current IRPL has
    /// already splatted into it.
    pub fn stamped(&self, axis: usize, i: i64, j: i64, p: Vec3, n: Vec3) -> Option<u32> {
        let index = self.frame.pixel_index(axis, i, j)?;
        self.best_match(index, p, n)
            .filter(|&l| self.layers[l as usize].stamp == self.stamp)
    }

    /// Splats `value` of the current IRPL at pixel `(i, j)` of LDI `axis` onto the surface
    /// `plane` (through `p` with normal `n`), `dist` being the distance (in LDI pixels)
    /// from the sample to the pixel's centre and `weight` its kernel weight.
    #[allow(clippy::too_many_arguments)]
    pub fn splat(
        &mut self,
        axis: usize,
        i: i64,
        j: i64,
        p: Vec3,
        n: Vec3,
        value: Vec3,
        dist: f32,
        weight: f32,
        combine: Combine,
    ) -> Result<(), IbrrError> {
        let Some(l) = self.found(axis, i, j, p, n)? else {
            return Ok(());
        };
        if (l as usize) < self.min_layer {
            return Ok(());
        }
        let stamp = self.stamp;
        let layer = &mut self.layers[l as usize];
        if layer.stamp != stamp {
            layer.stamp = stamp;
            layer.scratch = Vec4::ZERO;
            layer.scratch_w = match combine {
                Combine::Nearest => f32::INFINITY,
                Combine::Weighted => 0.0,
            };
            self.touched.push(l);
        }
        match combine {
            Combine::Nearest => {
                if dist < layer.scratch_w {
                    layer.scratch_w = dist;
                    layer.scratch = value.extend(1.0);
                }
            }
            Combine::Weighted => {
                layer.scratch += (value * weight).extend(weight);
            }
        }
        Ok(())
    }

    /// True when pixel `(i, j)` of LDI `axis` has a layer matching `(p, n)`.
    pub fn has_layer(&self, axis: usize, i: i64, j: i64, p: Vec3, n: Vec3) -> bool {
        self.frame
            .pixel_index(axis, i, j)
            .is_some_and(|index| self.best_match(index, p, n).is_some())
    }

    /// Gives every layer the current IRPL has not reached yet the value `value(centre,
    /// normal)` returns for its pixel centre on its plane (`None`: the IRPL does not light
    /// it). Layers are evaluated in parallel; the result does not depend on the thread
    /// count.
    pub fn gather<F>(&mut self, value: F)
    where
        F: Fn(Vec3, Vec3) -> Option<Vec3> + Sync,
    {
        use rayon::prelude::*;
        let frame = self.frame;
        let stamp = self.stamp;
        let r = frame.resolution as usize;
        let min_layer = self.min_layer;
        let found: Vec<Option<Vec3>> = self
            .layers
            .par_iter()
            .enumerate()
            .map(|(l, layer)| {
                if layer.stamp == stamp || l < min_layer {
                    return None;
                }
                let k = layer.pixel as usize;
                let (axis, rest) = (k / (r * r), k % (r * r));
                let (i, j) = ((rest % r) as i64, (rest / r) as i64);
                let q = frame.point_on_plane(axis, i, j, layer.plane)?;
                value(q, layer.plane.truncate())
            })
            .collect();
        self.apply_gathered(&found);
    }

    /// The planes and LDI pixels of layers `from..` (what a GPU gather uploads as layers
    /// appear).
    pub fn layers_from(&self, from: usize) -> Vec<(Vec4, u32)> {
        self.layers[from.min(self.layers.len())..]
            .iter()
            .map(|l| (l.plane, l.pixel))
            .collect()
    }

    /// Gives each layer `l` the current IRPL has not reached yet the value `values[l]`
    /// (computed elsewhere, e.g. on the GPU, for every layer).
    pub fn apply_gathered(&mut self, values: &[Option<Vec3>]) {
        let stamp = self.stamp;
        for (l, v) in values
            .iter()
            .enumerate()
            .take(self.layers.len())
            .skip(self.min_layer)
        {
            if let Some(v) = *v {
                let layer = &mut self.layers[l];
                if layer.stamp == stamp {
                    continue;
                }
                layer.stamp = stamp;
                layer.scratch = v.extend(1.0);
                layer.scratch_w = 0.0;
                self.touched.push(l as u32);
            }
        }
    }

    /// Adds the current IRPL's splats to `channel` of light source `source` (below
    /// [`LdcBuilder::sources`]; a larger index goes to the last): one value per layer it
    /// reached (its overlapping splats combined, never summed). A source's direct light
    /// is either exact ([`Channel::Exact`]) or from paths ([`Channel::Direct`]), never
    /// both.
    pub fn finish(&mut self, channel: Channel, source: usize) {
        let s = source.min(self.sources - 1);
        let slot = match channel {
            Channel::Exact => {
                self.exact[s] = true;
                0
            }
            Channel::Direct => 0,
            Channel::Indirect => 1,
        };
        for &l in &self.touched {
            let layer = &self.layers[l as usize];
            let v = if layer.scratch.w > 0.0 {
                layer.scratch.truncate() / layer.scratch.w
            } else {
                Vec3::ZERO
            };
            self.values[l as usize * self.sources + s][slot] += v;
        }
        self.touched.clear();
    }

    /// The compact LDC of what was built, with path sums divided by `paths` (at least 1),
    /// its per-source values stored at `precision` and each source's values multiplied by
    /// `unit[source]` (`[direct, indirect]` per channel: the inverse of the light factors
    /// the IRPLs were made with, so that the stored values are per unit of emission; a
    /// missing entry is 1). The combined values are those of unit factors. Errors when the
    /// compact copy would exceed the budget.
    pub fn compact(
        &self,
        paths: u64,
        precision: SourcePrecision,
        unit: &[[Vec3; 2]],
    ) -> Result<Ldc, IbrrError> {
        let needed = Ldc::bytes_for(self.frame.pixel_count(), self.layers.len())
            + self.layers.len() as u64 * self.sources as u64 * precision.bytes();
        if needed > self.max_bytes {
            return Err(IbrrError::Budget {
                needed,
                limit: self.max_bytes,
                what: format!(
                    "compact LDC of {} layers and {} light sources",
                    self.layers.len(),
                    self.sources
                ),
            });
        }
        let inv = 1.0 / paths.max(1) as f32;
        let scale: Vec<[Vec3; 2]> = (0..self.sources)
            .map(|s| {
                let u = unit.get(s).copied().unwrap_or([Vec3::ONE; 2]);
                let d = if self.exact[s] { 1.0 } else { inv };
                [u[0] * d, u[1] * inv]
            })
            .collect();
        let mut offsets = Vec::with_capacity(self.heads.len() + 1);
        let mut planes = Vec::with_capacity(self.layers.len());
        let mut per_source = Vec::with_capacity(self.layers.len() * self.sources);
        let mut stack = Vec::new();
        for &h in &self.heads {
            offsets.push(planes.len() as u32);
            // Layers in insertion order (the list holds them newest first).
            stack.clear();
            let mut l = h;
            while l != NONE {
                stack.push(l);
                l = self.layers[l as usize].next;
            }
            for &l in stack.iter().rev() {
                planes.push(self.layers[l as usize].plane);
                let v = &self.values[l as usize * self.sources..][..self.sources];
                per_source.extend(
                    v.iter()
                        .zip(&scale)
                        .map(|(v, k)| [v[0] * k[0], v[1] * k[1]]),
                );
            }
        }
        offsets.push(planes.len() as u32);
        let layers = planes.len();
        let mut ldc = Ldc {
            frame: self.frame,
            offsets,
            planes,
            direct: vec![Vec3::ZERO; layers],
            indirect: vec![Vec3::ZERO; layers],
            sources: SourceValues::new(self.sources, &per_source, precision),
        };
        ldc.relight(&vec![[Vec3::ONE; 2]; self.sources]);
        Ok(ldc)
    }
}

/// Each layer's direct and indirect irradiance per light source, per unit of the source's
/// light factors ([`scene_core::LightSetting::direct_factor`] and `indirect_factor`).
#[derive(Clone, Debug, PartialEq)]
pub struct SourceValues {
    sources: usize,
    store: SourceStore,
}

#[derive(Clone, Debug, PartialEq)]
enum SourceStore {
    F32(Vec<[Vec3; 2]>),
    /// The values over each source's scale (`value = f16 * scale[source]`).
    F16 {
        values: Vec<[half::f16; 6]>,
        scale: Vec<f32>,
        /// Values clamped at f16's largest since construction ([`SourceValues::add`]).
        saturated: u64,
    },
}

/// The largest stored f16 a source's brightest value maps to: 2^12, so that the light
/// compensation may add up to 16 times as much again before anything saturates.
const F16_TOP: f32 = 4096.0;

/// The power of two that maps `max` to at most [`F16_TOP`] (1 for a source without light).
fn f16_scale(max: f32) -> f32 {
    if !(max.is_finite() && max > 0.0) {
        return 1.0;
    }
    let e = (max / F16_TOP).log2().ceil().clamp(-126.0, 127.0);
    2f32.powi(e as i32)
}

/// `x / scale` as f16, clamped into [0, f16::MAX]; true when it was above the top.
fn to_f16(x: f32, scale: f32) -> (half::f16, bool) {
    let top = f32::from(half::f16::MAX);
    let v = x / scale;
    (half::f16::from_f32(v.clamp(0.0, top)), v > top)
}

impl SourceValues {
    fn new(sources: usize, values: &[[Vec3; 2]], precision: SourcePrecision) -> Self {
        let store = match precision {
            SourcePrecision::F32 => SourceStore::F32(values.to_vec()),
            SourcePrecision::F16 => {
                let mut max = vec![0.0f32; sources];
                for (k, [d, i]) in values.iter().enumerate() {
                    let m = &mut max[k % sources.max(1)];
                    *m = m.max(d.max_element()).max(i.max_element());
                }
                let scale: Vec<f32> = max.into_iter().map(f16_scale).collect();
                let values = values
                    .iter()
                    .enumerate()
                    .map(|(k, [d, i])| {
                        let s = scale[k % sources.max(1)];
                        [d.x, d.y, d.z, i.x, i.y, i.z].map(|x| to_f16(x, s).0)
                    })
                    .collect();
                SourceStore::F16 {
                    values,
                    scale,
                    saturated: 0,
                }
            }
        };
        Self { sources, store }
    }

    /// Values that [`SourceValues::add`] clamped at f16's largest (always 0 for f32).
    pub fn saturated(&self) -> u64 {
        match &self.store {
            SourceStore::F32(_) => 0,
            SourceStore::F16 { saturated, .. } => *saturated,
        }
    }

    /// Number of sources.
    pub fn sources(&self) -> usize {
        self.sources
    }

    /// How the values are stored.
    pub fn precision(&self) -> SourcePrecision {
        match self.store {
            SourceStore::F32(_) => SourcePrecision::F32,
            SourceStore::F16 { .. } => SourcePrecision::F16,
        }
    }

    /// Bytes held (with f16, the sources' scales too).
    pub fn bytes(&self) -> u64 {
        match &self.store {
            SourceStore::F32(v) => v.len() as u64 * SourcePrecision::F32.bytes(),
            SourceStore::F16 { values, scale, .. } => {
                values.len() as u64 * SourcePrecision::F16.bytes() + 4 * scale.len() as u64
            }
        }
    }

    /// Adds `[direct, indirect]` to layer `layer`'s values from source `source`.
    pub fn add(&mut self, layer: usize, source: usize, value: [Vec3; 2]) {
        let k = layer * self.sources + source;
        match &mut self.store {
            SourceStore::F32(v) => {
                v[k][0] += value[0];
                v[k][1] += value[1];
            }
            SourceStore::F16 {
                values,
                scale,
                saturated,
            } => {
                let [d, i] = value;
                let add = [d.x, d.y, d.z, i.x, i.y, i.z];
                let s = scale[source];
                for (h, a) in values[k].iter_mut().zip(add) {
                    let (v, over) = to_f16(f32::from(*h) * s + a, s);
                    *h = v;
                    *saturated += u64::from(over);
                }
            }
        }
    }

    /// `[direct, indirect]` of layer `layer` from source `source`.
    #[inline]
    pub fn get(&self, layer: usize, source: usize) -> [Vec3; 2] {
        let k = layer * self.sources + source;
        match &self.store {
            SourceStore::F32(v) => v[k],
            SourceStore::F16 { values, scale, .. } => {
                let s = scale[source];
                let h = values[k].map(|x| f32::from(x) * s);
                [Vec3::new(h[0], h[1], h[2]), Vec3::new(h[3], h[4], h[5])]
            }
        }
    }
}

/// A built LDC in its compact layout: for LDI pixel `k` (axis-major, then row, then
/// column) its layers are `offsets[k]..offsets[k + 1]` of the flat arrays.
#[derive(Clone, Debug, PartialEq)]
pub struct Ldc {
    /// Geometry and thresholds.
    pub frame: LdcFrame,
    /// Per pixel, the first layer; one more entry at the end.
    pub offsets: Vec<u32>,
    /// Per layer, its plane `(n, d)` with `n . x = d`.
    pub planes: Vec<Vec4>,
    /// Per layer, direct irradiance (W/m^2 in the scene's units).
    pub direct: Vec<Vec3>,
    /// Per layer, indirect irradiance.
    pub indirect: Vec<Vec3>,
    /// Per layer and light source, direct and indirect irradiance per unit of the source's
    /// light factors; `direct` and `indirect` are their sums weighted by the factors last
    /// applied ([`Ldc::relight`]).
    pub sources: SourceValues,
}

impl Ldc {
    /// Bytes of a compact LDC with `pixels` pixels and `layers` layers.
    pub fn bytes_for(pixels: usize, layers: usize) -> u64 {
        (pixels as u64 + 1) * 4 + layers as u64 * LAYER_BYTES
    }

    /// Bytes this LDC holds (the paper's "LDC pixels times the size of such a pixel", plus
    /// the per-pixel ranges and the per-source values).
    pub fn bytes(&self) -> u64 {
        Self::bytes_for(self.offsets.len().saturating_sub(1), self.planes.len())
            + self.sources.bytes()
    }

    /// How much the layers changed since `older`, an LDC of the same construction from an
    /// earlier round ([`crate::Construction::extend`]): over the layers both have (per LDI
    /// pixel, a round appends its new layers after the old ones), `sum |new - old| / sum
    /// new` of each layer's light summed over sources and channels, per unit of the
    /// sources' factors. When a round doubles the paths, the two estimates' difference is
    /// about the older one's error; `None` when no layer is shared.
    pub fn change_from(&self, older: &Ldc) -> Option<f64> {
        if older.frame != self.frame || older.offsets.len() != self.offsets.len() {
            return None;
        }
        let total = |ldc: &Ldc, l: usize| -> f64 {
            (0..ldc.sources.sources())
                .map(|s| {
                    let [d, i] = ldc.sources.get(l, s);
                    f64::from((d + i).element_sum())
                })
                .sum()
        };
        let (mut diff, mut sum) = (0.0f64, 0.0f64);
        for k in 0..self.offsets.len() - 1 {
            let (new, old) = (self.range(k), older.range(k));
            for (a, b) in new.zip(old) {
                let (x, y) = (total(self, a), total(older, b));
                diff += (x - y).abs();
                sum += x;
            }
        }
        (sum > 0.0).then(|| diff / sum)
    }

    /// Sets every layer's direct and indirect irradiance to the sum over sources of the
    /// source's values times `factors[source]` (`[direct, indirect]` factors per channel;
    /// a missing entry is 0): eq. 1 of the relighting paper applied to the layers. Costs
    /// one multiply-add per layer, source and channel; layers in parallel, the result
    /// independent of the thread count.
    pub fn relight(&mut self, factors: &[[Vec3; 2]]) {
        use rayon::prelude::*;
        let n = self.sources.sources();
        let sources = &self.sources;
        self.direct
            .par_iter_mut()
            .zip(self.indirect.par_iter_mut())
            .enumerate()
            .for_each(|(l, (d, i))| {
                let (mut sd, mut si) = (Vec3::ZERO, Vec3::ZERO);
                for (s, f) in factors.iter().enumerate().take(n) {
                    let v = sources.get(l, s);
                    sd += v[0] * f[0];
                    si += v[1] * f[1];
                }
                *d = sd;
                *i = si;
            });
    }

    /// Number of layers over all pixels.
    pub fn layer_count(&self) -> usize {
        self.planes.len()
    }

    /// The layers of pixel `index`.
    #[inline]
    pub fn range(&self, index: usize) -> std::ops::Range<usize> {
        self.offsets[index] as usize..self.offsets[index + 1] as usize
    }

    /// The layers of the LDC that a point `p` with normal `n` reads with the bilinear kernel in
    /// every LDI its normal belongs to, with weights summing to 1 (empty when none matches; no
    /// visibility test and no fallback): for sums over layers kept apart per source.
    /// Construction's compensation uses it (in `reconstruct.rs` until 2026-11-27); the
    /// reconstruction's bilinear lookup is the same kernel with visibility and fallback.
    pub(crate) fn layer_weights(&self, p: Vec3, n: Vec3, out: &mut Vec<(usize, f32)>) {
        bilinear_layers(&self.frame, p, n, out, |index| self.find(index, p, n));
    }
}

/// The layers a point `p` with normal `n` reads with the bilinear kernel in every LDI its
/// normal belongs to, with weights summing to 1 (empty when none matches), `find(pixel)`
/// giving the matching layer of an LDI pixel: [`Ldc::layer_weights`], and the build's
/// error probes on the layers being built ([`LdcBuilder::layer_weights`]).
pub(crate) fn bilinear_layers(
    frame: &LdcFrame,
    p: Vec3,
    n: Vec3,
    out: &mut Vec<(usize, f32)>,
    find: impl Fn(usize) -> Option<usize>,
) {
    out.clear();
    let mut total = 0.0f32;
    for (axis, w_axis) in axes_of(n, frame.band) {
        if w_axis <= 0.0 {
            continue;
        }
        let f = frame.pixel_coords(axis, p) - Vec2::splat(0.5);
        let (i0, j0) = (f.x.floor() as i64, f.y.floor() as i64);
        let t = f - Vec2::new(i0 as f32, j0 as f32);
        for (i, j, w) in [
            (i0, j0, (1.0 - t.x) * (1.0 - t.y)),
            (i0 + 1, j0, t.x * (1.0 - t.y)),
            (i0, j0 + 1, (1.0 - t.x) * t.y),
            (i0 + 1, j0 + 1, t.x * t.y),
        ] {
            if w <= 0.0 {
                continue;
            }
            if let Some(index) = frame.pixel_index(axis, i, j)
                && let Some(l) = find(index)
            {
                out.push((l, w * w_axis));
                total += w * w_axis;
            }
        }
    }
    if total > 0.0 {
        for (_, w) in out.iter_mut() {
            *w /= total;
        }
    }
}

impl Ldc {
    /// The layer of pixel `index` matching `(p, n)` best (smallest plane distance).
    #[inline]
    pub fn find(&self, index: usize, p: Vec3, n: Vec3) -> Option<usize> {
        let mut best: Option<(usize, f32)> = None;
        for l in self.range(index) {
            if let Some(d) = self.frame.matches(self.planes[l], p, n)
                && best.is_none_or(|(_, b)| d < b)
            {
                best = Some((l, d));
            }
        }
        best.map(|(l, _)| l)
    }
}
