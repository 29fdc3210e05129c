//! Construction (paper section 4, figure 4 left): for every IRPL, render the scene around
//! it through a [`GBufferRenderer`] (hemicube sampling, section 4.1), compute each pixel's
//! irradiance from the IRPL in software while warping (eq. 2, the paper's accurate
//! option), and splat it into the LDC (section 4.3).
//!
//! Splatting: a hemicube pixel's footprint on its surface is its solid angle times `r^2 /
//! cos_x`, projected onto the LDI; the sample is copied to every LDI pixel whose centre
//! lies within the footprint (the paper's nearest-neighbour copies, "sized by distance and
//! orientation") or weighted by a Gaussian of the footprint's size (the kernel the paper
//! planned, section 6.2). Overlapping splats of one IRPL in one layer are combined (nearest
//! sample, or weighted mean), never summed twice. Beyond the paper, a copy is kept only if
//! the IRPL's own render sees it on the same plane (the render is its own shadow map), so
//! a splat never crosses a wall or spills under an occluder.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use scene_core::gbuffer::hemicube_views;
use scene_core::ray::RayScene;
use scene_core::view::{FrustumReconstruction, Projection, pixel_uv};
use scene_core::{GBuffer, GBufferRenderer, LightState, Scene, View, ViewTarget, luminance};

use crate::error::IbrrError;
use crate::estimate::{BatchSums, ErrorEstimate, Probes, Stop};
use crate::irpl::{Irpl, IrplKind, IrplSet, WalkSettings, generate};
use crate::ldc::{Channel, Combine, Ldc, LdcBuilder, LdcFrame, axes_of};
use crate::settings::{IbrrSettings, Splat};

/// One surface sample of an IRPL's render.
#[derive(Clone, Copy, Debug)]
struct Sample {
    p: Vec3,
    n: Vec3,
    /// The IRPL's irradiance at `p` (the paper's kernels copy it; zero until the warp
    /// fills it in).
    value: Vec3,
    /// How the surface point moves for one pixel step right and down in the render: the
    /// pixel's footprint on its surface (a parallelogram), by distance and orientation.
    du: Vec3,
    dv: Vec3,
}

impl Sample {
    /// The larger side of the footprint (world units).
    fn footprint(&self) -> f32 {
        self.du.length().max(self.dv.length())
    }
}

/// Figures of a construction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConstructionStats {
    /// IRPLs warped so far.
    pub irpls_done: usize,
    /// IRPLs in all.
    pub irpls_total: usize,
    /// Complete particle paths warped so far (the divisor of path sums).
    pub paths_done: u64,
    /// Surface samples warped.
    pub samples: u64,
    /// Splat copies refused because the IRPL's render does not see them.
    pub copies_hidden: u64,
    /// Time in the G-buffer renderer.
    pub render_time: Duration,
    /// Time warping and splatting.
    pub warp_time: Duration,
    /// Time generating the IRPLs.
    pub walk_time: Duration,
    /// Time of the clamp's local compensation (last complete LDC).
    pub compensation_time: Duration,
    /// Rays of the clamp's local compensation, and those that added light.
    pub compensation: crate::compensate::CompensationStats,
}

/// An LDC being built, IRPL by IRPL, viewable at any point ([`Construction::ldc`]).
#[derive(Debug)]
pub struct Construction {
    /// The scene.
    pub scene: Arc<Scene>,
    /// The settings it was started with.
    pub settings: IbrrSettings,
    /// The IRPLs.
    pub irpls: IrplSet,
    /// The light state the IRPLs were made for.
    pub lights: LightState,
    /// The light sources whose light the LDC keeps apart
    /// ([`scene_core::lights::light_ids`]'s order; the LDC's per-source values follow it).
    pub sources: Vec<scene_core::LightId>,
    builder: LdcBuilder,
    next: usize,
    /// The exact mode's first pass: every IRPL founds its layers before any lights them,
    /// so that every layer receives every IRPL that sees it whatever the IRPL order (a
    /// layer founded by a later IRPL would otherwise miss the earlier ones' light).
    founding: bool,
    /// First IRPL of the current round (0 for the first; [`Construction::extend`] starts
    /// the next).
    round_start: usize,
    /// The order the founding pass takes the IRPLs in: each round's, sorted by
    /// [`founding_key`], so the layers founded (and so every plane) do not depend on the
    /// order the IRPLs were given in.
    founding_order: Vec<usize>,
    /// Layers that existed before the current round.
    layers_before: usize,
    /// The exact mode's catch-up pass of a later round: the earlier IRPLs light the layers
    /// the round founded, so that every layer receives every IRPL whatever the round.
    catch_up: bool,
    /// The current round's catch-up pass is done.
    caught_up: bool,
    /// Warps done and to do, over every pass and round so far.
    steps: (usize, usize),
    /// Rounds added by [`Construction::extend`].
    rounds: usize,
    /// The LDC of the last complete round, shown while a later round is built.
    last_complete: Option<Ldc>,
    stats: ConstructionStats,
    /// The exact mode's gather on the GPU, when asked for ([`Construction::gather_on_gpu`]).
    gpu: Option<crate::gpu::GpuGather>,
    /// Where the build's error estimate looks (made once the first round's layers are
    /// founded; the exact mode only).
    probes: Option<Probes>,
    /// The probes' light per batch of paths.
    sums: BatchSums,
    /// When the construction started (the time budget counts from here).
    started: Instant,
    /// Why the last [`Construction::build`] stopped adding rounds.
    stopped: Option<Stop>,
}

/// What [`Construction::plan`] says comes after a finished round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plan {
    /// Another round of this many paths.
    More(u64),
    /// No further round, and why.
    Stop(Stop),
}

