//! The build's own error estimate (beyond the paper): how far one build's lit surfaces may
//! be from the light its particle walks estimate, read from the build itself.
//!
//! The paths are dealt round robin into [`BATCHES`] batches, each walking its own
//! scrambled sequences ([`crate::irpl::batch_of`]), so every batch is an independent
//! replicate of the same randomised quasi-Monte Carlo estimate and the build is their
//! mean. Probes are the points the scene's cameras see on reflecting surfaces (a grid of
//! [`PROBE_COLUMNS`] columns per camera; every layer alike in a scene without cameras),
//! each read through the layers it looks up with the bilinear kernel. While the LDC is
//! lit, each IRPL's light on those layers is summed per batch (exact sources apart: they
//! are the same in every batch), weighted by the probes' albedo: each batch's lit-surface
//! mean radiance. The spread of the batch means gives the standard error of the build's
//! mean (batch means, weighted by the batches' path counts), and the stated error is the
//! half-width of its 95 % confidence interval (Student's t with one degree of freedom
//! fewer than the batches), relative to the mean, per channel.
//!
//! What it does not see: a bias that every batch shares (the clamp's compensation is
//! computed after the walks and left out; the LDC's resolution, the lookup's fallback).
//! How often the measured error falls within it is checked against the reference path
//! tracer (`tests/calibration.rs`, docs/ibrr-ldc.md).

use std::collections::BTreeMap;

use glam::Vec3;
use scene_core::view::{FrustumReconstruction, pixel_uv};
use scene_core::{GBufferRenderer, Scene, View};

use crate::error::IbrrError;
pub use crate::irpl::BATCHES;
use crate::irpl::{batch_of, paths_in_batch};
use crate::ldc::LdcBuilder;

/// Columns of each camera's grid of probe points (rows follow its aspect).
pub const PROBE_COLUMNS: u32 = 64;

/// Student's t at 97.5 % for 1 to 15 degrees of freedom (a two-sided 95 % interval).
const T_975: [f64; 15] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131,
];

/// Where the estimate looks: per layer (the builder's index), the weight of its light in
/// the probes' mean radiance (`albedo / pi` times the bilinear weight, over the probe
/// count).
#[derive(Clone, Debug, Default)]
pub struct Probes {
    layers: Vec<(u32, Vec3)>,
    /// Probe points (camera samples on reflecting surfaces, or layers).
    pub points: usize,
}

impl Probes {
    /// The probes of `scene` on the layers `builder` has founded: the scene's cameras'
    /// grids through `renderer` (prepared with `scene`), or, without cameras, every layer
    /// with weight one.
    pub fn new(
        scene: &Scene,
        builder: &LdcBuilder,
        renderer: &mut dyn GBufferRenderer,
    ) -> Result<Self, IbrrError> {
        if scene.cameras.is_empty() {
            let n = builder.layer_count();
            return Ok(Self {
                layers: (0..n as u32).map(|l| (l, Vec3::ONE / n as f32)).collect(),
                points: n,
            });
        }
        let offsets = scene.mesh_offsets();
        let mut weights: BTreeMap<u32, Vec3> = BTreeMap::new();
        let mut points = 0usize;
        let mut around = Vec::new();
        for camera in &scene.cameras {
            let view = View::from_camera(camera);
            let cols = PROBE_COLUMNS;
            let rows = ((cols as f32 / camera.aspect.max(1e-3)).round() as u32).clamp(1, 4 * cols);
            let g = renderer.render_view(&view, cols, rows)?;
            let recon = FrustumReconstruction::new(&view);
            for i in 0..g.len() {
                if g.is_background(i) || g.normal[i] == Vec3::ZERO {
                    continue;
                }
                let emissive = scene
                    .triangle_ref(&offsets, g.triangle_id[i])
                    .is_some_and(|t| {
                        let m = scene.meshes[t.mesh as usize].material_ids[t.local as usize];
                        scene
                            .materials
                            .get(m as usize)
                            .is_some_and(|m| m.is_emissive())
                    });
                let albedo = g.albedo[i].truncate();
                if emissive || albedo.max_element() <= 0.0 {
                    continue;
                }
                let (x, y) = (i as u32 % g.width, i as u32 / g.width);
                let p = recon.world(pixel_uv(x, y, g.width, g.height), g.depth[i]);
                if !p.is_finite() {
                    continue;
                }
                points += 1;
                builder.layer_weights(p, g.normal[i], &mut around);
                for &(l, w) in &around {
                    *weights.entry(l as u32).or_default() +=
                        albedo * (w * std::f32::consts::FRAC_1_PI);
                }
            }
        }
        let inv = 1.0 / points.max(1) as f32;
        Ok(Self {
            layers: weights.into_iter().map(|(l, w)| (l, w * inv)).collect(),
            points,
        })
    }

