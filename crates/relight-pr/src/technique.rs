//! Radiosity relighting as a [`Technique`]: `prepare` meshes the scene, solves (tagged
//! progressive refinement) and hands the element scene to its G-buffer renderer; `render`
//! relights with the frame's [`scene_core::LightState`] (eq. 1, never a re-solve) and
//! displays the result over the frame's G-buffer ([`crate::display`]).

use std::sync::Arc;
use std::time::Duration;

use scene_core::gpu::Keyed;
use scene_core::ray::RayScene;
use scene_core::{Error, FrameRequest, GBufferRenderer, Image, Scene, Technique};

use crate::direct::{DirectGather, DirectLight};
use crate::display::{
    PixelDirect, Shading, Welding, compose, light_slots, pixel_direct, pixel_direct_shadowed,
};
use crate::mesh::{MeshSettings, Meshing};
use crate::relight;
use crate::solver::{self, Solution, SolverSettings};

/// What `prepare` built.
#[derive(Debug)]
pub struct Prepared {
    /// The scene prepared for.
    pub scene: Arc<Scene>,
    /// Its meshing.
    pub meshing: Meshing,
    /// The k single-source solutions.
    pub solution: Solution,
    /// Welded element corners for smooth display.
    pub welding: Welding,
    /// The scene's rays (per-pixel direct light).
    pub rays: RayScene,
}

impl Prepared {
    /// Relighting's precomputed state for `scene`, as [`RelightTechnique`]'s `prepare`
    /// builds it, without a renderer (ray-cast form factors, [`solver::solve`]): the scene's
    /// rays, its meshing by `mesh`, the k single-source solutions by `solver` (`progress`
    /// as [`solver::solve`] calls it) and the welding with visibility. What
    /// [`crate::RelightFrame::prepare`] puts on a GPU.
    pub fn solve(
        scene: Arc<Scene>,
        mesh: &MeshSettings,
        solver: &SolverSettings,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Self, crate::RelightError> {
        Self::solve_mapped(scene, mesh, solver, None, &mut |f, _| progress(f))
    }

    /// [`Prepared::solve`] with a renderer for hemicube form factors, telling `progress`
    /// whether the solve is hierarchical too.
    fn solve_mapped(
        scene: Arc<Scene>,
        mesh: &MeshSettings,
        settings: &SolverSettings,
        renderer: Option<&mut (dyn GBufferRenderer + Send)>,
        progress: &mut dyn FnMut(f64, bool),
    ) -> Result<Self, crate::RelightError> {
        let k = solver::sources(&scene, &settings.banks)?.len();
        let rays = RayScene::build(&scene);
        let meshing = Meshing::with_rays(&scene, mesh, k, &rays)?;
        let hierarchical = settings.hierarchy_for(meshing.elements.len()).is_some();
        let progress = &mut |f: f64| progress(f, hierarchical);
        let solution = solver::solve_with(&scene, &meshing, &rays, renderer, settings, progress)?;
        let welding = Welding::with_visibility(&meshing, scene.extent(), &rays);
        Ok(Self {
            scene,
            meshing,
            solution,
            welding,
            rays,
        })
    }
}

/// Times of the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTimings {
    /// Eq. 1 over all elements and sources.
    pub relight: Duration,
    /// The G-buffer of the element scene.
    pub gbuffer: Duration,
    /// The per-pixel direct light of every source: the gather of [`DirectLight::PerPixel`]
    /// (zero when the view and size are those of the previous frame: the gather is
    /// reused), or the shadow-map lookups of [`DirectLight::ShadowMaps`] (every frame; the
    /// maps themselves are built once, in `prepare` or the first frame that asks for them).
    pub direct: Duration,
    /// Vertex averaging and per-pixel interpolation.
    pub display: Duration,
}

/// The per-pixel direct light of one view.
#[derive(Debug)]
struct DirectCache {
    view: scene_core::View,
    size: (u32, u32),
    settings: DirectLight,
    values: Vec<glam::Vec3>,
}

