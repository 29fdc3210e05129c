//! # relight-pr
//!
//! Radiosity relighting (Kasper Høy Nielsen and Niels Jørgen Christensen, "Real-Time
//! Dynamic Radiosity Relighting of Virtual Environments", Journal of WSCG 10(1-2),
//! 2002, pp. 325-332): progressive-refinement
//! radiosity whose energy is tagged with the light it came from, so k single-light
//! solutions are computed with one row of form factors per shot, and relit in real time
//! as `B_j = sum_m B_jm E_m` (eq. 1) with each light's direct and indirect parts scaled
//! apart.
//!
//! ```
//! use relight_pr::{mesh::{MeshSettings, Meshing}, relight, solver::{self, SolverSettings}};
//! use scene_core::{builtin, lights::{LightId, LightState}, ray::RayScene};
//!
//! let scene = builtin::scene("cornell-point").unwrap();
//! let meshing = Meshing::new(&scene, &MeshSettings::elements(256), 1).unwrap();
//! let rays = RayScene::build(&scene);
//! let settings = SolverSettings { max_unshot: 0.05, visibility_samples: 4, ..Default::default() };
//! let solution = solver::solve(&scene, &meshing, &rays, &settings, &mut |_| {}).unwrap();
//! // Relight: the point light at half power, in red.
//! let mut state = LightState::default();
//! state.set_color(LightId::Point(0), glam::Vec3::new(0.5, 0.0, 0.0));
//! let red = relight::radiance(&meshing, &solution, &state);
//! assert!(red.iter().all(|c| c.y == 0.0 && c.z == 0.0));
//! ```
//!
//! The pieces: [`mesh`] (patches and elements sized from the scene), [`form_factor`]
//! (closed-form point-to-polygon form factors with ray-cast visibility), [`solver`] (the
//! figure 2 loop, the two baselines of Table 1, direct and indirect apart, ambient term),
//! [`hierarchical`] (hierarchical radiosity with clustering, the
//! same tagged solution from links between clusters; opt-in, for large scenes), [`relight`]
//! (eq. 1 for any light state), [`display`] (smooth interpolation over a
//! camera G-buffer of the element scene), [`dynamic`] (moving lights and dynamic objects,
//! section 2.4), [`technique`] (`RelightTechnique`, a `scene_core::Technique`). `docs/relight-pr.md` has the design, the tests
//! and the measured figures.

pub mod direct;
pub mod display;
pub mod dynamic;
pub mod element_ids;
pub mod export;
pub mod form_factor;
pub mod gpu;
pub mod gpu_frame;
pub mod hierarchical;
pub mod merge;
pub mod mesh;
pub mod packed;
pub mod relight;
pub mod solver;
pub mod technique;
pub mod visibility;

pub use gpu_frame::{RelightFrame, RelightFrameSettings};
pub use hierarchical::{HierarchySettings, HierarchyStats};
pub use mesh::{MeshBudget, MeshSettings, Meshing};
pub use solver::{FormFactorMethod, Solution, SolverSettings, Strategy, solve, solve_with};
pub use technique::{Prepared, RelightTechnique, SUN_MAP_RESOLUTION};

/// Every shader pass of relighting, as `cargo xtask shaders` validates them.
pub use gpu::SHADER_PASSES;
pub use scene_core;

/// An error of the relighting crate.
#[derive(Debug, thiserror::Error)]
pub enum RelightError {
    /// A parameter is out of range.
    #[error("invalid relighting setting: {0}")]
    InvalidSetting(String),
    /// A light id the scene does not have.
    #[error("unknown light {0}")]
    UnknownLight(String),
    /// The meshing or the solution would exceed its budget (nothing was allocated).
    #[error("budget exceeded: {0}")]
    Budget(scene_core::BudgetExceeded),
    /// The G-buffer renderer of the hemicube failed.
    #[error("hemicube rendering failed: {0}")]
    Render(Box<scene_core::Error>),
    /// The GPU failed (device, validation, readback).
    #[error("GPU relighting failed: {0}")]
    Gpu(Box<scene_core::gpu::GpuError>),
    /// The solve gained energy instead of losing it: the unshot energy became non-finite
    /// or grew past [`solver::DIVERGED_FRACTION`] of the emitted energy. Form factors that
    /// sum above 1 do this (overlapping faces, a hemicube too coarse for its patches).
    #[error(
        "the radiosity solve diverged after {shots} shots: the unshot energy is {fraction:e} \
         times the emitted energy (form factors gain energy: overlapping faces, or a hemicube \
         too coarse)"
    )]
    Diverged {
        /// Shots taken when it was noticed.
        shots: usize,
        /// The unshot fraction then (non-finite or above the limit).
        fraction: f64,
    },
}

impl From<RelightError> for scene_core::Error {
    fn from(e: RelightError) -> Self {
        match e {
            RelightError::Render(inner) => *inner,
            RelightError::Gpu(inner) => scene_core::Error::Gpu(*inner),
            other => scene_core::Error::method("relight-pr", other),
        }
    }
}
