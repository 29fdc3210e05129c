//! The IBRR as a [`Technique`]: `prepare` constructs the LDC (or, with
//! [`IbrrTechnique::progressive`], only starts it and lets [`Technique::refine`] add IRPLs
//! while frames show the LDC so far, then, up to [`IbrrTechnique::max_irpls`] or until a
//! round changes the LDC by less than [`IbrrTechnique::target_change`], rounds of further
//! paths, [`Construction::extend`]); `render` reconstructs a frame from the camera's
//! G-buffer.
//!
//! ```
//! use std::sync::Arc;
//! use ibrr_ldc::{IbrrSettings, IbrrTechnique};
//! use scene_core::{FrameRequest, LightState, LightId, Technique, builtin};
//! use scene_core::gbuffer::RayCastRenderer;
//!
//! let scene = Arc::new(builtin::scene("cornell-point").unwrap());
//! let settings = IbrrSettings { resolution: 32, irpls: 16, ..Default::default() };
//! let mut ibrr = IbrrTechnique::new(settings, Box::new(RayCastRenderer::new()));
//! ibrr.prepare(scene.clone()).unwrap();
//! let white = ibrr.render(&FrameRequest::camera(&scene.cameras[0], 32, 24)).unwrap();
//! // Recoloured: a relight of the layers, not a rebuild.
//! let mut red = LightState::default();
//! red.set_color(LightId::Point(0), glam::Vec3::new(1.0, 0.0, 0.0));
//! let image = ibrr
//!     .render(&FrameRequest::from_camera(&scene.cameras[0], 32, 24, &red))
//!     .unwrap();
//! assert!(ibrr.last_timings().rebuild.is_zero());
//! assert!(image.pixels.iter().all(|p| p.y == 0.0 && p.z == 0.0));
//! assert!(white.pixels.iter().any(|p| p.y > 0.0));
//! ```
//!
//! The LDC keeps each layer's light per source ([`crate::ldc::SourceValues`]), so a
//! frame's [`scene_core::LightState`] (recolour, dim, switch off, direct and indirect
//! multipliers) is applied by recombining the layers ([`crate::Ldc::relight`]), not by
//! rebuilding: a rebuild happens only when the state lights a source the IRPLs were made
//! without (a build under a state with that light off), and then under the default state,
//! from which every later state can be shown. Costs are in [`IbrrTechnique::last_timings`].

use std::sync::Arc;
use std::time::{Duration, Instant};

use scene_core::{Error, FrameRequest, GBufferRenderer, Image, LightState, Scene, Technique};

use crate::construct::{Construction, Plan};
use crate::error::IbrrError;
use crate::gpu::GpuLdc;
use crate::ldc::Ldc;
use crate::reconstruct::{Reconstruction, Served, reconstruct, shade};
use crate::settings::IbrrSettings;
use scene_core::gpu::GpuGBuffer;

/// Times and counts of the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTimings {
    /// Rebuilding for a light state the LDC cannot show by relighting (zero almost always).
    pub rebuild: Duration,
    /// Recombining the layers' per-source light for a new light state, and uploading the
    /// result when reconstructing on the GPU (zero when the lights were unchanged).
    pub relight: Duration,
    /// The camera's G-buffer.
    pub gbuffer: Duration,
    /// Warping the pixels into the LDC and shading.
    pub lookup: Duration,
    /// Pixels with geometry, no matching layer and nothing to fill from: black.
    pub missing: u64,
    /// Pixels served by the fallback search.
    pub fallback: u64,
    /// Pixels without a layer filled from the camera pixels around them
    /// ([`crate::IbrrSettings::fill_radius`]).
    pub filled: u64,
}