/// The side of a sun's shadow map in [`DirectLight::ShadowMaps`] (twice the default of
/// [`scene_core::shadowed_lights::ShadowSettings`], where the texel budget holds it). On the
/// Breakfast Room, whose table and floor the sun stripes through a blind, 2 048 texels
/// narrowed the stripes: the maps read 1.32x the per-pixel gather's error (0.0734 against
/// 0.0557, 3 views at 128 x 96), and at 4 096 1.19x (0.0664), in the same frame time
/// (docs/relight-pr.md).
pub const SUN_MAP_RESOLUTION: u32 = 4096;

/// The shadow-mapped lights of [`DirectLight::ShadowMaps`] and each light's source.
#[derive(Debug)]
struct ShadowedLights {
    set: scene_core::shadowed_lights::LightSet,
    slots: Vec<Option<usize>>,
    /// Each element's own plane, where the pixels' footprints lie.
    planes: Vec<glam::Vec3>,
}

/// Radiosity relighting as a [`Technique`].
pub struct RelightTechnique {
    /// Meshing parameters (used by the next `prepare`).
    pub mesh: MeshSettings,
    /// Solver parameters (used by the next `prepare`).
    pub solver: SolverSettings,
    /// Display shading.
    pub shading: Shading,
    /// Where the display's direct light comes from. Default per pixel
    /// ([`DirectLight::default`]).
    pub direct: DirectLight,
    renderer: Box<dyn GBufferRenderer + Send>,
    prepared: Option<Prepared>,
    cache: Option<DirectCache>,
    /// The per-pixel gather, kept for its emitter rays: its emitters and the elements'
    /// planes do not depend on the view, so a new view reuses it.
    gather: Keyed<u32, DirectGather>,
    shadowed: Option<ShadowedLights>,
    timings: FrameTimings,
    name: String,
    /// The GPU path ([`RelightTechnique::on_gpu`]): the context, and the frame on the
    /// contract with what it was made for (the direct light's setting).
    gpu: Option<(scene_core::gpu::GpuContext, Option<GpuFrameState>)>,
}

/// Relighting's frame on the GPU and its target, made on the first GPU frame.
struct GpuFrameState {
    frame: crate::gpu_frame::RelightFrame,
    direct: DirectLight,
    target: Option<wgpu::Texture>,
}

impl std::fmt::Debug for RelightTechnique {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RelightTechnique")
            .field("mesh", &self.mesh)
            .field("solver", &self.solver)
            .field("renderer", &self.renderer.name())
            .finish()
    }
}

impl RelightTechnique {
    /// Relighting with the given meshing and solver settings, G-buffers from `renderer`.
    pub fn new(
        mesh: MeshSettings,
        solver: SolverSettings,
        renderer: Box<dyn GBufferRenderer + Send>,
    ) -> Self {
        Self {
            mesh,
            solver,
            shading: Shading::Smooth,
            direct: DirectLight::default(),
            renderer,
            prepared: None,
            cache: None,
            gather: Keyed::new(),
            shadowed: None,
            timings: FrameTimings::default(),
            name: "relight".into(),
            gpu: None,
        }
    }

    /// The same with its frames on `ctx`'s GPU: each frame is the display on the frame
    /// contract ([`crate::gpu_frame::RelightFrame`]) over the G-buffer where the renderer keeps
    /// it ([`GBufferRenderer::render_views_gpu`]; rendered on the CPU and uploaded by
    /// renderers that cannot, and whenever the per-pixel direct light is gathered, which
    /// reads it on the CPU), with the direct light of [`RelightTechnique::direct`]: the
    /// shadow maps evaluated per pixel on the GPU, the gathered values, or the elements'.
    /// Only the image is read back. Flat shading has no GPU display: it renders on the CPU.
    ///
    /// On the GPU the default direct light is the GPU's own: where
    /// [`RelightTechnique::direct`] is still [`DirectLight::default`] (the CPU gather,
    /// which would read the G-buffer back and gather on the CPU every new view), it
    /// becomes [`DirectLight::shadow_maps`]. A direct light set before stays.
    pub fn on_gpu(mut self, ctx: scene_core::gpu::GpuContext) -> Self {
        if self.direct == DirectLight::default() {
            self.direct = DirectLight::shadow_maps();
        }
        self.gpu = Some((ctx, None));
        self
    }