impl Construction {
    /// Generates the IRPLs of `scene` under `lights` and an empty LDC. Errors on invalid
    /// settings and when the empty LDC exceeds the memory budget.
    pub fn new(
        scene: Arc<Scene>,
        lights: &LightState,
        settings: &IbrrSettings,
    ) -> Result<Self, IbrrError> {
        settings.check()?;
        lights
            .check(&scene)
            .map_err(|e| IbrrError::Settings(format!("light state: {e}")))?;
        let t = Instant::now();
        let rays = RayScene::build(&scene);
        let irpls = generate(
            &scene,
            &rays,
            lights,
            &WalkSettings {
                irpls: settings.irpls,
                seed: settings.seed,
                max_depth: settings.max_depth,
                paths: settings.paths,
                camera_importance: settings.camera_importance,
                entry_importance: settings.entry_importance,
            },
        );
        let walk_time = t.elapsed();
        let mut c = Self::with_irpls(scene, irpls, settings)?;
        c.lights = lights.clone();
        c.stats.walk_time = walk_time;
        c.started = t;
        Ok(c)
    }

    /// A construction over given IRPLs (for experiments and tests: one IRPL above a
    /// plane, hand-placed lights), built for the default light state.
    pub fn with_irpls(
        scene: Arc<Scene>,
        irpls: IrplSet,
        settings: &IbrrSettings,
    ) -> Result<Self, IbrrError> {
        settings.check()?;
        let b = scene.bounds();
        let frame = if b.is_empty() {
            LdcFrame::around(
                Vec3::ZERO,
                Vec3::ZERO,
                settings.resolution,
                settings.eps_distance_px,
                settings.eps_normal,
                settings.band,
            )
        } else {
            LdcFrame::around(
                b.min,
                b.max,
                settings.resolution,
                settings.eps_distance_px,
                settings.eps_normal,
                settings.band,
            )
        };
        let sources = scene_core::lights::light_ids(&scene);
        let builder = LdcBuilder::new(frame, settings.max_bytes, sources.len())?;
        let steps_total = irpls.irpls.len() * if settings.splat == Splat::Exact { 2 } else { 1 };
        let order = founding_order(&irpls.irpls, 0);
        Ok(Self {
            stats: ConstructionStats {
                irpls_total: irpls.irpls.len(),
                ..Default::default()
            },
            scene,
            settings: *settings,
            irpls,
            lights: LightState::default(),
            sources,
            builder,
            next: 0,
            founding: settings.splat == Splat::Exact,
            round_start: 0,
            founding_order: order,
            layers_before: 0,
            catch_up: false,
            caught_up: false,
            steps: (0, steps_total),
            rounds: 0,
            last_complete: None,
            gpu: None,
            probes: None,
            sums: BatchSums::default(),
            started: Instant::now(),
            stopped: None,
        })
    }

    /// Runs the exact mode's gather (every layer, tested against the IRPL's renders) on
    /// the GPU of `ctx`; the scatter stays on the CPU. The values
    /// agree with the CPU gather's but for f32 rounding at a visibility threshold.
    pub fn gather_on_gpu(&mut self, ctx: &scene_core::gpu::GpuContext) -> Result<(), IbrrError> {
        self.gpu = Some(crate::gpu::GpuGather::new(ctx)?);
        Ok(())
    }

    /// True when every IRPL has been warped (and, after [`Construction::extend`], every
    /// layer the new round founded has the earlier IRPLs' light).
    pub fn is_done(&self) -> bool {
        !self.founding
            && !self.catch_up
            && self.next >= self.irpls.irpls.len()
            && (self.round_start == 0 || self.caught_up || self.settings.splat != Splat::Exact)
    }

    /// True while the exact mode founds its layers (nothing is lit yet).
    pub fn is_founding(&self) -> bool {
        self.founding
    }

    /// IRPL steps done and in all, over both passes of the exact mode (founding, then
    /// lighting: twice the IRPLs) or the one pass of the paper's kernels, and over the
    /// rounds [`Construction::extend`] added (the new IRPLs twice, the earlier ones once
    /// more for the catch-up).
    pub fn progress(&self) -> (usize, usize) {
        (self.steps.0.min(self.steps.1), self.steps.1)
    }

    /// Adds a round of `more_paths` particle paths (the next ones of the same walk,
    /// [`crate::irpl::extend`]) to a finished construction: their IRPLs found their layers,
    /// light every layer, and the earlier IRPLs light the layers the round founded; the
    /// result equals a construction that had asked for all the paths at once, but for
    /// float summation order. Until the round is done, [`Construction::ldc`] shows the
    /// last complete one. Returns the number of IRPLs added.
    pub fn extend(&mut self, more_paths: u64) -> Result<usize, IbrrError> {
        self.extend_keeping(more_paths, true)
    }