/// The IBRR as a [`Technique`].
pub struct IbrrTechnique {
    /// Construction and reconstruction settings (used by the next `prepare`).
    pub settings: IbrrSettings,
    /// When true, `prepare` only starts the construction and [`Technique::refine`] adds
    /// IRPLs; frames show the LDC so far.
    pub progressive: bool,
    /// With `progressive`: once the IRPLs asked for are built, [`Technique::refine`] goes
    /// on adding rounds of paths ([`Construction::extend`], each at most doubling them)
    /// until about this many IRPLs (it stops once fewer than a quarter of those built are
    /// still wanted); 0 stops at the settings' count. The caller's time budget per
    /// call bounds each call; frames show the last complete round.
    pub max_irpls: u32,
    /// With `max_irpls`: stop adding rounds once a round changed the LDC by less than this
    /// ([`Ldc::change_from`], about the error of the round before); 0 does not stop.
    pub target_change: f64,
    /// The change the last round made ([`IbrrTechnique::last_change`]).
    last_change: Option<f64>,
    renderer: Box<dyn GBufferRenderer + Send>,
    construction: Option<Construction>,
    ldc: Option<Ldc>,
    /// Fingerprint of the light state `ldc` shows.
    shown: u64,
    /// The GPU context frames reconstruct on, and the LDC uploaded there (dropped whenever
    /// the LDC changes).
    gpu: Option<(scene_core::gpu::GpuContext, Option<GpuLdc>)>,
    timings: FrameTimings,
    /// How each pixel of the last CPU frame found its light (empty after a GPU frame).
    served: Vec<Served>,
    name: String,
}

impl std::fmt::Debug for IbrrTechnique {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IbrrTechnique")
            .field("settings", &self.settings)
            .field("renderer", &self.renderer.name())
            .finish()
    }
}

impl IbrrTechnique {
    /// An IBRR with `settings`, hemicube and camera G-buffers from `renderer`.
    pub fn new(settings: IbrrSettings, renderer: Box<dyn GBufferRenderer + Send>) -> Self {
        Self {
            settings,
            progressive: false,
            max_irpls: 0,
            target_change: 0.0,
            last_change: None,
            renderer,
            construction: None,
            ldc: None,
            shown: 0,
            gpu: None,
            timings: FrameTimings::default(),
            served: Vec::new(),
            name: "ibrr".into(),
        }
    }

    /// Reconstructs frames on the GPU of `ctx` ([`GpuLdc`]): the LDC is uploaded once per
    /// construction, and the camera's G-buffer stays on the GPU when the renderer can
    /// render there (else it is uploaded). Construction runs the exact mode's gather there
    /// too ([`Construction::gather_on_gpu`]); the scatter stays on the CPU, the renders on
    /// whichever renderer was given.
    pub fn on_gpu(mut self, ctx: scene_core::gpu::GpuContext) -> Self {
        self.gpu = Some((ctx, None));
        self
    }

    /// The same with another report name.
    pub fn named(mut self, name: &str) -> Self {
        self.name = name.into();
        self
    }

    /// The construction (IRPLs, figures), once prepared.
    pub fn construction(&self) -> Option<&Construction> {
        self.construction.as_ref()
    }

    /// The LDC as last compacted.
    pub fn ldc(&self) -> Option<&Ldc> {
        self.ldc.as_ref()
    }

    /// The scene the LDC is being (or was) constructed for; `None` before `prepare`.
    pub fn scene(&self) -> Option<&Arc<Scene>> {
        self.construction.as_ref().map(|c| &c.scene)
    }

    /// How much the last round of progressive refinement changed the LDC
    /// ([`Ldc::change_from`]); `None` before a second round is complete.
    pub fn last_change(&self) -> Option<f64> {
        self.last_change
    }

    /// The figures of the last frame.
    pub fn last_timings(&self) -> FrameTimings {
        self.timings
    }

    /// How each pixel of the last frame found its light, row-major ([`Served`]); empty
    /// when that frame was reconstructed on the GPU, which only counts them.
    pub fn last_served(&self) -> &[Served] {
        &self.served
    }