    /// The same with another report name.
    pub fn named(mut self, name: &str) -> Self {
        self.name = name.into();
        self
    }

    /// What `prepare` built.
    pub fn prepared(&self) -> Option<&Prepared> {
        self.prepared.as_ref()
    }

    /// What `prepare` built, taken out of the technique (for a caller that shares it
    /// between threads, e.g. an interactive viewer).
    pub fn into_prepared(self) -> Option<Prepared> {
        self.prepared
    }

    /// [`Technique::prepare`] reporting the solver's progress after every shot: the
    /// progressive solve's unshot fraction, or the hierarchical solve's share of its work
    /// left ([`SolverSettings::hierarchy_for`] says which runs). A caller that shows a
    /// bar uses [`RelightTechnique::prepare_with_share_done`].
    pub fn prepare_with_progress(
        &mut self,
        scene: Arc<Scene>,
        progress: &mut dyn FnMut(f64),
    ) -> Result<(), Error> {
        self.prepare_mapped(scene, &mut |f, _| progress(f))
    }

    /// [`Technique::prepare`] reporting the share of the solve done, from 0 to 1, whichever
    /// solver runs: the progressive solve's unshot fraction on a log scale from 1 down to
    /// [`SolverSettings::max_unshot`], the hierarchical solve's share of work left turned
    /// around.
    pub fn prepare_with_share_done(
        &mut self,
        scene: Arc<Scene>,
        done: &mut dyn FnMut(f64),
    ) -> Result<(), Error> {
        let target = self.solver.max_unshot.clamp(1e-12, 0.5).log10();
        self.prepare_mapped(scene, &mut |f, hierarchical| {
            done(if hierarchical {
                (1.0 - f).clamp(0.0, 1.0)
            } else {
                (f.max(1e-12).log10() / target).clamp(0.0, 1.0)
            })
        })
    }

    /// Meshes and solves, telling `progress` the solver's figure and whether the solve is
    /// hierarchical.
    fn prepare_mapped(
        &mut self,
        scene: Arc<Scene>,
        progress: &mut dyn FnMut(f64, bool),
    ) -> Result<(), Error> {
        self.prepared = None;
        self.cache = None;
        self.gather.clear();
        self.shadowed = None;
        // The GPU frame holds the last scene's solution: made again for this one.
        if let Some((_, state)) = self.gpu.as_mut() {
            *state = None;
        }
        scene_core::contract::check(&scene)?;
        let prepared = Prepared::solve_mapped(
            scene,
            &self.mesh,
            &self.solver,
            Some(self.renderer.as_mut()),
            progress,
        )?;
        self.renderer
            .prepare(Arc::new(prepared.meshing.element_scene(&prepared.scene)))?;
        self.prepared = Some(prepared);
        if let DirectLight::ShadowMaps {
            emitter_samples,
            penumbrae,
            ..
        } = self.direct
        {
            self.shadowed_lights(emitter_samples, penumbrae)?;
        }
        Ok(())
    }