    /// [`Construction::extend`], keeping the last complete LDC for viewing during the
    /// round only when `keep_last` ([`Construction::build`] shows nothing meanwhile).
    fn extend_keeping(&mut self, more_paths: u64, keep_last: bool) -> Result<usize, IbrrError> {
        if !self.is_done() {
            return Err(IbrrError::Settings(
                "extend: the construction's current round is not finished".into(),
            ));
        }
        if more_paths == 0 || self.irpls.paths == 0 {
            return Ok(0);
        }
        self.stopped = None;
        if keep_last {
            let last = self.ldc()?;
            self.last_complete = Some(last);
        }
        let t = Instant::now();
        let rays = RayScene::build(&self.scene);
        let s = &self.settings;
        let before = self.irpls.irpls.len();
        crate::irpl::extend(
            &self.scene,
            &rays,
            &self.lights,
            &WalkSettings {
                irpls: s.irpls,
                seed: s.seed,
                max_depth: s.max_depth,
                paths: 0,
                camera_importance: s.camera_importance,
                entry_importance: s.entry_importance,
            },
            &mut self.irpls,
            more_paths,
        );
        self.stats.walk_time += t.elapsed();
        let added = self.irpls.irpls.len() - before;
        let exact = self.settings.splat == Splat::Exact;
        self.founding_order
            .extend(founding_order(&self.irpls.irpls, before));
        self.round_start = before;
        self.layers_before = self.builder.layer_count();
        self.founding = exact;
        self.catch_up = false;
        self.caught_up = false;
        self.next = before;
        self.steps.1 += if exact { 2 * added + before } else { added };
        self.stats.irpls_total = self.irpls.irpls.len();
        self.rounds += 1;
        Ok(added)
    }

    /// The build's estimate of its own error on lit surfaces ([`crate::estimate`]), once
    /// every IRPL is warped; `None` before, for the paper's kernels (the exact mode only),
    /// and when the probes see no light or fewer than two batches hold paths.
    pub fn error_estimate(&self) -> Option<ErrorEstimate> {
        let probes = self.probes.as_ref()?;
        if !self.is_done() {
            return None;
        }
        self.sums.estimate(self.irpls.paths, probes.points)
    }

    /// Why the last [`Construction::build`] (or progressive refinement) stopped adding
    /// rounds (`None` before it ends).
    pub fn stopped(&self) -> Option<Stop> {
        self.stopped
    }

    /// The build in a line, for logs and panels: IRPLs, paths and rounds, the stated
    /// error ([`Construction::error_estimate`]) and what ended the build.
    pub fn describe(&self) -> String {
        let stated = match self.error_estimate() {
            Some(e) => format!(
                "stated error {:.1} % (95 %, largest channel)",
                100.0 * e.worst()
            ),
            None => "no error estimate".into(),
        };
        format!(
            "{} IRPLs ({} paths, {} rounds), {stated}, stopped by {}",
            self.irpls.irpls.len(),
            self.irpls.paths,
            self.rounds + 1,
            self.stopped.map_or("-", Stop::name)
        )
    }

    /// Records why refinement stopped adding rounds, once a finished round plans none
    /// ([`Construction::plan`]; progressive refinement with its own IRPL count: that
    /// count).
    pub(crate) fn mark_stopped(&mut self) {
        if self.stopped.is_none() && self.is_done() {
            self.stopped = Some(match self.plan() {
                Plan::Stop(s) => s,
                Plan::More(_) => Stop::Count,
            });
        }
    }

    /// What comes after a finished round under [`IbrrSettings::target_error`]: another
    /// round of paths, enough by the estimate's `1 / sqrt(paths)` fall to meet the target
    /// (at least 1.5 and at most 4 times the paths so far, within the IRPL budget), or
    /// the reason to stop.
    pub fn plan(&self) -> Plan {
        let s = &self.settings;
        if s.target_error <= 0.0 {
            return Plan::Stop(Stop::Count);
        }
        let paths = self.irpls.paths;
        let Some(e) = self.error_estimate() else {
            return Plan::Stop(Stop::NoEstimate);
        };
        let (worst, target) = (e.worst(), f64::from(s.target_error));
        if worst <= target {
            return Plan::Stop(Stop::Target);
        }
        if s.time_budget > 0.0 && self.started.elapsed().as_secs_f64() >= f64::from(s.time_budget) {
            return Plan::Stop(Stop::TimeBudget);
        }
        let room = f64::from(s.budget()) - self.irpls.irpls.len() as f64;
        let most = self.paths_for(room).floor();
        // A round smaller than a quarter of the paths so far costs a catch-up over every
        // earlier IRPL for little.
        if most < 0.25 * paths as f64 {
            return Plan::Stop(Stop::IrplBudget);
        }
        let n = paths as f64;
        let wanted = n * (worst / target).powi(2) * 1.1;
        let total = wanted.clamp(1.5 * n, 4.0 * n);
        Plan::More(((total - n).ceil()).min(most).max(1.0) as u64)
    }

    /// About how many paths make `irpls` more IRPLs, at the mean IRPLs per path so far
    /// (exact sources left out).
    pub(crate) fn paths_for(&self, irpls: f64) -> f64 {
        let per_path = self.irpls.irpls.len().saturating_sub(self.irpls.exact) as f64
            / self.irpls.paths.max(1) as f64;
        irpls / per_path.max(1e-9)
    }