    /// [`Technique::prepare`] under a light state, reporting `(steps done, steps total)`
    /// to `progress` as it goes ([`Construction::progress`]: one step an IRPL, two in the
    /// exact mode, which founds every layer before lighting any).
    pub fn prepare_lit(
        &mut self,
        scene: Arc<Scene>,
        lights: &LightState,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<(), IbrrError> {
        self.construction = None;
        self.ldc = None;
        self.last_change = None;
        if let Some((_, uploaded)) = self.gpu.as_mut() {
            *uploaded = None;
        }
        scene_core::contract::check(&scene).map_err(scene_core::Error::from)?;
        let mut c = Construction::new(scene, lights, &self.settings)?;
        if let Some((ctx, _)) = self.gpu.as_ref() {
            c.gather_on_gpu(ctx)?;
        }
        c.prepare_renderer(self.renderer.as_mut())?;
        if !self.progressive {
            c.build(self.renderer.as_mut(), progress)?;
        }
        self.ldc = Some(c.ldc()?);
        self.shown = c.lights.fingerprint();
        self.construction = Some(c);
        Ok(())
    }
}

impl IbrrTechnique {
    /// True when the LDC shows `lights` (the state it was built or last relit for).
    pub fn shows(&self, lights: &LightState) -> bool {
        self.ldc.is_some() && self.shown == lights.fingerprint()
    }