    /// The probes' mean radiance from the current IRPL's light on the layers
    /// ([`LdcBuilder::current`]).
    pub(crate) fn read(&self, builder: &LdcBuilder) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        for &(l, w) in &self.layers {
            if let Some(v) = builder.current(l as usize) {
                let v = w * v;
                for c in 0..3 {
                    sum[c] += f64::from(v[c]);
                }
            }
        }
        sum
    }
}

/// The probes' light summed per batch while the LDC is lit.
#[derive(Clone, Debug, Default)]
pub struct BatchSums {
    /// The exact sources' light (the same in every batch).
    exact: [f64; 3],
    /// Per batch, its paths' light (summed over the paths, not yet divided by them).
    batches: Vec<[f64; 3]>,
}

impl BatchSums {
    /// Adds an IRPL's light at the probes: an exact source's (`path` `None`) or a path
    /// node's.
    pub(crate) fn add(&mut self, path: Option<u32>, value: [f64; 3]) {
        let slot = match path {
            None => &mut self.exact,
            Some(p) => {
                if self.batches.is_empty() {
                    self.batches = vec![[0.0; 3]; BATCHES as usize];
                }
                &mut self.batches[batch_of(p)]
            }
        };
        for c in 0..3 {
            slot[c] += value[c];
        }
    }

    /// The estimate for a build of `paths` paths; `None` with fewer than two batches
    /// holding paths, or where the probes receive no light.
    pub fn estimate(&self, paths: u64, probes: usize) -> Option<ErrorEstimate> {
        let used: Vec<(u64, [f64; 3])> = (0..BATCHES as usize)
            .map(|b| {
                (
                    paths_in_batch(paths, b),
                    self.batches.get(b).copied().unwrap_or([0.0; 3]),
                )
            })
            .filter(|&(n, _)| n > 0)
            .collect();
        if used.len() < 2 {
            return None;
        }
        let n_total = paths as f64;
        let mut mean = [0.0f64; 3];
        let mut relative = [0.0f64; 3];
        let t = T_975[(used.len() - 2).min(T_975.len() - 1)];
        for c in 0..3 {
            let pooled = used.iter().map(|(_, s)| s[c]).sum::<f64>() / n_total;
            // Batch means weighted by their path counts: sum n_b (m_b - m)^2 / (B - 1)
            // estimates the variance of one path's light.
            let var_path = used
                .iter()
                .map(|&(n, s)| n as f64 * (s[c] / n as f64 - pooled).powi(2))
                .sum::<f64>()
                / (used.len() - 1) as f64;
            mean[c] = self.exact[c] + pooled;
            let se = (var_path / n_total).sqrt();
            relative[c] = if mean[c] > 0.0 { t * se / mean[c] } else { 0.0 };
        }
        (mean.iter().any(|&m| m > 0.0) && mean.iter().all(|m| m.is_finite())).then_some(
            ErrorEstimate {
                mean,
                relative,
                batches: used.len() as u32,
                paths,
                probes,
            },
        )
    }
}

/// One build's estimate of its own error on lit surfaces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorEstimate {
    /// The probes' mean radiance per channel (the build's, before the clamp's
    /// compensation).
    pub mean: [f64; 3],
    /// Per channel, the half-width of the 95 % confidence interval of that mean, relative
    /// to it.
    pub relative: [f64; 3],
    /// Batches that hold paths.
    pub batches: u32,
    /// Paths of the build.
    pub paths: u64,
    /// Probe points.
    pub probes: usize,
}

impl ErrorEstimate {
    /// The largest channel's relative error: what a target is met by.
    pub fn worst(&self) -> f64 {
        self.relative.iter().copied().fold(0.0, f64::max)
    }
}

/// Why a construction stopped adding rounds of paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// No error target: the IRPL count asked for (the paper's).
    Count,
    /// The estimate fell below the target.
    Target,
    /// The IRPL budget ([`crate::IbrrSettings::irpl_budget`]) would be exceeded.
    IrplBudget,
    /// The time budget ([`crate::IbrrSettings::time_budget`]) ran out.
    TimeBudget,
    /// The build cannot estimate its error (no paths, no probes, or no light on them);
    /// nothing more was walked.
    NoEstimate,
}

impl Stop {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Stop::Count => "irpl count",
            Stop::Target => "target met",
            Stop::IrplBudget => "irpl budget",
            Stop::TimeBudget => "time budget",
            Stop::NoEstimate => "no estimate",
        }
    }
}