    /// The shadow-mapped lights for `emitter_samples` and `penumbrae`, built on first use
    /// (the maps do not depend on the view).
    fn shadowed_lights(
        &mut self,
        emitter_samples: u32,
        penumbrae: bool,
    ) -> Result<&ShadowedLights, Error> {
        let Some(p) = self.prepared.as_ref() else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        if self.shadowed.as_ref().is_none_or(|s| {
            s.set.shadows.emitter_samples != emitter_samples || s.set.shadows.penumbrae != penumbrae
        }) {
            use scene_core::shadowed_lights::{LightSet, ShadowSettings};
            let settings = ShadowSettings {
                emitter_samples,
                penumbrae,
                directional_resolution: SUN_MAP_RESOLUTION,
                ..Default::default()
            };
            // Suns at SUN_MAP_RESOLUTION where the texel budget holds them, else halved
            // back to the default (the budget's fit, `LightSet::directional_resolution`).
            let set =
                LightSet::new(&p.scene, &settings).map_err(|e| Error::method("relight-pr", e))?;
            let slots = light_slots(&set, &p.solution.sources);
            self.shadowed = Some(ShadowedLights {
                set,
                slots,
                planes: p.meshing.plane_normals(),
            });
        }
        Ok(self.shadowed.as_ref().expect("built above"))
    }

    /// The times of the last frame.
    pub fn last_timings(&self) -> FrameTimings {
        self.timings
    }

    /// A frame on the GPU ([`RelightTechnique::on_gpu`]).
    fn render_gpu(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        use scene_core::gpu::{FrameInputs, GpuFrame, GpuGBuffer};
        let (Some(p), Some((ctx, state))) = (self.prepared.as_ref(), self.gpu.as_mut()) else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        let (w, h) = (frame.width, frame.height);
        if state.as_ref().is_none_or(|s| s.direct != self.direct) {
            let shadowed_direct = match (self.direct, self.shadowed.as_ref()) {
                (DirectLight::ShadowMaps { footprint, .. }, Some(s)) => Some((&s.set, footprint)),
                _ => None,
            };
            let settings = crate::gpu_frame::RelightFrameSettings {
                precision: crate::packed::Precision::F32,
                shadowed_direct,
            };
            *state = Some(GpuFrameState {
                frame: crate::gpu_frame::RelightFrame::prepare(ctx, p, &settings)?,
                direct: self.direct,
                target: None,
            });
        }
        let state = state.as_mut().expect("made above");
        let t0 = std::time::Instant::now();
        let mut direct_time = Duration::ZERO;
        let g = match self.direct {
            DirectLight::PerPixel {
                subpixels,
                emitter_rays,
            } => {
                // The gather reads the G-buffer on the CPU: render it there, gather unless
                // this view and size are those of the last frame, and upload.
                let cpu = self.renderer.render_view(&frame.view, w, h)?;
                let t = std::time::Instant::now();
                if !state.frame.has_pixel_direct(&frame.view, (w, h)) {
                    let gather = self.gather.get_or_make(emitter_rays, |&n| {
                        DirectGather::new(&p.scene, &p.meshing, &p.solution.sources, n)
                    });
                    let values = pixel_direct(gather, &p.rays, &cpu, &frame.view, subpixels);
                    state.frame.set_pixel_direct(frame.view, (w, h), values);
                }
                direct_time = t.elapsed();
                GpuGBuffer::upload(ctx, &cpu).map_err(Error::from)?
            }
            _ => {
                let target = scene_core::ViewTarget::new(frame.view, w, h);
                match self.renderer.render_views_gpu(&[target])? {
                    Some(mut v) if v.len() == 1 => v.pop().expect("one view"),
                    _ => {
                        let cpu = self.renderer.render_view(&frame.view, w, h)?;
                        GpuGBuffer::upload(ctx, &cpu).map_err(Error::from)?
                    }
                }
            }
        };
        let gbuffer_time = t0.elapsed() - direct_time;
        let t1 = std::time::Instant::now();
        if state
            .target
            .as_ref()
            .is_none_or(|t| (t.width(), t.height()) != (w, h))
        {
            state.target = Some(ctx.create_texture_2d(
                "relight frame",
                w,
                h,
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            ));
        }
        let target = state.target.as_ref().expect("made above");
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let inputs = FrameInputs {
            gbuffer: &g,
            view: &frame.view,
            lights: frame.lights,
        };
        state.frame.encode(&mut encoder, &inputs, target)?;
        ctx.queue.submit([encoder.finish()]);
        let image = ctx.read_texture_image(target).map_err(Error::from)?;
        self.timings = FrameTimings {
            relight: Duration::ZERO,
            gbuffer: gbuffer_time,
            direct: direct_time,
            display: t1.elapsed(),
        };
        Ok(image)
    }
}