    /// Makes the LDC (and the technique's GPU copy) show `lights` by recombining its
    /// per-source light ([`Ldc::relight`]), unless it shows them already. Returns the time
    /// taken, or `None` when `lights` lights a source the IRPLs were made without (only a
    /// rebuild can show it) or nothing is prepared.
    pub fn relight(&mut self, lights: &LightState) -> Result<Option<Duration>, IbrrError> {
        let fingerprint = lights.fingerprint();
        if fingerprint == self.shown && self.ldc.is_some() {
            return Ok(Some(Duration::ZERO));
        }
        let t = Instant::now();
        let (Some(c), Some(ldc)) = (self.construction.as_ref(), self.ldc.as_mut()) else {
            return Ok(None);
        };
        let Some(factors) = c.relight_factors(lights) else {
            return Ok(None);
        };
        ldc.relight(&factors);
        if let Some((_, Some(g))) = self.gpu.as_mut() {
            g.update_values(ldc)?;
        }
        self.shown = fingerprint;
        Ok(Some(t.elapsed()))
    }
}

/// The paths of the next round of progressive refinement, if one is wanted. With
/// `max_irpls`: while the IRPLs still wanted are at least a quarter of those built (a
/// smaller round would cost a catch-up over every IRPL for little) and the last round
/// changed the LDC by more than `target` (0: no target), about the IRPLs still wanted.
/// Without it: what the construction's error target plans ([`Construction::plan`]).
fn next_round(
    progressive: bool,
    max_irpls: u32,
    target: f64,
    last_change: Option<f64>,
    c: &Construction,
) -> Option<u64> {
    if !progressive || !c.is_done() || c.irpls.paths == 0 {
        return None;
    }
    if max_irpls == 0 {
        return match c.plan() {
            Plan::More(paths) => Some(paths),
            Plan::Stop(_) => None,
        };
    }
    let n = c.irpls.irpls.len() as u64;
    if 4 * u64::from(max_irpls) <= 5 * n || target > 0.0 && last_change.is_some_and(|x| x <= target)
    {
        return None;
    }
    // About the IRPLs still wanted, at most as many paths as there are.
    let wanted = (u64::from(max_irpls) - n) as f64;
    Some((c.paths_for(wanted).ceil() as u64).clamp(1, c.irpls.paths))
}

impl Technique for IbrrTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        Ok(self.prepare_lit(scene, &LightState::default(), &mut |_, _| {})?)
    }

    fn refine(&mut self, budget: Duration) -> Result<scene_core::Refinement, Error> {
        let Some(c) = self.construction.as_mut() else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        let start = Instant::now();
        let mut steps = 0;
        let (progressive, max_irpls) = (self.progressive, self.max_irpls);
        let (target, last_change) = (self.target_change, self.last_change);
        // At least one IRPL per call, then as many as the budget allows, up to the end of a
        // round; the next call starts another round while more IRPLs are wanted.
        let mut finished_round = false;
        while steps == 0 || start.elapsed() < budget {
            if c.is_done() {
                let Some(more) = next_round(progressive, max_irpls, target, last_change, c) else {
                    break;
                };
                if c.extend(more)? == 0 {
                    break;
                }
            }
            steps += c.step(self.renderer.as_mut(), 1)? as u64;
            if c.is_done() {
                // A round ends the call, so that its LDC is shown before the next starts.
                finished_round = true;
                break;
            }
        }
        // A later round in progress shows the last complete one: no new LDC until it ends.
        let first_round = c.round() == 0;
        if steps > 0 && (finished_round || first_round) {
            let ldc = c.ldc()?;
            if finished_round
                && c.round() > 0
                && let Some(old) = self.ldc.as_ref()
            {
                self.last_change = ldc.change_from(old);
            }
            self.ldc = Some(ldc);
            self.shown = c.lights.fingerprint();
            if let Some((_, uploaded)) = self.gpu.as_mut() {
                *uploaded = None;
            }
        }
        let (done, total) = c.progress();
        let more = next_round(progressive, max_irpls, target, self.last_change, c).is_some();
        if c.is_done() && !more {
            c.mark_stopped();
        }
        Ok(scene_core::Refinement {
            done: c.is_done() && !more,
            steps,
            remaining: Some(if more && c.is_done() {
                1.0 - c.irpls.irpls.len() as f64 / f64::from(self.max_irpls.max(1))
            } else {
                (total - done) as f64 / total.max(1) as f64
            }),
        })
    }

    fn stated_error(&self) -> Option<f64> {
        self.construction
            .as_ref()
            .and_then(|c| c.error_estimate())
            .map(|e| e.worst())
    }

    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        let Some(c) = self.construction.as_ref() else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        let mut rebuild = Duration::ZERO;
        if c.relight_factors(frame.lights).is_none() {
            let t = Instant::now();
            let scene = c.scene.clone();
            let progressive = std::mem::replace(&mut self.progressive, false);
            let r = self.prepare_lit(scene, &LightState::default(), &mut |_, _| {});
            self.progressive = progressive;
            r?;
            rebuild = t.elapsed();
        }
        let relight = self.relight(frame.lights)?.unwrap_or_default();
        let (Some(c), Some(ldc)) = (self.construction.as_ref(), self.ldc.as_ref()) else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        let t = Instant::now();
        c.prepare_renderer(self.renderer.as_mut())?;
        if let Some((ctx, uploaded)) = self.gpu.as_mut() {
            if uploaded.is_none() {
                *uploaded = Some(GpuLdc::new(ctx, ldc, self.settings.reading())?);
            }
            let target = scene_core::ViewTarget::new(frame.view, frame.width, frame.height);
            let g = match self.renderer.render_views_gpu(&[target])? {
                Some(mut v) if v.len() == 1 => v.pop().expect("one view"),
                _ => {
                    let cpu = self
                        .renderer
                        .render_view(&frame.view, frame.width, frame.height)?;
                    GpuGBuffer::upload(ctx, &cpu).map_err(scene_core::Error::from)?
                }
            };
            let gbuffer = t.elapsed();
            let t = Instant::now();
            let gpu_ldc = uploaded.as_mut().expect("uploaded above");
            let (image, counts) = gpu_ldc.render(&c.scene, &g, &frame.view, frame.lights)?;
            self.served.clear();
            self.timings = FrameTimings {
                rebuild,
                relight,
                gbuffer,
                lookup: t.elapsed(),
                missing: counts.missing,
                fallback: counts.fallback,
                filled: counts.filled,
            };
            return Ok(image);
        }
        let g = self
            .renderer
            .render_view(&frame.view, frame.width, frame.height)?;
        let gbuffer = t.elapsed();
        let t = Instant::now();
        let r: Reconstruction = reconstruct(ldc, &g, &frame.view, self.settings.reading());
        let image = shade(&c.scene, &g, &frame.view, &r, frame.lights);
        self.timings = FrameTimings {
            rebuild,
            relight,
            gbuffer,
            lookup: t.elapsed(),
            missing: r.missing,
            fallback: r.fallback,
            filled: r.filled,
        };
        self.served = r.served;
        Ok(image)
    }
}

impl scene_core::technique::StageTimings for FrameTimings {
    fn stages(&self) -> Vec<(&'static str, Duration)> {
        vec![
            ("rebuild", self.rebuild),
            ("relight", self.relight),
            ("gbuffer", self.gbuffer),
            ("lookup", self.lookup),
        ]
    }
}
