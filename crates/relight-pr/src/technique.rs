//! Radiosity relighting as a [`Technique`]: `prepare` meshes the scene, solves (tagged
//! progressive refinement) and hands the element scene to its G-buffer renderer; `render`
//! relights with the frame's [`scene_core::LightState`] (eq. 1, never a re-solve) and
//! displays the result over the frame's G-buffer ([`crate::display`]).

use std::sync::Arc;
use std::time::Duration;

use scene_core::ray::RayScene;
use scene_core::{Error, FrameRequest, GBufferRenderer, Image, Scene, Technique};

use crate::display::{Shading, Welding, compose};
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
}

/// Times of the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTimings {
    /// Eq. 1 over all elements and sources.
    pub relight: Duration,
    /// The G-buffer of the element scene.
    pub gbuffer: Duration,
    /// Vertex averaging and per-pixel interpolation.
    pub display: Duration,
}

/// Radiosity relighting as a [`Technique`].
pub struct RelightTechnique {
    /// Meshing parameters (used by the next `prepare`).
    pub mesh: MeshSettings,
    /// Solver parameters (used by the next `prepare`).
    pub solver: SolverSettings,
    /// Display shading.
    pub shading: Shading,
    renderer: Box<dyn GBufferRenderer + Send>,
    prepared: Option<Prepared>,
    timings: FrameTimings,
    name: String,
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
            renderer,
            prepared: None,
            timings: FrameTimings::default(),
            name: "relight".into(),
        }
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

    /// The times of the last frame.
    pub fn last_timings(&self) -> FrameTimings {
        self.timings
    }
}

impl Technique for RelightTechnique {
    fn name(&self) -> &str {
        &self.name
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<(), Error> {
        self.prepared = None;
        let k = solver::sources(&scene, &self.solver.banks)?.len();
        let meshing = Meshing::new(&scene, &self.mesh, k)?;
        let rays = RayScene::build(&scene);
        let solution = solver::solve_with(
            &scene,
            &meshing,
            &rays,
            Some(self.renderer.as_mut()),
            &self.solver,
            &mut |_| {},
        )?;
        self.renderer
            .prepare(Arc::new(meshing.element_scene(&scene)))?;
        let welding = Welding::new(&meshing, scene.extent());
        self.prepared = Some(Prepared {
            scene,
            meshing,
            solution,
            welding,
        });
        Ok(())
    }

    fn render(&mut self, frame: &FrameRequest<'_>) -> Result<Image, Error> {
        let Some(p) = self.prepared.as_ref() else {
            return Err(Error::NotPrepared(format!("technique '{}'", self.name)));
        };
        let t0 = std::time::Instant::now();
        let irradiance = relight::irradiance(&p.solution, frame.lights);
        let glow = relight::glow(&p.meshing, &p.solution, frame.lights);
        let relight_time = t0.elapsed();
        let t1 = std::time::Instant::now();
        let g = self
            .renderer
            .render_view(&frame.view, frame.width, frame.height)?;
        let gbuffer_time = t1.elapsed();
        let t2 = std::time::Instant::now();
        let vertex = match self.shading {
            Shading::Smooth => p.welding.vertex_values(&p.meshing, &irradiance),
            Shading::Flat => Vec::new(),
        };
        let image = compose(
            &p.meshing,
            &p.welding,
            &g,
            &frame.view,
            &irradiance,
            &vertex,
            &glow,
            self.shading,
        );
        self.timings = FrameTimings {
            relight: relight_time,
            gbuffer: gbuffer_time,
            display: t2.elapsed(),
        };
        Ok(image)
    }
}