    /// Warps every IRPL through `renderer` (prepared with [`Construction::prepare_renderer`]),
    /// then adds rounds while [`Construction::plan`] asks for them, reporting `(steps done,
    /// steps total)` to `progress` (the total grows with each round). Returns why it
    /// stopped ([`Construction::stopped`]).
    pub fn build(
        &mut self,
        renderer: &mut dyn GBufferRenderer,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Stop, IbrrError> {
        loop {
            while !self.is_done() {
                self.step(renderer, 16)?;
                let (done, total) = self.progress();
                progress(done, total);
            }
            match self.plan() {
                Plan::More(paths) => {
                    if self.extend_keeping(paths, false)? == 0 {
                        self.stopped = Some(Stop::NoEstimate);
                        return Ok(Stop::NoEstimate);
                    }
                }
                Plan::Stop(stop) => {
                    self.stopped = Some(stop);
                    return Ok(stop);
                }
            }
        }
    }

    /// Rounds added by [`Construction::extend`] (0: the first round only).
    pub fn round(&self) -> usize {
        self.rounds
    }

    /// Moves to the next pass when the current one is finished.
    fn advance(&mut self) {
        let n = self.irpls.irpls.len();
        loop {
            if self.founding && self.next >= n {
                // Lighting: the round's IRPLs over every layer.
                self.founding = false;
                self.next = self.round_start;
                if self.round_start == 0 {
                    self.builder.reset_values();
                } else {
                    self.builder.reset_scratch();
                }
            } else if !self.founding
                && !self.catch_up
                && !self.caught_up
                && self.round_start > 0
                && self.settings.splat == Splat::Exact
                && self.next >= n
            {
                // Catch-up: the earlier IRPLs over the layers this round founded.
                self.catch_up = true;
                self.next = 0;
                self.builder.reset_scratch();
                self.builder.light_only_from(self.layers_before);
            } else if self.catch_up && self.next >= self.round_start {
                self.catch_up = false;
                self.caught_up = true;
                self.next = n;
                self.builder.light_only_from(0);
                self.builder.reset_scratch();
            } else {
                break;
            }
        }
    }

    /// Figures so far.
    pub fn stats(&self) -> ConstructionStats {
        self.stats
    }

    /// Layers so far.
    pub fn layer_count(&self) -> usize {
        self.builder.layer_count()
    }

    /// Warps up to `count` more IRPLs, rendering through `renderer` (prepared with this
    /// construction's scene by the caller, see [`Construction::prepare_renderer`]).
    /// Returns the number warped. On an error (budget, renderer) the construction stays
    /// as it was before the failing IRPL's splats were finished... except for layers the
    /// failing IRPL inserted; callers drop it on error.
    pub fn step(
        &mut self,
        renderer: &mut dyn GBufferRenderer,
        count: usize,
    ) -> Result<usize, IbrrError> {
        self.advance();
        if self.probes.is_none()
            && !self.founding
            && self.round_start == 0
            && self.settings.splat == Splat::Exact
        {
            self.probes = Some(Probes::new(&self.scene, &self.builder, renderer)?);
        }
        let pass_end = if self.catch_up {
            self.round_start
        } else {
            self.irpls.irpls.len()
        };
        let end = (self.next + count).min(pass_end);
        let mut done = 0;
        // Render in batches of up to 8 IRPLs (one submission each on the GPU) whose renders
        // fit beside the LDC in the memory budget.
        const BATCH: usize = 8;
        while self.next < end {
            let room = self.settings.max_bytes.saturating_sub(self.builder.bytes());
            let mut irpls: Vec<Irpl> = Vec::new();
            let mut targets = Vec::new();
            let mut counts = Vec::new();
            let mut bytes = 0u64;
            for k in self.next..(self.next + BATCH).min(end) {
                let irpl = &self.irpls.irpls[if self.founding {
                    self.founding_order[k]
                } else {
                    k
                }];
                let views = self.views_of(irpl);
                let need: u64 = views.iter().map(|v| render_bytes(v.width, v.height)).sum();
                if bytes + need > room {
                    if irpls.is_empty() {
                        return Err(IbrrError::Budget {
                            needed: self.builder.bytes() + need,
                            limit: self.settings.max_bytes,
                            what: format!(
                                "the {} renders of one IRPL ({} x {} hemicube faces and up) beside the LDC",
                                views.len(),
                                views[0].width,
                                views[0].height
                            ),
                        });
                    }
                    break;
                }
                bytes += need;
                counts.push(views.len());
                targets.extend(views);
                irpls.push(*irpl);
            }
            let t = Instant::now();
            let buffers = renderer.render_views(&targets)?;
            if buffers.len() != targets.len() {
                return Err(IbrrError::Core(scene_core::Error::InvalidArgument(
                    format!(
                        "renderer '{}' returned {} images for {} views",
                        renderer.name(),
                        buffers.len(),
                        targets.len()
                    ),
                )));
            }
            self.stats.render_time += t.elapsed();
            let t = Instant::now();
            let mut at = 0;
            for (irpl, &c) in irpls.iter().zip(&counts) {
                self.warp(irpl, &targets[at..at + c], &buffers[at..at + c])?;
                at += c;
                self.next += 1;
                self.steps.0 += 1;
                done += 1;
            }
            self.stats.warp_time += t.elapsed();
        }
        self.advance();
        if self.founding || self.catch_up {
            return Ok(done);
        }
        self.stats.irpls_done = self.next;
        let exact = self.irpls.exact;
        self.stats.paths_done = if self.next <= exact {
            0
        } else {
            self.irpls.path_ends.partition_point(|&e| e <= self.next) as u64
        };
        if self.is_done() {
            self.stats.paths_done = self.irpls.paths;
        }
        Ok(done)
    }

    /// Prepares `renderer` with this construction's scene (once, before [`Construction::step`]).
    pub fn prepare_renderer(&self, renderer: &mut dyn GBufferRenderer) -> Result<(), IbrrError> {
        let same = renderer
            .prepared_scene()
            .is_some_and(|s| Arc::ptr_eq(s, &self.scene));
        if !same {
            renderer.prepare(self.scene.clone())?;
        }
        Ok(())
    }

    /// The LDC so far: path sums divided by the complete paths warped (progressive
    /// viewing; partially warped paths count once complete), lit as the light state it was
    /// built for; [`Ldc::relight`] with [`Construction::relight_factors`] shows another.
    pub fn ldc(&mut self) -> Result<Ldc, IbrrError> {
        if !self.is_done()
            && let Some(last) = &self.last_complete
        {
            return Ok(last.clone());
        }
        let paths = if self.is_done() {
            self.irpls.paths
        } else {
            self.stats.paths_done
        };
        let mut ldc =
            self.builder
                .compact(paths, self.settings.source_precision, &self.unit_factors())?;
        let s = &self.settings;
        if self.is_done() && s.clamp > 0.0 && s.compensation == crate::settings::Compensation::Local
        {
            let t = Instant::now();
            let r = s.clamp * self.scene.extent();
            let g_max = std::f32::consts::FRAC_1_PI / (r * r);
            self.stats.compensation = crate::compensate::compensate(
                &self.scene,
                &mut ldc,
                &self.sources,
                &crate::compensate::Options {
                    g_max,
                    rays: s.compensation_rays,
                    levels: s.compensation_levels,
                    seed: s.seed,
                    // Reflected light only where the walks carry some (paths that bounce).
                    reflected: s.max_depth > 0 && self.irpls.paths > 0,
                },
            );
            self.stats.compensation_time = t.elapsed();
            ldc.relight(&vec![[Vec3::ONE; 2]; ldc.sources.sources()]);
        }
        if !self.lights.is_default()
            && let Some(f) = self.relight_factors(&self.lights)
        {
            ldc.relight(&f);
        }
        Ok(ldc)
    }

    /// Per source, the inverse of the light factors its IRPLs were made with (0 where a
    /// factor is 0: that source's light cannot be brought back without a rebuild).
    fn unit_factors(&self) -> Vec<[Vec3; 2]> {
        let inv = |v: Vec3| Vec3::select(v.cmpgt(Vec3::ZERO), v.recip(), Vec3::ZERO);
        self.sources
            .iter()
            .map(|&id| {
                let s = self.lights.get(id);
                [inv(s.direct_factor()), inv(s.indirect_factor())]
            })
            .collect()
    }

    /// The factors that make an LDC of this construction ([`Construction::ldc`], values per
    /// unit of each source's factors) show `state`, for [`Ldc::relight`]; `None` when
    /// `state` lights a source (or a channel of one) that the IRPLs were made without, so
    /// that only a rebuild can show it.
    pub fn relight_factors(&self, state: &LightState) -> Option<Vec<[Vec3; 2]>> {
        self.sources
            .iter()
            .map(|&id| {
                let (built, wanted) = (self.lights.get(id), state.get(id));
                let ok = |b: Vec3, w: Vec3| (w.cmple(Vec3::ZERO) | b.cmpgt(Vec3::ZERO)).all();
                (ok(built.direct_factor(), wanted.direct_factor())
                    && ok(built.indirect_factor(), wanted.indirect_factor()))
                .then(|| [wanted.direct_factor(), wanted.indirect_factor()])
            })
            .collect()
    }

    /// The views an IRPL renders: a hemicube (a full cube for a point light, an
    /// orthographic view for a directional light).
    fn views_of(&self, irpl: &Irpl) -> Vec<ViewTarget> {
        let extent = self.scene.extent();
        let (near, far) = (extent * 1e-5, extent * 2.0);
        let s = &self.settings;
        let res = if irpl.is_direct() {
            s.direct_resolution()
        } else {
            s.indirect_resolution()
        };
        let hemicube = |normal: Vec3| {
            hemicube_views(irpl.position, normal, near, far)
                .into_iter()
                .map(|(face, view)| {
                    let (w, h) = face.size(res);
                    ViewTarget::new(view, w, h)
                })
                .collect::<Vec<_>>()
        };
        match irpl.kind {
            IrplKind::PointSource { .. } => {
                let mut v = hemicube(Vec3::Z);
                v.extend(hemicube(-Vec3::Z));
                v
            }
            IrplKind::DirectionalSource { direction } => {
                let b = self.scene.bounds();
                let centre = if b.is_empty() { Vec3::ZERO } else { b.center() };
                let view = View::orthographic_fit(centre, direction, 0.5 * extent * 1.01);
                vec![ViewTarget::new(view, res, res)]
            }
            IrplKind::EmitterSample | IrplKind::Bounce => hemicube(irpl.normal),
        }
    }

    /// Warps one IRPL's renders into the LDC.
    fn warp(
        &mut self,
        irpl: &Irpl,
        targets: &[ViewTarget],
        buffers: &[GBuffer],
    ) -> Result<(), IbrrError> {
        let frame = self.builder.frame;
        let h = frame.pixel_size();
        let (combine, gaussian, exact) = match self.settings.splat {
            Splat::Nearest => (Combine::Nearest, false, false),
            Splat::Gaussian => (Combine::Weighted, true, false),
            Splat::Exact => (Combine::Nearest, false, true),
        };
        let max_r = self.settings.max_splat_px;
        let recon: Vec<FrustumReconstruction> = targets
            .iter()
            .map(|t| FrustumReconstruction::new(&t.view))
            .collect();
        let vps: Vec<glam::Mat4> = targets.iter().map(|t| t.view.view_projection()).collect();
        // The clamp; with the rescale compensation, the power the renders receive,
        // unclamped over clamped, scales every value of this IRPL (the local compensation
        // runs once the LDC is complete, `Construction::ldc`).
        let extent = self.scene.extent();
        let g_max = if self.settings.clamp > 0.0 && irpl.is_path_node() {
            let r = self.settings.clamp * extent;
            std::f32::consts::FRAC_1_PI / (r * r)
        } else {
            f32::INFINITY
        };
        let all: Vec<Vec<Sample>> = targets
            .iter()
            .enumerate()
            .map(|(k, t)| samples_of(t, &recon[k], &buffers[k]))
            .collect();
        let rescale = self.settings.compensation == crate::settings::Compensation::Rescale;
        let scale = if g_max.is_finite() && rescale {
            let (mut full, mut clamped) = (0.0f64, 0.0f64);
            for s in all.iter().flatten() {
                let area = f64::from(s.du.cross(s.dv).length());
                full += f64::from(luminance(irpl.irradiance_at(s.p, s.n))) * area;
                clamped += f64::from(luminance(irpl.irradiance_clamped(s.p, s.n, g_max))) * area;
            }
            if clamped > 0.0 && full.is_finite() {
                (full / clamped) as f32
            } else {
                1.0
            }
        } else {
            1.0
        };
        let value_at = |q: Vec3, n: Vec3| irpl.irradiance_clamped(q, n, g_max) * scale;
        let founding = self.founding;
        // The exact mode lights every layer by the gather below, at the layer's centre on
        // its own plane, the geometry term times the share of that centre the renders see:
        // its samples only found layers (in the founding pass). Lighting a sample's home
        // layer wholly let occluders finer than an LDI pixel (a window blind's slats, seen
        // by a render finer than the LDC) stop nothing: the Breakfast Room's sun through its
        // blind read 2.7 to 4 times too bright.
        let splats = !exact || founding;
        self.builder.begin();
        for samples in all {
            if !founding {
                self.stats.samples += samples.len() as u64;
            }
            if !splats {
                continue;
            }
            for mut s in samples {
                // The paper's kernels copy the sample's own value (clamped and compensated
                // like every other); the exact mode only founds layers here.
                if !exact {
                    s.value = value_at(s.p, s.n);
                }
                let plane_d = s.p.dot(s.n);
                for (axis, w) in axes_of(s.n, frame.band) {
                    if w <= 0.0 {
                        continue;
                    }
                    let (ua, va) = LdcFrame::image_axes(axis);
                    let c = frame.pixel_coords(axis, s.p);
                    // The footprint in LDI pixels as an ellipse: covariance of half a render
                    // pixel along each footprint axis, widened by half an LDI pixel so that a
                    // footprint smaller than an LDI pixel still reaches its own pixel.
                    let a = Vec2::new(s.du[ua], s.du[va]) / h;
                    let b = Vec2::new(s.dv[ua], s.dv[va]) / h;
                    let cov = [
                        0.25 * (a.x * a.x + b.x * b.x) + 0.25,
                        0.25 * (a.x * a.y + b.x * b.y),
                        0.25 * (a.y * a.y + b.y * b.y) + 0.25,
                    ];
                    let det = cov[0] * cov[2] - cov[1] * cov[1];
                    if !(det > 0.0 && det.is_finite()) {
                        continue;
                    }
                    let inv = [cov[2] / det, -cov[1] / det, cov[0] / det];
                    // Nearest: the footprint itself (Mahalanobis 1); Gaussian: 3 sigma.
                    let k2 = if gaussian { 9.0 } else { 1.0 };
                    let ru = (k2 * cov[0]).sqrt().min(max_r);
                    let rv = (k2 * cov[2]).sqrt().min(max_r);
                    let (i0, i1) = ((c.x - ru).floor() as i64, (c.x + ru).floor() as i64);
                    let (j0, j1) = ((c.y - rv).floor() as i64, (c.y + rv).floor() as i64);
                    let home = (c.x.floor() as i64, c.y.floor() as i64);
                    for j in j0..=j1 {
                        for i in i0..=i1 {
                            let d = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) - c;
                            let m2 =
                                d.x * d.x * inv[0] + 2.0 * d.x * d.y * inv[1] + d.y * d.y * inv[2];
                            let is_home = (i, j) == home;
                            if !is_home && m2 > k2 {
                                continue;
                            }
                            // Exact mode: a copy only founds a layer where none is yet.
                            if exact && !is_home && self.builder.has_layer(axis, i, j, s.p, s.n) {
                                continue;
                            }
                            let Some(q) = frame.point_on_plane(axis, i, j, s.n.extend(plane_d))
                            else {
                                continue;
                            };
                            let reached = !exact
                                && !is_home
                                && self.builder.stamped(axis, i, j, q, s.n).is_some();
                            if !reached
                                && !is_home
                                && !seen_on_plane(
                                    q,
                                    s.n,
                                    s.footprint(),
                                    frame.eps_distance,
                                    frame.eps_normal,
                                    &vps,
                                    &recon,
                                    buffers,
                                )
                            {
                                self.stats.copies_hidden += u64::from(!founding);
                                continue;
                            }
                            if founding {
                                self.builder.found(axis, i, j, q, s.n)?;
                                continue;
                            }
                            let weight = if gaussian { (-0.5 * m2).exp() } else { 1.0 };
                            // The sample's own value, as the paper copies it.
                            let value = if s.value.is_finite() {
                                s.value
                            } else {
                                Vec3::ZERO
                            };
                            self.builder
                                .splat(axis, i, j, q, s.n, value, m2, weight, combine)?;
                        }
                    }
                }
            }
        }
        if founding {
            return Ok(());
        }
        if exact {
            // Every layer, lit by the share of its centre that no surface of the IRPL's
            // renders lies in front of (`unoccluded`).
            let (eps_d, eps_n) = (frame.eps_distance, frame.eps_normal);
            if let Some(g) = self.gpu.as_mut() {
                let values = g.gather(&self.builder, irpl, g_max, scale, targets, buffers)?;
                self.builder.apply_gathered(&values);
            } else {
                let renders: Vec<Render> = targets
                    .iter()
                    .zip(&recon)
                    .zip(&vps)
                    .zip(buffers)
                    .map(|(((t, r), vp), g)| Render::new(&t.view, *r, *vp, g))
                    .collect();
                self.builder.gather(|q, n| {
                    let e = value_at(q, n);
                    if !(e.max_element() > 0.0 && e.is_finite()) {
                        return None;
                    }
                    let seen = unoccluded(&renders, q, n, eps_d, eps_n);
                    (seen > 0.0).then_some(e * seen)
                });
            }
        }
        let channel = match irpl.kind {
            IrplKind::PointSource { .. } | IrplKind::DirectionalSource { .. } => Channel::Exact,
            IrplKind::EmitterSample => Channel::Direct,
            IrplKind::Bounce => Channel::Indirect,
        };
        let source = self
            .sources
            .iter()
            .position(|&id| id == irpl.light)
            .unwrap_or(0);
        if !self.catch_up
            && let Some(probes) = &self.probes
        {
            let path = irpl.is_path_node().then_some(irpl.path);
            self.sums.add(path, probes.read(&self.builder));
        }
        self.builder.finish(channel, source);
        Ok(())
    }
}

