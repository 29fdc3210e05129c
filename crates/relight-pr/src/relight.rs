//! Reconstruction, the paper's eq. 1: `B_j = sum_m B_jm E_m` for any set of emissions, here
//! with the direct and indirect parts of each source scaled apart (scene-core's
//! [`LightState`]: on/off, colour, direct and indirect multipliers). A relight never
//! re-solves: it is one pass over the k x n solution.

use glam::Vec3;
use rayon::prelude::*;
use scene_core::lights::{LightSetting, LightState};

use crate::mesh::Meshing;
use crate::solver::Solution;

/// The direct and indirect factors of each source of `solution` under `state`. A bank
/// follows the setting of its first light.
pub fn factors(solution: &Solution, state: &LightState) -> Vec<(Vec3, Vec3)> {
    source_factors(&solution.sources, state)
}

/// [`factors`] from the sources alone (what a frame keeps of a solution once it is on the
/// GPU, [`crate::gpu_frame::RelightFrame`]).
pub fn source_factors(sources: &[crate::solver::Source], state: &LightState) -> Vec<(Vec3, Vec3)> {
    sources
        .iter()
        .map(|s| {
            let setting = s
                .lights
                .first()
                .map_or(LightSetting::default(), |&id| state.get(id));
            (setting.direct_factor(), setting.indirect_factor())
        })
        .collect()
}

/// Each solution element's irradiance under `state` (one per group of mesh elements,
/// [`Meshing::groups`]):
/// `E_j = sum_m d_m E_direct,jm + i_m E_indirect,jm` (the indirect part holds the ambient
/// term, [`Solution::ambient`]).
pub fn irradiance(solution: &Solution, state: &LightState) -> Vec<Vec3> {
    weighted(solution, state, true)
}

/// Each element's irradiance under `state` without the direct part,
/// `sum_m i_m E_indirect,jm`: what the display interpolates when the direct
/// light is gathered per pixel ([`crate::direct::DirectLight::PerPixel`]).
pub fn indirect_irradiance(solution: &Solution, state: &LightState) -> Vec<Vec3> {
    weighted(solution, state, false)
}

/// The weights of eq. 1 under `state`: each source's `(direct, indirect)` factor (the
/// direct one zero unless `with_direct`), and the constant term every element receives
/// besides: zero, since the ambient term is part of the solution's indirect light
/// (an engine may add its own constant to [`crate::packed::Packed::relight`]).
pub fn weights(
    solution: &Solution,
    state: &LightState,
    with_direct: bool,
) -> (Vec<(Vec3, Vec3)>, Vec3) {
    let mut f = factors(solution, state);
    if !with_direct {
        f.iter_mut().for_each(|(d, _)| *d = Vec3::ZERO);
    }
    (f, Vec3::ZERO)
}

fn weighted(solution: &Solution, state: &LightState, with_direct: bool) -> Vec<Vec3> {
    let k = solution.k();
    if k == 0 {
        return vec![Vec3::ZERO; solution.elements];
    }
    let (f, base) = weights(solution, state, with_direct);
    solution
        .direct
        .par_chunks(k)
        .zip(solution.indirect.par_chunks(k))
        .map(|(d, i)| {
            let mut e = base;
            for m in 0..k {
                e += d[m] * f[m].0 + i[m] * f[m].1;
            }
            e
        })
        .collect()
}

/// Each mesh element's emitted radiance under `state`: its emission times its light's direct
/// factor (zero for non-emitters); [`Glow::at`] for every element.
pub fn glow(meshing: &Meshing, solution: &Solution, state: &LightState) -> Vec<Vec3> {
    let glow = Glow::new(meshing, solution, state);
    (0..meshing.elements.len())
        .into_par_iter()
        .map(|j| glow.at(j))
        .collect()
}

/// The emitted radiance of [`glow`] one mesh element at a time: what a frame's display
/// evaluates for the elements its pixels show ([`crate::display::compose`]), rather than
/// a vector over every element of the scene each frame.
#[derive(Clone, Debug)]
pub struct Glow<'a> {
    meshing: &'a Meshing,
    solution: &'a Solution,
    factors: Vec<(Vec3, Vec3)>,
}

impl<'a> Glow<'a> {
    /// The glow of `meshing`'s elements under `state`.
    pub fn new(meshing: &'a Meshing, solution: &'a Solution, state: &LightState) -> Self {
        Self {
            meshing,
            solution,
            factors: factors(solution, state),
        }
    }

    /// Mesh element `j`'s emitted radiance (zero for a non-emitter or an index past the
    /// meshing).
    pub fn at(&self, j: usize) -> Vec3 {
        let Some(el) = self.meshing.elements.get(j) else {
            return Vec3::ZERO;
        };
        self.meshing.patches[el.patch as usize]
            .light
            .and_then(|id| self.solution.source_of(id))
            .map_or(Vec3::ZERO, |m| {
                self.meshing.seen_emission(j) * self.factors[m].0
            })
    }
}

/// Each mesh element's outgoing radiance under `state`: `albedo E / pi` (`E` its
/// solution element's, [`Meshing::groups`]), plus its emission times its light's direct
/// factor ([`glow`]).
pub fn radiance(meshing: &Meshing, solution: &Solution, state: &LightState) -> Vec<Vec3> {
    let e = irradiance(solution, state);
    let glow = glow(meshing, solution, state);
    meshing
        .elements
        .par_iter()
        .enumerate()
        .zip(glow.par_iter())
        .map(|((j, el), g)| {
            el.albedo * e[solution.slot(meshing, j)] * std::f32::consts::FRAC_1_PI + *g
        })
        .collect()
}