impl Technique for RelightTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.prepare_with_progress(scene, &mut |_| {})
    }

    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        if self.prepared.is_none() {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        }
        // Built before the frame's clock starts only when the mode changed after prepare.
        if let DirectLight::ShadowMaps {
            emitter_samples,
            penumbrae,
            ..
        } = self.direct
        {
            self.shadowed_lights(emitter_samples, penumbrae)?;
        }
        if self.gpu.is_some() && self.shading == Shading::Smooth {
            return self.render_gpu(frame);
        }
        let Some(p) = self.prepared.as_ref() else {
            unreachable!("checked above")
        };
        let t0 = std::time::Instant::now();
        let irradiance = if self.direct.is_per_pixel() {
            relight::indirect_irradiance(&p.solution, frame.lights)
        } else {
            relight::irradiance(&p.solution, frame.lights)
        };
        let glow = relight::Glow::new(&p.meshing, &p.solution, frame.lights);
        let factors: Vec<glam::Vec3> = relight::factors(&p.solution, frame.lights)
            .into_iter()
            .map(|(d, _)| d)
            .collect();
        let relight_time = t0.elapsed();
        let t1 = std::time::Instant::now();
        let g = self
            .renderer
            .render_view(&frame.view, frame.width, frame.height)?;
        let gbuffer_time = t1.elapsed();
        let t3 = std::time::Instant::now();
        match self.direct {
            DirectLight::PerPixel {
                subpixels,
                emitter_rays,
            } => {
                let size = (frame.width, frame.height);
                let fresh = self.cache.as_ref().is_some_and(|c| {
                    c.view == frame.view && c.size == size && c.settings == self.direct
                });
                if !fresh {
                    let gather = self.gather.get_or_make(emitter_rays, |&n| {
                        DirectGather::new(&p.scene, &p.meshing, &p.solution.sources, n)
                    });
                    self.cache = Some(DirectCache {
                        view: frame.view,
                        size,
                        settings: self.direct,
                        values: pixel_direct(gather, &p.rays, &g, &frame.view, subpixels),
                    });
                }
            }
            DirectLight::ShadowMaps { footprint, .. } => {
                let Some(s) = self.shadowed.as_ref() else {
                    unreachable!("built above")
                };
                self.cache = Some(DirectCache {
                    view: frame.view,
                    size: (frame.width, frame.height),
                    settings: self.direct,
                    values: pixel_direct_shadowed(
                        &s.set,
                        &s.slots,
                        p.solution.k(),
                        &g,
                        &frame.view,
                        footprint,
                        Some(&s.planes),
                    ),
                });
            }
            DirectLight::Elements => {}
        }
        let direct_time = t3.elapsed();
        let t2 = std::time::Instant::now();
        let direct = match &self.cache {
            Some(c) if self.direct.is_per_pixel() && c.settings == self.direct => {
                Some(PixelDirect {
                    values: &c.values,
                    factors: &factors,
                })
            }
            _ => None,
        };
        let image = compose(
            &p.meshing,
            &p.welding,
            &g,
            &frame.view,
            &irradiance,
            &glow,
            self.shading,
            direct,
        );
        self.timings = FrameTimings {
            relight: relight_time,
            gbuffer: gbuffer_time,
            direct: direct_time,
            display: t2.elapsed(),
        };
        Ok(image)
    }
}

impl scene_core::technique::StageTimings for FrameTimings {
    fn stages(&self) -> Vec<(&'static str, Duration)> {
        vec![
            ("relight", self.relight),
            ("gbuffer", self.gbuffer),
            ("direct", self.direct),
            ("display", self.display),
        ]
    }
}