/// The surface samples of one render of an IRPL: position, normal and footprint of every
/// pixel that hit geometry (values are filled in by the warp, once the clamp's compensation
/// is known).
fn samples_of(target: &ViewTarget, recon: &FrustumReconstruction, g: &GBuffer) -> Vec<Sample> {
    let (w, hgt) = (g.width, g.height);
    let view = &target.view;
    let (right, up) = (view.right(), view.up);
    let (dx, dy, perspective) = match view.projection {
        Projection::Perspective {
            left,
            right,
            bottom,
            top,
        } => ((right - left) / w as f32, (top - bottom) / hgt as f32, true),
        Projection::Orthographic {
            left,
            right,
            bottom,
            top,
        } => (
            (right - left) / w as f32,
            (top - bottom) / hgt as f32,
            false,
        ),
    };
    (0..hgt)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).filter_map(move |x| {
                let i = (y * w + x) as usize;
                if g.is_background(i) {
                    return None;
                }
                let n = g.normal[i];
                let uv = pixel_uv(x, y, w, hgt);
                let p = recon.world(uv, g.depth[i]);
                if !p.is_finite() || n == Vec3::ZERO {
                    return None;
                }
                // Ray differentials on the surface's plane: a step of one pixel moves the
                // ray (direction `dir`, length `t` per unit `dir`) by `dx right` or `dy up`;
                // the hit moves by `t (e - dir (n . e) / (n . dir))`, floored at a grazing
                // cosine of 1e-3.
                let (dir, t) = if perspective {
                    let dir = p - view.eye;
                    let tf = dir.dot(view.forward);
                    (dir / tf.max(1e-30), tf)
                } else {
                    (view.forward, 1.0)
                };
                let nd = n.dot(dir);
                let nd = if nd.abs() < 1e-3 * dir.length() {
                    (1e-3 * dir.length()).copysign(nd)
                } else {
                    nd
                };
                let step = |e: Vec3| (e - dir * (n.dot(e) / nd)) * t;
                Some(Sample {
                    p,
                    n,
                    value: Vec3::ZERO,
                    du: step(right * dx),
                    dv: step(up * dy),
                })
            })
        })
        .collect()
}

/// True when the IRPL's renders see `q` on the plane with normal `n` (its own shadow map,
/// [`render_sees`]); false when no render covers `q`.
#[allow(clippy::too_many_arguments)]
fn seen_on_plane(
    q: Vec3,
    n: Vec3,
    footprint: f32,
    eps_distance: f32,
    eps_normal: f32,
    vps: &[glam::Mat4],
    recon: &[FrustumReconstruction],
    buffers: &[GBuffer],
) -> bool {
    let tol = eps_distance + 0.05 * footprint;
    for ((vp, r), g) in vps.iter().zip(recon).zip(buffers) {
        if let Some(seen) = render_sees(vp, r, g, q, n, tol, eps_normal) {
            return seen;
        }
    }
    false
}

/// Whether the render `g` (view-projection `vp`, reconstruction `r`) sees the point `q` on
/// the plane with normal `n`: the four pixels whose centres surround `q`'s projection all
/// hit geometry with a normal within `eps_normal` of `n` and a plane within `tol` of `q`.
/// A pixel straddling an edge sees one surface at its centre, so asking the neighbours
/// too keeps a point hidden just behind a corner from passing. `None` when `q` is behind
/// the view or outside its image.
pub(crate) fn render_sees(
    vp: &glam::Mat4,
    r: &FrustumReconstruction,
    g: &GBuffer,
    q: Vec3,
    n: Vec3,
    tol: f32,
    eps_normal: f32,
) -> Option<bool> {
    let clip = *vp * q.extend(1.0);
    if clip.w <= 0.0 {
        return None;
    }
    let (u, v) = (clip.x / clip.w * 0.5 + 0.5, 0.5 - clip.y / clip.w * 0.5);
    if !(0.0..1.0).contains(&u) || !(0.0..1.0).contains(&v) {
        return None;
    }
    let f = Vec2::new(u * g.width as f32 - 0.5, v * g.height as f32 - 0.5);
    let (x0, y0) = (f.x.floor() as i64, f.y.floor() as i64);
    let sees = |x: i64, y: i64| {
        let x = x.clamp(0, g.width as i64 - 1) as u32;
        let y = y.clamp(0, g.height as i64 - 1) as u32;
        let i = (y * g.width + x) as usize;
        if g.is_background(i) {
            return false;
        }
        let np = g.normal[i];
        let pp = r.world(pixel_uv(x, y, g.width, g.height), g.depth[i]);
        np.dot(n) > 1.0 - eps_normal && (q - pp).dot(np).abs() < tol
    };
    Some(sees(x0, y0) && sees(x0 + 1, y0) && sees(x0, y0 + 1) && sees(x0 + 1, y0 + 1))
}

/// Bytes of a `width x height` CPU G-buffer and the warp's copy of its samples (albedo,
/// normal, depth, id: 36 bytes; a sample: 60).
pub fn render_bytes(width: u32, height: u32) -> u64 {
    u64::from(width) * u64::from(height) * (36 + 60)
}

/// One render of an IRPL, prepared for visibility queries.
struct Render<'a> {
    view: &'a View,
    vp: glam::Mat4,
    recon: FrustumReconstruction,
    g: &'a GBuffer,
    /// Pixel width: tangent units (perspective) or world units (orthographic).
    pixel: f32,
    perspective: bool,
}

impl<'a> Render<'a> {
    fn new(view: &'a View, recon: FrustumReconstruction, vp: glam::Mat4, g: &'a GBuffer) -> Self {
        let (pixel, perspective) = match view.projection {
            Projection::Perspective { left, right, .. } => ((right - left) / g.width as f32, true),
            Projection::Orthographic { left, right, .. } => {
                ((right - left) / g.width as f32, false)
            }
        };
        Self {
            view,
            vp,
            recon,
            g,
            pixel,
            perspective,
        }
    }
}

/// The share of `q` the IRPL sees, from the first render covering `q` (the renders as a
/// shadow map of planes): of the four pixels around `q`'s projection, weighted bilinearly,
/// those that see `q`'s own plane, the background, or a surface whose plane the segment
/// from the IRPL to `q` does not cross before `q` near that pixel's point. Concave edges (a
/// floor meeting a wall behind it) stay lit; a point behind a wall is hidden. A fraction
/// rather than "any of the four occludes": that all-or-nothing test widened every shadow
/// by about a render pixel, which read 1.3 % dark in cornell's direct light (0.3 % now).
/// 0 when no render covers `q`.
fn unoccluded(renders: &[Render], q: Vec3, n: Vec3, eps_distance: f32, eps_normal: f32) -> f32 {
    for r in renders {
        let clip = r.vp * q.extend(1.0);
        if clip.w <= 0.0 {
            continue;
        }
        let (u, v) = (clip.x / clip.w * 0.5 + 0.5, 0.5 - clip.y / clip.w * 0.5);
        if !(0.0..1.0).contains(&u) || !(0.0..1.0).contains(&v) {
            continue;
        }
        if r.perspective && (q - r.view.eye).dot(r.view.forward) <= 0.0 {
            continue;
        }
        let g = r.g;
        let origin = if r.perspective {
            r.view.eye
        } else {
            q - r.view.forward * (q - r.view.eye).dot(r.view.forward)
        };
        let dq = q - origin;
        let len = dq.length();
        if len <= 0.0 {
            return 0.0;
        }
        let dir = dq / len;
        let f = Vec2::new(u * g.width as f32 - 0.5, v * g.height as f32 - 0.5);
        let (x0, y0) = (f.x.floor() as i64, f.y.floor() as i64);
        let (fx, fy) = (f.x - x0 as f32, f.y - y0 as f32);
        let mut seen = 0.0f32;
        for (x, y, w) in [
            (x0, y0, (1.0 - fx) * (1.0 - fy)),
            (x0 + 1, y0, fx * (1.0 - fy)),
            (x0, y0 + 1, (1.0 - fx) * fy),
            (x0 + 1, y0 + 1, fx * fy),
        ] {
            let x = x.clamp(0, g.width as i64 - 1) as u32;
            let y = y.clamp(0, g.height as i64 - 1) as u32;
            let i = (y * g.width + x) as usize;
            if g.is_background(i) {
                seen += w;
                continue;
            }
            let np = g.normal[i];
            let pp = r.recon.world(pixel_uv(x, y, g.width, g.height), g.depth[i]);
            if np.dot(n) > 1.0 - eps_normal && (q - pp).dot(np).abs() < eps_distance {
                seen += w;
                continue;
            }
            let denom = dq.dot(np);
            if denom.abs() <= 1e-12 * len {
                seen += w;
                continue;
            }
            let s = (pp - origin).dot(np) / denom;
            if s <= 0.0 || s >= 1.0 - eps_distance / len {
                seen += w;
                continue;
            }
            let c = origin + dq * s;
            let along = if r.perspective {
                (pp - origin).length() * r.pixel
            } else {
                r.pixel
            };
            let reach = 2.0 * along / np.dot(dir).abs().max(0.1);
            if (c - pp).length() >= reach {
                seen += w;
            }
        }
        return seen;
    }
    0.0
}

/// The indices `from..` of `irpls` in the order the founding pass takes them: exact sources
/// first, then path nodes by path and depth (the order the walks produce them in, so a
/// round added later keeps the order of asking for all its paths at once), ties broken by
/// position, normal and power. Which sample founds a layer decides its plane, so a fixed
/// order makes the layers independent of the order the IRPLs were given in.
fn founding_order(irpls: &[Irpl], from: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (from..irpls.len()).collect();
    order.sort_by_key(|&i| founding_key(&irpls[i]));
    order
}

/// The sort key of [`founding_order`].
fn founding_key(i: &Irpl) -> (bool, u32, u32, [u32; 3], [u32; 3], [u32; 3]) {
    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
    (
        i.is_path_node(),
        i.path,
        i.depth,
        bits(i.position),
        bits(i.normal),
        bits(i.power),
    )
}
